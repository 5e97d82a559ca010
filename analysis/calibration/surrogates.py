"""Surrogates of the summary statistics for the emulator method: fitted to a training set, cheap to
evaluate anywhere.

Shapes: d free parameters, k statistics, P training points, n points predicted at once.

Surrogates (``build_surrogate(training, kind)``, kind ``"gp"`` or ``"rbf"``) are fitted on inputs scaled
to [0, 1] by the training box and outputs standardised (mean 0, sd 1 per output). Two outputs per
stat: the point means and the log variances. A log sample variance of n Gaussian replicates is biased
by ``digamma((n-1)/2) - log((n-1)/2)`` (removed) and has variance ``trigamma((n-1)/2)``; a point mean
has variance ``var / n``. These are each point's known noise.

* :class:`GPSurrogate`: per output scikit-learn's ``GaussianProcessRegressor``, kernel = signal variance
  x ARD squared exponential + a linear trend (intercept and slopes with fixed prior variance 1, centred
  on the box) + a fitted white nugget, with each point's known noise as ``alpha`` (heteroscedastic);
  the signal variance, length scales and nugget (bounded) maximise the log marginal likelihood
  (sklearn's L-BFGS-B with restarts from a fixed random state). Emulator variance of the mean: the GP's
  predictive variance of the latent function (nugget excluded); it grows away from the data.
* :class:`RBFSurrogate`: per output a :class:`scipy.interpolate.RBFInterpolator` (thin-plate spline,
  linear polynomial) with per-point smoothing ``lam x known noise / mean known noise`` (floored at
  1e-3 of the mean). ``lam`` (fixed log grid 1e-6..1e3) minimises Stein's unbiased risk estimate
  ``|y - H y|^2 + 2 sum_i H_ii noise_i - sum_i noise_i`` of the smoother with hat matrix ``H`` (exact,
  from fitting the identity).
  Emulator variance of the mean: constant per stat, ``max(0, mean(LOO residual^2 - known noise))``
  (exact LOO residuals ``e_i / (1 - H_ii)``: what the held-out error has beyond the noise of the
  held-out point means).

``surrogate.predict(theta)`` with theta (n, d) or (d,) -> :class:`EmulatorPrediction` of (n, k)
arrays: ``mean``, ``mean_var`` (emulator variance of the mean) and ``var`` (per-replicate variance =
``exp`` of the predicted log variance). It predicts anywhere; the box is enforced by the likelihood.
"""
from __future__ import annotations

import dataclasses
import hashlib
import warnings

import numpy as np
from scipy import special
from scipy.linalg import solve_triangular
from scipy.interpolate import RBFInterpolator

from .training import TrainingSet

SURROGATE_KINDS = ("gp", "rbf")


def single_threaded_blas():
    """A context in which BLAS runs on one thread: the emulator's linear algebra is on matrices of a few
    hundred rows, where a threaded BLAS on a busy machine spends far longer synchronising than computing
    (measured: a GP prediction 20 x slower under load)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


@dataclasses.dataclass(frozen=True)
class EmulatorPrediction:
    """Arrays (n, k): emulated mean, emulator variance of that mean, per-replicate variance."""

    mean: np.ndarray
    mean_var: np.ndarray
    var: np.ndarray


def _rows(values, width: int, what: str) -> np.ndarray:
    """``values`` as a (n, width) float array (a (width,) vector is one row); ValueError otherwise."""
    values = np.asarray(values, dtype=float)
    values = values[None, :] if values.ndim == 1 else values
    if values.ndim != 2 or values.shape[1] != width:
        raise ValueError(f"{what} must have shape (n, {width}) or ({width},), got {np.shape(values)}")
    return values


def _as_points(theta, d: int) -> np.ndarray:
    return _rows(theta, d, "theta")


def _log_variance_targets(var: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bias-corrected log sample variances (P, k) and their sampling variances (P, k) (Gaussian theory)."""
    half_dof = (count[:, None] - 1) / 2.0
    bias = special.digamma(half_dof) - np.log(half_dof)
    noise = special.polygamma(1, half_dof)
    return np.log(var) - bias, np.broadcast_to(noise, var.shape).copy()


@dataclasses.dataclass(frozen=True)
class _Standardised:
    """One output standardised: y = (value - centre) / scale; noise in standardised units."""

    values: np.ndarray
    noise: np.ndarray
    centre: float
    scale: float

    @classmethod
    def of(cls, values, noise) -> "_Standardised":
        centre = float(np.mean(values))
        scale = float(np.std(values))
        scale = scale if scale > 0 else 1.0
        return cls((values - centre) / scale, np.asarray(noise) / scale ** 2, centre, scale)


class Surrogate:
    """Common part: the training set, its box, the unit scaling and prediction. Subclasses fit
    ``mean_models`` and ``log_var_models`` (one per stat), or override ``_predict_unit(unit (n, d)) ->
    (mean, mean_var, log_var)`` (each (n, k), original units), e.g. a test stub with known functions."""

    kind = "base"

    def __init__(self, training: TrainingSet):
        self.training = training
        self.lower = np.array(training.lower, dtype=float)
        self.upper = np.array(training.upper, dtype=float)
        self.correlation = np.array(training.correlation, dtype=float)
        self.names = training.names
        self.columns = training.columns

    @property
    def d(self) -> int:
        return len(self.lower)

    @property
    def k(self) -> int:
        return len(self.columns)

    def to_unit(self, theta) -> np.ndarray:
        return (_as_points(theta, self.d) - self.lower) / (self.upper - self.lower)

    def inside(self, theta) -> np.ndarray:
        """(n,) whether each point lies in the training box (bounds included)."""
        theta = _as_points(theta, self.d)
        return np.all((theta >= self.lower) & (theta <= self.upper), axis=1)

    def fit(self, output_model) -> None:
        """One ``output_model(unit points, standardised output)`` per stat for the means and for the
        log variances."""
        unit = self.to_unit(self.training.points)
        means, logs = self.outputs()
        with single_threaded_blas():
            self.mean_models = [output_model(unit, out) for out in means]
            self.log_var_models = [output_model(unit, out) for out in logs]

    def outputs(self) -> tuple[list[_Standardised], list[_Standardised]]:
        """Standardised training outputs: per stat the point means, then the log variances."""
        t = self.training
        log_var, log_noise = _log_variance_targets(t.var, t.count)
        means = [_Standardised.of(t.mean[:, j], t.var[:, j] / t.count) for j in range(t.k)]
        logs = [_Standardised.of(log_var[:, j], log_noise[:, j]) for j in range(t.k)]
        return means, logs

    def predict(self, theta) -> EmulatorPrediction:
        """Emulated mean, its emulator variance and the per-replicate variance, each (n, k)."""
        mean, mean_var, log_var = self._predict_unit(self.to_unit(theta))
        return EmulatorPrediction(mean=mean, mean_var=mean_var, var=np.exp(log_var))

    def _predict_unit(self, unit):
        """From the fitted per-stat models (``mean_models``, ``log_var_models``: ``predict(unit) ->
        (mean, var)`` in standardised units, ``output`` their scaling), back in original units."""
        mean, mean_var, log_var = (np.empty((len(unit), self.k)) for _ in range(3))
        for j, model in enumerate(self.mean_models):
            m, v = model.predict(unit)
            out = model.output
            mean[:, j], mean_var[:, j] = out.centre + out.scale * m, out.scale ** 2 * v
        for j, model in enumerate(self.log_var_models):
            m, _ = model.predict(unit)
            log_var[:, j] = model.output.centre + model.output.scale * m
        return mean, mean_var, log_var

    @property
    def fingerprint(self) -> str:
        """Hash of the kind and the training data (what a stored chain must have been run with)."""
        t = self.training
        digest = hashlib.sha256(self.kind.encode())
        for array in (t.points, t.mean, t.var, t.count, t.correlation):
            digest.update(np.ascontiguousarray(array, dtype=float).tobytes())
        digest.update(repr((t.names, t.columns)).encode())
        return digest.hexdigest()[:32]


class _SklearnGP:
    """One output: :class:`sklearn.gaussian_process.GaussianProcessRegressor` on unit inputs centred on the
    box (x - 0.5), kernel ``ConstantKernel * RBF(ARD length scales) + DotProduct(sigma_0 = 1, fixed) +
    WhiteKernel`` (the linear trend has intercept and slopes of prior variance 1, smallest in the middle
    of the box), ``alpha`` = each point's known noise. sklearn maximises the log marginal likelihood
    (L-BFGS-B from the starting values and ``RESTARTS`` log-uniform restarts drawn with ``random_state``
    0, so a fit is deterministic)."""

    RESTARTS = 3
    SIGNAL_BOUNDS = (1e-3, 1e2)
    LENGTH_BOUNDS = (0.03, 30.0)
    NUGGET_BOUNDS = (1e-8, 10.0)

    def __init__(self, x: np.ndarray, output: _Standardised):
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import RBF, ConstantKernel, DotProduct, WhiteKernel

        self.output = output
        d = x.shape[1]
        kernel = (ConstantKernel(1.0, self.SIGNAL_BOUNDS) * RBF(np.full(d, 0.5), self.LENGTH_BOUNDS)
                  + DotProduct(sigma_0=1.0, sigma_0_bounds="fixed")
                  + WhiteKernel(1e-3, self.NUGGET_BOUNDS))
        self.gp = GaussianProcessRegressor(kernel, alpha=np.asarray(output.noise, dtype=float) + 1e-10,
                                           n_restarts_optimizer=self.RESTARTS, random_state=0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # ConvergenceWarning at a bound: the bound is the answer
            self.gp.fit(x - 0.5, output.values)
        self.nugget = float(self.gp.kernel_.k2.noise_level)

    def covariance(self, unit: np.ndarray) -> np.ndarray:
        """(n, n) latent posterior covariance at unit points (n, d), standardised units, nugget left out."""
        gp = self.gp
        centred = unit - 0.5
        v = solve_triangular(gp.L_, gp.kernel_(centred, gp.X_train_).T, lower=True, check_finite=False)
        prior = gp.kernel_(centred) - self.nugget * np.eye(len(unit))
        return prior - v.T @ v

    @property
    def length_scales(self) -> np.ndarray:
        """The fitted ARD length scales (d,), in units of the training box."""
        return np.atleast_1d(self.gp.kernel_.k1.k1.k2.length_scale)

    def predict(self, unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Latent mean and variance (n,) at unit points (n, d), in standardised units: sklearn's predictive
        equations on its fitted attributes (``kernel_``, ``X_train_``, ``alpha_``, ``L_``; what
        ``GaussianProcessRegressor.predict`` computes, without its per-call input checks, which cost more
        than the algebra inside an MCMC). The fitted nugget is noise, not emulator uncertainty, so the
        latent variance leaves it out."""
        gp = self.gp
        centred = unit - 0.5
        cross = gp.kernel_(centred, gp.X_train_)                               # (n, P)
        mean = cross @ gp.alpha_
        v = solve_triangular(gp.L_, cross.T, lower=True, check_finite=False)
        prior = gp.kernel_.diag(centred) - self.nugget
        return mean, np.maximum(prior - np.einsum("ij,ij->j", v, v), 1e-12 * prior)


class GPSurrogate(Surrogate):
    """scikit-learn GPs (see the module docstring): one per stat for the mean, one per stat for log variance."""

    kind = "gp"

    def __init__(self, training: TrainingSet):
        super().__init__(training)
        self.fit(_SklearnGP)


class _SmoothedRBF:
    """One output: thin-plate spline RBF with per-point smoothing ``lam x relative known noise``; ``lam``
    minimises the unbiased risk estimate (Mallows' Cp / SURE) over a fixed log grid."""

    LAMBDAS = 10.0 ** np.arange(-6.0, 3.01, 0.75)

    def __init__(self, x: np.ndarray, output: _Standardised):
        self.x = x
        self.output = output
        noise = np.asarray(output.noise, dtype=float)
        typical = float(np.mean(noise)) if np.mean(noise) > 0 else 1.0
        self.weights = np.maximum(noise / typical, 1e-3)
        fits = [self._risk(lam) for lam in self.LAMBDAS]
        best = int(np.argmin([risk for risk, _ in fits]))
        self.smoothing = float(self.LAMBDAS[best])
        self.loo_residuals = fits[best][1]
        self.model = self._interpolator(self.output.values, self.smoothing)
        self.emulator_var = max(0.0, float(np.mean(self.loo_residuals ** 2 - noise)))  # standardised units

    def _interpolator(self, values, lam: float):
        return RBFInterpolator(self.x, values, kernel="thin_plate_spline", degree=1,
                               smoothing=lam * self.weights)

    def _risk(self, lam: float) -> tuple[float, np.ndarray]:
        """(SURE = |y - H y|^2 + 2 sum H_ii noise_i - sum noise_i, leave-one-out residuals
        e_i / (1 - H_ii)) of the linear smoother with hat matrix H (fitted values = H y)."""
        size = len(self.x)
        hat = self._interpolator(np.eye(size), lam)(self.x)
        y, noise = self.output.values, self.output.noise
        residuals = y - hat @ y
        leverage = np.diag(hat)
        risk = float(np.sum(residuals ** 2) + 2.0 * np.sum(leverage * noise) - np.sum(noise))
        return risk, residuals / (1.0 - np.minimum(leverage, 1.0 - 1e-8))

    def predict(self, unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.model(unit), np.full(len(unit), self.emulator_var)


class RBFSurrogate(Surrogate):
    """Thin-plate spline RBF regression (see the module docstring) for means and log variances."""

    kind = "rbf"

    def __init__(self, training: TrainingSet):
        super().__init__(training)
        self.fit(_SmoothedRBF)


def build_surrogate(training: TrainingSet, kind: str = "gp") -> Surrogate:
    """Fit the surrogate ``kind`` ("gp" or "rbf") to ``training``."""
    if kind == "gp":
        return GPSurrogate(training)
    if kind == "rbf":
        return RBFSurrogate(training)
    raise ValueError(f"kind: unknown surrogate {kind!r}; allowed: {', '.join(SURROGATE_KINDS)}")


def prior_outside_box(prior, surrogate: Surrogate) -> list[str]:
    """Plain warnings for the parameters whose prior support reaches beyond the training box (the
    posterior is truncated there)."""
    out = []
    for name, (low, high), box_low, box_high in zip(prior.names, prior.bounds, surrogate.lower, surrogate.upper):
        if low < box_low or high > box_high:
            out.append(f"{name}: prior support [{low:g}, {high:g}] reaches beyond the swept range "
                       f"[{box_low:g}, {box_high:g}]; the posterior is truncated to the swept range")
    return out
