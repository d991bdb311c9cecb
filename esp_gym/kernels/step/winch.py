"""The winch: the LGVI step while the string's unstretched length l(t) changes at the reel speed
v = dl/dt (docs/physics.md, "The winch").

The nodes stay at fixed fractions a/N of the unstretched length (a uniform re-parametrisation),
so material flows through every node. Per element e (nodes e, e+1; k = N - e elements from e to
the load, inclusive), with c = mu v / N and theta = mu v^2 / (N l), the string's kinetic energy
gains a term linear and a term free of the node velocities:

    T1_e = c x_e . (alpha_e rdot_e + beta_e rdot_{e+1}),      T0_e = theta gamma_e |x_e|^2 / 2,

and its mass, rest length and stiffness follow l: m = mu l / N, u = l / N, kappa = EA / u. With
C = D^T G (D the element differences, G[e, e] = alpha_e, G[e, e+1] = beta_e), the step from
(r_k, p_k) with l_k -> l_{k+1} = l_k + h v solves (per coordinate, tridiagonal, not symmetric)

    (Mbar - (h c / 2)(C - C^T)) dr + M e_N R_k (F_k - I) rho_c = h (p_k + h/2 f~_k - c C^T r_k)   (1w)
    p_{k+1} = p_k + h/2 (f~_k + f~_{k+1}) + c C dr                                                (3w)

with Mbar the mass matrix at the mean length and f~ = f + grad T0 the forces at each end's length.
The body's equations (2), (4) are unchanged; the Schur complement takes this step's matrix.
With v = 0 this is the fixed-length step at length l.

The energy reported while reeling is the Hamiltonian H = T2 - T0 + V of this time-dependent
Lagrangian (T2 the usual kinetic energy of the nodes' motion), with p = M(l) rdot + c C^T r; the
winch's work is the integral of dH/dt = (dH/dl) v along the steps plus H's jump at fixed (q, p)
where the reel speed changes: the midpoint rule for the explicit string, per step for the implicit
one (:func:`length_shift`). The loops that reel are kernels/step/loops.py's;
the implicit string's step kernels/step/winch_implicit.py's.
"""
import numpy as np

from ..jit import kernel
from .diagnostics import diagnostics, kinetic_energies, node_velocities
from ..layout import (B_GRAVITY_IMPULSE, D_ENERGY, D_KINETIC_STRING, D_LINEAR_MOMENTUM, D_PI3, WN_EA, WN_END_SHARE,
                      WN_LENGTH, WN_MASS_PER_LENGTH, WN_MAX_STRETCH, WN_OFF_SHARE, LGVIParams, StateArrays)
from ..status import OK
from ..sums import kahan_add
from .lgvi import rigid_increments
from .step_shared import commit_step, held_inputs, left_torque, new_positions
from .string import nodal_forces
from .switch import settle_switches, switch_errors


def convective_weights(elements: int, consistent: bool) -> np.ndarray:
    """``(N, 3)``: per element alpha, beta, gamma of T1 and T0 (docs/physics.md, "The winch"):
    the integrals over the element (zeta in [0, 1]) of (1 - zeta)(k - zeta), zeta (k - zeta) and
    (k - zeta)^2, k = N - e; exact for the consistent mass, the trapezoid rule for the lumped one
    (as its kinetic energy is)."""
    k = elements - np.arange(elements, dtype=np.float64)
    if consistent:
        return np.column_stack([k / 2 - 1 / 6, k / 2 - 1 / 3, k * k - k + 1 / 3])
    return np.column_stack([k / 2, (k - 1) / 2, (k * k + (k - 1) ** 2) / 2])


@kernel(inline="always")
def add_convective_forces(r, coef, theta, out, first):
    """``out += grad T0`` on rows ``first..N`` (T0 = theta/2 sum gamma_e |x_e|^2): the convective
    kinetic energy pulls each element's nodes apart [N]."""
    n = r.shape[0] - 1
    for e in range(n):
        k = theta * coef[e, 2]
        for i in range(3):
            g = k * (r[e + 1, i] - r[e, i])
            if e >= first:
                out[e, i] -= g
            out[e + 1, i] += g


@kernel(inline="always")
def convective_energy(r, coef, theta):
    """T0 = theta/2 sum_e gamma_e |x_e|^2 [J]."""
    total = 0.0
    for e in range(r.shape[0] - 1):
        x0 = r[e + 1, 0] - r[e, 0]
        x1 = r[e + 1, 1] - r[e, 1]
        x2 = r[e + 1, 2] - r[e, 2]
        total += coef[e, 2] * (x0 * x0 + x1 * x1 + x2 * x2)
    return 0.5 * theta * total


@kernel(inline="always")
def convective_momentum(r, coef, a, i):
    """(C^T r)_a along coordinate i: alpha_a x_a + beta_{a-1} x_{a-1} [m]."""
    n = r.shape[0] - 1
    s = 0.0
    if a < n:
        s += coef[a, 0] * (r[a + 1, i] - r[a, i])
    if a > 0:
        s += coef[a - 1, 1] * (r[a, i] - r[a - 1, i])
    return s


@kernel(inline="always")
def convective_impulse(dr, coef, a, i):
    """(C dr)_a along coordinate i: alpha_{a-1} dr_{a-1} + (beta_{a-1} - alpha_a) dr_a - beta_a dr_{a+1}."""
    n = dr.shape[0] - 1
    s = 0.0
    if a > 0:
        s += coef[a - 1, 0] * dr[a - 1, i] + coef[a - 1, 1] * dr[a, i]
    if a < n:
        s -= coef[a, 0] * dr[a, i] + coef[a, 1] * dr[a + 1, i]
    return s


@kernel(inline="always")
def add_convective_impulse(X, dr, coef, theta1, c, h, fl, first):
    """``fl += grad T0 at (X, l1) + (2/h) c C dr`` on rows ``first..N``: the convective share of
    a reeling step's impulse h/2 (f~_k + f~_{k+1}) + c C dr of (3w), ``theta1`` = mu v^2 / (N l1),
    ``X`` the new positions, ``dr`` the increments [N]."""
    n = X.shape[0] - 1
    add_convective_forces(X, coef, theta1, fl, first)
    q = 2.0 * c / h
    for a in range(first, n + 1):
        for i in range(3):
            fl[a, i] += q * convective_impulse(dr, coef, a, i)


@kernel(inline="always")
def factor_string(m, skew, end_share, off_share, coef, first, n, pivot_mass, end_mass, lower, upper, diag, inv, cp,
                  w):
    """Thomas factors of one string's step matrix, the mass matrix at element mass ``m`` [kg] plus
    the skew part ``skew`` (C - C^T) ((1w); ``skew = 0``: the symmetric mass matrix), on rows
    ``first..n``, row 0 carrying ``pivot_mass`` and row n ``end_mass`` [kg] besides the elements'
    shares; its sub- and super-diagonals into ``lower``, ``upper``, its ``diag``onal, and its
    last column ``w`` = A^-1 e_n. A string with its body (``end_mass`` the body's mass), or a
    team's string block before its end (``n`` the row before the end, ``end_mass`` an element's
    share: an interior row; kernels/team/winch.py)."""
    end = end_share * m
    off = off_share * m
    prev = 0.0
    for a in range(first, n + 1):
        d = 2.0 * end
        if a == n:
            d = end + end_mass
        if a == 0:
            d = end + pivot_mass
        lo = 0.0
        if a > first:
            lo = off - skew * (coef[a - 1, 0] + coef[a - 1, 1])
        up = off  # row n: kernels/step/string.py's symmetric sweeps read cp_n = off inv_n
        if a < coef.shape[0]:
            up = off + skew * (coef[a, 0] + coef[a, 1])
        lower[a] = lo
        upper[a] = up
        diag[a] = d
        inv[a] = 1.0 / (d - lo * prev)
        cp[a] = up * inv[a]
        prev = cp[a]
    w[n] = inv[n]
    for k in range(n - first):
        a = n - 1 - k
        w[a] = -cp[a] * w[a + 1]


@kernel(inline="always")
def factor_tridiagonal(P, WA, m, skew, first, n, inv, cp, w, jeff, lower, upper, diag):
    """:func:`factor_string` of the single string with its load (row N carries P.M), and
    ``jeff`` = J + M^2 w_N rho^ rho^ of its Schur complement. Every output is a parameter:
    written as ``WA.diag[a]`` here, the diagonal stayed zero in the batched entry point (numba
    0.68.1, parallel=True, this function inlined in the prange body), while the single
    environment's was right."""
    st = WA.state
    factor_string(m, skew, st[WN_END_SHARE], st[WN_OFF_SHARE], WA.coef, first, n, P.Mp, P.M, lower, upper, diag,
                  inv, cp, w)
    body_schur(jeff, P.J, P.M, P.rho, inv[n])


@kernel(inline="always")
def body_schur(jeff, J, M, rho, s):
    """``jeff`` = J + M^2 s rho^ rho^ (3, 3) [kg m^2]: the body's inertia about the attachment
    point after the Schur complement over the string, s = (A^-1)_{N,N} of the step's matrix."""
    rr = rho[0] * rho[0] + rho[1] * rho[1] + rho[2] * rho[2]
    for i in range(3):
        for j in range(3):
            jeff[i, j] = J[i, j] + M * M * s * (rho[i] * rho[j] - (rr if i == j else 0.0))


@kernel(inline="always")
def length_params(P, WA, length, m_mean, first, n, diagnostic):
    """The constants at unstretched length ``length`` (LGVIParams: m, kappa, u, the guard) with
    the Thomas factors of the mass matrix at element mass ``m_mean``: the symmetric one (into the
    ``d*`` arrays, ``diagnostic``) or the step's (:func:`factor_tridiagonal` is called by the
    step itself; here its arrays are only referenced)."""
    st = WA.state
    u = length / n
    m = st[WN_MASS_PER_LENGTH] * u
    if diagnostic:
        factor_tridiagonal(P, WA, m_mean, 0.0, first, n, WA.dinv, WA.dcp, WA.dw, WA.djeff, WA.lower, WA.upper,
                           WA.diag)
        inv, cp, w, jeff = WA.dinv, WA.dcp, WA.dw, WA.djeff
    else:
        inv, cp, w, jeff = WA.inv, WA.cp, WA.w, WA.jeff
    guard = st[WN_MAX_STRETCH] * u
    return LGVIParams(P.h, m, st[WN_EA] / u, u, P.g, P.M, P.Mp, P.rho, P.J, P.Jd, jeff, inv, cp,
                      st[WN_OFF_SHARE] * m, w, P.first, P.slack, P.tol, P.max_iter, P.gammas, guard * guard,
                      P.compensated, P.mdiag, P.settle, P.gradient, P.damping, P.turn_mass)


@kernel(inline="always")
def convective_solve(p, r, fl, coef, c, hh, lower, inv, cp, up, push_pivot, first, last, X):
    """X = A^-1 B on rows ``first..last`` of one string (``last`` its end, or the row before a
    team's slaved end), B = p + h/2 f~ - c C^T r (+ h/2 u_p on a pushed free pivot, ``up``),
    with the step's factors (``lower``, ``inv``, ``cp``) and f~ in ``fl``; three columns at once.
    ``r`` holds the whole string (C^T r on row ``last`` reads the row after it)."""
    up0, up1, up2 = up
    y0 = y1 = y2 = 0.0
    for a in range(first, last + 1):
        b0 = p[a, 0] + hh * fl[a, 0] - c * convective_momentum(r, coef, a, 0)
        b1 = p[a, 1] + hh * fl[a, 1] - c * convective_momentum(r, coef, a, 1)
        b2 = p[a, 2] + hh * fl[a, 2] - c * convective_momentum(r, coef, a, 2)
        if push_pivot and a == 0:
            b0 += hh * up0
            b1 += hh * up1
            b2 += hh * up2
        y0 = (b0 - lower[a] * y0) * inv[a]
        y1 = (b1 - lower[a] * y1) * inv[a]
        y2 = (b2 - lower[a] * y2) * inv[a]
        X[a, 0] = y0
        X[a, 1] = y1
        X[a, 2] = y2
    for k in range(last - first):
        a = last - 1 - k
        y0 = X[a, 0] - cp[a] * y0
        y1 = X[a, 1] - cp[a] * y1
        y2 = X[a, 2] - cp[a] * y2
        X[a, 0] = y0
        X[a, 1] = y1
        X[a, 2] = y2


@kernel(inline="always")
def step_solve(S, W, WA, c, hh, up0, up1, up2, push_pivot, first, n):
    """X = A^-1 B of (1w) for the single string (:func:`convective_solve` on rows first..N into
    ``W.X``, f~ in ``W.fl``)."""
    convective_solve(S.p, S.r, W.fl, WA.coef, c, hh, WA.lower, WA.inv, WA.cp, (up0, up1, up2), push_pivot, first, n,
                     W.X)


@kernel
def settle_reeling_switches(S, P, WA, W, h, length, c, first, n):
    """:func:`~.switch.settle_switches` of a winch step that ended at unstretched length
    ``length`` with the convective coefficient ``c`` = mu v / N: the velocities from the momenta
    less c C^T r (into ``WA.pshift``) and the symmetric mass matrix at that length (into the
    diagnostics' factors ``WA.d*``). Not inlined, as settle_switches."""
    Pd = length_params(P, WA, length, WA.state[WN_MASS_PER_LENGTH] * length / n, first, n, True)
    ps = WA.pshift
    for a in range(n + 1):
        for i in range(3):
            ps[a, i] = S.p[a, i] - (c * convective_momentum(S.r, WA.coef, a, i) if a >= first else 0.0)
    settle_switches(S, Pd, h, ps, W.switch, S.owed, W.dy, W.fr)


@kernel(forceinline=True)
def winch_substep(S, W, P, WA, inputs, h, l0, l1, free, forced, coupled, compensated):
    """One LGVI step of length ``h`` while the unstretched length goes ``l0 -> l1`` (the reel
    speed v = (l1 - l0) / h), in place; as :func:`~.lgvi.lgvi_substep` otherwise (``S.f`` holds
    the nodal forces at length l0 on entry and at l1 on success; a failure leaves the state
    untouched). Returns ``(status, newton_iterations)``."""
    n = S.r.shape[0] - 1
    first = 0 if free else 1
    st = WA.state
    mu = st[WN_MASS_PER_LENGTH]
    v = (l1 - l0) / h
    c = mu * v / n
    hh = 0.5 * h
    m_mean = mu * (0.5 * (l0 + l1)) / n
    fl = W.fl
    for a in range(n + 1):  # f~_k = f + grad T0 at (r_k, l0)
        for i in range(3):
            fl[a, i] = S.f[a, i]
    if v != 0.0:
        add_convective_forces(S.r, WA.coef, mu * v * v / (n * l0), fl, first)
    factor_tridiagonal(P, WA, m_mean, 0.5 * h * c, first, n, WA.inv, WA.cp, WA.w, WA.jeff, WA.lower, WA.upper,
                       WA.diag)
    held = held_inputs(inputs, forced)
    up0, up1, up2, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held
    l_0, l_1, l_2, t0, t1, t2 = left_torque(S.R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    step_solve(S, W, WA, c, hh, up0, up1, up2, free and forced, first, n)
    c0, c1, c2, e0, e1, e2, dr00, dr01, dr02, iters, status = rigid_increments(
        S, W, P, h, P.M, P.rho, WA.jeff, WA.w, t0, t1, t2, free, forced, coupled)
    if status != OK:
        return status, iters
    new_positions(S, W, first, compensated)
    # the impulse h/2 (f~_k + f~_{k+1}) + c C dr, with f_{k+1} (nodal forces at l1) added by the
    # commit: fl <- f~_k + grad T0 at (r_{k+1}, l1) + (2/h) c C dr
    if v != 0.0:
        add_convective_impulse(W.X, W.Y, WA.coef, mu * v * v / (n * l1), c, h, fl, first)
    P1 = length_params(P, WA, l1, m_mean, first, n, False)
    unsettled = 0
    if P.settle:  # the slack switches of the step (kernels/step/switch.py), at each end's length
        u0 = l0 / n
        unsettled = switch_errors(S.r, W.X, st[WN_EA] / u0, u0, P1.kappa, P1.u, (l1 - l0) * st[WN_EA] / n, S.owed,
                                  W.switch)
    status = commit_step(S, W, P1, h, (c0, c1, c2), (e0, e1, e2), (dr00, dr01, dr02), (l_0, l_1, l_2, t0, t1, t2),
                         held, (fl, W.fn),
                         (free, forced, coupled, compensated))
    if status == OK and unsettled > 0:
        settle_reeling_switches(S, P, WA, W, h, l1, c, first, n)
    if status == OK:  # the commit counted the weight at l1; the step's is at the mean length
        kahan_add(S.acc, S.accc, B_GRAVITY_IMPULSE + 2, h * P.g * n * (m_mean - P1.m))
    return status, iters


@kernel(entry=True)
def winch_forces(S, P, WA):
    """``S.f`` = the nodal forces at the winch's length (a state just set)."""
    n = S.r.shape[0] - 1
    Pl = length_params(P, WA, WA.state[WN_LENGTH], 0.0, P.first, n, False)
    nodal_forces(S.r, Pl.kappa, Pl.u, Pl.m, Pl.M, Pl.Mp, Pl.g, Pl.slack, S.f)


@kernel(entry=True)
def winch_energy(S, P, WA, D, length, v):
    """The diagnostics ``D`` of the state at unstretched length ``length`` and reel speed ``v``,
    its energy the Hamiltonian H = T2 - T0 + V; returns ``(H, dH/dl)`` [J, J/m] (docs/physics.md,
    "The winch")."""
    r = S.r
    n = r.shape[0] - 1
    first = P.first
    st = WA.state
    mu = st[WN_MASS_PER_LENGTH]
    m = mu * length / n
    Pl = length_params(P, WA, length, m, first, n, True)
    c = mu * v / n
    ps = WA.pshift
    for a in range(n + 1):
        for i in range(3):
            ps[a, i] = S.p[a, i] - (c * convective_momentum(r, WA.coef, a, i) if a >= first else 0.0)
    S2 = StateArrays(r, ps, S.R, S.Pi, S.rc, S.pc, S.Rc, S.Pic, S.f, S.acc, S.accc, S.owed)
    diagnostics(S2, Pl, D)
    # pi3 and the linear momentum from the momenta themselves
    out = D.out
    pi3 = S.R[2, 0] * S.Pi[0] + S.R[2, 1] * S.Pi[1] + S.R[2, 2] * S.Pi[2]
    P0 = P1 = P2 = 0.0
    for a in range(n + 1):
        pi3 += r[a, 0] * S.p[a, 1] - r[a, 1] * S.p[a, 0]
        P0 += S.p[a, 0]
        P1 += S.p[a, 1]
        P2 += S.p[a, 2]
    out[D_PI3] = pi3
    out[D_LINEAR_MOMENTUM] = P0
    out[D_LINEAR_MOMENTUM + 1] = P1
    out[D_LINEAR_MOMENTUM + 2] = P2
    t0 = convective_energy(r, WA.coef, mu * v * v / (n * length))
    out[D_ENERGY] -= t0
    # dH/dl at fixed (q, p, v) = -dL/dl at fixed (q, qdot, v): the string's kinetic energy and
    # weight scale with l, T0 with 1/l, and V_e = sum EA/(2u) (|x| - u)^2 with u = l / N
    vz = 0.0
    de = 0.0
    u = length / n
    for e in range(n):
        vz += r[e, 2] + r[e + 1, 2]
        x0 = r[e + 1, 0] - r[e, 0]
        x1 = r[e + 1, 1] - r[e, 1]
        x2 = r[e + 1, 2] - r[e, 2]
        eps = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2) / u - 1.0
        if not (P.slack and eps < 0.0):
            de += eps + 0.5 * eps * eps
    weight = -P.g * 0.5 * m * vz
    dH = (-out[D_KINETIC_STRING] + t0 + weight) / length - st[WN_EA] / n * de
    return out[D_ENERGY], dH


@kernel(inline="always")
def kinetic_at_length(S, P, WA, D, length, first, n):
    """The kinetic energy [J] of the state whose node momenta less c C^T r are in ``WA.pshift``,
    with the string's mass at unstretched length ``length`` (the symmetric mass matrix's factors
    into the diagnostics' ``WA.d*``, the velocities into ``D.V``)."""
    Pl = length_params(P, WA, length, WA.state[WN_MASS_PER_LENGTH] * length / n, first, n, True)
    w0, w1, w2, q0, q1, q2 = node_velocities(WA.pshift, S.Pi[0], S.Pi[1], S.Pi[2], S.R, Pl, D.V)
    ts, tb, tp = kinetic_energies(D.V, w0, w1, w2, q0, q1, q2, Pl)
    return ts + tb + tp


@kernel
def length_shift(S, P, WA, D, l0, l1, v):
    """H(q, p; l1) - H(q, p; l0) less the elastic energy's share [J]: the change of the kinetic,
    convective (T0) and gravity terms of H (:func:`winch_energy`, at reel speed ``v``) when the
    length alone goes ``l0 -> l1`` at the state's (q, p). The implicit string's winch work per
    step is the mean of this at the step's two states plus the elastic share counted exactly
    (docs/physics.md, "The implicit string too"). Uses the diagnostics' scratch (``D.V``,
    ``WA.pshift``, ``WA.d*``)."""
    r = S.r
    n = r.shape[0] - 1
    first = P.first
    mu = WA.state[WN_MASS_PER_LENGTH]
    c = mu * v / n
    ps = WA.pshift
    for a in range(n + 1):
        for i in range(3):
            ps[a, i] = S.p[a, i] - (c * convective_momentum(r, WA.coef, a, i) if a >= first else 0.0)
    vz = 0.0
    for e in range(n):
        vz += r[e, 2] + r[e + 1, 2]
    kinetic = kinetic_at_length(S, P, WA, D, l1, first, n) - kinetic_at_length(S, P, WA, D, l0, first, n)
    convective = convective_energy(r, WA.coef, mu * v * v / n) * (1.0 / l1 - 1.0 / l0)
    weight = -P.g * 0.5 * (mu / n) * (l1 - l0) * vz
    return kinetic - convective + weight


@kernel(forceinline=True)
def midpoint_dH_dl(r, Y, st, coef, slack, g, h, l0, l1, first):
    """dH/dl [J/m] of one string at the midpoint of the step just taken (l0 -> l1 in ``h``):
    positions r_k + dr/2, velocities dr/h (second-order accurate there), length (l0 + l1)/2; the
    formula of :func:`winch_energy` without its solve for the velocities. ``r`` the string's
    nodes after the step, ``Y`` its increments dr (+ the remainders, so r_k + dr/2 =
    r_{k+1} - dr/2; rows before ``first`` do not move), ``st`` its WINCH vector, ``coef`` its
    :func:`convective_weights`. The midpoint rule of v dH/dl over the step is the explicit
    string's winch work, second order as the step (the implicit string's is counted per step:
    :func:`length_shift`, kernels/step/winch_implicit.py)."""
    n = r.shape[0] - 1
    mu = st[WN_MASS_PER_LENGTH]
    length = 0.5 * (l0 + l1)
    u = length / n
    m = mu * u
    off = st[WN_OFF_SHARE] * m
    end = 0.5 * m - off
    v = (l1 - l0) / h
    theta = mu * v * v / (n * length)
    kinetic = 0.0
    convective = 0.0
    vz = 0.0
    de = 0.0
    for e in range(n):
        a0 = Y[e, 0] / h if e >= first else 0.0
        a1 = Y[e, 1] / h if e >= first else 0.0
        a2 = Y[e, 2] / h if e >= first else 0.0
        b0 = Y[e + 1, 0] / h
        b1 = Y[e + 1, 1] / h
        b2 = Y[e + 1, 2] / h
        kinetic += end * (a0 * a0 + a1 * a1 + a2 * a2 + b0 * b0 + b1 * b1 + b2 * b2) + 2.0 * off * (
            a0 * b0 + a1 * b1 + a2 * b2)
        x0 = (r[e + 1, 0] - r[e, 0]) - 0.5 * h * (b0 - a0)
        x1 = (r[e + 1, 1] - r[e, 1]) - 0.5 * h * (b1 - a1)
        x2 = (r[e + 1, 2] - r[e, 2]) - 0.5 * h * (b2 - a2)
        s = x0 * x0 + x1 * x1 + x2 * x2
        convective += coef[e, 2] * s
        vz += (r[e, 2] - 0.5 * h * a2) + (r[e + 1, 2] - 0.5 * h * b2)
        eps = np.sqrt(s) / u - 1.0
        if not (slack and eps < 0.0):
            de += eps + 0.5 * eps * eps
    return (-0.5 * kinetic + 0.5 * theta * convective - g * 0.5 * m * vz) / length - st[WN_EA] / n * de
