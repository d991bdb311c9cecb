"""The implicit string with a winch (docs/physics.md, "The winch", "The implicit string too").

The discrete Lagrangian is the explicit winch's (kernels/step/winch.py: T2 + T1 exact along the
step, T0 and gravity by the trapezoid rule) with the elastic term of the implicit string
(kernels/step/implicit.py): each element's energy at its mean stretch over the step,

    -h EA / (2 ubar) phi(sbar)^2,   sbar = ((|x_k| - u_k) + (|x_k+1| - u_k+1)) / 2,   ubar = (u_k + u_k+1) / 2,

u = l / N at each end. Its equations are the implicit string's with the step's mass matrix of
(1w) (tridiagonal, not symmetric) in place of M, and the constant part of the residual

    h p_k + h^2/2 (f_g + grad T0)(r_k, l_k) - h c C^T r_k,

and the momenta p_k+1 = p_k + h/2 (f~_k + f~_k+1) + c C dr as in (3w), f~ the tensions of the step
along the elements at each end plus the weight and grad T0 at that end's length. The first guess
is the explicit winch step with the last step's right forces. kernels/step/step.py cuts a step
that fails back, as the implicit string's, each piece reeling its share of the length, and counts
the winch's work per piece: the elastic energy's change that the tensions' work does not account
for (:func:`elastic_winch_work`), plus the mean over the piece's two states of H's change with
the length alone (kinetic, T0 and weight terms).
"""

from ..jit import kernel
from ..layout import B_GRAVITY_IMPULSE, WN_EA, WN_MASS_PER_LENGTH
from ..status import OK
from ..sums import kahan_add
from .implicit import TOO_TENSE, TRANSVERSE_LIMIT, implicit_positions
from .implicit_newton import implicit_newton
from .implicit_terms import element_vectors, secant_terms, split_forces
from .lgvi import rigid_increments
from .step_shared import commit_step, held_inputs, left_torque
from .winch import (add_convective_forces, add_convective_impulse, convective_momentum, factor_tridiagonal,
                    length_params, step_solve)


@kernel(forceinline=True)
def winch_implicit_once(S, W, P, WA, inputs, h, l0, l1, free, forced, coupled, compensated, bounded):
    """One step of length ``h`` of the implicit string while the winch takes the unstretched
    length ``l0 -> l1`` [m], without cutting back: the state untouched on failure and (``bounded``, the
    variational form) where its largest tension breaks the transverse limit at the shorter end's
    elements (status
    TOO_TENSE). ``S.f`` holds the last step's right forces on entry (the first guess's) and this
    step's on success. Returns ``(status, newton_iterations, the winch's elastic work [J])``
    (:func:`elastic_winch_work`)."""
    r = S.r
    R = S.R
    X = W.X
    Y = W.Y
    fl = W.fl
    coef = WA.coef
    rhs = WA.rhs
    n = r.shape[0] - 1
    first = 0 if free else 1
    mu = WA.state[WN_MASS_PER_LENGTH]
    v = (l1 - l0) / h
    c = mu * v / n
    hh = 0.5 * h
    m0 = mu * l0 / n
    m1 = mu * l1 / n
    m_mean = 0.5 * (m0 + m1)
    u0 = l0 / n
    u1 = l1 / n
    Pm = length_params(P, WA, 0.5 * (l0 + l1), m_mean, first, n, False)  # kappa = EA/ubar, u = ubar
    factor_tridiagonal(P, WA, m_mean, hh * c, first, n, WA.inv, WA.cp, WA.w, WA.jeff, WA.lower, WA.upper, WA.diag)
    held = held_inputs(inputs, forced)
    up0, up1, up2, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held
    l_0, l_1, l_2, t0, t1, t2 = left_torque(R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    theta0 = mu * v * v / (n * l0)
    c0, c1, c2 = winch_first_guess(S, W, WA, Pm, h, c, v != 0.0, theta0, (up0, up1, up2), (t0, t1, t2),
                                   (free, forced, coupled))
    winch_constant_part(S, P, WA, h, c, m0, v != 0.0, theta0, first)
    c0, c1, c2, iters, status = implicit_newton(S, W, Pm, h, (t0, t1, t2), (up0, up1, up2), (c0, c1, c2),
                                                (WA.diag, WA.lower, WA.upper, rhs), (u0, u1),
                                                (free, forced, coupled, True))
    if status != OK:
        return status, iters, 0.0
    # the step's forces at each end: tensions along the elements, the weight at that end's length
    _, tension = split_forces(r, Y, Pm, fl, W.fr, m0, m1, u0, u1)
    short = min(u0, u1)
    if bounded and not P.gradient and 12.0 * tension * h * h > TRANSVERSE_LIMIT**2 * short * mu * short:
        return TOO_TENSE, iters, 0.0
    elastic = elastic_winch_work(r, Y, WA.state[WN_EA], Pm.kappa, u0, u1, P.slack)
    e0, e1, e2, dr00, dr01, dr02 = implicit_positions(S, W, c0, c1, c2, first, compensated)
    # the impulse h/2 (fl + fr) + c C dr: grad T0 at both ends and (2/h) c C dr join fl, so that
    # fr (-> S.f, the next step's first guess) holds the tensions and the weight only
    if v != 0.0:
        add_convective_forces(r, coef, theta0, fl, first)
        add_convective_impulse(X, Y, coef, mu * v * v / (n * l1), c, h, fl, first)
    P1 = length_params(P, WA, l1, m_mean, first, n, False)
    status = commit_step(S, W, P1, h, (c0, c1, c2), (e0, e1, e2), (dr00, dr01, dr02), (l_0, l_1, l_2, t0, t1, t2),
                         held, (W.fl, W.fr),
                         (free, forced, coupled, compensated))
    if status == OK:  # the commit counted the weight at l1; the step's is at the mean length
        kahan_add(S.acc, S.accc, B_GRAVITY_IMPULSE + 2, h * P.g * n * (m_mean - P1.m))
    return status, iters, elastic


@kernel(forceinline=True)
def winch_first_guess(S, W, WA, Pm, h, c, moving, theta0, up, t, flags):
    """:func:`winch_implicit_once`'s first guess: the explicit winch step (1w) with the last step's
    right forces (``S.f``; plus the convective forces of theta0 while the winch is ``moving``) into
    ``W.Y``, its body's Cayley vector returned (0, and the string's solve alone, if the rigid solve
    failed). ``c`` the flow's mass rate per node [kg/s], ``up`` the pivot force, ``t`` the left
    torque, ``flags`` = (free, forced, coupled)."""
    free, forced, coupled = flags
    r, X, Y, fl = S.r, W.X, W.Y, W.fl
    n = r.shape[0] - 1
    first = 0 if free else 1
    for a in range(n + 1):
        for i in range(3):
            fl[a, i] = S.f[a, i]
    if moving:
        add_convective_forces(r, WA.coef, theta0, fl, first)
    step_solve(S, W, WA, c, 0.5 * h, up[0], up[1], up[2], free and forced, first, n)
    c0, c1, c2, _, _, _, _, _, _, _, status = rigid_increments(S, W, Pm, h, Pm.M, Pm.rho, WA.jeff, WA.w, t[0], t[1],
                                                               t[2], free, forced, coupled)
    if status != OK:  # the string solve alone
        c0 = c1 = c2 = 0.0
        for a in range(first, n + 1):
            for i in range(3):
                Y[a, i] = h * X[a, i]
    return c0, c1, c2


@kernel(forceinline=True)
def winch_constant_part(S, P, WA, h, c, m0, moving, theta0, first):
    """The implicit residual's constant part into ``WA.rhs``: h p_k + h^2/2 (f_g + grad T0)(r_k, l0)
    - h c C^T r_k (node mass ``m0`` at the step's start; grad T0 of theta0 while ``moving``)."""
    r, coef, rhs = S.r, WA.coef, WA.rhs
    n = r.shape[0] - 1
    h2 = 0.5 * h * h
    for a in range(n + 1):
        for i in range(3):
            rhs[a, i] = h * (S.p[a, i] - c * convective_momentum(r, coef, a, i)) if a >= first else 0.0
        rhs[a, 2] += h2 * m0 * P.g
    rhs[0, 2] += h2 * (P.Mp - 0.5 * m0) * P.g
    rhs[n, 2] += h2 * (P.M - 0.5 * m0) * P.g
    if moving:
        add_convective_forces(r, coef, h2 * theta0, rhs, first)


@kernel(inline="always")
def elastic_winch_work(r, Y, EA, kappa, u0, u1, slack):
    """The winch's work on the elastic energy over the step r_k -> r_k + Y with the rest length
    u0 -> u1 [J]: sum over the elements of V(|x_k+1|, u1) - V(|x_k|, u0) - T (|x_k+1| - |x_k|),
    V(l, u) = EA/(2u) phi(l - u)^2 and T the step's tension (:func:`~.implicit_terms.secant_terms`),
    whose work on the nodes is T times the length change: the energy change the nodes' motion does
    not account for. Exact per step, so the balance closes however coarsely h resolves the
    string's axial modes, which a quadrature of dV/dl at points of the step would alias."""
    total = 0.0
    for a in range(r.shape[0] - 1):
        x0, x1, x2, w0, w1, w2 = element_vectors(r, Y, a)
        T, _, _, _, _, _, _, _, lk, ln = secant_terms(x0, x1, x2, w0, w1, w2, kappa, u0, u1, slack)
        s0 = lk - u0
        s1 = ln - u1
        if slack:
            s0 = max(s0, 0.0)
            s1 = max(s1, 0.0)
        total += 0.5 * EA * (s1 * s1 / u1 - s0 * s0 / u0) - T * (ln - lk)
    return total


