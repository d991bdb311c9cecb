"""The Lie group variational integrator of the elastic string pendulum, with inputs.

The paper writes the scheme as a two-step recursion (DEL0)-(DEL4). We run its equivalent
one-step (position-momentum) form: with the discrete Legendre transforms
``p_k = -D_1 L_d(g_k, f_k)`` and ``p_{k+1} = D_2 L_d(g_k, f_k)`` the map
``(g_k, p_k) -> (g_{k+1}, p_{k+1})`` is the same flow, and the momenta give the diagnostics.

From the discrete Lagrangian (Ldka), (Ldkrb) with errata 1-2 fixed, for nodes a = 2..N+1
(row 1..N here) and the body (notation of the paper; f_a(r) = -dV/dr_a, see nodal_forces)::

    (1/h) M_tot dr  +  (M/h) e_{N+1} (R_k (F_k - I) rho_c)   = p_k + (h/2) f(r_k)        (1)
    (1/h)(F_k J_d - J_d F_k^T)^vee + (M/h) rho_c^ R_k^T dr_{N+1} = Pi_k + (h/2) tau_g(R_k)   (2)
    p_{k+1}  = p_k + (h/2) (f(r_k) + f(r_{k+1}))                                           (3)
    Pi_{k+1} = (1/h)(J_d F_k - F_k^T J_d)^vee + (M/h) rho_c^ R_{k+1}^T dr_{N+1}
               + (h/2) tau_g(R_{k+1})                                                      (4)

with M_tot the consistent mass matrix (m/6)[1 4 1] with last diagonal M + m/3, and
tau_g(R) = M g rho_c x (R^T e3) the gravity torque about the attachment point (body frame).
(1) is linear in dr; eliminating it (Schur complement, s = (M_tot^-1)_{N+1,N+1},
w = M_tot^-1 e_{N+1}) gives dr = h M_tot^-1 B - M w (R_k (F_k - I) rho_c) and turns (2) into

    (F_k K - K F_k^T)^vee = h Pi_k + (h^2/2) tau_g - M rho_c x (R_k^T d),   d = h (M_tot^-1 B)_{N+1}
    K = J_d - M^2 s rho_c rho_c^T,  i.e. tr(K) I - K = J_eff = J + M^2 s rho_c^ rho_c^,

a rigid-body equation with a modified inertia, solved by Newton on the Cayley vector.

Inputs (docs/physics.md, "Inputs through the discrete Lagrange–d'Alembert principle") are held
constant over a step and enter as discrete forces split half and half, f_d^- = f_d^+ = (h/2) u:

* a free pivot (row 0 unknown, point mass M_p) pushed by the spatial force u_p: (h/2) u_p joins
  the right-hand side of (1) at row 0, and (3) gains h u_p there;
* a body torque tau (body frame) and a spatial torque T: the left half uses
  tau^- = tau + R_k^T T in (2), the right half tau^+ = tau + R_{k+1}^T T in (4).

With zero inputs and a fixed pivot every added term is an exact zero, so the scheme is the
paper's, bit for bit.
"""
import math

import numpy as np

from .jit import kernel
from .layout import (B_ANGULAR_IMPULSE_Z, B_GRAVITY_IMPULSE, B_PIVOT_IMPULSE, B_WORK, BLOW_UP, IN_BODY_TORQUE,
                     IN_PIVOT_FORCE, IN_SPATIAL_TORQUE, NEWTON_FAILED, NON_FINITE, OK)
from .so3 import cayley_minus_identity, cayley_newton
from .string import nodal_forces, string_solve
from .switch import settle_switches, switch_errors


@kernel
def kahan_add(x, c, i, dx):
    """x[i] += dx with Kahan compensation, the remainder kept in c[i]."""
    y = dx + c[i]
    t = x[i] + y
    c[i] = (x[i] - t) + y
    x[i] = t


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
    """The inputs held over a step (INPUTS), or zeros when not ``forced``: pivot force u_p
    (spatial) [N], body torque tau (body frame) [N m], spatial torque T [N m], as 9 scalars."""
    up0 = up1 = up2 = tb0 = tb1 = tb2 = ts0 = ts1 = ts2 = 0.0
    if forced:
        up0 = inputs[IN_PIVOT_FORCE]
        up1 = inputs[IN_PIVOT_FORCE + 1]
        up2 = inputs[IN_PIVOT_FORCE + 2]
        tb0 = inputs[IN_BODY_TORQUE]
        tb1 = inputs[IN_BODY_TORQUE + 1]
        tb2 = inputs[IN_BODY_TORQUE + 2]
        ts0 = inputs[IN_SPATIAL_TORQUE]
        ts1 = inputs[IN_SPATIAL_TORQUE + 1]
        ts2 = inputs[IN_SPATIAL_TORQUE + 2]
    return up0, up1, up2, tb0, tb1, tb2, ts0, ts1, ts2


@kernel(inline="always")
def left_torque(R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled):
    """The left torque of (2) in the body frame [N m]: ``(l, t)`` with l = tau^- = tau + R_k^T T
    (the inputs' share) and t = tau_g(R_k) + l, tau_g = M g rho_c x (R_k^T e3)."""
    Mg = P.M * P.g
    rho0 = P.rho[0]
    rho1 = P.rho[1]
    rho2 = P.rho[2]
    z0 = R[2, 0]  # R^T e3
    z1 = R[2, 1]
    z2 = R[2, 2]
    l0 = l1 = l2 = t0 = t1 = t2 = 0.0
    if forced:
        l0 = tb0 + (R[0, 0] * ts0 + R[1, 0] * ts1 + R[2, 0] * ts2)  # tau^- = tau + R_k^T T
        l1 = tb1 + (R[0, 1] * ts0 + R[1, 1] * ts1 + R[2, 1] * ts2)
        l2 = tb2 + (R[0, 2] * ts0 + R[1, 2] * ts1 + R[2, 2] * ts2)
        t0 = l0
        t1 = l1
        t2 = l2
    if coupled:
        t0 = Mg * (rho1 * z2 - rho2 * z1) + l0
        t1 = Mg * (rho2 * z0 - rho0 * z2) + l1
        t2 = Mg * (rho0 * z1 - rho1 * z0) + l2
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


# LLVM-inlined, not numba-IR-inlined: compiled once per signature instead of deep-copied
# into every caller (kernels/jit.py); the cold start of the env's first step halved.
@kernel(forceinline=True)
def explicit_increments(S, W, P, h, up0, up1, up2, t0, t1, t2, free, forced, coupled):
    """(1) and (2) with the string's forces ``S.f`` of the state: the string solve, the Schur
    complement and Newton on the Cayley vector c of F_k. Writes the increments dr of the
    unknown nodes into ``W.Y`` (no remainders added; ``W.X`` is scratch) and F_k - I into
    ``W.FmI``; ``t`` is the left torque (:func:`left_torque`), ``up`` the pivot force. The
    explicit step, and the implicit string's first guess. Returns ``(c (3), e = R_k^T dr_{N+1}
    (3), the pivot's displacement (3, when free and forced), iterations, status)``."""
    first = 0 if free else 1
    # (1): right-hand side and the string solve with F_k = I
    string_solve(P.inv, P.cp, first, S.p, S.f, 0.5 * h, up0, up1, up2, free and forced, W.X)
    return rigid_increments(S, W, P, h, P.Jeff, P.w, t0, t1, t2, free, forced, coupled)


@kernel(forceinline=True)
def rigid_increments(S, W, P, h, Jeff, w, t0, t1, t2, free, forced, coupled):
    """The rest of :func:`explicit_increments` once ``W.X`` holds the string solve with F_k = I
    (X = M^-1 B): the Schur complement (``w`` = M^-1 e_{N+1}, ``Jeff`` = J + M^2 w_{N+1}
    rho_c^ rho_c^), Newton on the Cayley vector of F_k and the increments dr into ``W.Y``. Shared
    with the winch's step (kernels/winch.py), whose M is the step's own. Returns as
    :func:`explicit_increments`."""
    r = S.r
    R = S.R
    Pi = S.Pi
    X = W.X
    Y = W.Y
    hh = 0.5 * h
    n = r.shape[0] - 1
    first = 0 if free else 1
    M = P.M
    rho0 = P.rho[0]
    rho1 = P.rho[1]
    rho2 = P.rho[2]
    d0 = h * X[n, 0]
    d1 = h * X[n, 1]
    d2 = h * X[n, 2]
    # (2) after the Schur complement: g = h Pi + h^2/2 tau_k - M rho_c x (R_k^T d)
    e0 = e1 = e2 = 0.0
    if coupled:
        e0 = R[0, 0] * d0 + R[1, 0] * d1 + R[2, 0] * d2  # R^T d
        e1 = R[0, 1] * d0 + R[1, 1] * d1 + R[2, 1] * d2
        e2 = R[0, 2] * d0 + R[1, 2] * d1 + R[2, 2] * d2
        g0 = h * (Pi[0] + hh * t0) - M * (rho1 * e2 - rho2 * e1)
        g1 = h * (Pi[1] + hh * t1) - M * (rho2 * e0 - rho0 * e2)
        g2 = h * (Pi[2] + hh * t2) - M * (rho0 * e1 - rho1 * e0)
    elif forced:
        g0 = h * (Pi[0] + hh * t0)
        g1 = h * (Pi[1] + hh * t1)
        g2 = h * (Pi[2] + hh * t2)
    else:
        g0 = h * Pi[0]
        g1 = h * Pi[1]
        g2 = h * Pi[2]
    c0, c1, c2, iters, converged = cayley_newton(g0, g1, g2, Jeff, P.tol, P.max_iter, W.jac)
    if not converged:
        if np.isfinite(c0 + c1 + c2 + d0 + d1 + d2):
            return c0, c1, c2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, iters, NEWTON_FAILED
        return c0, c1, c2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, iters, NON_FINITE
    FmI = W.FmI
    cayley_minus_identity(c0, c1, c2, FmI)
    # q = R_k (F_k - I) rho_c; dr = h X - M w q -> Y
    s0 = s1 = s2 = q0 = q1 = q2 = 0.0
    if coupled:
        s0 = FmI[0, 0] * rho0 + FmI[0, 1] * rho1 + FmI[0, 2] * rho2
        s1 = FmI[1, 0] * rho0 + FmI[1, 1] * rho1 + FmI[1, 2] * rho2
        s2 = FmI[2, 0] * rho0 + FmI[2, 1] * rho1 + FmI[2, 2] * rho2
        q0 = R[0, 0] * s0 + R[0, 1] * s1 + R[0, 2] * s2
        q1 = R[1, 0] * s0 + R[1, 1] * s1 + R[1, 2] * s2
        q2 = R[2, 0] * s0 + R[2, 1] * s1 + R[2, 2] * s2
    dr00 = dr01 = dr02 = 0.0
    if free and forced:  # pivot displacement, for the work of the pivot force
        dr00 = h * X[0, 0] - M * w[0] * q0
        dr01 = h * X[0, 1] - M * w[0] * q1
        dr02 = h * X[0, 2] - M * w[0] * q2
    for a in range(first, n + 1):
        y0 = h * X[a, 0]
        y1 = h * X[a, 1]
        y2 = h * X[a, 2]
        if coupled:
            y0 = y0 - M * w[a] * q0
            y1 = y1 - M * w[a] * q1
            y2 = y2 - M * w[a] * q2
        Y[a, 0] = y0
        Y[a, 1] = y1
        Y[a, 2] = y2
    if coupled:
        e0 = e0 - M * w[n] * s0  # R_k^T dr_{N+1} = R_k^T d - M s (F - I) rho_c
        e1 = e1 - M * w[n] * s1
        e2 = e2 - M * w[n] * s2
    return c0, c1, c2, e0, e1, e2, dr00, dr01, dr02, iters, OK


@kernel(forceinline=True)
def lgvi_substep(S, W, P, inputs, h, free, forced, coupled, compensated):
    """Advance the state ``S`` (:class:`StateArrays`) by one LGVI step of length ``h``, in place.

    ``inputs`` (9,): pivot force u_p (spatial) [N], body torque tau (body frame) [N m], spatial
    torque T [N m], held over the step. The flags say what the scene needs (see
    :func:`specialised_kernels`; passed as constants, the compiler drops what is off):
    ``free`` the pivot is a free point mass (``P.first == 0``), ``forced`` the inputs are
    read (else they are taken as zero and the input balances are not updated), ``coupled``
    rho_c != 0 (else the body's rotation is decoupled from the string: no gravity torque, no
    coupling terms). Each flag off gives the same numbers as the flag on with what it drops
    equal to zero (the dropped terms are exact zeros there).

    With ``compensated`` the increments are added with Kahan's trick (remainders in S.rc, pc,
    Rc, Pic), because in a smooth motion the round-off of ``r + dr`` repeats for many steps
    and would otherwise accumulate linearly into pi3 and the energy; without it they are plain
    sums (~13 % cheaper; for runs short enough that round-off does not matter, see
    ``solver.compensated``) and the remainders are left as they are.
    On entry ``S.f`` holds ``nodal_forces(r)``; on success it holds the forces at the new state.
    On failure the state is left untouched and a non-zero status is returned.
    Returns ``(status, newton_iterations)``.
    """
    R = S.R
    first = 0 if free else 1
    up0, up1, up2, tb0, tb1, tb2, ts0, ts1, ts2 = held_inputs(inputs, forced)
    l0, l1, l2, t0, t1, t2 = left_torque(R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    c0, c1, c2, e0, e1, e2, dr00, dr01, dr02, iters, status = explicit_increments(
        S, W, P, h, up0, up1, up2, t0, t1, t2, free, forced, coupled)
    if status != OK:
        return status, iters
    new_positions(S, W, first, compensated)
    unsettled = 0
    if P.settle:  # the slack switches of the step (kernels/switch.py)
        unsettled = switch_errors(S.r, W.X, P.kappa, P.u, P.kappa, P.u, 0.0, S.owed, W.switch)
    status = lgvi_commit(S, W, P, h, c0, c1, c2, e0, e1, e2, l0, l1, l2, t0, t1, t2, tb0, tb1, tb2, ts0, ts1, ts2,
                         up0, up1, up2, dr00, dr01, dr02, free, forced, coupled, compensated, False)
    if status == OK and unsettled > 0:
        settle_switches(S, P, h, S.p, W.switch, S.owed, W.dy, W.fr)
    return status, iters


@kernel(forceinline=True)
def lgvi_commit(S, W, P, h, c0, c1, c2, e0, e1, e2, l0, l1, l2, t0, t1, t2, tb0, tb1, tb2, ts0, ts1, ts2,
                up0, up1, up2, dr00, dr01, dr02, free, forced, coupled, compensated, implicit):
    """The end of a step, shared by the explicit and the implicit string: the forces at the new
    positions and the guards on them, R_{k+1}, Pi_{k+1} by (4), the input balances, and the
    write-back of the state. Returns the status (the state untouched unless OK).

    On entry ``W.X`` holds the new positions, ``W.Y`` the increments dr (+ the remainders
    S.rc, when ``compensated``), ``W.FmI`` = F_k - I for the Cayley vector c, and
    e = R_k^T dr_{N+1}; l, t are the left torques (:func:`left_torque`), tb, ts, up the held
    inputs, dr0 the pivot's displacement (read when ``free and forced``). The string's impulse
    is h/2 (f_k + f_{k+1}) (explicit) or h/2 (W.fl + W.fr) (``implicit``: the tensions of the
    step along the elements at both ends), and ``S.f`` becomes f_{k+1} or W.fr.
    """
    r = S.r
    p = S.p
    R = S.R
    Pi = S.Pi
    f = S.f
    X = W.X
    Y = W.Y
    fn = W.fn
    FmI = W.FmI
    rc = S.rc
    hh = 0.5 * h
    n = r.shape[0] - 1
    first = 0 if free else 1
    M = P.M
    Mg = M * P.g
    rho0 = P.rho[0]
    rho1 = P.rho[1]
    rho2 = P.rho[2]
    fl = W.fl if implicit else f
    fr = W.fr if implicit else fn
    fnext = fr  # what S.f holds after the step (the implicit step's first guess for the next)
    total, longest = nodal_forces(X, P.kappa, P.u, P.m, M, P.Mp, P.g, P.slack, fn)
    if not np.isfinite(total):
        return NON_FINITE
    if longest > P.max_len2:
        return BLOW_UP
    # R_k (F_k - I) + Rc, and R_{k+1} = R_k + that (Kahan)
    RF = W.RF
    Rc = S.Rc
    for i in range(3):
        for j in range(3):
            RF[i, j] = R[i, 0] * FmI[0, j] + R[i, 1] * FmI[1, j] + R[i, 2] * FmI[2, j]
            if compensated:
                RF[i, j] += Rc[i, j]
    Rn = W.Rn
    for i in range(3):
        for j in range(3):
            Rn[i, j] = R[i, j] + RF[i, j]
    # (4) in increment form. By (2), u := Pi_k + h/2 tau_k - (M/h) rho_c x (R_k^T dr_{N+1})
    # equals (1/h)(F J_d - J_d F^T)^vee, so (4) reads Pi_{k+1} = F^T u + (M/h) rho_c x
    # (R_{k+1}^T dr_{N+1}) + h/2 tau_{k+1}, i.e. Pi_{k+1} = Pi_k + dPi with
    #   dPi = h/2 (tau_k + tau_{k+1}) + (F - I)^T u + (M/h) rho_c x ((F - I)^T R_k^T dr_{N+1}).
    # Every term of dPi is O(h) and vanishes exactly where it should (e.g. a steady spin about
    # a principal axis), and R_{k+1} Pi_{k+1} = R_k u + ... uses the same F, so the Newton
    # round-off does not leak into pi3.
    Mh = M / h
    if coupled:
        u0 = Pi[0] + hh * t0 - Mh * (rho1 * e2 - rho2 * e1)
        u1 = Pi[1] + hh * t1 - Mh * (rho2 * e0 - rho0 * e2)
        u2 = Pi[2] + hh * t2 - Mh * (rho0 * e1 - rho1 * e0)
    elif forced:
        u0 = Pi[0] + hh * t0
        u1 = Pi[1] + hh * t1
        u2 = Pi[2] + hh * t2
    else:
        u0 = Pi[0]
        u1 = Pi[1]
        u2 = Pi[2]
    # right torque tau_{k+1} = tau_g(R_{k+1}) + tau + R_{k+1}^T T
    m0 = m1 = m2 = n0 = n1 = n2 = 0.0
    if forced:
        m0 = tb0 + (Rn[0, 0] * ts0 + Rn[1, 0] * ts1 + Rn[2, 0] * ts2)  # tau^+ = tau + R_{k+1}^T T
        m1 = tb1 + (Rn[0, 1] * ts0 + Rn[1, 1] * ts1 + Rn[2, 1] * ts2)
        m2 = tb2 + (Rn[0, 2] * ts0 + Rn[1, 2] * ts1 + Rn[2, 2] * ts2)
        n0 = m0
        n1 = m1
        n2 = m2
    dP0 = FmI[0, 0] * u0 + FmI[1, 0] * u1 + FmI[2, 0] * u2  # (F - I)^T u
    dP1 = FmI[0, 1] * u0 + FmI[1, 1] * u1 + FmI[2, 1] * u2
    dP2 = FmI[0, 2] * u0 + FmI[1, 2] * u1 + FmI[2, 2] * u2
    if coupled:
        n0 = Mg * (rho1 * Rn[2, 2] - rho2 * Rn[2, 1]) + m0
        n1 = Mg * (rho2 * Rn[2, 0] - rho0 * Rn[2, 2]) + m1
        n2 = Mg * (rho0 * Rn[2, 1] - rho1 * Rn[2, 0]) + m2
        a0 = FmI[0, 0] * e0 + FmI[1, 0] * e1 + FmI[2, 0] * e2  # (F - I)^T R_k^T dr_{N+1}
        a1 = FmI[0, 1] * e0 + FmI[1, 1] * e1 + FmI[2, 1] * e2
        a2 = FmI[0, 2] * e0 + FmI[1, 2] * e1 + FmI[2, 2] * e2
        dP0 = hh * (t0 + n0) + dP0 + Mh * (rho1 * a2 - rho2 * a1)
        dP1 = hh * (t1 + n1) + dP1 + Mh * (rho2 * a0 - rho0 * a2)
        dP2 = hh * (t2 + n2) + dP2 + Mh * (rho0 * a1 - rho1 * a0)
    elif forced:
        dP0 = hh * (t0 + n0) + dP0
        dP1 = hh * (t1 + n1) + dP1
        dP2 = hh * (t2 + n2) + dP2
    if not np.isfinite(dP0 + dP1 + dP2):
        return NON_FINITE
    # -- commit -------------------------------------------------------------------------------
    # balances of the inputs (before r and R move): discrete work u_p . dr_0 + tau_avg . theta
    # (theta the rotation vector of F, tau_avg = (tau^- + tau^+)/2), angular impulse about e3
    # e3 . [h/2 (r_0k + r_0k+1) x u_p + h/2 (R_k tau^- + R_{k+1} tau^+)], linear impulses.
    acc = S.acc
    accc = S.accc
    if forced:
        ff = c0 * c0 + c1 * c1 + c2 * c2
        th = 2.0 if ff == 0.0 else 2.0 * math.atan(math.sqrt(ff)) / math.sqrt(ff)
        work = 0.5 * th * ((l0 + m0) * c0 + (l1 + m1) * c1 + (l2 + m2) * c2)
        ang = hh * ((R[2, 0] + Rn[2, 0]) * tb0 + (R[2, 1] + Rn[2, 1]) * tb1 + (R[2, 2] + Rn[2, 2]) * tb2) + h * ts2
        if free:
            work += up0 * dr00 + up1 * dr01 + up2 * dr02
            ang += hh * ((2.0 * r[0, 0] + dr00) * up1 - (2.0 * r[0, 1] + dr01) * up0)
            kahan_add(acc, accc, B_PIVOT_IMPULSE, h * up0)
            kahan_add(acc, accc, B_PIVOT_IMPULSE + 1, h * up1)
            kahan_add(acc, accc, B_PIVOT_IMPULSE + 2, h * up2)
        kahan_add(acc, accc, B_WORK, work)
        kahan_add(acc, accc, B_ANGULAR_IMPULSE_Z, ang)
    kahan_add(acc, accc, B_GRAVITY_IMPULSE + 2, h * P.g * (M + P.Mp + n * P.m))  # weight along +e3
    pc = S.pc
    start = first
    if free and forced:  # the pivot row: its impulse h/2 (f_k + f_k+1) + h u_p in one compensated sum
        commit_node(r, p, rc, pc, f, fnext, fl, fr, X, Y, 0, 0, h * up0, hh, compensated)
        commit_node(r, p, rc, pc, f, fnext, fl, fr, X, Y, 0, 1, h * up1, hh, compensated)
        commit_node(r, p, rc, pc, f, fnext, fl, fr, X, Y, 0, 2, h * up2, hh, compensated)
        start = 1
    for a in range(start, n + 1):
        for i in range(3):
            commit_node(r, p, rc, pc, f, fnext, fl, fr, X, Y, a, i, 0.0, hh, compensated)
    for a in range(first):
        f[a, 0] = fnext[a, 0]
        f[a, 1] = fnext[a, 1]
        f[a, 2] = fnext[a, 2]
    for i in range(3):
        for j in range(3):
            if compensated:
                Rc[i, j] = (R[i, j] - Rn[i, j]) + RF[i, j]
            R[i, j] = Rn[i, j]
    if compensated:
        kahan_add(Pi, S.Pic, 0, dP0)
        kahan_add(Pi, S.Pic, 1, dP1)
        kahan_add(Pi, S.Pic, 2, dP2)
    else:
        Pi[0] += dP0
        Pi[1] += dP1
        Pi[2] += dP2
    return OK
