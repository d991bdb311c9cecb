"""The inverse of a team's continuous Legendre transform (docs/physics.md, "Diagnostics of a
team"): node velocities and the body's from the momenta, each string reduced to its end."""
from __future__ import annotations

import numpy as np
from scipy.linalg import LinAlgError, lapack

from ..physics.state import cross3
from ..scene.stability import hat
from .assembly import banded


def tridiagonal_solve(ab, b):
    """``scipy.linalg.solve_banded((1, 1), ab, b)``, bit for bit: the same LAPACK routine (gtsv)
    on the same arrays, without the wrapper's per-call validation, which was half of a team
    environment's inverse Legendre transform. ValueError for a non-finite entry, LinAlgError for
    a singular matrix, as there."""
    if not (np.isfinite(ab).all() and np.isfinite(b).all()):
        raise ValueError("array must not contain infs or NaNs")
    if ab.shape[1] == 1:  # a 1 x 1 matrix: SciPy divides
        return b / ab[1, 0]
    _, _, _, x, info = lapack.dgtsv(ab[2, :-1], ab[1, :], ab[0, 1:], b)
    if info > 0:
        raise LinAlgError("singular matrix")
    return x


def team_velocities(members, M: float, rho_c, J, R, px, Pi):
    """``members``: each string's ``(diagonal (N+1,), off-diagonal, first moving row, momenta of
    its rows before the end (N, 3), rho (3,))`` of its mass matrix without the body, string 0
    first (rho 0); ``M`` [kg], ``rho_c`` [m], ``J`` [kg m^2] the body's; ``R`` its attitude;
    ``px`` (3,) the body's translational momentum (string 0's last row: the body's and every
    end's share) and ``Pi`` (3,) its angular one. Returns ``(each string's node velocities
    (N_k+1, 3), Omega (3,))`` [m/s, rad/s]."""
    solves, mus, cs = [], [], []
    for diag, off, first, p, rho in members:
        n = diag.shape[0] - 1
        lo = first
        if n - 1 >= lo:
            ab = banded(diag[lo:n], off)
            y = tridiagonal_solve(ab, p[lo:n])
            e = np.zeros(n - lo)
            e[-1] = 1.0
            col = tridiagonal_solve(ab, e)
            mu, c = diag[n] - off * off * col[-1], off * y[-1]
        else:
            ab, y, col, mu, c = None, None, None, float(diag[n]), np.zeros(3)
        solves.append((ab, y, col, lo, n))
        mus.append(mu)
        cs.append(c)
    rhos = [m[4] for m in members]
    Mt = M + sum(mus)
    St = M * rho_c + sum(mu * r for mu, r in zip(mus, rhos))
    Jt = J + sum(mu * (r @ r * np.eye(3) - np.outer(r, r)) for mu, r in zip(mus, rhos))
    px = px - sum(cs)
    Pt = Pi - sum(cross3(r, R.T @ c) for r, c in zip(rhos, cs))
    K6 = np.zeros((6, 6))
    K6[:3, :3] = Mt * np.eye(3)
    K6[:3, 3:] = -hat(St)
    K6[3:, :3] = hat(St)
    K6[3:, 3:] = Jt
    sol = np.linalg.solve(K6, np.concatenate([R.T @ px, Pt]))
    V, Omega = R @ sol[:3], sol[3:]
    out = []
    for (diag, off, first, p, rho), (ab, y, col, lo, n) in zip(members, solves):
        v = np.zeros((n + 1, 3))
        v[n] = V + R @ cross3(Omega, rho)
        if ab is not None:
            v[lo:n] = y - off * col[:, None] * v[n]
        out.append(v)
    return out, Omega
