"""Compiled helpers of the Rerun recorder (esp_gym/viz/recorder.py): copy a sample of the live
arrays into a row, turn buffered rows into the 3-D columns Rerun stores, and build the load's
trail.

A sample row is laid out by :func:`sample_layout` (here, with the recording's other layouts): the
fixed head (:data:`SAMPLE_HEAD`, offsets ``S_*``), then the nodes r (N+1, 3), the per-element
strain energies (N) and the diagnostics (:data:`~.layout.DIAG`). The variable part's offsets
come from the array shapes. Explicit loops throughout: the kernels compile without numba's
runtime (``jit.py``), so there is no slice assignment.
"""
import math
from collections import namedtuple

from ..jit import kernel
from ..layout import (B_ANGULAR_IMPULSE_Z, B_DISSIPATION, B_WINCH_WORK, B_WORK, D_ENERGY, D_PI3, DIAG, IN_BODY_TORQUE,
                      IN_PIVOT_FORCE, R_NEWTON_TOTAL, R_STEPS, WN_LENGTH, WN_REEL_SPEED, Layout)
from ..step.disturbance import DISTURBANCE
from .arrays import A_BODY_TORQUE, A_PIVOT_FORCE, ACTION_SIZE, REWARD_TERMS, SENSORS, TARGET

#: The fixed head of a recording sample row; then the nodes r (N+1, 3), the per-element strain
#: energies (N) and the diagnostics (:data:`DIAG`): see :func:`sample_columns`. ``stepped`` is
#: 1 for a sample after a step, 0 after a reset; ``newton`` the mean Newton iterations per
#: physics step; ``inputs`` pivot force [N] (spatial) and body torque [N m] (body frame);
#: ``balances`` work, E - E0 - W, angular impulse, pi3 - pi3_0 - impulse; ``target`` NaN but at
#: an episode's reset; ``R`` row-major; ``sensors`` (:data:`SENSORS`: hook tension [N], load
#: target offset [m]) and ``disturbance`` (:data:`DISTURBANCE`: gust and wind [m/s], load drag,
#: push, line drag [N]), spatial frame, zeros for free simulations; ``rho`` the episode's
#: attachment -> centre of mass offset rho_c (body frame) [m]; ``winch`` (:data:`SAMPLE_WINCH`)
#: the unstretched length [m], the reel speed [m/s] and the winch's work [J] (E - E0 - W then
#: subtracts it too).
SAMPLE_WINCH = Layout(("unstretched_length", 1), ("reel_speed", 1), ("winch_work", 1))
#: The sample's inputs: pivot force [N] (spatial) and body torque [N m] (body frame).
SAMPLE_INPUTS = Layout(("pivot_force", 3), ("body_torque", 3))
#: The sample's balances [J, N m s]: the inputs' work, E - E0 - W, the angular impulse about e3,
#: pi3 - pi3_0 - that impulse.
SAMPLE_BALANCES = Layout(("work", 1), ("energy_residual", 1), ("angular_impulse", 1), ("pi3_residual", 1))
SAMPLE_HEAD = Layout(("step", 1), ("time", 1), ("episode", 1), ("stepped", 1), ("newton", 1), ("reward", 1),
                     ("action", ACTION_SIZE), ("terms", len(REWARD_TERMS)), ("inputs", SAMPLE_INPUTS.size),
                     ("balances", SAMPLE_BALANCES.size), ("target", TARGET.size), ("R", 9), ("sensors", SENSORS.size),
                     ("disturbance", DISTURBANCE.size), ("rho", 3), ("winch", SAMPLE_WINCH.size))
S_STEP = SAMPLE_HEAD.scalar("step")
S_TIME = SAMPLE_HEAD.scalar("time")
S_EPISODE = SAMPLE_HEAD.scalar("episode")
S_STEPPED = SAMPLE_HEAD.scalar("stepped")
S_NEWTON = SAMPLE_HEAD.scalar("newton")
S_REWARD = SAMPLE_HEAD.scalar("reward")
S_ACTION = SAMPLE_HEAD.start("action")
S_TERMS = SAMPLE_HEAD.start("terms")
S_INPUTS = SAMPLE_HEAD.start("inputs")
S_BALANCES = SAMPLE_HEAD.start("balances")
S_TARGET = SAMPLE_HEAD.start("target")
S_R = SAMPLE_HEAD.start("R")
S_SENSORS = SAMPLE_HEAD.start("sensors")
S_DISTURBANCE = SAMPLE_HEAD.start("disturbance")
S_RHO = SAMPLE_HEAD.start("rho")
S_WINCH = SAMPLE_HEAD.start("winch")
SW_UNSTRETCHED_LENGTH = SAMPLE_WINCH.scalar("unstretched_length")
SW_REEL_SPEED = SAMPLE_WINCH.scalar("reel_speed")
SW_WINCH_WORK = SAMPLE_WINCH.scalar("winch_work")
SAMPLE_HEAD_SIZE = SAMPLE_HEAD.size
SI_PIVOT_FORCE = SAMPLE_INPUTS.start("pivot_force")
SI_BODY_TORQUE = SAMPLE_INPUTS.start("body_torque")
SB_WORK = SAMPLE_BALANCES.scalar("work")
SB_ENERGY_RESIDUAL = SAMPLE_BALANCES.scalar("energy_residual")
SB_ANGULAR_IMPULSE = SAMPLE_BALANCES.scalar("angular_impulse")
SB_PI3_RESIDUAL = SAMPLE_BALANCES.scalar("pi3_residual")

_HEAD_SIZES = dict(SAMPLE_HEAD.fields)
#: Entries of the head's action, reward-terms, target, sensors and disturbance fields.
N_ACTION = _HEAD_SIZES["action"]
N_TERMS = _HEAD_SIZES["terms"]
N_TARGET = _HEAD_SIZES["target"]
N_SENSORS = _HEAD_SIZES["sensors"]
N_DISTURBANCE = _HEAD_SIZES["disturbance"]


def sample_layout(n_elements: int) -> Layout:
    """The whole sample row for a string of ``n_elements`` elements."""
    return Layout(*SAMPLE_HEAD.fields, ("nodes", 3 * (n_elements + 1)), ("strain", n_elements), ("diag", DIAG.size))


#: The live arrays a sample is copied from: nodes ``r``, ``R``, the diagnostics ``out`` (DIAG) and
#: ``strain`` energies (current), the balances ``acc`` (BALANCE), the applied ``action`` (ACTION)
#: and reward ``terms`` (REWARD), the step ``report`` (REPORT), the ``inputs`` (INPUTS: pivot
#: force, body torque), the ``target`` (TARGET; NaN when not an episode's reset), the
#: ``sensors`` (SENSORS), the ``disturbance`` (DISTURBANCE), the episode's ``rho`` (rho_c, body
#: frame [m]) and the ``winch`` state (WINCH).
SampleSources = namedtuple("SampleSources", "r R out strain acc action terms report inputs target sensors "
                                            "disturbance rho winch")
#: Where a sample stands: the balances' origins ``E0`` [J] and ``pi30`` [kg m^2/s], and the
#: timelines and scalars: ``step``, ``t`` [s], ``episode``, ``stepped`` (1 after a step, 0 after a
#: reset) and the step's ``reward``.
SampleClock = namedtuple("SampleClock", "E0 pi30 step t episode stepped reward")


@kernel(entry=True)
def capture_sample(buf, i, sources, clock):
    """Write one sample into row ``i`` of ``buf`` from the live arrays ``sources`` and the scalars
    ``clock``, the fields of :class:`SampleSources` and :class:`SampleClock` as plain tuples
    (numba types those faster). The Newton column is newton_total / steps (NaN without steps);
    the winch's columns are its length and speed, with the winch's work from the balances. The
    balance residuals are computed as in ``Simulator.diagnostics`` (same operations, same order,
    so the same bits)."""
    src = SampleSources(*sources)
    clk = SampleClock(*clock)
    row = buf[i]
    row[S_STEP] = clk.step
    row[S_TIME] = clk.t
    row[S_EPISODE] = clk.episode
    row[S_STEPPED] = clk.stepped
    row[S_NEWTON] = src.report[R_NEWTON_TOTAL] / src.report[R_STEPS] if src.report[R_STEPS] > 0 else math.nan
    row[S_REWARD] = clk.reward
    for k in range(N_ACTION):
        row[S_ACTION + k] = src.action[k]
    for k in range(N_TERMS):
        row[S_TERMS + k] = src.terms[k]
    for c in range(3):
        row[S_INPUTS + SI_PIVOT_FORCE + c] = src.inputs[IN_PIVOT_FORCE + c]
        row[S_INPUTS + SI_BODY_TORQUE + c] = src.inputs[IN_BODY_TORQUE + c]
    row[S_BALANCES + SB_WORK] = src.acc[B_WORK]
    row[S_BALANCES + SB_ENERGY_RESIDUAL] = (src.out[D_ENERGY] - clk.E0 - src.acc[B_WORK] - src.acc[B_WINCH_WORK]
                                            + src.acc[B_DISSIPATION])
    row[S_BALANCES + SB_ANGULAR_IMPULSE] = src.acc[B_ANGULAR_IMPULSE_Z]
    row[S_BALANCES + SB_PI3_RESIDUAL] = src.out[D_PI3] - clk.pi30 - src.acc[B_ANGULAR_IMPULSE_Z]
    for k in range(N_TARGET):
        row[S_TARGET + k] = src.target[k]
    for k in range(N_SENSORS):
        row[S_SENSORS + k] = src.sensors[k]
    for k in range(N_DISTURBANCE):
        row[S_DISTURBANCE + k] = src.disturbance[k]
    for c in range(3):
        row[S_RHO + c] = src.rho[c]
    row[S_WINCH + SW_UNSTRETCHED_LENGTH] = src.winch[WN_LENGTH]
    row[S_WINCH + SW_REEL_SPEED] = src.winch[WN_REEL_SPEED]
    row[S_WINCH + SW_WINCH_WORK] = src.acc[B_WINCH_WORK]
    for a in range(3):
        for c in range(3):
            row[S_R + 3 * a + c] = src.R[a, c]
    for a in range(src.r.shape[0]):
        for c in range(3):
            row[SAMPLE_HEAD_SIZE + 3 * a + c] = src.r[a, c]
    base = SAMPLE_HEAD_SIZE + 3 * src.r.shape[0]
    for k in range(src.strain.shape[0]):
        row[base + k] = src.strain[k]
    base += src.strain.shape[0]
    for k in range(src.out.shape[0]):
        row[base + k] = src.out[k]


#: How the 3-D columns are drawn: ``inv_strain_scale`` [1/J] and the colour ``lut`` of the strain,
#: whether the arrows' inputs come from the action (``inputs_from_action``) or the input columns,
#: the hover ``force_offset`` (3) [N], the action's ``force_limit`` [N] and ``torque_limit``
#: [N m], and the arrows' lengths per unit, ``force_scale`` [m/N] and ``torque_scale`` [m/(N m)].
GeometryStyle = namedtuple("GeometryStyle", "inv_strain_scale lut inputs_from_action force_offset force_limit "
                                            "torque_limit force_scale torque_scale")
#: The 3-D columns (float32 unless stated): element end points ``pts`` (n, N, 2, 3), strain
#: ``colors`` (n N,) uint32, the attachment point ``translation`` (n, 3) and R column-major
#: ``mat`` (n, 9) (Rerun's layout), the ``pivot`` (n, 3), the arrows ``force_vec`` and
#: ``torque_vec`` (n, 3), and the load's centre of mass ``load`` (n, 3) float64.
GeometryColumns = namedtuple("GeometryColumns", "pts colors translation mat pivot force_vec torque_vec load")


@kernel(entry=True)
def sample_geometry(buf, n, style, columns):
    """The 3-D columns (:class:`GeometryColumns`, a plain tuple of its fields) of the first ``n``
    rows of ``buf``, drawn as ``style`` says (:class:`GeometryStyle`, likewise): strain colours
    from the ``lut`` at sqrt(E / scale) clipped to [0, 1] (NaN -> 0); the arrows force_scale x
    (pivot force - force_offset) and torque_scale x body torque, with the inputs taken from the
    action (force_offset + force_limit a_force, torque_limit a_torque) or from the input
    columns; and the load's centre of mass r_N + R rho_c, with the row's own rho_c (each
    episode's)."""
    (inv_strain_scale, lut, inputs_from_action, force_offset, force_limit, torque_limit, force_scale,
     torque_scale) = style
    pts, colors, translation, mat, pivot, force_vec, torque_vec, load = columns
    N = pts.shape[1]
    strain0 = SAMPLE_HEAD_SIZE + 3 * (N + 1)
    for i in range(n):
        row = buf[i]
        for a in range(N):
            for c in range(3):
                pts[i, a, 0, c] = row[SAMPLE_HEAD_SIZE + 3 * a + c]
                pts[i, a, 1, c] = row[SAMPLE_HEAD_SIZE + 3 * (a + 1) + c]
            x = row[strain0 + a] * inv_strain_scale
            x = min(x, 1.0) if x > 0.0 else 0.0
            colors[i * N + a] = lut[int(math.sqrt(x) * 255.0 + 0.5)]
        for c in range(3):
            translation[i, c] = row[SAMPLE_HEAD_SIZE + 3 * N + c]
            pivot[i, c] = row[SAMPLE_HEAD_SIZE + c]
            acc = row[SAMPLE_HEAD_SIZE + 3 * N + c]
            for k in range(3):
                mat[i, 3 * c + k] = row[S_R + 3 * k + c]
                acc += row[S_R + 3 * c + k] * row[S_RHO + k]
            load[i, c] = acc
            if inputs_from_action:
                force = force_offset[c] + force_limit * row[S_ACTION + A_PIVOT_FORCE + c]
                torque = torque_limit * row[S_ACTION + A_BODY_TORQUE + c]
            else:
                force = row[S_INPUTS + SI_PIVOT_FORCE + c]
                torque = row[S_INPUTS + SI_BODY_TORQUE + c]
            force_vec[i, c] = force_scale * (force - force_offset[c])
            torque_vec[i, c] = torque_scale * torque


@kernel(entry=True)
def trail_points(points, episode, first_new, span, stride, offsets, out):
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
