"""A conditional normalising flow q(theta | x) trained on simulations: the neural posterior estimator of
the ``npe`` method (:mod:`analysis.calibration.npe`), on JAX through ``flowjax`` (the ``sbi`` extra:
``pip install -e '.[sbi]'``; docs/calibration.md says why JAX and not PyTorch).

Shapes: N training simulations, d parameters, k statistics, S draws.

Contract
--------
``FlowSettings(width, layers, knots, max_epochs, patience, learning_rate, batch_size, validation)``: the
architecture (a masked autoregressive flow of rational-quadratic splines, Durkan et al. 2019, on a
standard normal base) and its training (Adam, early stopping on a validation share).

``train_flow(theta (N, d), x (N, k), settings, seed, progress=False) -> Estimator``: theta is standardised by its
training mean and sd, x likewise (a statistic constant over the training set keeps sd 1), and the flow is
fitted by maximum likelihood of theta given x. A deterministic function of its inputs and ``seed`` on
CPU (tested bit for bit: float32, one thread of XLA's CPU reductions in order).

:class:`Estimator` (frozen): ``sample(x (k,), count, seed, support=None) -> (count, d)`` draws of the
posterior at one observed row; with ``support`` (a predicate on (S, d) -> (S,) bool, e.g. inside the
prior's bounds) the draws outside it are redrawn (the flow leaks mass outside a bounded prior; the
share is ``Estimator.last_leakage``, each row's ``last_row_leakage``; a row keeping under about 1/1,300 of its
draws is :class:`OutsideSupport`, a ValueError); ``sample_many(X (m, k), count, seed, support=None,
short="raise", rows=None) -> (m, count, d)`` one posterior per row, vectorised in compiled calls of
:func:`rows_per_call` rows (``short = "nan"``: a row that cannot be filled is all NaN instead, for the caller
to count and leave out; row i draws with the key ``fold_in(key(seed), rows[i])``, ``rows`` 0..m-1 by default,
so its draws are bit for bit the same alone or among any others) (an amortised estimator answers a new flock
without simulating); ``log_prob(theta, x)``; ``save(folder)`` / :func:`load_estimator(folder)` store the
weights (``flow.eqx``, equinox's serialisation) beside ``flow.json`` (settings, dimensions,
standardisation), so a stored estimator rebuilds exactly.

``train_ensemble(theta, x, settings, seed, members) -> Ensemble``: ``members`` flows trained on the same
simulations with the seeds ``seed, seed + 1, ...`` (each its own initial weights, batches and validation
split); member 0 is ``train_flow(..., seed)``. :class:`Ensemble` is the equally weighted mixture of its
members (Lakshminarayanan et al. 2017; Hermans et al. 2022 show such mixtures of neural posterior
estimators are less over-confident than one), with the Estimator's interface: ``sample_many`` draws
``count`` from the mixture as the members' draws (``count // K`` each, the first ``count % K`` one more,
every member's rejection at the support as above) shuffled with ``seed``; ``log_prob`` is the log of the
members' mean density; ``save`` puts member i in ``member<i>/`` beside a ``flow.json`` naming the count,
and :func:`load_estimator` rebuilds whichever was stored. A one-member ensemble is its Estimator. The
members share member 0's static structure, so the vectorised sampler compiles once for all of them.

Every import of JAX happens inside these functions: without the extra, the rest of the calibration
works and ``npe`` says how to install it (:func:`require_jax`).
"""
from __future__ import annotations

import json
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from flocksweep.simcore.schema import ConfigError, check_at_least
from flocksweep.sweeps.files import atomic_path

from .jax_cache import enable_cache

FLOW_WEIGHTS = "flow.eqx"
FLOW_RECORD = "flow.json"
POSTERIOR_MARGIN = 4        # flocksweep posterior's first pass draws count + count / this a row (``margin``) ...
MAX_REDRAWS = 50            # ... then redraws of every row lacking draws inside the support, as many each ...
WIDE_BATCH, MAX_WIDE = 64, 20   # ... then of each row still lacking, WIDE_BATCH x count at a time
MEMBER_SEED_STEP = 104729   # member i of an ensemble samples with seed + i x this
DENSITY_CHUNK = 4096        # log_prob runs compiled on chunks of this many rows (the last one padded)
SAMPLE_THREADS = 2          # an ensemble's members sample in this many threads
SAMPLE_BLOCK, SAMPLE_ROWS = 12_800, 16   # a compiled sampler call draws for up to SAMPLE_ROWS observed rows, at most
                            # about SAMPLE_BLOCK draws in all (at least one row): the rows per call depend on the
                            # draws per row only, never on how many rows there are (the last call is padded), so a
                            # row's draws are bit for bit the same alone or among many (XLA's float32 rounding
                            # depends on the batch's shape) and one compiled program serves every table size


def rows_per_call(count: int) -> int:
    """Observed rows per compiled sampler call for ``count`` draws a row (:data:`SAMPLE_BLOCK`)."""
    return int(min(SAMPLE_ROWS, max(1, SAMPLE_BLOCK // max(1, count))))


def require_jax():
    """The jax, equinox and flowjax modules, or a ConfigError saying how to install them; JAX's persistent
    compilation cache turned on as :mod:`analysis.calibration.jax_cache` says (before any compile)."""
    os.environ.setdefault("JAX_PLATFORMS", "cpu")   # no accelerator probing: CPU, deterministic
    try:
        import equinox
        import flowjax  # noqa: F401
        import jax
    except ImportError:
        raise ConfigError("method.kind", "npe needs the sbi extra (JAX and flowjax, about 100 MB): "
                                         "pip install -e '.[sbi]'") from None
    enable_cache(jax)
    return jax, equinox


def support_of(prior=None, bounds=None):
    """(S, d) -> (S,) inside the prior's bounds (or the given (d, 2) bounds): the support the samplers
    redraw into."""
    bounds = np.asarray(prior.bounds if prior is not None else bounds, dtype=float)

    def inside(theta):
        return np.all((theta >= bounds[:, 0]) & (theta <= bounds[:, 1]), axis=1)
    return inside


class OutsideSupport(ValueError):
    """The estimator puts almost no mass inside the support at an observed row: the statistics lie far
    outside what the training simulations cover."""


@dataclass(frozen=True, kw_only=True)
class FlowSettings:
    """The flow's architecture and training (module docstring)."""

    width: int = 50
    layers: int = 5
    knots: int = 8
    max_epochs: int = 500
    patience: int = 20
    learning_rate: float = 1e-3
    batch_size: int = 50
    validation: float = 0.1

    def __post_init__(self):
        for name in ("width", "layers", "knots", "max_epochs", "patience", "batch_size"):
            check_at_least(name, getattr(self, name), 1)
        if not 0 < self.validation < 0.5:
            raise ConfigError("validation", f"got {self.validation}; expected a share in (0, 0.5)")
        if not self.learning_rate > 0:
            raise ConfigError("learning_rate", f"got {self.learning_rate}; expected a number > 0")


def _build(settings: FlowSettings, d: int, k: int, key):
    from flowjax.bijections import RationalQuadraticSpline
    from flowjax.distributions import Normal
    from flowjax.flows import masked_autoregressive_flow
    import jax.numpy as jnp

    return masked_autoregressive_flow(key, base_dist=Normal(jnp.zeros(d)), cond_dim=k,
                                      transformer=RationalQuadraticSpline(knots=settings.knots, interval=5),
                                      flow_layers=settings.layers, nn_width=settings.width)


_SAMPLER = []


def _sampler():
    """One compiled vectorised sampler (flow, conditions (r, k), key, rows (r,), count) -> (r, count, d), kept
    for the process: row j draws with the key ``fold_in(key, rows[j])``, so a row's draws depend on its
    own index and not on the others in the call; equinox's filter_jit compiles once per flow architecture,
    r and count (the callers give r = SAMPLE_ROWS: one program for every table size)."""
    if not _SAMPLER:
        _, eqx = require_jax()
        import jax

        def sample(flow, conditions, key, rows, count):
            return jax.vmap(lambda c, row: flow.sample(jax.random.fold_in(key, row), (count,), condition=c))(
                conditions, rows)
        _SAMPLER.append(eqx.filter_jit(sample))
    return _SAMPLER[0]


_DENSITY = []


def _density():
    """One compiled log density (flow, theta (c, d), conditions (c, k)) -> (c,), kept for the process; a
    chunk's size is fixed (DENSITY_CHUNK), so it compiles once per flow architecture."""
    if not _DENSITY:
        _, eqx = require_jax()
        _DENSITY.append(eqx.filter_jit(lambda flow, theta, conditions: flow.log_prob(theta, condition=conditions)))
    return _DENSITY[0]


def _scale(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mean, sd = values.mean(axis=0), values.std(axis=0)
    return mean, np.where(sd > 0, sd, 1.0)


@dataclass(frozen=True, eq=False)
class Estimator:
    """A trained posterior estimator (module docstring)."""

    flow: object
    settings: FlowSettings
    theta_mean: np.ndarray
    theta_sd: np.ndarray
    x_mean: np.ndarray
    x_sd: np.ndarray
    losses: dict = field(default_factory=dict)
    leakage: list = field(default_factory=lambda: [0.0, np.zeros(0)])   # the last call's: pooled, per row

    @property
    def d(self) -> int:
        return len(self.theta_mean)

    @property
    def k(self) -> int:
        return len(self.x_mean)

    @property
    def last_leakage(self) -> float:
        """Share of the last call's raw draws that fell outside the support (redrawn)."""
        return self.leakage[0]

    @property
    def last_row_leakage(self) -> np.ndarray:
        """(m,): each observed row's share of the last call's raw draws outside the support."""
        return self.leakage[1]

    def _condition(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.shape[-1] != self.k:
            raise ValueError(f"observed rows need {self.k} statistics, got shape {x.shape}")
        return ((x - self.x_mean) / self.x_sd).astype(np.float32)

    def _raw(self, conditions: np.ndarray, count: int, seed: int, rows=None) -> np.ndarray:
        """(m, count, d) raw draws at the m standardised ``conditions``; ``rows``: their row numbers (the
        key of row i is ``fold_in(key(seed), rows[i])``; default 0..m-1), :func:`rows_per_call` rows a call."""
        import jax
        import jax.numpy as jnp

        rows = np.arange(len(conditions)) if rows is None else np.asarray(rows)
        chunk = rows_per_call(count)
        key = jax.random.key(int(seed))
        calls = []   # dispatched before any is read: JAX runs them on its CPU threads as they come
        for start in range(0, len(conditions), chunk):
            pad = chunk - len(rows[start:start + chunk])
            calls.append(_sampler()(self.flow, jnp.asarray(np.pad(conditions[start:start + chunk], ((0, pad), (0, 0)),
                                                                  mode="edge")),
                                    key, jnp.asarray(np.pad(rows[start:start + chunk], (0, pad), mode="edge"),
                                                     dtype=jnp.uint32), int(count)))
        draws = np.concatenate([np.asarray(values, dtype=float) for values in calls])[:len(conditions)]
        return draws * self.theta_sd + self.theta_mean

    def sample_many(self, x, count: int, seed: int, support=None, short: str = "raise", rows=None,
                    margin: int | None = None) -> np.ndarray:
        """(m, count, d): ``count`` posterior draws for each of the m observed rows; a row the support
        holds too little of (module docstring) raises, or with ``short = "nan"`` is all NaN. Row i's draws
        depend only on its statistics, ``seed``, ``count``, ``margin`` and its row number ``rows[i]`` (default
        i), not on the other rows: one row sampled alone with its row number gets the draws it gets among
        many. ``margin`` M (with a support): every pass draws count + ceil(count / M) a row and a row keeps
        its first ``count`` draws inside, so that a row leaking under about 1 / (M + 1) of its mass needs no
        redraw pass (many flocks at once: nearly every flock leaks a little)."""
        conditions = np.atleast_2d(self._condition(x))
        rows = np.arange(len(conditions)) if rows is None else np.asarray(rows, dtype=np.int64)
        if rows.shape != (len(conditions),) or (rows < 0).any() or (rows >= 2**31).any():
            raise ValueError(f"rows: expected {len(conditions)} row numbers in [0, 2^31), got {rows!r:.80}")
        wide = count if support is None or not margin else count + -(-count // margin)   # one compiled shape a call
        raw = self._raw(conditions, wide, seed, rows)
        if support is None:
            self.leakage[:] = [0.0, np.zeros(len(raw))]
            return raw
        raw_inside = support(raw.reshape(-1, self.d)).reshape(raw.shape[:2])
        self.leakage[:] = [float(1.0 - raw_inside.mean()), 1.0 - raw_inside.mean(axis=1)]
        if wide == count:
            draws, inside = raw, raw_inside
        else:           # each row's first count draws inside the support, in order
            draws, inside = np.full((len(raw), count, self.d), np.nan), np.zeros((len(raw), count), dtype=bool)
            for i in range(len(raw)):
                kept = raw[i][raw_inside[i]][:count]
                draws[i, :len(kept)], inside[i, :len(kept)] = kept, True
        for attempt in range(1, MAX_REDRAWS + 1):
            lacking = np.flatnonzero(~inside.all(axis=1))
            if not len(lacking):
                return draws
            more = self._raw(conditions[lacking], wide, seed + 7919 * attempt, rows[lacking])
            more_inside = support(more.reshape(-1, self.d)).reshape(more.shape[:2])
            for j, i in enumerate(lacking):
                pool = np.concatenate([draws[i][inside[i]], more[j][more_inside[j]]])[:count]
                draws[i, :len(pool)] = pool
                inside[i] = np.arange(count) < len(pool)
        if inside.all():
            return draws
        for i in np.flatnonzero(~inside.all(axis=1)):
            try:
                draws[i] = self._fill(conditions[i], rows[i], draws[i][inside[i]], count, seed, support)
            except OutsideSupport:
                if short != "nan":
                    raise
                draws[i] = np.nan
        return draws

    def _fill(self, condition, row: int, have, count: int, seed: int, support) -> np.ndarray:
        """(count, d) draws for one row whose support holds too little of its mass for the redraws above
        (e.g. a posterior near the edge of a truncation region): batches of WIDE_BATCH x count."""
        pool, found = [have], len(have)
        for attempt in range(1, MAX_WIDE + 1):
            more = self._raw(condition[None, :], WIDE_BATCH * count, seed + 7919 * (MAX_REDRAWS + attempt), [row])[0]
            keep = more[support(more)]
            pool.append(keep)
            found += len(keep)
            if found >= count:
                return np.concatenate(pool)[:count]
        raise OutsideSupport(f"the estimator puts almost no mass inside the support (leakage {self.leakage[0]:.3f}; "
                         f"one row kept {found} of {count} draws out of {MAX_REDRAWS * count + MAX_WIDE * WIDE_BATCH * count}): "
                         "the observed statistics are far outside the training set")

    def sample(self, x, count: int, seed: int, support=None) -> np.ndarray:
        """(count, d) posterior draws at one observed row ``x`` (k,); :class:`OutsideSupport` when the
        support holds too little of its mass."""
        return self.sample_many(np.asarray(x, dtype=float)[None, :], count, seed, support)[0]

    def log_prob(self, theta, x) -> np.ndarray:
        """log q(theta | x) in the parameters' own units, (N,) for theta (N, d) and x (k,) or (N, k);
        computed in compiled chunks of DENSITY_CHUNK rows (a truncation region asks for many)."""
        import jax.numpy as jnp

        theta = ((np.atleast_2d(np.asarray(theta, dtype=float)) - self.theta_mean) / self.theta_sd).astype(np.float32)
        condition = self._condition(x)
        conditions = np.broadcast_to(condition, (len(theta), condition.shape[-1]))
        out = np.empty(len(theta))
        for start in range(0, len(theta), DENSITY_CHUNK):
            rows = slice(start, start + DENSITY_CHUNK)
            count = len(theta[rows])
            pad = ((0, DENSITY_CHUNK - count), (0, 0))
            values = _density()(self.flow, jnp.asarray(np.pad(theta[rows], pad, mode="edge")),
                                jnp.asarray(np.pad(conditions[rows], pad, mode="edge")))
            out[rows] = np.asarray(values, dtype=float)[:count]
        return out - np.log(self.theta_sd).sum()

    def record(self) -> dict:
        return {"settings": asdict(self.settings), "d": self.d, "k": self.k,
                "theta_mean": self.theta_mean.tolist(), "theta_sd": self.theta_sd.tolist(),
                "x_mean": self.x_mean.tolist(), "x_sd": self.x_sd.tolist(),
                "epochs": len(self.losses.get("train", [])),
                "best_validation_loss": min(self.losses["val"]) if self.losses.get("val") else None}

    def save(self, folder) -> Path:
        """flow.eqx (weights) and flow.json (the rest) in ``folder``, each written atomically."""
        _, eqx = require_jax()
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        with atomic_path(folder / FLOW_WEIGHTS) as tmp:
            eqx.tree_serialise_leaves(str(tmp), self.flow)
        with atomic_path(folder / FLOW_RECORD) as tmp:
            Path(tmp).write_text(json.dumps(self.record(), indent=1))
        return folder


@dataclass(frozen=True, eq=False)
class Ensemble:
    """An equally weighted mixture of trained estimators (module docstring)."""

    members: tuple
    leakage: list = field(default_factory=lambda: [0.0, np.zeros(0)])   # the last call's: pooled, per row

    @property
    def d(self) -> int:
        return self.members[0].d

    @property
    def k(self) -> int:
        return self.members[0].k

    @property
    def last_leakage(self) -> float:
        return self.leakage[0]

    @property
    def last_row_leakage(self) -> np.ndarray:
        return self.leakage[1]

    def sample_many(self, x, count: int, seed: int, support=None, short: str = "raise", rows=None,
                    margin: int | None = None) -> np.ndarray:
        """(m, count, d) draws of the mixture for each of the m observed rows (``short``, ``rows``, ``margin``:
        as :meth:`Estimator.sample_many`; a row any member cannot fill is all NaN)."""
        size = len(self.members)
        shares = [count // size + (i < count % size) for i in range(size)]
        jobs = [(member, share, seed + MEMBER_SEED_STEP * i) for i, (member, share) in enumerate(zip(self.members, shares))
                if share]
        _sampler()   # made before the threads start: one compiled sampler for all
        # the members sample in two threads (JAX releases the GIL while a compiled call runs): each
        # member's draws are its own calls' whatever the threads, so the mixture is bit for bit the same
        with ThreadPoolExecutor(max_workers=min(SAMPLE_THREADS, len(jobs))) as threads:
            parts = list(threads.map(lambda job: job[0].sample_many(x, job[1], job[2], support, short, rows, margin),
                                     jobs))
        leaks = [member.last_leakage * share for member, share, _ in jobs]
        row_leaks = [member.last_row_leakage * share for member, share, _ in jobs]
        self.leakage[:] = [float(sum(leaks) / count), sum(row_leaks) / count]
        draws = np.concatenate(parts, axis=1)
        draws[np.isnan(draws).any(axis=(1, 2))] = np.nan
        rows = np.arange(len(draws)) if rows is None else np.asarray(rows, dtype=np.int64)
        order = np.stack([np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(int(row),))).permutation(count)
                          for row in rows])
        return np.take_along_axis(draws, order[:, :, None], axis=1)

    def sample(self, x, count: int, seed: int, support=None) -> np.ndarray:
        return self.sample_many(np.asarray(x, dtype=float)[None, :], count, seed, support)[0]

    def log_prob(self, theta, x) -> np.ndarray:
        values = np.stack([member.log_prob(theta, x) for member in self.members])
        top = values.max(axis=0)
        return top + np.log(np.exp(values - top).mean(axis=0))

    def record(self) -> dict:
        members = [member.record() for member in self.members]
        learned = {key: members[0][key] for key in ("summary", "layout", "flocks") if key in members[0]}  # a learned summary's
        return {"members": len(members), "settings": members[0]["settings"], "d": self.d, "k": self.k, **learned,
                "epochs": [m["epochs"] for m in members],
                "best_validation_loss": [m["best_validation_loss"] for m in members]}

    def save(self, folder) -> Path:
        folder = Path(folder)
        for i, member in enumerate(self.members):
            member.save(folder / f"member{i}")
        folder.mkdir(parents=True, exist_ok=True)
        with atomic_path(folder / FLOW_RECORD) as tmp:
            Path(tmp).write_text(json.dumps(self.record(), indent=1))
        return folder


def _one_structure(members) -> tuple:
    """The members with member 0's static structure: built apart, their flows hold equal but distinct
    functions, which equinox's compile cache tells apart (one compile per member); rebuilt on one
    structure, the sampler compiles once for all of them."""
    import dataclasses

    _, eqx = require_jax()
    static = eqx.partition(members[0].flow, eqx.is_array)[1]
    return tuple(dataclasses.replace(m, flow=eqx.combine(eqx.partition(m.flow, eqx.is_array)[0], static))
                 for m in members)


def train_ensemble(theta, x, settings: FlowSettings, seed: int, members: int = 1, progress: bool = False,
                   trainer=None):
    """``members`` flows on the same simulations, seeds seed, seed + 1, ... (module docstring);
    ``progress``: flowjax's bar of epochs for each; ``trainer``: ``(theta, x, settings, seed, progress) ->
    estimator`` in place of :func:`train_flow` (a learned summary's,
    :func:`analysis.calibration.learned_summary.learned_trainer`)."""
    check_at_least("ensemble", members, 1)
    train = train_flow if trainer is None else trainer
    trained = tuple(train(theta, x, settings, seed + i, progress) for i in range(members))
    return trained[0] if members == 1 else Ensemble(_one_structure(trained))


def train_flow(theta, x, settings: FlowSettings, seed: int, progress: bool = False) -> Estimator:
    """Fit q(theta | x) to the simulations (module docstring); ``progress``: flowjax's bar of epochs on
    stderr (the result does not depend on it)."""
    jax, _ = require_jax()
    import jax.numpy as jnp
    from flowjax.train import fit_to_data

    theta, x = np.asarray(theta, dtype=float), np.asarray(x, dtype=float)
    if theta.ndim != 2 or x.ndim != 2 or len(theta) != len(x):
        raise ValueError(f"theta must be (N, d) and x (N, k) with the same N, got {theta.shape} and {x.shape}")
    if not (np.isfinite(theta).all() and np.isfinite(x).all()):
        raise ValueError("training simulations must be finite (drop the failed ones first)")
    theta_mean, theta_sd = _scale(theta)
    x_mean, x_sd = _scale(x)
    build_key, train_key = jax.random.split(jax.random.key(int(seed)))
    flow = _build(settings, theta.shape[1], x.shape[1], build_key)
    data = (jnp.asarray((theta - theta_mean) / theta_sd, dtype=jnp.float32),
            jnp.asarray((x - x_mean) / x_sd, dtype=jnp.float32))
    flow, losses = fit_to_data(train_key, flow, data, learning_rate=settings.learning_rate,
                               max_epochs=settings.max_epochs, max_patience=settings.patience,
                               batch_size=min(settings.batch_size, max(1, int(len(theta) * (1 - settings.validation)))),
                               val_prop=settings.validation, show_progress=progress)
    losses = {name: [float(v) for v in values] for name, values in losses.items()}
    return Estimator(flow, settings, theta_mean, theta_sd, x_mean, x_sd, losses)


MAX_MEMBERS = 256            # an ensemble's flow.json naming more members is not one flocksweep wrote


def load_estimator(folder, load_other=None):
    """The estimator (or ensemble) stored by ``save`` in ``folder``: its records' types and the weights'
    shapes checked against the flow they describe (:class:`~analysis.calibration.estimator_folder.
    DamagedEstimator` naming the file otherwise; the folder's checksums are the caller's:
    ``estimator_folder.verify``). ``load_other(folder, record)``: the loader of a record that is not a bare
    flow's (a learned summary's, :func:`analysis.calibration.learned_summary.load_any`), also for an
    ensemble's members."""
    from .estimator_folder import DamagedEstimator, read_json, retrain_hint

    jax, eqx = require_jax()
    folder = Path(folder)
    record = read_json(folder / FLOW_RECORD, missing=True) or {}
    if not isinstance(record, dict):
        raise DamagedEstimator(f"{folder / FLOW_RECORD}: not a flow record (a JSON object); {retrain_hint()}")
    if "members" in record:
        members = record["members"]
        if not (isinstance(members, int) and not isinstance(members, bool) and 1 <= members <= MAX_MEMBERS):
            raise DamagedEstimator(f"{folder / FLOW_RECORD}: members: got {members!r:.40}; expected an integer from 1 "
                                   f"to {MAX_MEMBERS}; {retrain_hint()}")
        return Ensemble(_one_structure([load_estimator(folder / f"member{i}", load_other) for i in range(members)]))
    if not record or not (folder / FLOW_WEIGHTS).is_file():
        raise DamagedEstimator(f"{folder}: no trained estimator ({FLOW_RECORD} and {FLOW_WEIGHTS}); train one "
                               "with flocksweep calibrate FILE --method npe")
    if "layout" in record:      # a learned summary beside the flow (analysis.calibration.learned_summary)
        if load_other is None:
            raise DamagedEstimator(f"{folder}: an estimator with a learned summary; load it with "
                                   "analysis.calibration.learned_summary.load_any")
        return load_other(folder, record)
    settings, arrays = _checked_record(folder / FLOW_RECORD, record, DamagedEstimator, retrain_hint())
    architecture = (settings, record["d"], record["k"])
    if architecture not in _SKELETONS:
        _SKELETONS[architecture] = _build(settings, record["d"], record["k"], jax.random.key(0))
    skeleton = _SKELETONS[architecture]
    flow = _read_weights(folder / FLOW_WEIGHTS, skeleton, DamagedEstimator, retrain_hint())
    static = eqx.partition(skeleton, eqx.is_array)[1]
    return Estimator(eqx.combine(eqx.partition(flow, eqx.is_array)[0], static), settings, *arrays)


_SKELETONS = {}   # (settings, d, k) -> a flow of that architecture (built once per process; its weights are
                  # replaced): every flow loaded with that architecture shares its static structure, so the
                  # compiled sampler and density programs traced for one serve all (members, estimators loaded
                  # again). (A flow of shapes only, eqx.filter_eval_shape, would cost no compile but flowjax's
                  # spline constructor keeps a closure over the trace's values.)


def _checked_record(path: Path, record: dict, damaged, hint: str):
    """(FlowSettings, (theta_mean, theta_sd, x_mean, x_sd)) of a flow record whose types hold."""
    def refuse(what):
        return damaged(f"{path}: {what}; not a flow record flocksweep writes: {hint}")

    d, k = record.get("d"), record.get("k")
    if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 10_000 for v in (d, k)):
        raise refuse(f"d and k: got {d!r:.20} and {k!r:.20}; expected the numbers of parameters and statistics")
    try:
        settings = FlowSettings(**record["settings"])
    except (KeyError, TypeError, ValueError, ConfigError) as err:
        raise refuse(f"settings: {err}") from None
    if not all(isinstance(getattr(settings, name), (int, float)) and not isinstance(getattr(settings, name), bool)
               for name in ("width", "layers", "knots", "max_epochs", "patience", "learning_rate", "batch_size",
                            "validation")) or not (1 <= settings.width <= 4096 and 1 <= settings.layers <= 64
                                                   and 1 <= settings.knots <= 256):
        raise refuse(f"settings: got {record['settings']!r:.120}")
    arrays = []
    for name, size in (("theta_mean", d), ("theta_sd", d), ("x_mean", k), ("x_sd", k)):
        try:
            values = np.asarray(record[name], dtype=float)
        except (KeyError, TypeError, ValueError):
            raise refuse(f"{name}: missing or not numbers") from None
        if values.shape != (size,) or not np.isfinite(values).all() or (name.endswith("_sd") and (values <= 0).any()):
            raise refuse(f"{name}: got {values.shape[0] if values.ndim == 1 else values.shape} values; expected {size} "
                         f"finite numbers{' > 0' if name.endswith('_sd') else ''}")
        arrays.append(values)
    return settings, tuple(arrays)


def _read_weights(path: Path, skeleton, damaged, hint: str):
    """The flow's weights from ``path`` (equinox's leaves, one .npy each, read with pickling off), each
    leaf's header checked against the flow's own shape and dtype before its data is read, and nothing
    left over."""
    jax, eqx = require_jax()

    def leaf(handle, like):
        if not (isinstance(like, (jax.Array, jax.ShapeDtypeStruct, np.ndarray)) or eqx.is_array_like(like)):
            return like
        start = handle.tell()
        version = np.lib.format.read_magic(handle)
        shape, _, dtype = (np.lib.format.read_array_header_1_0(handle) if version == (1, 0)
                           else np.lib.format.read_array_header_2_0(handle))
        want_shape, want_dtype = np.shape(like), np.asarray(like).dtype
        if tuple(shape) != tuple(want_shape) or np.dtype(dtype) != want_dtype:
            raise ValueError(f"an array of shape {tuple(shape)} ({np.dtype(dtype)}) where the flow has "
                             f"{tuple(want_shape)} ({want_dtype})")
        handle.seek(start)
        return eqx.default_deserialise_filter_spec(handle, like)   # numpy's load: pickling off

    try:
        with open(path, "rb") as handle:
            flow = eqx.tree_deserialise_leaves(handle, skeleton, filter_spec=leaf)
            if handle.read(1):
                raise ValueError("bytes left over after the flow's last array")
    except (ValueError, EOFError, OSError, RuntimeError) as raised:   # equinox wraps a leaf's error (RuntimeError)
        err = raised
        while isinstance(err, RuntimeError) and err.__cause__ is not None:
            err = err.__cause__
        raise damaged(f"{path}: not the weights of this estimator's flow ({type(err).__name__}: {err}); {hint}") from None
    return flow
