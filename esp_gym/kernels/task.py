"""Compiled per-environment step of the Gymnasium environment: inputs -> physics -> observation,
reward terms, termination. The single and the batched environments call the same
:func:`env_step_one`, so their results agree bit for bit.

Task parameters ``tp`` (float64, see :data:`TASK_PARAM_NAMES`) and per-env targets
``target`` (6,: pivot target, load target [m], spatial frame) come from esp_gym/tasks.py.
"""
import math

import numpy as np
from numba import prange

from ._jit import kernel
from .diagnostics import DiagWork, diagnostics
from .lgvi import OK, LGVIParams, StateArrays, Work, advance_loop

#: Layout of the task parameter vector.
TASK_PARAM_NAMES = (
    "w_load_position", "w_load_velocity", "w_pivot_position", "w_swing", "w_spin", "w_control",
    "scale_position", "scale_velocity", "scale_swing", "scale_spin",
    "max_stretched_length", "workspace_radius", "string_length",
)
#: Reward terms, in the order they are summed (env info keys are "reward_" + name).
REWARD_TERMS = ("load_position", "load_velocity", "pivot_position", "swing", "spin", "control")
#: Observation layout: (name, size).
OBS_LAYOUT = (
    ("pivot_position_error", 3), ("pivot_velocity", 3), ("load_position_error", 3),
    ("load_velocity", 3), ("attitude_6d", 6), ("angular_velocity", 3), ("string_stretch", 1),
)
OBS_SIZE = 22

#: Layout of the action parameter vector ``ap`` (float64, 17): the action box's low (6) and
#: high (6) bounds, the hover force (3) [N], force_limit [N] and torque_limit [N m].
ACTION_PARAM_SIZE = 17

#: Termination codes (result[4]); 1 and 2 are the physics kernel's failure statuses.
TERM_NONE = 0
TERM_OVERSTRETCH = 3
TERM_WORKSPACE = 4


@kernel
def _tol(x, scale):
    """Bounded shaping in (0, 1]: 1 at x = 0, 1/2 at x = scale (a Cauchy-shaped tolerance)."""
    q = x / scale
    return 1.0 / (1.0 + q * q)


@kernel(inline="always")
def env_observe(S, P, D, target, tp, action, obs, terms):
    """Observation (OBS_SIZE) and reward terms of the current state (``D`` filled by
    diagnostics). Returns the termination code (TERM_*)."""
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
        obs[i] = r[0, i] - target[i]
        obs[3 + i] = V[0, i]
        obs[6 + i] = ci - target[3 + i]
        obs[9 + i] = vi
        obs[12 + i] = R[i, 0]
        obs[15 + i] = R[i, 1]
        obs[18 + i] = w[i]
        ep += obs[i] * obs[i]
        el += obs[6 + i] * obs[6 + i]
        vl += vi * vi
    length = D.out[7]
    obs[21] = length / tp[12] - 1.0
    # swing: angle of (load - pivot) from the downward vertical e3
    dx = (r[n, 0] - r[0, 0]) + (R[0, 0] * rho[0] + R[0, 1] * rho[1] + R[0, 2] * rho[2])  # load - pivot
    dy = (r[n, 1] - r[0, 1]) + (R[1, 0] * rho[0] + R[1, 1] * rho[1] + R[1, 2] * rho[2])
    dz = (r[n, 2] - r[0, 2]) + (R[2, 0] * rho[0] + R[2, 1] * rho[1] + R[2, 2] * rho[2])
    swing = math.atan2(math.sqrt(dx * dx + dy * dy), dz)
    spin = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    a2 = 0.0
    for i in range(action.shape[0]):
        a2 += action[i] * action[i]
    terms[0] = tp[0] * _tol(math.sqrt(el), tp[6])
    terms[1] = tp[1] * _tol(math.sqrt(vl), tp[7])
    terms[2] = tp[2] * _tol(math.sqrt(ep), tp[6])
    terms[3] = tp[3] * _tol(swing, tp[8])
    terms[4] = tp[4] * _tol(spin, tp[9])
    terms[5] = -tp[5] * a2 / action.shape[0]
    if not (length <= tp[10]):
        return TERM_OVERSTRETCH
    if not (ep <= tp[11] * tp[11] and el <= tp[11] * tp[11]):
        return TERM_WORKSPACE
    return TERM_NONE


@kernel(inline="always")
def action_inputs(action, ap, inputs):
    """Clipped action (6,) -> kernel inputs (9,): pivot force hover + force_limit a[0:3] [N]
    (spatial), body torque torque_limit a[3:6] [N m], no spatial torque. The same operations
    as the NumPy expression, so the same bits."""
    for i in range(3):
        inputs[i] = ap[12 + i] + ap[15] * action[i]
        inputs[3 + i] = ap[16] * action[3 + i]
        inputs[6 + i] = 0.0


@kernel
def actions_finite(raw):
    """Whether every entry of the raw actions (B, 6) is finite (the batched envs check this
    before any sub-environment resets, so a bad call changes nothing)."""
    for b in range(raw.shape[0]):
        for i in range(raw.shape[1]):
            if not np.isfinite(raw[b, i]):
                return False
    return True


@kernel(inline="always")
def take_action(raw, ap, action, inputs):
    """Check, clip and map a raw action (6,): False, touching nothing, if any entry is not
    finite; else ``action`` = raw clipped to [low, high] (as np.clip) and ``inputs`` from it."""
    for i in range(6):
        if not np.isfinite(raw[i]):
            return False
    for i in range(6):
        a = raw[i]
        if a < ap[i]:
            a = ap[i]
        elif a > ap[6 + i]:
            a = ap[6 + i]
        action[i] = a
    action_inputs(action, ap, inputs)
    return True


@kernel(inline="always")
def env_step_one(S, W, P, D, inputs, nsub, target, tp, action, obs, terms, result):
    """One control step: ``nsub`` physics steps with constant ``inputs`` (9: pivot force,
    body torque, spatial torque), then observation, reward terms and termination code.
    ``result`` (int64, 5): status, steps taken, Newton iterations (total, max), termination."""
    # the general kernel: an environment always has inputs and, as a rule, an off-centre load
    advance_loop(S, W, P, inputs, nsub, result, P.first == 0, True, True, P.compensated)
    status = result[0]
    diagnostics(S, P, D)
    code = env_observe(S, P, D, target, tp, action, obs, terms)
    result[4] = status if status != OK else code


@kernel
def env_step(s, w, p, d, raw, ap, inputs, nsub, target, tp, action, obs, terms, result):
    """:func:`take_action` of the raw action, then :func:`env_step_one`, for one environment
    (one compiled call per control step). Returns False, with nothing changed, if the raw
    action is not finite.

    ``s, w, p, d`` are the fields of StateArrays, Work, LGVIParams and DiagWork as *plain*
    tuples: numba's dispatcher types a plain tuple about twice as fast as a namedtuple (3 us
    less per call here), and the namedtuples are rebuilt for free in compiled code."""
    if not take_action(raw, ap, action, inputs):
        return False
    env_step_one(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), inputs, nsub, target, tp, action,
                 obs, terms, result)
    return True


@kernel
def env_reset_observe(S, P, D, target, tp, action, obs, terms):
    """Observation of a freshly set state (no step). Returns the termination code."""
    diagnostics(S, P, D)
    return env_observe(S, P, D, target, tp, action, obs, terms)


@kernel(parallel=True)
def env_step_batch(r, p, R, Pi, rc, pc, Rc, Pic, f, acc, accc,
                   fn, X, Y, FmI, RF, Rn, jac, backup, V, strain, omega, dout,
                   P, raw, ap, inputs, active, nsub, target, tp, action, obs, terms, result):
    """:func:`take_action` of ``raw[b]`` and :func:`env_step_one` for every environment b with
    ``active[b]``, in parallel (the raw actions must be finite: :func:`actions_finite`).

    Every array carries a leading batch axis: the state (StateArrays fields), the scratch (Work
    and DiagWork fields), raw (B, 6), inputs (B, 9), target (B, 6), action (B, A), obs, terms,
    result.
    """
    for b in prange(r.shape[0]):
        if active[b] and take_action(raw[b], ap, action[b], inputs[b]):
            S = StateArrays(r[b], p[b], R[b], Pi[b], rc[b], pc[b], Rc[b], Pic[b], f[b], acc[b], accc[b])
            W = Work(fn[b], X[b], Y[b], FmI[b], RF[b], Rn[b], jac[b], backup[b])
            D = DiagWork(V[b], strain[b], omega[b], dout[b])
            env_step_one(S, W, P, D, inputs[b], nsub, target[b], tp, action[b], obs[b], terms[b], result[b])
