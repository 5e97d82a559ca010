"""What a calibration asks of the model and of the machine, checked before anything is written.

* ``check_support(where, key, support, preset, integer)``: both ends of the support the chain explores
  (the prior's, cut to ``bounds``) must be allowed values of the preset ``key``; integer keys are
  rounded as the simulator rounds them (Python's ``round``); an end that is itself excluded but whose
  inside is allowed (``field_deg`` at 0: the range is (0, 360]) is fine, since the chain never proposes
  it. ConfigError at ``where`` (``parameters.<name>.prior`` or ``.bounds``) naming the end and why.
* ``check_memory(preset, parameters, n_sim)``: one evaluation runs ``n_sim`` replicates at once; they
  must fit in memory for the largest ``init.n`` the parameters allow (:func:`sweeps.budget.check_runs`).
"""
from __future__ import annotations

import numpy as np

from simcore.params import Preset
from simcore.schema import ConfigError
from sweeps.budget import check_runs


def check_support(where: str, key: str, support: tuple[float, float], preset: Preset, integer: bool) -> None:
    """Both ends of the support the chain explores must be allowed values of ``key`` (see the module
    docstring); the message names ``where`` and the offending end."""
    low, high = support
    for end, inward in ((low, high), (high, low)):
        candidates = [end, float(np.nextafter(end, inward))]
        if integer:
            candidates = [int(round(v)) for v in candidates]
        errors = []
        for value in candidates:
            try:
                preset.replace({key: value})
                break
            except ConfigError as err:
                errors.append(err)
        else:
            raise ConfigError(where, f"the prior's support [{low:g}, {high:g}] reaches {candidates[0]!r}, where "
                                     f"{errors[0]}; keep it inside the allowed range (e.g. with bounds = "
                                     "[low, high])") from None


def check_memory(preset: Preset, parameters, n_sim: int) -> None:
    """``n_sim`` runs at once (one batched evaluation) of the largest flock the parameters allow must fit."""
    n, key = preset.init.n, "run.n"
    for parameter in parameters:
        if parameter.key == "init.n" and parameter.bounds[1] > n:
            n, key = parameter.bounds[1], f"parameters.{parameter.name}.prior"
    check_runs(key, n, preset.run.n_steps, preset.run.record_every, copies=n_sim,
               what=f"a run of {n:,.0f} boids ({key})")
