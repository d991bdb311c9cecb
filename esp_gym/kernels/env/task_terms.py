"""What the environment's tasks make of the state after each control step and each reset
(docs/environment.md): the features, computed once, then the observation and sensors, the
reward terms and the termination code, each a stage of its own. kernels/env/step.py calls
:func:`observe_and_score` after the physics; every vector is laid out by name
(kernels/env/arrays.py: OBSERVATION, SENSORS, REWARD, TASK_PARAMS, TARGET,
FEATURES).
"""
import math

from ..jit import kernel
from ..layout import D_STRETCHED_LENGTH
from .arrays import F_LOAD_POSITION, F_LOAD_VELOCITY, F_SPIN, F_SWING
from .arrays import (O_ANGULAR_VELOCITY, O_ATTITUDE_6D, O_LOAD_POSITION_ERROR, O_LOAD_VELOCITY,
                     O_PIVOT_POSITION_ERROR, O_PIVOT_VELOCITY, O_STRING_STRETCH, RW_CONTROL, RW_LOAD_POSITION,
                     RW_LOAD_VELOCITY, RW_PIVOT_POSITION, RW_SPIN, RW_SWING, SN_HOOK_TENSION, SN_LOAD_TARGET_OFFSET,
                     T_LOAD, T_PIVOT, T_VELOCITY, TP_MAX_STRETCHED_LENGTH, TP_SCALE_POSITION, TP_SCALE_SPIN,
                     TP_SCALE_SWING, TP_SCALE_VELOCITY, TP_STRING_LENGTH, TP_W_CONTROL, TP_W_LOAD_POSITION,
                     TP_W_LOAD_VELOCITY, TP_W_PIVOT_POSITION, TP_W_SPIN, TP_W_SWING, TP_WORKSPACE_RADIUS,
                     TP_GROUND_DEPTH)
from ..status import TERM_GROUND, TERM_NONE, TERM_OVERSTRETCH, TERM_WORKSPACE
from ..tolerance import tolerance


@kernel(inline="always")
def env_sensors(S, P, target, sensors):
    """SENSORS of the current state: the first element's force on the pivot, c x_0 with c =
    kappa (1 - u/|x_0|) (0 where a slack string is compressed; kernels/step/string.py
    ``nodal_forces``) [N], and the load target - pivot position [m]."""
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


@kernel(inline="always")
def task_features(S, P, D, features):
    """FEATURES of the current state (``D`` filled by diagnostics): the load's centre of mass
    r_N + R rho_c [m] and its velocity v_N + R (Omega x rho_c) [m/s], the swing angle of
    (load centre - pivot) from the downward vertical e3 [rad], the spin |Omega| [rad/s]."""
    r = S.r
    R = S.R
    n = r.shape[0] - 1
    rho = P.rho
    V = D.V
    w = D.omega
    x0 = w[1] * rho[2] - w[2] * rho[1]  # Omega x rho_c
    x1 = w[2] * rho[0] - w[0] * rho[2]
    x2 = w[0] * rho[1] - w[1] * rho[0]
    for i in range(3):
        features[F_LOAD_POSITION + i] = r[n, i] + (R[i, 0] * rho[0] + R[i, 1] * rho[1] + R[i, 2] * rho[2])
        features[F_LOAD_VELOCITY + i] = V[n, i] + (R[i, 0] * x0 + R[i, 1] * x1 + R[i, 2] * x2)
    dx = (r[n, 0] - r[0, 0]) + (R[0, 0] * rho[0] + R[0, 1] * rho[1] + R[0, 2] * rho[2])  # load - pivot
    dy = (r[n, 1] - r[0, 1]) + (R[1, 0] * rho[0] + R[1, 1] * rho[1] + R[1, 2] * rho[2])
    dz = (r[n, 2] - r[0, 2]) + (R[2, 0] * rho[0] + R[2, 1] * rho[1] + R[2, 2] * rho[2])
    features[F_SWING] = math.atan2(math.sqrt(dx * dx + dy * dy), dz)
    features[F_SPIN] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])


@kernel(inline="always")
def observe(S, D, E, length):
    """OBSERVATION ``E.obs``: the pivot's and the load's position errors and velocities against
    the targets (``track``'s moving reference) [m, m/s], the load's attitude (R's first two
    columns) and body angular velocity [rad/s], and the string's stretch at the unstretched
    ``length`` [m] (``D`` filled by diagnostics, ``E.features`` by :func:`task_features`)."""
    r = S.r
    R = S.R
    V = D.V
    w = D.omega
    target = E.target
    features = E.features
    obs = E.obs
    for i in range(3):
        obs[O_PIVOT_POSITION_ERROR + i] = r[0, i] - target[T_PIVOT + i]
        obs[O_PIVOT_VELOCITY + i] = V[0, i] - target[T_VELOCITY + i]
        obs[O_LOAD_POSITION_ERROR + i] = features[F_LOAD_POSITION + i] - target[T_LOAD + i]
        obs[O_LOAD_VELOCITY + i] = features[F_LOAD_VELOCITY + i] - target[T_VELOCITY + i]  # x - 0.0 == x
        obs[O_ATTITUDE_6D + i] = R[i, 0]
        obs[O_ATTITUDE_6D + 3 + i] = R[i, 1]
        obs[O_ANGULAR_VELOCITY + i] = w[i]
    obs[O_STRING_STRETCH] = D.out[D_STRETCHED_LENGTH] / length - 1.0


@kernel(inline="always")
def squared_norm(v, start):
    """|v[start:start + 3]|^2, summed in index order."""
    s = 0.0
    for i in range(3):
        s += v[start + i] * v[start + i]
    return s


@kernel(inline="always")
def reward_terms(E, pivot2, load2):
    """REWARD ``E.terms``: each weight of TASK_PARAMS times :func:`~.tolerance.tolerance` of its
    error at its scale (the load's and the pivot's distances to their targets, from their squares
    ``load2``, ``pivot2`` [m^2], the load's speed against the reference, the swing, the spin),
    and the control cost, minus the weight times the applied action's mean square
    (docs/environment.md, "Reward")."""
    tp = E.tp
    obs = E.obs
    action = E.action
    terms = E.terms
    a2 = 0.0
    for i in range(action.shape[0]):
        a2 += action[i] * action[i]
    terms[RW_LOAD_POSITION] = tp[TP_W_LOAD_POSITION] * tolerance(math.sqrt(load2), tp[TP_SCALE_POSITION])
    terms[RW_LOAD_VELOCITY] = tp[TP_W_LOAD_VELOCITY] * tolerance(math.sqrt(squared_norm(obs, O_LOAD_VELOCITY)),
                                                                 tp[TP_SCALE_VELOCITY])
    terms[RW_PIVOT_POSITION] = tp[TP_W_PIVOT_POSITION] * tolerance(math.sqrt(pivot2), tp[TP_SCALE_POSITION])
    terms[RW_SWING] = tp[TP_W_SWING] * tolerance(E.features[F_SWING], tp[TP_SCALE_SWING])
    terms[RW_SPIN] = tp[TP_W_SPIN] * tolerance(E.features[F_SPIN], tp[TP_SCALE_SPIN])
    terms[RW_CONTROL] = -tp[TP_W_CONTROL] * a2 / action.shape[0]


@kernel(inline="always")
def terminate(D, E, length, pivot2, load2, pivot_depth, load_depth):
    """The task's termination code (TERM_*): the string stretched past its limit (scaled to
    the unstretched ``length`` [m]), the pivot or the load outside the workspace's radius
    (their squared distances to their targets ``pivot2``, ``load2`` [m^2]), or the pivot or the
    load's centre of mass (their z ``pivot_depth``, ``load_depth`` [m], e3 down) at or under the
    ground plane's depth."""
    tp = E.tp
    if not (D.out[D_STRETCHED_LENGTH] <= tp[TP_MAX_STRETCHED_LENGTH] * (length / tp[TP_STRING_LENGTH])):
        return TERM_OVERSTRETCH
    r2 = tp[TP_WORKSPACE_RADIUS] * tp[TP_WORKSPACE_RADIUS]
    if not (pivot2 <= r2 and load2 <= r2):
        return TERM_WORKSPACE
    if not (pivot_depth < tp[TP_GROUND_DEPTH] and load_depth < tp[TP_GROUND_DEPTH]):
        return TERM_GROUND
    return TERM_NONE


@kernel
def observe_and_score(S, P, D, E, length):
    """The stages in order: sensors, features, observation, reward terms; returns the
    termination code. ``D`` filled by diagnostics, ``length`` the unstretched length [m] (the
    scene's; a winch's current one, whose constants ``P`` then holds). The distances the reward
    and the termination both read are squared once, from the observation."""
    env_sensors(S, P, E.target, E.sensors)
    task_features(S, P, D, E.features)
    observe(S, D, E, length)
    pivot2 = squared_norm(E.obs, O_PIVOT_POSITION_ERROR)
    load2 = squared_norm(E.obs, O_LOAD_POSITION_ERROR)
    reward_terms(E, pivot2, load2)
    return terminate(D, E, length, pivot2, load2, S.r[0, 2], E.features[F_LOAD_POSITION + 2])
