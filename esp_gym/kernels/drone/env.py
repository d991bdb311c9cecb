"""The environment's compiled control step with a drone at the pivot (docs/environment.md, "A drone
at the pivot"): the raw action -> the actuation's setpoint -> the physics steps of
kernels/drone/loops.py, the rate controller run before each of them -> the balances closed -> the
tasks' stages (kernels/env/task_terms.py), then the drone's sensors and its flip -> the energy
watchdog, with the drone's rotation in the energy. The single and the batched environments call
the same :func:`drone_control_step`, so their results agree bit for bit.

Its layouts: the action path's constants (:data:`DRONE_ACTION_PARAMS`), the action with a winch
(:data:`DRONE_WINCH_ACTION`) and the sensors, SENSORS then the drone's (:data:`DRONE_SENSORS`).
The action is four numbers in [-1, 1] in every actuation (:data:`~esp_gym.kernels.drone.quadrotor.ACTUATIONS`), and the
reel speed fifth with a winch; 0 hovers.
"""
import math

import numpy as np
from numba import prange

from ..step.diagnostics import diagnostics
from .quadrotor import (MOTORS, THRUST_RATES, THRUST_TORQUE, DroneArrays, actuate, drone_diagnostics, max_rotor_thrust,
                        Q_THRUST_COEFFICIENT, QD_RATES)
from ..env.arrays import O_UNSTRETCHED_LENGTH, SCHEME_DISTURBED, SENSORS, TP_ENERGY_ORIGIN, TP_STRING_LENGTH, EnvArrays
from .hook import HookArrays, hook_diagnostics
from .loops import drone_steps
from ..env.step import (EntryPoints, close_balances, diag_row, energy_watchdog, env_prepare,
                        env_row, params_row, state_row, winch_row, work_row)
from ..jit import announce_compile, kernel
from ..layout import (D_ENERGY, R_TERMINATION, WN_LENGTH, WN_MASS_PER_LENGTH, WN_REEL_SPEED, DiagWork, Layout,
                      LGVIParams, StateArrays, WinchArrays, Work)
from ..env.task_terms import observe_and_score
from ..rows import row_function
from ..status import OK, TERM_DRONE_FLIPPED
from ..step.winch import length_params, winch_energy

#: The drone's action path: the actuation's code (:data:`~esp_gym.kernels.drone.quadrotor.ACTUATIONS`), the collective
#: thrust at action 0, the rig's weight [N], and the largest [N]; the body torque [N m] and the
#: body rates [rad/s] at |action| = 1 per axis; cos of the tilt past which the drone has flipped;
#: the winch's largest reel speed [m/s].
DRONE_ACTION_PARAMS = Layout(("actuation", 1), ("hover_thrust", 1), ("max_thrust", 1), ("torque_limit", 3),
                             ("rate_limit", 3), ("flip_cosine", 1), ("max_reel_speed", 1))
QA_ACTUATION = DRONE_ACTION_PARAMS.scalar("actuation")
QA_HOVER_THRUST = DRONE_ACTION_PARAMS.scalar("hover_thrust")
QA_MAX_THRUST = DRONE_ACTION_PARAMS.scalar("max_thrust")
QA_TORQUE_LIMIT = DRONE_ACTION_PARAMS.start("torque_limit")
QA_RATE_LIMIT = DRONE_ACTION_PARAMS.start("rate_limit")
QA_FLIP_COSINE = DRONE_ACTION_PARAMS.scalar("flip_cosine")
QA_MAX_REEL_SPEED = DRONE_ACTION_PARAMS.scalar("max_reel_speed")

#: The action's size in every actuation: thrust and three body torques or rates, or four motors;
#: with a winch, the reel speed after them (x the winch's largest [m/s]; > 0 reels out).
DRONE_ACTION_SIZE = 4
DRONE_WINCH_ACTION = Layout(("drone", DRONE_ACTION_SIZE), ("reel_speed", 1))
DRONE_WINCH_ACTION_SIZE = DRONE_WINCH_ACTION.size

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
    clip(f_hover/4 (1 + a_i), 0, k_f omega_max^2), whose speed is its command. Returns the reel
    speed [m/s] (with a winch: ``action``'s fifth entry; else 0), or -inf, touching nothing, if an
    entry is not finite."""
    size = action.shape[0]
    for i in range(size):
        if not np.isfinite(raw[i]):
            return -np.inf
    for i in range(size):
        action[i] = min(max(raw[i], -1.0), 1.0)
    reel = 0.0 if size == DRONE_ACTION_SIZE else qa[QA_MAX_REEL_SPEED] * action[DRONE_ACTION_SIZE]
    mode = int(qa[QA_ACTUATION])
    hover = qa[QA_HOVER_THRUST]
    if mode == MOTORS:
        top = max_rotor_thrust(DR)
        for i in range(4):
            thrust = min(max(0.25 * hover * (1.0 + action[i]), 0.0), top)
            DR.command[i] = math.sqrt(thrust / DR.consts[Q_THRUST_COEFFICIENT])
        return reel
    DR.setpoint[0] = min(max(hover * (1.0 + action[0]), 0.0), qa[QA_MAX_THRUST])
    limit = QA_TORQUE_LIMIT if mode == THRUST_TORQUE else QA_RATE_LIMIT
    for i in range(3):
        DR.setpoint[1 + i] = qa[limit + i] * action[1 + i]
    if mode == THRUST_TORQUE:
        actuate(DR, THRUST_TORQUE)
    return reel


@kernel(inline="always")
def drone_sensors(DR, sensors):
    """The drone's fields of DRONE_SENSORS: R_q's first two columns and Omega_q (``DR.diag``
    filled by :func:`~esp_gym.kernels.drone.quadrotor.drone_diagnostics`, J_q^-1 Pi_q, or at an offset hook by
    :func:`~esp_gym.kernels.drone.hook.hook_diagnostics`)."""
    for i in range(3):
        sensors[QS_DRONE_ATTITUDE_6D + i] = DR.R[i, 0]
        sensors[QS_DRONE_ATTITUDE_6D + 3 + i] = DR.R[i, 1]
        sensors[QS_DRONE_RATES + i] = DR.diag[QD_RATES + i]


@kernel
def drone_observe(S, P, D, WA, DR, HK, E):
    """The diagnostics with the drone's share (with the winch ``WA``: at its length and reel speed,
    the energy the Hamiltonian, as kernels/env/step.py's ``env_finish_winched``; at the offset hook
    ``HK``: with the Legendre transform at both ends, kernels/drone/hook.py; each None where the
    rig has none), the tasks' stages, the drone's sensors; returns the task's termination code,
    or TERM_DRONE_FLIPPED when the drone's b3 is tilted from e3 past the limit (R_q[2, 2] below
    its cosine)."""
    if WA is not None:
        length = WA.state[WN_LENGTH]
        winch_energy(S, P, WA, D, length, WA.state[WN_REEL_SPEED])
        drone_diagnostics(DR, D.out)
        n = S.r.shape[0] - 1
        Pl = length_params(P, WA, length, WA.state[WN_MASS_PER_LENGTH] * length / n, 0 if P.first == 0 else 1, n,
                           False)
        code = observe_and_score(S, Pl, D, E, length)
        E.obs[O_UNSTRETCHED_LENGTH] = length
    else:
        if HK is not None:
            hook_diagnostics(S, P, D, DR, HK)
        else:
            diagnostics(S, P, D)
            drone_diagnostics(DR, D.out)
        code = observe_and_score(S, P, D, E, E.tp[TP_STRING_LENGTH])
    drone_sensors(DR, E.sensors)
    if code == OK and not (DR.R[2, 2] >= E.ap[QA_FLIP_COSINE]):
        return TERM_DRONE_FLIPPED
    return code


@kernel(inline="always")
def drone_control_step(S, W, P, D, WA, DR, HK, E, reel, disturbed, damped):
    """One control step of one environment with a drone (the setpoint already taken from the
    action; ``reel`` the reel speed [m/s] with the winch ``WA``; ``WA``, ``HK`` None where the rig
    has no winch, no offset hook): wind and pushes, the physics steps, the balances closed, the
    observation, reward terms and termination code (a physics failure's status, else the
    watchdog's, else the task's or the flip). ``damped``: None, or True with the string's damper
    (kernels/drone/loops.py)."""
    phi = env_prepare(S, W, P, D, E, disturbed)
    coupled = P.rho[0] != 0.0 or P.rho[1] != 0.0 or P.rho[2] != 0.0
    drone_steps(S, W, P, WA, D, DR, HK, E.inputs, E.nsub[0], E.result, reel, coupled, disturbed,
                int(E.ap[QA_ACTUATION]) == THRUST_RATES, damped)
    status = close_balances(S, W, P, E, phi, disturbed)
    code = drone_observe(S, P, D, WA, DR, HK, E)
    E.result[R_TERMINATION] = status if status != OK else energy_watchdog(S, D, E.tp, code)


@kernel(entry=True)
def drone_reset_observe(S, P, D, WA, DR, HK, E):
    """Observation of a freshly set state with its drone (no step; a winch ``WA`` at the scene's
    length and at rest; ``WA``, ``HK`` None where the rig has none), whose energy, the drone's
    rotation in it, becomes the episode's E0. Returns the termination code."""
    code = drone_observe(S, P, D, WA, DR, HK, E)
    E.tp[TP_ENERGY_ORIGIN] = D.out[D_ENERGY]
    return code


drone_row = row_function(DroneArrays)
hook_row = row_function(HookArrays)


#: The seconds to the first step of an environment and of a vector environment with a drone on an
#: empty cache (2 cores; docs/performance.md, "Start-up"; its own kernels on top of the point
#: pivot's), said when their entry points first compile.
COLD_DRONE_ENV_STEP_S = 37
COLD_DRONE_BATCH_STEP_S = 47

@kernel(inline="always")
def drone_env_step(S, W, P, D, WA, E, DR, HK, raw, scheme, damped):
    """:func:`drone_take_action` of the raw action, then :func:`drone_control_step`, for one
    environment (``WA``: its winch's arrays, ``HK``: the hook's, each None where the rig has
    none; ``damped`` None, or True with the string's damper). Returns False, with nothing changed,
    if the raw action is not finite."""
    reel = drone_take_action(raw, E.ap, E.action, DR)
    if reel == -np.inf:
        return False
    drone_control_step(S, W, P, D, WA, DR, HK, E, reel, (scheme & SCHEME_DISTURBED) != 0, damped)
    return True


# A batch loop per rig, not one with the rig's flags: numba inlined drone_env_step into every
# branch before pruning the two dead ones, and the batch entry compiled 4.5 s against 2.7 s.
@kernel(inline="always")
def drone_env_batch(S, W, P, D, E, Q, raw, active, scheme, damped):
    """:func:`drone_env_step` for every environment b with ``active[b]`` (each struct's row b by
    its row function; the raw actions must be finite; ``damped`` as there). A ``prange``: on numba's
    threads in an entry compiled with ``parallel=True``, a plain loop in one without."""
    for b in prange(raw.shape[0]):
        if active[b]:
            drone_env_step(state_row(S, b), work_row(W, b), params_row(P, b), diag_row(D, b), None, env_row(E, b),
                           drone_row(Q, b), None, raw[b], scheme, damped)


@kernel(inline="always")
def drone_winch_env_batch(S, W, P, D, WA, E, Q, raw, active, scheme):
    """:func:`drone_env_batch` with a winch."""
    for b in prange(raw.shape[0]):
        if active[b]:
            drone_env_step(state_row(S, b), work_row(W, b), params_row(P, b), diag_row(D, b), winch_row(WA, b),
                           env_row(E, b), drone_row(Q, b), None, raw[b], scheme, None)


@kernel(inline="always")
def hook_env_batch(S, W, P, D, E, Q, K, raw, active, scheme):
    """:func:`drone_env_batch` at an offset hook."""
    for b in prange(raw.shape[0]):
        if active[b]:
            drone_env_step(state_row(S, b), work_row(W, b), params_row(P, b), diag_row(D, b), None, env_row(E, b),
                           drone_row(Q, b), hook_row(K, b), raw[b], scheme, None)


# The entry points: kernels/env/step.py's, with the drone's arrays ``q`` (DroneArrays) after the
# environment's ``e``, all plain tuples as there; with a winch its arrays ``wa`` come after ``d``
# (without one they are not passed: a tuple more costs every call the dispatcher's typing of it).
@kernel(entry=True)
def drone_step(s, w, p, d, e, q, raw, scheme):
    return drone_env_step(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), None, EnvArrays(*e),
                          DroneArrays(*q), None, raw, scheme, None)


@kernel(entry=True)
def damped_drone_step(s, w, p, d, e, q, raw, scheme):
    return drone_env_step(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), None, EnvArrays(*e),
                          DroneArrays(*q), None, raw, scheme, True)


@kernel(entry=True)
def drone_winch_env_step(s, w, p, d, wa, e, q, raw, scheme):
    return drone_env_step(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), WinchArrays(*wa), EnvArrays(*e),
                          DroneArrays(*q), None, raw, scheme, None)


@kernel(entry=True)
def hook_env_step(s, w, p, d, e, q, k, raw, scheme):
    return drone_env_step(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), None, EnvArrays(*e),
                          DroneArrays(*q), HookArrays(*k), raw, scheme, None)


# The batches in one thread, and on numba's threads (``threads`` > 1: docs/performance.md,
# "Threads"): other functions, not one with two options, as numba's cache keys a function by its
# code, not its options.
@kernel(entry=True)
def drone_batch(s, w, p, d, e, q, raw, active, scheme):
    drone_env_batch(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), EnvArrays(*e), DroneArrays(*q), raw, active,
                    scheme, None)


@kernel(entry=True)
def damped_drone_batch(s, w, p, d, e, q, raw, active, scheme):
    drone_env_batch(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), EnvArrays(*e), DroneArrays(*q), raw, active,
                    scheme, True)


@kernel(entry=True)
def drone_winch_batch(s, w, p, d, wa, e, q, raw, active, scheme):
    drone_winch_env_batch(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), WinchArrays(*wa), EnvArrays(*e),
                          DroneArrays(*q), raw, active, scheme)


@kernel(entry=True)
def hook_batch(s, w, p, d, e, q, k, raw, active, scheme):
    hook_env_batch(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), EnvArrays(*e), DroneArrays(*q),
                   HookArrays(*k), raw, active, scheme)


@kernel(parallel=True, entry=True)
def threaded_drone_batch(s, w, p, d, e, q, raw, active, scheme):
    drone_env_batch(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), EnvArrays(*e), DroneArrays(*q), raw, active,
                    scheme, None)


@kernel(parallel=True, entry=True)
def threaded_damped_drone_batch(s, w, p, d, e, q, raw, active, scheme):
    drone_env_batch(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), EnvArrays(*e), DroneArrays(*q), raw, active,
                    scheme, True)


@kernel(parallel=True, entry=True)
def threaded_drone_winch_batch(s, w, p, d, wa, e, q, raw, active, scheme):
    drone_winch_env_batch(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), WinchArrays(*wa), EnvArrays(*e),
                          DroneArrays(*q), raw, active, scheme)


@kernel(parallel=True, entry=True)
def threaded_hook_batch(s, w, p, d, e, q, k, raw, active, scheme):
    hook_env_batch(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), EnvArrays(*e), DroneArrays(*q),
                   HookArrays(*k), raw, active, scheme)


def _entries(step, batch, threaded_batch, what):
    """:class:`~esp_gym.kernels.env.step.EntryPoints`, each announced when it first compiles (``what``: the rig)."""
    return EntryPoints(announce_compile(step, "the environment's step with " + what, COLD_DRONE_ENV_STEP_S),
                       announce_compile(batch, "the batched environment's step with " + what, COLD_DRONE_BATCH_STEP_S),
                       announce_compile(threaded_batch, "the threaded batched environment's step with " + what,
                                        COLD_DRONE_BATCH_STEP_S))


# The drone's entry points ``(step, batch, threaded_batch)``, each named after its rig
# (esp_gym/physics/rig.py: a rig's name with "_" for "-") and compiled when first asked for; their
# arguments are kernels/env/step.py's with the drone's ``q`` after ``e`` (and at an offset hook the
# hook's ``k`` after it).
drone_explicit = _entries(drone_step, drone_batch, threaded_drone_batch, "a drone")
drone_explicit_winch = _entries(drone_winch_env_step, drone_winch_batch, threaded_drone_winch_batch,
                                "a drone and the winch")
drone_explicit_offset_hook = _entries(hook_env_step, hook_batch, threaded_hook_batch, "a drone at an offset hook")
drone_explicit_damped = _entries(damped_drone_step, damped_drone_batch, threaded_damped_drone_batch,
                                 "a drone and the string's damper")
