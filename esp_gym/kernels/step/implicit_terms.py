"""The pieces of the implicit string's Newton system (kernels/step/implicit.py, docs/physics.md "The
implicit string"): an element's tension over the step and its directions, its force and Jacobian
block in either form (the energy-momentum form's discrete gradient, or the variational form's
directions at the two ends), the string's forces of the step, the body's coupling blocks, and a
3x3 inverse."""
import math

from ..jit import kernel


@kernel(inline="always")
def element_vectors(r, Y, a):
    """Element ``a`` (nodes a, a+1) at both ends of the step r_k -> r_k + Y: x_k = r_{a+1} - r_a
    and x_{k+1} = x_k + (Y_{a+1} - Y_a) [m]. Returns ``(x_k (3), x_{k+1} (3))``."""
    x0 = r[a + 1, 0] - r[a, 0]
    x1 = r[a + 1, 1] - r[a, 1]
    x2 = r[a + 1, 2] - r[a, 2]
    return x0, x1, x2, x0 + (Y[a + 1, 0] - Y[a, 0]), x1 + (Y[a + 1, 1] - Y[a, 1]), x2 + (Y[a + 1, 2] - Y[a, 2])


@kernel(inline="always")
def secant_terms(x0, x1, x2, w0, w1, w2, kappa, u0, u1, slack):
    """An element x_k = (x0, x1, x2) -> x_{k+1} = (w0, w1, w2) over the step, stretches s0 = |x_k| -
    u0 and s1 = |x_{k+1}| - u1 (the rest lengths at both ends: equal unless a winch reels, then
    kappa is EA over their mean): its tension T = kappa (s0 + s1)/2 [N] (with ``slack``: 0 where
    both are negative and the energy's secant where they straddle 0), the unit vectors n_k,
    n_{k+1} along it at both ends, 2 dT/ds1 [N/m] (kappa where taut) and its lengths [m].
    Returns ``(T, n_k (3), n_{k+1} (3), 2 dT/ds1, |x_k|, |x_{k+1}|)``."""
    lk = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    ln = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    s0 = lk - u0
    s1 = ln - u1
    T = 0.5 * kappa * (s0 + s1)
    dT = kappa
    if slack:
        # the secant of the energy kappa/2 max(s, 0)^2 over [s0, s1]: the mean-length tension
        # where both ends are on one side of the kink, energy-neutral across it (docs/physics.md,
        # "The slack switch"); continuous with a continuous derivative in s1
        if s0 <= 0.0 and s1 <= 0.0:
            T = 0.0
            dT = 0.0
        elif s0 < 0.0:
            d = s1 - s0
            T = 0.5 * kappa * s1 * s1 / d
            dT = kappa * s1 * (s1 - 2.0 * s0) / (d * d)
        elif s1 < 0.0:
            d = s0 - s1
            T = 0.5 * kappa * s0 * s0 / d
            dT = kappa * s0 * s0 / (d * d)
    return T, x0 / lk, x1 / lk, x2 / lk, w0 / ln, w1 / ln, w2 / ln, dT, lk, ln


@kernel(inline="always")
def hold_taut(r, taut, u, slack):
    """Mark (1.0 in ``taut``) the elements taut at r_k (|x_k| >= u) with the ``slack`` law:
    Newton holds them to the taut branch, tension kappa (s0 + s1)/2 of either sign, until it has
    converged (:func:`release_slack`)."""
    for a in range(taut.shape[0]):
        taut[a] = 0.0
        if slack:
            x0 = r[a + 1, 0] - r[a, 0]
            x1 = r[a + 1, 1] - r[a, 1]
            x2 = r[a + 1, 2] - r[a, 2]
            if math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) >= u:
                taut[a] = 1.0


@kernel(inline="always")
def release_slack(r, Y, taut, u):
    """Release the elements held taut (:func:`hold_taut`) whose new length |x_k + dx| is below u:
    their tension from there on is the slack law's. Returns how many were released (0: the held
    solution is the slack law's, both branches agree where s0, s1 >= 0)."""
    released = 0
    for a in range(taut.shape[0]):
        if taut[a] != 0.0:
            w0 = (r[a + 1, 0] - r[a, 0]) + (Y[a + 1, 0] - Y[a, 0])
            w1 = (r[a + 1, 1] - r[a, 1]) + (Y[a + 1, 1] - Y[a, 1])
            w2 = (r[a + 1, 2] - r[a, 2]) + (Y[a + 1, 2] - Y[a, 2])
            if math.sqrt(w0 * w0 + w1 * w1 + w2 * w2) < u:
                taut[a] = 0.0
                released += 1
    return released


@kernel(inline="always")
def gradient_direction(x0, x1, x2, w0, w1, w2, n0, n1, n2, m0, m1, m2):
    """The discrete gradient's direction of an element x_k = (x0, x1, x2) -> x_{k+1} = (w0, w1, w2)
    over the step, d = (x_k + x_{k+1}) / (|x_k| + |x_{k+1}|) (|d| <= 1, = 1 where the element does
    not turn), the lengths from its unit vectors n_k = (n0, n1, n2) and n_{k+1} = (m0, m1, m2); with
    T its tension, T d . dx equals T d|x| exactly (docs/physics.md, "The energy-momentum form").
    Returns ``(d (3), 1/(|x_k| + |x_{k+1}|) [1/m])``."""
    inv_sum = 1.0 / ((n0 * x0 + n1 * x1 + n2 * x2) + (m0 * w0 + m1 * w1 + m2 * w2))
    return (x0 + w0) * inv_sum, (x1 + w1) * inv_sum, (x2 + w2) * inv_sum, inv_sum


@kernel(inline="always")
def element_block(r, Y, a, kappa, u0, u1, slack, gradient):
    """Element ``a``'s share of the Newton system (:func:`secant_terms` of its :func:`element_vectors`): its force on node a
    [N] and k = 2 d(force)/dx_{k+1} (9, row-major) [N/m]. ``gradient`` (the energy-momentum
    form): force T d (:func:`gradient_direction`), k = 2 dT/ds1 d n_{k+1}^T + 2T/(|x_k| +
    |x_{k+1}|) (I - d n_{k+1}^T); otherwise (the variational form) T n_k and 2 dT/ds1 n_k n_{k+1}^T."""
    x0, x1, x2, w0, w1, w2 = element_vectors(r, Y, a)
    T, n0, n1, n2, m0, m1, m2, dT, _, _ = secant_terms(x0, x1, x2, w0, w1, w2, kappa, u0, u1, slack)
    g = 0.0  # the geometric stiffness 2 T / (|x_k| + |x_{k+1}|)
    if gradient:
        n0, n1, n2, inv_sum = gradient_direction(x0, x1, x2, w0, w1, w2, n0, n1, n2, m0, m1, m2)
        g = 2.0 * T * inv_sum
        dT -= g
    return (T * n0, T * n1, T * n2, dT * n0 * m0 + g, dT * n0 * m1, dT * n0 * m2, dT * n1 * m0, dT * n1 * m1 + g,
            dT * n1 * m2, dT * n2 * m0, dT * n2 * m1, dT * n2 * m2 + g)


@kernel(inline="always")
def coupling_block(off, q4, k00, k01, k02, k10, k11, k12, k20, k21, k22):
    """The off-diagonal block off I - q4 k of the string's Jacobian (9, row-major)."""
    return (off - q4 * k00, -q4 * k01, -q4 * k02, -q4 * k10, off - q4 * k11, -q4 * k12, -q4 * k20, -q4 * k21,
            off - q4 * k22)


@kernel
def split_forces(r, Y, P, fl, fr, mass0, mass1, u0, u1):
    """The string's forces of the step, gravity included [N]: ``fl`` = f_g + sum T n_k (the left
    half, along the elements at r_k) and ``fr`` = f_g + sum T n_{k+1} (the right half), T the
    elements' tensions at their mean lengths (:func:`secant_terms`; rest lengths ``u0``, ``u1``
    [m] at the two ends) and f_g the weight at element mass ``mass0`` (left) and ``mass1`` (right)
    [kg]: P.m and P.u at both ends unless a winch reels. With ``P.gradient`` (the energy-momentum
    form) both halves take the discrete gradient's direction d (:func:`gradient_direction`) in
    place of n_k and n_{k+1}. Returns the sum of the tensions (non-finite iff any is) and the
    largest [N]."""
    n = r.shape[0] - 1
    total = 0.0
    most = 0.0
    for i in range(3):
        for a in range(n + 1):
            fl[a, i] = 0.0
            fr[a, i] = 0.0
    fl[0, 2] = (0.5 * mass0 + P.Mp) * P.g
    fr[0, 2] = (0.5 * mass1 + P.Mp) * P.g
    for a in range(1, n):
        fl[a, 2] = mass0 * P.g
        fr[a, 2] = mass1 * P.g
    fl[n, 2] = (0.5 * mass0 + P.M) * P.g
    fr[n, 2] = (0.5 * mass1 + P.M) * P.g
    for a in range(n):
        x0, x1, x2, w0, w1, w2 = element_vectors(r, Y, a)
        T, k0, k1, k2, m0, m1, m2, _, _, _ = secant_terms(x0, x1, x2, w0, w1, w2, P.kappa, u0, u1, P.slack)
        if P.gradient:
            k0, k1, k2, _ = gradient_direction(x0, x1, x2, w0, w1, w2, k0, k1, k2, m0, m1, m2)
            m0 = k0
            m1 = k1
            m2 = k2
        fl[a, 0] += T * k0
        fl[a, 1] += T * k1
        fl[a, 2] += T * k2
        fl[a + 1, 0] -= T * k0
        fl[a + 1, 1] -= T * k1
        fl[a + 1, 2] -= T * k2
        fr[a, 0] += T * m0
        fr[a, 1] += T * m1
        fr[a, 2] += T * m2
        fr[a + 1, 0] -= T * m0
        fr[a + 1, 1] -= T * m1
        fr[a + 1, 2] -= T * m2
        total += T
        most = max(most, T)
    return total, most


@kernel(inline="always")
def inverse3(a00, a01, a02, a10, a11, a12, a20, a21, a22):
    """The inverse of a 3x3 matrix by cofactors, row by row (9 scalars)."""
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    d = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02)
    return (c00 * d, (a02 * a21 - a01 * a22) * d, (a01 * a12 - a02 * a11) * d,
            c01 * d, (a00 * a22 - a02 * a20) * d, (a02 * a10 - a00 * a12) * d,
            c02 * d, (a01 * a20 - a00 * a21) * d, (a00 * a11 - a01 * a10) * d)


@kernel(inline="always")
def body_coupling(R, P, yn0, yn1, yn2, c0, c1, c2, gk0, gk1, gk2, coupled):
    """The body's side of the implicit string's Newton system at an iterate (attachment-node
    increment y_N, Cayley vector c): g = gk - M rho_c x (R_k^T y_N), q = R_k (F(c) - I) rho_c
    (the attachment row's coupling term), B = dG_N/dc = M R_k d(F rho_c)/dc and C = dphi/dy_N =
    -(I - c^ + c c^T) M rho_c^ R_k^T (docs/physics.md, "Newton's method"); B, C, q are 0 unless
    ``coupled``. Returns ``(g (3), q (3), B (9, row-major), C (9, row-major))``."""
    M = P.M
    rho0 = P.rho[0]
    rho1 = P.rho[1]
    rho2 = P.rho[2]
    g0 = gk0
    g1 = gk1
    g2 = gk2
    q0 = q1 = q2 = 0.0
    b00 = b01 = b02 = b10 = b11 = b12 = b20 = b21 = b22 = 0.0  # B = dG_N/dc
    cy00 = cy01 = cy02 = cy10 = cy11 = cy12 = cy20 = cy21 = cy22 = 0.0  # C = dphi/dy_N
    if coupled:
        w0 = R[0, 0] * yn0 + R[1, 0] * yn1 + R[2, 0] * yn2  # R^T y_N
        w1 = R[0, 1] * yn0 + R[1, 1] * yn1 + R[2, 1] * yn2
        w2 = R[0, 2] * yn0 + R[1, 2] * yn1 + R[2, 2] * yn2
        g0 = gk0 - M * (rho1 * w2 - rho2 * w1)
        g1 = gk1 - M * (rho2 * w0 - rho0 * w2)
        g2 = gk2 - M * (rho0 * w1 - rho1 * w0)
        q0, q1, q2, b00, b01, b02, b10, b11, b12, b20, b21, b22 = offset_terms(R, M, rho0, rho1, rho2, c0, c1, c2)
        cy00, cy01, cy02, cy10, cy11, cy12, cy20, cy21, cy22 = attitude_row_terms(R, M, rho0, rho1, rho2, c0, c1, c2)
    return (g0, g1, g2, q0, q1, q2, b00, b01, b02, b10, b11, b12, b20, b21, b22,
            cy00, cy01, cy02, cy10, cy11, cy12, cy20, cy21, cy22)


@kernel(inline="always")
def offset_terms(R, M, rho0, rho1, rho2, c0, c1, c2):
    """:func:`body_coupling`'s q = R_k (F(c) - I) rho_c and B = M R_k d(F rho_c)/dc (row-major):
    ``(q0, q1, q2, b00, ..., b22)``."""
    cc = c0 * c0 + c1 * c1 + c2 * c2
    # (F - I) rho = s v, v = c x rho + c x (c x rho), s = 2/(1 + |c|^2)
    sc = 2.0 / (1.0 + cc)
    cr0 = c1 * rho2 - c2 * rho1
    cr1 = c2 * rho0 - c0 * rho2
    cr2 = c0 * rho1 - c1 * rho0
    v0 = cr0 + (c1 * cr2 - c2 * cr1)
    v1 = cr1 + (c2 * cr0 - c0 * cr2)
    v2 = cr2 + (c0 * cr1 - c1 * cr0)
    q0 = sc * (R[0, 0] * v0 + R[0, 1] * v1 + R[0, 2] * v2)  # q = R (F - I) rho
    q1 = sc * (R[1, 0] * v0 + R[1, 1] * v1 + R[1, 2] * v2)
    q2 = sc * (R[2, 0] * v0 + R[2, 1] * v1 + R[2, 2] * v2)
    # d((F - I) rho)/dc = -s^2 v c^T + s (-rho^ + (c . rho) I + c rho^T - 2 rho c^T)
    s2 = sc * sc
    crho = c0 * rho0 + c1 * rho1 + c2 * rho2
    d00 = -s2 * v0 * c0 + sc * (crho + c0 * rho0 - 2.0 * rho0 * c0)
    d01 = -s2 * v0 * c1 + sc * (rho2 + c0 * rho1 - 2.0 * rho0 * c1)
    d02 = -s2 * v0 * c2 + sc * (-rho1 + c0 * rho2 - 2.0 * rho0 * c2)
    d10 = -s2 * v1 * c0 + sc * (-rho2 + c1 * rho0 - 2.0 * rho1 * c0)
    d11 = -s2 * v1 * c1 + sc * (crho + c1 * rho1 - 2.0 * rho1 * c1)
    d12 = -s2 * v1 * c2 + sc * (rho0 + c1 * rho2 - 2.0 * rho1 * c2)
    d20 = -s2 * v2 * c0 + sc * (rho1 + c2 * rho0 - 2.0 * rho2 * c0)
    d21 = -s2 * v2 * c1 + sc * (-rho0 + c2 * rho1 - 2.0 * rho2 * c1)
    d22 = -s2 * v2 * c2 + sc * (crho + c2 * rho2 - 2.0 * rho2 * c2)
    b00 = M * (R[0, 0] * d00 + R[0, 1] * d10 + R[0, 2] * d20)
    b01 = M * (R[0, 0] * d01 + R[0, 1] * d11 + R[0, 2] * d21)
    b02 = M * (R[0, 0] * d02 + R[0, 1] * d12 + R[0, 2] * d22)
    b10 = M * (R[1, 0] * d00 + R[1, 1] * d10 + R[1, 2] * d20)
    b11 = M * (R[1, 0] * d01 + R[1, 1] * d11 + R[1, 2] * d21)
    b12 = M * (R[1, 0] * d02 + R[1, 1] * d12 + R[1, 2] * d22)
    b20 = M * (R[2, 0] * d00 + R[2, 1] * d10 + R[2, 2] * d20)
    b21 = M * (R[2, 0] * d01 + R[2, 1] * d11 + R[2, 2] * d21)
    b22 = M * (R[2, 0] * d02 + R[2, 1] * d12 + R[2, 2] * d22)
    return q0, q1, q2, b00, b01, b02, b10, b11, b12, b20, b21, b22


@kernel(inline="always")
def attitude_row_terms(R, M, rho0, rho1, rho2, c0, c1, c2):
    """:func:`body_coupling`'s C = (I - c^ + c c^T)(-M rho^ R_k^T) (row-major): ``(c00, ..., c22)``."""
    # C = (I - c^ + c c^T)(-M rho^ R^T): first P = -M rho^ R^T
    p00 = -M * (rho1 * R[0, 2] - rho2 * R[0, 1])
    p01 = -M * (rho1 * R[1, 2] - rho2 * R[1, 1])
    p02 = -M * (rho1 * R[2, 2] - rho2 * R[2, 1])
    p10 = -M * (rho2 * R[0, 0] - rho0 * R[0, 2])
    p11 = -M * (rho2 * R[1, 0] - rho0 * R[1, 2])
    p12 = -M * (rho2 * R[2, 0] - rho0 * R[2, 2])
    p20 = -M * (rho0 * R[0, 1] - rho1 * R[0, 0])
    p21 = -M * (rho0 * R[1, 1] - rho1 * R[1, 0])
    p22 = -M * (rho0 * R[2, 1] - rho1 * R[2, 0])
    m00 = 1.0 + c0 * c0
    m01 = c2 + c0 * c1
    m02 = -c1 + c0 * c2
    m10 = -c2 + c1 * c0
    m11 = 1.0 + c1 * c1
    m12 = c0 + c1 * c2
    m20 = c1 + c2 * c0
    m21 = -c0 + c2 * c1
    m22 = 1.0 + c2 * c2
    cy00 = m00 * p00 + m01 * p10 + m02 * p20
    cy01 = m00 * p01 + m01 * p11 + m02 * p21
    cy02 = m00 * p02 + m01 * p12 + m02 * p22
    cy10 = m10 * p00 + m11 * p10 + m12 * p20
    cy11 = m10 * p01 + m11 * p11 + m12 * p21
    cy12 = m10 * p02 + m11 * p12 + m12 * p22
    cy20 = m20 * p00 + m21 * p10 + m22 * p20
    cy21 = m20 * p01 + m21 * p11 + m22 * p21
    cy22 = m20 * p02 + m21 * p12 + m22 * p22
    return cy00, cy01, cy02, cy10, cy11, cy12, cy20, cy21, cy22
