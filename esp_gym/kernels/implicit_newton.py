"""Newton's method for the implicit string's step (kernels/implicit.py; docs/physics.md, "The
implicit string"): the string's increments y and the body's Cayley vector c together.

Each iteration runs four stages: :func:`string_elimination` (the residual and the forward
elimination of the string's block-tridiagonal Jacobian, pivot -> attachment node),
:func:`attachment_solve` (the 6x6 system of the attachment node and the body, by its Schur
complement), :func:`back_substitution` (the string's corrections) and :func:`take_correction`;
:func:`implicit_newton` drives them with a line search on the merit and the convergence test.
O(N) per iteration. The slack law's kink makes the residual only semismooth: a step that does
not reduce the residual (rows in metres) is halved, at most ``MAX_HALVINGS`` times per step,
while the step is not yet in the round-off range.
"""
import numpy as np

from .implicit_terms import body_coupling, coupling_block, element_block, hold_taut, inverse3, release_slack
from .jit import kernel
from .status import NEWTON_FAILED, NON_FINITE
from .so3 import cayley_jacobian, cayley_residual, solve3

#: Corrections that stop shrinking below this (relative to the increments) are round-off: the
#: iteration has converged as far as float64 allows.
ROUNDOFF_TOL = 1e-12
#: ... or below this many units in the last place of the positions (the new lengths |r_{a+1} -
#: r_a| carry that much rounding, which Newton cannot remove; at the slack kink it is all there is).
ROUNDOFF_ULPS = 64.0
#: Halvings of one Newton step the line search may take (per step).
MAX_HALVINGS = 8
#: A correction below this (relative to the increments) is in the quadratic, round-off
#: dominated range, where the residual no longer measures progress: no line search there.
LINE_SEARCH_FLOOR = 1e-8


@kernel(inline="always")
def string_elimination(S, W, P, h, mass, lengths, up, q, flags):
    """The string's residual -G at the iterate ``W.Y`` and the forward elimination of its
    Jacobian, pivot -> attachment node: E_a (``W.elim``) and z_a (``W.dy``) for a < N. Returns
    the merit (the string's rows, scaled by the mass diagonal) [m^2], the attachment node's
    Schur block S_N (9) and its eliminated residual r_N (3) [kg m].

    The Jacobian's blocks: A_aa = mdiag I + h^2/4 (k_{a-1} + k_a) and A_{a,a+1} = A_{a+1,a} =
    off I - h^2/4 k_a, k_a = kappa' n_k n_{k+1}^T (element a; not symmetric). ``mass`` = (diag,
    lower, upper, rhs): the mass matrix and the residual's constant part while ``reeling``
    (otherwise the diagonal only, off-diagonals P.off, the constant part h p_k + h^2/2 f_g);
    ``lengths`` = (u0, u1) the rest lengths at the two ends; ``up`` the pivot force [N];
    ``q`` = R_k (F - I) rho_c at this iterate (the body's pull on the attachment row) [m];
    ``flags`` = (free, forced, reeling)."""
    r = S.r
    p = S.p
    Y = W.Y
    dy = W.dy
    E = W.elim
    taut = W.taut
    diag, lower, upper, rhs = mass
    u0, u1 = lengths
    up0, up1, up2 = up
    q0, q1, q2 = q
    free, forced, reeling = flags
    n = r.shape[0] - 1
    first = 0 if free else 1
    kappa = P.kappa
    slack = P.slack
    gradient = P.gradient
    off = P.off
    M = P.M
    q4 = 0.25 * h * h
    h2 = 0.5 * h * h
    # gravity forces of the nodes (along +e3): (m/2 + Mp) g, m g, ..., (m/2 + M) g
    g_end0 = (0.5 * P.m + P.Mp) * P.g
    g_mid = P.m * P.g
    g_endn = (0.5 * P.m + M) * P.g
    merit = 0.0
    tp0 = tp1 = tp2 = 0.0  # the element above node a: T n_k, and k
    k00 = k01 = k02 = k10 = k11 = k12 = k20 = k21 = k22 = 0.0
    if not free:
        tp0, tp1, tp2, k00, k01, k02, k10, k11, k12, k20, k21, k22 = element_block(
            r, Y, 0, kappa, u0, u1, slack and taut[0] == 0.0, gradient)
    e00 = e01 = e02 = e10 = e11 = e12 = e20 = e21 = e22 = 0.0  # E_{a-1}
    z0 = z1 = z2 = 0.0  # z_{a-1}
    s00 = s01 = s02 = s10 = s11 = s12 = s20 = s21 = s22 = 0.0
    r0 = r1 = r2 = 0.0
    for a in range(first, n + 1):
        ta0 = ta1 = ta2 = 0.0
        l00 = l01 = l02 = l10 = l11 = l12 = l20 = l21 = l22 = 0.0
        if a < n:
            ta0, ta1, ta2, l00, l01, l02, l10, l11, l12, l20, l21, l22 = element_block(
                r, Y, a, kappa, u0, u1, slack and taut[a] == 0.0, gradient)
        grav = g_mid
        if a == 0:
            grav = g_end0
        elif a == n:
            grav = g_endn
        lo = off  # the mass matrix's row a: A_{a,a-1}, A_{a,a+1}
        hi = off
        if reeling:
            lo = lower[a]
            hi = upper[a]
        my0 = diag[a] * Y[a, 0]
        my1 = diag[a] * Y[a, 1]
        my2 = diag[a] * Y[a, 2]
        if a > 0:
            my0 += lo * Y[a - 1, 0]
            my1 += lo * Y[a - 1, 1]
            my2 += lo * Y[a - 1, 2]
        if a < n:
            my0 += hi * Y[a + 1, 0]
            my1 += hi * Y[a + 1, 1]
            my2 += hi * Y[a + 1, 2]
        # -G_a = h p_a + h^2/2 (f~_a + f_g,a) (+ h^2/2 u_p) - (M_tot y)_a  [- M q at the attachment]
        if reeling:
            r0 = (rhs[a, 0] + h2 * (ta0 - tp0)) - my0
            r1 = (rhs[a, 1] + h2 * (ta1 - tp1)) - my1
            r2 = (rhs[a, 2] + h2 * (ta2 - tp2)) - my2
        else:
            r0 = (h * p[a, 0] + h2 * (ta0 - tp0)) - my0
            r1 = (h * p[a, 1] + h2 * (ta1 - tp1)) - my1
            r2 = (h * p[a, 2] + h2 * ((ta2 - tp2) + grav)) - my2
        if free and forced and a == 0:
            r0 += h2 * up0
            r1 += h2 * up1
            r2 += h2 * up2
        if a == n:
            r0 -= M * q0
            r1 -= M * q1
            r2 -= M * q2
        inv_m = 1.0 / diag[a]
        merit += (r0 * r0 + r1 * r1 + r2 * r2) * inv_m * inv_m
        s00 = diag[a] + q4 * (k00 + l00)
        s01 = q4 * (k01 + l01)
        s02 = q4 * (k02 + l02)
        s10 = q4 * (k10 + l10)
        s11 = diag[a] + q4 * (k11 + l11)
        s12 = q4 * (k12 + l12)
        s20 = q4 * (k20 + l20)
        s21 = q4 * (k21 + l21)
        s22 = diag[a] + q4 * (k22 + l22)
        if a > first:
            # O = A_{a,a-1} = lo I - h^2/4 k_{a-1}: S_a = A_aa - O E_{a-1}, rhs_a -= O z_{a-1}
            o00, o01, o02, o10, o11, o12, o20, o21, o22 = coupling_block(lo, q4, k00, k01, k02, k10, k11, k12,
                                                                         k20, k21, k22)
            s00 -= o00 * e00 + o01 * e10 + o02 * e20
            s01 -= o00 * e01 + o01 * e11 + o02 * e21
            s02 -= o00 * e02 + o01 * e12 + o02 * e22
            s10 -= o10 * e00 + o11 * e10 + o12 * e20
            s11 -= o10 * e01 + o11 * e11 + o12 * e21
            s12 -= o10 * e02 + o11 * e12 + o12 * e22
            s20 -= o20 * e00 + o21 * e10 + o22 * e20
            s21 -= o20 * e01 + o21 * e11 + o22 * e21
            s22 -= o20 * e02 + o21 * e12 + o22 * e22
            r0 -= o00 * z0 + o01 * z1 + o02 * z2
            r1 -= o10 * z0 + o11 * z1 + o12 * z2
            r2 -= o20 * z0 + o21 * z1 + o22 * z2
        if a < n:
            i00, i01, i02, i10, i11, i12, i20, i21, i22 = inverse3(s00, s01, s02, s10, s11, s12, s20, s21, s22)
            # E_a = S_a^-1 A_{a,a+1}, A_{a,a+1} = hi I - h^2/4 k_a; z_a = S_a^-1 rhs_a
            o00, o01, o02, o10, o11, o12, o20, o21, o22 = coupling_block(hi, q4, l00, l01, l02, l10, l11, l12,
                                                                         l20, l21, l22)
            e00 = i00 * o00 + i01 * o10 + i02 * o20
            e01 = i00 * o01 + i01 * o11 + i02 * o21
            e02 = i00 * o02 + i01 * o12 + i02 * o22
            e10 = i10 * o00 + i11 * o10 + i12 * o20
            e11 = i10 * o01 + i11 * o11 + i12 * o21
            e12 = i10 * o02 + i11 * o12 + i12 * o22
            e20 = i20 * o00 + i21 * o10 + i22 * o20
            e21 = i20 * o01 + i21 * o11 + i22 * o21
            e22 = i20 * o02 + i21 * o12 + i22 * o22
            E[a, 0, 0] = e00
            E[a, 0, 1] = e01
            E[a, 0, 2] = e02
            E[a, 1, 0] = e10
            E[a, 1, 1] = e11
            E[a, 1, 2] = e12
            E[a, 2, 0] = e20
            E[a, 2, 1] = e21
            E[a, 2, 2] = e22
            z0 = i00 * r0 + i01 * r1 + i02 * r2
            z1 = i10 * r0 + i11 * r1 + i12 * r2
            z2 = i20 * r0 + i21 * r1 + i22 * r2
            dy[a, 0] = z0
            dy[a, 1] = z1
            dy[a, 2] = z2
        tp0 = ta0
        tp1 = ta1
        tp2 = ta2
        k00 = l00
        k01 = l01
        k02 = l02
        k10 = l10
        k11 = l11
        k12 = l12
        k20 = l20
        k21 = l21
        k22 = l22
    return merit, (s00, s01, s02, s10, s11, s12, s20, s21, s22), (r0, r1, r2)


@kernel(inline="always")
def attachment_solve(W, J, s, rn, b, cy, g, c, ph, gc, coupled):
    """The 6x6 system at the attachment node, [S B; C D] [dy_N; dc] = [r_N; -phi], by the Schur
    complement of S_N (``s``; ``rn`` its eliminated residual): D = g^ + (g . c) I + c g^T - 2 J
    (``W.jac``), Z = S^-1 B, (D - C Z) dc = -phi - C S^-1 r_N. ``b`` = B, ``cy`` = C (the body's
    coupling, :func:`~.implicit_terms.body_coupling`), ``g``, ``c``, ``ph`` = phi and ``gc`` =
    g . c at this iterate. Returns ``(dc, x_N)``: the Cayley vector's correction and the
    attachment node's [m]."""
    s00, s01, s02, s10, s11, s12, s20, s21, s22 = s
    r0, r1, r2 = rn
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = b
    cy00, cy01, cy02, cy10, cy11, cy12, cy20, cy21, cy22 = cy
    i00, i01, i02, i10, i11, i12, i20, i21, i22 = inverse3(s00, s01, s02, s10, s11, s12, s20, s21, s22)
    zn0 = i00 * r0 + i01 * r1 + i02 * r2
    zn1 = i10 * r0 + i11 * r1 + i12 * r2
    zn2 = i20 * r0 + i21 * r1 + i22 * r2
    jac = W.jac
    cayley_jacobian(g[0], g[1], g[2], c[0], c[1], c[2], gc, J, jac)
    f0 = -ph[0]
    f1 = -ph[1]
    f2 = -ph[2]
    z00 = z01 = z02 = z10 = z11 = z12 = z20 = z21 = z22 = 0.0
    if coupled:
        # Z = S^-1 B; D - C Z and -phi - C z_N
        z00 = i00 * b00 + i01 * b10 + i02 * b20
        z01 = i00 * b01 + i01 * b11 + i02 * b21
        z02 = i00 * b02 + i01 * b12 + i02 * b22
        z10 = i10 * b00 + i11 * b10 + i12 * b20
        z11 = i10 * b01 + i11 * b11 + i12 * b21
        z12 = i10 * b02 + i11 * b12 + i12 * b22
        z20 = i20 * b00 + i21 * b10 + i22 * b20
        z21 = i20 * b01 + i21 * b11 + i22 * b21
        z22 = i20 * b02 + i21 * b12 + i22 * b22
        jac[0, 0] -= cy00 * z00 + cy01 * z10 + cy02 * z20
        jac[0, 1] -= cy00 * z01 + cy01 * z11 + cy02 * z21
        jac[0, 2] -= cy00 * z02 + cy01 * z12 + cy02 * z22
        jac[1, 0] -= cy10 * z00 + cy11 * z10 + cy12 * z20
        jac[1, 1] -= cy10 * z01 + cy11 * z11 + cy12 * z21
        jac[1, 2] -= cy10 * z02 + cy11 * z12 + cy12 * z22
        jac[2, 0] -= cy20 * z00 + cy21 * z10 + cy22 * z20
        jac[2, 1] -= cy20 * z01 + cy21 * z11 + cy22 * z21
        jac[2, 2] -= cy20 * z02 + cy21 * z12 + cy22 * z22
        f0 -= cy00 * zn0 + cy01 * zn1 + cy02 * zn2
        f1 -= cy10 * zn0 + cy11 * zn1 + cy12 * zn2
        f2 -= cy20 * zn0 + cy21 * zn1 + cy22 * zn2
    dc0, dc1, dc2 = solve3(jac, f0, f1, f2)
    x0 = zn0 - (z00 * dc0 + z01 * dc1 + z02 * dc2)
    x1 = zn1 - (z10 * dc0 + z11 * dc1 + z12 * dc2)
    x2 = zn2 - (z20 * dc0 + z21 * dc1 + z22 * dc2)
    return (dc0, dc1, dc2), (x0, x1, x2)


@kernel(inline="always")
def back_substitution(W, first, xn):
    """The string's corrections into ``W.X``, from the attachment node's ``xn`` back to the
    first unknown (x_a = z_a - E_a x_{a+1}). Returns their squared norm [m^2]."""
    X = W.X
    dy = W.dy
    E = W.elim
    n = X.shape[0] - 1
    x0, x1, x2 = xn
    X[n, 0] = x0
    X[n, 1] = x1
    X[n, 2] = x2
    dd = x0 * x0 + x1 * x1 + x2 * x2
    for k in range(n - first):
        a = n - 1 - k
        xa0 = dy[a, 0] - (E[a, 0, 0] * x0 + E[a, 0, 1] * x1 + E[a, 0, 2] * x2)
        xa1 = dy[a, 1] - (E[a, 1, 0] * x0 + E[a, 1, 1] * x1 + E[a, 1, 2] * x2)
        xa2 = dy[a, 2] - (E[a, 2, 0] * x0 + E[a, 2, 1] * x1 + E[a, 2, 2] * x2)
        x0 = xa0
        x1 = xa1
        x2 = xa2
        X[a, 0] = x0
        X[a, 1] = x1
        X[a, 2] = x2
        dd += x0 * x0 + x1 * x1 + x2 * x2
    return dd


@kernel(inline="always")
def take_correction(W, first, fraction):
    """``W.Y += fraction W.X`` on the unknown rows (``fraction`` -alpha: the line search's
    halving of the last correction). Returns |Y|^2 after it [m^2]."""
    X = W.X
    Y = W.Y
    yy = 0.0
    for a in range(first, Y.shape[0]):
        Y[a, 0] += fraction * X[a, 0]
        Y[a, 1] += fraction * X[a, 1]
        Y[a, 2] += fraction * X[a, 2]
        yy += Y[a, 0] * Y[a, 0] + Y[a, 1] * Y[a, 1] + Y[a, 2] * Y[a, 2]
    return yy


@kernel(forceinline=True)
def implicit_newton(S, W, P, h, t, up, c, mass, lengths, flags):
    """Solve the implicit string's equations (kernels/implicit.py) for the increments y (into
    ``W.Y``, rows before the first unknown 0) and the Cayley vector c, from the first guess in
    ``W.Y`` and ``c`` (:func:`~.implicit.explicit_start`). ``t`` is the left torque tau_k
    [N m] (:func:`~.step_shared.left_torque`), ``up`` the pivot force [N] (read if free and
    forced). ``mass`` = (diag, lower, upper, rhs) and ``lengths`` = (u0, u1) as in
    :func:`string_elimination`: while ``reeling`` (kernels/winch_implicit.py) the step's mass
    matrix, the residual's constant part h p_k + h^2/2 (f_g + grad T0) - h c C^T r_k and the rest
    lengths at the two ends; otherwise P.mdiag and P.u. ``flags`` = (free, forced, coupled,
    reeling). Returns ``(c0, c1, c2, iterations, status)``: status 0, or NEWTON_FAILED /
    NON_FINITE."""
    free, forced, coupled, reeling = flags
    r = S.r
    R = S.R
    J = P.J
    Y = W.Y
    n = r.shape[0] - 1
    first = 0 if free else 1
    u = P.u
    M = P.M
    c0, c1, c2 = c
    gk0 = h * (S.Pi[0] + 0.5 * h * t[0])  # h Pi_k + h^2/2 tau_k [kg m^2]
    gk1 = h * (S.Pi[1] + 0.5 * h * t[1])
    gk2 = h * (S.Pi[2] + 0.5 * h * t[2])
    body_weight = u / (J[0, 0] + J[1, 1] + J[2, 2])  # body residual [kg m^2] -> [m]
    floor2 = (1e-3 * u) ** 2  # |y| below this counts as 0 in the tolerances [m^2]
    reach = u
    for a in range(n + 1):
        reach = max(reach, abs(r[a, 0]), abs(r[a, 1]), abs(r[a, 2]))
    rounding2 = (ROUNDOFF_ULPS * 2.220446049250313e-16 * reach) ** 2  # the positions' rounding [m^2]
    body_length2 = 4.0 * (J[0, 0] + J[1, 1] + J[2, 2]) / M  # (2 x the body's radius of gyration)^2 [m^2]
    for a in range(first):
        Y[a, 0] = 0.0
        Y[a, 1] = 0.0
        Y[a, 2] = 0.0
    # the elements taut at r_k keep the taut branch (the elastic law) until Newton has converged
    # (docs/physics.md, "The taut-branch start")
    taut = W.taut
    hold_taut(r, taut, lengths[0], P.slack)
    dc0 = dc1 = dc2 = 0.0
    alpha = 1.0
    merit_prev = np.inf
    dd_prev = 0.0
    large_step = True
    halvings = 0
    for it in range(1, P.max_iter + 1):
        # -- the body's equation and its coupling to the attachment node (at this iterate) --
        (g0, g1, g2, q0, q1, q2, b00, b01, b02, b10, b11, b12, b20, b21, b22,
         cy00, cy01, cy02, cy10, cy11, cy12, cy20, cy21, cy22) = body_coupling(
            R, P, Y[n, 0], Y[n, 1], Y[n, 2], c0, c1, c2, gk0, gk1, gk2, coupled)
        merit, s, rn = string_elimination(S, W, P, h, mass, lengths, up, (q0, q1, q2), (free, forced, reeling))
        ph0, ph1, ph2, gc = cayley_residual(g0, g1, g2, c0, c1, c2, J)
        merit += (ph0 * ph0 + ph1 * ph1 + ph2 * ph2) * body_weight * body_weight
        if not np.isfinite(merit):
            return c0, c1, c2, it, NON_FINITE
        # -- line search: a step that did not reduce the residual is halved -----------------
        if merit > merit_prev and large_step and halvings < MAX_HALVINGS:
            halvings += 1
            alpha *= 0.5
            take_correction(W, first, -alpha)
            c0 -= alpha * dc0
            c1 -= alpha * dc1
            c2 -= alpha * dc2
            continue
        merit_prev = merit
        backtracked = halvings > 0
        halvings = 0
        dc, xn = attachment_solve(W, J, s, rn, (b00, b01, b02, b10, b11, b12, b20, b21, b22),
                                  (cy00, cy01, cy02, cy10, cy11, cy12, cy20, cy21, cy22), (g0, g1, g2),
                                  (c0, c1, c2), (ph0, ph1, ph2), gc, coupled)
        dc0, dc1, dc2 = dc
        dd = back_substitution(W, first, xn)
        alpha = 1.0
        yy = take_correction(W, first, 1.0)
        c0 += dc0
        c1 += dc1
        c2 += dc2
        # one norm for both unknowns [m]: a rotation by 2 |c| moves the body's points by about
        # body_length 2 |c|
        tol2 = P.tol * P.tol
        dd += body_length2 * (dc0 * dc0 + dc1 * dc1 + dc2 * dc2)
        scale = yy + body_length2 * (c0 * c0 + c1 * c1 + c2 * c2) + floor2
        large_step = dd > LINE_SEARCH_FLOOR * LINE_SEARCH_FLOOR * scale
        # converged: the correction is below the tolerance, or will be by quadratic convergence
        # (the next correction is about |d|^2 / |d_prev|), or is round-off: it stopped shrinking
        # at the level the residual's rounding allows (about 10-100 eps relative to the
        # increments, or the positions' own rounding)
        converged = (dd <= tol2 * scale
                     or (it > 1 and not backtracked and dd * dd <= tol2 * scale * dd_prev)
                     or (it > 1 and dd >= 0.25 * dd_prev and dd <= ROUNDOFF_TOL * ROUNDOFF_TOL * scale + rounding2))
        if converged:
            # an element held to the taut branch that ended slack takes the slack law's
            # branch from here on: a new equation, so the merit and the rates restart
            if release_slack(r, Y, taut, lengths[1]) == 0:
                return c0, c1, c2, it, 0
            merit_prev = np.inf
            large_step = True
            dd = 0.0
        dd_prev = dd
    if np.isfinite(c0 + c1 + c2):
        return c0, c1, c2, P.max_iter, NEWTON_FAILED
    return c0, c1, c2, P.max_iter, NON_FINITE
