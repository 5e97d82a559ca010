"""The ``npe`` calibration method: neural posterior estimation (Papamakarios & Murray 2016; Greenberg et
al. 2019), amortised, with its coverage checked on held-out simulations before it is trusted.

Shapes: N training and H held-out simulations, d parameters, k statistics, S posterior draws.

Contract
--------
``training_design(config) -> (N + H, d)``: prior draws from ``[seed, Tag.NPE, NPEStream.DESIGN]``; the
first N train, the last H are held out.

``training_sweep(config, theta) -> SweepConfig``: those draws as a sweep (one zipped axis over the free
parameters' keys, one replicate, the calibration's ``[model]``, ``[run]`` and seed; an integer key's values
rounded, as the calibration's simulator rounds them), so the training set
runs on the sweep machinery: content-addressed runs, resumable (run the same command again), every
executor, failures recorded. Its results folder is ``<out>/training``.

``simulated_rows(config, theta, table) -> (N + H, k)``: the runs table's target columns in design
order (a failed run's row is NaN), plus, for mean/sd targets, the targets' measurement noise N(0, cov)
from ``[seed, Tag.NPE, NPEStream.NOISE]`` (the data model of every other method), or from ``noise``.

``estimator_identity(config) -> dict``: what the trained estimator depends on (model and its version,
metric settings, parameters and priors, target columns and their measurement covariance, seed,
simulations, held-out count, the flow's settings and the ensemble's size): NOT the observed values. An estimator folder whose
``identity.json`` equals it is reused: ``flocksweep calibrate`` with other targets (another flight,
another flock) runs no training simulation.

``coverage_check(estimator, theta (H, d), x (H, k), draws, seed, support, tolerance, names) -> dict``:
per parameter the share of held-out truths inside the estimator's central 50% and 90% intervals (its
expected coverage) and SBC ranks (Talts et al. 2018) of the truths among ``draws`` posterior draws;
``passed`` when every coverage is within ``allowed`` of nominal, ``allowed = max(tolerance, 2.58 x
sqrt(p (1 - p) / H))`` (a 99 % binomial band: a correct estimator on few held-out sets is not failed by
chance). A failed check makes the calibration's verdict "NOT converged".

``run_npe(config, folder, pool_kind, workers, scheduler, phases, cost) -> NpeResult``: the method as
``flocksweep calibrate`` runs it (analysis.calibration.run writes the common outputs).

Sequential rounds (``rounds = R > 1``; :mod:`analysis.calibration.npe_rounds`): round 1 runs the first N
draws of the one-round design (no held-out share) in ``<out>/training``; round r >= 2 runs N draws of
the prior truncated to round r - 1's estimator's region at the targets (``[seed, Tag.NPE,
ROUND_DESIGN, r]``; the last round N + H, its last H held out) in ``<out>/training-round<r>``, with its
noise from ``[.., ROUND_NOISE, r]``; round r's estimator is trained on all rounds' N-shares so far
(seed ``[.., ROUND_TRAIN, r]``; round 1 ``TRAIN``) and stored in ``estimator-round<r>`` (the last in
``estimator``) with its identity, so a calibration run again after an interrupt re-uses finished
rounds' runs and estimators (every design is deterministic given the seed). The identity then holds
the observed values: a truncated estimator serves these targets only. The coverage check's held-out
truths come from the last round's truncated prior and its posteriors, like the draws at the targets,
are restricted to that region: coverage of the truncated problem, where TSNPE's posterior is valid.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.observables.summary import motion_settings
from flocksweep.simcore import MODEL_VERSION
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.config import SweepConfig
from flocksweep.sweeps.files import json_ready
from flocksweep.sweeps.runner import run_sweep
from flocksweep.sweeps.seeds import NPEStream, Tag, generator

from .diagnostics import sbc_ranks
from .simulator import summary_simulator
from .npe_flow import Estimator, FlowSettings, load_estimator, train_ensemble
from .npe_rounds import truncated_prior_draws, truncation_region

IDENTITY_FILE = "identity.json"
LEVELS = (0.5, 0.9)


def _stream(config, which: NPEStream, *more: int) -> np.random.Generator:
    return generator(config.seed, Tag.NPE, int(which), *more)


def _jax_seed(config, which: NPEStream, *more: int) -> int:
    return int(_stream(config, which, *more).integers(0, 2 ** 31 - 1))


def check_npe(config) -> None:
    """What npe cannot do yet, as ConfigErrors naming the key."""
    if config.observation is not None:
        raise ConfigError("observation", "the npe method trains on sweep runs, which are not measured through an "
                                         "[observation] block; use emcee or remove the block")
    if len(config.targets.observed) != 1:
        raise ConfigError("targets", f"npe gives the posterior of one observed flock; the targets hold "
                                     f"{len(config.targets.observed)} rows: use flocksweep posterior ESTIMATOR "
                                     "--targets FILE for one posterior per flock, or aggregate them")


def training_design(config) -> np.ndarray:
    settings = config.method
    count = settings.simulations + settings.heldout
    return np.asarray(config.prior.sample(_stream(config, NPEStream.DESIGN), count), dtype=float).reshape(count, -1)


def training_sweep(config, theta: np.ndarray) -> SweepConfig:
    source = config.source
    integer = summary_simulator(config, n_sim=1).integer_keys   # an integer key (init.n, neighbours) runs rounded
    rows = [[int(round(v)) if whole else float(v) for v, whole in zip(row, integer)] for row in theta]
    if any(integer) and len({tuple(row) for row in rows}) < len(rows):
        raise ConfigError("parameters", "rounded to integers, the prior draws repeat (a sweep runs each point once): "
                                        "an integer parameter needs a continuous one beside it for npe and compare")
    values = rows if config.dim > 1 else [row[0] for row in rows]
    axis = {"keys": list(config.keys)} if config.dim > 1 else {"key": config.keys[0]}
    axis.update(name="prior_draw", values=values)
    data = {"name": f"{config.name}-npe-training", "seed": int(config.seed), "replicates": 1,
            "model": {"preset": str(config.preset_path), "set": dict(source.get("model", {}).get("set", {}))},
            "run": dict(source.get("run", {})), "axes": [axis]}
    return SweepConfig.from_dict(data, config.preset_path.parent)


def simulated_rows(config, theta: np.ndarray, table: pd.DataFrame, noise: np.random.Generator | None = None
                   ) -> np.ndarray:
    columns = list(config.targets.columns)
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ConfigError("targets.stats", f"the training runs have no column {missing[0]!r}")
    rows = np.full((len(theta), len(columns)), np.nan)
    ok = table[table["status"] == "ok"]
    rows[ok["point_index"].to_numpy(dtype=int)] = ok[columns].to_numpy(dtype=float)
    cov = config.targets.cov
    if cov is not None:
        noise = _stream(config, NPEStream.NOISE) if noise is None else noise
        rows = rows + noise.multivariate_normal(np.zeros(len(cov)), cov, size=len(rows))
    return rows


def flow_settings(config) -> FlowSettings:
    return config.method.flow


def estimator_identity(config) -> dict:
    settings = config.method
    m = config.metrics
    return json_ready({"model": config.preset.to_dict(), "model_version": MODEL_VERSION,
                       "metrics": {"warmup": m.warmup, "group_radius": m.group_radius,
                                   "fragmentation_cohesion": m.fragmentation_cohesion,
                                   **motion_settings(m)},   # only those that differ: earlier identities hold
                       "parameters": [[p.name, p.key] for p in config.parameters], "prior": repr(config.prior),
                       "bounds": [list(b) for b in config.prior.bounds],
                       "columns": list(config.targets.columns),
                       "observation_cov": None if config.targets.cov is None else np.asarray(config.targets.cov).tolist(),
                       "seed": int(config.seed), "simulations": settings.simulations, "heldout": settings.heldout,
                       "flow": asdict(flow_settings(config)),
                       **({"ensemble": settings.ensemble} if settings.ensemble > 1 else {}),
                       **({"rounds": settings.rounds, "observed": np.asarray(config.targets.observed[0]).tolist()}
                          if settings.rounds > 1 else {})})


def digest(identity: dict) -> str:
    return hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()[:16]


def stored_identity(folder: Path) -> dict | None:
    path = Path(folder) / IDENTITY_FILE
    return json.loads(path.read_text()) if path.is_file() else None


def support_of(prior=None, bounds=None):
    """(S, d) -> (S,) inside the prior's bounds (or the given (d, 2) bounds)."""
    bounds = np.asarray(prior.bounds if prior is not None else bounds, dtype=float)

    def inside(theta):
        return np.all((theta >= bounds[:, 0]) & (theta <= bounds[:, 1]), axis=1)
    return inside


def coverage_check(estimator: Estimator, theta, x, draws: int, seed: int, support, tolerance: float,
                   names) -> dict:
    """Expected coverage and SBC ranks on held-out simulations (module docstring)."""
    theta, x = np.asarray(theta, dtype=float), np.asarray(x, dtype=float)
    samples = estimator.sample_many(x, draws, seed, support)
    rows = []
    held = len(theta)
    for level in LEVELS:
        low = np.quantile(samples, (1 - level) / 2, axis=1)
        high = np.quantile(samples, (1 + level) / 2, axis=1)
        inside = (theta >= low) & (theta <= high)
        allowed = max(tolerance, 2.58 * np.sqrt(level * (1 - level) / held))
        for j, name in enumerate(names):
            rows.append({"parameter": name, "level": level, "coverage": float(inside[:, j].mean()),
                         "allowed": float(allowed), "ok": bool(abs(inside[:, j].mean() - level) <= allowed)})
    table = pd.DataFrame(rows)
    ranks = sbc_ranks(theta, list(samples), np.random.default_rng(seed))
    messages = [f"{r.parameter}: {r.level:.0%} intervals cover {r.coverage:.1%} of {held} held-out truths "
                f"(allowed {r.level:.0%} +- {r.allowed:.1%})" for r in table.itertuples() if not r.ok]
    passed = bool(table["ok"].all())
    if passed:
        messages = [f"coverage: the 50% and 90% intervals cover their share of {held} held-out truths "
                    f"(within {table['allowed'].max():.1%})"]
    else:
        messages.insert(0, "coverage FAILED: the estimator's intervals do not cover their share of held-out "
                           "truths; do not trust its posterior (more simulations, another flow)")
    return {"table": table, "ranks": ranks, "draws": int(draws), "heldout": held, "passed": passed,
            "messages": messages}


@dataclass
class NpeResult:
    estimator: Estimator
    draws: np.ndarray            # (S, d) at the targets
    coverage: dict
    info: dict                   # convergence.json's "npe" entry


def _training_sweep_run(config, theta, path, trained: int, executor, phases, cost, label: str = ""):
    """Run the design ``theta`` as a sweep in ``path`` (only its runs not stored yet), counting the new
    runs of its first ``trained`` rows as training and the rest as held out; the runs table."""
    pool_kind, workers, scheduler = executor
    held = len(theta) - trained
    phases.start(f"the training sweep{label}: {len(theta)} simulations ({trained} for training"
                 f"{f', {held} held out' if held else ''}), only those not stored yet")
    result = run_sweep(training_sweep(config, theta), None, path, executor=pool_kind, workers=workers,
                       scheduler=scheduler, progress=phases.enabled)
    train_new = sum(1 for spec in result.plan.todo if spec.point_index < trained)
    cost.add("training", train_new)
    cost.add("heldout", len(result.plan.todo) - train_new)
    return result.table


def _fit(config, theta, rows, seed: int, phases, label: str = ""):
    settings = config.method
    if len(theta) < 20:
        raise ConfigError("method.simulations", f"only {len(theta)} training runs gave finite statistics; choose "
                                                "statistics every run has")
    flows = f"{settings.ensemble} flows" if settings.ensemble > 1 else "the flow"
    phases.start(f"training {flows}{label} on {len(theta)} simulations (at most "
                 f"{flow_settings(config).max_epochs} epochs each)")
    return train_ensemble(theta, rows, flow_settings(config), seed, settings.ensemble, progress=phases.enabled)


def _train(config, folder, executor, phases, cost):
    """Run the training sweep (only its missing runs) and fit the flow; (estimator, heldout theta, x)."""
    n = config.method.simulations
    theta = training_design(config)
    table = _training_sweep_run(config, theta, folder.path("training"), n, executor, phases, cost)
    rows = simulated_rows(config, theta, table)
    usable = np.isfinite(rows).all(axis=1)
    estimator = _fit(config, theta[:n][usable[:n]], rows[:n][usable[:n]], _jax_seed(config, NPEStream.TRAIN), phases)
    return estimator, theta[n:][usable[n:]], rows[n:][usable[n:]], int((~usable).sum())


def _heldout(config, folder):
    """The held-out simulations of a stored training sweep (runs found done, none computed)."""
    from flocksweep.sweeps.results import load_results

    theta = training_design(config)
    table = load_results(folder.path("training")).runs
    rows = simulated_rows(config, theta, table)
    n = config.method.simulations
    usable = np.isfinite(rows[n:]).all(axis=1)
    return theta[n:][usable], rows[n:][usable]


def run_npe(config, folder, pool_kind: str, workers, scheduler, phases, cost) -> NpeResult:
    """Train or reuse the estimator, check its coverage, draw the posterior at the targets; ``phases``
    (:class:`sweeps.progress.Phases`) shows each step on stderr."""
    check_npe(config)
    settings = config.method
    if settings.rounds > 1:
        return _run_rounds(config, folder, (pool_kind, workers, scheduler), phases, cost)
    identity = estimator_identity(config)
    where = Path(settings.estimator) if settings.estimator is not None else folder.path("estimator")
    reused = stored_identity(where) == identity
    if settings.estimator is not None and not reused:
        found = stored_identity(where)
        raise ConfigError("method.estimator", f"{where} holds no estimator trained for this calibration "
                                              f"({'no ' + IDENTITY_FILE if found is None else 'its identity differs'}"
                                              "; the model, parameters, priors, statistics, their sd, seed and "
                                              "flow settings must all be the same)")
    failed = 0
    if reused:
        estimator = load_estimator(where)
        heldout_theta, heldout_x = _heldout(config, folder) if settings.estimator is None else \
            _heldout(config, _Folder(where.parent))
        phases.total -= 1     # one phase instead of the training sweep and the flow's training
        phases.start(f"reusing the trained estimator in {where} (no simulation)")
    else:
        estimator, heldout_theta, heldout_x, failed = _train(config, folder, (pool_kind, workers, scheduler),
                                                             phases, cost)
        _store(folder, where, estimator, identity)
    info = {"estimator": str(where), "identity": digest(identity), "reused": bool(reused),
            "training_simulations": settings.simulations, "failed_runs": failed}
    return _checked_posterior(config, estimator, heldout_theta, heldout_x, support_of(config.prior), phases, info)


def _store(folder, where: Path, estimator, identity: dict) -> None:
    estimator.save(where)
    folder.write_json(str(Path(where).relative_to(folder.root) / IDENTITY_FILE), identity)


def _checked_posterior(config, estimator, heldout_theta, heldout_x, support, phases, info: dict) -> NpeResult:
    """The coverage check on the held-out simulations and the posterior draws at the targets, both
    restricted to ``support``."""
    settings = config.method
    phases.start(f"the coverage check on {len(heldout_theta)} held-out simulations (199 posterior draws each)")
    check = coverage_check(estimator, heldout_theta, heldout_x, draws=199, seed=_jax_seed(config, NPEStream.COVERAGE),
                           support=support, tolerance=settings.coverage_tolerance, names=config.names)
    draws = estimator.sample(config.targets.observed[0], settings.draws, _jax_seed(config, NPEStream.POSTERIOR),
                             support)
    info = {**info, "heldout_simulations": int(len(heldout_theta)), "leakage": estimator.last_leakage,
            "flow": estimator.record(), "coverage": {"passed": check["passed"], "table": check["table"].to_dict("records")}}
    return NpeResult(estimator, draws, check, info)


def _round_design(config, r: int, region) -> tuple[np.ndarray, float]:
    """Round r's parameter vectors and the prior mass of the region they come from: round 1 the first
    ``simulations`` prior draws of the one-round design, round r >= 2 draws from the prior truncated to
    ``region`` (the last round's with ``heldout`` more)."""
    settings = config.method
    if r == 1:
        return training_design(config)[:settings.simulations], 1.0
    count = settings.simulations + (settings.heldout if r == settings.rounds else 0)
    return truncated_prior_draws(config.prior, region, count, _stream(config, NPEStream.ROUND_DESIGN, r))


def _round_estimator(config, folder, r: int, identity: dict, theta, rows, phases, label: str):
    """Round r's estimator: the stored one when its identity matches (an interrupted calibration run again
    trains no finished round anew), else trained on all rounds' simulations so far and stored."""
    last = r == config.method.rounds
    where = folder.path("estimator" if last else f"estimator-round{r}")
    if stored_identity(where) == identity:
        phases.start(f"reusing round {r}'s trained estimator in {where}")
        return load_estimator(where), where, True
    seed = _jax_seed(config, NPEStream.TRAIN) if r == 1 else _jax_seed(config, NPEStream.ROUND_TRAIN, r)
    estimator = _fit(config, theta, rows, seed, phases, label)
    _store(folder, where, estimator, identity)
    return estimator, where, False


def _run_rounds(config, folder, executor, phases, cost) -> NpeResult:
    """Truncated sequential rounds (analysis.calibration.npe_rounds; docs/calibration.md): each round's
    sweep in ``training`` (round 1) or ``training-round<r>``, its estimator in ``estimator-round<r>``
    (the last in ``estimator``); the coverage check and the posterior inside the last round's region."""
    settings = config.method
    identity = estimator_identity(config)
    observed = np.asarray(config.targets.observed[0], dtype=float)
    inside_prior = support_of(config.prior)
    n, region, thetas, rows, rounds, failed = settings.simulations, None, [], [], [], 0
    for r in range(1, settings.rounds + 1):
        label = f" of round {r}/{settings.rounds}"
        theta, accepted = _round_design(config, r, region)
        table = _training_sweep_run(config, theta, folder.path("training" if r == 1 else f"training-round{r}"), n,
                                    executor, phases, cost, label)
        x = simulated_rows(config, theta, table, None if r == 1 else _stream(config, NPEStream.ROUND_NOISE, r))
        usable = np.isfinite(x).all(axis=1)
        failed += int((~usable).sum())
        thetas.append(theta[:n][usable[:n]])
        rows.append(x[:n][usable[:n]])
        round_identity = identity if r == settings.rounds else {**identity, "rounds": "sequential", "round": r}
        estimator, where, reused = _round_estimator(config, folder, r, round_identity, np.concatenate(thetas),
                                                    np.concatenate(rows), phases, label)
        rounds.append({"round": r, "simulations": n, "prior_mass": accepted, "estimator_reused": reused,
                       **({"threshold": region.threshold} if region is not None else {})})
        if r < settings.rounds:
            region = truncation_region(estimator, observed, inside_prior, _jax_seed(config, NPEStream.ROUND_REGION, r + 1))
    info = {"estimator": str(where), "identity": digest(identity), "reused": bool(reused),
            "training_simulations": n * settings.rounds, "failed_runs": failed, "rounds": rounds}
    return _checked_posterior(config, estimator, theta[n:][usable[n:]], x[n:][usable[n:]], region.contains,
                              phases, info)


class _Folder:
    """The one method of an OutputFolder that _heldout needs, for a foreign estimator's calibration folder."""

    def __init__(self, root: Path):
        self.root = Path(root)

    def path(self, name: str) -> Path:
        return self.root / name
