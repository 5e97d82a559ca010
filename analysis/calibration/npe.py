"""The ``npe`` calibration method: neural posterior estimation (Papamakarios & Murray 2016; Greenberg et
al. 2019), amortised, with its coverage checked on held-out simulations before it is trusted.

Shapes: N training and H held-out simulations, d parameters, k statistics, S posterior draws, m observed
rows.

Contract
--------
The data model is the calibration's own (:func:`npe_simulator`, on
:func:`analysis.calibration.simulator.summary_simulator`): every training run is the model (built-in,
plug-in or external command) measured through the ``[observation]`` block exactly as the tracks were
(projection, sampling and velocity intervals, missed detections, position noise, the group radius), the
same runs every other method simulates. With m observed rows (targets given as ``samples`` or several
flocks ``from_tracks``) a training simulation is the mean statistics of m runs at its parameters and the
estimator is conditioned on the mean of the m observed rows (the flocks are independent replicates of the
model; a learned summary's row is the m runs' mean statistics followed by each run's raw inputs, and the
estimator embeds each flock alike and pools the m embeddings: :mod:`analysis.calibration.learned_summary`); with
one row it is one run. Measurement noise of mean/sd targets (or ``from_tracks`` with ``sd``)
N(0, cov / m) is added to every training row from ``[seed, Tag.NPE, NPEStream.NOISE]`` (round r >= 2:
``ROUND_NOISE, r``), as the other methods add it. The statistics the flow sees are transformed
(:mod:`analysis.calibration.transforms`, ``config.transforms``), the observed row likewise.

``training_design(config) -> (N + H, d)``: prior draws from ``[seed, Tag.NPE, NPEStream.DESIGN]``; the
first N train, the last H are held out. Row i runs with the seed drawn from ``[seed, Tag.NPE,
NPEStream.RUNS, i]`` (round r >= 2: ``ROUND_RUNS, r, i``), so its statistics are a function of the file and
i only. The runs are computed by :func:`analysis.calibration.training_runs.design_rows` into
``<out>/training/`` (stored as they finish under the design's digest: the same command run again after
an interrupt or a failure finds them), on the calibration's executor, or a local process pool when it
runs ``serial``. A run that fails or gives statistics that are not finite is counted, its reason kept
(``npe.failed_runs``, ``npe.failure_reasons``) and left out.

``estimator_identity(config) -> dict``: what the trained estimator depends on: the data model (the
simulator's identity: model and its version, free keys, statistic columns, metric settings, observation
block or command), the measurement of the observed statistics (:func:`measurement_settings`), parameters
and priors, the targets' measurement covariance, the statistics' transforms, seed, simulations, held-out
count, the flow's settings and the ensemble's size: NOT the observed values (one round). An estimator
folder whose ``identity.json`` equals it is reused: ``flocksweep calibrate`` with other targets (another
flight) runs no training simulation.

``measurement_settings(config) -> dict``: how statistics must be measured to be given to the estimator:
``interval`` (s), ``velocity_interval`` (s or "recorded"), ``max_gap``, ``dims`` (2 with a projection),
``length_unit`` ("BL"), ``group_radius``, ``fragmentation_cohesion``, ``dcd_max_delay``, ``warmup`` (seconds
skipped at the start of each measured flock: ``[targets.tracks] warmup``); stored in the
identity, checked by ``flocksweep posterior`` against a measured table
(:mod:`analysis.calibration.posterior_command`).

``coverage_check(estimator, theta (H, d), x (H, k), draws, seed, support, tolerance, names) -> dict``:
per parameter the share of held-out truths inside the estimator's central 50% and 90% intervals (its
expected coverage) and SBC ranks (Talts et al. 2018) of the truths among ``draws`` posterior draws;
``passed`` when every coverage is within ``allowed`` of nominal, ``allowed = max(tolerance, 2.58 x
sqrt(p (1 - p) / H))`` (a 99 % binomial band: a correct estimator on few held-out sets is not failed by
chance). A held-out simulation whose posterior the support holds almost no mass of (its statistics far
from the training set's) is left out and counted (``excluded``); more than :data:`MAX_EXCLUDED` of them
fails the check. A failed check makes the calibration's verdict "NOT converged" and the fit not credible;
the verdict is stored beside the estimator (``coverage.json``) for ``flocksweep posterior``.

``trained_estimator(config, folder, pool, executor, phases, cost) -> (estimator, (theta, x) held out, info,
where)``: the one-round estimator trained or reused (what ``run_npe`` starts with; SBC,
:mod:`analysis.calibration.sbc_npe`, uses it alone).

``run_npe(config, folder, pool, executor, phases, cost) -> NpeResult``: the method as ``flocksweep
calibrate`` runs it (:mod:`analysis.calibration.methods.npe` writes the common outputs). An observed row
the estimator puts almost no mass inside the prior at raises
:class:`~analysis.calibration.outcome.NoPosterior` (the calibration then writes its accounting and the
verdict "not credible", never a traceback).

Sequential rounds (``rounds = R > 1``; :mod:`analysis.calibration.npe_rounds`): round 1 runs the first N
draws of the one-round design (no held-out share); round r >= 2 runs N draws of the prior truncated to
round r - 1's estimator's region at the targets (all but ``truncation`` of its posterior mass there;
``[seed, Tag.NPE, ROUND_DESIGN, r]``; the last round N + H, its last H held out); round r's estimator is
trained on all rounds' N-shares so far (seed ``[.., ROUND_TRAIN, r]``; round 1 ``TRAIN``) and stored in
``estimator-round<r>`` (the last in ``estimator``) with its identity, so a calibration run again after an
interrupt re-uses finished rounds' runs and estimators (every design is deterministic given the seed).
The identity then holds the observed values (a truncated estimator serves these targets only) and
``truncation`` when it is not the default. The coverage check's held-out truths come from the last round's
truncated prior and its posteriors, like the draws at the targets, are restricted to that region:
coverage of the truncated problem, where TSNPE's posterior is valid.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.files import json_ready
from flocksweep.sweeps.progress import bar
from flocksweep.sweeps.seeds import NPEStream, Tag, generator

from .diagnostics import sbc_ranks
from .estimator_folder import COVERAGE_FILE, IDENTITY_FILE, DamagedEstimator, seal, set_aside, verify
from .learned_summary import learned_trainer, load_any as load_estimator
from .npe_flow import Estimator, FlowSettings, OutsideSupport, support_of, train_ensemble
from .npe_rounds import QUANTILE, truncated_prior_draws, truncation_region
from .outcome import NoPosterior
from .simulator import summary_simulator
from .training_runs import design_rows

LEVELS = (0.5, 0.9)
MAX_EXCLUDED = 0.05      # held-out simulations outside the estimator's support allowed before the check fails
COVERAGE_DRAWS = 199


def _stream(config, which: NPEStream, *more: int) -> np.random.Generator:
    return generator(config.seed, Tag.NPE, int(which), *more)


def _jax_seed(config, which: NPEStream, *more: int) -> int:
    return int(_stream(config, which, *more).integers(0, 2 ** 31 - 1))


def replicates(config) -> int:
    """Runs per training simulation: the number of observed rows (module docstring)."""
    return int(len(config.targets.observed))


def observed_row(config) -> np.ndarray:
    """(k,): the row the estimator is conditioned on: the mean of the observed rows (a learned summary: then
    each observed flock's raw inputs, :func:`analysis.calibration.learned_inputs.observed_raw`)."""
    row = np.asarray(config.targets.observed, dtype=float).mean(axis=0)
    if learned(config):
        from .learned_inputs import observed_raw

        return np.concatenate([row, observed_raw(config)])
    return row


def learned(config) -> bool:
    """Whether the estimator learns its own summary (``[method.npe.summary] kind = "learned"``)."""
    return config.method.summary.learned


def npe_simulator(config):
    """The calibration's simulator, ``replicates(config)`` runs per call, its target columns (a learned
    summary: each row followed by the run's raw inputs, :class:`~analysis.calibration.learned_inputs.
    LearnedSimulator`)."""
    if learned(config):
        from .learned_inputs import check_learned, learned_simulator

        check_learned(config)
        return learned_simulator(config)
    return summary_simulator(config, n_sim=replicates(config))


def transformed(config, rows: np.ndarray) -> np.ndarray:
    """Rows (m, k [+ raw]) with the statistics' transforms applied to their first k columns (the raw inputs
    of a learned summary are standardised by its embedding, not transformed)."""
    k = len(config.targets.columns)
    rows = np.atleast_2d(np.asarray(rows, dtype=float))
    return np.concatenate([config.transforms.apply(rows[:, :k], clip=True), rows[:, k:]], axis=1)


def training_design(config) -> np.ndarray:
    settings = config.method
    count = settings.simulations + settings.heldout
    return np.asarray(config.prior.sample(_stream(config, NPEStream.DESIGN), count), dtype=float).reshape(count, -1)


def measurement_settings(config) -> dict:
    """How the observed statistics are measured (module docstring)."""
    observation, m = config.observation, config.metrics
    if observation is not None:
        interval = float(observation.interval)
        velocity = observation.velocity_interval if observation.velocity_interval is not None else interval
        max_gap, dims = observation.max_gap, observation.dims
    else:
        interval = float(config.record_interval)
        velocity, max_gap, dims = "recorded", None, config.dims
    return json_ready({"interval": interval, "velocity_interval": velocity, "max_gap": max_gap, "dims": int(dims),
                       "length_unit": "BL", "group_radius": m.group_radius,
                       "fragmentation_cohesion": m.fragmentation_cohesion, "dcd_max_delay": m.dcd_max_delay,
                       "warmup": float(getattr(config.targets, "tracks_warmup", 0.0))})


def noise_covariance(config) -> np.ndarray | None:
    """The measurement covariance of the conditioning row: the targets' cov / m, or None."""
    cov = config.targets.cov
    return None if cov is None else np.asarray(cov, dtype=float) / replicates(config)


def _with_noise(config, rows: np.ndarray, noise: np.random.Generator) -> np.ndarray:
    cov = noise_covariance(config)
    if cov is None:
        return rows
    added = noise.multivariate_normal(np.zeros(len(cov)), cov, size=len(rows))
    if rows.shape[1] == len(cov):
        return rows + added
    return np.concatenate([rows[:, :len(cov)] + added, rows[:, len(cov):]], axis=1)   # a learned summary's raw inputs


def flow_settings(config) -> FlowSettings:
    return config.method.flow


def estimator_identity(config) -> dict:
    settings = config.method
    return json_ready({"simulator": npe_simulator(config).identity(), "measurement": measurement_settings(config),
                       "parameters": [[p.name, p.key] for p in config.parameters], "prior": repr(config.prior),
                       "bounds": [list(b) for b in config.prior.bounds],
                       "columns": list(config.targets.columns), "transforms": config.transforms.record(),
                       "observation_cov": None if config.targets.cov is None else np.asarray(config.targets.cov).tolist(),
                       "replicates": replicates(config),
                       "seed": int(config.seed), "simulations": settings.simulations, "heldout": settings.heldout,
                       "flow": asdict(flow_settings(config)),
                       **({"summary": {key: value for key, value in asdict(settings.summary).items()
                                       if key != "observed_seed"}} if learned(config) else {}),   # not the observed
                       **({"ensemble": settings.ensemble} if settings.ensemble > 1 else {}),
                       **({"rounds": settings.rounds, "observed": observed_row(config).tolist()}
                          if settings.rounds > 1 else {}),
                       **({"truncation": settings.truncation}
                          if settings.rounds > 1 and settings.truncation != QUANTILE else {})})


def digest(identity: dict) -> str:
    return hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()[:16]


def stored_identity(folder: Path) -> dict | None:
    path = Path(folder) / IDENTITY_FILE
    try:
        return json.loads(path.read_text()) if path.is_file() else None
    except (OSError, ValueError):
        return None


def coverage_check(estimator: Estimator, theta, x, draws: int, seed: int, support, tolerance: float,
                   names) -> dict:
    """Expected coverage and SBC ranks on held-out simulations (module docstring)."""
    theta, x = np.asarray(theta, dtype=float), np.asarray(x, dtype=float)
    samples = estimator.sample_many(x, draws, seed, support, short="nan")
    kept = ~np.isnan(samples).any(axis=(1, 2))
    excluded = int((~kept).sum())
    theta, samples = theta[kept], samples[kept]
    rows = []
    held = len(theta)
    for level in LEVELS:
        low = np.quantile(samples, (1 - level) / 2, axis=1)
        high = np.quantile(samples, (1 + level) / 2, axis=1)
        inside = (theta >= low) & (theta <= high)
        allowed = max(tolerance, 2.58 * np.sqrt(level * (1 - level) / max(held, 1)))
        for j, name in enumerate(names):
            coverage = float(inside[:, j].mean()) if held else float("nan")
            rows.append({"parameter": name, "level": level, "coverage": coverage, "allowed": float(allowed),
                         "ok": bool(held and abs(coverage - level) <= allowed)})
    table = pd.DataFrame(rows)
    ranks = sbc_ranks(theta, list(samples), np.random.default_rng(seed)) if held else np.zeros((0, len(names)))
    messages = [f"{r.parameter}: {r.level:.0%} intervals cover {r.coverage:.1%} of {held} held-out truths "
                f"(allowed {r.level:.0%} +- {r.allowed:.1%})" for r in table.itertuples() if not r.ok]
    too_many = excluded > MAX_EXCLUDED * (held + excluded)
    passed = bool(table["ok"].all()) and not too_many
    if passed:
        messages = [f"coverage: the 50% and 90% intervals cover their share of {held} held-out truths "
                    f"(within {table['allowed'].max():.1%})"]
    else:
        messages.insert(0, "coverage FAILED: the estimator's intervals do not cover their share of held-out "
                           "truths; do not trust its posterior (more simulations, another flow)")
    if excluded:
        messages.append(f"{excluded} of {held + excluded} held-out simulations were left out of the check: the "
                        "estimator puts almost no mass inside the prior at their statistics (far from the training "
                        f"set){'; more than ' + format(MAX_EXCLUDED, '.0%') + ' of them fails the check' if too_many else ''}")
    return {"table": table, "ranks": ranks, "draws": int(draws), "heldout": held, "excluded": excluded,
            "passed": passed, "messages": messages}


@dataclass
class NpeResult:
    estimator: Estimator
    draws: np.ndarray            # (S, d) at the targets
    coverage: dict
    info: dict                   # convergence.json's "npe" entry


@dataclass
class _Design:
    """One design's runs: parameters, rows (transformed, with noise; NaN where unusable), and what failed."""

    theta: np.ndarray
    x: np.ndarray
    failed: dict = field(default_factory=dict)
    reused_runs: int = 0          # runs found stored, not simulated again

    def usable(self, part: slice) -> tuple[np.ndarray, np.ndarray]:
        keep = np.isfinite(self.x[part]).all(axis=1)
        return self.theta[part][keep], self.x[part][keep]


def _run_design(config, theta, keys, folder, training: tuple, phases, cost, trained: int, noise, label: str = "",
                heldout_only: bool = False) -> _Design:
    """Run (only the missing rows of) the design ``theta``; the first ``trained`` rows' new runs count as
    training, the rest as held out (``heldout_only``: the training rows are not needed, a reused
    estimator's)."""
    pool, description = training
    held = len(theta) - trained
    per = f" simulations of {replicates(config)} runs each" if replicates(config) > 1 else ""
    wanted = slice(trained, None) if heldout_only else slice(None)
    what = f"the {held} held-out simulations" if heldout_only else (
        f"the training simulations{label}: {len(theta)}{per} ({trained} for training"
        f"{f', {held} held out' if held else ''})")
    phases.start(f"{what}, only those not stored yet, {description}")
    with bar(len(theta[wanted]), f"{config.name}: training", "sim", phases.enabled) as shown:
        result = design_rows(npe_simulator(config), theta, keys, folder, pool, shown.update,
                             subset=np.arange(len(theta))[wanted], label=label.strip().replace("of ", "") or "training")
    new = result.new
    cost.add("training", int(new[:trained].sum()) * replicates(config))
    cost.add("heldout", int(new[trained:].sum()) * replicates(config))
    rows = transformed(config, _with_noise(config, result.rows, noise))
    outside = ~np.isfinite(rows).all(axis=1) & result.usable
    failed = dict(result.failed)
    for i in np.flatnonzero(outside):
        failed[int(i)] = "statistics outside the range their transform is defined on"
    return _Design(theta, rows, failed, result.reused * replicates(config))


def _fit(config, theta, rows, seed: int, phases, label: str = ""):
    settings = config.method
    if len(theta) < 20:
        raise ConfigError("method.simulations", f"only {len(theta)} training runs gave finite statistics; choose "
                                                "statistics every run has")
    flows = f"{settings.ensemble} flows" if settings.ensemble > 1 else "the flow"
    phases.start(f"training {flows}{label} on {len(theta)} simulations (at most "
                 f"{flow_settings(config).max_epochs} epochs each)")
    trainer = None
    if learned(config):
        from .learned_inputs import layout, max_individuals

        trainer = learned_trainer(settings.summary, layout(settings.summary, max_individuals(config)),
                                  replicates(config))
    return train_ensemble(theta, rows, flow_settings(config), seed, settings.ensemble, progress=phases.enabled,
                          trainer=trainer)


def _keys(config, n: int, r: int = 1) -> list[tuple]:
    if r == 1:
        return [(config.seed, Tag.NPE, int(NPEStream.RUNS), i) for i in range(n)]
    return [(config.seed, Tag.NPE, int(NPEStream.ROUND_RUNS), r, i) for i in range(n)]


def _with_training_pool(pool: Executor, executor: tuple, work):
    """``work((pool, description))`` on the calibration's pool, or on a local process pool when the
    calibration runs in this process (one run at a time would leave cores idle)."""
    if not pool.in_process:
        return work((pool, pool.description))
    kind, workers, scheduler = executor
    with Executor("local" if kind == "serial" else kind, workers, scheduler) as fresh:
        return work((fresh, fresh.description))


def _failure_info(failed: dict) -> dict:
    reasons = {}
    for reason in failed.values():
        reasons[reason] = reasons.get(reason, 0) + 1
    return {"failed_runs": len(failed),
            "failure_reasons": [{"reason": r, "runs": n} for r, n in sorted(reasons.items(), key=lambda x: -x[1])][:5]}


def run_npe(config, folder, pool: Executor, executor: tuple, phases, cost) -> NpeResult:
    """Train or reuse the estimator, check its coverage, draw the posterior at the targets; ``phases``
    (:class:`sweeps.progress.Phases`) shows each step on stderr."""
    settings = config.method
    if learned(config):
        observed_row(config)     # the observed flock's raw inputs measured (or refused) before any training run
    if settings.rounds > 1:
        return _with_training_pool(pool, executor, lambda training: _run_rounds(config, folder, training, phases,
                                                                                 cost))
    estimator, heldout, info, where = trained_estimator(config, folder, pool, executor, phases, cost)
    return _checked_posterior(config, estimator, *heldout, support_of(config.prior), phases, info, where)


def trained_estimator(config, folder, pool: Executor, executor: tuple, phases, cost):
    """The one-round estimator of ``config``, trained into ``<folder>/estimator`` (or ``method.estimator``)
    or reused when its identity matches; ``(estimator, (held-out theta, held-out x), info, where)``.
    Used by :func:`run_npe` and by SBC (:mod:`analysis.calibration.sbc_npe`)."""
    settings = config.method
    identity = estimator_identity(config)
    where = Path(settings.estimator) if settings.estimator is not None else folder.path("estimator")
    found = stored_identity(where)
    reused = found == identity
    if settings.estimator is not None and not reused:
        raise ConfigError("method.estimator", f"{where} holds no estimator trained for this calibration "
                                              f"({'no ' + IDENTITY_FILE if found is None else 'its identity differs'}"
                                              "; the model, observation, parameters, priors, statistics, their "
                                              "transforms and sd, seed and flow settings must all be the same)")
    n = settings.simulations
    theta = training_design(config)
    runs_folder = (where.parent if settings.estimator is not None else folder.root) / "training"

    def simulate(training):
        return _run_design(config, theta, _keys(config, len(theta)), runs_folder, training, phases, cost, n,
                           _stream(config, NPEStream.NOISE), heldout_only=reused)

    if reused:
        reused = _trusted(folder, where, external=settings.estimator is not None)
    if reused:
        design = _with_training_pool(pool, executor, simulate)   # the held-out runs, found stored as a rule
        estimator = load_estimator(where)
        phases.start(f"reusing the trained estimator in {where} (no training)")
    else:
        design = _with_training_pool(pool, executor, simulate)
        estimator = _fit(config, *design.usable(slice(0, n)), _jax_seed(config, NPEStream.TRAIN), phases)
        _store(config, folder, where, estimator, identity)
    heldout = design.usable(slice(n, None))
    info = {"estimator": str(where), "identity": digest(identity), "reused": bool(reused),
            "training_simulations": n, "replicates": replicates(config), "runs_found": design.reused_runs,
            **_failure_info(design.failed)}
    return estimator, heldout, info, where


def _trusted(folder, where: Path, external: bool) -> bool:
    """Whether the estimator folder ``where``, trained for this calibration, passes its checksums
    (:func:`analysis.calibration.estimator_folder.verify`). One of the calibration's own that does not is
    moved to ``quarantine/`` (a warning) and trained again; a ``method.estimator`` folder is refused."""
    try:
        verify(where)
        return True
    except DamagedEstimator as err:
        if external:
            raise ConfigError("method.estimator", str(err)) from None
        set_aside(folder.root, where, f"cannot be trusted ({str(err).split('; train it again')[0]}); an estimator is "
                                      "trained in its place")
        return False


def _store(config, folder, where: Path, estimator, identity: dict) -> None:
    """The trained estimator and its identity in ``where`` (an older folder there moved to quarantine/ first,
    so the new one is sealed whole), then its manifest."""
    if Path(where).exists() and any(Path(where).iterdir()):
        set_aside(folder.root, where, "was trained for other settings (or its writing was cut short); a new "
                                      "estimator is trained in its place")
    estimator.save(where)
    _write_json(folder, where, IDENTITY_FILE, identity)
    seal(where, calibration=str(config.source_path) if config.source_path else None, out=str(folder.root))


def _write_json(folder, where: Path, name: str, data: dict) -> None:
    try:
        relative = Path(where).relative_to(folder.root)
    except ValueError:    # an estimator kept elsewhere (method.estimator): written beside it
        from flocksweep.sweeps.files import atomic_path

        with atomic_path(Path(where) / name) as tmp:
            Path(tmp).write_text(json.dumps(json_ready(data), indent=1))
        return
    folder.write_json(str(relative / name), data)


def _checked_posterior(config, estimator, heldout_theta, heldout_x, support, phases, info: dict,
                       where: Path | None = None, folder=None) -> NpeResult:
    """The coverage check on the held-out simulations and the posterior draws at the targets, both
    restricted to ``support``; the check's verdict stored beside the estimator."""
    settings = config.method
    phases.start(f"the coverage check on {len(heldout_theta)} held-out simulations ({COVERAGE_DRAWS} posterior "
                 "draws each)")
    check = coverage_check(estimator, heldout_theta, heldout_x, draws=COVERAGE_DRAWS,
                           seed=_jax_seed(config, NPEStream.COVERAGE), support=support,
                           tolerance=settings.coverage_tolerance, names=config.names)
    if where is not None and Path(where).is_dir():
        verdict = {"passed": check["passed"], "heldout": check["heldout"], "excluded": check["excluded"],
                   "messages": check["messages"], "table": check["table"].to_dict("records")}
        from flocksweep.sweeps.files import atomic_path

        with atomic_path(Path(where) / COVERAGE_FILE) as tmp:
            Path(tmp).write_text(json.dumps(json_ready(verdict), indent=1))
        seal(where, [COVERAGE_FILE])
    observed = transformed(config, observed_row(config)[None, :])[0]
    try:
        if not np.isfinite(observed).all():
            raise OutsideSupport("the observed statistics lie outside the range their transforms are defined on")
        draws = estimator.sample(observed, settings.draws, _jax_seed(config, NPEStream.POSTERIOR), support)
    except OutsideSupport as err:
        raise NoPosterior(f"the estimator gives no posterior at the observed statistics: {err}; the observed flock "
                          "lies outside what the training simulations cover: widen the priors, check the model "
                          "and the statistics (flocksweep targets CALIB --from-tracks shows them)",
                          {"npe": {**info, "coverage": {"passed": check["passed"],
                                                        "table": check["table"].to_dict("records")}}}) from None
    info = {**info, "heldout_simulations": int(len(heldout_theta)), "heldout_excluded": check["excluded"],
            "leakage": estimator.last_leakage, "flow": estimator.record(),
            "coverage": {"passed": check["passed"], "table": check["table"].to_dict("records")}}
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
    if stored_identity(where) == identity and _trusted(folder, where, external=False):
        phases.start(f"reusing round {r}'s trained estimator in {where}")
        return load_estimator(where), where, True
    seed = _jax_seed(config, NPEStream.TRAIN) if r == 1 else _jax_seed(config, NPEStream.ROUND_TRAIN, r)
    estimator = _fit(config, theta, rows, seed, phases, label)
    _store(config, folder, where, estimator, identity)
    return estimator, where, False


def _run_rounds(config, folder, training: tuple, phases, cost) -> NpeResult:
    """Truncated sequential rounds (analysis.calibration.npe_rounds; docs/calibration.md): every round's
    runs in ``training/``, its estimator in ``estimator-round<r>`` (the last in ``estimator``); the coverage
    check and the posterior inside the last round's region."""
    settings = config.method
    identity = estimator_identity(config)
    observed = config.transforms.apply(observed_row(config)[None, :], clip=True)[0]
    inside_prior = support_of(config.prior)
    n, region, thetas, rows, rounds, failed, found = settings.simulations, None, [], [], [], {}, 0
    for r in range(1, settings.rounds + 1):
        label = f" of round {r}/{settings.rounds}"
        theta, accepted = _round_design(config, r, region)
        noise = _stream(config, NPEStream.NOISE) if r == 1 else _stream(config, NPEStream.ROUND_NOISE, r)
        design = _run_design(config, theta, _keys(config, len(theta), r), folder.path("training"), training, phases,
                             cost, n, noise, label)
        failed.update({(r, i): reason for i, reason in design.failed.items()})
        found += design.reused_runs
        kept_theta, kept_x = design.usable(slice(0, n))
        thetas.append(kept_theta)
        rows.append(kept_x)
        round_identity = identity if r == settings.rounds else {**identity, "rounds": "sequential", "round": r}
        estimator, where, reused = _round_estimator(config, folder, r, round_identity, np.concatenate(thetas),
                                                    np.concatenate(rows), phases, label)
        rounds.append({"round": r, "simulations": n, "prior_mass": accepted, "estimator_reused": reused,
                       **({"threshold": region.threshold, "truncation": settings.truncation}
                          if region is not None else {})})
        if r < settings.rounds:
            if not np.isfinite(observed).all():
                raise NoPosterior("the observed statistics lie outside the range their transforms are defined on",
                                  {"npe": {"rounds": rounds}})
            try:
                region = truncation_region(estimator, observed, inside_prior,
                                           _jax_seed(config, NPEStream.ROUND_REGION, r + 1), settings.truncation)
            except OutsideSupport as err:
                raise NoPosterior(f"round {r}'s estimator gives no posterior at the observed statistics ({err}): the "
                                  "observed flock lies outside what the training simulations cover",
                                  {"npe": {"rounds": rounds}}) from None
    info = {"estimator": str(where), "identity": digest(identity), "reused": bool(reused),
            "training_simulations": n * settings.rounds, "replicates": replicates(config), "runs_found": found,
            **_failure_info(failed),
            "rounds": rounds}
    return _checked_posterior(config, estimator, *design.usable(slice(n, None)), region.contains, phases, info,
                              where)
