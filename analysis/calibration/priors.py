"""Prior distributions for calibration parameters.

One-parameter priors are frozen dataclasses with the same interface:

* ``logpdf(x)``  vectorised log density, ``-inf`` outside the support;
* ``sample(rng, size)`` draws with an explicit :class:`numpy.random.Generator`;
* ``ppf(u)``     quantile function (for unit-cube transforms), ``nan`` for ``u`` outside [0, 1];
* ``bounds``     support as ``(low, high)`` (may be infinite);
* ``mean``, ``sd`` numbers; for Uniform/LogUniform/Normal they are the moments of the distribution,
  for TruncatedNormal they are its *parent* normal's parameters (constructor fields);
* ``moments``    ``(mean, sd)`` of the distribution itself for every family (use this for
  "posterior narrower than prior" checks; the truncated sd is below the parent sd).

Parameters are validated in ``__post_init__``; a bad value raises :class:`ConfigError` with key
``prior.<field>`` (``prior_from_dict`` re-keys it to ``<key>.<field>``).

:class:`JointPrior` is the product of independent one-parameter priors. Optional explicit hard bounds
per parameter: a prior with bounded support must lie inside its bounds, a :class:`Normal` (unbounded
support) must have its mean inside them and is then truncated to them (becomes a
:class:`TruncatedNormal`); anything else is a ConfigError "prior outside bounds".
"""
from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Mapping, Sequence

import numpy as np
from scipy import special, stats

from flocksweep.simcore.schema import ConfigError, build, check_choice, join, suggest

_LOG_2PI = math.log(2.0 * math.pi)


def _number(value, key: str, *, finite: bool = True) -> float:
    """``value`` as a float; ConfigError for bools, non-numbers, nan (and infinities when ``finite``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(key, f"expected a number, got {value!r}")
    out = float(value)
    if math.isnan(out) or (finite and math.isinf(out)):
        allowed = "a finite number" if finite else "a number or +-inf"
        raise ConfigError(key, f"expected {allowed}, got {value!r}")
    return out


def _coerce(obj, names: Sequence[str], *, finite: Sequence[bool] | None = None) -> None:
    finite = [True] * len(names) if finite is None else finite
    for name, fin in zip(names, finite):
        object.__setattr__(obj, name, _number(getattr(obj, name), f"prior.{name}", finite=fin))


def _check_order(low: float, high: float) -> None:
    if not low < high:
        raise ConfigError("prior.high", f"must be greater than low={low!r}, got {high!r}")


def _check_sd(sd: float) -> None:
    if not sd > 0:
        raise ConfigError("prior.sd", f"must be > 0, got {sd!r}")


def _check_rng(rng) -> None:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")


def _out(a):
    """0-d arrays become numpy scalars; other arrays pass through."""
    a = np.asarray(a, dtype=float)
    return a[()] if a.ndim == 0 else a


def _ppf_guard(u, values):
    u = np.asarray(u, dtype=float)
    return _out(np.where((u >= 0.0) & (u <= 1.0), values, np.nan))


class _Interval:
    """A prior on [low, high] whose ``mean`` and ``sd`` are its own moments."""

    @property
    def bounds(self) -> tuple[float, float]:
        return (self.low, self.high)

    @property
    def moments(self) -> tuple[float, float]:
        """(mean, sd) of the distribution."""
        return (self.mean, self.sd)


@dataclasses.dataclass(frozen=True)
class Uniform(_Interval):
    """Uniform on [low, high]."""

    low: float
    high: float

    def __post_init__(self):
        _coerce(self, ("low", "high"))
        _check_order(self.low, self.high)

    @property
    def mean(self) -> float:
        return 0.5 * (self.low + self.high)

    @property
    def sd(self) -> float:
        return (self.high - self.low) / math.sqrt(12.0)

    def logpdf(self, x):
        x = np.asarray(x, dtype=float)
        inside = (x >= self.low) & (x <= self.high)
        return _out(np.where(inside, -math.log(self.high - self.low), -np.inf))

    def ppf(self, u):
        u = np.asarray(u, dtype=float)
        return _ppf_guard(u, self.low + u * (self.high - self.low))

    def sample(self, rng: np.random.Generator, size=None):
        _check_rng(rng)
        return rng.uniform(self.low, self.high, size=size)


@dataclasses.dataclass(frozen=True)
class LogUniform(_Interval):
    """Log-uniform (reciprocal) on [low, high], 0 < low < high: density 1 / (x log(high/low))."""

    low: float
    high: float

    def __post_init__(self):
        _coerce(self, ("low", "high"))
        if not self.low > 0:
            raise ConfigError("prior.low", f"must be > 0 for a loguniform prior, got {self.low!r}")
        _check_order(self.low, self.high)

    @property
    def _log_ratio(self) -> float:
        return math.log(self.high / self.low)

    @property
    def mean(self) -> float:
        return (self.high - self.low) / self._log_ratio

    @property
    def sd(self) -> float:
        second = (self.high ** 2 - self.low ** 2) / (2.0 * self._log_ratio)
        return math.sqrt(max(second - self.mean ** 2, 0.0))

    def logpdf(self, x):
        x = np.asarray(x, dtype=float)
        inside = (x >= self.low) & (x <= self.high)
        safe = np.where(inside, x, 1.0)
        return _out(np.where(inside, -np.log(safe) - math.log(self._log_ratio), -np.inf))

    def ppf(self, u):
        u = np.asarray(u, dtype=float)
        return _ppf_guard(u, self.low * np.exp(u * self._log_ratio))

    def sample(self, rng: np.random.Generator, size=None):
        _check_rng(rng)
        return np.exp(rng.uniform(math.log(self.low), math.log(self.high), size=size))


@dataclasses.dataclass(frozen=True)
class Normal:
    """Normal(mean, sd), sd > 0; support is the whole real line."""

    mean: float
    sd: float

    def __post_init__(self):
        _coerce(self, ("mean", "sd"))
        _check_sd(self.sd)

    @property
    def bounds(self) -> tuple[float, float]:
        return (-math.inf, math.inf)

    @property
    def moments(self) -> tuple[float, float]:
        """(mean, sd) of the distribution."""
        return (self.mean, self.sd)

    def logpdf(self, x):
        z = (np.asarray(x, dtype=float) - self.mean) / self.sd
        return _out(-0.5 * z * z - math.log(self.sd) - 0.5 * _LOG_2PI)

    def ppf(self, u):
        u = np.asarray(u, dtype=float)
        return _ppf_guard(u, self.mean + self.sd * special.ndtri(np.clip(u, 0.0, 1.0)))

    def sample(self, rng: np.random.Generator, size=None):
        _check_rng(rng)
        return rng.normal(self.mean, self.sd, size=size)


@dataclasses.dataclass(frozen=True)
class TruncatedNormal:
    """Normal(mean, sd) restricted to [low, high] and renormalised. ``low``/``high`` may be -inf/+inf.

    ``mean``/``sd`` are the parameters of the parent normal; the moments of the truncated distribution
    are ``dist_mean``/``dist_sd`` (``moments`` gives both)."""

    mean: float
    sd: float
    low: float
    high: float

    def __post_init__(self):
        _coerce(self, ("mean", "sd", "low", "high"), finite=(True, True, False, False))
        _check_sd(self.sd)
        _check_order(self.low, self.high)
        x0 = min(max(self.mean, self.low), self.high)
        if not np.isfinite(self.logpdf(x0)):
            raise ConfigError("prior.low", f"[{self.low}, {self.high}] has no usable probability mass under "
                                           f"Normal({self.mean}, {self.sd}); widen it or move the mean")

    @property
    def _ab(self) -> tuple[float, float]:
        return ((self.low - self.mean) / self.sd, (self.high - self.mean) / self.sd)

    def _dist(self):
        a, b = self._ab
        return stats.truncnorm(a, b, loc=self.mean, scale=self.sd)

    @property
    def bounds(self) -> tuple[float, float]:
        return (self.low, self.high)

    @property
    def dist_mean(self) -> float:
        return float(self._dist().mean())

    @property
    def dist_sd(self) -> float:
        return float(self._dist().std())

    @property
    def moments(self) -> tuple[float, float]:
        """(mean, sd) of the truncated distribution (not the parent's ``mean``/``sd`` fields)."""
        return (self.dist_mean, self.dist_sd)

    def logpdf(self, x):
        a, b = self._ab
        return _out(stats.truncnorm.logpdf(np.asarray(x, dtype=float), a, b, loc=self.mean, scale=self.sd))

    def ppf(self, u):
        u = np.asarray(u, dtype=float)
        return _ppf_guard(u, self._dist().ppf(np.clip(u, 0.0, 1.0)))

    def sample(self, rng: np.random.Generator, size=None):
        _check_rng(rng)
        return self._dist().rvs(size=size, random_state=rng)


Prior = Uniform | LogUniform | Normal | TruncatedNormal

DISTRIBUTIONS: dict[str, type] = {
    "uniform": Uniform,
    "loguniform": LogUniform,
    "normal": Normal,
    "truncnormal": TruncatedNormal,
}


def _rekey(err: ConfigError, key: str) -> ConfigError:
    """``prior.low`` -> ``<key>.low``, keeping the message."""
    field = err.key.split(".", 1)[-1]
    return ConfigError(join(key, field), str(err).split(": ", 1)[-1])


def prior_from_dict(d: Mapping, key: str = "prior") -> Prior:
    """One prior from a TOML-like table ``{"dist": "uniform", "low": 0, "high": 1}``.

    ``dist`` is one of uniform | loguniform | normal | truncnormal; the other keys are that family's
    fields (all required), read by the schema engine (:func:`simcore.schema.build`). Errors are
    ConfigError naming ``<key>.<field>``."""
    if not isinstance(d, Mapping):
        raise ConfigError(key, f"expected a table with a 'dist' key, got {d!r}")
    if "dist" not in d:
        raise ConfigError(join(key, "dist"), f"missing required key; allowed: {', '.join(DISTRIBUTIONS)}")
    check_choice(join(key, "dist"), d["dist"], tuple(DISTRIBUTIONS))
    try:
        return build(DISTRIBUTIONS[d["dist"]], {k: v for k, v in d.items() if k != "dist"})
    except ConfigError as err:
        raise _rekey(err, key) from None


def _within(inner: tuple[float, float], outer: tuple[float, float]) -> bool:
    return outer[0] <= inner[0] and inner[1] <= outer[1]


class JointPrior:
    """Product of independent one-parameter priors over the named parameters (in order).

    ``explicit_bounds`` maps (some) names to hard bounds ``(low, high)``. A prior with bounded support
    must lie inside its bounds; a Normal must have its mean inside them and is truncated to them; any
    other combination raises ConfigError "prior outside bounds" (key ``prior.<name>``).
    ``marginals`` are the priors actually used (after truncation); ``priors`` are those given."""

    def __init__(self, names: Sequence[str], priors: Sequence[Prior],
                 explicit_bounds: Mapping[str, tuple[float, float]] | None = None):
        names = tuple(names)
        priors = tuple(priors)
        if not names:
            raise ConfigError("prior.names", "need at least one parameter")
        for n in names:
            if not isinstance(n, str) or not n:
                raise ConfigError("prior.names", f"parameter names must be non-empty strings, got {n!r}")
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ConfigError("prior.names", f"duplicate parameter names {dupes}; each must be unique")
        if len(priors) != len(names):
            raise ConfigError("prior.priors", f"got {len(priors)} priors for {len(names)} names {list(names)}")
        for n, p in zip(names, priors):
            if not isinstance(p, tuple(DISTRIBUTIONS.values())):
                raise ConfigError(f"prior.{n}", f"expected one of Uniform, LogUniform, Normal, "
                                                f"TruncatedNormal, got {type(p).__name__}")
        explicit = dict(explicit_bounds or {})
        for n in explicit:
            if n not in names:
                raise ConfigError(f"bounds.{n}", f"no parameter named {n!r}{suggest(n, names)}; "
                                                 f"parameters: {', '.join(names)}")
        marginals = []
        for n, p in zip(names, priors):
            if n not in explicit:
                marginals.append(p)
                continue
            b = explicit[n]
            if not isinstance(b, (tuple, list)) or len(b) != 2:
                raise ConfigError(f"bounds.{n}", f"expected (low, high), got {b!r}")
            low = _number(b[0], f"bounds.{n}", finite=False)
            high = _number(b[1], f"bounds.{n}", finite=False)
            if not low < high:
                raise ConfigError(f"bounds.{n}", f"need low < high, got ({low!r}, {high!r})")
            if isinstance(p, Normal):
                if not low <= p.mean <= high:
                    raise ConfigError(f"prior.{n}", f"prior outside bounds: normal mean {p.mean!r} is not "
                                                    f"inside bounds [{low}, {high}]")
                marginals.append(TruncatedNormal(p.mean, p.sd, low, high))
            elif _within(p.bounds, (low, high)):
                marginals.append(p)
            else:
                raise ConfigError(f"prior.{n}", f"prior outside bounds: support [{p.bounds[0]}, "
                                                f"{p.bounds[1]}] is not inside bounds [{low}, {high}]")
        self.names: tuple[str, ...] = names
        self.priors: tuple[Prior, ...] = priors
        self.marginals: tuple[Prior, ...] = tuple(marginals)
        self.explicit_bounds: dict[str, tuple[float, float]] = {
            n: (float(explicit[n][0]), float(explicit[n][1])) for n in explicit}

    def __repr__(self) -> str:
        inner = ", ".join(f"{n}={p!r}" for n, p in zip(self.names, self.marginals))
        return f"JointPrior({inner})"

    @property
    def dim(self) -> int:
        return len(self.names)

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        """Support of each marginal (after truncation to explicit bounds)."""
        return tuple(p.bounds for p in self.marginals)

    @property
    def mean(self) -> np.ndarray:
        return np.array([p.moments[0] for p in self.marginals])

    @property
    def sd(self) -> np.ndarray:
        return np.array([p.moments[1] for p in self.marginals])

    def _theta(self, theta) -> np.ndarray:
        theta = np.asarray(theta, dtype=float)
        if theta.ndim == 0 or theta.shape[-1] != self.dim:
            raise ValueError(f"theta must have shape (..., {self.dim}) for parameters {list(self.names)}, "
                             f"got shape {theta.shape}")
        return theta

    def logpdf(self, theta):
        """Sum of marginal log densities; ``theta`` shape (..., d) -> shape (...)."""
        theta = self._theta(theta)
        total = np.zeros(theta.shape[:-1])
        for j, p in enumerate(self.marginals):
            total = total + np.asarray(p.logpdf(theta[..., j]), dtype=float)
        return _out(total)

    def ppf(self, u):
        """Map points of the unit cube, shape (..., d), to parameter space marginal by marginal."""
        u = self._theta(u)
        return np.stack([np.asarray(p.ppf(u[..., j]), dtype=float) for j, p in enumerate(self.marginals)],
                        axis=-1)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` independent draws, shape (n, d)."""
        _check_rng(rng)
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 0:
            raise ValueError(f"n must be a non-negative integer, got {n!r}")
        return np.stack([np.asarray(p.sample(rng, int(n)), dtype=float).reshape(int(n))
                         for p in self.marginals], axis=-1)
