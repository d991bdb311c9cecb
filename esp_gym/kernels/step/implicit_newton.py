"""Newton's method for the implicit string's step (kernels/step/implicit.py; docs/physics.md, "The
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

from ..jit import kernel
from ..so3 import cayley_jacobian, cayley_residual, solve3
from ..status import NEWTON_FAILED, NON_FINITE
from .implicit_terms import body_coupling, coupling_block, element_block, hold_taut, inverse3, release_slack

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


#: A 3x3 block of zeros (9, row-major).
ZERO_BLOCK = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@kernel(inline="always")
def residual_row(p, Y, rhs, a, n, h, diag_a, band, t_below, t_above, grav, reeling):
    """Row a of -G without the pivot's force and the body's pull [kg m]: h p_a + h^2/2 (f~_a +
    f_g,a) - (M y)_a, the mass matrix's row ``diag_a`` and ``band`` = (A_{a,a-1}, A_{a,a+1});
    ``t_below``, ``t_above`` the forces of the elements below and above node a [N], ``grav`` its weight
    [N]. While ``reeling``, ``rhs[a]`` is the constant part (h p_a + h^2/2 f_g,a at the moving
    masses)."""
    lo, hi = band
    h2 = 0.5 * h * h
    my0 = diag_a * Y[a, 0]
    my1 = diag_a * Y[a, 1]
    my2 = diag_a * Y[a, 2]
    if a > 0:
        my0 += lo * Y[a - 1, 0]
        my1 += lo * Y[a - 1, 1]
        my2 += lo * Y[a - 1, 2]
    if a < n:
        my0 += hi * Y[a + 1, 0]
        my1 += hi * Y[a + 1, 1]
        my2 += hi * Y[a + 1, 2]
    if reeling:
        return ((rhs[a, 0] + h2 * (t_below[0] - t_above[0])) - my0, (rhs[a, 1] + h2 * (t_below[1] - t_above[1])) - my1,
                (rhs[a, 2] + h2 * (t_below[2] - t_above[2])) - my2)
    return ((h * p[a, 0] + h2 * (t_below[0] - t_above[0])) - my0, (h * p[a, 1] + h2 * (t_below[1] - t_above[1])) - my1,
            (h * p[a, 2] + h2 * ((t_below[2] - t_above[2]) + grav)) - my2)


@kernel(inline="always")
def diagonal_block(d, q4, k, l):
    """A_aa = d I + h^2/4 (k_{a-1} + k_a) (9, row-major; ``q4`` = h^2/4)."""
    return (d + q4 * (k[0] + l[0]), q4 * (k[1] + l[1]), q4 * (k[2] + l[2]),
            q4 * (k[3] + l[3]), d + q4 * (k[4] + l[4]), q4 * (k[5] + l[5]),
            q4 * (k[6] + l[6]), q4 * (k[7] + l[7]), d + q4 * (k[8] + l[8]))


@kernel(inline="always")
def eliminate_previous(s, r, o, e, z):
    """The previous row eliminated: S_a - O E_{a-1} and rhs_a - O z_{a-1}, O = A_{a,a-1}."""
    return ((s[0] - (o[0] * e[0] + o[1] * e[3] + o[2] * e[6]), s[1] - (o[0] * e[1] + o[1] * e[4] + o[2] * e[7]),
             s[2] - (o[0] * e[2] + o[1] * e[5] + o[2] * e[8]), s[3] - (o[3] * e[0] + o[4] * e[3] + o[5] * e[6]),
             s[4] - (o[3] * e[1] + o[4] * e[4] + o[5] * e[7]), s[5] - (o[3] * e[2] + o[4] * e[5] + o[5] * e[8]),
             s[6] - (o[6] * e[0] + o[7] * e[3] + o[8] * e[6]), s[7] - (o[6] * e[1] + o[7] * e[4] + o[8] * e[7]),
             s[8] - (o[6] * e[2] + o[7] * e[5] + o[8] * e[8])),
            (r[0] - (o[0] * z[0] + o[1] * z[1] + o[2] * z[2]), r[1] - (o[3] * z[0] + o[4] * z[1] + o[5] * z[2]),
             r[2] - (o[6] * z[0] + o[7] * z[1] + o[8] * z[2])))


@kernel(inline="always")
def forward_row(s, r, o):
    """E_a = S_a^-1 O and z_a = S_a^-1 rhs_a, O = A_{a,a+1} (9 and 3 scalars)."""
    i00, i01, i02, i10, i11, i12, i20, i21, i22 = inverse3(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8])
    e = (i00 * o[0] + i01 * o[3] + i02 * o[6], i00 * o[1] + i01 * o[4] + i02 * o[7],
         i00 * o[2] + i01 * o[5] + i02 * o[8], i10 * o[0] + i11 * o[3] + i12 * o[6],
         i10 * o[1] + i11 * o[4] + i12 * o[7], i10 * o[2] + i11 * o[5] + i12 * o[8],
         i20 * o[0] + i21 * o[3] + i22 * o[6], i20 * o[1] + i21 * o[4] + i22 * o[7],
         i20 * o[2] + i21 * o[5] + i22 * o[8])
    z = (i00 * r[0] + i01 * r[1] + i02 * r[2], i10 * r[0] + i11 * r[1] + i12 * r[2],
         i20 * r[0] + i21 * r[1] + i22 * r[2])
    return e, z


@kernel(inline="always")
def off_diagonal_block(off, q4, k):
    """:func:`coupling_block` of the element block ``k`` (9): off I - h^2/4 k."""
    return coupling_block(off, q4, k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8])


@kernel(inline="always")
def store_row(E, dy, a, e, z):
    """E_a into ``E[a]`` (3, 3) and z_a into ``dy[a]``."""
    for i in range(3):
        for j in range(3):
            E[a, i, j] = e[3 * i + j]
        dy[a, i] = z[i]


@kernel(inline="always")
def element_row(r, Y, a, kappa, lengths, slack, gradient):
    """:func:`element_block` of element ``a`` as (its force on node a (3) [N], its k (9) [N/m])."""
    u0, u1 = lengths
    t0, t1, t2, k00, k01, k02, k10, k11, k12, k20, k21, k22 = element_block(r, Y, a, kappa, u0, u1, slack, gradient)
    return (t0, t1, t2), (k00, k01, k02, k10, k11, k12, k20, k21, k22)


@kernel(inline="always")
def node_residual(p, Y, rhs, a, n, h, diag_a, band, t_below, t_above, gravity, M, up, q, flags):
    """Node a's row of the residual -G (:func:`residual_row`, its weight the end nodes' or the
    middle's of ``gravity`` (3,) [N]) with the pivot force ``up`` on a free, forced pivot's node 0
    and the body's pull M ``q`` on the attachment node: ``(r0, r1, r2)`` [kg m]."""
    free, forced, reeling = flags
    grav = gravity[1]
    if a == 0:
        grav = gravity[0]
    elif a == n:
        grav = gravity[2]
    r0, r1, r2 = residual_row(p, Y, rhs, a, n, h, diag_a, band, t_below, t_above, grav, reeling)
    if free and forced and a == 0:
        h2 = 0.5 * h * h
        r0 += h2 * up[0]
        r1 += h2 * up[1]
        r2 += h2 * up[2]
    if a == n:
        r0 -= M * q[0]
        r1 -= M * q[1]
        r2 -= M * q[2]
    return r0, r1, r2


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
    ``flags`` = (free, forced, reeling). Per node: :func:`node_residual`, :func:`diagonal_block`,
    :func:`eliminate_previous`, :func:`forward_row`."""
    r = S.r
    Y = W.Y
    taut = W.taut
    diag, lower, upper, rhs = mass
    free, _, reeling = flags
    n = r.shape[0] - 1
    first = 0 if free else 1
    q4 = 0.25 * h * h
    # gravity forces of the nodes (along +e3): (m/2 + Mp) g, m g, ..., (m/2 + M) g
    gravity = ((0.5 * P.m + P.Mp) * P.g, P.m * P.g, (0.5 * P.m + P.M) * P.g)
    merit = 0.0
    t_above = (0.0, 0.0, 0.0)  # the element above node a: its force on node a - 1, and its k
    k = ZERO_BLOCK
    if not free:
        t_above, k = element_row(r, Y, 0, P.kappa, lengths, P.slack and taut[0] == 0.0, P.gradient)
    e = ZERO_BLOCK  # E_{a-1}
    z = (0.0, 0.0, 0.0)  # z_{a-1}
    s = ZERO_BLOCK
    rr = (0.0, 0.0, 0.0)
    for a in range(first, n + 1):
        t_below = (0.0, 0.0, 0.0)
        l = ZERO_BLOCK
        if a < n:
            t_below, l = element_row(r, Y, a, P.kappa, lengths, P.slack and taut[a] == 0.0, P.gradient)
        band = (lower[a], upper[a]) if reeling else (P.off, P.off)  # the mass matrix's row a
        r0, r1, r2 = node_residual(S.p, Y, rhs, a, n, h, diag[a], band, t_below, t_above, gravity, P.M, up, q,
                                   flags)
        inv_m = 1.0 / diag[a]
        merit += (r0 * r0 + r1 * r1 + r2 * r2) * inv_m * inv_m
        s = diagonal_block(diag[a], q4, k, l)
        rr = (r0, r1, r2)
        if a > first:
            s, rr = eliminate_previous(s, rr, off_diagonal_block(band[0], q4, k), e, z)
        if a < n:
            e, z = forward_row(s, rr, off_diagonal_block(band[1], q4, l))
            store_row(W.elim, W.dy, a, e, z)
        t_above = t_below
        k = l
    return merit, s, rr


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


@kernel(inline="always")
def newton_scales(r, J, u, M):
    """:func:`implicit_newton`'s scales: ``(the body residual's weight [m / (kg m^2)], the
    increment below which |y| counts as 0 [m^2], the positions' rounding [m^2], (2 x the body's
    radius of gyration)^2 [m^2])``, from the nodes ``r``, the body's J and mass M, the rest length u."""
    body_weight = u / (J[0, 0] + J[1, 1] + J[2, 2])  # body residual [kg m^2] -> [m]
    floor2 = (1e-3 * u) ** 2
    reach = u
    for a in range(r.shape[0]):
        reach = max(reach, abs(r[a, 0]), abs(r[a, 1]), abs(r[a, 2]))
    rounding2 = (ROUNDOFF_ULPS * 2.220446049250313e-16 * reach) ** 2
    body_length2 = 4.0 * (J[0, 0] + J[1, 1] + J[2, 2]) / M
    return body_weight, floor2, rounding2, body_length2


@kernel(forceinline=True)
def newton_start(S, W, P, h, t, first, lengths):
    """Before :func:`implicit_newton`'s iterations: the rows before the first unknown of ``W.Y``
    zeroed, the elements taut at r_k held to the taut branch (the elastic law) until Newton has
    converged (docs/physics.md, "The taut-branch start"). Returns ``(h Pi_k + h^2/2 tau_k (3)
    [kg m^2], then :func:`newton_scales`)``."""
    Y = W.Y
    gk = (h * (S.Pi[0] + 0.5 * h * t[0]), h * (S.Pi[1] + 0.5 * h * t[1]), h * (S.Pi[2] + 0.5 * h * t[2]))
    for a in range(first):
        Y[a, 0] = 0.0
        Y[a, 1] = 0.0
        Y[a, 2] = 0.0
    hold_taut(S.r, W.taut, lengths[0], P.slack)
    return (gk,) + newton_scales(S.r, P.J, P.u, P.M)


@kernel(forceinline=True)
def newton_residual(S, W, P, h, mass, lengths, up, c, gk, flags, body_weight):
    """The residual at the iterate (``W.Y``, ``c``): the body's equation and its coupling to the
    attachment node (:func:`~.implicit_terms.body_coupling`), the string's rows eliminated
    (:func:`string_elimination`) and the Cayley residual phi. Returns ``(the merit [m^2], S_N, r_N,
    the coupling (g, q, B, C: 24), phi (3), g . c)``."""
    free, forced, coupled, reeling = flags
    Y = W.Y
    n = S.r.shape[0] - 1
    coupling = body_coupling(S.R, P, Y[n, 0], Y[n, 1], Y[n, 2], c[0], c[1], c[2], gk[0], gk[1], gk[2], coupled)
    merit, s, rn = string_elimination(S, W, P, h, mass, lengths, up, coupling[3:6], (free, forced, reeling))
    ph0, ph1, ph2, gc = cayley_residual(coupling[0], coupling[1], coupling[2], c[0], c[1], c[2], P.J)
    merit += (ph0 * ph0 + ph1 * ph1 + ph2 * ph2) * body_weight * body_weight
    return merit, s, rn, coupling, (ph0, ph1, ph2), gc


@kernel(inline="always")
def take_back(W, first, alpha, c, dc):
    """Half of the last correction taken back (the line search's halving to ``alpha``): y -= alpha
    dy in ``W``, c -= alpha dc; returns c."""
    take_correction(W, first, -alpha)
    return c[0] - alpha * dc[0], c[1] - alpha * dc[1], c[2] - alpha * dc[2]


@kernel(forceinline=True)
def newton_correction(W, J, first, s, rn, coupling, c, ph, gc, coupled, body_length2, floor2):
    """One Newton correction taken whole: the attachment node's 6x6 system (:func:`attachment_solve`;
    ``coupling`` = (B, C, g) of :func:`~.implicit_terms.body_coupling`), the back substitution,
    y += dy in ``W`` and c += dc. Returns ``(c (3), dc (3), the correction's squared size, the
    iterate's)`` [m^2], one norm for both unknowns: a rotation by 2 |c| moves the body's points by
    about body_length 2 |c|."""
    b, cy, g = coupling
    dc, xn = attachment_solve(W, J, s, rn, b, cy, g, c, ph, gc, coupled)
    dc0, dc1, dc2 = dc
    dd = back_substitution(W, first, xn)
    yy = take_correction(W, first, 1.0)
    c0 = c[0] + dc0
    c1 = c[1] + dc1
    c2 = c[2] + dc2
    dd += body_length2 * (dc0 * dc0 + dc1 * dc1 + dc2 * dc2)
    scale = yy + body_length2 * (c0 * c0 + c1 * c1 + c2 * c2) + floor2
    return c0, c1, c2, dc0, dc1, dc2, dd, scale


@kernel(inline="always")
def newton_converged(it, dd, dd_prev, scale, tol2, rounding2, backtracked):
    """Whether Newton's iteration ``it`` converged, its squared correction ``dd`` [m^2] (the last's
    ``dd_prev``) against the tolerance ``tol2`` x ``scale``: the correction is below the tolerance,
    or will be by quadratic convergence (the next correction is about |d|^2 / |d_prev|), or is
    round-off: it stopped shrinking at the level the residual's rounding allows (about 10-100 eps
    relative to the increments, or the positions' own rounding ``rounding2``)."""
    return (dd <= tol2 * scale
            or (it > 1 and not backtracked and dd * dd <= tol2 * scale * dd_prev)
            or (it > 1 and dd >= 0.25 * dd_prev and dd <= ROUNDOFF_TOL * ROUNDOFF_TOL * scale + rounding2))


@kernel(forceinline=True)
def implicit_newton(S, W, P, h, t, up, c, mass, lengths, flags):
    """Solve the implicit string's equations (kernels/step/implicit.py) for the increments y (into
    ``W.Y``, rows before the first unknown 0) and the Cayley vector c, from the first guess in
    ``W.Y`` and ``c`` (:func:`~.implicit.explicit_start`). ``t`` is the left torque tau_k
    [N m] (:func:`~.step_shared.left_torque`), ``up`` the pivot force [N] (read if free and
    forced). ``mass`` = (diag, lower, upper, rhs) and ``lengths`` = (u0, u1) as in
    :func:`string_elimination`: while ``reeling`` (kernels/step/winch_implicit.py) the step's mass
    matrix, the residual's constant part h p_k + h^2/2 (f_g + grad T0) - h c C^T r_k and the rest
    lengths at the two ends; otherwise P.mdiag and P.u. ``flags`` = (free, forced, coupled,
    reeling). Returns ``(c0, c1, c2, iterations, status)``: status 0, or NEWTON_FAILED /
    NON_FINITE."""
    free, forced, coupled, reeling = flags
    first = 0 if free else 1
    c0, c1, c2 = c
    gk, body_weight, floor2, rounding2, body_length2 = newton_start(S, W, P, h, t, first, lengths)
    dc0 = dc1 = dc2 = 0.0
    alpha = 1.0
    merit_prev = np.inf
    dd_prev = 0.0
    large_step = True
    halvings = 0
    for it in range(1, P.max_iter + 1):
        merit, s, rn, coupling, ph, gc = newton_residual(S, W, P, h, mass, lengths, up, (c0, c1, c2), gk, flags,
                                                         body_weight)
        if not np.isfinite(merit):
            return c0, c1, c2, it, NON_FINITE
        # -- line search: a step that did not reduce the residual is halved -----------------
        if merit > merit_prev and large_step and halvings < MAX_HALVINGS:
            halvings += 1
            alpha *= 0.5
            c0, c1, c2 = take_back(W, first, alpha, (c0, c1, c2), (dc0, dc1, dc2))
            continue
        merit_prev = merit
        backtracked = halvings > 0
        halvings = 0
        c0, c1, c2, dc0, dc1, dc2, dd, scale = newton_correction(
            W, P.J, first, s, rn, (coupling[6:15], coupling[15:24], coupling[0:3]), (c0, c1, c2), ph, gc, coupled,
            body_length2, floor2)
        alpha = 1.0
        tol2 = P.tol * P.tol
        large_step = dd > LINE_SEARCH_FLOOR * LINE_SEARCH_FLOOR * scale
        if newton_converged(it, dd, dd_prev, scale, tol2, rounding2, backtracked):
            # an element held to the taut branch that ended slack takes the slack law's
            # branch from here on: a new equation, so the merit and the rates restart
            if release_slack(S.r, W.Y, W.taut, lengths[1]) == 0:
                return c0, c1, c2, it, 0
            merit_prev = np.inf
            large_step = True
            dd = 0.0
        dd_prev = dd
    if np.isfinite(c0 + c1 + c2):
        return c0, c1, c2, P.max_iter, NEWTON_FAILED
    return c0, c1, c2, P.max_iter, NON_FINITE
