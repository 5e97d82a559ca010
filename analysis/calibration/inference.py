"""Calibration results in the Bayesian ecosystem's format: ArviZ ``InferenceData``, stored as
``posterior.nc`` (NetCDF4 groups, readable by ``arviz.from_netcdf`` and by xarray).

Shapes: W walkers, T steps, B burn-in steps, d free parameters, k target statistics, m observed rows,
P predictive draws.

Contract
--------
``chain_inference_data(config, result, burn, *, predictive=None, predictive_source=None, prior_draws=1000,
attrs=None) -> arviz.InferenceData``
    * ``posterior``: one variable per free parameter, named by it (attrs: its preset ``key``), dims
      ``(chain, draw)`` = (W walkers, T - B steps after the burn-in); ``warmup_posterior`` the B burn-in
      steps (when B > 0). The walkers of an ensemble are not independent chains: R-hat across them
      compares the walkers' distributions, a useful check, not Gelman and Rubin's original setting.
    * ``sample_stats`` (and ``warmup_sample_stats``): ``lp`` (the log posterior emcee sampled),
      ``log_prior``, ``log_likelihood`` (= lp - log_prior: BSL's noisy synthetic estimate, or the
      emulated one), ``accepted`` (bool: the walker moved at this step; False at step 0, whose
      previous position is not stored), and ``walker_acceptance`` (dims ``chain``: emcee's acceptance
      fraction of each walker over the whole chain).
    * ``posterior_predictive``: one variable per target column, dims ``(chain, draw)`` = (1, P), a
      simulated dataset per posterior draw (coords ``source_chain``, ``source_draw``: the walker and
      step of the draw it was simulated at); only when ``predictive`` (P, k) is given.
    * ``observed_data``: one variable per target column, dims ``(observation,)`` (m rows).
    * ``constant_data``: ``observation_cov`` (``statistic``, ``statistic_``) for mean/sd targets, and
      ``truth_<name>`` when the targets give the truth they were simulated at.
    * ``prior``: ``prior_draws`` draws of the joint prior, ``generator(seed, Tag.PRIOR)``.
    * attrs: ``calibration``, ``method``, ``seed``, ``burn``, ``inference_library`` ("emcee"),
      ``flocksweep_version``, ``created_at``, plus ``attrs``.

``optimum_inference_data(config, theta, recheck, attrs=None) -> InferenceData``: ``optimize`` has no
posterior: ``constant_data`` holds the optimum ``optimum_<name>``, ``posterior_predictive`` the re-check
replicates at it (as above, chain 1), with ``observed_data``, ``prior`` and the constant data above.

``draws_inference_data(config, draws, *, chains=4, predictive=None, attrs=None)``: independent
posterior draws (npe) split into chains, with the same other groups.

``write_inference_data(idata, path)``: atomically (``sweeps.files.atomic_path``), engine h5netcdf. The file
is built in memory (the groups and attributes ArviZ's ``to_netcdf`` writes, zlib on numeric variables) and
its bytes then written by plain writes: HDF5 never writes to the disk itself, so a full disk is one
``WriteFailed`` (exit 4) and leaves no half-closed HDF5 file, whose library would retry its writes while
the interpreter exits and die of SIGSEGV (issue 42).
``load_calibration_results(out_dir) -> InferenceData``: ``arviz.from_netcdf(out_dir / "posterior.nc")``.
``arviz_diagnostics(idata) -> DataFrame``: per parameter ``r_hat, ess_bulk, ess_tail, mcse_mean, mcse_sd``
(``arviz.summary(kind="diagnostics")`` on the posterior).
``arviz()``: the arviz module, imported quietly (its import-time FutureWarning about the 1.0 refactor).
"""
from __future__ import annotations

import io
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from flocksweep.sweeps.files import atomic_path
from flocksweep.sweeps.seeds import Tag, generator

POSTERIOR_FILE = "posterior.nc"
VERSION = "0.1.0"


def arviz():
    """The arviz module (its FutureWarning on import about the coming refactor silenced)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az
    return az


def _accepted(chain: np.ndarray) -> np.ndarray:
    """(W, T) whether each walker moved at each step (False at step 0)."""
    moved = np.zeros(chain.shape[:2], dtype=bool)
    moved[1:] = np.any(chain[1:] != chain[:-1], axis=-1)
    return moved.T


def _split(array: np.ndarray, burn: int) -> tuple[np.ndarray, np.ndarray]:
    """(walker-major array after the burn-in, the burn-in) from a (T, W, ...) array."""
    array = np.swapaxes(np.asarray(array), 0, 1)
    return array[:, burn:], array[:, :burn]


def _samples(variables: dict, *, chain_coords=None) -> xr.Dataset:
    """A (chain, draw) Dataset of arrays shaped (chains, draws)."""
    dataset = xr.Dataset({name: (("chain", "draw"), np.asarray(values)) for name, values in variables.items()})
    first = next(iter(variables.values()))
    return dataset.assign_coords(chain=np.arange(np.shape(first)[0]), draw=np.arange(np.shape(first)[1]))


def _observed(config) -> xr.Dataset:
    targets = config.targets
    return xr.Dataset({column: ("observation", np.asarray(targets.observed[:, j], dtype=float))
                       for j, column in enumerate(targets.columns)},
                      coords={"observation": np.arange(len(targets.observed))})


def _constant(config, extra: dict | None = None) -> xr.Dataset | None:
    targets = config.targets
    variables = {}
    if targets.cov is not None:
        variables["observation_cov"] = (("statistic", "statistic_"), np.asarray(targets.cov, dtype=float))
    for name, value in (targets.truth or {}).items():
        variables[f"truth_{name}"] = ((), float(value))
    variables.update({key: ((), float(value)) for key, value in (extra or {}).items()})
    if not variables:
        return None
    coords = {"statistic": list(targets.columns), "statistic_": list(targets.columns)} \
        if targets.cov is not None else {}
    return xr.Dataset(variables, coords=coords)


def _prior(config, count: int) -> xr.Dataset:
    draws = np.asarray(config.prior.sample(generator(config.seed, Tag.PRIOR), count), dtype=float)
    draws = draws.reshape(count, config.dim)
    return _samples({name: draws[None, :, j] for j, name in enumerate(config.names)})


def _predictive(config, predictive, source=None) -> xr.Dataset:
    predictive = np.asarray(predictive, dtype=float)
    dataset = _samples({column: predictive[None, :, j] for j, column in enumerate(config.targets.columns)})
    if source is not None:
        walker, step = np.asarray(source, dtype=int).T
        dataset = dataset.assign_coords(source_chain=("draw", walker), source_draw=("draw", step))
    return dataset


def _base_attrs(config, extra: dict | None) -> dict:
    attrs = {"calibration": config.name, "method": config.method.kind, "seed": int(config.seed),
             "inference_library": "emcee", "flocksweep_version": VERSION,
             "created_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    attrs.update({k: v for k, v in (extra or {}).items() if isinstance(v, (str, int, float, bool))})
    return attrs


def _with_attrs(groups: dict, attrs: dict) -> dict:
    for dataset in groups.values():
        dataset.attrs.update(attrs)
    return groups


def chain_inference_data(config, result, burn: int, *, predictive=None, predictive_source=None,
                         prior_draws: int = 1000, attrs: dict | None = None):
    """InferenceData of a chain (see the module docstring)."""
    az = arviz()
    chain = np.asarray(result.chain, dtype=float)
    lp = np.asarray(result.log_prob, dtype=float)
    log_prior = np.asarray(config.prior.logpdf(chain.reshape(-1, chain.shape[-1])), dtype=float).reshape(lp.shape)
    posterior, warmup = {}, {}
    for j, name in enumerate(config.names):
        posterior[name], warmup[name] = _split(chain[:, :, j], burn)
    stats, warm_stats = {}, {}
    for key, values in (("lp", lp), ("log_prior", log_prior), ("log_likelihood", lp - log_prior),
                        ("accepted", _accepted(chain).T)):
        stats[key], warm_stats[key] = _split(values, burn)
    groups = {"posterior": _samples(posterior), "sample_stats": _samples(stats), "observed_data": _observed(config),
              "prior": _prior(config, prior_draws)}
    for name, key in zip(config.names, config.keys):
        groups["posterior"][name].attrs["key"] = key
    groups["sample_stats"]["walker_acceptance"] = ("chain", np.asarray(result.acceptance_fraction, dtype=float))
    constant = _constant(config)
    if constant is not None:
        groups["constant_data"] = constant
    if predictive is not None:
        groups["posterior_predictive"] = _predictive(config, predictive, predictive_source)
    if burn:
        groups.update(warmup_posterior=_samples(warmup), warmup_sample_stats=_samples(warm_stats))
    groups = _with_attrs(groups, {**_base_attrs(config, attrs), "burn": int(burn)})
    return az.InferenceData(**groups)


def optimum_inference_data(config, theta, recheck, attrs: dict | None = None):
    """InferenceData of an optimisation (see the module docstring)."""
    az = arviz()
    optimum = {f"optimum_{name}": value for name, value in zip(config.names, theta)}
    groups = {"posterior_predictive": _predictive(config, recheck), "observed_data": _observed(config),
              "constant_data": _constant(config, optimum), "prior": _prior(config, 1000)}
    return az.InferenceData(**_with_attrs(groups, _base_attrs(config, attrs)))


def draws_inference_data(config, draws, *, chains: int = 4, predictive=None, attrs: dict | None = None):
    """InferenceData of independent posterior draws (S, d) (the npe method): ``posterior`` with the
    draws split into ``chains`` chains of S // chains draws (R-hat and ESS then check them as any
    sample), ``posterior_predictive``, ``observed_data``, ``constant_data``, ``prior``; attrs as above
    with ``inference_library`` "flowjax"."""
    az = arviz()
    draws = np.asarray(draws, dtype=float)
    per = len(draws) // chains
    kept = draws[:per * chains].reshape(chains, per, draws.shape[1])
    groups = {"posterior": _samples({name: kept[:, :, j] for j, name in enumerate(config.names)}),
              "observed_data": _observed(config), "prior": _prior(config, 1000)}
    for name, key in zip(config.names, config.keys):
        groups["posterior"][name].attrs["key"] = key
    constant = _constant(config)
    if constant is not None:
        groups["constant_data"] = constant
    if predictive is not None:
        groups["posterior_predictive"] = _predictive(config, predictive)
    return az.InferenceData(**_with_attrs(groups, {**_base_attrs(config, attrs), "inference_library": "flowjax"}))


def netcdf_bytes(idata) -> bytes:
    """``idata`` as the bytes of the NetCDF file ArviZ's ``to_netcdf(engine="h5netcdf")`` writes, built in
    memory (module docstring)."""
    buffer, mode = io.BytesIO(), "w"
    if idata._attrs:
        xr.Dataset(attrs=idata._attrs).to_netcdf(buffer, mode=mode, engine="h5netcdf", group="/")
        mode = "a"
    for group in idata._groups_all:
        data = getattr(idata, group)
        encoding = {name: {"zlib": True} for name, values in data.variables.items()
                    if values.dtype.kind in "biufcS"}
        data.to_netcdf(buffer, mode=mode, group=f"/{group}", engine="h5netcdf", encoding=encoding)
        mode = "a"
    return buffer.getvalue()


def write_inference_data(idata, path) -> Path:
    """``idata`` to NetCDF at ``path``, atomically (built in memory, then written: module docstring)."""
    path = Path(path)
    content = netcdf_bytes(idata)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(content)
    return path


def load_calibration_results(out_dir):
    """The InferenceData of a calibration's output folder (``posterior.nc``)."""
    path = Path(out_dir) / POSTERIOR_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: not a calibration output folder, or written before "
                                "posterior.nc existed (run the calibration again)")
    return arviz().from_netcdf(str(path))


def arviz_diagnostics(idata) -> pd.DataFrame:
    """R-hat, bulk and tail ESS and MCSE per parameter, from ArviZ."""
    az = arviz()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        table = az.summary(idata, kind="diagnostics", round_to="none")
    return table[["r_hat", "ess_bulk", "ess_tail", "mcse_mean", "mcse_sd"]].rename_axis("parameter")
