"""The Lie group variational integrator of the elastic string pendulum, with inputs.

The paper writes the scheme as a two-step recursion (DEL0)-(DEL4). We run its equivalent
one-step (position-momentum) form: with the discrete Legendre transforms
``p_k = -D_1 L_d(g_k, f_k)`` and ``p_{k+1} = D_2 L_d(g_k, f_k)`` the map
``(g_k, p_k) -> (g_{k+1}, p_{k+1})`` is the same flow, and the momenta give the diagnostics.

From the discrete Lagrangian (Ldka), (Ldkrb) with errata 1-2 fixed, for nodes a = 2..N+1
(row 1..N here) and the body (notation of the paper; f_a(r) = -dV/dr_a, see nodal_forces)::

    (1/h) M_tot dr  +  (M/h) e_{N+1} (R_k (F_k - I) rho_c)   = p_k + (h/2) f(r_k)        (1)
    (1/h)(F_k J_d - J_d F_k^T)^vee + (M/h) rho_c^ R_k^T dr_{N+1} = Pi_k + (h/2) tau_g(R_k)   (2)
    p_{k+1}  = p_k + (h/2) (f(r_k) + f(r_{k+1}))                                           (3)
    Pi_{k+1} = (1/h)(J_d F_k - F_k^T J_d)^vee + (M/h) rho_c^ R_{k+1}^T dr_{N+1}
               + (h/2) tau_g(R_{k+1})                                                      (4)

with M_tot the consistent mass matrix (m/6)[1 4 1] with last diagonal M + m/3, and
tau_g(R) = M g rho_c x (R^T e3) the gravity torque about the attachment point (body frame).
(1) is linear in dr; eliminating it (Schur complement, s = (M_tot^-1)_{N+1,N+1},
w = M_tot^-1 e_{N+1}) gives dr = h M_tot^-1 B - M w (R_k (F_k - I) rho_c) and turns (2) into

    (F_k K - K F_k^T)^vee = h Pi_k + (h^2/2) tau_g - M rho_c x (R_k^T d),   d = h (M_tot^-1 B)_{N+1}
    K = J_d - M^2 s rho_c rho_c^T,  i.e. tr(K) I - K = J_eff = J + M^2 s rho_c^ rho_c^,

a rigid-body equation with a modified inertia, solved by Newton on the Cayley vector.

Inputs (docs/physics.md, "Inputs through the discrete Lagrange–d'Alembert principle") are held
constant over a step and enter as discrete forces split half and half, f_d^- = f_d^+ = (h/2) u:

* a free pivot (row 0 unknown, point mass M_p) pushed by the spatial force u_p: (h/2) u_p joins
  the right-hand side of (1) at row 0, and (3) gains h u_p there;
* a body torque tau (body frame) and a spatial torque T: the left half uses
  tau^- = tau + R_k^T T in (2), the right half tau^+ = tau + R_{k+1}^T T in (4).

With zero inputs and a fixed pivot every added term is an exact zero, so the scheme is the
paper's, bit for bit.
"""
import numpy as np

from ..jit import kernel
from ..so3 import cayley_minus_identity, cayley_newton
from ..status import NEWTON_FAILED, NON_FINITE, OK
from .step_shared import commit_step, held_inputs, left_torque, new_positions
from .string import string_solve
from .switch import settle_switches, switch_errors


# LLVM-inlined, not numba-IR-inlined: compiled once per signature instead of deep-copied
# into every caller (kernels/jit.py); the cold start of the env's first step halved.
@kernel(forceinline=True)
def explicit_increments(S, W, P, h, up0, up1, up2, t0, t1, t2, free, forced, coupled):
    """(1) and (2) with the string's forces ``S.f`` of the state: the string solve, the Schur
    complement and Newton on the Cayley vector c of F_k. Writes the increments dr of the
    unknown nodes into ``W.Y`` (no remainders added; ``W.X`` is scratch) and F_k - I into
    ``W.FmI``; ``t`` is the left torque (:func:`left_torque`), ``up`` the pivot force. The
    explicit step, and the implicit string's first guess. Returns ``(c (3), e = R_k^T dr_{N+1}
    (3), the pivot's displacement (3, when free and forced), iterations, status)``."""
    first = 0 if free else 1
    # (1): right-hand side and the string solve with F_k = I
    string_solve(P.inv, P.cp, first, S.p, S.f, 0.5 * h, up0, up1, up2, free and forced, W.X)
    return rigid_increments(S, W, P, h, P.M, P.rho, P.Jeff, P.w, t0, t1, t2, free, forced, coupled)


@kernel(inline="always")
def load_rhs(S, M, rho, X, h, t, forced, coupled):
    """The right-hand side of the load's (2) after the Schur complement, once ``X`` holds the
    string solve with F_k = I: g = h Pi + h^2/2 t - M rho_c x (R_k^T d) with d = h X_{N+1} and
    the left torque ``t`` (body frame) [N m], for the load's inertial mass ``M`` [kg] and
    attachment -> centre of mass ``rho`` (body frame) [m] (P.M, P.rho; a team's body with its
    other strings' end masses: kernels/team/step.py). Returns ``(g (3), d (3), e = R_k^T d (3))``,
    e = 0 when not ``coupled``."""
    R = S.R
    Pi = S.Pi
    hh = 0.5 * h
    n = X.shape[0] - 1
    rho0 = rho[0]
    rho1 = rho[1]
    rho2 = rho[2]
    t0, t1, t2 = t
    d0 = h * X[n, 0]
    d1 = h * X[n, 1]
    d2 = h * X[n, 2]
    e0 = e1 = e2 = 0.0
    if coupled:
        e0 = R[0, 0] * d0 + R[1, 0] * d1 + R[2, 0] * d2  # R^T d
        e1 = R[0, 1] * d0 + R[1, 1] * d1 + R[2, 1] * d2
        e2 = R[0, 2] * d0 + R[1, 2] * d1 + R[2, 2] * d2
        g0 = h * (Pi[0] + hh * t0) - M * (rho1 * e2 - rho2 * e1)
        g1 = h * (Pi[1] + hh * t1) - M * (rho2 * e0 - rho0 * e2)
        g2 = h * (Pi[2] + hh * t2) - M * (rho0 * e1 - rho1 * e0)
    elif forced:
        g0 = h * (Pi[0] + hh * t0)
        g1 = h * (Pi[1] + hh * t1)
        g2 = h * (Pi[2] + hh * t2)
    else:
        g0 = h * Pi[0]
        g1 = h * Pi[1]
        g2 = h * Pi[2]
    return g0, g1, g2, d0, d1, d2, e0, e1, e2


@kernel(inline="always")
def end_shift(R, FmI, rho):
    """s = (F - I) rho and q = R (F - I) rho [m]: how far a body's turn over the step moves the
    point at ``rho`` from its centre of mass (body frame) relative to its string end. Returns
    ``(s (3), q (3))``."""
    rho0 = rho[0]
    rho1 = rho[1]
    rho2 = rho[2]
    s0 = FmI[0, 0] * rho0 + FmI[0, 1] * rho1 + FmI[0, 2] * rho2
    s1 = FmI[1, 0] * rho0 + FmI[1, 1] * rho1 + FmI[1, 2] * rho2
    s2 = FmI[2, 0] * rho0 + FmI[2, 1] * rho1 + FmI[2, 2] * rho2
    q0 = R[0, 0] * s0 + R[0, 1] * s1 + R[0, 2] * s2
    q1 = R[1, 0] * s0 + R[1, 1] * s1 + R[1, 2] * s2
    q2 = R[2, 0] * s0 + R[2, 1] * s1 + R[2, 2] * s2
    return s0, s1, s2, q0, q1, q2


@kernel(inline="always")
def string_increments(X, Y, w, M, q, h, first, coupled):
    """The increments dr = h X - M w q of the unknown nodes into ``Y`` (rows from ``first``):
    the string solve ``X`` with F_k = I, corrected by the load's turn q = R_k (F_k - I) rho_c
    through its column ``w`` = M^-1 e_{N+1} when ``coupled``."""
    q0, q1, q2 = q
    for a in range(first, X.shape[0]):
        y0 = h * X[a, 0]
        y1 = h * X[a, 1]
        y2 = h * X[a, 2]
        if coupled:
            y0 = y0 - M * w[a] * q0
            y1 = y1 - M * w[a] * q1
            y2 = y2 - M * w[a] * q2
        Y[a, 0] = y0
        Y[a, 1] = y1
        Y[a, 2] = y2


@kernel(forceinline=True)
def rigid_increments(S, W, P, h, M, rho, Jeff, w, t0, t1, t2, free, forced, coupled):
    """The rest of :func:`explicit_increments` once ``W.X`` holds the string solve with F_k = I
    (X = M^-1 B): the Schur complement (``w`` = M^-1 e_{N+1}, ``Jeff`` = J + M^2 w_{N+1}
    rho_c^ rho_c^), Newton on the Cayley vector of F_k and the increments dr into ``W.Y``, for the
    load's inertial mass ``M`` and offset ``rho`` (:func:`load_rhs`). Shared with the winch's step
    (kernels/step/winch.py), whose matrix is the step's own, and a team's (kernels/team/step.py), whose load
    carries its other strings' ends. Returns as :func:`explicit_increments`."""
    X = W.X
    n = X.shape[0] - 1
    # (2) after the Schur complement: g = h Pi + h^2/2 tau_k - M rho_c x (R_k^T d)
    g0, g1, g2, d0, d1, d2, e0, e1, e2 = load_rhs(S, M, rho, X, h, (t0, t1, t2), forced, coupled)
    c0, c1, c2, iters, converged = cayley_newton(g0, g1, g2, Jeff, P.tol, P.max_iter, W.jac)
    if not converged:
        if np.isfinite(c0 + c1 + c2 + d0 + d1 + d2):
            return c0, c1, c2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, iters, NEWTON_FAILED
        return c0, c1, c2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, iters, NON_FINITE
    FmI = W.FmI
    cayley_minus_identity(c0, c1, c2, FmI)
    # q = R_k (F_k - I) rho_c; dr = h X - M w q -> Y
    s0 = s1 = s2 = q0 = q1 = q2 = 0.0
    if coupled:
        s0, s1, s2, q0, q1, q2 = end_shift(S.R, FmI, rho)
    dr00 = dr01 = dr02 = 0.0
    if free and forced:  # pivot displacement, for the work of the pivot force
        dr00 = h * X[0, 0] - M * w[0] * q0
        dr01 = h * X[0, 1] - M * w[0] * q1
        dr02 = h * X[0, 2] - M * w[0] * q2
    string_increments(X, W.Y, w, M, (q0, q1, q2), h, 0 if free else 1, coupled)
    if coupled:
        e0 = e0 - M * w[n] * s0  # R_k^T dr_{N+1} = R_k^T d - M s (F - I) rho_c
        e1 = e1 - M * w[n] * s1
        e2 = e2 - M * w[n] * s2
    return c0, c1, c2, e0, e1, e2, dr00, dr01, dr02, iters, OK


@kernel(forceinline=True)
def lgvi_substep(S, W, P, inputs, h, free, forced, coupled, compensated):
    """Advance the state ``S`` (:class:`StateArrays`) by one LGVI step of length ``h``, in place.

    ``inputs`` (9,): pivot force u_p (spatial) [N], body torque tau (body frame) [N m], spatial
    torque T [N m], held over the step. The flags say what the scene needs (passed as constants,
    the compiler drops what is off; :func:`specialised_kernels` fixes ``coupled`` and
    ``compensated``, and passes the others as run-time values):
    ``free`` the pivot is a free point mass (``P.first == 0``), ``forced`` the inputs are
    read (else they are taken as zero and the input balances are not updated), ``coupled``
    rho_c != 0 (else the body's rotation is decoupled from the string: no gravity torque, no
    coupling terms). Each flag off gives the same numbers as the flag on with what it drops
    equal to zero (the dropped terms are exact zeros there).

    With ``compensated`` the increments are added with Kahan's trick (remainders in S.rc, pc,
    Rc, Pic), because in a smooth motion the round-off of ``r + dr`` repeats for many steps
    and would otherwise accumulate linearly into pi3 and the energy; without it they are plain
    sums (~13 % cheaper; for runs short enough that round-off does not matter, see
    ``solver.compensated``) and the remainders are left as they are.
    On entry ``S.f`` holds ``nodal_forces(r)``; on success it holds the forces at the new state.
    On failure the state is left untouched and a non-zero status is returned.
    Returns ``(status, newton_iterations)``.
    """
    R = S.R
    first = 0 if free else 1
    held = held_inputs(inputs, forced)
    up0, up1, up2, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held
    l0, l1, l2, t0, t1, t2 = left_torque(R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    c0, c1, c2, e0, e1, e2, dr00, dr01, dr02, iters, status = explicit_increments(
        S, W, P, h, up0, up1, up2, t0, t1, t2, free, forced, coupled)
    if status != OK:
        return status, iters
    new_positions(S, W, first, compensated)
    unsettled = 0
    if P.settle:  # the slack switches of the step (kernels/step/switch.py)
        unsettled = switch_errors(S.r, W.X, P.kappa, P.u, P.kappa, P.u, 0.0, S.owed, W.switch)
    status = commit_step(S, W, P, h, (c0, c1, c2), (e0, e1, e2), (dr00, dr01, dr02), (l0, l1, l2, t0, t1, t2),
                         held, (S.f, W.fn),
                         (free, forced, coupled, compensated))
    if status == OK and unsettled > 0:
        settle_switches(S, P, h, S.p, W.switch, S.owed, W.dy, W.fr)
    return status, iters
