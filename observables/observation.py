"""The observation model: a simulated run seen the way a tracking system saw a real flock.

An :class:`Observation` (the ``[observation]`` table of a calibration file; the options of
``flocksweep measure``) states how a flock was measured:

* ``interval`` (s): the sampling interval, the spacing of the records;
* ``velocity_interval`` (s, a whole multiple of ``interval``; default ``interval``): velocities are
  differences of positions over it, or ``"recorded"``: the tracker's own velocities (the simulator's,
  for a simulated run);
* ``max_gap`` (s, default 2.5 x ``interval``): gaps up to this long are bridged by linear interpolation;
* ``detection_probability`` (default 1): the chance that an individual is detected at a sample;
* ``position_sd`` (length units, default 0): sd of independent Gaussian noise on each coordinate;
* ``projection`` ("none", or the plane kept: "xz", "xy", "yz"): a 3-D run seen in 2-D. The simulator's
  vertical axis is y, so "xz" is the horizontal plane of a 3-D run, a view from above. A 2-D model's
  world moves in the x-y plane: a projection that drops x or y would measure one axis, so it is refused
  (:func:`check_projection` at configuration time; :func:`detect` refuses any projection dropping an
  axis a planar run moves along, naming its plane). A planar run's observed flock is 2-D.

Measured tracks already carry their detection losses and noise: for them only ``interval``,
``velocity_interval`` and ``max_gap`` act, through :func:`~observables.resample.resample`.
Tracks a simulator wrote (an external command's output) go through :func:`observe_tracks`: put on the
sampling grid, then projected, detected and given noise the same way, and resampled.
A simulated run goes through :func:`observe_run`: its records at the sampling interval are projected,
each sample is detected with ``detection_probability`` and gets position noise (:func:`detect`, giving
the samples a tracker would have delivered), then the same :func:`resample` makes the records. So the
simulated statistics are measured the way the real ones were, by the same code.

Randomness: a run's observation stream is the third child (spawn key 2) of its seed's SeedSequence
(the simulator uses the first two: :func:`simcore.rng.run_streams`); its first child draws detections,
its second the noise. The same seed always gives the same observed flock, and the noise does not
depend on which other runs are in the batch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from flocksweep.simcore.rng import seed_sequence
from flocksweep.simcore.schema import ConfigError, check_non_negative, check_positive, check_within

from .observed import ObservedFlock
from .resample import RECORDED, SNAP, resample, velocity_steps
from .tracks import RawFlock

PROJECTIONS = {"none": None, "xy": 2, "xz": 1, "yz": 0}   # the plane kept -> the axis set to 0
OBSERVATION_CHILD = 2      # spawn key of a run seed's observation stream
AXIS_NAMES = "xyz"


def check_projection(observation: "Observation", dimensions: int, key: str = "observation.projection") -> None:
    """ConfigError when the projection drops an axis a world of ``dimensions`` moves along: a 2-D world
    moves in the x-y plane, so only "none" and "xy" keep it."""
    axis = PROJECTIONS[observation.projection]
    if dimensions == 2 and axis is not None and axis != 2:
        raise ConfigError(key, f"got {observation.projection!r}, which drops {AXIS_NAMES[axis]}; the model's 2-D "
                               "world moves in the x-y plane, so its runs would be measured along one axis: use "
                               'projection = "xy" (or "none": 2-D runs are already planar)')


def moving_plane(pos: np.ndarray) -> int | None:
    """The axis along which every position is one constant (the run moves in the plane of the other two),
    or None when it moves along all three."""
    for axis in (2, 1, 0):
        values = pos[..., axis]
        if values.size and np.all(values == values.flat[0]):
            return axis
    return None


def _check_run_plane(pos: np.ndarray, projection: str) -> None:
    """ValueError when ``projection`` drops an axis a planar run moves along (naming the run's plane)."""
    dropped, still = PROJECTIONS[projection], moving_plane(pos)
    if dropped is not None and still is not None and dropped != still:
        plane = "-".join(AXIS_NAMES[a] for a in range(3) if a != still)
        raise ValueError(f"projection {projection!r} drops {AXIS_NAMES[dropped]}, along which the run moves: it "
                         f"moves in the {plane} plane ({AXIS_NAMES[still]} is constant); use projection = "
                         f"\"{plane.replace('-', '')}\" or \"none\"")


@dataclass(frozen=True)
class Observation:
    """How a flock was measured (see the module docstring)."""

    interval: float = field(metadata={"expected": "the sampling interval in seconds, a number > 0"})
    velocity_interval: Any = field(default=None, metadata={"expected": 'seconds (a whole multiple of interval) '
                                                                       'or "recorded"'})
    max_gap: float | None = None
    detection_probability: float = 1.0
    position_sd: float = 0.0
    projection: Literal["none", "xz", "xy", "yz"] = "none"

    def __post_init__(self):
        check_positive("interval", self.interval)
        if self.velocity_interval is not None:
            value = self.velocity_interval
            if isinstance(value, bool) or not isinstance(value, (int, float, str)):
                raise ConfigError("velocity_interval", f'got {value!r}; expected seconds or "recorded"')
            try:
                velocity_steps(value, self.interval)
            except ValueError as err:
                raise ConfigError("velocity_interval", str(err).split(": ", 1)[-1]) from None
        if self.max_gap is not None and not (math.isfinite(self.max_gap) and self.max_gap >= self.interval):
            raise ConfigError("max_gap", f"got {self.max_gap!r}; must be at least the interval {self.interval!r} s")
        check_within("detection_probability", self.detection_probability, 0.0, 1.0, lo_open=True)
        check_non_negative("position_sd", self.position_sd)

    @property
    def dims(self) -> int:
        return 3 if self.projection == "none" else 2

    @property
    def recorded_velocities(self) -> bool:
        return self.velocity_interval == RECORDED

    def record_every(self, dt: float) -> int:
        """Simulation steps per sample: interval / dt, which must be a whole number."""
        steps = self.interval / dt
        if abs(steps - round(steps)) > SNAP * max(1.0, steps) or round(steps) < 1:
            raise ConfigError("interval", f"got {self.interval!r}; must be a whole multiple of the run's dt = {dt!r}")
        return int(round(steps))

    def describe(self) -> str:
        velocity = ("recorded velocities" if self.recorded_velocities else
                    f"velocities over {self.velocity_interval or self.interval:g} s")
        parts = [f"every {self.interval:g} s", velocity]
        if self.detection_probability < 1:
            parts.append(f"detection probability {self.detection_probability:g}")
        if self.position_sd > 0:
            parts.append(f"position noise sd {self.position_sd:g}")
        if self.projection != "none":
            parts.append(f"projected onto {self.projection}")
        return ", ".join(parts)


def observation_streams(seed) -> tuple[np.random.Generator, np.random.Generator]:
    """(detection generator, noise generator) of a run seed (see the module docstring)."""
    root = seed_sequence(seed)
    child = np.random.SeedSequence(root.entropy, spawn_key=tuple(root.spawn_key) + (OBSERVATION_CHILD,),
                                   pool_size=root.pool_size)
    detection, noise = child.spawn(2)
    return np.random.Generator(np.random.PCG64(detection)), np.random.Generator(np.random.PCG64(noise))


def _samples_every(obs, interval: float) -> int:
    record = obs.dt * obs.record_every
    ratio = interval / record
    k = int(round(ratio))
    if k < 1 or abs(ratio - k) > SNAP * max(1.0, ratio):
        raise ValueError(f"observation interval {interval!r} s is not a whole multiple of the run's record "
                         f"interval {record!r} s")
    return k


def detect(obs, observation: Observation, seed) -> RawFlock:
    """The samples a tracker would deliver for a simulated run (see the module docstring)."""
    k = _samples_every(obs, observation.interval)
    times = obs.times[::k]
    pos = np.array(obs.pos[::k], dtype=np.float64)
    vel = np.array(obs.vel[::k], dtype=np.float64)
    _check_run_plane(pos, observation.projection)
    planar = observation.dims == 2 or moving_plane(pos) == 2      # a 2-D model's run is 2-D tracks
    axis = PROJECTIONS[observation.projection]
    kept = [a for a in range(3) if a != axis]
    if axis is not None:
        pos[:, :, axis] = 0.0
        vel[:, :, axis] = 0.0
    detection_rng, noise_rng = observation_streams(seed)
    n_records, n = pos.shape[:2]
    detected = np.ones((n_records, n), dtype=bool)
    if observation.detection_probability < 1:
        detected = detection_rng.random((n_records, n)) < observation.detection_probability
    if observation.position_sd > 0:
        pos[:, :, kept] += noise_rng.normal(0.0, observation.position_sd, (n_records, n, len(kept)))
    ind, rec = np.nonzero(detected.T)          # individual-major, times in order
    return RawFlock(name="simulated", ids=np.arange(n), t=times[rec], ind=ind.astype(np.int64), pos=pos[rec, ind],
                    vel=vel[rec, ind], pattern=np.asarray(obs.pattern, dtype=np.int64), dims=2 if planar else 3)


def observe_run(obs, observation: Observation, seed) -> ObservedFlock:
    """A simulated run as the observer sees it: :func:`detect`, then the same resampling as measured tracks."""
    return resample(detect(obs, observation, seed), observation.interval, observation.max_gap,
                    observation.velocity_interval)


def observe_tracks(raw: RawFlock, observation: Observation, seed) -> ObservedFlock:
    """Tracks a simulator wrote (an external command's output) as the observer sees them: each individual's
    track on the observation's sampling grid (:func:`~observables.resample.resample`: interpolated there,
    velocities as recorded, else differenced over one interval), projected, each sample detected with
    ``detection_probability`` and given position noise from the seed's observation stream (as
    :func:`detect`), then resampled as measured tracks are (:func:`observe_run`'s second half)."""
    grid = resample(raw, observation.interval, None, RECORDED if raw.vel is not None else None)
    pos, vel = np.array(grid.pos, dtype=np.float64), np.array(grid.vel, dtype=np.float64)
    axis = PROJECTIONS[observation.projection]
    kept = [a for a in range(3) if a != axis]
    if axis is not None:
        pos[:, :, axis] = 0.0
        vel[:, :, axis] = 0.0
    detection_rng, noise_rng = observation_streams(seed)
    n_records, n = pos.shape[:2]
    detected = np.array(grid.present, dtype=bool)
    if observation.detection_probability < 1:
        detected &= detection_rng.random((n_records, n)) < observation.detection_probability
    if observation.position_sd > 0:
        pos[:, :, kept] += noise_rng.normal(0.0, observation.position_sd, (n_records, n, len(kept)))
    ind, rec = np.nonzero(detected.T)
    dims = observation.dims if axis is not None else raw.dims
    seen = RawFlock(name=raw.name, ids=raw.ids, t=grid.times[rec], ind=ind.astype(np.int64), pos=pos[rec, ind],
                    vel=vel[rec, ind], pattern=raw.pattern, dims=dims)
    return resample(seen, observation.interval, observation.max_gap, observation.velocity_interval)


def predicted_velocity_sd(observation: Observation) -> float:
    """Velocity noise sd per coordinate that position noise causes: position_sd sqrt(2) / velocity_interval
    (0 with recorded velocities)."""
    if observation.recorded_velocities:
        return 0.0
    return observation.position_sd * math.sqrt(2.0) / float(observation.velocity_interval or observation.interval)
