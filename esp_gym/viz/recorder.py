"""The Rerun recorder: :class:`Recorder` buffers samples as rows (kernels/env/recording.py) and
writes them as record batches (arrow.py). What a recording holds (entity paths, scalar series,
blueprint, body shape) is entities.py's; entities, timelines and interruption are described in
esp_gym/viz/recording.py.
"""
from __future__ import annotations

import math
import time as _time
from pathlib import Path
from typing import Optional

import numpy as np
import rerun as rr

from ..kernels.env.arrays import ACTION, REWARD_TERMS, SENSORS, TARGET
from ..kernels.env.recording import capture_sample, sample_layout
from ..kernels.layout import INPUTS, REPORT, R_NEWTON_TOTAL, R_STEPS, WINCH
from ..kernels.step.disturbance import DISTURBANCE
from ..pendulum.control import read_only
from . import lifecycle, palette
from .drone_track import DroneTrack
from .encoder import SampleEncoder
from .entities import (BLACK, BODY_COM, BODY_SHAPE, BODY_TORQUE, HOOK_TENSION, LOAD_TRAIL, PIVOT, PIVOT_FORCE,
                       PUSH, RETURN, STRING, TARGET_LOAD, TARGET_PIVOT, WIND, WORLD, body_shape, default_blueprint,
                       default_strain_scale, rig_eye, scalar_series)


def check_options(flush_every, flush_seconds, write_timeout, sample_period, trail_seconds, trail_spacing,
                  scales: dict, env: bool, action_scale) -> None:
    """ValueError unless a recording's options make sense: ``flush_every`` >= 1 sample,
    ``flush_seconds``, ``write_timeout``, ``sample_period`` and ``trail_spacing`` > 0 [s],
    ``trail_seconds`` >= 0, each of the arrows' ``scales`` (name -> value) >= 0, and an ``env``
    recording's ``action_scale`` given."""
    if flush_every < 1 or not flush_seconds > 0 or not write_timeout > 0:
        raise ValueError("flush_every must be >= 1, flush_seconds and write_timeout > 0")
    if not (sample_period > 0 and trail_seconds >= 0 and trail_spacing > 0):
        raise ValueError("sample_period and trail_spacing must be > 0; trail_seconds >= 0")
    negative = [name for name, value in scales.items() if not value >= 0]
    if negative:
        raise ValueError(f"{', '.join(negative)} must be >= 0, got {[scales[name] for name in negative]}")
    if env and action_scale is None:
        raise ValueError("env recordings need action_scale = (force_limit [N], torque_limit [N m])")


class Recorder:
    """Writes one ``.rrd`` recording of a simulator's samples (see esp_gym/viz/recording.py for
    entities and timelines).

    Arguments (lengths [m], forces [N], torques [N m], times [s]):

    | argument | default | meaning |
    |---|---|---|
    | `path` | | output ``.rrd`` (parent directories are created) |
    | `scene` | | the :class:`~esp_gym.scene.params.Scene` (body shape, string, gravity) |
    | `env` | False | also the reward, action and return series (env rollouts) |
    | `winch` | False | also the winch's length, reel speed and work series |
    | `sample_period` | 0.02 | time between samples: ``time = step * sample_period`` for env rollouts; sets the trail length |
    | `strain_scale` | scene | string colours saturate at this element strain energy [J] (:func:`default_strain_scale`) |
    | `force_scale` | 0.05 | pivot-force arrow length per newton [m/N]; env: also the push and hook tension |
    | `wind_scale` | 0.05 | env: wind arrow length per m/s [m/(m/s)] |
    | `force_offset` | 0 | subtracted from the pivot force before drawing (env: the hover force) |
    | `torque_scale` | 10 | body-torque arrow length per N m [m/(N m)] |
    | `action_scale` | None | env: (force_limit, torque_limit); inputs = (force_offset + force_limit a[:3], torque_limit a[3:]) |
    | `drone` | None | env with a drone: (its actuation, its rotors' positions (4, 3) [m] in its body frame): its frame, rates and rotor speeds (:meth:`add_drone`); the arrows from the inputs |
    | `trail_seconds` | 1.0 | length of the load's trail |
    | `trail_spacing` | 0.1 | time between the trail's points (a multiple of the sample period) |
    | `flush_every` | 2000 | samples buffered before they are written |
    | `flush_seconds` | 5.0 | wall time after which buffered samples are written at the next sample |
    | `write_timeout` | 5.0 | a wait for the file (a flush, :meth:`close`) fails after this long [s] without it growing |
    | `application_id` | "esp_gym" | Rerun application id |
    | `recording_id` | None | Rerun recording id (None: a random one) |

    Samples: :meth:`sample` (a free simulation's :class:`~esp_gym.physics.simulator.Simulator`) or
    :meth:`add_sample` (live kernel arrays, e.g. an environment's); :meth:`start_episode` takes
    the balance origins; env recordings draw each episode's body with :meth:`log_body` (free
    simulations: the scene's, static). Use as a context manager or call :meth:`close`; open
    recorders are also closed at exit and on SIGTERM (lifecycle.py).
    A failed write (disk full, ...) raises :class:`~esp_gym.viz.lifecycle.RecordingError` from the
    next sample, flush or :meth:`close`; the recording stops, and the file keeps the first
    :attr:`samples_written` samples, readable (lifecycle.py, :class:`~esp_gym.viz.lifecycle.RrdFile`).
    """

    def __init__(self, path, scene, *, env: bool = False, winch: bool = False, sample_period: float = 0.02,
                 strain_scale: Optional[float] = None, force_scale: float = 0.05, wind_scale: float = 0.05,
                 force_offset=None, torque_scale: float = 10.0, action_scale: Optional[tuple] = None,
                 trail_seconds: float = 1.0, trail_spacing: float = 0.1, flush_every: int = 2000,
                 flush_seconds: float = 5.0, write_timeout: float = 5.0, application_id: str = "esp_gym",
                 recording_id: Optional[str] = None, drone: Optional[tuple] = None):
        scales = dict(force_scale=force_scale, wind_scale=wind_scale, torque_scale=torque_scale)
        check_options(flush_every, flush_seconds, write_timeout, sample_period, trail_seconds, trail_spacing, scales,
                      env, action_scale)
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.scene = scene
        self.env = bool(env)
        self.winch = bool(winch)
        self.sample_period = float(sample_period)
        self.strain_scale = float(strain_scale) if strain_scale else default_strain_scale(scene)
        self.force_scale, self.torque_scale = float(force_scale), float(torque_scale)
        self.wind_scale = float(wind_scale)
        self.force_offset = np.zeros(3) if force_offset is None else np.asarray(force_offset, dtype=float)
        self.action_scale = action_scale
        #: the scene's rho_c (body frame [m]): the samples' default (read-only, see ``_zeros``)
        self.rho = read_only(np.array(scene.body.rho_c, dtype=float))
        self.flush_every, self.flush_seconds = int(flush_every), float(flush_seconds)
        self.write_timeout = float(write_timeout)
        self.samples = 0  #: samples written or buffered so far
        self.samples_written = 0  #: samples known to be whole in the file (at its last complete point)
        self._sent = 0  # samples handed to Rerun
        self.closed = False

        self.n_elements = n = scene.string.elements
        self.layout = sample_layout(n)  #: the layout of a buffered sample row
        #: the scalar series (a drone's action named for its actuation)
        self.scalars = scalar_series("force" if drone is None else drone[0])
        self._buf = np.zeros((self.flush_every, self.layout.size))
        #: the drone's samples (esp_gym/viz/drone_track.py), or None without a drone
        self.drone = None if drone is None else DroneTrack(drone[1], self.flush_every)
        self._n = 0  # rows buffered
        # read-only like the environment's views, so every caller hits one compiled signature
        self._zeros = read_only(np.zeros(max(ACTION.size, len(REWARD_TERMS), INPUTS.size, SENSORS.size,
                                             DISTURBANCE.size)))
        self._no_target = read_only(np.full(TARGET.size, math.nan))
        self._no_winch = read_only(np.zeros(WINCH.size))
        #: the buffered rows' encoding into record batches (esp_gym/viz/encoder.py)
        self._encoder = SampleEncoder(self.layout, n, env=self.env, winch=self.winch, drone=self.drone,
                                      scalars=self.scalars, strain_scale=self.strain_scale,
                                      force_offset=self.force_offset, action_scale=action_scale,
                                      trail=(max(1, int(round(trail_seconds / sample_period)) + 1),
                                             max(1, int(round(trail_spacing / sample_period)))), **scales)
        self._last_flush = _time.monotonic()
        self.E0 = self.pi3_0 = 0.0  #: balance origins of the current episode
        self.max_abs_residuals = np.zeros(2)  #: largest |E - E0 - W|, |pi3 - pi3_0 - impulse| in sample()
        self._last_newton = None  # (total iterations, steps) of the simulator at the last sample

        self._file = lifecycle.RrdFile(self.path, self.write_timeout)
        self.rec = rr.RecordingStream(application_id, recording_id=recording_id)
        self.rec.set_log_time_enabled(False)
        self.rec.set_log_tick_enabled(False)
        self._file.attach(self.rec, default_blueprint(self.env, self.winch, self.drone is not None, rig_eye(scene)))
        self._log_static()
        lifecycle.track(self)

    def _log_static(self) -> None:
        log, rho = self.rec.log, self.rho
        log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)
        log(STRING, rr.LineStrips3D.from_fields(radii=0.004), static=True)
        log(PIVOT, rr.Points3D.from_fields(radii=0.025, colors=[palette.PIVOT], labels=["pivot"]), static=True)
        log(PIVOT_FORCE, rr.Arrows3D.from_fields(radii=0.006, colors=[palette.FORCE]), static=True)
        log(LOAD_TRAIL, rr.LineStrips3D.from_fields(radii=0.002, colors=[palette.TRAIL]), static=True)
        if self.env:
            # each episode's body (randomised sizes and rho_c) is logged at its reset (log_body): a
            # static shape, centre of mass or torque origin would hide it (static data wins in Rerun)
            log(BODY_TORQUE, rr.Arrows3D.from_fields(radii=0.005, colors=[palette.TORQUE]), static=True)
            for path, label in ((TARGET_PIVOT, "pivot target"), (TARGET_LOAD, "load target")):
                log(path, rr.Points3D.from_fields(radii=0.03, colors=[palette.TARGET], labels=[label]), static=True)
            for path, radius, color in ((WIND, 0.006, palette.WIND), (PUSH, 0.008, palette.PUSH),
                                        (HOOK_TENSION, 0.006, palette.HOOK_TENSION)):
                log(path, rr.Arrows3D.from_fields(radii=radius, colors=[color]), static=True)
        else:
            log(BODY_TORQUE, rr.Arrows3D.from_fields(origins=[rho], radii=0.005, colors=[palette.TORQUE]),
                static=True)
            log(BODY_COM, _com(rho), static=True)
            log(BODY_SHAPE, body_shape(self.scene.body, rho), static=True)
        for path, series in self.scalars.items():
            if (self.env or not series.env_only) and (self.winch or not series.winch_only):
                log(path, rr.SeriesLines(names=list(series.names), colors=series.colors), static=True)
        if self.drone is not None:
            self.drone.log_static(log)
        if self.env:
            log(RETURN, rr.SeriesLines(names="return", colors=[BLACK]), static=True)

    # -- samples ----------------------------------------------------------------------------
    @property
    def buffered(self) -> int:
        """Samples buffered, not yet written."""
        return self._n

    def start_episode(self, sim) -> None:
        """Take the balance origins (E0, pi3_0) of the series E - E0 - W and pi3 - pi3_0 -
        impulse from the simulator: after a reset its work and impulse are zero, so E0 is its
        energy exactly (otherwise E - W - residual, to round-off)."""
        d = sim.diagnostics()
        self.E0 = d["energy"] - d["work"] - d["energy_balance_residual"]
        self.pi3_0 = d["pi3"] - d["angular_impulse_z"] - d["pi3_balance_residual"]
        self._last_newton = (sim.newton_iterations, sim.step_count)

    def log_body(self, body, rho, step: int, time: float) -> None:
        """Env recordings: draw the body of the episode reset at ``step``, ``time`` [s] (its
        reset sample's): its shape centred on ``rho`` (its rho_c, body frame [m]), its centre of
        mass and the torque arrow's origin there, until the next call. Logged now, on the step
        and time timelines set for these calls only (the buffered samples carry their own).
        Raises RecordingError after a failed write."""
        if not self.env:
            raise ValueError("log_body is for env recordings: a free simulation draws its scene's body, static")
        if self.closed:
            return
        self._check()
        rho = np.asarray(rho, dtype=float)
        rec = self.rec
        rec.set_time("step", sequence=int(step))
        rec.set_time("time", duration=np.timedelta64(int(np.rint(time * 1e9)), "ns"))  # as arrow.record_batch
        try:
            rec.log(BODY_SHAPE, body_shape(body, rho))
            rec.log(BODY_COM, _com(rho))
            rec.log(BODY_TORQUE, rr.Arrows3D.from_fields(origins=[rho]))
        finally:
            rec.reset_time()  # no later log on this thread inherits these times

    def add_sample(self, state, diag, *, report, step, time, stepped: bool, episode: int = 0, action=None,
                   terms=None, reward: float = math.nan, inputs=None, target=None, sensors=None, disturbance=None,
                   rho=None, winch=None) -> None:
        """Record one sample from live kernel arrays: ``state``
        (:class:`~esp_gym.kernels.layout.StateArrays`) and ``diag`` (DiagWork, current), the
        step ``report`` (REPORT), ``step`` and ``time`` [s] on the timelines, whether it follows
        a step (``stepped``; False after a reset), the ``episode``, the applied ``action``
        (ACTION) and reward ``terms`` (REWARD) with the ``reward``, the ``inputs`` (INPUTS), the
        episode's ``target`` (TARGET; at the episode's reset, and while it moves), the
        ``sensors`` (SENSORS), the ``disturbance`` (DISTURBANCE), the episode's ``rho``
        (rho_c, body frame [m]) and the ``winch`` (WINCH, :attr:`~esp_gym.physics.winch.Winch.vector`).
        Arrays not given are zeros (the target: none; rho: the scene's);
        pass read-only float64 arrays (one compiled signature). Raises RecordingError after a
        failed write."""
        if self.closed:
            return
        self._check()
        z = self._zeros
        # plain tuples of SampleSources' and SampleClock's fields, in order: numba types a plain
        # tuple faster than a named one, and building the named ones cost 1.2 us per sample
        sources = (state.r, state.R, diag.out, diag.strain, state.acc, z if action is None else action,
                   z if terms is None else terms, report, z if inputs is None else inputs,
                   self._no_target if target is None else target, z if sensors is None else sensors,
                   z if disturbance is None else disturbance, self.rho if rho is None else rho,
                   self._no_winch if winch is None else winch)
        clock = (self.E0, self.pi3_0, float(step), float(time), float(episode), 1.0 if stepped else 0.0, float(reward))
        capture_sample(self._buf, self._n, sources, clock)
        self._commit()

    def add_drone(self, R, rates, rotor_speeds) -> None:
        """The drone's attitude R_q (3, 3), body rates (3) and rotor speeds (4) [rad/s] of the
        sample :meth:`add_sample` adds next."""
        if not self.closed:
            self.drone.set(self._n, R, rates, rotor_speeds)

    def sample(self, sim, *, pivot_force=None, body_torque=None, step: Optional[int] = None,
               time: Optional[float] = None) -> None:
        """Record the simulator's current state and diagnostics (free simulations): inputs as
        given to ``Simulator.step`` (pivot force spatial [N], body torque body frame [N m]);
        ``step``/``time`` default to the simulator's physics step and time. The Newton series
        is the mean over the steps since the previous sample. The first call takes the balance
        origins (:meth:`start_episode`)."""
        if self.closed:
            return
        if self._last_newton is None:
            self.start_episode(sim)
        d = sim.diagnostics()  # also makes the simulator's diagnostic arrays (read below) current
        residuals = [d["energy"] - self.E0 - d["work"] - d["winch_work"],
                     d["pi3"] - self.pi3_0 - d["angular_impulse_z"]]  # as recorded
        self.max_abs_residuals = np.maximum(self.max_abs_residuals, np.abs(residuals))
        total, steps = sim.newton_iterations, sim.step_count
        report = np.zeros(REPORT.size, dtype=np.int64)
        report[R_STEPS], report[R_NEWTON_TOTAL] = steps - self._last_newton[1], total - self._last_newton[0]
        self._last_newton = (total, steps)
        inputs = np.zeros(INPUTS.size)
        inputs[INPUTS["pivot_force"]] = 0.0 if pivot_force is None else pivot_force
        inputs[INPUTS["pivot_force_end"]] = inputs[INPUTS["pivot_force"]]
        inputs[INPUTS["body_torque"]] = 0.0 if body_torque is None else body_torque
        state, _, _, diag = sim.buffers
        self.add_sample(state, diag, report=read_only(report), step=sim.step_count if step is None else step,
                        time=sim.time if time is None else time, stepped=report[R_STEPS] > 0,
                        inputs=read_only(inputs), winch=sim.winch.vector)

    def _commit(self) -> None:
        """Count the row just written (last, so an interrupted sample is simply not counted)
        and flush when the buffer is full or ``flush_seconds`` have passed."""
        self._n += 1
        self.samples += 1
        if self._n >= self.flush_every or _time.monotonic() - self._last_flush > self.flush_seconds:
            self.flush()

    # -- writing ----------------------------------------------------------------------------
    def flush(self, wait: bool = False) -> None:
        """Write the buffered samples (one record batch) and hand them to the file writer
        (``wait``: until they are in the file, see ``write_timeout``). Signals arriving
        meanwhile wait for it. Raises RecordingError after a failed write."""
        if self.closed or lifecycle.flushing():
            return
        with lifecycle.holding_signals():
            self._flush(wait)

    def _flush(self, wait: bool) -> None:
        self._check()
        if self._n:
            self._synced()  # what was sent before is in the file: it ends readable there
            self._write(self._n)
            self._sent, self._n = self._sent + self._n, 0
        if wait:
            self._synced()
        else:
            self.rec.flush(timeout_sec=0.0)
        self._last_flush = _time.monotonic()

    def _synced(self) -> None:
        self._file.sync(self.rec)
        self._check()
        self.samples_written = self._sent

    def close(self) -> None:
        """Flush and close the file (it gets its footer); idempotent. Returns once the file
        is written, or has not grown for ``write_timeout``; raises RecordingError if the file
        is incomplete."""
        if self.closed:
            return
        with lifecycle.holding_signals():
            try:
                self._flush(wait=True)
            finally:
                self._shut()
            self._check()

    def _shut(self) -> None:
        if not self.closed:
            self.closed = True
            lifecycle.untrack(self)
            if self._file.finish(self.rec):
                self.samples_written = self._sent

    def _check(self) -> None:
        """After a failed write: stop recording and raise RecordingError."""
        if self._file.error is not None:
            self._shut()
            self._file.raise_error(f"the file keeps the first {self.samples_written} of {self.samples} samples")

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _write(self, n: int) -> None:
        """Send the first ``n`` buffered samples (esp_gym/viz/encoder.py: one record batch with every
        entity that has a value at every sample, and one with the targets of the episodes reset
        among them)."""
        for batch in self._encoder.batches(self._buf, n):
            self.rec.send_record_batch(batch)


def _com(rho: np.ndarray):
    """The body's centre-of-mass point at ``rho`` (body frame [m])."""
    return rr.Points3D([rho], radii=0.008, colors=[BLACK])
