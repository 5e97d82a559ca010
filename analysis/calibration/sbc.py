"""Simulation-based calibration (SBC; Talts et al. 2018, arXiv:1804.06788) of the BSL posterior.

SBC checks the whole inference pipeline (simulator, synthetic likelihood, MCMC, burn-in, thinning): if
``theta ~ prior``, ``y ~ p(y | theta)`` and ``theta_1..theta_S`` are draws of the posterior computed
from ``y``, then the rank of ``theta`` among the ``theta_s`` (the number of draws below it, 0..S) is
uniformly distributed on 0..S for every parameter. Non-uniform ranks mean miscalibration: a U shape an
overconfident posterior, a hump an overdispersed one, a slope a biased one.

Contract
--------
``run_sbc(config, datasets=50, draws=49, out_dir=None, progress=True, *, steps=None, walkers=None,
bins=None, workers=1, order=None, resume=True, alpha=0.05) -> dict``

* ``config`` is a :class:`~analysis.calibration.config.CalibrationConfig` with method ``emcee`` (or an
  :class:`SBCProblem`, e.g. a cheap toy model in tests). ``steps`` / ``walkers`` override the config's.
* For dataset ``j = 0..datasets-1``, every random number comes from ``(config.seed, j)`` only, through
  ``SeedSequence([seed, SBC_TAG, j, stream])``:
    - stream 0: ``theta_j = prior.sample(rng, 1)[0]``, shape (d,);
    - stream 1: the observed data ``y_j``, shape (m, k) (m = rows of the config's targets, 1 for
      mean/sd targets), from the SAME data model the likelihood assumes: the summary simulator plus,
      for mean/sd (or cov) targets, Gaussian observation noise with the targets' covariance
      (:func:`analysis.calibration.run.simulate_fn` on a one-replicate-per-row simulator);
    - stream 2: the integer ``seed`` given to :func:`~analysis.calibration.bsl.run_bsl` (observed=y_j,
      the config's walkers, steps, n_sim, likelihood, reevaluate_every);
    - stream 3: which thinned posterior draws are kept; stream 4: tie-breaking in the ranks.
  A dataset's result therefore does not depend on the order datasets are processed in, on other
  datasets, on the number of worker processes or on being resumed.
* Posterior draws (:func:`posterior_draws`): burn-in is the first HALF of the chain; the integrated
  autocorrelation time ``tau`` (largest over parameters, estimated on the kept half) sets the thinning
  ``thin = ceil(tau)``; ``draws`` = S of the thinned rows x walkers are picked without replacement.
  When fewer than S thinned draws exist the thinning is reduced until S exist and the dataset is
  flagged ``short`` (its draws are autocorrelated; too many short datasets mean the chains are too
  short for SBC).
* Storage in ``out_dir`` (default ``results/calibration/<name>/sbc``): ``settings.json`` (everything
  the results depend on; a resume with other settings is refused, except a larger ``datasets``),
  ``datasets/<j:06d>.json`` per dataset, written atomically when that dataset is done (theta, y,
  ranks, posterior draws, tau, thinning, acceptance, wall time), so an interrupted run resumes where it
  stopped (``resume=False`` refuses an existing folder with results). When all datasets are done:
  ``ranks.csv`` (one row per dataset), ``uniformity.csv`` and ``uniformity.md`` (chi-square test per
  parameter from :func:`~analysis.calibration.diagnostics.sbc_uniformity`, plus the ECDF band test),
  ``rank_histogram.png`` (:func:`~analysis.calibration.plots.sbc_figure`), ``ecdf_diff.png`` (ECDF
  of the fractional ranks minus the uniform CDF with a simultaneous band) and ``summary.json``.
* Two uniformity tests per parameter: the chi-square test of the binned rank histogram
  (:func:`~analysis.calibration.diagnostics.sbc_uniformity`, ``bins`` default :func:`default_bins`)
  and the ECDF test (Saeilynoja et al. 2022), whose p-value is the probability, under uniform ranks, of
  a rank ECDF whose most extreme point-wise binomial tail probability is as small as the observed one
  (more powerful against U and hump shapes than a coarse histogram). Verdict: no significant
  miscalibration when every p-value is at least ``alpha / (2 d)`` (Bonferroni over both tests and the
  d parameters).
* ``workers > 1`` runs datasets in that many "spawn" worker processes (each builds the simulators
  from the config once; an :class:`SBCProblem` must then be picklable). As with any spawn pool, a
  script calling it needs the ``if __name__ == "__main__":`` guard. Results are the same as with 1.
* ``write_report(out, names, datasets, draws, bins=None, alpha=0.05, seed=0, columns=None)`` rebuilds
  the tables and figures from the stored datasets alone (run_sbc calls it at the end).
* Return value: ``{"out", "table" (DataFrame, index parameter: chi2, dof, p, n, bins, ecdf_p),
  "ranks" (DataFrame), "calibrated" (bool), "verdict" (sentence), "paths" (name -> Path), "wall_s"}``.

Array shapes: theta (d,), y (m, k), posterior draws (S, d), ranks (L, d) for L datasets; ranks are
integers in 0..S. Nothing runs at import; matplotlib, emcee and tqdm are imported inside functions.
"""
from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from .diagnostics import integrated_times, sbc_ranks, sbc_uniformity

SBC_TAG = 0x5BC
STREAM_THETA, STREAM_OBSERVED, STREAM_BSL, STREAM_SELECT, STREAM_TIES = range(5)
BAND_TRIALS = 4000          # uniform rank sets simulated for the ECDF band and test
MIN_EXPECTED_PER_BIN = 5    # default bins keep at least this many expected ranks per bin


@dataclasses.dataclass(frozen=True)
class SBCProblem:
    """Everything SBC needs: prior, the likelihood's simulator, the data model and the BSL settings.

    ``simulate_fn(theta, rng) -> (n_sim, k)`` is what the synthetic likelihood fits (as in run_bsl);
    ``observe_fn(theta, rng) -> (m, k)`` draws one observed dataset from the generative model. For a
    calibrated posterior both must describe the same model. ``meta`` (JSON-ready) identifies the
    problem in ``settings.json``."""

    prior: object
    simulate_fn: Callable
    observe_fn: Callable
    names: tuple[str, ...]
    columns: tuple[str, ...]
    seed: int
    walkers: int
    steps: int
    likelihood: str = "gaussian"
    reevaluate_every: int = 0
    moves: str = "stretch"
    meta: dict = dataclasses.field(default_factory=dict, compare=False)

    @property
    def dim(self) -> int:
        return len(self.names)


# ------------------------------------------------------------------------------------------ the problem

def problem_from_config(config, steps: int | None = None, walkers: int | None = None) -> SBCProblem:
    """The SBC problem of an emcee calibration config (optionally with other steps / walkers)."""
    from .run import simulate_fn, summary_simulator
    from .simulator import SummarySimulator

    if config.method.kind != "emcee":
        raise ValueError(f"SBC runs the emcee (BSL) method; this config's method is {config.method.kind!r}")
    settings = config.method.settings
    rows = int(np.asarray(config.targets.observed).shape[0])
    observer = SummarySimulator(config.preset_data, config.keys, config.targets.columns, rows, config.warmup)
    meta = {"name": config.name, "n_sim": int(settings["n_sim"]), "observed_rows": rows,
            "config": _plain(config.source), "preset_sha256": _digest(config.preset_data)}
    return SBCProblem(prior=config.prior, simulate_fn=simulate_fn(config, summary_simulator(config)),
                      observe_fn=simulate_fn(config, observer), names=tuple(config.names),
                      columns=tuple(config.targets.columns), seed=int(config.seed),
                      walkers=int(walkers if walkers is not None else settings["walkers"]),
                      steps=int(steps if steps is not None else settings["steps"]),
                      likelihood=settings["likelihood"], reevaluate_every=int(settings["reevaluate_every"]),
                      moves=settings.get("moves", "stretch"), meta=meta)


def _as_problem(source, steps=None, walkers=None) -> SBCProblem:
    if isinstance(source, SBCProblem):
        changes = {k: int(v) for k, v in (("steps", steps), ("walkers", walkers)) if v is not None}
        return dataclasses.replace(source, **changes) if changes else source
    return problem_from_config(source, steps=steps, walkers=walkers)


# ---------------------------------------------------------------------------------------------- seeds

def stream(seed: int, j: int, which: int) -> np.random.SeedSequence:
    """The seed sequence of stream ``which`` of dataset ``j`` (see the module docstring)."""
    return np.random.SeedSequence([int(seed), SBC_TAG, int(j), int(which)])


def generator(seed: int, j: int, which: int) -> np.random.Generator:
    return np.random.Generator(np.random.PCG64(stream(seed, j, which)))


def bsl_seed(seed: int, j: int) -> int:
    """The integer seed of dataset ``j``'s BSL run, in [0, 2**63)."""
    word = stream(seed, j, STREAM_BSL).generate_state(1, np.uint64)[0]
    return int(word >> np.uint64(1))


# ------------------------------------------------------------------------------------------ one dataset

def draw_theta(problem: SBCProblem, j: int) -> np.ndarray:
    """theta_j ~ prior, shape (d,)."""
    return np.asarray(problem.prior.sample(generator(problem.seed, j, STREAM_THETA), 1), dtype=float)[0]


def draw_observed(problem: SBCProblem, theta, j: int) -> np.ndarray:
    """y_j ~ p(y | theta_j), shape (m, k)."""
    y = np.asarray(problem.observe_fn(np.asarray(theta, dtype=float), generator(problem.seed, j,
                                                                                STREAM_OBSERVED)), dtype=float)
    return y[None, :] if y.ndim == 1 else y


def thinning(chain: np.ndarray, draws: int) -> dict:
    """Burn-in (half the chain), tau of the kept half (max over parameters) and the thinning that
    leaves at least ``draws`` draws: ``ceil(tau)``, reduced (``short``) when that leaves too few."""
    steps, walkers, _ = chain.shape
    burn = steps // 2
    kept = steps - burn
    tau = integrated_times(chain[burn:]) if kept >= 2 else np.full(chain.shape[2], np.nan)
    finite = tau[np.isfinite(tau)]
    tau_max = float(finite.max()) if finite.size else math.nan
    thin = max(1, math.ceil(tau_max)) if math.isfinite(tau_max) else 1
    rows_needed = math.ceil(draws / walkers)
    if kept < rows_needed:
        raise ValueError(f"{kept} steps after burn-in x {walkers} walkers cannot give {draws} draws; "
                         f"run at least {2 * rows_needed} steps")
    short = math.ceil(kept / thin) < rows_needed
    if short:
        thin = max(1, kept // rows_needed)
    return {"burn": burn, "tau": [float(t) for t in tau], "tau_max": tau_max, "thin": thin, "short": short,
            "pool": int(math.ceil(kept / thin) * walkers)}


def posterior_draws(chain, draws: int, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """``draws`` roughly independent posterior draws (S, d) from an emcee chain (steps, walkers, d),
    with the burn-in / thinning record of :func:`thinning`."""
    chain = np.asarray(chain, dtype=float)
    info = thinning(chain, draws)
    pool = chain[info["burn"]::info["thin"]].reshape(-1, chain.shape[2])
    pick = np.sort(rng.choice(len(pool), size=draws, replace=False))
    return pool[pick], info


def sbc_dataset(problem: SBCProblem, j: int, draws: int) -> dict:
    """Run SBC dataset ``j``: theta, y, BSL posterior, ranks. A JSON-ready record."""
    from .bsl import run_bsl

    started = time.time()
    theta = draw_theta(problem, j)
    y = draw_observed(problem, theta, j)
    result = run_bsl(problem.simulate_fn, y, problem.prior, walkers=problem.walkers, steps=problem.steps,
                     seed=bsl_seed(problem.seed, j), likelihood=problem.likelihood,
                     reevaluate_every=problem.reevaluate_every, moves=problem.moves)
    sample, info = posterior_draws(result.chain, draws, generator(problem.seed, j, STREAM_SELECT))
    ranks = sbc_ranks(theta[None, :], [sample], rng=generator(problem.seed, j, STREAM_TIES))[0]
    return {"dataset": int(j), "theta": theta.tolist(), "observed": y.tolist(), "ranks": ranks.tolist(),
            "draws": sample.tolist(), "post_mean": sample.mean(axis=0).tolist(),
            "post_sd": sample.std(axis=0, ddof=1).tolist(), "acceptance": float(result.acceptance_fraction.mean()),
            "steps": int(result.chain.shape[0]), "walkers": int(result.chain.shape[1]), "bsl_seed":
            bsl_seed(problem.seed, j), **info, "wall_s": time.time() - started}


# -------------------------------------------------------------------------------------------- storage

def settings_record(problem: SBCProblem, draws: int) -> dict:
    """What the per-dataset results depend on (compared on resume)."""
    moves = {} if problem.moves == "stretch" else {"moves": problem.moves}   # records before moves: stretch
    return _plain({**moves, "method": "sbc", "seed": problem.seed, "draws": int(draws), "names": list(problem.names),
                   "columns": list(problem.columns), "walkers": problem.walkers, "steps": problem.steps,
                   "likelihood": problem.likelihood, "reevaluate_every": problem.reevaluate_every,
                   "burn": "first half of the chain", "thin": "ceil(max tau of the kept half)",
                   "problem": problem.meta})


def dataset_path(out: Path, j: int) -> Path:
    return Path(out) / "datasets" / f"{int(j):06d}.json"


def load_record(out: Path, j: int) -> dict | None:
    path = dataset_path(out, j)
    return json.loads(path.read_text()) if path.exists() else None


def _prepare_out(out: Path, settings: dict, resume: bool) -> None:
    from sweeps.atomic import write_json

    path = out / "settings.json"
    if path.exists():
        stored = json.loads(path.read_text())
        if stored != settings:
            diff = sorted(k for k in set(stored) | set(settings) if stored.get(k) != settings.get(k))
            raise ValueError(f"{path} was written with other settings ({', '.join(diff)} differ); "
                             "use another out_dir or remove it")
        if not resume and any((out / "datasets").glob("*.json")):
            raise FileExistsError(f"{out} holds SBC results; pass resume=True to continue, or remove it")
    out.mkdir(parents=True, exist_ok=True)
    write_json(path, settings)


def _save_record(out: Path, record: dict) -> None:
    from sweeps.atomic import write_json

    write_json(dataset_path(out, record["dataset"]), _plain(record))


# -------------------------------------------------------------------------------------------- running

_WORKER: dict = {}


def _worker_init(source, steps, walkers, threads) -> None:
    """Worker process: build the problem once (simulators are not picklable) and limit numba threads."""
    try:
        import numba
        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    except Exception:  # noqa: BLE001 - only a performance setting
        pass
    _WORKER["problem"] = _as_problem(source, steps, walkers)


def _worker_dataset(j: int, draws: int) -> dict:
    return sbc_dataset(_WORKER["problem"], j, draws)


def _bar(total: int, done: int, name: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=done, desc=f"SBC {name}", unit="dataset", smoothing=0.1)


def _tick(bar, record: dict) -> None:
    if bar is not None:
        bar.update(1)
        bar.set_postfix(tau=f"{record['tau_max']:.1f}", acc=f"{record['acceptance']:.2f}",
                        s=f"{record['wall_s']:.0f}", refresh=False)


def _run_missing(source, problem: SBCProblem, todo: list[int], draws: int, out: Path, workers: int,
                 bar, steps, walkers) -> None:
    if workers <= 1:
        for j in todo:
            record = sbc_dataset(problem, j, draws)
            _save_record(out, record)
            _tick(bar, record)
        return
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor, as_completed

    threads = max(1, (os.cpu_count() or 1) // workers)
    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_worker_init,
                               initargs=(source, steps, walkers, threads))
    try:
        futures = [pool.submit(_worker_dataset, j, draws) for j in todo]
        for future in as_completed(futures):
            record = future.result()
            _save_record(out, record)
            _tick(bar, record)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)   # finished datasets are saved; stop the rest
        raise
    pool.shutdown()


def default_bins(draws: int, datasets: int) -> int:
    """The largest divisor of S + 1 that is at most 20 and keeps >= 5 expected ranks per bin."""
    cap = max(1, min(20, datasets // MIN_EXPECTED_PER_BIN))
    return max(b for b in range(1, cap + 1) if (draws + 1) % b == 0)


def run_sbc(config, datasets: int = 50, draws: int = 49, out_dir=None, progress: bool = True, *,
            steps: int | None = None, walkers: int | None = None, bins: int | None = None,
            workers: int = 1, order: Sequence[int] | None = None, resume: bool = True,
            alpha: float = 0.05) -> dict:
    """Simulation-based calibration of the config's BSL posterior; see the module docstring."""
    problem = _as_problem(config, steps, walkers)
    datasets, draws, workers = _count(datasets, "datasets", 1), _count(draws, "draws", 1), _count(workers,
                                                                                                  "workers", 1)
    if out_dir is None:
        if isinstance(config, SBCProblem):
            raise ValueError("out_dir is required when config is an SBCProblem")
        out_dir = Path("results") / "calibration" / config.name / "sbc"
    out = Path(out_dir)
    _prepare_out(out, settings_record(problem, draws), resume)
    order = list(range(datasets)) if order is None else [int(j) for j in order]
    if sorted(order) != list(range(datasets)):
        raise ValueError(f"order must be a permutation of 0..{datasets - 1}")
    todo = [j for j in order if not dataset_path(out, j).exists()]
    started = time.time()
    bar = _bar(datasets, datasets - len(todo), problem.meta.get("name", "problem"), progress)
    try:
        _run_missing(config, problem, todo, draws, out, workers, bar, steps, walkers)
    finally:
        if bar is not None:
            bar.close()
    result = write_report(out, problem.names, datasets, draws, bins=bins, alpha=alpha, seed=problem.seed,
                          columns=problem.columns)
    result["wall_s"] = time.time() - started
    return result


# -------------------------------------------------------------------------------------------- reports

def collect(out: Path, datasets: int) -> list[dict]:
    """The records of datasets 0..datasets-1 (FileNotFoundError naming the missing ones)."""
    records = [load_record(out, j) for j in range(datasets)]
    missing = [j for j, r in enumerate(records) if r is None]
    if missing:
        raise FileNotFoundError(f"{len(missing)} SBC datasets not done yet in {out}: {missing[:10]}...")
    return records


def ranks_frame(records: list[dict], names: Sequence[str], columns: Sequence[str] | None = None) -> pd.DataFrame:
    """One row per dataset: theta, rank, posterior mean and sd per parameter, the observed summaries
    (``y_<column>``, or ``y<i>_<column>`` for several observed rows), tau, thinning, acceptance."""
    rows = []
    for r in records:
        row = {"dataset": r["dataset"]}
        for i, name in enumerate(names):
            row.update({f"theta_{name}": r["theta"][i], f"rank_{name}": r["ranks"][i],
                        f"post_mean_{name}": r["post_mean"][i], f"post_sd_{name}": r["post_sd"][i]})
        observed = np.asarray(r["observed"], dtype=float)
        labels = columns or [str(c) for c in range(observed.shape[1])]
        for i, values in enumerate(observed):
            prefix = "y" if len(observed) == 1 else f"y{i}"
            row.update({f"{prefix}_{label}": value for label, value in zip(labels, values)})
        row.update({k: r[k] for k in ("tau_max", "thin", "short", "acceptance", "steps", "walkers", "wall_s")})
        rows.append(row)
    return pd.DataFrame(rows).set_index("dataset")


def ecdf_points(S: int) -> np.ndarray:
    """Fractional ranks z_m = (m + 1) / (S + 1), m = 0..S-1, where the rank ECDF is evaluated."""
    return np.arange(1, S + 1) / (S + 1)


def _ecdf_counts(ranks: np.ndarray, S: int) -> np.ndarray:
    """(..., S) counts of ranks <= m for m = 0..S-1; ``ranks`` (..., L)."""
    below = ranks[..., None] <= np.arange(S)
    return below.sum(axis=-2)


def _min_tail(counts: np.ndarray, L: int, z: np.ndarray) -> np.ndarray:
    """Smallest point-wise two-sided binomial tail probability over the evaluation points."""
    from scipy import stats

    low = stats.binom.cdf(counts, L, z)
    high = stats.binom.sf(counts - 1, L, z)
    return np.minimum(1.0, 2.0 * np.minimum(low, high)).min(axis=-1)


def ecdf_band(L: int, S: int, alpha: float, rng: np.random.Generator, trials: int = BAND_TRIALS):
    """Simultaneous (1 - alpha) band for the rank ECDF of L uniform ranks on 0..S (Saeilynoja et al.
    2022, simulation method). Returns z (S,), lower (S,), upper (S,) (ECDF values) and the simulated
    minimum tail probabilities (trials,) used by :func:`ecdf_test`."""
    from scipy import stats

    z = ecdf_points(S)
    sims = rng.integers(0, S + 1, size=(trials, L))
    gammas = _min_tail(_ecdf_counts(sims, S), L, z)
    gamma = float(np.quantile(gammas, alpha))
    lower = stats.binom.ppf(gamma / 2, L, z) / L
    upper = stats.binom.ppf(1 - gamma / 2, L, z) / L
    return z, lower, upper, gammas


def ecdf_test(ranks, S: int, gammas: np.ndarray) -> np.ndarray:
    """p-value per parameter: share of uniform rank sets whose ECDF is at least as extreme."""
    ranks = np.asarray(ranks)
    L = ranks.shape[0]
    observed = _min_tail(_ecdf_counts(ranks.T, S), L, ecdf_points(S))
    return np.array([(1 + np.sum(gammas <= g)) / (1 + gammas.size) for g in np.atleast_1d(observed)])


def ecdf_figure(ranks, S: int, names: Sequence[str], band, path, level: float = 0.95) -> Path:
    """ECDF of the fractional ranks minus the uniform CDF, one panel per parameter, with the ``level``
    simultaneous band ``band`` from :func:`ecdf_band`."""
    from .plots import _grid, _hide_unused, _pyplot, _save

    ranks = np.asarray(ranks)
    L, d = ranks.shape
    z, lower, upper, _ = band
    counts = _ecdf_counts(ranks.T, S) / L
    plt = _pyplot()
    nrows, ncols = _grid(d)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 2.8 * nrows), squeeze=False)
    flat = axes.ravel()
    for j, name in enumerate(names):
        ax = flat[j]
        ax.fill_between(z, lower - z, upper - z, step="post", color="0.85", label=f"{level:.0%} simultaneous band")
        ax.step(z, counts[j] - z, where="post", color="tab:blue", lw=1.5, label="ECDF - uniform")
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xlim(0, 1)
        ax.set_title(name, fontsize="medium")
        ax.set_xlabel(f"fractional rank (L = {L}, S = {S})")
    flat[0].legend(fontsize="small", loc="lower left")
    _hide_unused(flat, d)
    return _save(fig, path)


def _markdown(table: pd.DataFrame) -> str:
    cols = ["chi2", "dof", "p", "ecdf_p", "n", "bins"]
    lines = ["| parameter | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name, row in table.iterrows():
        cells = [f"{row['chi2']:.2f}", f"{int(row['dof'])}", f"{row['p']:.3f}", f"{row['ecdf_p']:.3f}",
                 f"{int(row['n'])}", f"{int(row['bins'])}"]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def verdict(table: pd.DataFrame, alpha: float) -> tuple[bool, str]:
    """Calibrated unless a chi-square or ECDF p-value is below alpha / (2 d) (Bonferroni over both tests
    and the d parameters, so the chance of a false alarm is at most alpha); not judged (False) when
    there are too few datasets for two histogram bins."""
    level = alpha / (2 * len(table))
    if not table["p"].notna().all():
        return False, (f"cannot judge: {int(table['n'].iloc[0])} datasets leave a single histogram bin; "
                       f"run at least {2 * MIN_EXPECTED_PER_BIN} datasets")
    bad = [name for name, row in table.iterrows() if not (row["p"] >= level and row["ecdf_p"] >= level)]
    pvals = "; ".join(f"{n}: chi-square p = {r['p']:.3f}, ECDF p = {r['ecdf_p']:.3f}" for n, r in table.iterrows())
    where = f"level {level:.3g} = {alpha} / (2 tests x {len(table)} parameters)"
    if bad:
        return False, f"significant miscalibration for {', '.join(bad)} at {where}; {pvals}"
    return True, f"no significant miscalibration at {where}; {pvals}"


def write_report(out, names: Sequence[str], datasets: int, draws: int, bins: int | None = None,
                 alpha: float = 0.05, seed: int = 0, columns: Sequence[str] | None = None) -> dict:
    """Ranks table, uniformity tests, figures and summary.json from the stored datasets 0..datasets-1."""
    from sweeps.atomic import atomic_path, write_json, write_text

    from .plots import sbc_figure

    out = Path(out)
    records = collect(out, datasets)
    frame = ranks_frame(records, names, columns)
    ranks = np.array([r["ranks"] for r in records], dtype=int)
    bins = default_bins(draws, datasets) if bins is None else int(bins)
    band = ecdf_band(datasets, draws, alpha, np.random.default_rng([int(seed), SBC_TAG, 0xECDF]))
    table = sbc_uniformity(ranks, draws, bins, names)
    table["ecdf_p"] = ecdf_test(ranks, draws, band[3])
    calibrated, sentence = verdict(table, alpha)
    paths = {"ranks": out / "ranks.csv", "uniformity": out / "uniformity.csv",
             "uniformity_md": out / "uniformity.md", "histogram": out / "rank_histogram.png",
             "ecdf": out / "ecdf_diff.png", "summary": out / "summary.json"}
    with atomic_path(paths["ranks"]) as tmp:
        frame.to_csv(tmp)
    with atomic_path(paths["uniformity"]) as tmp:
        table.to_csv(tmp)
    write_text(paths["uniformity_md"], _markdown(table))
    sbc_figure(ranks, draws, bins, names, paths["histogram"])
    ecdf_figure(ranks, draws, names, band, paths["ecdf"], level=1 - alpha)
    summary = {"datasets": datasets, "draws": draws, "bins": bins, "alpha": alpha, "calibrated": calibrated,
               "verdict": sentence, "table": table.reset_index().to_dict(orient="records"),
               "short_datasets": int(frame["short"].sum()), "tau_max_median": float(frame["tau_max"].median()),
               "tau_max_max": float(frame["tau_max"].max()), "acceptance_median":
               float(frame["acceptance"].median()), "dataset_wall_s_median": float(frame["wall_s"].median()),
               "dataset_wall_s_total": float(frame["wall_s"].sum())}
    write_json(paths["summary"], _plain(summary))
    return {"out": out, "table": table, "ranks": frame, "calibrated": calibrated, "verdict": sentence,
            "paths": paths}


# -------------------------------------------------------------------------------------------- helpers

def _count(value, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}: got {value!r}; must be an integer >= {minimum}")
    return int(value)


def _digest(data) -> str:
    """sha256 of a JSON-ready structure (sorted keys): detects a changed model preset on resume."""
    import hashlib

    return hashlib.sha256(json.dumps(_plain(data), sort_keys=True).encode()).hexdigest()


def _plain(value):
    """JSON-ready copy (numpy scalars and arrays to Python, paths to strings, nan to None)."""
    def default(o):
        return o.tolist() if hasattr(o, "tolist") else str(o)
    text = json.dumps(value, default=default)
    return json.loads(text, parse_constant=lambda c: None)
