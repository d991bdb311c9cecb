"""A team's step: K strings from their own pivots to one body (docs/physics.md, "A team: several
strings on one body").

String 0 and the body are a single string's arrays (StateArrays, Work, LGVIParams: the lead scene's)
and run through the single string's stages (kernels/step/lgvi.py, kernels/step/step_shared.py), with the
body's inertia augmented by the other strings' effective end masses
(:data:`~esp_gym.kernels.team.arrays.TeamParams` ``mass``, ``rho_inertial``, ``jeff``, and string 0's factors
``inv0``, ``cp0``, ``w0`` with that mass on its last row). Gravity keeps the body's own mass and
offset (P.M, P.rho).

The other strings 1..K-1 are stacked by rows in :data:`~esp_gym.kernels.team.arrays.TeamArrays`: string j owns
rows ``start[j] .. start[j+1] - 1``, its pivot first and its end, slaved to the body at ``rho[j]``
from string 0's attachment point (body frame), last. A slaved end carries no momentum of its
own: its row of ``p`` stays 0 and its share is in the body's (S.p[N], S.Pi).

With K = 1 every loop below is empty and every addition an exact zero: the step is the single
string's general-path step, bit for bit.
"""
import numpy as np

from ..jit import kernel
from ..layout import B_ANGULAR_IMPULSE_Z, B_GRAVITY_IMPULSE, B_PIVOT_IMPULSE, B_WORK
from ..so3 import cross, unrotated
from ..status import BLOW_UP, NON_FINITE, OK
from ..step.lgvi import end_shift, rigid_increments
from ..step.step_shared import (body_momentum_increment, commit_body, commit_node, commit_string, guarded_forces,
                                held_inputs, input_balances, left_torque, new_positions, next_attitude)
from ..step.string import nodal_forces, string_solve
from ..sums import kahan_add
from .arrays import add_end_loads, pivot_rows
from .switch import settle_team_switches, team_switch_errors

@kernel(forceinline=True)
def end_loads(R, T, A, h, forced):
    """Each string j >= 1 reduced to its end: the solve of its rows before the end,
    X = M_II^-1 (p + h/2 f (+ h/2 u at a free pivot)), its coupling c_j = off X_last (into
    ``A.c``), and the left load l_j = h/2 f_end - c_j on the body. Returns the sum of the l_j
    (spatial) [N s] and their torque (2/h) sum rho_j x R_k^T l_j (body frame) [N m], the
    share of the left torque of (2)."""
    hh = 0.5 * h
    E0 = E1 = E2 = 0.0
    t0 = t1 = t2 = 0.0
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1] - 1
        first = pivot_rows(T, j)
        X = A.X[s:e]
        string_solve(T.inv[s:e], T.cp[s:e], first, A.p[s:e], A.f[s:e], hh, A.force[j, 0, 0], A.force[j, 0, 1],
                     A.force[j, 0, 2], first == 0 and forced, X)
        c0 = c1 = c2 = 0.0
        if e - 1 >= s + first:  # a moving row next to the end
            c0 = T.off[j] * X[e - 1 - s, 0]
            c1 = T.off[j] * X[e - 1 - s, 1]
            c2 = T.off[j] * X[e - 1 - s, 2]
        E0, E1, E2, t0, t1, t2 = add_left_load(A, T, R, j, (c0, c1, c2), A.f[e], hh, (E0, E1, E2, t0, t1, t2))
    return E0, E1, E2, t0 / hh, t1 / hh, t2 / hh


@kernel(inline="always")
def add_left_load(A, T, R, j, c, f_end, hh, sums):
    """String j's coupling momentum ``c`` into ``A.c[j]`` and its left load l = h/2 ``f_end`` - c
    on the body added to ``sums`` (the loads' sum (3) and their torques' sum rho_j x R^T l (3));
    returns the six sums (``hh`` = h/2)."""
    E0, E1, E2, t0, t1, t2 = sums
    A.c[j, 0] = c[0]
    A.c[j, 1] = c[1]
    A.c[j, 2] = c[2]
    l0 = hh * f_end[0] - c[0]
    l1 = hh * f_end[1] - c[1]
    l2 = hh * f_end[2] - c[2]
    m0, m1, m2 = cross(T.rho[j], unrotated(R, (l0, l1, l2)))  # rho_j x R_k^T l
    return E0 + l0, E1 + l1, E2 + l2, t0 + m0, t1 + m1, t2 + m2


@kernel(forceinline=True)
def lead_solve(S, W, P, T, h, up, E, free, forced):
    """String 0's solve of (1) with F_k = I: M'^-1 (p + h/2 f (+ h/2 u_p at a free pivot)) into
    ``W.X``, plus w0 ``E`` (the other strings' left loads on the attachment row)."""
    first = 0 if free else 1
    up0, up1, up2 = up
    string_solve(T.inv0, T.cp0, first, S.p, S.f, 0.5 * h, up0, up1, up2, free and forced, W.X)
    add_end_loads(W.X, T.w0, E, first, T.first.shape[0])


@kernel(forceinline=True)
def other_increments(S, W, T, A, h, forced, compensated):
    """Once Newton has F_k: each string j >= 1's end moves by dr_e = dr_x + R_k (F_k - I) rho_j,
    its other rows by h X - off w_end dr_e; ``A.Y`` gets the increments, ``A.X`` the new positions
    of the rows before the end (r + dr, + the remainders when ``compensated``) and ``A.dr0`` each
    pivot's displacement. Reads string 0's raw attachment increment ``W.Y[N]``, so it runs
    before :func:`new_positions`."""
    n = S.r.shape[0] - 1
    dx0 = W.Y[n, 0]
    dx1 = W.Y[n, 1]
    dx2 = W.Y[n, 2]
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1]
        first = pivot_rows(T, j)
        r = A.r[s:e]  # string j's rows, its end last (local row index `end`)
        rc = A.rc[s:e]
        X = A.X[s:e]
        Y = A.Y[s:e]
        w = T.w_end[s:e]
        end = e - s - 1
        _, _, _, q0, q1, q2 = end_shift(S.R, W.FmI, T.rho[j])
        d0 = dx0 + q0
        d1 = dx1 + q1
        d2 = dx2 + q2
        o = T.off[j]
        if first == 0:  # the free pivot's displacement (its row's increment, before any remainder)
            A.dr0[j, 0] = h * X[0, 0] - o * w[0] * d0
            A.dr0[j, 1] = h * X[0, 1] - o * w[0] * d1
            A.dr0[j, 2] = h * X[0, 2] - o * w[0] * d2
        else:
            A.dr0[j, 0] = 0.0
            A.dr0[j, 1] = 0.0
            A.dr0[j, 2] = 0.0
        for a in range(first):  # a fixed pivot stays where it is
            for i in range(3):
                X[a, i] = r[a, i]
        for a in range(first, end):  # one pass: each row's increment, then its new position
            y0 = h * X[a, 0] - o * w[a] * d0
            y1 = h * X[a, 1] - o * w[a] * d1
            y2 = h * X[a, 2] - o * w[a] * d2
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
        Y[end, 0] = d0
        Y[end, 1] = d1
        Y[end, 2] = d2


@kernel(forceinline=True)
def other_forces(S, W, P, T, A):
    """The other strings' ends placed on the body at x_{k+1} + R_{k+1} rho_j (``W.Rn`` holds
    R_{k+1}), their forces at the new positions (string j's constants ``T.kappa[j]``, ``T.u[j]``,
    ``T.m[j]``) into ``A.fn``, and their guards. Returns the status."""
    n = S.r.shape[0] - 1
    Rn = W.Rn
    X = A.X
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1] - 1
        rho = T.rho[j]
        for i in range(3):
            X[e, i] = W.X[n, i] + (Rn[i, 0] * rho[0] + Rn[i, 1] * rho[1] + Rn[i, 2] * rho[2])
        total, longest = nodal_forces(X[s:e + 1], T.kappa[j], T.u[j], T.m[j], 0.0, T.Mp[j], P.g, T.slack[j],
                                      A.fn[s:e + 1])
        if not np.isfinite(total):
            return NON_FINITE
        if longest > T.max_len2[j]:
            return BLOW_UP
    return OK


@kernel(forceinline=True)
def right_loads(W, T, A, h, fl, fr):
    """The other strings' right loads on the body, h/2 fr_end + c_j, as ``(their torque (2/h) sum
    rho_j x R_{k+1}^T (h/2 fr_end + c_j) (body frame) [N m], the attachment row's impulse
    h/2 sum (fl_end + fr_end) [N s])``: ``fl``, ``fr`` the forces whose mean is a string's
    impulse (A.f, A.fn; a reeling string's with its convective terms: kernels/team/winch.py)."""
    hh = 0.5 * h
    Rn = W.Rn
    t0 = t1 = t2 = 0.0
    i0 = i1 = i2 = 0.0
    for j in range(T.first.shape[0]):
        e = T.start[j + 1] - 1
        l0 = hh * fr[e, 0] + A.c[j, 0]
        l1 = hh * fr[e, 1] + A.c[j, 1]
        l2 = hh * fr[e, 2] + A.c[j, 2]
        m0, m1, m2 = cross(T.rho[j], unrotated(Rn, (l0, l1, l2)))  # rho_j x R_{k+1}^T l
        t0 += m0
        t1 += m1
        t2 += m2
        i0 += hh * (fl[e, 0] + fr[e, 0])
        i1 += hh * (fl[e, 1] + fr[e, 1])
        i2 += hh * (fl[e, 2] + fr[e, 2])
    return t0 / hh, t1 / hh, t2 / hh, i0, i1, i2


@kernel(forceinline=True)
def other_balances(S, P, T, A, h, forced):
    """The other strings' shares of the input balances: their weight's impulse along +e3, and
    with ``forced`` their free pivots' work u_bar . dr_0, impulse h u_bar and angular impulse
    about e3 h/2 ((2 r_0 + dr_0) x u_bar + 1/2 dr_0 x (u_{k+1} - u_k)) . e3 [N s, J, N m s]
    (u_bar = (u_k + u_{k+1})/2; the string 0's terms of step_shared.py's ``input_balances``)."""
    acc = S.acc
    accc = S.accc
    hh = 0.5 * h
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1] - 1
        kahan_add(acc, accc, B_GRAVITY_IMPULSE + 2, h * P.g * (T.Mp[j] + (e - s) * T.m[j]))
        if forced and T.first[j] == 0:
            ul = A.force[j, 0]
            ur = A.force[j, 1]
            u0 = 0.5 * (ul[0] + ur[0])  # the mean force: u itself, bit for bit, when held
            u1 = 0.5 * (ul[1] + ur[1])
            u2 = 0.5 * (ul[2] + ur[2])
            d0 = A.dr0[j, 0]
            d1 = A.dr0[j, 1]
            kahan_add(acc, accc, B_WORK, u0 * d0 + u1 * d1 + u2 * A.dr0[j, 2])
            turning = 0.5 * (d0 * (ur[1] - ul[1]) - d1 * (ur[0] - ul[0]))
            kahan_add(acc, accc, B_ANGULAR_IMPULSE_Z,
                      hh * (((2.0 * A.r[s, 0] + d0) * u1 - (2.0 * A.r[s, 1] + d1) * u0) + turning))
            kahan_add(acc, accc, B_PIVOT_IMPULSE, h * u0)
            kahan_add(acc, accc, B_PIVOT_IMPULSE + 1, h * u1)
            kahan_add(acc, accc, B_PIVOT_IMPULSE + 2, h * u2)


@kernel(forceinline=True)
def commit_others(T, A, h, forced, compensated, fl, fr):
    """Write the other strings' new positions and momenta (:func:`commit_node`, the impulse
    h/2 (fl + fr): A.f and A.fn, or a reeling string's with its convective terms; a free pivot's
    row with its impulse h/2 (u_k + u_{k+1}), h u bit for bit when held), their ends' positions
    (no momentum of their own), and f <- fn."""
    hh = 0.5 * h
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1]
        first = pivot_rows(T, j)
        r = A.r[s:e]  # string j's rows, its end last (local row index `end`)
        p = A.p[s:e]
        rc = A.rc[s:e]
        pc = A.pc[s:e]
        f = A.f[s:e]
        fn = A.fn[s:e]
        left = fl[s:e]
        right = fr[s:e]
        X = A.X[s:e]
        Y = A.Y[s:e]
        end = e - s - 1
        for a in range(first, end):
            for i in range(3):
                impulse = 0.0
                if forced and a == 0:
                    impulse = hh * (A.force[j, 0, i] + A.force[j, 1, i])
                commit_node(r, p, rc, pc, f, fn, left, right, X, Y, a, i, impulse, hh, compensated)
        for i in range(3):
            for a in range(first):
                f[a, i] = fn[a, i]
            r[end, i] = X[end, i]
            rc[end, i] = 0.0
            f[end, i] = fn[end, i]


# A stage of its own (compiled once, inlined by LLVM: kernels/jit.py), not spliced into
# team_substep's IR: spliced, team_substep alone took 13 s of the team's first compile.
@kernel(forceinline=True)
def commit_team_step(S, W, P, balance_params, T, A, h, held, c, left, torque, e, dr0, lead_force, other_forces,
                     flags):
    """The end of a team's step (:func:`team_substep`, kernels/team/winch.py's
    ``team_winch_substep``): the other strings' right loads, the body's right torque
    tau_g(R_{k+1}) + tau^+ and Pi_{k+1}, the input balances and the write-back of string 0, the
    other strings and the body. ``c`` the Cayley vector, ``left`` string 0's left pivot load,
    ``torque`` the body's left torque (with the ends' loads), ``e`` = R_k^T dr_{N+1}, ``dr0`` the
    pivot's displacement, ``held`` :func:`~.step_shared.held_inputs`'s; ``balance_params`` the
    parameters of string 0's input balances (``P``, or at the reeled length), ``lead_force``
    string 0's force at the start (its impulse's left half), ``other_forces`` the other strings'
    (left, right) forces; ``flags`` = (free, forced, coupled, compensated). Returns the status
    (the state untouched unless OK)."""
    free, forced, coupled, compensated = flags
    _, _, _, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held
    b0, b1, b2, i0, i1, i2 = right_loads(W, T, A, h, other_forces[0], other_forces[1])
    m0, m1, m2, n0, n1, n2 = left_torque(W.Rn, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    dP = body_momentum_increment(S.Pi, W.FmI, T.mass, T.rho_inertial, h, torque, (n0 + b0, n1 + b1, n2 + b2), e,
                                 forced, coupled)
    if not np.isfinite(dP[0] + dP[1] + dP[2]):
        return NON_FINITE
    input_balances(S, balance_params, S.R, W.Rn, h, c, left, (m0, m1, m2), held, dr0, free, forced)
    other_balances(S, P, T, A, h, forced)
    commit_string(S, W, h, held, lead_force, W.fn, free, forced, compensated, (i0, i1, i2))
    commit_others(T, A, h, forced, compensated, other_forces[0], other_forces[1])
    commit_body(S, W.Rn, W.RF, dP, compensated)
    return OK


@kernel(forceinline=True)
def team_substep(S, W, P, T, A, inputs, h, free, forced, coupled, compensated):
    """Advance a team by one step of length ``h``, in place (docs/physics.md, "A team: several
    strings on one body"): string 0 and the body as :func:`~.lgvi.lgvi_substep` with the body's
    inertia augmented (``T``), the other strings (``A``) reduced to their ends before Newton and
    back-substituted after it. ``inputs`` (:data:`~.layout.INPUTS`) push string 0's pivot and
    turn the body; ``A.force`` pushes the other pivots (its pair, as string 0's). Every slack string settles its
    switches (kernels/team/switch.py) as ``lgvi_substep`` does. Flags as in ``lgvi_substep``; a
    failing step leaves the state untouched. Returns ``(status,
    newton_iterations)``."""
    R = S.R
    first = 0 if free else 1
    held = held_inputs(inputs, forced)
    up0, up1, up2, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held
    l0, l1, l2, t0, t1, t2 = left_torque(R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    E0, E1, E2, a0, a1, a2 = end_loads(R, T, A, h, forced)
    t0 = t0 + a0
    t1 = t1 + a1
    t2 = t2 + a2
    lead_solve(S, W, P, T, h, (up0, up1, up2), (E0, E1, E2), free, forced)
    c0, c1, c2, e0, e1, e2, dr00, dr01, dr02, iters, status = rigid_increments(
        S, W, P, h, T.mass, T.rho_inertial, T.jeff, T.w0, t0, t1, t2, free, forced, coupled)
    if status != OK:
        return status, iters
    other_increments(S, W, T, A, h, forced, compensated)
    new_positions(S, W, first, compensated)
    status = guarded_forces(W.X, P, W.fn)
    if status != OK:
        return status, iters
    next_attitude(S.R, S.Rc, W.FmI, W.RF, W.Rn, compensated)
    status = other_forces(S, W, P, T, A)
    if status != OK:
        return status, iters
    unsettled = team_switch_errors(S, W, P, T, A, None)  # the slack switches (kernels/team/switch.py)
    status = commit_team_step(S, W, P, P, T, A, h, held, (c0, c1, c2), (l0, l1, l2), (t0, t1, t2), (e0, e1, e2),
                              (dr00, dr01, dr02), S.f, (A.f, A.fn), (free, forced, coupled, compensated))
    if status != OK:
        return status, iters
    if unsettled > 0:
        settle_team_switches(S, W, P, T, A, h, S.p, A.p, (S.Pi[0], S.Pi[1], S.Pi[2]), P.off)
    return OK, iters


@kernel(entry=True)
def team_forces(S, P, T, A):
    """The forces at the state's positions: string 0's into ``S.f``, the others' into ``A.f``
    (a state just set)."""
    nodal_forces(S.r, P.kappa, P.u, P.m, P.M, P.Mp, P.g, P.slack, S.f)
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1]
        nodal_forces(A.r[s:e], T.kappa[j], T.u[j], T.m[j], 0.0, T.Mp[j], P.g, T.slack[j], A.f[s:e])
