"""Plain-NumPy reference path of the LGVI: the paper's derivative formulas and a dense Newton step.

This module is deliberately independent of :mod:`esp_gym.kernels` (no numba, no Schur
complement, no tridiagonal solve): it is what the compiled stepper is checked against.

Notation (Lee, Leok & McClamroch, section "Lie Group Variational Integrator"); SI units.
Nodes are rows of an ``(N+1, 3)`` array, row 0 the fixed pivot (paper node 1), row N the
attachment node (paper node N+1); element ``e`` (0-based) joins rows ``e`` and ``e+1``.
The step ``f_k = (dr, F)`` moves ``r_{k+1} = r_k + dr`` and ``R_{k+1} = R_k F``; ``dr[0] = 0``.

The rotation increment is passed as ``E = F - I`` everywhere: ``F = I + O(h)``, and every
formula below is rewritten in ``E`` by exact algebra (``J_d F - F^T J_d = J_d E - E^T J_d``,
``F x = x + E x``), so no digit is lost to ``F - I`` cancellation (docs/physics.md, "Round-off").

Derivatives (errata 1-3 in docs/physics.md fixed; grad V^e_{k,a} = kappa (|x| - u)/|x| x,
x = r_{k,a+1} - r_{k,a})::

    (DdrLd)  D_{dr_a} L_d = m/(6h) (dr_{a-1} + 4 dr_a + dr_{a+1}) + h/2 m g e3
                            + h/2 grad V^e_{k+1,a} - h/2 grad V^e_{k+1,a-1}           a = 2..N
             D_{r_a}  L_d = h m g e3 + h/2 (grad V^e_{k,a} + grad V^e_{k+1,a})
                            - h/2 (grad V^e_{k,a-1} + grad V^e_{k+1,a-1})             a = 2..N
             D_{dr_{N+1}} L_d = (M + m/3)/h dr_{N+1} + m/(6h) dr_N + M/h R_k (F_k - I) rho_c
                                + h/2 (M + m/2) g e3 - h/2 grad V^e_{k+1,N}
             D_{r_{N+1}}  L_d = h (M + m/2) g e3 - h/2 (grad V^e_{k,N} + grad V^e_{k+1,N})
    (DFLd)   T_I^*L_F . D_F L_d = 1/h (J_d F - F^T J_d)^vee + rho_c^ F^T A_k,
             A_k = M/h R_k^T dr_{N+1} + h/2 M g R_k^T e3
    (DRLd)   T_I^*L_R . D_R L_d = M/h ((F - I) rho_c)^ R_k^T dr_{N+1}
                                  + h/2 M g rho_c^ R_k^T e3 + h/2 M g (F rho_c)^ R_k^T e3

Discrete Legendre transforms (co-Ad: Ad^*_{F^{-1}} x = F x)::

    p_k  = -D_1 L_d = D_dr L_d - D_r L_d,        Pi_k     = F (DFLd) - (DRLd)
    p_{k+1} = D_2 L_d = D_dr L_d,                Pi_{k+1} = (DFLd)

:func:`reference_step` solves the left transform for all 3N+3 unknowns (dr of the free nodes
and the Cayley vector f of F) by a dense Newton iteration whose Jacobian is formed by
complex-step differentiation (exact to round-off), then evaluates the right transform.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..scene.params import Scene

if TYPE_CHECKING:  # esp_gym.physics.simulator imports the kernels; only its State type is needed here
    from ..physics.state import State

E3 = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Constants:
    """The scene constants that enter the discrete Lagrangian (SI units)."""

    h: float  #: time step [s]
    u: float  #: unstretched element length l/N [m]
    m: float  #: element mass mu u [kg]
    kappa: float  #: element stiffness EA/u [N/m]
    g: float  #: gravitational acceleration along +e3 [m/s^2]
    M: float  #: body mass [kg]
    rho: np.ndarray  #: attachment point -> centre of mass, body frame [m]
    J: np.ndarray  #: inertia about the attachment point, body frame [kg m^2]
    Jd: np.ndarray  #: nonstandard inertia tr(J)/2 I - J [kg m^2]

    @classmethod
    def from_scene(cls, scene: Scene) -> "Constants":
        J = scene.body.J
        return cls(
            h=float(scene.h), u=float(scene.string.u), m=float(scene.string.m),
            kappa=float(scene.string.kappa), g=float(scene.gravity), M=float(scene.body.mass),
            rho=np.array(scene.body.rho_c, dtype=float), J=J,
            Jd=0.5 * np.trace(J) * np.eye(3) - J,
        )


# -- so(3) helpers (dtype-agnostic: they also run on complex arrays for the complex step) --------
def hat(v) -> np.ndarray:
    """The hat map, ``hat(v) @ y == v x y``."""
    return np.array([[0.0 * v[0], -v[2], v[1]], [v[2], 0.0 * v[0], -v[0]], [-v[1], v[0], 0.0 * v[0]]])


def cross(a, b) -> np.ndarray:
    """``a x b`` for 3-vectors (np.cross's generality costs more than the rest of a residual)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def vee(S) -> np.ndarray:
    """Inverse of :func:`hat` for a skew-symmetric ``S``."""
    return np.array([S[2, 1], S[0, 2], S[1, 0]])


def cayley_minus_identity(f) -> np.ndarray:
    """``F - I`` for ``F = cay(f) = (I - f^)^-1 (I + f^)``, as ``2 (I - f^)^-1 f^`` (no cancellation)."""
    fh = hat(f)
    return 2.0 * np.linalg.solve(np.eye(3) - fh, fh)


# -- the paper's derivative formulas ------------------------------------------------------------
def elastic_gradients(c: Constants, r) -> np.ndarray:
    """grad V^e_a = kappa (|x_a| - u)/|x_a| x_a for every element, x_a = r_{a+1} - r_a; (N, 3) [N]."""
    x = r[1:] - r[:-1]
    length = np.sqrt(np.sum(x * x, axis=1))  # not np.linalg.norm: stays analytic for complex input
    return (c.kappa * (1.0 - c.u / length))[:, None] * x


def D_dr_Ld(c: Constants, r, R, dr, E) -> np.ndarray:
    """D_{dr_a} L_d for every node, (N+1, 3) [kg m/s]; row 0 (the pivot) is 0.

    Rows 1..N-1: (DdrLd). Row N (the attachment node): the node-(N+1) formula with the body.
    """
    n = r.shape[0] - 1
    h, m, M = c.h, c.m, c.M
    G1 = elastic_gradients(c, r + dr)  # grad V^e_{k+1}
    out = np.zeros(np.shape(r), dtype=np.result_type(r, dr, E))
    # interior nodes a = 1..N-1 (rows): neighbours a-1, a+1; elements a (right) and a-1 (left)
    out[1:n] = (m / (6.0 * h) * (dr[:n - 1] + 4.0 * dr[1:n] + dr[2:]) + 0.5 * h * m * c.g * E3
                + 0.5 * h * G1[1:n] - 0.5 * h * G1[:n - 1])
    out[n] = ((M + m / 3.0) / h * dr[n] + m / (6.0 * h) * dr[n - 1] + M / h * (R @ (E @ c.rho))
              + 0.5 * h * (M + 0.5 * m) * c.g * E3 - 0.5 * h * G1[n - 1])
    return out


def D_r_Ld(c: Constants, r, R, dr, E) -> np.ndarray:
    """D_{r_a} L_d (at fixed dr) for every node, (N+1, 3) [kg m/s]; row 0 (the pivot) is 0."""
    n = r.shape[0] - 1
    h, m, M = c.h, c.m, c.M
    G = elastic_gradients(c, r) + elastic_gradients(c, r + dr)  # grad V^e_k + grad V^e_{k+1}
    out = np.zeros(np.shape(r), dtype=np.result_type(r, dr, E))
    out[1:n] = h * m * c.g * E3 + 0.5 * h * G[1:n] - 0.5 * h * G[:n - 1]
    out[n] = h * (M + 0.5 * m) * c.g * E3 - 0.5 * h * G[n - 1]
    return out


def _A(c: Constants, R, dr_attach) -> np.ndarray:
    """A_k = M/h R_k^T dr_{N+1} + h/2 M g R_k^T e3 [kg m/s]."""
    return c.M / c.h * (R.T @ dr_attach) + 0.5 * c.h * c.M * c.g * (R.T @ E3)


def DF_Ld(c: Constants, R, dr_attach, E) -> np.ndarray:
    """(DFLd) T_I^*L_F . D_F L_d = 1/h (J_d F - F^T J_d)^vee + rho_c^ F^T A_k [kg m^2/s], F = I + E."""
    A = _A(c, R, dr_attach)
    return vee(c.Jd @ E - E.T @ c.Jd) / c.h + cross(c.rho, A + E.T @ A)


def co_Ad(E, x) -> np.ndarray:
    """Ad^*_{F^{-1}} x = F x for F = I + E (the paper's co-Ad on the SO(3) factor)."""
    return x + E @ x


def AdDF_Ld(c: Constants, R, dr_attach, E) -> np.ndarray:
    """(AdDFLd) 1/h (F J_d - J_d F^T)^vee + (F rho_c)^ A_k [kg m^2/s], written out, F = I + E."""
    A = _A(c, R, dr_attach)
    return vee(E @ c.Jd - c.Jd @ E.T) / c.h + cross(c.rho + E @ c.rho, A)


def DR_Ld(c: Constants, R, dr_attach, E) -> np.ndarray:
    """(DRLd) T_I^*L_R . D_R L_d [kg m^2/s], F = I + E."""
    Mg = c.M * c.g
    z = R.T @ E3
    return (c.M / c.h * cross(E @ c.rho, R.T @ dr_attach) + 0.5 * c.h * Mg * cross(c.rho, z)
            + 0.5 * c.h * Mg * cross(c.rho + E @ c.rho, z))


def left_momenta(c: Constants, r, R, dr, E):
    """p_k = -D_1 L_d: ``(p (N+1, 3) [kg m/s], Pi (3,) [kg m^2/s])``; row 0 of p is 0."""
    p = D_dr_Ld(c, r, R, dr, E) - D_r_Ld(c, r, R, dr, E)
    Pi = AdDF_Ld(c, R, dr[-1], E) - DR_Ld(c, R, dr[-1], E)
    return p, Pi


def right_momenta(c: Constants, r, R, dr, E):
    """p_{k+1} = D_2 L_d: ``(p (N+1, 3) [kg m/s], Pi (3,) [kg m^2/s])``; row 0 of p is 0."""
    return D_dr_Ld(c, r, R, dr, E), DF_Ld(c, R, dr[-1], E)


# -- the step -----------------------------------------------------------------------------------
@dataclass
class NewtonInfo:
    """Outcome of one dense Newton solve of the left Legendre transform."""

    iterations: int
    converged: bool
    last_update: float  #: |dx| / |x| of the last Newton update


def _unpack(x, n):
    dr = np.zeros((n + 1, 3), dtype=x.dtype)
    dr[1:] = x[:3 * n].reshape(n, 3)
    return dr, cayley_minus_identity(x[3 * n:])


def _residual(c, r, R, p, Pi, x):
    """-D_1 L_d(q_k; dr, F(f)) - (p_k, Pi_k) on the 3N+3 unknowns x = (dr_2..dr_{N+1}, f)."""
    n = r.shape[0] - 1
    dr, E = _unpack(x, n)
    pk, Pik = left_momenta(c, r, R, dr, E)
    return np.concatenate([(pk[1:] - p[1:]).ravel(), Pik - Pi])


def _jacobian(c, r, R, p, Pi, x):
    """d residual/dx by the complex step: Im(res(x + i t e_j))/t, exact to round-off."""
    t = 1e-30
    jac = np.empty((x.size, x.size))
    xc = x.astype(complex)
    for j in range(x.size):
        xc[j] += 1j * t
        jac[:, j] = _residual(c, r, R, p, Pi, xc).imag / t
        xc[j] = x[j]
    return jac


def solve_left_legendre(c: Constants, r, R, p, Pi, rtol: float = 1e-15, max_iter: int = 30):
    """Solve p_k = -D_1 L_d(q_k, f_k) for f_k = (dr, F) by dense Newton from dr = 0, F = I.

    Stops when the update is at most ``rtol`` times the iterate (2-norms over all 3N+3
    unknowns), or, once the update has reached round-off (|dx| <= 1e-13 |x|), when it stops
    shrinking. Returns ``(dr (N+1, 3) [m], E = F - I, NewtonInfo)``.
    """
    n = r.shape[0] - 1
    x = np.zeros(3 * n + 3)
    prev = np.inf
    rel = np.inf
    for it in range(1, max_iter + 1):
        res = _residual(c, r, R, p, Pi, x)
        dx = np.linalg.solve(_jacobian(c, r, R, p, Pi, x), -res)
        x = x + dx
        size = np.linalg.norm(x)
        rel = np.linalg.norm(dx) / size if size > 0 else 0.0
        if rel <= rtol or (rel <= 1e-13 and rel >= 0.5 * prev):
            dr, E = _unpack(x, n)
            return dr, E, NewtonInfo(it, True, rel)
        prev = rel
    dr, E = _unpack(x, n)
    return dr, E, NewtonInfo(max_iter, False, rel)


def reference_step(scene: Scene, state: "State", rtol: float = 1e-15, max_iter: int = 30) -> "State":
    """One LGVI step ``(q_k, p_k) -> (q_{k+1}, p_{k+1})`` in plain NumPy; returns a new state of
    the same type as ``state`` (:class:`esp_gym.physics.simulator.State`). Raises RuntimeError if Newton fails.

    Solves ``p_k = -D_1 L_d`` densely for (dr, F), then ``r_{k+1} = r_k + dr``,
    ``R_{k+1} = R_k F``, ``p_{k+1} = D_dr L_d``, ``Pi_{k+1} = (DFLd)``. The pivot row is copied.
    """
    c = Constants.from_scene(scene)
    r = np.asarray(state.r, dtype=float)
    R = np.asarray(state.R, dtype=float)
    p = np.asarray(state.p, dtype=float)
    Pi = np.asarray(state.Pi, dtype=float)
    dr, E, info = solve_left_legendre(c, r, R, p, Pi, rtol=rtol, max_iter=max_iter)
    if not info.converged:
        raise RuntimeError(f"reference Newton did not converge in {max_iter} iterations "
                           f"(last relative update {info.last_update:.3g}) at step {state.step}")
    p_new, Pi_new = right_momenta(c, r, R, dr, E)
    p_new[0] = p[0]
    return type(state)(r=r + dr, p=p_new, R=R + R @ E, Pi=Pi_new, step=state.step + 1)


def reference_run(scene: Scene, state: "State", nsteps: int) -> "State":
    """``nsteps`` applications of :func:`reference_step`; returns the last state."""
    for _ in range(int(nsteps)):
        state = reference_step(scene, state)
    return state
