"""The largest eigenvalue of the string's linearised chain, K x = lambda M x, by Sturm bisection
(esp_gym/scene/stability.py is the Python face; docs/physics.md, "The stability bound").

Both matrices are symmetric tridiagonal on the moving nodes: K is the path Laplacian (one unit
stiffness per element), M the string's consistent (m/6 [[2, 1], [1, 2]] per element) or lumped
(m/2 per end) mass, with a free pivot's mass on node 1 and the load's effective mass on the
attachment node. M is positive definite, so by Sylvester's law of inertia the number of negative
pivots of the LDL^T factorisation of K - lambda M counts the eigenvalues below lambda; bisection on
that count between 0 and one free element's eigenvalue (12/m consistent, 4/m lumped, an upper
bound of the chain's) finds the largest to a relative 4 ulp in O(N) per count.
"""
from __future__ import annotations

import numpy as np

from .jit import kernel

#: Bisection steps: the bracket [0, 12/m] halves each time; 64 reach the float64 resolution.
BISECTIONS = 64


@kernel
def below_count(lam, elements, m, consistent, pivot_mass, fixed_pivot, end_mass):
    """The number of eigenvalues of K x = lam M x below ``lam`` [1/kg] (chain as in the module
    docstring; ``pivot_mass`` and ``end_mass`` [kg] on the end nodes, ``fixed_pivot``: node 1 does
    not move)."""
    end = m / 3.0 if consistent else 0.5 * m
    off_mass = m / 6.0 if consistent else 0.0
    first = 1 if fixed_pivot else 0
    count = 0
    pivot = 1.0
    for a in range(first, elements + 1):
        mass = 2.0 * end
        stiff = 2.0
        if a == 0:
            mass = end + pivot_mass
            stiff = 1.0
        if a == elements:
            mass = end + end_mass
            stiff = 1.0
        diagonal = stiff - lam * mass
        if a > first:
            coupling = -1.0 - lam * off_mass
            diagonal -= coupling * coupling / pivot
        if diagonal == 0.0:
            diagonal = -1e-300  # an exact zero pivot: lam is an eigenvalue, count it as below
        if diagonal < 0.0:
            count += 1
        pivot = diagonal
    return count


@kernel(entry=True)
def largest_eigenvalue(elements, m, consistent, pivot_mass, fixed_pivot, end_mass):
    """The largest eigenvalue [1/kg] of K x = lam M x (unit element stiffness), by bisection."""
    unknowns = elements + (0 if fixed_pivot else 1)
    low, high = 0.0, (12.0 if consistent else 4.0) / m * 1.0000001
    for _ in range(BISECTIONS):
        mid = 0.5 * (low + high)
        if mid <= low or mid >= high:
            break
        if below_count(mid, elements, m, consistent, pivot_mass, fixed_pivot, end_mass) < unknowns:
            low = mid
        else:
            high = mid
    return high


@kernel(entry=True)
def least_effective_mass(M, rho, J):
    """The least eigenvalue [kg] of M I + M^2 hat(rho) J^-1 hat(rho), the load's translational mass
    matrix at its attachment point once its rotation is eliminated (``rho`` attachment -> centre
    of mass [m], ``J`` inertia about the attachment point [kg m^2], both body frame): J^-1 by its
    adjugate, the symmetric 3x3 eigenvalue in closed form (the trigonometric solution of the
    characteristic cubic). Scalars and tuples only: a kernel allocates nothing."""
    a, b, c = J[0, 0], 0.5 * (J[0, 1] + J[1, 0]), 0.5 * (J[0, 2] + J[2, 0])
    d, e, f = J[1, 1], 0.5 * (J[1, 2] + J[2, 1]), J[2, 2]
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    inv = ((d * f - e * e, c * e - b * f, b * e - c * d),
           (c * e - b * f, a * f - c * c, b * c - a * e),
           (b * e - c * d, b * c - a * e, a * d - b * b))
    x, y, z = rho[0], rho[1], rho[2]
    hat = ((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0))
    # A = M I + M^2 hat inv hat / det, its upper triangle
    A00 = A01 = A02 = A11 = A12 = A22 = 0.0
    for k in range(3):
        for l in range(3):
            w = inv[k][l] / det
            A00 += hat[0][k] * w * hat[l][0]
            A01 += hat[0][k] * w * hat[l][1]
            A02 += hat[0][k] * w * hat[l][2]
            A11 += hat[1][k] * w * hat[l][1]
            A12 += hat[1][k] * w * hat[l][2]
            A22 += hat[2][k] * w * hat[l][2]
    A00, A11, A22 = M + M * M * A00, M + M * M * A11, M + M * M * A22
    A01, A02, A12 = M * M * A01, M * M * A02, M * M * A12
    # eigenvalues of a symmetric 3x3: A = q I + p B with det(B)/2 = cos(3 phi)
    q = (A00 + A11 + A22) / 3.0
    off = A01 * A01 + A02 * A02 + A12 * A12
    p2 = (A00 - q) ** 2 + (A11 - q) ** 2 + (A22 - q) ** 2 + 2.0 * off
    if p2 <= 1e-30 * q * q:
        return q
    p = np.sqrt(p2 / 6.0)
    b00, b11, b22, b01, b02, b12 = (A00 - q) / p, (A11 - q) / p, (A22 - q) / p, A01 / p, A02 / p, A12 / p
    half_det = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02))
    half_det = min(1.0, max(-1.0, half_det))
    return q + 2.0 * p * np.cos(np.arccos(half_det) / 3.0 + 2.0 * np.pi / 3.0)
