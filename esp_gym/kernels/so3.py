"""SO(3) kernels: Cayley parametrisation and the implicit rigid-body equation of the LGVI.

All functions work on scalars and 3x3 arrays without allocating in the hot path.
"""
import numpy as np

from .jit import kernel


@kernel(inline="always")
def rotated(R, v):
    """R v for a 3x3 ``R`` and a 3-vector ``v`` (a body vector in the spatial frame), a 3-tuple."""
    return (R[0, 0] * v[0] + R[0, 1] * v[1] + R[0, 2] * v[2], R[1, 0] * v[0] + R[1, 1] * v[1] + R[1, 2] * v[2],
            R[2, 0] * v[0] + R[2, 1] * v[1] + R[2, 2] * v[2])


@kernel(inline="always")
def unrotated(R, v):
    """R^T v for a 3x3 ``R`` and a 3-vector ``v`` (a spatial vector in the body frame), a 3-tuple."""
    return (R[0, 0] * v[0] + R[1, 0] * v[1] + R[2, 0] * v[2], R[0, 1] * v[0] + R[1, 1] * v[1] + R[2, 1] * v[2],
            R[0, 2] * v[0] + R[1, 2] * v[1] + R[2, 2] * v[2])


@kernel(inline="always")
def cross(a, b):
    """a x b of two 3-vectors, a 3-tuple."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@kernel
def solve3(A, b0, b1, b2):
    """Solve ``A x = b`` for a 3x3 matrix by cofactors; returns ``(x0, x1, x2)``.

    A is well conditioned wherever it is used here (an inertia-like Newton Jacobian), so
    Cramer's rule is accurate and much cheaper than a general LU call.
    """
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    c10 = A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]
    c11 = A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]
    c12 = A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]
    c20 = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
    c21 = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
    c22 = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    inv_det = 1.0 / (A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02)
    x0 = (c00 * b0 + c10 * b1 + c20 * b2) * inv_det
    x1 = (c01 * b0 + c11 * b1 + c21 * b2) * inv_det
    x2 = (c02 * b0 + c12 * b1 + c22 * b2) * inv_det
    return x0, x1, x2


@kernel
def cayley_minus_identity(f0, f1, f2, out):
    """Write ``F - I`` for ``F = cay(f) = (I - f^)^-1 (I + f^)`` into ``out`` (3x3).

    ``F - I = 2/(1+|f|^2) (f^ + f^ f^)``. F = I + O(h), so forming F and subtracting I would
    lose about four digits (docs/physics.md, "Round-off"); every user of F takes F - I.
    """
    c = 2.0 / (1.0 + f0 * f0 + f1 * f1 + f2 * f2)
    # f^ f^ = f f^T - |f|^2 I
    out[0, 0] = c * (-f1 * f1 - f2 * f2)
    out[1, 1] = c * (-f0 * f0 - f2 * f2)
    out[2, 2] = c * (-f0 * f0 - f1 * f1)
    out[0, 1] = c * (-f2 + f0 * f1)
    out[1, 0] = c * (f2 + f0 * f1)
    out[0, 2] = c * (f1 + f0 * f2)
    out[2, 0] = c * (-f1 + f0 * f2)
    out[1, 2] = c * (-f0 + f1 * f2)
    out[2, 1] = c * (f0 + f1 * f2)


@kernel(inline="always")
def cayley_jacobian(g0, g1, g2, f0, f1, f2, gf, J, jac):
    """Write d phi/df = g^ + (g . f) I + f g^T - 2 J into ``jac`` (3x3), phi(f) = g + g x f +
    (g . f) f - 2 J f the rigid-body equation in Cayley form; ``gf`` = g . f."""
    jac[0, 0] = gf + f0 * g0 - 2.0 * J[0, 0]
    jac[0, 1] = -g2 + f0 * g1 - 2.0 * J[0, 1]
    jac[0, 2] = g1 + f0 * g2 - 2.0 * J[0, 2]
    jac[1, 0] = g2 + f1 * g0 - 2.0 * J[1, 0]
    jac[1, 1] = gf + f1 * g1 - 2.0 * J[1, 1]
    jac[1, 2] = -g0 + f1 * g2 - 2.0 * J[1, 2]
    jac[2, 0] = -g1 + f2 * g0 - 2.0 * J[2, 0]
    jac[2, 1] = g0 + f2 * g1 - 2.0 * J[2, 1]
    jac[2, 2] = gf + f2 * g2 - 2.0 * J[2, 2]


@kernel(inline="always")
def cayley_residual(g0, g1, g2, f0, f1, f2, J):
    """phi(f) = g + g x f + (g . f) f - 2 J f, the residual of ``(F K - K F^T)^vee = g`` for
    ``F = cay(f)`` (:func:`cayley_newton`). Returns ``(phi (3), g . f)``."""
    gf = g0 * f0 + g1 * f1 + g2 * f2
    Jf0 = J[0, 0] * f0 + J[0, 1] * f1 + J[0, 2] * f2
    Jf1 = J[1, 0] * f0 + J[1, 1] * f1 + J[1, 2] * f2
    Jf2 = J[2, 0] * f0 + J[2, 1] * f1 + J[2, 2] * f2
    return (g0 + (g1 * f2 - g2 * f1) + gf * f0 - 2.0 * Jf0, g1 + (g2 * f0 - g0 * f2) + gf * f1 - 2.0 * Jf1,
            g2 + (g0 * f1 - g1 * f0) + gf * f2 - 2.0 * Jf2, gf)


@kernel
def cayley_newton(g0, g1, g2, J, tol, max_iter, jac):
    """Solve ``(F K - K F^T)^vee = g`` for ``F = cay(f)``, where ``J = tr(K) I - K``.

    With the Cayley vector f the equation is (Lee 2008, Sec. 3.3.8)

        phi(f) = g + g x f + (g . f) f - 2 J f = 0,
        dphi/df = g^ + (g . f) I + f g^T - 2 J.

    The first iterate is the linearisation (2J - g^) f = g, i.e. one Newton step from f = 0.
    Iterates until the Newton correction satisfies |df| <= tol |f| (tol = 1e-14 or smaller), or
    until the next correction, predicted from the last two as |df|^2 / |df_prev| (conservative
    for quadratic convergence), does: that saves the iteration that only confirmed convergence
    (2 instead of 3 per step at h = 1e-4; pi3 and orthogonality unchanged at round-off).
    ``jac`` is a 3x3 scratch array. Returns ``(f0, f1, f2, iterations, converged)``.
    """
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    dd_prev = 0.0
    for it in range(1, max_iter + 1):
        phi0, phi1, phi2, gf = cayley_residual(g0, g1, g2, f0, f1, f2, J)
        cayley_jacobian(g0, g1, g2, f0, f1, f2, gf, J, jac)
        d0, d1, d2 = solve3(jac, -phi0, -phi1, -phi2)
        f0 += d0
        f1 += d1
        f2 += d2
        dd = d0 * d0 + d1 * d1 + d2 * d2
        ff = f0 * f0 + f1 * f1 + f2 * f2
        if not np.isfinite(ff):
            return f0, f1, f2, it, False
        if dd <= tol * tol * ff:
            return f0, f1, f2, it, True
        # quadratic convergence: the next correction is about |d|^2 / |d_prev|; stop if that
        # is below the tolerance already
        if it > 1 and dd * dd <= tol * tol * ff * dd_prev:
            return f0, f1, f2, it, True
        dd_prev = dd
    return f0, f1, f2, max_iter, False
