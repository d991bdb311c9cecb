"""String kernels: elastic and gravity nodal forces, strain energies, the consistent-mass solve.

Nodes are rows of an ``(N+1, 3)`` array, row 0 the pivot end, row N the attachment node.
Gravity acts along +e3 (the paper's convention), so the gravity force is ``+m g e3``.
"""
import math

import numpy as np

from ..jit import fma, kernel


@kernel
def nodal_forces(r, kappa, u, m, M, Mp, g, slack, f):
    """Write the conservative force on each node, ``f = -dV/dr``, into ``f`` (N+1, 3).

    V = sum_a kappa/2 (|x_a| - u)^2 - g e3 . (sum_a m/2 (r_a + r_{a+1}) + M r_{N+1} + Mp r_1),
    x_a = r_{a+1} - r_a, so with grad V^e_a = kappa (1 - u/|x_a|) x_a (the paper's notation)
    f_a = m_a g e3 + grad V^e_a - grad V^e_{a-1}, with gravity masses m/2 + Mp, m, ..., m,
    m/2 + M (consistent for linear elements; Mp the pivot's point mass, 0 when fixed). The
    body's gravity torque is handled in the rotational equation. With ``slack`` the string
    resists no compression: the element energy is kappa/2 max(|x_a| - u, 0)^2.
    Returns ``(sum of all components, longest squared element length)``: the sum is
    non-finite iff any entry is; the length [m^2] feeds the stepper's blow-up guard.
    """
    n = r.shape[0] - 1
    # one pass, each node written once: f_a = (gravity_a - t_{a-1}) + t_a with the previous
    # element's tension t carried in registers: the same operations in the same order as
    # accumulating element by element into a zeroed array, at half the memory traffic
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    total = 0.0
    longest = 0.0
    for a in range(n):
        x0 = r[a + 1, 0] - r[a, 0]
        x1 = r[a + 1, 1] - r[a, 1]
        x2 = r[a + 1, 2] - r[a, 2]
        s = x0 * x0 + x1 * x1 + x2 * x2
        longest = max(longest, s)
        c = kappa * (1.0 - u / math.sqrt(s))
        if slack and c < 0.0:
            c = 0.0
        if a == 0:
            f[0, 0] = 0.0 + c * x0
            f[0, 1] = 0.0 + c * x1
            f[0, 2] = (0.5 * m + Mp) * g + c * x2
        else:
            f[a, 0] = (0.0 - t0) + c * x0
            f[a, 1] = (0.0 - t1) + c * x1
            f[a, 2] = (m * g - t2) + c * x2
        t0 = c * x0
        t1 = c * x1
        t2 = c * x2
        total += t0 + t1 + t2
    gz = (0.5 * m + M) * g
    f[n, 0] = 0.0 - t0
    f[n, 1] = 0.0 - t1
    f[n, 2] = gz - t2
    return total + f[n, 0] + f[n, 1] + f[n, 2], longest


@kernel
def element_strain(r, kappa, u, slack, strain_energy):
    """Per-element strain energy kappa/2 (|x_a| - u)^2 [J] into ``strain_energy`` (N,); with
    ``slack`` a compressed element stores none.

    Returns ``(elastic potential [J], stretched length [m])``.
    """
    n = r.shape[0] - 1
    total = 0.0
    length = 0.0
    for a in range(n):
        x0 = r[a + 1, 0] - r[a, 0]
        x1 = r[a + 1, 1] - r[a, 1]
        x2 = r[a + 1, 2] - r[a, 2]
        L = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        e = 0.5 * kappa * (L - u) ** 2
        if slack and L < u:
            e = 0.0
        strain_energy[a] = e
        total += e
        length += L
    return total, length


@kernel(inline="always")
def back_substitute(cp, first, y0, y1, y2, x):
    """Back substitution of the Thomas algorithm on rows N-1 .. first of ``x`` (3 columns),
    whose forward sweep left (y0, y1, y2) = row N: x_a -= cp_a x_{a+1}, with x_{a+1} carried in
    registers and one fused multiply-add per entry."""
    n = x.shape[0] - 1
    for k in range(n - first):
        a = n - 1 - k
        y0 = fma(-cp[a], y0, x[a, 0])
        y1 = fma(-cp[a], y1, x[a, 1])
        y2 = fma(-cp[a], y2, x[a, 2])
        x[a, 0] = y0
        x[a, 1] = y1
        x[a, 2] = y2


@kernel
def tridiag_solve(inv, cp, off, first, b, x):
    """Solve the constant tridiagonal system ``M x = b`` on rows ``first..N`` (3 columns).

    ``inv``/``cp`` are the Thomas factors of M (from :func:`tridiag_factor`),
    ``off`` its constant off-diagonal. Rows below ``first`` are not touched.
    """
    n = b.shape[0] - 1
    y0 = 0.0
    y1 = 0.0
    y2 = 0.0
    for a in range(first, n + 1):
        # (b_a - off y_{a-1}) inv_a with off inv_a = cp_a: one fused multiply-add on the
        # recurrence (the chain of dependent operations is what limits this loop)
        # (cp_first = off inv_first multiplies y = 0 there)
        y0 = fma(-cp[a], y0, b[a, 0] * inv[a])
        y1 = fma(-cp[a], y1, b[a, 1] * inv[a])
        y2 = fma(-cp[a], y2, b[a, 2] * inv[a])
        x[a, 0] = y0
        x[a, 1] = y1
        x[a, 2] = y2
    back_substitute(cp, first, y0, y1, y2, x)


@kernel(inline="always")
def string_solve(inv, cp, first, p, f, hh, up0, up1, up2, push_pivot, x):
    """:func:`tridiag_solve` of ``M x = p + hh f`` (the LGVI's string right-hand side) with the
    right-hand side formed on the fly, plus ``hh (up0, up1, up2)`` (the pivot force, spatial
    [N]) at row 0 if ``push_pivot``.
    Same operations in the same order as forming b first (bit-identical), one pass less."""
    n = p.shape[0] - 1
    y0 = 0.0
    y1 = 0.0
    y2 = 0.0
    for a in range(first, n + 1):
        b0 = p[a, 0] + hh * f[a, 0]
        b1 = p[a, 1] + hh * f[a, 1]
        b2 = p[a, 2] + hh * f[a, 2]
        if push_pivot and a == 0:
            b0 += hh * up0
            b1 += hh * up1
            b2 += hh * up2
        y0 = fma(-cp[a], y0, b0 * inv[a])
        y1 = fma(-cp[a], y1, b1 * inv[a])
        y2 = fma(-cp[a], y2, b2 * inv[a])
        x[a, 0] = y0
        x[a, 1] = y1
        x[a, 2] = y2
    back_substitute(cp, first, y0, y1, y2, x)


def tridiag_factor(diag, off):
    """Thomas factors ``(inv, cp)`` of a symmetric tridiagonal matrix with constant ``off``.

    Plain NumPy (run once per scene). Entries where ``diag`` is 0 are left 0 (rows that are
    not unknowns, e.g. a fixed pivot).
    """
    diag = np.asarray(diag, dtype=np.float64)
    inv = np.zeros_like(diag)
    cp = np.zeros_like(diag)
    first = int(np.argmax(diag != 0.0))
    prev_cp = 0.0
    for a in range(first, diag.size):
        inv[a] = 1.0 / (diag[a] - off * prev_cp)
        cp[a] = off * inv[a]
        prev_cp = cp[a]
    return inv, cp


@kernel(entry=True)
def state_forces(S, P):
    """``S.f = nodal_forces(S.r)`` for a state just set (a reset): the explicit step recomputes
    them anyway, the implicit one takes them as its first guess (kernels/step/implicit.py)."""
    nodal_forces(S.r, P.kappa, P.u, P.m, P.M, P.Mp, P.g, P.slack, S.f)
