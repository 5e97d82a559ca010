"""npe's learned summary: a permutation-invariant embedding of a run's raw inputs
(:mod:`analysis.calibration.learned_inputs`) trained jointly with the flow, in JAX/equinox (the ``sbi``
extra, as the flow).

Shapes: N training simulations, d parameters, k statistics, M individuals of F features (+ a mask), L bins of
S series, E = ``size`` numbers of the embedding, W = ``width``, f observed flocks per row.

Contract
--------
:class:`Embedding` (an equinox module): raw inputs (M, F + 1), (L, S), both standardised -> (E,). A
per-individual network phi (F -> W -> W, ReLU) is applied to every individual; its outputs are pooled over
the individuals whose mask is 1 by their mean and their maximum (DeepSets, Zaheer et al. 2017: a function of
the set, whatever their order; padding rows never count); the series pass through a network (L S -> W, ReLU);
rho (2 W + W + 1 -> W -> E, ReLU) maps the pooled individuals, the series' output and the share of the M
slots that count to the summary. Standardisation: each feature by its mean and sd over the counted
individuals of the training set, each (bin, series) by its mean and sd over the training set (sd 0 -> 1).

*Several flocks* (f > 1: the calibration observed f flocks, each training simulation is f runs): a row holds
the f runs' (flocks') mean statistics and each one's raw inputs; the same embedding summarises every flock and
the f summaries are pooled by their mean (E numbers, whatever the order of the flocks) before the flow; the
standardisation is fitted over all flocks of the training set. f = 1 is the one-flock estimator, bit for bit.

``train_learned(theta (N, d), x (N, k + f length), settings (FlowSettings), summary (SummarySettings), plan
(Layout), seed, progress=False, flocks=f) -> LearnedEstimator``: one loss, -log q(theta | standardised statistics,
embedding(raw)), minimised over the flow's and the embedding's weights together (Adam, the flow's learning
rate, batches, validation share and early stopping: flowjax's training steps and split, the best validation
epoch's weights kept). A deterministic function of its inputs and ``seed`` on CPU (tested bit for bit).

:class:`LearnedEstimator`: an :class:`~analysis.calibration.npe_flow.Estimator` whose rows are the k
statistics followed by the raw inputs of its ``flocks`` flocks (``k`` is their whole length); its flow's
condition is the standardised statistics and the (pooled) embedding. ``save(folder)`` writes ``flow.eqx``,
``embedding.eqx`` (equinox's serialisation) and ``flow.json`` (the settings, dimensions, standardisations,
layout and, when f > 1, ``flocks``: never pickle);
``load_learned(folder, record)`` rebuilds it (each weight's shape and dtype checked, as the flow's).

``load_any(folder) -> estimator``: whatever npe stored in ``folder`` (a flow, an ensemble, either with a learned
summary): what ``calibrate`` and ``posterior`` load. ``learned_trainer(summary, plan, flocks=1)``: the trainer
:func:`~analysis.calibration.npe_flow.train_ensemble` takes for a learned summary.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from flocksweep.sweeps.files import atomic_path

from .learned_inputs import Layout, SummarySettings, layout_from_record
from .npe_flow import FLOW_RECORD, FLOW_WEIGHTS, Estimator, FlowSettings, _build, _scale, require_jax

EMBEDDING_WEIGHTS = "embedding.eqx"


def _embedding_class():
    """The Embedding class (defined when JAX is loaded: equinox is the sbi extra's)."""
    if _CLASS:
        return _CLASS[0]
    _, eqx = require_jax()
    import jax
    import jax.numpy as jnp

    class Embedding(eqx.Module):
        phi: eqx.nn.MLP
        series: eqx.nn.MLP
        rho: eqx.nn.MLP

        def __init__(self, features: int, series: int, width: int, size: int, key):
            a, b, c = jax.random.split(key, 3)
            self.phi = eqx.nn.MLP(features, width, width, 1, activation=jax.nn.relu, final_activation=jax.nn.relu,
                                  key=a)
            self.series = eqx.nn.MLP(series, width, width, 0, activation=jax.nn.relu, final_activation=jax.nn.relu,
                                     key=b)
            self.rho = eqx.nn.MLP(3 * width + 1, size, width, 1, activation=jax.nn.relu, key=c)

        def __call__(self, individuals, series):
            values, mask = individuals[:, :-1], individuals[:, -1:]
            h = jax.vmap(self.phi)(values)
            count = mask.sum()
            mean = (h * mask).sum(axis=0) / jnp.maximum(count, 1.0)
            top = jnp.where(mask > 0, h, -jnp.inf).max(axis=0)
            top = jnp.where(count > 0, top, 0.0)
            share = count / individuals.shape[0]
            return self.rho(jnp.concatenate([mean, top, self.series(series.ravel()), share[None]]))

    _CLASS.append(Embedding)
    return Embedding


_CLASS = []


@dataclass(frozen=True)
class Standardise:
    """The raw inputs' standardisation (module docstring)."""

    feature_mean: np.ndarray     # (F,)
    feature_sd: np.ndarray
    series_mean: np.ndarray      # (L, S)
    series_sd: np.ndarray

    @staticmethod
    def fit(individuals: np.ndarray, series: np.ndarray) -> "Standardise":
        values, mask = individuals[..., :-1], individuals[..., -1] > 0
        counted = values[mask]
        mean, sd = _scale(counted) if len(counted) else (np.zeros(values.shape[-1]), np.ones(values.shape[-1]))
        s_mean, s_sd = _scale(series.reshape(len(series), -1))
        return Standardise(mean, sd, s_mean.reshape(series.shape[1:]), s_sd.reshape(series.shape[1:]))

    def apply(self, individuals: np.ndarray, series: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mask = individuals[..., -1:]
        values = (individuals[..., :-1] - self.feature_mean) / self.feature_sd * mask
        return (np.concatenate([values, mask], axis=-1).astype(np.float32),
                ((series - self.series_mean) / self.series_sd).astype(np.float32))

    def record(self) -> dict:
        return {name: getattr(self, name).tolist() for name in ("feature_mean", "feature_sd", "series_mean",
                                                                "series_sd")}


_EMBED = []


def _embed():
    """One compiled (embedding, individuals (m, M, F + 1), series (m, L, S)) -> (m, E), kept for the process;
    given (m, f, M, F + 1) and (m, f, L, S), each row's f embeddings pooled by their mean (:func:`_embedded`)."""
    if not _EMBED:
        _, eqx = require_jax()
        _EMBED.append(eqx.filter_jit(_embedded))
    return _EMBED[0]


def _embedded(net, individuals, series):
    """(m, E): the embedding of each row, of its one flock (individuals 3-D) or the mean of its f flocks' (4-D)."""
    import jax

    if individuals.ndim == 3:
        return jax.vmap(net)(individuals, series)
    return jax.vmap(lambda ind, ser: jax.vmap(net)(ind, ser).mean(axis=0))(individuals, series)


@dataclass(frozen=True, eq=False)
class LearnedEstimator(Estimator):
    """An estimator conditioned on the statistics and a learned summary (module docstring)."""

    embedding: object = None
    summary: SummarySettings = field(default_factory=SummarySettings)
    plan: Layout | None = None
    raw_scale: Standardise | None = None
    flocks: int = 1

    @property
    def k(self) -> int:
        return len(self.x_mean) + self.flocks * self.plan.length

    def _condition(self, x) -> np.ndarray:
        import jax.numpy as jnp

        x = np.asarray(x, dtype=float)
        if x.shape[-1] != self.k:
            raise ValueError(f"observed rows need {len(self.x_mean)} statistics and {self.flocks} x "
                             f"{self.plan.length} raw inputs ({self.k} numbers), got shape {x.shape}")
        stats, individuals, series = self.plan.split(np.atleast_2d(x), len(self.x_mean), self.flocks)
        individuals, series = self.raw_scale.apply(individuals, series)
        embedded = np.asarray(_embed()(self.embedding, jnp.asarray(individuals), jnp.asarray(series)), dtype=np.float32)
        out = np.concatenate([((stats - self.x_mean) / self.x_sd).astype(np.float32), embedded], axis=1)
        return out if x.ndim > 1 else out[0]

    def record(self) -> dict:
        return {**super().record(), "summary": asdict(self.summary), "layout": self.plan.record(),
                "raw_scale": self.raw_scale.record(), **({"flocks": self.flocks} if self.flocks > 1 else {})}

    def save(self, folder) -> Path:
        """flow.eqx, embedding.eqx (weights) and flow.json (the rest), each written atomically."""
        _, eqx = require_jax()
        super().save(folder)
        with atomic_path(Path(folder) / EMBEDDING_WEIGHTS) as tmp:
            eqx.tree_serialise_leaves(str(tmp), self.embedding)
        return Path(folder)


def _new_embedding(summary: SummarySettings, plan: Layout, key):
    return _embedding_class()(len(plan.features), plan.series_length * len(plan.series), summary.width, summary.size,
                              key)


def _loss(params, static, theta, stats, individuals, series, key=None):
    import equinox as eqx
    import jax.numpy as jnp
    import paramax

    flow, embedding = paramax.unwrap(eqx.combine(params, static))
    condition = jnp.concatenate([stats, _embedded(embedding, individuals, series)], axis=1)
    return -flow.log_prob(theta, condition).mean()


def train_learned(theta, x, settings: FlowSettings, summary: SummarySettings, plan: Layout, seed: int,
                  progress: bool = False, flocks: int = 1) -> LearnedEstimator:
    """Fit the flow and the embedding together (module docstring)."""
    jax, eqx = require_jax()
    import jax.numpy as jnp
    import optax
    import paramax
    from flowjax.train.train_utils import count_fruitless, get_batches, step, train_val_split

    theta, x = np.asarray(theta, dtype=float), np.asarray(x, dtype=float)
    if theta.ndim != 2 or x.ndim != 2 or len(theta) != len(x):
        raise ValueError(f"theta must be (N, d) and x (N, k + raw) with the same N, got {theta.shape} and {x.shape}")
    if not (np.isfinite(theta).all() and np.isfinite(x).all()):
        raise ValueError("training simulations must be finite (drop the failed ones first)")
    k = x.shape[1] - flocks * plan.length
    stats, individuals, series = plan.split(x, k, flocks)
    theta_mean, theta_sd = _scale(theta)
    x_mean, x_sd = _scale(stats)
    raw_scale = Standardise.fit(individuals.reshape(-1, *individuals.shape[-2:]), series.reshape(-1, *series.shape[-2:]))
    individuals, series = raw_scale.apply(individuals, series)
    build_key, embed_key, train_key = jax.random.split(jax.random.key(int(seed)), 3)
    model = (_build(settings, theta.shape[1], k + summary.size, build_key), _new_embedding(summary, plan, embed_key))
    data = [jnp.asarray((theta - theta_mean) / theta_sd, dtype=jnp.float32),
            jnp.asarray((stats - x_mean) / x_sd, dtype=jnp.float32), jnp.asarray(individuals), jnp.asarray(series)]
    optimizer = optax.adam(settings.learning_rate)
    params, static = eqx.partition(model, eqx.is_inexact_array,
                                   is_leaf=lambda leaf: isinstance(leaf, paramax.NonTrainable))
    best, state = params, optimizer.init(params)
    key, split = jax.random.split(train_key)
    train, val = train_val_split(split, data, val_prop=settings.validation)
    batch = min(settings.batch_size, max(1, len(train[0])))
    losses = {"train": [], "val": []}
    loss_fn = eqx.filter_jit(_loss)
    from flocksweep.sweeps.progress import bar

    with bar(settings.max_epochs, "learned summary: epochs", "epoch", progress) as shown:
        for _ in range(settings.max_epochs):
            key, a, b = jax.random.split(key, 3)
            train = [jax.random.permutation(a, arr) for arr in train]
            val = [jax.random.permutation(b, arr) for arr in val]
            parts = []
            for chunk in zip(*get_batches(train, batch), strict=True):
                key, sub = jax.random.split(key)
                params, state, value = step(params, static, *chunk, optimizer=optimizer, opt_state=state,
                                            loss_fn=_loss, key=sub)
                parts.append(value)
            losses["train"].append(float(sum(parts) / len(parts)))
            parts = [loss_fn(params, static, *chunk) for chunk in zip(*get_batches(val, batch), strict=True)]
            losses["val"].append(float(sum(parts) / len(parts)))
            shown.update()
            if losses["val"][-1] == min(losses["val"]):
                best = params
            elif count_fruitless(losses["val"]) > settings.patience:
                break
    flow, embedding = eqx.combine(best, static)
    return LearnedEstimator(flow, settings, theta_mean, theta_sd, x_mean, x_sd, losses, embedding=embedding,
                            summary=summary, plan=plan, raw_scale=raw_scale, flocks=int(flocks))


def learned_trainer(summary: SummarySettings, plan: Layout, flocks: int = 1):
    """``(theta, x, settings, seed, progress) -> LearnedEstimator`` for :func:`~analysis.calibration.npe_flow.
    train_ensemble` (rows of ``flocks`` flocks each)."""
    def train(theta, x, settings, seed, progress=False):
        return train_learned(theta, x, settings, summary, plan, seed, progress, flocks)
    return train


def load_any(folder, record: dict | None = None):
    """The estimator stored in ``folder``, a learned summary's or not (module docstring)."""
    from .npe_flow import load_estimator

    if record is not None:      # called back by load_estimator with a learned summary's record
        return load_learned(Path(folder), record)
    return load_estimator(folder, load_any)


_SKELETONS = {}


def load_learned(folder: Path, record: dict) -> LearnedEstimator:
    """The learned-summary estimator stored in ``folder`` (module docstring)."""
    from .estimator_folder import DamagedEstimator, retrain_hint
    from .npe_flow import _checked_record, _read_weights

    jax, eqx = require_jax()
    hint = retrain_hint()
    path = folder / FLOW_RECORD

    def refuse(what):
        return DamagedEstimator(f"{path}: {what}; not a flow record flocksweep writes: {hint}")

    try:
        summary = SummarySettings(**{key: tuple(v) if isinstance(v, list) else v
                                     for key, v in record["summary"].items()})
        plan = layout_from_record(record["layout"])
        flocks = record.get("flocks", 1)
        if not (isinstance(flocks, int) and not isinstance(flocks, bool) and 1 <= flocks <= 100_000):
            raise ValueError(f"flocks: got {flocks!r:.20}; expected an integer >= 1")
        scale = record["raw_scale"]
        raw_scale = Standardise(*(np.asarray(scale[name], dtype=float) for name in ("feature_mean", "feature_sd",
                                                                                   "series_mean", "series_sd")))
    except Exception as err:  # noqa: BLE001 - any malformed record is a damaged estimator
        raise refuse(f"summary, layout or raw_scale: {type(err).__name__}: {err}") from None
    stat_count = len(record.get("x_mean") or [])
    want = {"feature_mean": (len(plan.features),), "series_mean": (plan.series_length, len(plan.series))}
    if (raw_scale.feature_mean.shape != want["feature_mean"] or raw_scale.feature_sd.shape != want["feature_mean"]
            or raw_scale.series_mean.shape != want["series_mean"] or raw_scale.series_sd.shape != want["series_mean"]
            or not all(np.isfinite(getattr(raw_scale, n)).all() for n in ("feature_mean", "feature_sd", "series_mean",
                                                                         "series_sd"))):
        raise refuse("raw_scale: shapes or values do not fit the layout")
    if record.get("k") != stat_count + flocks * plan.length:
        raise refuse(f"k: got {record.get('k')!r:.20}; expected {stat_count} statistics + {flocks} x {plan.length} "
                     "raw inputs")
    settings, arrays = _checked_record(path, {**record, "k": stat_count}, DamagedEstimator, hint)
    architecture = (settings, summary, plan, record["d"], stat_count)
    if architecture not in _SKELETONS:
        skeleton_flow = _build(settings, record["d"], stat_count + summary.size, jax.random.key(0))
        _SKELETONS[architecture] = (skeleton_flow, _new_embedding(summary, plan, jax.random.key(0)))
    skeleton_flow, skeleton_embedding = _SKELETONS[architecture]
    flow = _read_weights(folder / FLOW_WEIGHTS, skeleton_flow, DamagedEstimator, hint)
    embedding = _read_weights(folder / EMBEDDING_WEIGHTS, skeleton_embedding, DamagedEstimator, hint)
    static = eqx.partition(skeleton_flow, eqx.is_array)[1]
    return LearnedEstimator(eqx.combine(eqx.partition(flow, eqx.is_array)[0], static), settings, *arrays,
                            embedding=embedding, summary=summary, plan=plan, raw_scale=raw_scale, flocks=flocks)

