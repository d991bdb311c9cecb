"""A drone whose hook is not its centre of mass (docs/physics.md, "A drone at the pivot", "The offset
hook"): the drone is then the load's mirror image at the string's other end, and its rotation is
coupled to the string through the pivot's row as the load's is through the attachment's.

With rho_q (hook -> centre of mass, body frame) and m_q = P.Mp, the one-step form gains the
drone's copies of the load's (2) and (4), and (1) the term (m_q/h) e_1 R_q,k (F_q - I) rho_q on
the pivot's row. The Schur complement eliminates the string onto both ends; with
w = M_tot^-1 e_{N+1} (``P.w``) and w_1 = M_tot^-1 e_1 (``HK.column``) the increments are

    dr = h X - M w q_L - m_q w_1 q_q,   q_L = R_k (F_k - I) rho_c,  q_q = R_q,k (F_q - I) rho_q,

and the two Cayley equations, each a rigid body's with its reduced inertia (the load's
``P.Jeff``, the drone's ``HK.jeff`` = J_q^h + m_q^2 (w_1)_1 rho_q^ rho_q^), are coupled only
through the corner (M_tot^-1)_{1,N+1} = w_1[N]:

    drone: g_q = h Pi_q + h^2/2 t_q - m_q rho_q x R_q,k^T (h X_1 - M w_1[N] q_L)
    load:  g_L = (the load's own, kernels/step/lgvi.py) + M m_q w_1[N] rho_c x R_k^T q_q.

They are solved by alternating the two Newton iterations (block Gauss-Seidel) until q_L stops
changing to the Newton tolerance; the coupling is of the order of the string's corner entry
against the bodies' inertias, so a second pass confirms the first (one pass when rho_c = 0).
The step then commits the string and the load (kernels/step/step_shared.py), then the drone. The
hook's constants are :class:`HookArrays`, apart from the drone's (kernels/drone/quadrotor.py), so the
environment's kernels, which fly the default hook, compile as before.
"""
from collections import namedtuple

import numpy as np

from ..jit import kernel
from ..layout import IN_PIVOT_FORCE, IN_PIVOT_FORCE_END
from ..so3 import cayley_minus_identity, cayley_newton, cross, rotated, solve3, unrotated
from ..status import NEWTON_FAILED, NON_FINITE, OK
from ..step.lgvi import end_shift, load_rhs, string_increments
from ..step.step_shared import (body_momentum_increment, commit_rotation, commit_step, held_inputs, left_torque,
                                new_positions, next_attitude, weight_torque)
from ..step.diagnostics import state_diagnostics
from ..step.string import string_solve, tridiag_solve
from ..step.switch import settle_switches, switch_errors
from .quadrotor import drone_balances, drone_share, rotor_ends

#: The hook's constants: ``rho`` rho_q (3,), hook -> centre of mass (body frame) [m]; ``inertia``
#: J_q^h about the hook and ``jeff`` J_q^h + m_q^2 (M_tot^-1)_{11} rho_q^ rho_q^ (3, 3) [kg m^2], the
#: drone's reduced inertia in its Cayley equation; ``column`` M_tot^-1 e_1 (N+1,) [1/kg], the
#: inverse mass matrix's pivot column (esp_gym/physics/drone.py ``hook_arrays``).
HookArrays = namedtuple("HookArrays", "rho inertia jeff column")


@kernel(inline="always")
def hook_torque(rho, wrench):
    """The rotors' torque about the hook [N m] (body frame), tau + rho_q x (-f e3), from the wrench
    ``(f, tau)``: the thrust acts at the centre of mass, ``rho`` from the hook."""
    f = wrench[0]
    return wrench[1] - f * rho[1], wrench[2] + f * rho[0], wrench[3]


@kernel(inline="always")
def drone_turn(DR, HK, P, X, h, t, qL, coupled):
    """The drone's Cayley equation for a given load turn ``qL``: Newton on F_q with g_q (module
    docstring), then F_q - I into ``DR.scratch[1]``. Returns ``(c_q (3), q_q (3), iterations,
    converged)``."""
    R = DR.R
    Pi = DR.Pi
    rho = HK.rho
    hh = 0.5 * h
    mq = P.Mp
    corner = P.M * P.w[0] if coupled else 0.0
    e = unrotated(R, (h * X[0, 0] - corner * qL[0], h * X[0, 1] - corner * qL[1], h * X[0, 2] - corner * qL[2]))
    a = cross(rho, e)  # rho_q x R_q^T d_1
    g0 = h * (Pi[0] + hh * t[0]) - mq * a[0]
    g1 = h * (Pi[1] + hh * t[1]) - mq * a[1]
    g2 = h * (Pi[2] + hh * t[2]) - mq * a[2]
    c0, c1, c2, iters, converged = cayley_newton(g0, g1, g2, HK.jeff, P.tol, P.max_iter, DR.scratch[0])
    FmI = DR.scratch[1]
    cayley_minus_identity(c0, c1, c2, FmI)
    _, _, _, q0, q1, q2 = end_shift(R, FmI, rho)
    return (c0, c1, c2), (q0, q1, q2), iters, converged


@kernel(inline="always")
def load_turn(S, W, P, HK, g, qq, coupled):
    """The load's Cayley equation for a given drone turn ``qq``: Newton on F with g_L, the load's own
    right-hand side ``g`` (kernels/step/lgvi.py ``load_rhs``) plus the drone's share (module docstring),
    F - I into ``W.FmI``. Returns ``(c (3), q_L (3), s_L = (F - I) rho_c (3), iterations,
    converged)``."""
    R = S.R
    g0, g1, g2 = g
    s0 = s1 = s2 = q0 = q1 = q2 = 0.0
    if coupled:
        k = P.M * P.Mp * HK.column[W.X.shape[0] - 1]
        a = cross(P.rho, unrotated(R, qq))  # rho_c x R^T q_q
        g0 += k * a[0]
        g1 += k * a[1]
        g2 += k * a[2]
    c0, c1, c2, iters, converged = cayley_newton(g0, g1, g2, P.Jeff, P.tol, P.max_iter, W.jac)
    cayley_minus_identity(c0, c1, c2, W.FmI)
    if coupled:
        s0, s1, s2, q0, q1, q2 = end_shift(R, W.FmI, P.rho)
    return (c0, c1, c2), (q0, q1, q2), (s0, s1, s2), iters, converged


@kernel(inline="always")
def failure(c):
    """The status of a Newton that did not converge at the Cayley vector ``c``."""
    return NEWTON_FAILED if np.isfinite(c[0] + c[1] + c[2]) else NON_FINITE


@kernel(inline="always")
def coupled_turns(S, W, P, DR, HK, h, t, tq, forced, coupled):
    """Both Cayley equations, alternated until the load's turn q_L is still to the Newton tolerance
    (module docstring). Returns ``(status, iterations, c, q_L, s_L, c_q, q_q, R_k^T d)`` (d = h X_{N+1},
    the string solve's share of dr_{N+1}; 0 when not ``coupled``)."""
    g0, g1, g2, _, _, _, e0, e1, e2 = load_rhs(S, P.M, P.rho, W.X, h, t, forced, coupled)
    e = (e0, e1, e2)
    qL = (0.0, 0.0, 0.0)
    c = s = qq = cq = (0.0, 0.0, 0.0)
    total = 0
    tol2 = P.tol * P.tol
    for _ in range(P.max_iter):
        cq, qq, iters, converged = drone_turn(DR, HK, P, W.X, h, tq, qL, coupled)
        total += iters
        if not converged:
            return failure(cq), total, c, qL, s, cq, qq, e
        c, q, s, iters, converged = load_turn(S, W, P, HK, (g0, g1, g2), qq, coupled)
        total += iters
        if not converged:
            return failure(c), total, c, qL, s, cq, qq, e
        change = (q[0] - qL[0]) ** 2 + (q[1] - qL[1]) ** 2 + (q[2] - qL[2]) ** 2
        qL = q
        if not coupled or change <= tol2 * (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]):
            return OK, total, c, qL, s, cq, qq, e
    return NEWTON_FAILED, total, c, qL, s, cq, qq, e


@kernel(inline="always")
def hook_increments(S, W, P, HK, h, ed, qL, sL, qq, coupled):
    """The increments dr = h X - M w q_L - m_q w_1 q_q into ``W.Y`` (module docstring), from ``ed`` =
    R_k^T h X_{N+1}. Returns ``(e = R_k^T dr_{N+1} (3), the pivot's displacement dr_1 (3))``."""
    X = W.X
    Y = W.Y
    n = X.shape[0] - 1
    M = P.M
    mq = P.Mp
    w = P.w
    w1 = HK.column
    string_increments(X, Y, w, M, qL, h, 0, coupled)
    for a in range(n + 1):
        for i in range(3):
            Y[a, i] = Y[a, i] - mq * w1[a] * qq[i]
    e0 = e1 = e2 = 0.0
    if coupled:  # R_k^T dr_{N+1} = R_k^T d - M w_{N+1} (F - I) rho_c - m_q (w_1)_{N+1} R_k^T q_q
        a = unrotated(S.R, qq)
        e0 = ed[0] - M * w[n] * sL[0] - mq * w1[n] * a[0]
        e1 = ed[1] - M * w[n] * sL[1] - mq * w1[n] * a[1]
        e2 = ed[2] - M * w[n] * sL[2] - mq * w1[n] * a[2]
    return (e0, e1, e2), (Y[0, 0], Y[0, 1], Y[0, 2])


@kernel(inline="always")
def drone_momentum(DR, HK, P, h, tq, wr, dr1, compensated):
    """R_q,k+1 into ``DR.scratch[3]`` (R_q,k (F_q - I) in ``DR.scratch[2]``), and the drone's
    (4) at the hook: dPi_q (body_momentum_increment with m_q, rho_q) from its left torque ``tq``,
    its right one (the weight's and the rotors' about the hook at R_q,k+1, ``wr`` the end's
    wrench) and e_q = R_q,k^T dr_1. Returns ``(dPi_q, tau_q^+)``."""
    R = DR.R
    rho = HK.rho
    next_attitude(R, DR.Rc, DR.scratch[1], DR.scratch[2], DR.scratch[3], compensated)
    right = hook_torque(rho, wr)
    n0, n1, n2 = weight_torque(P.Mp * P.g, rho, DR.scratch[3])
    dP = body_momentum_increment(DR.Pi, DR.scratch[1], P.Mp, rho, h, tq, (n0 + right[0], n1 + right[1], n2 + right[2]),
                                 unrotated(R, dr1), True, True)
    return dP, right


@kernel(forceinline=True)
def hook_substep(S, W, P, DR, HK, inputs, h, coupled, compensated):
    """One step of length ``h`` of the string, the load and a drone at an offset hook (module
    docstring), the motor commands held, ``DR.wrench[0]`` the wrench at the state's rotor speeds;
    ``inputs`` (INPUTS) receives the thrust pair. Returns ``(status, newton_iterations)``; on
    failure nothing has moved."""
    rotor_ends(DR)
    wl = DR.wrench[0]
    wr = DR.wrench[1]
    Rq = DR.R
    rho = HK.rho
    for i in range(3):  # the thrust along -b3 at the step's start
        inputs[IN_PIVOT_FORCE + i] = -wl[0] * Rq[i, 2]
    up0, up1, up2, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held_inputs(inputs, True)
    left = left_torque(S.R, P, tb0, tb1, tb2, ts0, ts1, ts2, True, coupled)
    lq = hook_torque(rho, wl)
    g0, g1, g2 = weight_torque(P.Mp * P.g, rho, Rq)
    tq = (g0 + lq[0], g1 + lq[1], g2 + lq[2])
    string_solve(P.inv, P.cp, 0, S.p, S.f, 0.5 * h, up0, up1, up2, True, W.X)
    status, iters, c, qL, sL, cq, qq, ed = coupled_turns(S, W, P, DR, HK, h, (left[3], left[4], left[5]), tq, True,
                                                           coupled)
    if status != OK:
        return status, iters
    e, dr1 = hook_increments(S, W, P, HK, h, ed, qL, sL, qq, coupled)
    dP, right = drone_momentum(DR, HK, P, h, tq, wr, dr1, compensated)
    if not np.isfinite(dP[0] + dP[1] + dP[2]):
        return NON_FINITE, iters
    Rn = DR.scratch[3]
    for i in range(3):  # the thrust along -b3 at the step's end
        inputs[IN_PIVOT_FORCE_END + i] = -wr[0] * Rn[i, 2]
    held = held_inputs(inputs, True)
    new_positions(S, W, 0, compensated)
    unsettled = 0
    if P.settle:  # the slack switches of the step (kernels/step/switch.py)
        unsettled = switch_errors(S.r, W.X, P.kappa, P.u, P.kappa, P.u, 0.0, S.owed, W.switch)
    status = commit_step(S, W, P, h, c, e, dr1, left, held, (S.f, W.fn), (True, True, coupled, compensated))
    if status != OK:
        return status, iters
    if unsettled > 0:
        settle_switches(S, P, h, S.p, W.switch, S.owed, W.dy, W.fr)
    drone_balances(S, Rq, Rn, h, cq, lq, right)
    commit_rotation(Rq, DR.Rc, DR.Pi, DR.Pic, Rn, DR.scratch[2], dP, compensated)
    for i in range(4):
        DR.speed[i] = DR.next_speed[i]
        wl[i] = wr[i]
    return OK, iters


@kernel(inline="always")
def cross_columns(a, B, out):
    """``out`` = a^ B (3, 3): each column of B crossed with the 3-vector ``a``."""
    for j in range(3):
        out[0, j] = a[1] * B[2, j] - a[2] * B[1, j]
        out[1, j] = a[2] * B[0, j] - a[0] * B[2, j]
        out[2, j] = a[0] * B[1, j] - a[1] * B[0, j]


@kernel(inline="always")
def hook_velocities(S, P, DR, HK, V):
    """The continuous Legendre transform inverted with both ends coupled: node velocities ``V``
    (N+1, 3) [m/s] from the momenta, the load's and the drone's Omega from Pi and Pi_q by the
    Schur complement over the 6 x 6 block (docs/physics.md, "The offset hook"):

        J_eff Omega + C Omega_q = Pi - M rho_c x R^T y_{N+1},   C^T Omega + J_q,eff Omega_q = Pi_q - m_q rho_q x R_q^T y_1,

    y = M_tot^-1 p, C = M m_q (M_tot^-1)_{1,N+1} rho_c^ R^T R_q rho_q^. Returns (Omega, R (rho_c x
    Omega), Omega_q, R_q (rho_q x Omega_q)), four 3-tuples."""
    p = S.p
    n = p.shape[0] - 1
    R = S.R
    Rq = DR.R
    rc = P.rho
    rq = HK.rho
    M = P.M
    mq = P.Mp
    tridiag_solve(P.inv, P.cp, P.off, 0, p, V)
    aL = cross(rc, unrotated(R, V[n]))  # rho_c x R^T y_{N+1}
    aq = cross(rq, unrotated(Rq, V[0]))  # rho_q x R_q^T y_1
    bL0 = S.Pi[0] - M * aL[0]
    bL1 = S.Pi[1] - M * aL[1]
    bL2 = S.Pi[2] - M * aL[2]
    bq0 = DR.Pi[0] - mq * aq[0]
    bq1 = DR.Pi[1] - mq * aq[1]
    bq2 = DR.Pi[2] - mq * aq[2]
    _, B, C, _ = DR.scratch
    hook_coupling(R, Rq, rc, rq, M * mq * HK.column[n], HK.jeff, P.Jeff, DR.scratch)
    Jq = HK.jeff
    u0, u1, u2 = solve3(Jq, bq0, bq1, bq2)
    o0, o1, o2 = solve3(B, bL0 - (C[0, 0] * u0 + C[0, 1] * u1 + C[0, 2] * u2),
                        bL1 - (C[1, 0] * u0 + C[1, 1] * u1 + C[1, 2] * u2),
                        bL2 - (C[2, 0] * u0 + C[2, 1] * u1 + C[2, 2] * u2))
    v0, v1, v2 = solve3(Jq, bq0 - (C[0, 0] * o0 + C[1, 0] * o1 + C[2, 0] * o2),
                        bq1 - (C[0, 1] * o0 + C[1, 1] * o1 + C[2, 1] * o2),
                        bq2 - (C[0, 2] * o0 + C[1, 2] * o1 + C[2, 2] * o2))
    qL = rotated(R, cross(rc, (o0, o1, o2)))  # R (rho_c x Omega)
    qq = rotated(Rq, cross(rq, (v0, v1, v2)))  # R_q (rho_q x Omega_q)
    w = P.w
    column = HK.column
    for a in range(n + 1):
        for i in range(3):
            V[a, i] += M * w[a] * qL[i] + mq * column[a] * qq[i]
    return (o0, o1, o2), qL, (v0, v1, v2), qq


@kernel(inline="always")
def hook_coupling(R, Rq, rc, rq, k, Jq, Jeff, scratch):
    """The coupling C = k rho_c^ R^T R_q rho_q^ (k = M m_q (M_tot^-1)_{1,N+1}) into ``scratch[2]``
    and the Schur complement J_eff - C J_q,eff^-1 C^T into ``scratch[1]`` (:func:`hook_velocities`;
    ``scratch[0]`` holds R^T R_q, then J_q,eff^-1 C^T: the drone's scratch, free between steps)."""
    A, B, C, _ = scratch
    for i in range(3):
        for j in range(3):
            A[i, j] = R[0, i] * Rq[0, j] + R[1, i] * Rq[1, j] + R[2, i] * Rq[2, j]
    for i in range(3):  # B = A rho_q^, column j = A (rho_q x e_j)
        B[i, 0] = A[i, 1] * rq[2] - A[i, 2] * rq[1]
        B[i, 1] = A[i, 2] * rq[0] - A[i, 0] * rq[2]
        B[i, 2] = A[i, 0] * rq[1] - A[i, 1] * rq[0]
    cross_columns(rc, B, C)
    for i in range(3):
        for j in range(3):
            C[i, j] *= k
    for j in range(3):  # Z = J_q,eff^-1 C^T column by column, then J_eff - C Z into B
        z0, z1, z2 = solve3(Jq, C[j, 0], C[j, 1], C[j, 2])
        A[0, j] = z0
        A[1, j] = z1
        A[2, j] = z2
    for i in range(3):
        for j in range(3):
            B[i, j] = Jeff[i, j] - (C[i, 0] * A[0, j] + C[i, 1] * A[1, j] + C[i, 2] * A[2, j])


@kernel(entry=True)
def hook_diagnostics(S, P, D, DR, HK):
    """The rig's diagnostics (``D.out``: DIAG; ``DR.diag``: DRONE_DIAG) with the drone at an offset
    hook: the velocities of :func:`hook_velocities`, the drone's kinetic energy beyond its hook's
    translation 1/2 Omega_q . J_q^h Omega_q + m_q v_1 . R_q (Omega_q x rho_q) and its weight's
    potential -m_q g (R_q rho_q) . e3 [J]."""
    omega, qL, rates, qq = hook_velocities(S, P, DR, HK, D.V)
    state_diagnostics(S, P, D, omega[0], omega[1], omega[2], qL[0], qL[1], qL[2])
    J = HK.inertia
    kinetic = 0.0
    for i in range(3):
        kinetic += 0.5 * rates[i] * (J[i, 0] * rates[0] + J[i, 1] * rates[1] + J[i, 2] * rates[2])
        kinetic -= P.Mp * D.V[0, i] * qq[i]
    R = DR.R
    rho = HK.rho
    potential = -P.Mp * P.g * (R[2, 0] * rho[0] + R[2, 1] * rho[1] + R[2, 2] * rho[2])
    drone_share(DR, D.out, rates, kinetic, potential)
