"""Diagnostics from the discrete state ``(r, p, R, Pi)``: energies, pi3, orthogonality, strain.

Velocities come from the continuous Legendre transform of the finite-element Lagrangian,
inverted with the same Schur complement as the step:

    M_tot v - M e_{N+1} R (rho_c x Omega) = p,      J Omega + M rho_c x (R^T v_{N+1}) = Pi,
    => y = M_tot^-1 p,  J_eff Omega = Pi - M rho_c x (R^T y_{N+1}),  v = y + M w R (rho_c x Omega).

The energy is then E = H(q_k, p_k) (docs/physics.md, "Conventions"), and
pi3 = e3 . (sum_a r_a x p_a + R Pi).
"""
import math

from ..jit import kernel
from ..layout import (D_ENERGY, D_KINETIC_BODY, D_KINETIC_PIVOT, D_KINETIC_STRING, D_LINEAR_MOMENTUM, D_ORTHOGONALITY,
                      D_PI3, D_POTENTIAL_ELASTIC, D_POTENTIAL_GRAVITY, D_STRETCHED_LENGTH)
from ..so3 import solve3
from .string import element_strain, tridiag_solve


@kernel(inline="always")
def node_velocities(p, Pi0, Pi1, Pi2, R, P, V):
    """The continuous Legendre transform inverted: node velocities ``V`` (N+1, 3) [m/s] from the
    momenta ``p`` (N+1, 3) [kg m/s] and ``Pi`` (body frame) [kg m^2/s] at the attitude R, by the
    step's Schur complement (module docstring); rows of fixed nodes are 0. Returns the body's
    angular velocity Omega (body frame) [rad/s] and R (rho_c x Omega) [m/s], six scalars."""
    first = P.first
    tridiag_solve(P.inv, P.cp, P.off, first, p, V)
    for a in range(first):
        V[a, 0] = 0.0
        V[a, 1] = 0.0
        V[a, 2] = 0.0
    return body_velocities(V, Pi0, Pi1, Pi2, R, P.M, P.rho, P.Jeff, P.w, first)


@kernel(inline="always")
def body_velocities(V, Pi0, Pi1, Pi2, R, M, rho, Jeff, w, first):
    """:func:`node_velocities` once ``V`` holds y = M_tot^-1 p: Omega from J_eff Omega = Pi -
    M rho x (R^T y_{N+1}) and v = y + M w R (rho x Omega) on rows ``first..N``, for a body of
    inertial mass ``M`` [kg] at ``rho`` (body frame) [m] with ``Jeff`` (3, 3) and the string's
    column ``w`` = M_tot^-1 e_{N+1} (P's; a team's assembled body: kernels/team/switch.py).
    Returns as :func:`node_velocities`."""
    n = V.shape[0] - 1
    rho0 = rho[0]
    rho1 = rho[1]
    rho2 = rho[2]
    y0 = V[n, 0]
    y1 = V[n, 1]
    y2 = V[n, 2]
    e0 = R[0, 0] * y0 + R[1, 0] * y1 + R[2, 0] * y2
    e1 = R[0, 1] * y0 + R[1, 1] * y1 + R[2, 1] * y2
    e2 = R[0, 2] * y0 + R[1, 2] * y1 + R[2, 2] * y2
    w0, w1, w2 = solve3(
        Jeff,
        Pi0 - M * (rho1 * e2 - rho2 * e1),
        Pi1 - M * (rho2 * e0 - rho0 * e2),
        Pi2 - M * (rho0 * e1 - rho1 * e0),
    )
    x0 = rho1 * w2 - rho2 * w1  # rho_c x Omega, then R (rho_c x Omega)
    x1 = rho2 * w0 - rho0 * w2
    x2 = rho0 * w1 - rho1 * w0
    q0 = R[0, 0] * x0 + R[0, 1] * x1 + R[0, 2] * x2
    q1 = R[1, 0] * x0 + R[1, 1] * x1 + R[1, 2] * x2
    q2 = R[2, 0] * x0 + R[2, 1] * x1 + R[2, 2] * x2
    for a in range(first, n + 1):
        V[a, 0] += M * w[a] * q0
        V[a, 1] += M * w[a] * q1
        V[a, 2] += M * w[a] * q2
    return w0, w1, w2, q0, q1, q2


@kernel(inline="always")
def kinetic_energies(V, w0, w1, w2, q0, q1, q2, P):
    """The kinetic energies of the string, the body and the pivot [J] from the node velocities
    ``V`` [m/s] and the body's Omega (body frame) [rad/s] and R (rho_c x Omega) [m/s]
    (:func:`node_velocities`'s returns)."""
    n = V.shape[0] - 1
    M = P.M
    # element a contributes 1/2 [v_a v_b] M_e [v_a v_b]^T with M_e = [[m/2 - off, off], [off, m/2 - off]]
    # (consistent: off = m/6; lumped: off = 0)
    ts = 0.0
    end = 0.5 * P.m - P.off
    for a in range(n):
        va0 = V[a, 0]
        va1 = V[a, 1]
        va2 = V[a, 2]
        vb0 = V[a + 1, 0]
        vb1 = V[a + 1, 1]
        vb2 = V[a + 1, 2]
        ts += (end * (va0 * va0 + va1 * va1 + va2 * va2 + vb0 * vb0 + vb1 * vb1 + vb2 * vb2)
               + 2.0 * P.off * (va0 * vb0 + va1 * vb1 + va2 * vb2))
    ts *= 0.5
    # body: M/2 |v|^2 + 1/2 Omega.J Omega + M v . R (Omega x rho_c)
    J = P.J
    Jw0 = J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2
    Jw1 = J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2
    Jw2 = J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2
    vn0 = V[n, 0]
    vn1 = V[n, 1]
    vn2 = V[n, 2]
    tb = (0.5 * M * (vn0 * vn0 + vn1 * vn1 + vn2 * vn2) + 0.5 * (w0 * Jw0 + w1 * Jw1 + w2 * Jw2)
          - M * (vn0 * q0 + vn1 * q1 + vn2 * q2))
    tp = 0.5 * P.Mp * (V[0, 0] * V[0, 0] + V[0, 1] * V[0, 1] + V[0, 2] * V[0, 2])
    return ts, tb, tp


@kernel(entry=True)
def diagnostics(S, P, D):
    """Fill the :class:`~.layout.DiagWork` ``D`` (``D.out``: :data:`~.layout.DIAG`) from the state
    ``S`` (:class:`~.layout.StateArrays`)."""
    w0, w1, w2, q0, q1, q2 = node_velocities(S.p, S.Pi[0], S.Pi[1], S.Pi[2], S.R, P, D.V)
    state_diagnostics(S, P, D, w0, w1, w2, q0, q1, q2)


@kernel(inline="always")
def state_diagnostics(S, P, D, w0, w1, w2, q0, q1, q2):
    """:func:`diagnostics` once ``D.V`` holds the node velocities and (w, q) the body's Omega (body
    frame) [rad/s] and R (rho_c x Omega) [m/s]: shared with a drone at an offset hook, whose
    velocities couple both ends (kernels/drone/hook.py)."""
    r = S.r
    p = S.p
    R = S.R
    Pi = S.Pi
    V = D.V
    strain = D.strain
    omega = D.omega
    out = D.out
    n = r.shape[0] - 1
    M = P.M
    rho0 = P.rho[0]
    rho1 = P.rho[1]
    rho2 = P.rho[2]
    omega[0] = w0
    omega[1] = w1
    omega[2] = w2
    ts, tb, tp = kinetic_energies(V, w0, w1, w2, q0, q1, q2, P)
    vg = 0.0
    for a in range(n):
        vg += r[a, 2] + r[a + 1, 2]
    zc = R[2, 0] * rho0 + R[2, 1] * rho1 + R[2, 2] * rho2
    pot_g = -P.g * (0.5 * P.m * vg + M * (r[n, 2] + zc) + P.Mp * r[0, 2])
    pot_e, length = element_strain(r, P.kappa, P.u, P.slack, strain)
    # pi3 = e3 . (sum r_a x p_a + R Pi); total linear momentum sum p_a
    pi3 = R[2, 0] * Pi[0] + R[2, 1] * Pi[1] + R[2, 2] * Pi[2]
    P0 = 0.0
    P1 = 0.0
    P2 = 0.0
    for a in range(n + 1):
        pi3 += r[a, 0] * p[a, 1] - r[a, 1] * p[a, 0]
        P0 += p[a, 0]
        P1 += p[a, 1]
        P2 += p[a, 2]
    # || I - R^T R ||_F
    orth = 0.0
    for i in range(3):
        for j in range(3):
            s = R[0, i] * R[0, j] + R[1, i] * R[1, j] + R[2, i] * R[2, j]
            if i == j:
                s -= 1.0
            orth += s * s
    out[D_KINETIC_STRING] = ts
    out[D_KINETIC_BODY] = tb
    out[D_POTENTIAL_GRAVITY] = pot_g
    out[D_POTENTIAL_ELASTIC] = pot_e
    out[D_ENERGY] = ts + tb + tp + pot_g + pot_e
    out[D_PI3] = pi3
    out[D_ORTHOGONALITY] = math.sqrt(orth)
    out[D_STRETCHED_LENGTH] = length
    out[D_KINETIC_PIVOT] = tp
    out[D_LINEAR_MOMENTUM] = P0
    out[D_LINEAR_MOMENTUM + 1] = P1
    out[D_LINEAR_MOMENTUM + 2] = P2
