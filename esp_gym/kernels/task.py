"""Compiled per-environment step of the Gymnasium environment: inputs -> physics -> observation,
reward terms, termination. The single and the batched environments call the same
:func:`env_step_one`, so their results agree bit for bit; esp_gym/control.py is their
Python face.

Every packed vector is laid out in kernels/layout.py: the observation (OBSERVATION), reward
terms (REWARD), task parameters ``tp`` (TASK_PARAMS, from esp_gym/tasks.py), action
parameters ``ap`` (ACTION_PARAMS), targets (TARGET, spatial frame [m]), inputs (INPUTS) and
the step report (REPORT).
"""
import math

import numpy as np
from numba import prange

from .jit import kernel
from .diagnostics import diagnostics
from .disturbance import disturb, external_potential
from .lgvi import kahan_add
from .layout import (A_BODY_TORQUE, A_PIVOT_FORCE, A_REEL_SPEED, ACTION_SIZE, AP_FORCE_LIMIT, AP_HIGH, AP_HOVER,
                     AP_LOW, AP_MAX_REEL_SPEED, AP_TORQUE_LIMIT, B_WINCH_WORK, B_WORK, D_ENERGY, D_STRETCHED_LENGTH,
                     ENERGY_BALANCE, IN_BODY_TORQUE, IN_PIVOT_FORCE, IN_SPATIAL_TORQUE, O_ANGULAR_VELOCITY, O_ATTITUDE,
                     O_LENGTH, O_LOAD_ERROR, O_LOAD_VELOCITY, O_PIVOT_ERROR, O_PIVOT_VELOCITY, O_STRETCH, OK,
                     R_STATUS, R_STEPS, R_TERMINATION, RW_CONTROL, RW_LOAD_POSITION, RW_LOAD_VELOCITY,
                     RW_PIVOT_POSITION, RW_SPIN, RW_SWING, SCHEME_DISTURBED, SCHEME_IMPLICIT, SN_HOOK_TENSION,
                     SN_LOAD_TARGET_OFFSET, T_LOAD, T_PIVOT, T_VELOCITY, TERM_NONE, TERM_OVERSTRETCH, TERM_WORKSPACE,
                     TP_ENERGY_BOUND, TP_ENERGY_ORIGIN, TP_ENERGY_WATCHDOG, TP_MAX_STRETCHED_LENGTH,
                     TP_SCALE_POSITION, TP_SCALE_SPIN, TP_SCALE_SWING, TP_SCALE_VELOCITY, TP_STRING_LENGTH,
                     TP_W_CONTROL, TP_W_LOAD_POSITION, TP_W_LOAD_VELOCITY, TP_W_PIVOT_POSITION, TP_W_SPIN, TP_W_SWING,
                     TP_WORKSPACE_RADIUS, WN_LENGTH, WN_MASS_PER_LENGTH, WN_SPEED, DiagWork, LGVIParams, StateArrays,
                     WinchArrays, Work)
from .loops import advance_loop_shared
from .reference import advance_reference
from .winch import length_params, winch_energy
from .winch_loops import winch_loop_shared


@kernel
def _tol(x, scale):
    """Bounded shaping in (0, 1]: 1 at x = 0, 1/2 at x = scale (a Cauchy-shaped tolerance)."""
    q = x / scale
    return 1.0 / (1.0 + q * q)


@kernel(inline="always")
def env_sensors(S, P, target, sensors):
    """SENSORS of the current state: the first element's force on the pivot, c x_0 with c =
    kappa (1 - u/|x_0|) (0 where a slack string is compressed; kernels/string.py
    ``nodal_forces``), and the load target - pivot position."""
    r = S.r
    x0 = r[1, 0] - r[0, 0]
    x1 = r[1, 1] - r[0, 1]
    x2 = r[1, 2] - r[0, 2]
    c = P.kappa * (1.0 - P.u / math.sqrt(x0 * x0 + x1 * x1 + x2 * x2))
    if P.slack and c < 0.0:
        c = 0.0
    sensors[SN_HOOK_TENSION] = c * x0
    sensors[SN_HOOK_TENSION + 1] = c * x1
    sensors[SN_HOOK_TENSION + 2] = c * x2
    for i in range(3):
        sensors[SN_LOAD_TARGET_OFFSET + i] = target[T_LOAD + i] - r[0, i]


@kernel
def env_observe(S, P, D, target, tp, action, obs, terms, sensors, length):
    """Observation (OBSERVATION), SENSORS and reward terms (REWARD) of the current state (``D``
    filled by diagnostics) at the unstretched ``length`` [m] (the scene's; a winch's current one,
    whose constants ``P`` then holds). Returns the termination code (TERM_*)."""
    env_sensors(S, P, target, sensors)
    r = S.r
    R = S.R
    n = r.shape[0] - 1
    rho = P.rho
    V = D.V
    w = D.omega
    # load centre of mass and its velocity: r_N + R rho_c, v_N + R (Omega x rho_c)
    x0 = w[1] * rho[2] - w[2] * rho[1]
    x1 = w[2] * rho[0] - w[0] * rho[2]
    x2 = w[0] * rho[1] - w[1] * rho[0]
    ep = 0.0
    el = 0.0
    vl = 0.0
    for i in range(3):
        ci = r[n, i] + (R[i, 0] * rho[0] + R[i, 1] * rho[1] + R[i, 2] * rho[2])
        vi = V[n, i] + (R[i, 0] * x0 + R[i, 1] * x1 + R[i, 2] * x2)
        vi -= target[T_VELOCITY + i]  # relative to the moving reference (x - 0.0 == x)
        ei = r[0, i] - target[T_PIVOT + i]
        li = ci - target[T_LOAD + i]
        obs[O_PIVOT_ERROR + i] = ei
        obs[O_PIVOT_VELOCITY + i] = V[0, i] - target[T_VELOCITY + i]
        obs[O_LOAD_ERROR + i] = li
        obs[O_LOAD_VELOCITY + i] = vi
        obs[O_ATTITUDE + i] = R[i, 0]
        obs[O_ATTITUDE + 3 + i] = R[i, 1]
        obs[O_ANGULAR_VELOCITY + i] = w[i]
        ep += ei * ei
        el += li * li
        vl += vi * vi
    stretched = D.out[D_STRETCHED_LENGTH]
    obs[O_STRETCH] = stretched / length - 1.0
    # swing: angle of (load - pivot) from the downward vertical e3
    dx = (r[n, 0] - r[0, 0]) + (R[0, 0] * rho[0] + R[0, 1] * rho[1] + R[0, 2] * rho[2])  # load - pivot
    dy = (r[n, 1] - r[0, 1]) + (R[1, 0] * rho[0] + R[1, 1] * rho[1] + R[1, 2] * rho[2])
    dz = (r[n, 2] - r[0, 2]) + (R[2, 0] * rho[0] + R[2, 1] * rho[1] + R[2, 2] * rho[2])
    swing = math.atan2(math.sqrt(dx * dx + dy * dy), dz)
    spin = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    a2 = 0.0
    for i in range(action.shape[0]):
        a2 += action[i] * action[i]
    terms[RW_LOAD_POSITION] = tp[TP_W_LOAD_POSITION] * _tol(math.sqrt(el), tp[TP_SCALE_POSITION])
    terms[RW_LOAD_VELOCITY] = tp[TP_W_LOAD_VELOCITY] * _tol(math.sqrt(vl), tp[TP_SCALE_VELOCITY])
    terms[RW_PIVOT_POSITION] = tp[TP_W_PIVOT_POSITION] * _tol(math.sqrt(ep), tp[TP_SCALE_POSITION])
    terms[RW_SWING] = tp[TP_W_SWING] * _tol(swing, tp[TP_SCALE_SWING])
    terms[RW_SPIN] = tp[TP_W_SPIN] * _tol(spin, tp[TP_SCALE_SPIN])
    terms[RW_CONTROL] = -tp[TP_W_CONTROL] * a2 / action.shape[0]
    if not (stretched <= tp[TP_MAX_STRETCHED_LENGTH] * (length / tp[TP_STRING_LENGTH])):
        return TERM_OVERSTRETCH
    radius = tp[TP_WORKSPACE_RADIUS]
    if not (ep <= radius * radius and el <= radius * radius):
        return TERM_WORKSPACE
    return TERM_NONE


@kernel(inline="always")
def energy_watchdog(S, D, tp, code):
    """``code``, or ENERGY_BALANCE where the energy balance of the state just observed (``D``
    filled) broke the episode's bound: |E - E0 - W| > f (scale + |W|), W the inputs' and the
    winch's work, E0 the reset's energy (docs/physics.md, "The energy watchdog"). It outranks
    the task's terminations."""
    work = S.acc[B_WORK] + S.acc[B_WINCH_WORK]
    residual = D.out[D_ENERGY] - tp[TP_ENERGY_ORIGIN] - work
    if not (abs(residual) <= tp[TP_ENERGY_BOUND] + tp[TP_ENERGY_WATCHDOG] * abs(work)):
        return ENERGY_BALANCE
    return code


@kernel(inline="always")
def action_inputs(action, ap, inputs):
    """Clipped action (ACTION) -> kernel inputs (INPUTS): pivot force hover + force_limit x
    the action's pivot force [N] (spatial), body torque torque_limit x its body torque [N m],
    no spatial torque."""
    for i in range(3):
        inputs[IN_PIVOT_FORCE + i] = ap[AP_HOVER + i] + ap[AP_FORCE_LIMIT] * action[A_PIVOT_FORCE + i]
        inputs[IN_BODY_TORQUE + i] = ap[AP_TORQUE_LIMIT] * action[A_BODY_TORQUE + i]
        inputs[IN_SPATIAL_TORQUE + i] = 0.0


@kernel
def actions_finite(raw):
    """Whether every entry of the raw actions (B, ACTION) is finite (the batched envs check this
    before any sub-environment resets, so a bad call changes nothing)."""
    for b in range(raw.shape[0]):
        for i in range(raw.shape[1]):
            if not np.isfinite(raw[b, i]):
                return False
    return True


@kernel(inline="always")
def take_action(raw, ap, action, inputs):
    """Check, clip and map a raw action (ACTION, or WINCH_ACTION: ``action``'s size says): False,
    touching nothing, if any entry is not finite; else ``action`` = raw clipped to [low, high] (as
    np.clip; the reel speed's box is [-1, 1]) and ``inputs`` from it. Returns the reel speed
    [m/s] (0 without a winch) as a float, or -inf for an action that is not finite."""
    size = action.shape[0]
    for i in range(size):
        if not np.isfinite(raw[i]):
            return -np.inf
    for i in range(ACTION_SIZE):
        a = raw[i]
        if a < ap[AP_LOW + i]:
            a = ap[AP_LOW + i]
        elif a > ap[AP_HIGH + i]:
            a = ap[AP_HIGH + i]
        action[i] = a
    action_inputs(action, ap, inputs)
    if size == ACTION_SIZE:
        return 0.0
    action[A_REEL_SPEED] = min(max(raw[A_REEL_SPEED], -1.0), 1.0)
    return ap[AP_MAX_REEL_SPEED] * action[A_REEL_SPEED]


@kernel
def env_step_one(S, W, P, D, WA, inputs, reel, nsub, target, tp, action, obs, terms, sensors, result, dp, ds, draws,
                 drawn, implicit=False, disturbed=False, winched=False):
    """One control step: ``nsub`` physics steps with constant ``inputs`` (INPUTS), then
    observation, reward terms and termination code. ``result``: the step's REPORT (int64).
    ``winched``: the winch reels at ``reel`` [m/s] (kernels/winch.py, its arrays ``WA``), and
    the observation ends with the unstretched length. ``implicit``: the implicit string's step
    (kernels/implicit.py). ``disturbed``: wind and pushes (kernels/disturbance.py) from the
    episode's DISTURBANCE_PARAMS ``dp``, the DISTURBANCE state ``ds`` and the next row
    ``drawn[0]`` of the random ``draws`` (rows of DRAWS; ``drawn[0]`` is then advanced); their
    work over the step joins the balances."""
    free = P.first == 0
    first = 0 if free else 1
    phi = 0.0
    if disturbed:
        disturb(S.r, S.R, D.V, D.omega, P.rho, dp, ds, draws[drawn[0]], W.ext)
        drawn[0] += 1
        phi = external_potential(S, P, W.ext, first)
    # the general kernel: an environment always has inputs and, as a rule, an off-centre load
    if winched:
        winch_loop_shared(S, W, P, WA, D, inputs, reel, nsub, result, disturbed, implicit)
    else:
        advance_loop_shared(S, W, P, inputs, nsub, result, free, True, True, P.compensated, False, implicit, disturbed)
    if disturbed:
        kahan_add(S.acc, S.accc, B_WORK, external_potential(S, P, W.ext, first) - phi)
    advance_reference(target, result[R_STEPS] * P.h)
    status = result[R_STATUS]
    if winched:
        length = WA.state[WN_LENGTH]
        winch_energy(S, P, WA, D, length, WA.state[WN_SPEED])
        n = S.r.shape[0] - 1
        Pl = length_params(P, WA, length, WA.state[WN_MASS_PER_LENGTH] * length / n, first, n, False)
        code = env_observe(S, Pl, D, target, tp, action, obs, terms, sensors, length)
        obs[O_LENGTH] = length
    else:
        diagnostics(S, P, D)
        code = env_observe(S, P, D, target, tp, action, obs, terms, sensors, tp[TP_STRING_LENGTH])
    result[R_TERMINATION] = status if status != OK else energy_watchdog(S, D, tp, code)


@kernel
def env_reset_observe(S, P, D, WA, target, tp, action, obs, terms, sensors, winched):
    """Observation of a freshly set state (no step; a winch at the scene's length and at rest),
    whose energy becomes the episode's E0 (TP_ENERGY_ORIGIN). Returns the termination code."""
    diagnostics(S, P, D)
    tp[TP_ENERGY_ORIGIN] = D.out[D_ENERGY]
    code = env_observe(S, P, D, target, tp, action, obs, terms, sensors, tp[TP_STRING_LENGTH])
    if winched:
        obs[O_LENGTH] = WA.state[WN_LENGTH]
    return code


@kernel(inline="always")
def state_row(S, b):
    """Sub-environment ``b`` of a stacked :class:`StateArrays` (views)."""
    return StateArrays(S.r[b], S.p[b], S.R[b], S.Pi[b], S.rc[b], S.pc[b], S.Rc[b], S.Pic[b], S.f[b], S.acc[b],
                       S.accc[b], S.owed[b])


@kernel(inline="always")
def work_row(W, b):
    """Sub-environment ``b`` of a stacked :class:`Work` (views)."""
    return Work(W.fn[b], W.X[b], W.Y[b], W.FmI[b], W.RF[b], W.Rn[b], W.jac[b], W.backup[b], W.fl[b], W.fr[b], W.dy[b],
                W.elim[b], W.taut[b], W.ext[b], W.switch[b])


@kernel(inline="always")
def diag_row(D, b):
    """Sub-environment ``b`` of a stacked :class:`DiagWork` (views)."""
    return DiagWork(D.V[b], D.strain[b], D.omega[b], D.out[b])


@kernel(inline="always")
def winch_row(WA, b):
    """Sub-environment ``b`` of a stacked :class:`WinchArrays` (views)."""
    return WinchArrays(WA.state[b], WA.coef[b], WA.lower[b], WA.upper[b], WA.inv[b], WA.cp[b], WA.w[b], WA.jeff[b],
                       WA.pshift[b], WA.dinv[b], WA.dcp[b], WA.dw[b], WA.djeff[b], WA.backup[b], WA.diag[b], WA.rhs[b])


@kernel(inline="always")
def params_row(P, b):
    """Sub-environment ``b``'s constants from a stacked :class:`LGVIParams` (each scalar field a
    (B,) array, each array field with a leading batch axis): the types of one environment's."""
    return LGVIParams(P.h[b], P.m[b], P.kappa[b], P.u[b], P.g[b], P.M[b], P.Mp[b], P.rho[b], P.J[b], P.Jd[b],
                      P.Jeff[b], P.inv[b], P.cp[b], P.off[b], P.w[b], P.first[b], P.slack[b], P.tol[b],
                      P.max_iter[b], P.gammas[b], P.max_len2[b], P.compensated[b], P.mdiag[b], P.settle[b],
                      P.gradient[b])


def _entry_points(winched: bool):
    """``(step, batch)``, the compiled entry points of the environment without or with the winch
    (``winched`` is a closure constant: the winch's loop compiles only for environments that
    reel).

    ``step(s, w, p, d, wa, raw, ap, inputs, nsub, target, tp, action, obs, terms, sensors,
    result, dp, ds, draws, drawn, scheme)``: :func:`take_action` of the raw action, then
    :func:`env_step_one`, for one environment (one compiled call per control step). Returns
    False, with nothing changed, if the raw action is not finite. ``s, w, p, d, wa`` are the
    fields of StateArrays, Work, LGVIParams, DiagWork and WinchArrays (read only when
    ``winched``) as *plain* tuples: numba's dispatcher types a plain tuple about twice as fast
    as a namedtuple (3 us less per call here), and the namedtuples are rebuilt for free in
    compiled code. ``dp, ds, draws, drawn`` (read only when disturbed): DISTURBANCE_PARAMS,
    DISTURBANCE, (K, DRAWS) random draws and the index (1,) int64 of the next one, which the
    caller keeps below K.

    ``scheme`` (int, bits SCHEME_*) chooses the implicit string and wind and pushes. It is an
    argument, not a compile-time constant: as constants each combination compiled the whole step
    again (numba types a constant bool as a literal, one signature each), 36-60 s apiece on a
    cold cache; as an argument one compile serves them all (docs/performance.md, "Start-up").

    ``batch(s, w, d, p, wa, raw, ap, inputs, active, nsub, target, tp, action, obs, terms,
    sensors, result, dp, ds, draws, drawn, scheme)``: :func:`take_action` of ``raw[b]`` and
    :func:`env_step_one` for every environment b with ``active[b]``, in parallel (the raw actions
    must be finite: :func:`actions_finite`). ``s, w, d, p, wa`` are StateArrays, Work, DiagWork,
    LGVIParams and WinchArrays whose arrays carry a leading batch axis (:func:`params_row`), as
    plain tuples; the other arrays are batched too: raw (B, ACTION), ap (B, ACTION_PARAMS),
    inputs (B, INPUTS), nsub (B,), target (B, TARGET), tp (B, TASK_PARAMS), action, obs, terms,
    sensors (B, SENSORS), result (B, REPORT), dp, ds, draws (B, K, DRAWS), drawn (B, 1).
    """

    @kernel
    def step(s, w, p, d, wa, raw, ap, inputs, nsub, target, tp, action, obs, terms, sensors, result, dp, ds, draws,
             drawn, scheme):
        reel = take_action(raw, ap, action, inputs)
        if reel == -np.inf:
            return False
        env_step_one(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), WinchArrays(*wa), inputs, reel, nsub,
                     target, tp, action, obs, terms, sensors, result, dp, ds, draws, drawn,
                     (scheme & SCHEME_IMPLICIT) != 0, (scheme & SCHEME_DISTURBED) != 0, winched)
        return True

    @kernel(parallel=True)
    def batch(s, w, d, p, wa, raw, ap, inputs, active, nsub, target, tp, action, obs, terms, sensors, result, dp, ds,
              draws, drawn, scheme):
        implicit = (scheme & SCHEME_IMPLICIT) != 0
        disturbed = (scheme & SCHEME_DISTURBED) != 0
        S = StateArrays(*s)
        W = Work(*w)
        D = DiagWork(*d)
        P = LGVIParams(*p)
        WA = WinchArrays(*wa)
        for b in prange(raw.shape[0]):
            if active[b]:
                reel = take_action(raw[b], ap[b], action[b], inputs[b])
                if reel != -np.inf:
                    env_step_one(state_row(S, b), work_row(W, b), params_row(P, b), diag_row(D, b), winch_row(WA, b),
                                 inputs[b], reel, nsub[b], target[b], tp[b], action[b], obs[b], terms[b], sensors[b],
                                 result[b], dp[b], ds[b], draws[b], drawn[b], implicit, disturbed, winched)

    return step, batch


#: The entry points without and with the winch (see :func:`_entry_points`); each compiles only
#: for environments that use it.
ENTRY_POINTS = {winched: _entry_points(winched) for winched in (False, True)}
