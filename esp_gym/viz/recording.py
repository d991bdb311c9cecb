"""Rerun recordings (``.rrd``) of esp_gym runs: the 3-D scene and the energy and momentum
diagnostics, for free simulations (:func:`record_simulation`, ``esp-gym record``) and for
rollouts of ElasticStringPendulum-v0 (the Gymnasium wrapper :class:`RecordRerun`).

Open a recording with ``rerun FILE.rrd``; it carries its default blueprint (the 3-D view
beside the time-series panels). Read it back with ``rerun.chunk.RrdReader(FILE).stream()``.

Timelines
    ``step`` (sequence): the physics step for free simulations; for env rollouts the control
    step, counted across episodes (a reset takes the index after the previous episode's last
    step). ``time`` (duration [s]): the simulated time for free simulations, ``step`` x the
    control period for env rollouts.

Entities (SI units; spatial frame unless stated; gravity along +z, the 3-D view is z-down)

==============================  =====================================================================
``/world``                      static: view coordinates (right-handed, z down)
``/world/string``               N two-point line strips, one per element (Rerun colours per strip),
                                coloured by the element's strain energy: the rgb_array renderer's
                                ramp at ``sqrt(E / strain_scale)``
``/world/body``                 Transform3D, translation = attachment node, mat3x3 = R (body to
                                spatial): everything below is drawn in the body frame
``/world/body/shape``           static: the body's shape centred on rho_c (box, sphere, a mesh for
                                the cylinders; without a shape the box of the same mass and inertia
                                about the centre of mass)
``/world/body/center_of_mass``  static: a point at rho_c
``/world/body/torque``          arrow from the centre of mass (static origin): ``torque_scale`` x
                                body torque [m per N m]
``/world/pivot``                node 0
``/world/pivot_force``          arrow from the pivot: ``force_scale`` x (pivot force -
                                ``force_offset``) [m per N] (env rollouts: minus the hover force)
``/world/load_trail``           the load's centre of mass over the last ``trail_seconds``
``/world/targets/{pivot,load}`` env rollouts: the episode's targets, at its reset
``/diag/energy/total``          E [J]
``/diag/energy/parts``          kinetic_string, kinetic_body, kinetic_pivot, potential_gravity,
                                potential_elastic and the input work W [J] (named series)
``/diag/energy_residual``       E - E0 - W [J] (the input work balance; E0 at the episode's start)
``/diag/pi3``                   pi3 [kg m^2/s]
``/diag/pi3_residual``          pi3 - pi3_0 - angular impulse [kg m^2/s]
``/diag/orthogonality``         ||I - R^T R||_F
``/diag/stretched_length``      [m]
``/diag/newton_iterations``     mean Newton iterations per physics step since the previous sample
``/rl/reward/total``            env rollouts: the reward ...
``/rl/reward/terms``            ... and its terms (``info["reward_*"]``, named series)
``/rl/return``                  the episode's return so far
``/rl/action``                  the applied (clipped) action, force_x .. torque_z (named series)
==============================  =====================================================================

A sample holds the state after a step (or a reset, or the start of a free simulation) and its
diagnostics; for env rollouts also what that ``env.step`` returned and applied (reward, terms,
action). Reset samples have no Newton, reward or action values (nulls: no data at that row).

Bulk logging: each sample is copied into a preallocated row by one compiled call (~1 us);
the rows are written ``flush_every`` at a time (also after ``flush_seconds`` of wall time, on
:meth:`Recorder.close`, at exit and on signals; :class:`RecordRerun` optionally at each
episode's end) as ONE ``send_record_batch`` per flush: a column per (entity, component), each
field described by the ``rerun:*`` metadata that ``rerun.chunk.Chunk.from_record_batch`` reads,
with the component's own Rerun descriptor and Arrow type. That is ``send_columns`` for all
entities at once: one ``send_columns`` call costs ~0.1-0.5 ms, and ~20 of them per flush cost
more than the rollout. Scalars are stored as float64 (the simulator's bits); 3-D geometry as
float32 (Rerun's types). Related scalar series share an entity (named series): every entity
costs a row id and two time values per sample.

Interruption: SIGTERM closes every open recording (the file gets its footer) and then ends the
process as SIGTERM would have (or calls the previously installed Python handler). SIGINT
writes the buffers and raises KeyboardInterrupt as usual; ``atexit`` closes the recordings. A
signal arriving during a flush is handled when it is done. Only SIGKILL (or a crash) loses
data: the samples buffered since the last flush (at most ``flush_seconds`` of wall time, or
``flush_every`` samples); the file is then still readable with ``RrdReader(path).stream()``
(without its footer ``.store()`` refuses it).
"""
from __future__ import annotations

import atexit
import math
import os
import signal
import threading
import time as _time
from functools import lru_cache
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb

from ..kernels._jit import kernel
from ..kernels.diagnostics import DIAG_NAMES
from .render import STRAIN_LUT

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

ENERGY_PARTS = ("kinetic_string", "kinetic_body", "kinetic_pivot", "potential_gravity", "potential_elastic")
REWARD_TERMS = ("load_position", "load_velocity", "pivot_position", "swing", "spin", "control")
ACTION_NAMES = ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z")
NEWTON = "/diag/newton_iterations"
RETURN = "/rl/return"

_BODY_COLOR = (226, 150, 84)
_PIVOT_COLOR = (38, 38, 46)
_TARGET_COLOR = (214, 30, 50)
_FORCE_COLOR = (190, 40, 170)
_TORQUE_COLOR = (40, 150, 190)
_TRAIL_COLOR = (90, 120, 200)

# -- the sample buffer and its capture kernel -----------------------------------------------------
#
# A sample is one float64 row of width row_width(N): meta (step, time, episode, stepped, Newton
# iterations per physics step, reward), the clipped action (6), the reward terms (6), the inputs
# (pivot force [N] spatial, body torque [N m] body frame), the balances (work, E - E0 - W,
# angular impulse, pi3 - pi3_0 - impulse), the targets (pivot, load; NaN but at an episode's
# reset), R (row-major), the nodes r (N+1, 3), the per-element strain energies (N) and last the
# diagnostics (DIAG_NAMES). The kernels take the variable part's offsets from the array shapes:
# numba's cache would keep a constant such as len(DIAG_NAMES) from another file stale.

_STEP, _TIME, _EPISODE, _STEPPED, _NEWTON, _REWARD = range(6)
_ACTION = 6
_TERMS = 12
_INPUTS = 18
_BAL = 24
_TARGET = 28
_ROT = 34
_NODES = 43


def _strain_column(n_elements: int) -> int:
    return _NODES + 3 * (n_elements + 1)


def _diag_column(n_elements: int, name: str) -> int:
    return _strain_column(n_elements) + n_elements + DIAG_NAMES.index(name)


def row_width(n_elements: int) -> int:
    """Width of a sample row for a string of ``n_elements`` elements."""
    return _strain_column(n_elements) + n_elements + len(DIAG_NAMES)


@kernel
def _capture(buf, i, r, R, out, strain, acc, action, terms, result, E0, pi30, step, t, episode, stepped,
             reward):
    """Write one sample into row ``i`` of ``buf`` (layout above) from the simulator's live
    arrays: nodes r, R, diagnostics ``out`` (DIAG_NAMES) and strain energies (current),
    accumulators ``acc`` (work, angular impulse, ...), the applied ``action`` and reward
    ``terms`` (6 each), and ``result`` (status, physics steps, Newton iterations total, max,
    termination). The balances are computed as in ``Simulator.diagnostics`` (same operations,
    same order, so the same bits). Explicit loops: slice assignment compiles ~10x slower."""
    row = buf[i]
    row[_STEP] = step
    row[_TIME] = t
    row[_EPISODE] = episode
    row[_STEPPED] = stepped
    row[_NEWTON] = result[2] / result[1] if result[1] > 0 else math.nan
    row[_REWARD] = reward
    for k in range(6):
        row[_ACTION + k] = action[k]
        row[_TERMS + k] = terms[k]
    row[_BAL + 0] = acc[0]
    row[_BAL + 1] = out[4] - E0 - acc[0]
    row[_BAL + 2] = acc[1]
    row[_BAL + 3] = out[5] - pi30 - acc[1]
    for k in range(6):
        row[_TARGET + k] = math.nan
    for a in range(3):
        for c in range(3):
            row[_ROT + 3 * a + c] = R[a, c]
    for a in range(r.shape[0]):
        for c in range(3):
            row[_NODES + 3 * a + c] = r[a, c]
    base = _NODES + 3 * r.shape[0]
    for k in range(strain.shape[0]):
        row[base + k] = strain[k]
    base += strain.shape[0]
    for k in range(out.shape[0]):
        row[base + k] = out[k]


@kernel
def _geometry(buf, n, inv_strain_scale, lut, inputs_from_action, force_offset, force_limit, torque_limit,
              force_scale, torque_scale, rho, pts, colors, translation, mat, pivot, force_vec, torque_vec, load):
    """The 3-D columns of the first ``n`` samples of ``buf`` (float32 unless stated): element
    end points ``pts`` (n, N, 2, 3); strain colours (n N,) uint32 from ``lut`` at
    sqrt(E / scale) clipped to [0, 1] (NaN -> 0); the attachment point ``translation`` and R
    column-major ``mat`` (n, 9) (Rerun's layout); the pivot; the arrows ``force_scale`` x
    (pivot force - force_offset) and ``torque_scale`` x body torque, with the inputs taken
    from the action (hover + force_limit a[:3], torque_limit a[3:]) or from the input columns;
    and the load's centre of mass r_N + R rho_c (n, 3) float64."""
    N = pts.shape[1]
    strain0 = _NODES + 3 * (N + 1)
    for i in range(n):
        row = buf[i]
        for a in range(N):
            for c in range(3):
                pts[i, a, 0, c] = row[_NODES + 3 * a + c]
                pts[i, a, 1, c] = row[_NODES + 3 * (a + 1) + c]
            x = row[strain0 + a] * inv_strain_scale
            x = min(x, 1.0) if x > 0.0 else 0.0
            colors[i * N + a] = lut[int(math.sqrt(x) * 255.0 + 0.5)]
        for c in range(3):
            translation[i, c] = row[_NODES + 3 * N + c]
            pivot[i, c] = row[_NODES + c]
            acc = row[_NODES + 3 * N + c]
            for k in range(3):
                mat[i, 3 * c + k] = row[_ROT + 3 * k + c]
                acc += row[_ROT + 3 * c + k] * rho[k]
            load[i, c] = acc
            if inputs_from_action:
                force = force_offset[c] + force_limit * row[_ACTION + c]
                torque = torque_limit * row[_ACTION + 3 + c]
            else:
                force = row[_INPUTS + c]
                torque = row[_INPUTS + 3 + c]
            force_vec[i, c] = force_scale * (force - force_offset[c])
            torque_vec[i, c] = torque_scale * torque


@kernel
def _trail_points(points, episode, first_new, span, stride, offsets, out):
    """Strips through ``points`` (M, 3) for each sample k >= ``first_new``: the points
    k - stride (m - 1), ..., k - stride, k (oldest first) that lie within ``span`` samples of k
    and in k's episode. Fills ``offsets`` (M - first_new + 1,) and, if ``out`` is large enough
    (offsets[-1] rows), the float32 points. Returns the total number of points."""
    start = 0
    total = 0
    offsets[0] = 0
    for k in range(points.shape[0]):
        if k > 0 and episode[k] != episode[k - 1]:
            start = k
        if k < first_new:
            continue
        lo = max(k - span + 1, start)
        m = (k - lo) // stride + 1
        if out.shape[0] >= total + m:
            for j in range(m):
                src = k - stride * (m - 1 - j)
                for c in range(3):
                    out[total + j, c] = points[src, c]
        total += m
        offsets[k - first_new + 1] = total
    return total


_TAB10 = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
          (227, 119, 194), (127, 127, 127)]
_BLACK = (20, 20, 20)


#: Scalar series: entity path -> (series names, their sources: a sample-row column or a
#: DIAG_NAMES entry, colours, only samples after a step (not resets), env rollouts only). Related series share an entity (one
#: Scalars batch per sample, a named line each): every entity costs a row id and two time
#: values per sample; grouping the energy parts, reward terms and actions (27 -> 11 scalar
#: entities) cut an env recording from 1.1 to 0.8 kB per step, and Rerun's encoding work with it.
SCALARS = {
    "/diag/energy/total": (("total",), ("energy",), [_BLACK], False, False),
    "/diag/energy/parts": (ENERGY_PARTS + ("work",), ENERGY_PARTS + (_BAL + 0,), _TAB10[:6], False, False),
    "/diag/energy_residual": (("E - E0 - W",), (_BAL + 1,), [_TAB10[3]], False, False),
    "/diag/pi3": (("pi3",), ("pi3",), [_TAB10[0]], False, False),
    "/diag/pi3_residual": (("pi3 - pi3_0 - angular impulse",), (_BAL + 3,), [_TAB10[3]], False, False),
    "/diag/orthogonality": (("||I - R^T R||_F",), ("orthogonality",), [_TAB10[7]], False, False),
    "/diag/stretched_length": (("stretched length",), ("stretched_length",), [_TAB10[2]], False, False),
    NEWTON: (("Newton iterations / step",), (_NEWTON,), [_TAB10[7]], True, False),
    "/rl/reward/total": (("reward",), (_REWARD,), [_BLACK], True, True),
    "/rl/reward/terms": (REWARD_TERMS, tuple(_TERMS + k for k in range(6)), _TAB10[:6], True, True),
    "/rl/action": (ACTION_NAMES, tuple(_ACTION + k for k in range(6)), _TAB10[:6], True, True),
}


# -- signals and exit -----------------------------------------------------------------------------

#: Recorders not yet closed (strong references: buffered samples are written at exit even if
#: the recorder was dropped without close).
_OPEN: set = set()
_GUARD = {"busy": 0, "pending": [], "installed": False}
_PREVIOUS: dict = {}


def _close_all() -> None:
    for rec in list(_OPEN):
        rec.close()


def _dispatch(signum, frame) -> None:
    if signum == signal.SIGINT:
        for rec in list(_OPEN):
            rec.flush(wait=True)
    else:
        _close_all()
    prev = _PREVIOUS.get(signum, signal.SIG_DFL)
    if callable(prev):
        prev(signum, frame)  # e.g. default_int_handler raises KeyboardInterrupt
    elif prev == signal.SIG_DFL:
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)  # end the process as the signal would have


def _on_signal(signum, frame) -> None:
    if _GUARD["busy"]:  # in the middle of a flush: finish it first (see Recorder.flush)
        _GUARD["pending"].append(signum)
        return
    _dispatch(signum, frame)


def _install_handlers() -> None:
    """Once per process: ``atexit`` closing of open recordings, and SIGTERM/SIGINT handlers
    chaining to the previous ones (main thread only; elsewhere signals are left alone)."""
    if _GUARD["installed"]:
        return
    _GUARD["installed"] = True
    atexit.register(_close_all)
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in (signal.SIGTERM, signal.SIGINT):
        prev = signal.getsignal(sig)
        if prev in (signal.SIG_IGN, None):
            continue
        _PREVIOUS[sig] = prev
        signal.signal(sig, _on_signal)


# -- geometry -------------------------------------------------------------------------------------

def quaternion_xyzw(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's method: the largest of
    w, x, y, z is taken from the diagonal, the others from the off-diagonal sums)."""
    R = np.asarray(R, dtype=float)
    tr = np.trace(R)
    d = np.array([tr, R[0, 0], R[1, 1], R[2, 2]])
    k = int(np.argmax(d))
    if k == 0:
        w = 0.5 * math.sqrt(1.0 + tr)
        q = [(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w]
    else:
        i, j, l = k - 1, k % 3, (k + 1) % 3
        s = 0.5 * math.sqrt(max(1.0 + 2.0 * R[i, i] - tr, 0.0))
        q = [0.0, 0.0, 0.0, (R[l, j] - R[j, l]) / (4 * s)]
        q[i] = s
        q[j] = (R[j, i] + R[i, j]) / (4 * s)
        q[l] = (R[l, i] + R[i, l]) / (4 * s)
    q = np.array(q)
    return q / np.linalg.norm(q)


def prism_triangles(a: float, b: float, height: float, facets: int = 32):
    """Triangle mesh of an elliptic prism (semi-axes a, b along body x, y; ``height`` along z;
    centred on the origin): vertices (V, 3), outward-wound triangles (T, 3), vertex normals
    (smooth sides, flat caps)."""
    phi = np.linspace(0.0, 2.0 * np.pi, facets, endpoint=False)
    ring = np.stack([a * np.cos(phi), b * np.sin(phi)], axis=1)
    n_side = np.stack([np.cos(phi) / a, np.sin(phi) / b, np.zeros(facets)], axis=1)
    n_side /= np.linalg.norm(n_side, axis=1, keepdims=True)
    lo, hi = -0.5 * height, 0.5 * height
    col = lambda z: np.full((facets, 1), z)  # noqa: E731
    verts = np.vstack([np.hstack([ring, col(lo)]), np.hstack([ring, col(hi)]),       # sides
                       np.hstack([ring, col(lo)]), np.hstack([ring, col(hi)]),       # caps
                       [[0.0, 0.0, lo], [0.0, 0.0, hi]]])
    normals = np.vstack([n_side, n_side, np.tile([0.0, 0.0, -1.0], (facets, 1)),
                         np.tile([0.0, 0.0, 1.0], (facets, 1)), [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]])
    i = np.arange(facets)
    j = (i + 1) % facets
    f = facets
    side = np.vstack([np.stack([i, j, f + j], 1), np.stack([i, f + j, f + i], 1)])
    bottom = np.stack([np.full(f, 4 * f), 2 * f + j, 2 * f + i], 1)
    top = np.stack([np.full(f, 4 * f + 1), 3 * f + i, 3 * f + j], 1)
    return verts, np.vstack([side, bottom, top]).astype(np.uint32), normals


def equivalent_box(mass: float, J: np.ndarray, rho_c) -> Optional[tuple]:
    """(half sizes (3,), rotation (3, 3)) of the uniform box with the body's mass and inertia
    about its centre of mass (J_cm = J - M (|rho|^2 I - rho rho^T)), or None if J_cm is not
    that of any box. For a box, I_x = M (b^2 + c^2)/3 with half sizes (a, b, c)."""
    rho = np.asarray(rho_c, dtype=float)
    Jcm = np.asarray(J, dtype=float) - mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))
    lam, Q = np.linalg.eigh(0.5 * (Jcm + Jcm.T))
    half_sq = 1.5 / mass * (lam.sum() - 2.0 * lam)
    if not np.all(half_sq > 0):
        return None
    if np.linalg.det(Q) < 0:
        Q[:, 2] = -Q[:, 2]
    return np.sqrt(half_sq), Q


def pack_rgba(rgb: np.ndarray) -> np.ndarray:
    """(n, 3) uint8 colours -> (n,) uint32 0xRRGGBBAA (Rerun's packed colour, opaque)."""
    c = rgb.astype(np.uint32)
    return (c[:, 0] << 24) | (c[:, 1] << 16) | (c[:, 2] << 8) | np.uint32(255)


_STRAIN_RGBA = pack_rgba(STRAIN_LUT)


def default_strain_scale(scene) -> float:
    """Strain-energy scale [J] of the string colours: 2.5x the static tension at the top,
    T0 = g (M + mu l), in one element: (2.5 T0)^2 u / (2 EA); the hanging string sits at 40 %
    of the colour ramp (as the rgb_array renderer's default for drone_load)."""
    st = scene.string
    T0 = scene.gravity * (scene.body.mass + st.mass_per_length * st.length)
    e = (2.5 * T0) ** 2 * st.u / (2.0 * st.EA)
    return float(e) if e > 0 else 1.0


# -- Arrow columns for send_record_batch ----------------------------------------------------------
#
# One flush sends one record batch: an index column per timeline and a column per (entity,
# component), each field described by the ``rerun:*`` metadata that ``Chunk.from_record_batch``
# reads (kind, entity path, archetype, component, component type, taken from Rerun's own
# descriptors). Component columns are lists (one batch per row) of the component's Arrow type,
# also taken from Rerun's own conversions; scalar columns are plain float64 with nulls where a
# series has no sample (Rerun wraps each value as a one-element list).

_TYPES: dict = {}


def _arrow_type(name: str) -> pa.DataType:
    if not _TYPES:
        c = rr.components
        _TYPES.update(
            position=c.Position3DBatch([[0.0, 0.0, 0.0]]).as_arrow_array().type,
            vector=c.Vector3DBatch([[0.0, 0.0, 0.0]]).as_arrow_array().type,
            translation=c.Translation3DBatch([[0.0, 0.0, 0.0]]).as_arrow_array().type,
            mat3x3=c.TransformMat3x3Batch(np.eye(3)).as_arrow_array().type,
            strip=c.LineStrip3DBatch([[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]]).as_arrow_array().type,
            color=c.ColorBatch([0]).as_arrow_array().type)
    return _TYPES[name]


@lru_cache(maxsize=None)
def _field_cached(path: str, component: str, archetype: str, component_type: str, arrow_type) -> pa.Field:
    return pa.field(f"{path}:{component}", arrow_type, metadata={
        "rerun:kind": "data", "rerun:entity_path": path, "rerun:archetype": archetype,
        "rerun:component": component, "rerun:component_type": component_type})


def _field(path: str, descriptor, arrow_type: pa.DataType) -> pa.Field:
    """The record-batch field of ``descriptor``'s component of entity ``path``."""
    return _field_cached(path, descriptor.component, descriptor.archetype or "", descriptor.component_type or "",
                         arrow_type)


_INDEX_FIELDS = [pa.field("step", pa.int64(), metadata={"rerun:kind": "index", "rerun:index_name": "step"}),
                 pa.field("time", pa.duration("ns"), metadata={"rerun:kind": "index", "rerun:index_name": "time"})]


def _vec3(a: np.ndarray, kind: str) -> pa.Array:
    """(m, 3) -> FixedSizeList<float32, 3> array of Rerun's ``kind`` type."""
    flat = pa.array(np.ascontiguousarray(a, dtype=np.float32).reshape(-1))
    return pa.FixedSizeListArray.from_arrays(flat, type=_arrow_type(kind))


def _strips(points: np.ndarray, offsets: np.ndarray) -> pa.Array:
    """LineStrip3D array from points (P, 3) and strip offsets (S + 1,)."""
    return pa.ListArray.from_arrays(pa.array(offsets, type=pa.int32()), _vec3(points, "position"),
                                    type=_arrow_type("strip"))


def _rows(values: pa.Array, offsets: np.ndarray, missing: Optional[np.ndarray] = None) -> pa.Array:
    """Group ``values`` into one list per sample (row k holds values[offsets[k]:offsets[k+1]]);
    ``missing`` rows are null (no data; an empty list would clear the entity)."""
    mask = None if missing is None else pa.array(missing)
    return pa.ListArray.from_arrays(pa.array(offsets, type=pa.int32()), values, type=pa.list_(values.type),
                                    mask=mask)


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


# -- the recorder ---------------------------------------------------------------------------------

class Recorder:
    """Writes one ``.rrd`` recording of a simulator's samples (see the module docstring for
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
    | `application_id` | "esp_gym" | Rerun application id |
    | `recording_id` | None | Rerun recording id (None: a random one) |

    Use as a context manager or call :meth:`close`; open recorders are also closed at exit and
    on SIGTERM (see the module docstring).
    """

    def __init__(self, path, scene, *, env: bool = False, sample_period: float = 0.02,
                 strain_scale: Optional[float] = None, force_scale: float = 0.05, force_offset=None,
                 torque_scale: float = 10.0, action_scale: Optional[tuple] = None, trail_seconds: float = 1.0,
                 trail_spacing: float = 0.1, flush_every: int = 2000, flush_seconds: float = 5.0,
                 application_id: str = "esp_gym", recording_id: Optional[str] = None):
        if flush_every < 1 or not flush_seconds > 0:
            raise ValueError("flush_every must be >= 1 and flush_seconds > 0")
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
        self.samples = 0  #: samples written or buffered so far
        self.closed = False

        self.n_elements = n = scene.string.elements
        self._buf = np.zeros((self.flush_every, row_width(n)))
        self._n = 0  # rows buffered
        self._zeros6 = np.zeros(6)
        self._trail_hist = np.empty((0, 3))  # the current episode's last load positions
        self._trail_episode = None
        self._return, self._return_episode = 0.0, None
        self._last_flush = _time.monotonic()
        self.E0 = self.pi3_0 = 0.0  #: balance origins of the current episode
        self.max_abs_residuals = np.zeros(2)  #: largest |E - E0 - W|, |pi3 - pi3_0 - impulse| in sample()
        self._last_newton = None  # (total iterations, steps) of the simulator at the last sample

        self.rec = rr.RecordingStream(application_id, recording_id=recording_id)
        self.rec.set_log_time_enabled(False)
        self.rec.set_log_tick_enabled(False)
        self.rec.save(str(self.path), default_blueprint=default_blueprint(self.env))
        self._log_static()
        _OPEN.add(self)
        _install_handlers()

    # -- static content ---------------------------------------------------------------------
    def _log_static(self) -> None:
        log = self.rec.log
        log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)
        log(STRING, rr.LineStrips3D.from_fields(radii=0.004), static=True)
        log(PIVOT, rr.Points3D.from_fields(radii=0.025, colors=[_PIVOT_COLOR], labels=["pivot"]), static=True)
        log(PIVOT_FORCE, rr.Arrows3D.from_fields(radii=0.006, colors=[_FORCE_COLOR]), static=True)
        log(BODY_TORQUE, rr.Arrows3D.from_fields(origins=[self.rho], radii=0.005, colors=[_TORQUE_COLOR]),
            static=True)
        log(LOAD_TRAIL, rr.LineStrips3D.from_fields(radii=0.002, colors=[_TRAIL_COLOR]), static=True)
        log(BODY_COM, rr.Points3D([self.rho], radii=0.008, colors=[(20, 20, 20)]), static=True)
        if self.env:
            for path, label in ((TARGET_PIVOT, "pivot target"), (TARGET_LOAD, "load target")):
                log(path, rr.Points3D.from_fields(radii=0.03, colors=[_TARGET_COLOR], labels=[label]), static=True)
        self._log_body_shape()
        for path, (names, _, colors, _, env_only) in SCALARS.items():
            if self.env or not env_only:
                log(path, rr.SeriesLines(names=list(names), colors=colors), static=True)
        if self.env:
            log(RETURN, rr.SeriesLines(names="return", colors=[_BLACK]), static=True)

    def _log_body_shape(self) -> None:
        body, rho, color = self.scene.body, self.rho, [_BODY_COLOR]
        shape = body.shape
        kind = getattr(shape, "kind", None)
        if kind == "box":
            geom = rr.Boxes3D(centers=[rho], half_sizes=[0.5 * np.asarray(shape.size)], colors=color,
                              fill_mode="solid")
        elif kind == "sphere":
            geom = rr.Ellipsoids3D(centers=[rho], half_sizes=[[shape.radius] * 3], colors=color, fill_mode="solid")
        elif kind in ("cylinder", "elliptic_cylinder"):
            a, b = (shape.radius, shape.radius) if kind == "cylinder" else shape.semi_axes
            v, t, nrm = prism_triangles(a, b, shape.height)
            geom = rr.Mesh3D(vertex_positions=v + rho, triangle_indices=t, vertex_normals=nrm,
                             albedo_factor=_BODY_COLOR)
        else:  # no shape: the box with the same mass and inertia about the centre of mass
            eq = equivalent_box(body.mass, body.J, rho)
            if eq is None:
                geom = rr.Ellipsoids3D(centers=[rho], half_sizes=[[0.03] * 3], colors=color, fill_mode="solid")
            else:
                half, Q = eq
                geom = rr.Boxes3D(centers=[rho], half_sizes=[half], colors=color, fill_mode="solid",
                                  quaternions=[rr.Quaternion(xyzw=quaternion_xyzw(Q))],
                                  labels=["inertia-equivalent box"])
        self.rec.log(BODY_SHAPE, geom, static=True)

    # -- samples ----------------------------------------------------------------------------
    def start_episode(self, sim) -> None:
        """Take the balance origins (E0, pi3_0) of the series E - E0 - W and pi3 - pi3_0 -
        impulse from the simulator: after a reset its work and impulse are zero, so E0 is its
        energy exactly (otherwise E - W - residual, to round-off)."""
        d = sim.diagnostics()
        self.E0 = d["energy"] - d["work"] - d["energy_balance_residual"]
        self.pi3_0 = d["pi3"] - d["angular_impulse_z"] - d["pi3_balance_residual"]
        self._last_newton = (sim.newton_iterations, sim.step_count)

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
        sim.diagnostics()  # makes the simulator's diagnostic arrays (read below) current
        total, steps = sim.newton_iterations, sim.step_count
        result = np.array([0, steps - self._last_newton[1], total - self._last_newton[0], 0, 0], dtype=np.int64)
        self._last_newton = (total, steps)
        S, _, _, D = sim.kernel_args
        i = self._n
        _capture(self._buf, i, S.r, S.R, D.out, D.strain, S.acc, self._zeros6, self._zeros6, result,
                 self.E0, self.pi3_0, float(sim.step_count if step is None else step),
                 float(sim.time if time is None else time), 0.0, 1.0 if result[1] > 0 else 0.0, math.nan)
        bal = self._buf[i, [_BAL + 1, _BAL + 3]]
        self.max_abs_residuals = np.maximum(self.max_abs_residuals, np.abs(bal))
        self._buf[i, _INPUTS:_INPUTS + 3] = 0.0 if pivot_force is None else pivot_force
        self._buf[i, _INPUTS + 3:_INPUTS + 6] = 0.0 if body_torque is None else body_torque
        self._commit()

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
        (``wait``: until they are written)."""
        if self.closed or _GUARD["busy"]:
            return
        _GUARD["busy"] += 1
        try:
            if self._n:
                self._write(self._n)
                self._n = 0
            self.rec.flush(timeout_sec=1e38 if wait else 0.0)
            self._last_flush = _time.monotonic()
        finally:
            _GUARD["busy"] -= 1
            if not _GUARD["busy"] and _GUARD["pending"]:
                signum = _GUARD["pending"].pop(0)
                _GUARD["pending"].clear()
                _dispatch(signum, None)

    def close(self) -> None:
        """Flush and close the file (it gets its footer); idempotent."""
        if self.closed:
            return
        self.flush(wait=True)
        self.closed = True
        _OPEN.discard(self)
        self.rec.disconnect()

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _write(self, n: int) -> None:
        """Send the first ``n`` buffered samples: one record batch with every entity that has
        a value at every sample, and one with the targets of the episodes reset among them."""
        b = self._buf[:n]
        N = self.n_elements
        stepped = b[:, _STEPPED] > 0
        each = np.arange(n + 1, dtype=np.int32)
        per_sample = np.arange(0, n * N + 1, N, dtype=np.int32)
        f32 = lambda *shape: np.empty(shape, dtype=np.float32)  # noqa: E731
        pts, colors, translation, mat = f32(n, N, 2, 3), np.empty(n * N, np.uint32), f32(n, 3), f32(n, 9)
        pivot, force_vec, torque_vec, load = f32(n, 3), f32(n, 3), f32(n, 3), np.empty((n, 3))
        force_limit, torque_limit = self.action_scale if self.env else (0.0, 0.0)
        _geometry(self._buf, n, 1.0 / self.strain_scale, _STRAIN_RGBA, self.env, self.force_offset, float(force_limit),
                  float(torque_limit), self.force_scale, self.torque_scale, self.rho, pts, colors, translation, mat,
                  pivot, force_vec, torque_vec, load)
        strips = _strips(pts.reshape(-1, 3), np.arange(0, 2 * n * N + 1, 2, dtype=np.int32))
        colors = pa.array(colors, type=_arrow_type("color"))
        cols = [
            (STRING, rr.LineStrips3D.descriptor_strips(), _rows(strips, per_sample)),
            (STRING, rr.LineStrips3D.descriptor_colors(), _rows(colors, per_sample)),
            (BODY, rr.Transform3D.descriptor_translation(), _rows(_vec3(translation, "translation"), each)),
            (BODY, rr.Transform3D.descriptor_mat3x3(),
             _rows(pa.FixedSizeListArray.from_arrays(pa.array(mat.reshape(-1)), type=_arrow_type("mat3x3")), each)),
            (PIVOT, rr.Points3D.descriptor_positions(), _rows(_vec3(pivot, "position"), each)),
            (PIVOT_FORCE, rr.Arrows3D.descriptor_origins(), _rows(_vec3(pivot, "position"), each)),
            (PIVOT_FORCE, rr.Arrows3D.descriptor_vectors(), _rows(_vec3(force_vec, "vector"), each)),
            (BODY_TORQUE, rr.Arrows3D.descriptor_vectors(), _rows(_vec3(torque_vec, "vector"), each)),
            (LOAD_TRAIL, rr.LineStrips3D.descriptor_strips(), _rows(self._trail(load, b[:, _EPISODE]), each)),
        ]
        scalar = rr.Scalars.descriptor_scalars()
        missing = ~stepped  # reset samples have no step: no Newton count, reward or action
        for path, (_, sources, _, stepped_only, env_only) in SCALARS.items():
            if env_only and not self.env:
                continue
            columns = [c if isinstance(c, int) else _diag_column(N, c) for c in sources]
            mask = missing if stepped_only else None
            k = len(columns)
            if k == 1:
                values = pa.array(b[:, columns[0]], mask=mask)
            else:
                values = _rows(pa.array(b[:, columns].reshape(-1)), np.arange(0, n * k + 1, k, dtype=np.int32), mask)
            cols.append((path, scalar, values))
        if self.env:
            cols.append((RETURN, scalar, pa.array(self._returns(b[:, _REWARD], b[:, _EPISODE], stepped), mask=missing)))
        self._send(b[:, _STEP], b[:, _TIME], cols)
        reset = ~np.isnan(b[:, _TARGET])  # the targets of the episodes reset here
        if reset.any():
            one = np.arange(reset.sum() + 1, dtype=np.int32)
            self._send(b[reset, _STEP], b[reset, _TIME], [
                (path, rr.Points3D.descriptor_positions(), _rows(_vec3(b[reset, k:k + 3], "position"), one))
                for path, k in ((TARGET_PIVOT, _TARGET), (TARGET_LOAD, _TARGET + 3))])

    def _send(self, steps: np.ndarray, times: np.ndarray, cols) -> None:
        """One record batch: the ``step`` and ``time`` [s] indexes and (entity path,
        component descriptor, values) columns."""
        fields = list(_INDEX_FIELDS)
        arrays = [pa.array(steps.astype(np.int64)),
                  pa.array(np.rint(times * 1e9).astype(np.int64), type=pa.duration("ns"))]
        for path, descriptor, values in cols:
            fields.append(_field(path, descriptor, values.type))
            arrays.append(values)
        self.rec.send_record_batch(pa.RecordBatch.from_arrays(arrays, schema=pa.schema(fields)))

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
        total = _trail_points(points, ep, len(hist), L, self.trail_stride, offsets, out)
        keep = np.arange(max(0, len(points) - (L - 1)), len(points)) if L > 1 else np.arange(0)
        keep = keep[ep[keep] == episode[-1]]
        self._trail_hist, self._trail_episode = points[keep], episode[-1]
        return _strips(out[:total], offsets)

    def _returns(self, rewards: np.ndarray, episode: np.ndarray, stepped: np.ndarray) -> np.ndarray:
        """Running sum of the rewards of stepped samples within each episode (carried across
        flushes)."""
        vals = np.where(stepped, rewards, 0.0)
        if episode[0] == self._return_episode:
            vals[0] += self._return
        idx = np.arange(len(vals))
        start = np.maximum.accumulate(np.where(np.r_[True, episode[1:] != episode[:-1]], idx, 0))
        cs = np.cumsum(vals)
        out = cs - (cs[start] - vals[start])
        self._return, self._return_episode = float(out[-1]), episode[-1]
        return out


# -- free simulations -----------------------------------------------------------------------------

def default_record_every(h: float, rate: float = 50.0) -> int:
    """Physics steps between samples for ~``rate`` samples per simulated second."""
    return max(1, int(round(1.0 / (rate * h))))


def record_simulation(sim, path, t_final: float, record_every: Optional[int] = None, progress: bool = False,
                      pivot_force=None, body_torque=None, **recorder_kwargs) -> dict:
    """Advance ``sim`` by ``t_final`` seconds (a whole number of steps) with constant inputs
    (as in ``Simulator.step``: pivot force spatial [N], body torque body frame [N m]) and
    record it to ``path``: the current state, then every ``record_every`` physics steps
    (default: ~50 samples per simulated second) and at the end. Returns a summary (samples,
    steps, wall time, largest |E - E0 - W| and |pi3 - pi3_0 - impulse| at the samples). A
    :class:`~esp_gym.model.SimulationError` propagates after the recording of the steps before
    it is closed."""
    from tqdm.auto import tqdm

    nsteps = int(round(t_final / sim.h))
    if nsteps < 0 or abs(nsteps * sim.h - t_final) > 1e-9 * max(1.0, abs(t_final)):
        raise ValueError(f"t_final = {t_final} s is not a whole number of steps h = {sim.h} s")
    record_every = default_record_every(sim.h) if record_every is None else int(record_every)
    if record_every < 1:
        raise ValueError(f"record_every must be >= 1, got {record_every}")
    start = _time.perf_counter()
    with Recorder(path, sim.scene, sample_period=record_every * sim.h, **recorder_kwargs) as rec:
        rec.start_episode(sim)
        rec.sample(sim, pivot_force=pivot_force, body_torque=body_torque)
        done = 0
        with tqdm(total=nsteps, disable=not progress, unit="step", unit_scale=True,
                  desc=f"{sim.scene.name} -> {Path(path).name}") as bar:
            while done < nsteps:
                k = min(record_every, nsteps - done)
                sim.step(k, pivot_force=pivot_force, body_torque=body_torque)
                rec.sample(sim, pivot_force=pivot_force, body_torque=body_torque)
                done += k
                bar.update(k)
        samples = rec.samples
        worst = rec.max_abs_residuals
    return {"path": str(path), "scene": sim.scene.name, "steps": nsteps, "record_every": record_every,
            "samples": samples, "wall_time_s": _time.perf_counter() - start,
            "max_abs_energy_balance_residual": float(worst[0]), "max_abs_pi3_balance_residual": float(worst[1])}


# -- the Gymnasium wrapper ------------------------------------------------------------------------

class RecordRerun(gym.Wrapper):
    """Records rollouts of ElasticStringPendulum-v0 to a Rerun ``.rrd`` at the control rate.

    Every ``reset`` and every ``step`` adds one sample: the state and its diagnostics, and for
    steps the applied (clipped) action, the reward and its terms (``info["reward_*"]``) and
    the mean Newton iterations per physics step; each episode's targets are logged at its
    reset. Episodes follow each other on the ``step`` timeline (one step apart) and ``time``
    is ``step`` times the control period. Samples are buffered and written every
    ``flush_every`` samples, after ``flush_seconds`` of wall time, when an episode ends
    (``flush_on_episode_end``), on :meth:`close`, at exit and on SIGTERM/SIGINT.

    There is no every-physics-step option: the environment advances its physics steps inside
    one compiled call (kernels/task.py), so the intermediate states never reach Python;
    recording them would mean re-stepping the physics outside the environment's own kernel.

    The sample is copied by one compiled call from the env's live arrays: the simulator's state
    and diagnostics (which the env's step leaves current), and, when the env has them, its
    applied action, reward terms and step report (``_action``, ``_terms``, ``_result``; the
    same numbers as the clipped action and ``info["reward_*"]``, which the tests check);
    otherwise they are taken from ``action`` and ``info`` (slower) and the Newton series is
    NaN. ``recorder_kwargs`` go to :class:`Recorder` (``flush_every``, ``flush_seconds``,
    ``trail_seconds``, ``strain_scale``, ``force_scale``, ``torque_scale``, ...).
    """

    def __init__(self, env: gym.Env, path, *, flush_on_episode_end: bool = False, **recorder_kwargs):
        super().__init__(env)
        u = env.unwrapped
        if not all(hasattr(u, a) for a in ("sim", "setup", "target")):
            raise TypeError("RecordRerun records ElasticStringPendulum-v0 (an env with sim, setup and target)")
        setup = u.setup
        self.flush_on_episode_end = bool(flush_on_episode_end)
        self.recorder = Recorder(path, setup.scene, env=True, sample_period=setup.control_period,
                                 force_offset=setup.hover, action_scale=(setup.force_limit, setup.torque_limit),
                                 **recorder_kwargs)
        self._fast = all(isinstance(getattr(u, a, None), np.ndarray) for a in ("_action", "_terms", "_result"))
        self._action = u._action if self._fast else np.zeros(6)
        self._terms = u._terms if self._fast else np.zeros(len(REWARD_TERMS))
        self._result = u._result if self._fast else np.zeros(5, dtype=np.int64)
        self._keys = tuple("reward_" + t for t in REWARD_TERMS)
        self._src = None  # the simulator's live arrays (r, R, diagnostics, strain, accumulators)
        self._episode = -1
        self._step = -1  # step index of the last sample

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        rec = self.recorder
        if not rec.closed:
            if rec._n and self.flush_on_episode_end:
                rec.flush(wait=True)
            u = self.env.unwrapped
            S, _, _, D = u.sim.kernel_args
            self._src = (S.r, S.R, D.out, D.strain, S.acc)
            self._episode += 1
            self._step += 1
            rec.start_episode(u.sim)
            i = self._sample(0.0, math.nan)
            rec._buf[i, _TARGET:_TARGET + 6] = u.target
            rec._commit()
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._src is not None and not self.recorder.closed:
            if not self._fast:
                self._action[:] = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
                self._terms[:] = [info[k] for k in self._keys]
            self._step += 1
            self._sample(1.0, reward)
            self.recorder._commit()
            if self.flush_on_episode_end and (terminated or truncated):
                self.recorder.flush(wait=True)  # on disk when the episode ends
        return obs, reward, terminated, truncated, info

    def _sample(self, stepped: float, reward: float) -> int:
        """Write the current sample into the recorder's next row (committed by the caller)."""
        rec = self.recorder
        step = self._step
        _capture(rec._buf, rec._n, *self._src, self._action, self._terms, self._result, rec.E0, rec.pi3_0,
                 float(step), step * rec.sample_period, float(self._episode), stepped, float(reward))
        return rec._n

    def close(self):
        self.recorder.close()
        super().close()
