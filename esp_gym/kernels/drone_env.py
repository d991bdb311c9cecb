"""The environment's compiled control step with a drone at the pivot (docs/environment.md, "A drone
at the pivot"): the raw action -> the actuation's setpoint -> the physics steps of
kernels/drone.py, the rate controller run before each of them -> the balances closed -> the
tasks' stages (kernels/task_terms.py), then the drone's sensors and its flip -> the energy
watchdog, with the drone's rotation in the energy. The single and the batched environments call
the same :func:`drone_control_step`, so their results agree bit for bit.

Its layouts: the action path's constants (:data:`DRONE_ACTION_PARAMS`) and the sensors, SENSORS
then the drone's (:data:`DRONE_SENSORS`). The action is four numbers in [-1, 1] in every
actuation (:data:`~.drone.ACTUATIONS`); 0 hovers.
"""
import math

import numpy as np
from numba import prange

from .diagnostics import diagnostics
from .disturbance import kick
from .drone import (MOTORS, THRUST_RATES, THRUST_TORQUE, DroneArrays, actuate, drone_diagnostics, drone_substep,
                    max_rotor_thrust, start_wrench, Q_THRUST_COEFFICIENT, QD_RATES)
from .env_arrays import SCHEME_DISTURBED, SENSORS, TP_ENERGY_ORIGIN, TP_STRING_LENGTH, EnvArrays
from .env_step import (close_balances, diag_row, energy_watchdog, env_prepare,
                       env_row, params_row, state_row, work_row)
from .jit import announce_compile, kernel
from .layout import D_ENERGY, R_TERMINATION, DiagWork, Layout, LGVIParams, StateArrays, Work
from .loops import finish
from .rows import row_function
from .status import OK, TERM_DRONE_FLIPPED
from .task_terms import observe_and_score

#: The drone's action path: the actuation's code (:data:`~.drone.ACTUATIONS`), the collective
#: thrust at action 0, the rig's weight [N], and the largest [N]; the body torque [N m] and the
#: body rates [rad/s] at |action| = 1 per axis; cos of the tilt past which the drone has flipped.
DRONE_ACTION_PARAMS = Layout(("actuation", 1), ("hover_thrust", 1), ("max_thrust", 1), ("torque_limit", 3),
                             ("rate_limit", 3), ("flip_cosine", 1))
QA_ACTUATION = DRONE_ACTION_PARAMS.scalar("actuation")
QA_HOVER_THRUST = DRONE_ACTION_PARAMS.scalar("hover_thrust")
QA_MAX_THRUST = DRONE_ACTION_PARAMS.scalar("max_thrust")
QA_TORQUE_LIMIT = DRONE_ACTION_PARAMS.start("torque_limit")
QA_RATE_LIMIT = DRONE_ACTION_PARAMS.start("rate_limit")
QA_FLIP_COSINE = DRONE_ACTION_PARAMS.scalar("flip_cosine")

#: The action's size in every actuation: thrust and three body torques or rates, or four motors.
DRONE_ACTION_SIZE = 4

#: What the step measures with a drone: SENSORS, then the drone's attitude (R_q's first two
#: columns, the body's forward and right axes in the spatial frame) and its body rates [rad/s].
DRONE_SENSORS = Layout(*SENSORS.fields, ("drone_attitude_6d", 6), ("drone_rates", 3))
QS_DRONE_ATTITUDE_6D = DRONE_SENSORS.start("drone_attitude_6d")
QS_DRONE_RATES = DRONE_SENSORS.start("drone_rates")


# A kernel of its own, not inlined: inlined into the batch's prange, numba's parallel transforms
# dropped the stores of its loops (the setpoint's rates stayed 0 in the batch alone).
@kernel
def drone_take_action(raw, qa, action, DR):
    """Check and clip a raw action (4) into ``action`` and set the drone's setpoint from it
    (``qa``: DRONE_ACTION_PARAMS): f = clip(f_hover (1 + a_0), 0, f_max) and the torque
    tau_lim a_1..3 or the rates Omega_lim a_1..3; with ``motors`` each rotor's thrust
    clip(f_hover/4 (1 + a_i), 0, k_f omega_max^2), whose speed is its command. False, touching
    nothing, if an entry is not finite."""
    for i in range(DRONE_ACTION_SIZE):
        if not np.isfinite(raw[i]):
            return False
    for i in range(DRONE_ACTION_SIZE):
        action[i] = min(max(raw[i], -1.0), 1.0)
    mode = int(qa[QA_ACTUATION])
    hover = qa[QA_HOVER_THRUST]
    if mode == MOTORS:
        top = max_rotor_thrust(DR)
        for i in range(4):
            thrust = min(max(0.25 * hover * (1.0 + action[i]), 0.0), top)
            DR.command[i] = math.sqrt(thrust / DR.consts[Q_THRUST_COEFFICIENT])
        return True
    DR.setpoint[0] = min(max(hover * (1.0 + action[0]), 0.0), qa[QA_MAX_THRUST])
    limit = QA_TORQUE_LIMIT if mode == THRUST_TORQUE else QA_RATE_LIMIT
    for i in range(3):
        DR.setpoint[1 + i] = qa[limit + i] * action[1 + i]
    if mode == THRUST_TORQUE:
        actuate(DR, THRUST_TORQUE)
    return True


@kernel
def drone_loop(S, W, P, DR, E, coupled, disturbed):
    """``E.nsub[0]`` steps of :func:`~.drone.drone_substep`, the rate controller before each in
    ``thrust_rates``; the held external forces (``disturbed``) as kicks of h/2 on both sides of
    each step, as kernels/loops.py does. A failed step leaves the state after the last good one
    (its pending half kick taken back). Fills ``E.result``'s first four entries."""
    first = 0 if P.first == 0 else 1
    hh = 0.5 * P.h
    nsub = E.nsub[0]
    rates = int(E.ap[QA_ACTUATION]) == THRUST_RATES
    if disturbed and nsub > 0:
        kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, hh, first)
    start_wrench(DR)
    total = 0
    most = 0
    for k in range(nsub):
        if rates:
            actuate(DR, THRUST_RATES)
        status, iters = drone_substep(S, W, P, DR, E.inputs, P.h, coupled, P.compensated)
        total += iters
        most = max(most, iters)
        if status != OK:
            if disturbed:
                kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, -hh, first)
            finish(E.result, status, k, total, most)
            return
        if disturbed:
            kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, P.h if k + 1 < nsub else hh, first)
    finish(E.result, OK, nsub, total, most)


@kernel(inline="always")
def drone_sensors(DR, sensors):
    """The drone's fields of DRONE_SENSORS: R_q's first two columns and Omega_q = J_q^-1 Pi_q
    (``DR.diag`` filled by :func:`~.drone.drone_diagnostics`)."""
    for i in range(3):
        sensors[QS_DRONE_ATTITUDE_6D + i] = DR.R[i, 0]
        sensors[QS_DRONE_ATTITUDE_6D + 3 + i] = DR.R[i, 1]
        sensors[QS_DRONE_RATES + i] = DR.diag[QD_RATES + i]


@kernel
def drone_observe(S, P, D, DR, E):
    """The diagnostics with the drone's share, the tasks' stages, the drone's sensors; returns the
    task's termination code, or TERM_DRONE_FLIPPED when the drone's b3 is tilted from e3 past
    the limit (R_q[2, 2] below its cosine)."""
    diagnostics(S, P, D)
    drone_diagnostics(DR, D.out)
    code = observe_and_score(S, P, D, E, E.tp[TP_STRING_LENGTH])
    drone_sensors(DR, E.sensors)
    if code == OK and not (DR.R[2, 2] >= E.ap[QA_FLIP_COSINE]):
        return TERM_DRONE_FLIPPED
    return code


@kernel(inline="always")
def drone_control_step(S, W, P, D, DR, E, disturbed):
    """One control step of one environment with a drone (the setpoint already taken from the
    action): wind and pushes, the physics steps, the balances closed, the observation, reward
    terms and termination code (a physics failure's status, else the watchdog's, else the
    task's or the flip)."""
    phi = env_prepare(S, W, P, D, E, disturbed)
    drone_loop(S, W, P, DR, E, P.rho[0] != 0.0 or P.rho[1] != 0.0 or P.rho[2] != 0.0, disturbed)
    status = close_balances(S, W, P, E, phi, disturbed)
    code = drone_observe(S, P, D, DR, E)
    E.result[R_TERMINATION] = status if status != OK else energy_watchdog(S, D, E.tp, code)


@kernel(entry=True)
def drone_reset_observe(S, P, D, DR, E):
    """Observation of a freshly set state with its drone (no step), whose energy, the drone's
    rotation in it, becomes the episode's E0. Returns the termination code."""
    code = drone_observe(S, P, D, DR, E)
    E.tp[TP_ENERGY_ORIGIN] = D.out[D_ENERGY]
    return code


drone_row = row_function(DroneArrays)


def _drone_entry_points():
    """``(step, batch)``: kernels/env_step.py's entry points for an environment with a drone, which
    take the drone's arrays after the environment's: ``step(s, w, p, d, e, q, raw, scheme)`` and
    ``batch(s, w, p, d, e, q, raw, active, scheme)`` (plain tuples of StateArrays, Work,
    LGVIParams, DiagWork, EnvArrays and DroneArrays, as there)."""

    @kernel(entry=True)
    def step(s, w, p, d, e, q, raw, scheme):
        E = EnvArrays(*e)
        DR = DroneArrays(*q)
        if not drone_take_action(raw, E.ap, E.action, DR):
            return False
        drone_control_step(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), DR, E, (scheme & SCHEME_DISTURBED) != 0)
        return True

    @kernel(parallel=True, entry=True)
    def batch(s, w, p, d, e, q, raw, active, scheme):
        disturbed = (scheme & SCHEME_DISTURBED) != 0
        S = StateArrays(*s)
        W = Work(*w)
        D = DiagWork(*d)
        P = LGVIParams(*p)
        E = EnvArrays(*e)
        Q = DroneArrays(*q)
        for b in prange(raw.shape[0]):
            if active[b]:
                Eb = env_row(E, b)
                DRb = drone_row(Q, b)
                if drone_take_action(raw[b], Eb.ap, Eb.action, DRb):
                    drone_control_step(state_row(S, b), work_row(W, b), params_row(P, b), diag_row(D, b), DRb, Eb,
                                       disturbed)

    return (announce_compile(step, "the environment's step with a drone", COLD_DRONE_ENV_STEP_S),
            announce_compile(batch, "the batched environment's step with a drone", COLD_DRONE_BATCH_STEP_S))


#: The seconds to the first step of an environment and of a vector environment with a drone on an
#: empty cache (2 cores; docs/performance.md, "Start-up"; its own kernels on top of the point
#: pivot's), said when their entry points first compile.
COLD_DRONE_ENV_STEP_S = 25
COLD_DRONE_BATCH_STEP_S = 35


#: The drone environment's (step, batch) entry points (compiled when first asked for).
DRONE_ENTRY_POINTS = _drone_entry_points()
