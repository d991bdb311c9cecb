"""Compiled right-hand side of the finite-element model as a first-order ODE, and a fixed-step
RK4 on it: the general-purpose baselines of ``benchmarks/work_precision.py``.

The model, the state layout and the derivation are in ``esp_gym/verify/ode.py`` (its Python face,
:class:`~esp_gym.verify.ode.ElasticStringODE`). The kernels are compiled with the product's
options (esp_gym/kernels/jit.py ``kernel``: no numba runtime, so no reference counting in the
loops, and the comparison with the LGVI is between equally lean kernels) and cached beside its
kernels, but they live outside esp_gym/kernels/, whose sources alone key that cache: a change
here recompiles these kernels only.
"""
from collections import namedtuple

import numpy as np

from ..kernels.jit import kernel
from ..kernels.layout import IN_BODY_TORQUE, IN_PIVOT_FORCE, IN_SPATIAL_TORQUE
from ..kernels.so3 import solve3
from ..kernels.step.string import nodal_forces, tridiag_solve

#: Scratch of the right-hand side: full (N+1, 3) node positions (row 0 holds the fixed pivot),
#: forces and the solve's right-hand side / solution.
ODEWork = namedtuple("ODEWork", "r f X")


@kernel(entry=True)
def ode_rhs(y, P, r0, inputs, W, dy):
    """Write ``f(y)`` (the ODE of this module's docstring) into ``dy``; returns 0.

    ``P``: :class:`esp_gym.kernels.layout.LGVIParams` (h, tol, max_iter are not used); ``r0``
    (3,) the fixed pivot's position [m]; ``inputs`` (9,) = (u_p [N, spatial], tau [N m, body],
    T [N m, spatial]); ``W`` an :class:`ODEWork`. Non-finite inputs give non-finite output
    (no exception): callers check.
    """
    r = W.r
    f = W.f
    X = W.X
    n = r.shape[0] - 1
    first = P.first
    nf = n + 1 - first
    ov = 3 * nf  # offset of v in y
    oR = 6 * nf  # offset of R
    oW = oR + 9  # offset of Omega
    M = P.M
    rho0 = P.rho[0]
    rho1 = P.rho[1]
    rho2 = P.rho[2]
    for a in range(first):
        r[a, 0] = r0[0]
        r[a, 1] = r0[1]
        r[a, 2] = r0[2]
    for a in range(first, n + 1):
        j = 3 * (a - first)
        r[a, 0] = y[j]
        r[a, 1] = y[j + 1]
        r[a, 2] = y[j + 2]
        dy[j] = y[ov + j]
        dy[j + 1] = y[ov + j + 1]
        dy[j + 2] = y[ov + j + 2]
    R00 = y[oR]
    R01 = y[oR + 1]
    R02 = y[oR + 2]
    R10 = y[oR + 3]
    R11 = y[oR + 4]
    R12 = y[oR + 5]
    R20 = y[oR + 6]
    R21 = y[oR + 7]
    R22 = y[oR + 8]
    w0 = y[oW]
    w1 = y[oW + 1]
    w2 = y[oW + 2]
    # R' = R Omega^ (column j of Omega^ is Omega x e_j)
    dy[oR] = R01 * w2 - R02 * w1
    dy[oR + 1] = R02 * w0 - R00 * w2
    dy[oR + 2] = R00 * w1 - R01 * w0
    dy[oR + 3] = R11 * w2 - R12 * w1
    dy[oR + 4] = R12 * w0 - R10 * w2
    dy[oR + 5] = R10 * w1 - R11 * w0
    dy[oR + 6] = R21 * w2 - R22 * w1
    dy[oR + 7] = R22 * w0 - R20 * w2
    dy[oR + 8] = R20 * w1 - R21 * w0
    # (T) with Omega' = 0: f(r) - M e_N R (Omega x (Omega x rho_c)) + e_0 u_p
    nodal_forces(r, P.kappa, P.u, P.m, M, P.Mp, P.g, P.slack, f)
    if first == 0:
        f[0, 0] += inputs[IN_PIVOT_FORCE]
        f[0, 1] += inputs[IN_PIVOT_FORCE + 1]
        f[0, 2] += inputs[IN_PIVOT_FORCE + 2]
    x0 = w1 * rho2 - w2 * rho1  # Omega x rho_c
    x1 = w2 * rho0 - w0 * rho2
    x2 = w0 * rho1 - w1 * rho0
    c0 = w1 * x2 - w2 * x1  # Omega x (Omega x rho_c)
    c1 = w2 * x0 - w0 * x2
    c2 = w0 * x1 - w1 * x0
    f[n, 0] -= M * (R00 * c0 + R01 * c1 + R02 * c2)
    f[n, 1] -= M * (R10 * c0 + R11 * c1 + R12 * c2)
    f[n, 2] -= M * (R20 * c0 + R21 * c1 + R22 * c2)
    tridiag_solve(P.inv, P.cp, P.off, first, f, X)
    # (Rot) after the Schur complement
    J = P.J
    Jw0 = J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2
    Jw1 = J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2
    Jw2 = J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2
    Mg = M * P.g
    e0 = R00 * X[n, 0] + R10 * X[n, 1] + R20 * X[n, 2]  # R^T Y_N
    e1 = R01 * X[n, 0] + R11 * X[n, 1] + R21 * X[n, 2]
    e2 = R02 * X[n, 0] + R12 * X[n, 1] + R22 * X[n, 2]
    ts0 = inputs[IN_SPATIAL_TORQUE]
    ts1 = inputs[IN_SPATIAL_TORQUE + 1]
    ts2 = inputs[IN_SPATIAL_TORQUE + 2]
    b0 = (-(w1 * Jw2 - w2 * Jw1) + Mg * (rho1 * R22 - rho2 * R21) + inputs[IN_BODY_TORQUE]
          + (R00 * ts0 + R10 * ts1 + R20 * ts2) - M * (rho1 * e2 - rho2 * e1))
    b1 = (-(w2 * Jw0 - w0 * Jw2) + Mg * (rho2 * R20 - rho0 * R22) + inputs[IN_BODY_TORQUE + 1]
          + (R01 * ts0 + R11 * ts1 + R21 * ts2) - M * (rho2 * e0 - rho0 * e2))
    b2 = (-(w0 * Jw1 - w1 * Jw0) + Mg * (rho0 * R21 - rho1 * R20) + inputs[IN_BODY_TORQUE + 2]
          + (R02 * ts0 + R12 * ts1 + R22 * ts2) - M * (rho0 * e1 - rho1 * e0))
    d0, d1, d2 = solve3(P.Jeff, b0, b1, b2)
    dy[oW] = d0
    dy[oW + 1] = d1
    dy[oW + 2] = d2
    # a = Y + M w R (rho_c x Omega')
    z0 = rho1 * d2 - rho2 * d1
    z1 = rho2 * d0 - rho0 * d2
    z2 = rho0 * d1 - rho1 * d0
    q0 = M * (R00 * z0 + R01 * z1 + R02 * z2)
    q1 = M * (R10 * z0 + R11 * z1 + R12 * z2)
    q2 = M * (R20 * z0 + R21 * z1 + R22 * z2)
    w = P.w
    for a in range(first, n + 1):
        j = ov + 3 * (a - first)
        dy[j] = X[a, 0] + w[a] * q0
        dy[j + 1] = X[a, 1] + w[a] * q1
        dy[j + 2] = X[a, 2] + w[a] * q2
    return 0


@kernel(entry=True)
def ode_rhs_columns(Y, P, r0, inputs, W, y, dy, dY):
    """:func:`ode_rhs` for each column of ``Y`` (size, k) into ``dY`` (SciPy's ``vectorized``
    form, used by the finite-difference Jacobian of Radau and BDF); ``y``, ``dy`` (size,)
    are scratch."""
    for c in range(Y.shape[1]):
        for i in range(Y.shape[0]):
            y[i] = Y[i, c]
        ode_rhs(y, P, r0, inputs, W, dy)
        for i in range(Y.shape[0]):
            dY[i, c] = dy[i]


@kernel(entry=True)
def rk4_run(y, h, nsteps, every, P, r0, inputs, W, K, out):
    """Classical fixed-step RK4 on :func:`ode_rhs`: ``nsteps`` steps of ``h`` [s] from ``y``
    (advanced in place), storing the state after every ``every`` steps in ``out`` (rows 1..;
    row 0 = the start). ``K`` (5, size) is scratch (the four stages and the stage state).

    Returns the number of steps taken: fewer than ``nsteps`` if the state became non-finite
    (then the rows after the last good sample are left untouched).
    """
    size = y.shape[0]
    k1 = K[0]
    k2 = K[1]
    k3 = K[2]
    k4 = K[3]
    yt = K[4]
    h2 = 0.5 * h
    h6 = h / 6.0
    for i in range(size):
        out[0, i] = y[i]
    row = 1
    for k in range(nsteps):
        ode_rhs(y, P, r0, inputs, W, k1)
        for i in range(size):
            yt[i] = y[i] + h2 * k1[i]
        ode_rhs(yt, P, r0, inputs, W, k2)
        for i in range(size):
            yt[i] = y[i] + h2 * k2[i]
        ode_rhs(yt, P, r0, inputs, W, k3)
        for i in range(size):
            yt[i] = y[i] + h * k3[i]
        ode_rhs(yt, P, r0, inputs, W, k4)
        total = 0.0
        for i in range(size):
            y[i] += h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
            total += y[i]
        if not np.isfinite(total):
            return k
        if (k + 1) % every == 0 and row < out.shape[0]:
            for i in range(size):
                out[row, i] = y[i]
            row += 1
    return nsteps
