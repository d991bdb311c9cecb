"""The implicit string (docs/physics.md, "The implicit string"; a scene option, order 2): the LGVI
with each element's elastic energy taken over the step as a whole, at its mean length; kinetic,
gravity and rigid-body terms and the inputs are the explicit scheme's. In the unknowns y = dr (the
string's increments) and the Cayley vector c of F_k, multiplied by h::

    G_a = (M_tot y)_a + M delta_aN R_k (F(c) - I) rho_c - h^2/2 (f~_k + f_g)_a - h b_a = 0
    phi = g + g x c + (g . c) c - 2 J c = 0,    g = h Pi_k + h^2/2 tau_k - M rho_c x (R_k^T y_N)

with b = p_k (+ h/2 u_p at a free pivot; phi is (2) in Cayley form, Lee 2008), then the commit of
every scheme (kernels/step/step_shared.py) with the impulse h/2 (f~_k + f~_{k+1}).
f~ are the forces of the elements' tensions T_a over the step (the energy's secant in the stretch):
in the energy-momentum form (``P.gradient``, the default) along the discrete gradient's direction
(x_k + x_{k+1})/(|x_k| + |x_{k+1}|) at both ends, so that the string's energy is conserved exactly;
in the variational form along the elements at r_k (f~_k) and r_{k+1} (f~_{k+1}), the discrete
Euler-Lagrange equations of the mean-length Lagrangian (kernels/step/implicit_terms.py).

Newton's method solves them together (kernels/step/implicit_newton.py, in stages; the pieces of
its system in kernels/step/implicit_terms.py): the string's block-tridiagonal Jacobian bordered by the
body's three unknowns (coupled to the attachment node only), by block elimination from the pivot
down, a 3x3 Schur complement there and back substitution: O(N) per iteration. This module holds
the step around it (the first guess, the new positions, the commit); kernels/step/step.py cuts a
step that fails back.
"""
import math

from ..jit import kernel
from ..so3 import cayley_minus_identity
from .implicit_newton import implicit_newton
from .implicit_terms import split_forces
from .lgvi import explicit_increments
from .step_shared import commit_step, held_inputs, left_torque, new_positions
from .string import string_solve

#: A step whose Newton iteration fails, or (variational form) whose tension breaks the transverse
#: limit, is cut in halves, at most this many times (to h / 64).
CUTBACKS = 6
#: The transverse limit of the variational form: h omega_t <= this (omega_t^2 = 12 T_max / (u m)),
#: under a quarter turn per step, below its parametric resonances (docs/physics.md, "The transverse step").
TRANSVERSE_LIMIT = 0.9 * 2.0 * math.sin(math.pi / 8.0)
#: Status of a step that broke the transverse bound (internal: it is cut back, never reported).
TOO_TENSE = -1


@kernel(forceinline=True)
def explicit_start(S, W, P, h, t0, t1, t2, up0, up1, up2, free, forced, coupled):
    """The implicit string's first guess: one explicit step with the forces ``S.f`` of the last
    step's right half (the tensions along the elements at r_k): the tensions of consecutive steps
    differ little even where f(r_k) would carry the stiff modes, and the body's turn comes with
    the coupling. Increments into ``W.Y``; returns the Cayley vector (0 if the explicit step's
    own Newton failed, with the string solve's increments)."""
    n = S.r.shape[0] - 1
    first = 0 if free else 1
    c0, c1, c2, _, _, _, _, _, _, _, status = explicit_increments(S, W, P, h, up0, up1, up2, t0, t1, t2, free,
                                                                  forced, coupled)
    if status != 0:
        c0 = c1 = c2 = 0.0
        X = W.X
        Y = W.Y
        string_solve(P.inv, P.cp, first, S.p, S.f, 0.5 * h, up0, up1, up2, free and forced, X)
        for a in range(first, n + 1):
            Y[a, 0] = h * X[a, 0]
            Y[a, 1] = h * X[a, 1]
            Y[a, 2] = h * X[a, 2]
    return c0, c1, c2


@kernel(inline="always")
def implicit_positions(S, W, c0, c1, c2, first, compensated):
    """After the Newton of the fixed-length or reeling step: ``W.FmI`` = F - I, the new positions,
    and :func:`~.step_shared.commit_step`'s ``(e, dr_0)``: R_k^T dr_{N+1} (body frame), dr_0 [m]."""
    R = S.R
    Y = W.Y
    n = Y.shape[0] - 1
    cayley_minus_identity(c0, c1, c2, W.FmI)
    yn0 = Y[n, 0]
    yn1 = Y[n, 1]
    yn2 = Y[n, 2]
    e0 = R[0, 0] * yn0 + R[1, 0] * yn1 + R[2, 0] * yn2  # R_k^T dr_{N+1}
    e1 = R[0, 1] * yn0 + R[1, 1] * yn1 + R[2, 1] * yn2
    e2 = R[0, 2] * yn0 + R[1, 2] * yn1 + R[2, 2] * yn2
    dr00 = Y[0, 0]
    dr01 = Y[0, 1]
    dr02 = Y[0, 2]
    new_positions(S, W, first, compensated)
    return e0, e1, e2, dr00, dr01, dr02


@kernel(inline="always")
def implicit_step_once(S, W, P, inputs, h, free, forced, coupled, compensated, bounded):
    """One step of length ``h`` of the implicit string without cutting back: the state untouched
    on failure, and (``bounded``, variational form) where its largest tension breaks the transverse limit
    (status ``TOO_TENSE``). Returns ``(status, newton_iterations)``."""
    first = 0 if free else 1
    held = held_inputs(inputs, forced)
    up0, up1, up2, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held
    l0, l1, l2, t0, t1, t2 = left_torque(S.R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    c0, c1, c2 = explicit_start(S, W, P, h, t0, t1, t2, up0, up1, up2, free, forced, coupled)
    c0, c1, c2, iters, status = implicit_newton(S, W, P, h, (t0, t1, t2), (up0, up1, up2), (c0, c1, c2),
                                                (P.mdiag, P.mdiag, P.mdiag, S.p), (P.u, P.u),
                                                (free, forced, coupled, False))
    if status != 0:
        return status, iters
    # the string's impulse over the step, h/2 (fl + fr): along the elements at both ends
    _, tension = split_forces(S.r, W.Y, P, W.fl, W.fr, P.m, P.m, P.u, P.u)
    if bounded and not P.gradient and 12.0 * tension * h * h > TRANSVERSE_LIMIT * TRANSVERSE_LIMIT * P.u * P.m:
        return TOO_TENSE, iters
    e0, e1, e2, dr00, dr01, dr02 = implicit_positions(S, W, c0, c1, c2, first, compensated)
    status = commit_step(S, W, P, h, (c0, c1, c2), (e0, e1, e2), (dr00, dr01, dr02), (l0, l1, l2, t0, t1, t2),
                         held, (W.fl, W.fr),
                         (free, forced, coupled, compensated))
    return status, iters
