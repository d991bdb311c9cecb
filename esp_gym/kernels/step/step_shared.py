"""The parts of a step that every scheme shares (the explicit string, kernels/step/lgvi.py; the implicit
one, kernels/step/implicit.py; the winch's, kernels/step/winch.py and kernels/step/winch_implicit.py): the inputs
held over the step, the torque at either end of it, the new positions, and the commit, which
ends every step in named stages: the forces at the new positions and their guards, R_{k+1},
Pi_{k+1} by (4), the input balances, and the write-back of the state (the equations in
kernels/step/lgvi.py's docstring; docs/physics.md).

The commit takes the step's increments grouped as the physics groups them: the Cayley vector c,
e = R_k^T dr_{N+1} and the pivot's displacement dr_0, the left torques (l, t), the held inputs
(u_k, u_{k+1}, tau, T), the two forces whose mean is the string's impulse, and the scheme's flags
(free, forced, coupled, compensated).
"""
import math

import numpy as np

from ..jit import kernel
from ..layout import (B_ANGULAR_IMPULSE_Z, B_GRAVITY_IMPULSE, B_PIVOT_IMPULSE, B_WORK, IN_BODY_TORQUE, IN_PIVOT_FORCE,
                      IN_PIVOT_FORCE_END, IN_SPATIAL_TORQUE)
from ..status import BLOW_UP, NON_FINITE, OK
from ..sums import kahan_add
from .string import nodal_forces


@kernel(inline="always")
def commit_node(r, p, rc, pc, f, fnext, fl, fr, X, Y, a, i, impulse, hh, compensated):
    """Commit coordinate ``i`` of node ``a`` of a step: the position
    r + dr (X, with dr + remainder in Y) and the momentum p + (h/2 (fl + fr) + impulse), both
    with Kahan's compensation if ``compensated`` (else plain sums, remainders untouched); then
    f <- fnext. The explicit string's impulse averages the forces at both ends (fl = f, fr = fnext
    = f_{k+1}); the implicit one's the tensions of the step along the elements at both ends.
    ``impulse + 0.0`` is exact, so rows without an external impulse get the same bits as a
    plain h/2 (fl + fr)."""
    x = X[a, i]
    if compensated:
        rc[a, i] = (r[a, i] - x) + Y[a, i]
    r[a, i] = x
    dp = hh * (fl[a, i] + fr[a, i]) + impulse
    p0 = p[a, i]
    if compensated:
        dp += pc[a, i]
        pn = p0 + dp
        pc[a, i] = (p0 - pn) + dp
        p[a, i] = pn
    else:
        p[a, i] = p0 + dp
    f[a, i] = fnext[a, i]


@kernel(inline="always")
def held_inputs(inputs, forced):
    """The inputs of a step (INPUTS), or zeros when not ``forced``: the pivot force at the step's
    start u_k and at its end u_{k+1} (spatial) [N] (equal for a held force; a drone's thrust
    turns with it), body torque tau (body frame) [N m], spatial torque T [N m], as 12 scalars."""
    up0 = up1 = up2 = ue0 = ue1 = ue2 = tb0 = tb1 = tb2 = ts0 = ts1 = ts2 = 0.0
    if forced:
        up0 = inputs[IN_PIVOT_FORCE]
        up1 = inputs[IN_PIVOT_FORCE + 1]
        up2 = inputs[IN_PIVOT_FORCE + 2]
        ue0 = inputs[IN_PIVOT_FORCE_END]
        ue1 = inputs[IN_PIVOT_FORCE_END + 1]
        ue2 = inputs[IN_PIVOT_FORCE_END + 2]
        tb0 = inputs[IN_BODY_TORQUE]
        tb1 = inputs[IN_BODY_TORQUE + 1]
        tb2 = inputs[IN_BODY_TORQUE + 2]
        ts0 = inputs[IN_SPATIAL_TORQUE]
        ts1 = inputs[IN_SPATIAL_TORQUE + 1]
        ts2 = inputs[IN_SPATIAL_TORQUE + 2]
    return up0, up1, up2, ue0, ue1, ue2, tb0, tb1, tb2, ts0, ts1, ts2


@kernel(inline="always")
def weight_torque(Mg, rho, R):
    """The weight's torque about a body's string end, Mg rho x (R^T e3) (body frame) [N m]:
    ``Mg`` its weight [N], ``rho`` its end -> centre of mass (body frame) [m], R its attitude."""
    z0 = R[2, 0]  # R^T e3
    z1 = R[2, 1]
    z2 = R[2, 2]
    return (Mg * (rho[1] * z2 - rho[2] * z1), Mg * (rho[2] * z0 - rho[0] * z2),
            Mg * (rho[0] * z1 - rho[1] * z0))


@kernel(inline="always")
def left_torque(R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled):
    """The left torque of (2) in the body frame [N m]: ``(l, t)`` with l = tau^- = tau + R_k^T T
    (the inputs' share) and t = tau_g(R_k) + l, tau_g = M g rho_c x (R_k^T e3)."""
    l0 = l1 = l2 = t0 = t1 = t2 = 0.0
    if forced:
        l0 = tb0 + (R[0, 0] * ts0 + R[1, 0] * ts1 + R[2, 0] * ts2)  # tau^- = tau + R_k^T T
        l1 = tb1 + (R[0, 1] * ts0 + R[1, 1] * ts1 + R[2, 1] * ts2)
        l2 = tb2 + (R[0, 2] * ts0 + R[1, 2] * ts1 + R[2, 2] * ts2)
        t0 = l0
        t1 = l1
        t2 = l2
    if coupled:
        w0, w1, w2 = weight_torque(P.M * P.g, P.rho, R)
        t0 = w0 + l0
        t1 = w1 + l1
        t2 = w2 + l2
    return l0, l1, l2, t0, t1, t2


@kernel(inline="always")
def new_positions(S, W, first, compensated):
    """The step's new positions r + dr into ``W.X`` (rows before ``first`` stay at r), from the
    increments in ``W.Y``, to which the remainders S.rc are added first when ``compensated``."""
    r = S.r
    rc = S.rc
    X = W.X
    Y = W.Y
    for a in range(first, r.shape[0]):
        y0 = Y[a, 0]
        y1 = Y[a, 1]
        y2 = Y[a, 2]
        if compensated:
            y0 = y0 + rc[a, 0]
            y1 = y1 + rc[a, 1]
            y2 = y2 + rc[a, 2]
            Y[a, 0] = y0
            Y[a, 1] = y1
            Y[a, 2] = y2
        X[a, 0] = r[a, 0] + y0
        X[a, 1] = r[a, 1] + y1
        X[a, 2] = r[a, 2] + y2
    for a in range(first):
        X[a, 0] = r[a, 0]
        X[a, 1] = r[a, 1]
        X[a, 2] = r[a, 2]


@kernel(inline="always")
def guarded_forces(X, P, fn):
    """``fn`` = the nodal forces at the new positions ``X``; NON_FINITE or BLOW_UP (an element
    longer than the guard, P.max_len2) where they cannot be committed, else OK."""
    total, longest = nodal_forces(X, P.kappa, P.u, P.m, P.M, P.Mp, P.g, P.slack, fn)
    if not np.isfinite(total):
        return NON_FINITE
    if longest > P.max_len2:
        return BLOW_UP
    return OK


@kernel(inline="always")
def next_attitude(R, Rc, FmI, RF, Rn, compensated):
    """``RF`` = R_k (F_k - I) (+ the remainder Rc when ``compensated``) and ``Rn`` = R_k + RF =
    R_{k+1}, the Kahan sum committed by :func:`commit_body`."""
    for i in range(3):
        for j in range(3):
            RF[i, j] = R[i, 0] * FmI[0, j] + R[i, 1] * FmI[1, j] + R[i, 2] * FmI[2, j]
            if compensated:
                RF[i, j] += Rc[i, j]
    for i in range(3):
        for j in range(3):
            Rn[i, j] = R[i, j] + RF[i, j]


@kernel(inline="always")
def free_body_increment(Pi, FmI, h, t, n, forced):
    """dPi of (4) for a body no string pulls on (rho = 0 at its end) [kg m^2/s]: h/2 (t + n) +
    (F - I)^T (Pi_k + h/2 t) with the left and right torques ``t``, ``n`` (body frame) when
    ``forced``, else (F - I)^T Pi_k. The load's uncoupled case and a drone's rotation."""
    hh = 0.5 * h
    t0, t1, t2 = t
    n0, n1, n2 = n
    if forced:
        u0 = Pi[0] + hh * t0
        u1 = Pi[1] + hh * t1
        u2 = Pi[2] + hh * t2
    else:
        u0 = Pi[0]
        u1 = Pi[1]
        u2 = Pi[2]
    dP0 = FmI[0, 0] * u0 + FmI[1, 0] * u1 + FmI[2, 0] * u2  # (F - I)^T u
    dP1 = FmI[0, 1] * u0 + FmI[1, 1] * u1 + FmI[2, 1] * u2
    dP2 = FmI[0, 2] * u0 + FmI[1, 2] * u1 + FmI[2, 2] * u2
    if forced:
        dP0 = hh * (t0 + n0) + dP0
        dP1 = hh * (t1 + n1) + dP1
        dP2 = hh * (t2 + n2) + dP2
    return dP0, dP1, dP2


@kernel(inline="always")
def body_momentum_increment(Pi, FmI, M, rho, h, t, n, e, forced, coupled):
    """dPi of (4) in increment form [kg m^2/s], from the left total torque ``t`` = tau_g(R_k) +
    tau^-, the right one ``n`` = tau_g(R_{k+1}) + tau^+ (body frame) and ``e`` = R_k^T dr_{N+1},
    for a body of mass ``M`` [kg] whose string end is ``rho`` from its centre of mass (body
    frame) [m]: the load (M, rho_c), or a drone at an offset hook (m_q, rho_q; kernels/drone/hook.py).

    By (2), u := Pi_k + h/2 t - (M/h) rho_c x e equals (1/h)(F J_d - J_d F^T)^vee, so (4) reads
    Pi_{k+1} = F^T u + (M/h) rho_c x (R_{k+1}^T dr_{N+1}) + h/2 n, i.e.
    dPi = h/2 (t + n) + (F - I)^T u + (M/h) rho_c x ((F - I)^T e). Every term is O(h) and
    vanishes exactly where it should (a steady spin about a principal axis), and R_{k+1}
    Pi_{k+1} = R_k u + ... uses the same F, so the Newton round-off does not leak into pi3."""
    if not coupled:
        return free_body_increment(Pi, FmI, h, t, n, forced)
    hh = 0.5 * h
    Mh = M / h
    rho0 = rho[0]
    rho1 = rho[1]
    rho2 = rho[2]
    t0, t1, t2 = t
    n0, n1, n2 = n
    e0, e1, e2 = e
    u0 = Pi[0] + hh * t0 - Mh * (rho1 * e2 - rho2 * e1)
    u1 = Pi[1] + hh * t1 - Mh * (rho2 * e0 - rho0 * e2)
    u2 = Pi[2] + hh * t2 - Mh * (rho0 * e1 - rho1 * e0)
    dP0 = FmI[0, 0] * u0 + FmI[1, 0] * u1 + FmI[2, 0] * u2  # (F - I)^T u
    dP1 = FmI[0, 1] * u0 + FmI[1, 1] * u1 + FmI[2, 1] * u2
    dP2 = FmI[0, 2] * u0 + FmI[1, 2] * u1 + FmI[2, 2] * u2
    a0 = FmI[0, 0] * e0 + FmI[1, 0] * e1 + FmI[2, 0] * e2  # (F - I)^T R_k^T dr_{N+1}
    a1 = FmI[0, 1] * e0 + FmI[1, 1] * e1 + FmI[2, 1] * e2
    a2 = FmI[0, 2] * e0 + FmI[1, 2] * e1 + FmI[2, 2] * e2
    dP0 = hh * (t0 + n0) + dP0 + Mh * (rho1 * a2 - rho2 * a1)
    dP1 = hh * (t1 + n1) + dP1 + Mh * (rho2 * a0 - rho0 * a2)
    dP2 = hh * (t2 + n2) + dP2 + Mh * (rho0 * a1 - rho1 * a0)
    return dP0, dP1, dP2


@kernel(inline="always")
def torque_work(c, left, right):
    """The discrete work tau_avg . theta [J] of a body torque over a step: theta the rotation
    vector of F = cay(c) from the Cayley vector ``c``, tau_avg = (tau^- + tau^+)/2 from the
    torques ``left`` and ``right`` (body frame [N m])."""
    c0, c1, c2 = c
    l0, l1, l2 = left
    m0, m1, m2 = right
    ff = c0 * c0 + c1 * c1 + c2 * c2
    th = 2.0 if ff == 0.0 else 2.0 * math.atan(math.sqrt(ff)) / math.sqrt(ff)
    return 0.5 * th * ((l0 + m0) * c0 + (l1 + m1) * c1 + (l2 + m2) * c2)


@kernel(inline="always")
def input_balances(S, P, R, Rn, h, c, left, right, held, dr0, free, forced):
    """The inputs' balances over the step, before r and R move: the discrete work
    u_bar . dr_0 + tau_avg . theta (u_bar = (u_k + u_{k+1})/2 the pivot force's mean, theta the
    rotation vector of F from the Cayley vector ``c``, tau_avg = (tau^- + tau^+)/2 from the
    inputs' shares ``left`` and ``right``), the angular impulse about e3,
    e3 . [h/2 (r_0k x u_k + r_0k+1 x u_{k+1}) + h/2 (R_k tau + R_{k+1} tau) + h T], the pivot's
    impulse h u_bar; and the weight's impulse along +e3 [J, N m s, N s]. A held pivot force
    (u_k = u_{k+1}) gives the bits of u . dr_0 and h/2 (r_0k + r_0k+1) x u: the mean is exact
    and the turning term an exact zero."""
    acc = S.acc
    accc = S.accc
    r = S.r
    hh = 0.5 * h
    n = r.shape[0] - 1
    if forced:
        up0, up1, up2, ue0, ue1, ue2, tb0, tb1, tb2, _, _, ts2 = held
        work = torque_work(c, left, right)
        ang = hh * ((R[2, 0] + Rn[2, 0]) * tb0 + (R[2, 1] + Rn[2, 1]) * tb1 + (R[2, 2] + Rn[2, 2]) * tb2) + h * ts2
        if free:
            dr00, dr01, dr02 = dr0
            u0 = 0.5 * (up0 + ue0)  # the mean force: u itself, bit for bit, when held
            u1 = 0.5 * (up1 + ue1)
            u2 = 0.5 * (up2 + ue2)
            work += u0 * dr00 + u1 * dr01 + u2 * dr02
            # h/2 (r_k x u_k + r_{k+1} x u_{k+1}) = h/2 ((2 r_k + dr) x u_bar + 1/2 dr x (u_{k+1} - u_k))
            turning = 0.5 * (dr00 * (ue1 - up1) - dr01 * (ue0 - up0))
            ang += hh * (((2.0 * r[0, 0] + dr00) * u1 - (2.0 * r[0, 1] + dr01) * u0) + turning)
            kahan_add(acc, accc, B_PIVOT_IMPULSE, h * u0)
            kahan_add(acc, accc, B_PIVOT_IMPULSE + 1, h * u1)
            kahan_add(acc, accc, B_PIVOT_IMPULSE + 2, h * u2)
        kahan_add(acc, accc, B_WORK, work)
        kahan_add(acc, accc, B_ANGULAR_IMPULSE_Z, ang)
    kahan_add(acc, accc, B_GRAVITY_IMPULSE + 2, h * P.g * (P.M + P.Mp + n * P.m))  # weight along +e3


@kernel(inline="always")
def commit_string(S, W, h, held, fl, fr, free, forced, compensated, end_impulse=(0.0, 0.0, 0.0)):
    """Write the nodes' new positions and momenta (:func:`commit_node`) with the impulse
    h/2 (fl + fr), the free pivot's row with its input impulse h/2 (u_k + u_{k+1}) (h u, bit for
    bit, for a held force) in the same compensated sum, and the attachment row with
    ``end_impulse`` (spatial) [N s] (a team's other strings' ends: kernels/team/step.py; an exact zero
    otherwise); ``S.f`` becomes ``fr`` (the implicit step's first guess for the next)."""
    r = S.r
    p = S.p
    f = S.f
    n = r.shape[0] - 1
    hh = 0.5 * h
    first = 0 if free else 1
    fnext = fr
    start = first
    if free and forced:
        up0, up1, up2, ue0, ue1, ue2, _, _, _, _, _, _ = held
        commit_node(r, p, S.rc, S.pc, f, fnext, fl, fr, W.X, W.Y, 0, 0, hh * (up0 + ue0), hh, compensated)
        commit_node(r, p, S.rc, S.pc, f, fnext, fl, fr, W.X, W.Y, 0, 1, hh * (up1 + ue1), hh, compensated)
        commit_node(r, p, S.rc, S.pc, f, fnext, fl, fr, W.X, W.Y, 0, 2, hh * (up2 + ue2), hh, compensated)
        start = 1
    for a in range(start, n + 1):
        for i in range(3):  # one inlined site: the end row's impulse picked in the loop
            impulse = end_impulse[i] if a == n else 0.0
            commit_node(r, p, S.rc, S.pc, f, fnext, fl, fr, W.X, W.Y, a, i, impulse, hh, compensated)
    for a in range(first):
        f[a, 0] = fnext[a, 0]
        f[a, 1] = fnext[a, 1]
        f[a, 2] = fnext[a, 2]


@kernel(inline="always")
def commit_rotation(R, Rc, Pi, Pic, Rn, RF, dP, compensated):
    """R <- R_{k+1} and Pi <- Pi_k + dPi, compensated (remainders in Rc, Pic) or plain: the
    load's (:func:`commit_body`) and a drone's (kernels/drone/quadrotor.py)."""
    for i in range(3):
        for j in range(3):
            if compensated:
                Rc[i, j] = (R[i, j] - Rn[i, j]) + RF[i, j]
            R[i, j] = Rn[i, j]
    if compensated:
        kahan_add(Pi, Pic, 0, dP[0])
        kahan_add(Pi, Pic, 1, dP[1])
        kahan_add(Pi, Pic, 2, dP[2])
    else:
        Pi[0] += dP[0]
        Pi[1] += dP[1]
        Pi[2] += dP[2]


@kernel(inline="always")
def commit_body(S, Rn, RF, dP, compensated):
    """R <- R_{k+1} and Pi <- Pi_k + dPi, compensated (remainders in S.Rc, S.Pic) or plain."""
    commit_rotation(S.R, S.Rc, S.Pi, S.Pic, Rn, RF, dP, compensated)


# LLVM-inlined, not numba-IR-inlined: compiled once per signature instead of deep-copied
# into every caller (kernels/jit.py).
@kernel(forceinline=True)
def commit_step(S, W, P, h, c, e, dr0, left, held, impulse, flags):
    """The end of a step, shared by every scheme: the forces at the new positions and the guards
    on them, R_{k+1} and Pi_{k+1} by (4), the input balances, and the write-back of the state.
    Returns the status (the state untouched unless OK).

    On entry ``W.X`` holds the new positions, ``W.Y`` the increments dr (+ the remainders
    S.rc, when compensated), ``W.FmI`` = F_k - I for the Cayley vector ``c``; ``e`` = R_k^T
    dr_{N+1}, ``dr0`` the pivot's displacement (read when free and forced), ``left`` =
    :func:`left_torque`'s (l, t) at R_k, ``held`` = :func:`held_inputs`'s (u_k, u_{k+1}, tau, T).
    ``impulse`` = (fl, fr), the forces whose mean times h is the string's impulse: (S.f, W.fn)
    for the explicit string, h/2 (f_k + f_{k+1}), with W.fn filled here; the step's own for the
    implicit string (its tensions at both ends) and the winch (with grad T0 and the convective
    impulse); ``S.f`` becomes fr. ``flags`` = (free, forced, coupled, compensated).
    """
    free, forced, coupled, compensated = flags
    fl, fr = impulse
    status = guarded_forces(W.X, P, W.fn)
    if status != OK:
        return status
    next_attitude(S.R, S.Rc, W.FmI, W.RF, W.Rn, compensated)
    # the torque at the right end, tau_g(R_{k+1}) + tau^+ with tau^+ = tau + R_{k+1}^T T
    _, _, _, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held
    m0, m1, m2, n0, n1, n2 = left_torque(W.Rn, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    dP = body_momentum_increment(S.Pi, W.FmI, P.M, P.rho, h, (left[3], left[4], left[5]), (n0, n1, n2), e,
                                 forced, coupled)
    if not np.isfinite(dP[0] + dP[1] + dP[2]):
        return NON_FINITE
    input_balances(S, P, S.R, W.Rn, h, c, (left[0], left[1], left[2]), (m0, m1, m2), held, dr0, free, forced)
    commit_string(S, W, h, held, fl, fr, free, forced, compensated)
    commit_body(S, W.Rn, W.RF, dP, compensated)
    return OK
