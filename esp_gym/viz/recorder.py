"""The Rerun recorder: what a recording holds (entity paths, scalar series, blueprint, static
geometry) and :class:`Recorder`, which buffers samples as rows (kernels/recording.py) and writes
them as record batches (arrow.py). Entities, timelines and interruption are described in
esp_gym/viz/recording.py.
"""
from __future__ import annotations

import math
import time as _time
from pathlib import Path
from typing import NamedTuple, Optional

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb

from ..kernels.layout import (ACTION, DIAG, INPUTS, REPORT, REWARD_TERMS, R_NEWTON_TOTAL, R_STEPS, SB_ENERGY_RESIDUAL,
                              SB_PI3_RESIDUAL, SB_WORK, TARGET, sample_layout)
from ..control import read_only
from ..kernels.recording import capture_sample, sample_geometry, trail_points
from . import arrow, lifecycle, palette
from .geometry import equivalent_box, prism_triangles, quaternion_xyzw

# -- entity paths ---------------------------------------------------------------------------------

WORLD = "/world"
STRING = "/world/string"
BODY = "/world/body"
BODY_SHAPE = "/world/body/shape"
BODY_COM = "/world/body/center_of_mass"
BODY_TORQUE = "/world/body/torque"
PIVOT = "/world/pivot"
PIVOT_FORCE = "/world/pivot_force"
LOAD_TRAIL = "/world/load_trail"
TARGET_PIVOT = "/world/targets/pivot"
TARGET_LOAD = "/world/targets/load"
NEWTON = "/diag/newton_iterations"
RETURN = "/rl/return"

ENERGY_PARTS = ("kinetic_string", "kinetic_body", "kinetic_pivot", "potential_gravity", "potential_elastic")
ACTION_NAMES = ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z")


class Series(NamedTuple):
    """Named scalar series sharing one entity: the names, their sources (a field of
    :func:`~esp_gym.kernels.layout.sample_layout` and an offset in it), colours, whether only
    samples after a step have values (not resets), whether only env rollouts have them."""

    names: tuple
    sources: tuple
    colors: list
    stepped_only: bool = False
    env_only: bool = False


def _diag(*names) -> tuple:
    return tuple(("diag", DIAG.scalar(name)) for name in names)


def _field(field: str, offsets=(0,)) -> tuple:
    return tuple((field, k) for k in offsets)


TAB10, BLACK = palette.TAB10, palette.BLACK
#: The scalar series by entity. Related series share an entity (one Scalars batch per sample,
#: a named line each): every entity costs a row id and two time values per sample; grouping
#: the energy parts, reward terms and actions (27 -> 11 scalar entities) cut an env recording
#: from 1.1 to 0.8 kB per step, and Rerun's encoding work with it.
SCALARS = {
    "/diag/energy/total": Series(("total",), _diag("energy"), [BLACK]),
    "/diag/energy/parts": Series(ENERGY_PARTS + ("work",), _diag(*ENERGY_PARTS) + _field("balances", [SB_WORK]),
                                 TAB10[:6]),
    "/diag/energy_residual": Series(("E - E0 - W",), _field("balances", [SB_ENERGY_RESIDUAL]), [TAB10[3]]),
    "/diag/pi3": Series(("pi3",), _diag("pi3"), [TAB10[0]]),
    "/diag/pi3_residual": Series(("pi3 - pi3_0 - angular impulse",), _field("balances", [SB_PI3_RESIDUAL]),
                                 [TAB10[3]]),
    "/diag/orthogonality": Series(("||I - R^T R||_F",), _diag("orthogonality"), [TAB10[7]]),
    "/diag/stretched_length": Series(("stretched length",), _diag("stretched_length"), [TAB10[2]]),
    NEWTON: Series(("Newton iterations / step",), _field("newton"), [TAB10[7]], True),
    "/rl/reward/total": Series(("reward",), _field("reward"), [BLACK], True, True),
    "/rl/reward/terms": Series(REWARD_TERMS, _field("terms", range(len(REWARD_TERMS))), TAB10[:6], True, True),
    "/rl/action": Series(ACTION_NAMES, _field("action", range(ACTION.size)), TAB10[:6], True, True),
}


def default_blueprint(env: bool) -> rrb.Blueprint:
    """The 3-D view beside the diagnostics (and, for env rollouts, reward and action) panels."""
    ts = rrb.TimeSeriesView
    panels = [
        ts(origin="/diag/energy", name="energy [J]"),
        rrb.Tabs(ts(origin="/diag/energy_residual", name="E - E0 - W [J]"),
                 ts(origin="/diag/pi3_residual", name="pi3 - pi3_0 - impulse [kg m2/s]"),
                 ts(origin="/diag/pi3", name="pi3 [kg m2/s]")),
        rrb.Tabs(ts(origin="/diag/stretched_length", name="stretched length [m]"),
                 ts(origin="/diag/orthogonality", name="||I - R^T R||"),
                 ts(origin=NEWTON, name="Newton iterations / step")),
    ]
    if env:
        panels.append(rrb.Tabs(ts(origin="/rl/reward", name="reward"), ts(origin="/rl/action", name="action"),
                               ts(origin=RETURN, name="return")))
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Spatial3DView(origin=WORLD, name="3-D"), rrb.Vertical(*panels), column_shares=[3, 2]),
        collapse_panels=True)


def default_strain_scale(scene) -> float:
    """Strain-energy scale [J] of the string colours: 2.5x the static tension at the top,
    T0 = g (M + mu l), in one element: (2.5 T0)^2 u / (2 EA); the hanging string sits at 40 %
    of the colour ramp (as the rgb_array renderer's default for drone_load)."""
    st = scene.string
    T0 = scene.gravity * (scene.body.mass + st.mass_per_length * st.length)
    e = (2.5 * T0) ** 2 * st.u / (2.0 * st.EA)
    return float(e) if e > 0 else 1.0


def body_shape(body, rho: np.ndarray):
    """The Rerun archetype of the body's shape centred on ``rho`` (body frame): box, sphere, a
    mesh for the cylinders; without a shape the box of the same mass and inertia about the
    centre of mass (a small sphere if there is none)."""
    shape, color = body.shape, [palette.BODY]
    kind = getattr(shape, "kind", None)
    if kind == "box":
        return rr.Boxes3D(centers=[rho], half_sizes=[0.5 * np.asarray(shape.size)], colors=color, fill_mode="solid")
    if kind == "sphere":
        return rr.Ellipsoids3D(centers=[rho], half_sizes=[[shape.radius] * 3], colors=color, fill_mode="solid")
    if kind in ("cylinder", "elliptic_cylinder"):
        a, b = (shape.radius, shape.radius) if kind == "cylinder" else shape.semi_axes
        v, t, nrm = prism_triangles(a, b, shape.height)
        return rr.Mesh3D(vertex_positions=v + rho, triangle_indices=t, vertex_normals=nrm, albedo_factor=palette.BODY)
    eq = equivalent_box(body.mass, body.J, rho)
    if eq is None:
        return rr.Ellipsoids3D(centers=[rho], half_sizes=[[0.03] * 3], colors=color, fill_mode="solid")
    half, Q = eq
    return rr.Boxes3D(centers=[rho], half_sizes=[half], colors=color, fill_mode="solid",
                      quaternions=[rr.Quaternion(xyzw=quaternion_xyzw(Q))], labels=["inertia-equivalent box"])


class Recorder:
    """Writes one ``.rrd`` recording of a simulator's samples (see esp_gym/viz/recording.py for
    entities and timelines).

    Arguments (lengths [m], forces [N], torques [N m], times [s]):

    | argument | default | meaning |
    |---|---|---|
    | `path` | | output ``.rrd`` (parent directories are created) |
    | `scene` | | the :class:`~esp_gym.params.Scene` (body shape, string, gravity) |
    | `env` | False | also the reward, action and return series (env rollouts) |
    | `sample_period` | 0.02 | time between samples: ``time = step * sample_period`` for env rollouts; sets the trail length |
    | `strain_scale` | scene | string colours saturate at this element strain energy [J] (:func:`default_strain_scale`) |
    | `force_scale` | 0.05 | pivot-force arrow length per newton [m/N] |
    | `force_offset` | 0 | subtracted from the pivot force before drawing (env: the hover force) |
    | `torque_scale` | 10 | body-torque arrow length per N m [m/(N m)] |
    | `action_scale` | None | env: (force_limit, torque_limit); inputs = (force_offset + force_limit a[:3], torque_limit a[3:]) |
    | `trail_seconds` | 1.0 | length of the load's trail |
    | `trail_spacing` | 0.1 | time between the trail's points (a multiple of the sample period) |
    | `flush_every` | 2000 | samples buffered before they are written |
    | `flush_seconds` | 5.0 | wall time after which buffered samples are written at the next sample |
    | `write_timeout` | 5.0 | a wait for the file (a flush, :meth:`close`) fails after this long [s] without it growing |
    | `application_id` | "esp_gym" | Rerun application id |
    | `recording_id` | None | Rerun recording id (None: a random one) |

    Samples: :meth:`sample` (a free simulation's :class:`~esp_gym.model.Simulator`) or
    :meth:`add_sample` (live kernel arrays, e.g. an environment's); :meth:`start_episode` takes
    the balance origins. Use as a context manager or call :meth:`close`; open recorders are also
    closed at exit and on SIGTERM (lifecycle.py).
    A failed write (disk full, ...) raises :class:`~esp_gym.viz.lifecycle.RecordingError` from the
    next sample, flush or :meth:`close`; the recording stops, and the file keeps the first
    :attr:`samples_written` samples, readable (lifecycle.py, :class:`~esp_gym.viz.lifecycle.RrdFile`).
    """

    def __init__(self, path, scene, *, env: bool = False, sample_period: float = 0.02,
                 strain_scale: Optional[float] = None, force_scale: float = 0.05, force_offset=None,
                 torque_scale: float = 10.0, action_scale: Optional[tuple] = None, trail_seconds: float = 1.0,
                 trail_spacing: float = 0.1, flush_every: int = 2000, flush_seconds: float = 5.0,
                 write_timeout: float = 5.0, application_id: str = "esp_gym", recording_id: Optional[str] = None):
        if flush_every < 1 or not flush_seconds > 0 or not write_timeout > 0:
            raise ValueError("flush_every must be >= 1, flush_seconds and write_timeout > 0")
        if not (sample_period > 0 and trail_seconds >= 0 and trail_spacing > 0 and force_scale >= 0
                and torque_scale >= 0):
            raise ValueError("sample_period and trail_spacing must be > 0; trail_seconds, force_scale and "
                             "torque_scale >= 0")
        if env and action_scale is None:
            raise ValueError("env recordings need action_scale = (force_limit [N], torque_limit [N m])")
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.scene = scene
        self.env = bool(env)
        self.sample_period = float(sample_period)
        self.strain_scale = float(strain_scale) if strain_scale else default_strain_scale(scene)
        self.force_scale, self.torque_scale = float(force_scale), float(torque_scale)
        self.force_offset = np.zeros(3) if force_offset is None else np.asarray(force_offset, dtype=float)
        self.action_scale = action_scale
        self.rho = np.asarray(scene.body.rho_c, dtype=float)
        self.trail_len = max(1, int(round(trail_seconds / sample_period)) + 1)  # samples spanned
        self.trail_stride = max(1, int(round(trail_spacing / sample_period)))
        self.flush_every, self.flush_seconds = int(flush_every), float(flush_seconds)
        self.write_timeout = float(write_timeout)
        self.samples = 0  #: samples written or buffered so far
        self.samples_written = 0  #: samples known to be whole in the file (at its last complete point)
        self._sent = 0  # samples handed to Rerun
        self.closed = False

        self.n_elements = n = scene.string.elements
        self.layout = sample_layout(n)  #: the layout of a buffered sample row
        self._columns = {path: [self.layout.start(f) + k for f, k in s.sources] for path, s in SCALARS.items()}
        self._buf = np.zeros((self.flush_every, self.layout.size))
        self._n = 0  # rows buffered
        # read-only like the environment's views, so every caller hits one compiled signature
        self._zeros = read_only(np.zeros(max(ACTION.size, len(REWARD_TERMS), INPUTS.size)))
        self._no_target = read_only(np.full(TARGET.size, math.nan))
        self._trail_hist = np.empty((0, 3))  # the current episode's last load positions
        self._trail_episode = None
        self._return = (None, 0.0)  # (episode, return) at the last sample written
        self._last_flush = _time.monotonic()
        self.E0 = self.pi3_0 = 0.0  #: balance origins of the current episode
        self.max_abs_residuals = np.zeros(2)  #: largest |E - E0 - W|, |pi3 - pi3_0 - impulse| in sample()
        self._last_newton = None  # (total iterations, steps) of the simulator at the last sample

        self._file = lifecycle.RrdFile(self.path, self.write_timeout)
        self.rec = rr.RecordingStream(application_id, recording_id=recording_id)
        self.rec.set_log_time_enabled(False)
        self.rec.set_log_tick_enabled(False)
        self._file.attach(self.rec, default_blueprint(self.env))
        self._log_static()
        lifecycle.track(self)

    def _log_static(self) -> None:
        log, rho = self.rec.log, self.rho
        log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)
        log(STRING, rr.LineStrips3D.from_fields(radii=0.004), static=True)
        log(PIVOT, rr.Points3D.from_fields(radii=0.025, colors=[palette.PIVOT], labels=["pivot"]), static=True)
        log(PIVOT_FORCE, rr.Arrows3D.from_fields(radii=0.006, colors=[palette.FORCE]), static=True)
        log(BODY_TORQUE, rr.Arrows3D.from_fields(origins=[rho], radii=0.005, colors=[palette.TORQUE]), static=True)
        log(LOAD_TRAIL, rr.LineStrips3D.from_fields(radii=0.002, colors=[palette.TRAIL]), static=True)
        log(BODY_COM, rr.Points3D([rho], radii=0.008, colors=[BLACK]), static=True)
        if self.env:
            for path, label in ((TARGET_PIVOT, "pivot target"), (TARGET_LOAD, "load target")):
                log(path, rr.Points3D.from_fields(radii=0.03, colors=[palette.TARGET], labels=[label]), static=True)
        log(BODY_SHAPE, body_shape(self.scene.body, rho), static=True)
        for path, series in SCALARS.items():
            if self.env or not series.env_only:
                log(path, rr.SeriesLines(names=list(series.names), colors=series.colors), static=True)
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

    def add_sample(self, state, diag, *, report, step, time, stepped: bool, episode: int = 0, action=None,
                   terms=None, reward: float = math.nan, inputs=None, target=None) -> None:
        """Record one sample from live kernel arrays: ``state``
        (:class:`~esp_gym.kernels.layout.StateArrays`) and ``diag`` (DiagWork, current), the
        step ``report`` (REPORT), ``step`` and ``time`` [s] on the timelines, whether it follows
        a step (``stepped``; False after a reset), the ``episode``, the applied ``action``
        (ACTION) and reward ``terms`` (REWARD) with the ``reward``, the ``inputs`` (INPUTS) and
        the episode's ``target`` (TARGET; at the episode's reset, and while it moves). Arrays not given
        are zeros (the target: none). Raises RecordingError after a failed write."""
        if self.closed:
            return
        self._check()
        z = self._zeros
        capture_sample(self._buf, self._n, state.r, state.R, diag.out, diag.strain, state.acc,
                       z if action is None else action, z if terms is None else terms, report,
                       z if inputs is None else inputs, self._no_target if target is None else target,
                       self.E0, self.pi3_0, float(step), float(time), float(episode), 1.0 if stepped else 0.0,
                       float(reward))
        self._commit()

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
        residuals = [d["energy"] - self.E0 - d["work"], d["pi3"] - self.pi3_0 - d["angular_impulse_z"]]  # as recorded
        self.max_abs_residuals = np.maximum(self.max_abs_residuals, np.abs(residuals))
        total, steps = sim.newton_iterations, sim.step_count
        report = np.zeros(REPORT.size, dtype=np.int64)
        report[R_STEPS], report[R_NEWTON_TOTAL] = steps - self._last_newton[1], total - self._last_newton[0]
        self._last_newton = (total, steps)
        inputs = np.zeros(INPUTS.size)
        inputs[INPUTS["pivot_force"]] = 0.0 if pivot_force is None else pivot_force
        inputs[INPUTS["body_torque"]] = 0.0 if body_torque is None else body_torque
        state, _, _, diag = sim.buffers
        self.add_sample(state, diag, report=read_only(report), step=sim.step_count if step is None else step,
                        time=sim.time if time is None else time, stepped=report[R_STEPS] > 0,
                        inputs=read_only(inputs))

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
        """Send the first ``n`` buffered samples: one record batch with every entity that has
        a value at every sample, and one with the targets of the episodes reset among them."""
        b = self._buf[:n]
        N, col = self.n_elements, self.layout.start
        step, time, episode = b[:, col("step")], b[:, col("time")], b[:, col("episode")]
        stepped = b[:, col("stepped")] > 0
        each = np.arange(n + 1, dtype=np.int32)
        per_sample = np.arange(0, n * N + 1, N, dtype=np.int32)
        f32 = lambda *shape: np.empty(shape, dtype=np.float32)  # noqa: E731
        pts, colors, translation, mat = f32(n, N, 2, 3), np.empty(n * N, np.uint32), f32(n, 3), f32(n, 9)
        pivot, force_vec, torque_vec, load = f32(n, 3), f32(n, 3), f32(n, 3), np.empty((n, 3))
        force_limit, torque_limit = self.action_scale if self.env else (0.0, 0.0)
        sample_geometry(self._buf, n, 1.0 / self.strain_scale, palette.STRAIN_RGBA, self.env, self.force_offset,
                        float(force_limit), float(torque_limit), self.force_scale, self.torque_scale, self.rho, pts,
                        colors, translation, mat, pivot, force_vec, torque_vec, load)
        rows, vec3 = arrow.rows, arrow.vec3
        cols = [
            (STRING, rr.LineStrips3D.descriptor_strips(),
             rows(arrow.strips(pts.reshape(-1, 3), np.arange(0, 2 * n * N + 1, 2, dtype=np.int32)), per_sample)),
            (STRING, rr.LineStrips3D.descriptor_colors(),
             rows(pa.array(colors, type=arrow.arrow_type("color")), per_sample)),
            (BODY, rr.Transform3D.descriptor_translation(), rows(vec3(translation, "translation"), each)),
            (BODY, rr.Transform3D.descriptor_mat3x3(), rows(arrow.mat3x3(mat), each)),
            (PIVOT, rr.Points3D.descriptor_positions(), rows(vec3(pivot, "position"), each)),
            (PIVOT_FORCE, rr.Arrows3D.descriptor_origins(), rows(vec3(pivot, "position"), each)),
            (PIVOT_FORCE, rr.Arrows3D.descriptor_vectors(), rows(vec3(force_vec, "vector"), each)),
            (BODY_TORQUE, rr.Arrows3D.descriptor_vectors(), rows(vec3(torque_vec, "vector"), each)),
            (LOAD_TRAIL, rr.LineStrips3D.descriptor_strips(), rows(self._trail(load, episode), each)),
        ]
        scalar = rr.Scalars.descriptor_scalars()
        missing = ~stepped  # reset samples have no step: no Newton count, reward or action
        for path, series in SCALARS.items():
            if series.env_only and not self.env:
                continue
            columns = self._columns[path]
            mask = missing if series.stepped_only else None
            k = len(columns)
            if k == 1:
                values = pa.array(b[:, columns[0]], mask=mask)
            else:
                values = rows(pa.array(b[:, columns].reshape(-1)), np.arange(0, n * k + 1, k, dtype=np.int32), mask)
            cols.append((path, scalar, values))
        if self.env:
            returns, self._return = arrow.episode_returns(b[:, col("reward")], episode, stepped, self._return)
            cols.append((RETURN, scalar, pa.array(returns, mask=missing)))
        self.rec.send_record_batch(arrow.record_batch(step, time, cols))
        target = col("target")
        reset = ~np.isnan(b[:, target])  # the targets of the episodes reset here
        if reset.any():
            one = np.arange(reset.sum() + 1, dtype=np.int32)
            targets = [(path, rr.Points3D.descriptor_positions(), rows(vec3(b[reset, k:k + 3], "position"), one))
                       for path, k in ((TARGET_PIVOT, target + TARGET.start("pivot")),
                                       (TARGET_LOAD, target + TARGET.start("load")))]
            self.rec.send_record_batch(arrow.record_batch(step[reset], time[reset], targets))

    def _trail(self, load: np.ndarray, episode: np.ndarray) -> pa.Array:
        """Per sample, one strip through the load's positions over the last ``trail_seconds``
        of the same episode, every ``trail_stride`` samples back from the current one (the
        tail of the previous flush is kept)."""
        L = self.trail_len
        hist = self._trail_hist if self._trail_episode == episode[0] else np.empty((0, 3))
        points = np.vstack([hist, load])
        ep = np.concatenate([np.full(len(hist), episode[0]), episode])
        offsets = np.empty(len(load) + 1, dtype=np.int32)
        m_max = (L - 1) // self.trail_stride + 1
        out = np.empty((len(load) * m_max, 3), dtype=np.float32)
        total = trail_points(points, ep, len(hist), L, self.trail_stride, offsets, out)
        keep = np.arange(max(0, len(points) - (L - 1)), len(points)) if L > 1 else np.arange(0)
        keep = keep[ep[keep] == episode[-1]]
        self._trail_hist, self._trail_episode = points[keep], episode[-1]
        return arrow.strips(out[:total], offsets)
