"""A drone at the pivot (docs/physics.md, "A drone at the pivot"): its arrays (:class:`DroneArrays`,
the constants :data:`DRONE`, the diagnostics :data:`DRONE_DIAG`), its step and its diagnostics.

With the hook at the centre of mass the string exerts no torque on the drone, and its rotation
is a free rigid body under the rotors' torque, stepped by the LGVI's own stages (the Cayley
Newton of kernels/so3.py, the attitude and momentum updates of kernels/step/step_shared.py). Its
translation is the free pivot's (node 0, of mass M_p = the drone's), pushed by the thrust
-f R_q e3 taken at each end of the step. A step (:func:`drone_substep`): the rotors' lag over
the step (kernels/drone/rotors.py), their wrench at both ends, the rotation's solve, the string's
step with the thrust pair, then the rotation's commit; a failure anywhere leaves all of it
untouched. While a winch reels, the string's step is the winch's (:func:`drone_winch_step`).
The actuations (:data:`ACTUATIONS`) turn the environment's setpoint into motor commands
(:func:`actuate`).
"""
from collections import namedtuple

import math

from ..jit import kernel
from ..layout import B_ANGULAR_IMPULSE_Z, B_WORK, D_ENERGY, D_PI3, D_POTENTIAL_GRAVITY, IN_PIVOT_FORCE, IN_PIVOT_FORCE_END, Layout
from ..so3 import cayley_minus_identity, cayley_newton
from ..status import NEWTON_FAILED, OK
from ..step.lgvi import lgvi_substep
from ..step.step import winch_step
from ..step.step_shared import commit_rotation, free_body_increment, next_attitude, torque_work
from ..sums import kahan_add
from .rotors import motor_lag, rate_command, rotor_wrench, wrench_command

#: The drone's constants: k_f [N s^2/rad^2], the motor lag's decays over a step e^(-h/t_up) and
#: e^(-h/t_down) (0 for no lag), the largest rotor speed [rad/s], the rate controller's gain
#: K_Omega (3) [1/s] and the physics steps per rate-loop period (1: every step).
DRONE = Layout(("thrust_coefficient", 1), ("decay_up", 1), ("decay_down", 1), ("max_rotor_speed", 1),
               ("rate_gain", 3), ("rate_loop_steps", 1))
Q_THRUST_COEFFICIENT = DRONE.scalar("thrust_coefficient")
Q_DECAY_UP = DRONE.scalar("decay_up")
Q_DECAY_DOWN = DRONE.scalar("decay_down")
Q_MAX_ROTOR_SPEED = DRONE.scalar("max_rotor_speed")
Q_RATE_GAIN = DRONE.start("rate_gain")
Q_RATE_LOOP_STEPS = DRONE.scalar("rate_loop_steps")

#: The drone's diagnostics (:func:`drone_diagnostics`): its rotational kinetic energy [J], its
#: angular momentum about e3, e3 . R_q Pi_q [kg m^2/s], ||I - R_q^T R_q||_F, its body rates
#: Omega_q (3) [rad/s], and the rotors' collective thrust [N] and body torque (3) [N m].
DRONE_DIAG = Layout(("kinetic", 1), ("pi3", 1), ("orthogonality", 1), ("rates", 3), ("thrust", 1), ("torque", 3))
QD_KINETIC = DRONE_DIAG.scalar("kinetic")
QD_PI3 = DRONE_DIAG.scalar("pi3")
QD_ORTHOGONALITY = DRONE_DIAG.scalar("orthogonality")
QD_RATES = DRONE_DIAG.start("rates")
QD_THRUST = DRONE_DIAG.scalar("thrust")
QD_TORQUE = DRONE_DIAG.start("torque")

#: A drone's arrays: attitude ``R`` (3, 3) and body angular momentum ``Pi`` (3,) [kg m^2/s]
#: (conjugate to R_q with the hook as the drone's point: docs/physics.md) with their
#: compensated-summation remainders ``Rc``, ``Pic``; the rotor speeds ``speed`` (4,)
#: [rad/s] (state) and the motor commands ``command`` (4,) [rad/s], held over a step; the
#: actuation's ``setpoint`` (4,): the collective thrust [N], then the body torque [N m] or
#: the body rates [rad/s] (:func:`actuate`); each rotor's thrust scale ``thrust_scale`` (4,) (1:
#: nominal; the environment's thrust noise, held over a control step); the constants ``consts``
#: (:data:`DRONE`), ``inertia`` J_q about the centre of mass and its inverse ``inertia_inv`` (3, 3)
#: [kg m^2], the mixer ``mixer`` A and ``allocation`` A^-1 (4, 4) (esp_gym/scene/rotors.py); scratch: ``next_speed`` (4,), ``wrench`` (2, 4), the wrench (f, tau) at the step's start and
#: end, ``scratch`` (4, 3, 3), Newton's Jacobian, F - I, R_k (F - I) and R_{k+1}; and ``diag``
#: (:data:`DRONE_DIAG`).
DroneArrays = namedtuple("DroneArrays", "R Rc Pi Pic speed command setpoint thrust_scale consts inertia inertia_inv "
                                        "mixer allocation next_speed wrench scratch diag")

#: How the environment's action drives the rotors (docs/environment.md, "Drone actuation"): its
#: code is the index. ``thrust_torque``: the setpoint's wrench through A^-1; ``thrust_rates``:
#: the rate controller at every physics step; ``motors``: the motor commands themselves.
ACTUATIONS = ("thrust_torque", "thrust_rates", "motors")
THRUST_TORQUE, THRUST_RATES, MOTORS = range(3)


@kernel(forceinline=True)
def attitude_solve(R, Rc, Pi, inertia, h, torques, scratch, solver, compensated):
    """The rotation's half of a step, nothing committed: Newton on (F K - K F^T)^vee = h Pi_k +
    h^2/2 tau^- (K = J_d, so J_eff = ``inertia`` J_q (3, 3) [kg m^2]) for F = cay(c), then
    ``scratch`` = (jac, F - I, R_k (F - I) (+ Rc when ``compensated``), R_{k+1}) and dPi of (4)
    in increment form. ``torques`` = (tau^-, tau^+), the left and right body torques (3 each,
    body frame [N m]); ``solver`` = (Newton's relative tolerance, its iteration cap). Returns
    ``(status, iterations, dPi, c)``."""
    left, right = torques
    jac, FmI, RF, Rn = scratch
    tol, max_iter = solver
    hh = 0.5 * h
    c0, c1, c2, iterations, converged = cayley_newton(h * (Pi[0] + hh * left[0]), h * (Pi[1] + hh * left[1]),
                                                      h * (Pi[2] + hh * left[2]), inertia, tol, max_iter, jac)
    if not converged:
        return NEWTON_FAILED, iterations, (0.0, 0.0, 0.0), (c0, c1, c2)
    cayley_minus_identity(c0, c1, c2, FmI)
    next_attitude(R, Rc, FmI, RF, Rn, compensated)
    dP = free_body_increment(Pi, FmI, h, left, right, True)
    return OK, iterations, dP, (c0, c1, c2)


@kernel(forceinline=True)
def attitude_step(body, inertia, h, torques, scratch, solver, compensated):
    """One step of length ``h`` [s] of the drone's rotation alone: ``body`` = (R_q (3, 3), its
    remainder Rc, Pi_q (3) [kg m^2/s], its remainder Pic), updated in place by
    :func:`attitude_solve` and the commit, compensated or plain. Returns ``(status,
    newton_iterations)``; a failed Newton leaves the body untouched."""
    R, Rc, Pi, Pic = body
    status, iterations, dP, _ = attitude_solve(R, Rc, Pi, inertia, h, torques, scratch, solver, compensated)
    if status == OK:
        _, _, RF, Rn = scratch
        commit_rotation(R, Rc, Pi, Pic, Rn, RF, dP, compensated)
    return status, iterations


@kernel(inline="always")
def start_wrench(DR):
    """``DR.wrench[0]`` = (f, tau) at the state's rotor speeds: at the start of a run of steps,
    each of which then carries its end's wrench over to the next (:func:`drone_substep`)."""
    rotor_wrench(DR.speed, DR.consts[Q_THRUST_COEFFICIENT], DR.thrust_scale, DR.mixer, DR.wrench[0])


@kernel(inline="always")
def rotor_ends(DR):
    """The rotors over a step (``DR.wrench[0]`` holding the wrench at the state's speeds):
    ``DR.next_speed`` = the speeds one step later under the held commands (the exact lag) and
    ``DR.wrench[1]`` at those."""
    consts = DR.consts
    for i in range(4):
        DR.next_speed[i] = motor_lag(DR.speed[i], DR.command[i], consts[Q_DECAY_UP], consts[Q_DECAY_DOWN])
    rotor_wrench(DR.next_speed, consts[Q_THRUST_COEFFICIENT], DR.thrust_scale, DR.mixer, DR.wrench[1])


@kernel(inline="always")
def max_rotor_thrust(DR):
    """A rotor's largest thrust, k_f omega_max^2 [N]."""
    top = DR.consts[Q_MAX_ROTOR_SPEED]
    return DR.consts[Q_THRUST_COEFFICIENT] * top * top


@kernel(inline="always")
def actuate(DR, mode):
    """``DR.command`` from ``DR.setpoint`` for the actuation ``mode`` (:data:`ACTUATIONS`): the
    wrench's commands (THRUST_TORQUE), the rate controller's at the state's rates Omega_q =
    J_q^-1 Pi_q (THRUST_RATES; kernels/drone/rotors.py); MOTORS leaves the commands as set."""
    sp = DR.setpoint
    kf = DR.consts[Q_THRUST_COEFFICIENT]
    if mode == THRUST_TORQUE:
        wrench_command(sp[0], (sp[1], sp[2], sp[3]), DR.allocation, max_rotor_thrust(DR), kf, DR.command)
    elif mode == THRUST_RATES:
        Ji = DR.inertia_inv
        Pi = DR.Pi
        rate_actuate(DR, (Ji[0, 0] * Pi[0] + Ji[0, 1] * Pi[1] + Ji[0, 2] * Pi[2],
                          Ji[1, 0] * Pi[0] + Ji[1, 1] * Pi[1] + Ji[1, 2] * Pi[2],
                          Ji[2, 0] * Pi[0] + Ji[2, 1] * Pi[1] + Ji[2, 2] * Pi[2]))


@kernel(inline="always")
def rate_loop_due(DR, k):
    """Whether the rate controller samples before step ``k`` of a control step: every
    ``rate_loop_steps`` steps from the control step's start (the period divides the control period)."""
    return k % int(DR.consts[Q_RATE_LOOP_STEPS]) == 0


@kernel(inline="always")
def rate_actuate(DR, rates):
    """``DR.command`` from the rate controller (kernels/drone/rotors.py) at the body ``rates`` Omega_q
    [rad/s]: J_q^-1 Pi_q at the default hook (:func:`actuate`), the Legendre transform's at an
    offset one (kernels/drone/hook.py)."""
    sp = DR.setpoint
    rate_command(rates, (sp[1], sp[2], sp[3]), sp[0], DR.inertia, DR.consts[Q_RATE_GAIN:Q_RATE_GAIN + 3],
                 DR.allocation, max_rotor_thrust(DR), DR.consts[Q_THRUST_COEFFICIENT], DR.command)


@kernel(inline="always")
def drone_balances(S, R, Rn, h, c, left, right):
    """The rotors' torque in the balances (``S.acc``): its work tau_avg . theta on the drone's
    rotation (Cayley vector ``c``) and its angular impulse about e3,
    e3 . h/2 (R_k tau^- + R_{k+1} tau^+) [J, kg m^2/s]; the thrust's are the pivot force's."""
    kahan_add(S.acc, S.accc, B_WORK, torque_work(c, left, right))
    hh = 0.5 * h
    ang = hh * ((R[2, 0] * left[0] + R[2, 1] * left[1] + R[2, 2] * left[2])
                + (Rn[2, 0] * right[0] + Rn[2, 1] * right[1] + Rn[2, 2] * right[2]))
    kahan_add(S.acc, S.accc, B_ANGULAR_IMPULSE_Z, ang)


@kernel(inline="always")
def drone_solve(DR, P, h, compensated, thrust):
    """The drone's half of a step before the string's: the rotors over the step, the rotation
    solved (not committed), and the thrust pair u_k = -f_k R_{q,k} e3, u_{k+1} = -f_{k+1}
    R_{q,k+1} e3 into ``thrust`` (2, 3) (spatial) [N]. Returns ``(status, iterations, dPi, c)``."""
    rotor_ends(DR)
    wl = DR.wrench[0]
    wr = DR.wrench[1]
    R = DR.R
    status, iters, dP, c = attitude_solve(R, DR.Rc, DR.Pi, DR.inertia, h, ((wl[1], wl[2], wl[3]),
                                                                            (wr[1], wr[2], wr[3])),
                                          DR.scratch, (P.tol, P.max_iter), compensated)
    if status == OK:
        Rn = DR.scratch[3]
        for i in range(3):  # the thrust along -b3 at either end
            thrust[0, i] = -wl[0] * R[i, 2]
            thrust[1, i] = -wr[0] * Rn[i, 2]
    return status, iters, dP, c


# drone_start views the pivot force pair as one (2, 3) block of INPUTS
assert IN_PIVOT_FORCE_END == IN_PIVOT_FORCE + 3


@kernel(inline="always")
def drone_start(DR, P, inputs, h, compensated):
    """:func:`drone_solve` before the string's step of :func:`drone_substep`, its thrust pair into
    ``inputs`` (INPUTS' pivot force at the step's start and end, contiguous)."""
    return drone_solve(DR, P, h, compensated, inputs[IN_PIVOT_FORCE:IN_PIVOT_FORCE_END + 3].reshape((2, 3)))


@kernel(inline="always")
def drone_at(D, k):
    """Drone ``k`` of stacked :class:`DroneArrays` ``D`` (every field with a leading index over
    drones: a team's, kernels/team/drones.py) as its own :class:`DroneArrays` of views."""
    return DroneArrays(D.R[k], D.Rc[k], D.Pi[k], D.Pic[k], D.speed[k], D.command[k], D.setpoint[k],
                       D.thrust_scale[k], D.consts[k], D.inertia[k], D.inertia_inv[k], D.mixer[k], D.allocation[k],
                       D.next_speed[k], D.wrench[k], D.scratch[k], D.diag[k])


@kernel(inline="always")
def drone_finish(S, DR, h, dP, c, compensated):
    """The drone's half after the string's step succeeded: the rotors' torque in the balances, the
    rotation committed, the rotor speeds advanced, the end's wrench carried over to the next step."""
    wl = DR.wrench[0]
    wr = DR.wrench[1]
    R = DR.R
    drone_balances(S, R, DR.scratch[3], h, c, (wl[1], wl[2], wl[3]), (wr[1], wr[2], wr[3]))
    commit_rotation(R, DR.Rc, DR.Pi, DR.Pic, DR.scratch[3], DR.scratch[2], dP, compensated)
    for i in range(4):
        DR.speed[i] = DR.next_speed[i]
        wl[i] = wr[i]


@kernel(forceinline=True)
def drone_substep(S, W, P, DR, inputs, h, coupled, compensated):
    """One step of length ``h`` of the string, the load and the drone (module docstring), the motor
    commands ``DR.command`` held, ``DR.wrench[0]`` the wrench at the state's rotor speeds
    (:func:`start_wrench`; on success it becomes the end's, the next step's start, the same bits
    as computing it anew); ``inputs`` (INPUTS) receives the thrust pair (its torques are left as
    they are). Returns ``(status, newton_iterations)``; on failure nothing has moved."""
    status, iters, dP, c = drone_start(DR, P, inputs, h, compensated)
    if status != OK:
        return status, iters
    status, string_iters = lgvi_substep(S, W, P, inputs, h, True, True, coupled, compensated)
    if status == OK:
        drone_finish(S, DR, h, dP, c, compensated)
    return status, iters + string_iters


@kernel(forceinline=True)
def drone_winch_step(S, W, P, WA, D, DR, inputs, speed, compensated):
    """:func:`drone_substep` while the winch reels at ``speed`` [m/s]: the string's step is the
    winch's (kernels/step/step.py ``winch_step``, the explicit string of order 2: one substep of
    ``P.h``); the drone is committed only when it succeeds."""
    status, iters, dP, c = drone_start(DR, P, inputs, P.h, compensated)
    if status != OK:
        return status, iters
    status, string_iters = winch_step(S, W, P, WA, D, inputs, speed, True, compensated, False)
    if status == OK:
        drone_finish(S, DR, P.h, dP, c, compensated)
    return status, iters + string_iters


@kernel(entry=True)
def drone_diagnostics(DR, out):
    """``DR.diag`` (:data:`DRONE_DIAG`) of the drone's state at the default hook, and its share of
    the system's diagnostics ``out`` (DIAG, the string's and the load's on entry): its rotational
    kinetic energy 1/2 Pi_q . J_q^-1 Pi_q joins the energy, e3 . R_q Pi_q joins pi3."""
    Pi = DR.Pi
    Ji = DR.inertia_inv
    rates = (Ji[0, 0] * Pi[0] + Ji[0, 1] * Pi[1] + Ji[0, 2] * Pi[2],
             Ji[1, 0] * Pi[0] + Ji[1, 1] * Pi[1] + Ji[1, 2] * Pi[2],
             Ji[2, 0] * Pi[0] + Ji[2, 1] * Pi[1] + Ji[2, 2] * Pi[2])
    kinetic = 0.0
    for i in range(3):
        kinetic += 0.5 * Pi[i] * rates[i]
    drone_share(DR, out, rates, kinetic, 0.0)


@kernel(inline="always")
def drone_share(DR, out, rates, kinetic, potential):
    """``DR.diag`` from the drone's body ``rates`` Omega_q [rad/s], its kinetic energy beyond its
    hook's translation [J] and its weight's potential beyond the hook's, -m_q g (R_q rho_q) . e3
    [J] (0 at the default hook); both join the energy in ``out`` (DIAG), e3 . R_q Pi_q joins pi3."""
    Pi = DR.Pi
    R = DR.R
    d = DR.diag
    orth = 0.0
    for i in range(3):
        d[QD_RATES + i] = rates[i]
        for j in range(3):
            s = R[0, i] * R[0, j] + R[1, i] * R[1, j] + R[2, i] * R[2, j] - (1.0 if i == j else 0.0)
            orth += s * s
    d[QD_KINETIC] = kinetic
    d[QD_PI3] = R[2, 0] * Pi[0] + R[2, 1] * Pi[1] + R[2, 2] * Pi[2]
    d[QD_ORTHOGONALITY] = math.sqrt(orth)
    rotor_wrench(DR.speed, DR.consts[Q_THRUST_COEFFICIENT], DR.thrust_scale, DR.mixer, DR.wrench[0])
    d[QD_THRUST] = DR.wrench[0, 0]
    for i in range(3):
        d[QD_TORQUE + i] = DR.wrench[0, 1 + i]
    out[D_ENERGY] += kinetic + potential
    out[D_POTENTIAL_GRAVITY] += potential
    out[D_PI3] += d[QD_PI3]
