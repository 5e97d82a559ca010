"""Where a run's state stopped being finite: the step and the boid, for a failed run's reason.

``where_non_finite(preset, seed, obs)`` is the reason of a run whose records hold a non-finite position or
velocity: the first step and the lowest-index boid where it began, whether the velocity or the position,
NaN or infinite, and the likely cause (a plug-in's steer returning a force that is not finite, or forces
that overflow). Records taken every ``k`` > 1 steps only bracket the step, so the run is simulated again
from its seed, recording every step, up to the first record that shows it (deterministic: the same run; it
costs at most the run again, and only when it failed). ``check_finite_run(preset, seed, obs)`` raises
:class:`observables.summary.NonFiniteState` with that reason. Used by the sweep worker and by ``flocksweep
simulate`` (:mod:`sweeps.single`); light: numpy and the simulator only.
"""
from __future__ import annotations

import numpy as np

from flocksweep.observables.summary import NonFiniteState
from flocksweep.simcore import simulate
from flocksweep.simcore.registry import is_builtin


def _first_bad(obs):
    """(index of the first record with a non-finite position or velocity, the boids it holds), or (None, None)."""
    bad = ~(np.isfinite(obs.pos).all(axis=2) & np.isfinite(obs.vel).all(axis=2))   # (records, boids)
    rows = np.flatnonzero(bad.any(axis=1))
    return (int(rows[0]), np.flatnonzero(bad[rows[0]])) if len(rows) else (None, None)


def where_non_finite(preset, seed, obs) -> str:
    """The reason of a run (``preset``, ``seed``) whose records ``obs`` hold a non-finite position or
    velocity (module docstring)."""
    record, boids = _first_bad(obs)
    if record is None:
        return "non-finite position or velocity"
    dt, every = preset.run.dt, obs.record_every
    pos, vel = obs.pos[record], obs.vel[record]
    first, last = (record - 1) * every, record * every - 1   # the steps that can have made it
    if record and every > 1:
        fine = simulate(preset.model, preset.init, seed, record * every * dt, dt, 1)
        fine_record, fine_boids = _first_bad(fine)
        if fine_record:   # the same run: seen again, at its one step (else the records' bracket stands)
            boids, pos, vel = fine_boids, fine.pos[fine_record], fine.vel[fine_record]
            first = last = fine_record - 1
    boid = int(boids[0])
    what, value = ("velocity", vel[boid]) if not np.isfinite(vel[boid]).all() else ("position", pos[boid])
    kind = "NaN" if np.isnan(value).any() else "infinite"
    others = f" (and {len(boids) - 1} more boids)" if len(boids) > 1 else ""
    if record == 0:
        return f"non-finite state: boid {boid}'s initial {what} is {kind}{others}"
    when = (f"in step {first} (t = {first * dt:g} to {(first + 1) * dt:g} s)" if first == last else
            f"between steps {first} and {last} (t = {first * dt:g} to {(last + 1) * dt:g} s)")
    cause = ("a steering force that is not finite: the plug-in's steer returned NaN or inf, or a force so "
             "large that the motion overflowed" if not is_builtin(preset.model.dynamics) else
             "forces so large that the motion overflowed")
    return f"non-finite state: boid {boid}'s {what} became {kind} {when}{others}; {cause}"


def check_finite_run(preset, seed, obs) -> None:
    """:class:`NonFiniteState` naming the step and boid (:func:`where_non_finite`) when ``obs`` holds a
    non-finite position or velocity."""
    if not (np.isfinite(obs.pos).all() and np.isfinite(obs.vel).all()):
        raise NonFiniteState(where_non_finite(preset, seed, obs))
