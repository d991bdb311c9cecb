"""The slack switch of the explicit string: the energy a step owes where an element of the
tension-only law changes between slack and taut, settled by an impulse along the element
(docs/physics.md, "The slack switch of the explicit string").

The explicit step is kick-drift-kick in the string's forces f. With the momenta p and the inverse
mass matrix A (constant), its kinetic energy T changes over a step by exactly

    dT = W + (h^2/8) (f_{k+1} . A f_{k+1} - f_k . A f_k),    W = 1/2 (f_k + f_{k+1}) . dr,

so H~ = T + V - (h^2/8) f . A f changes by W + dV: the trapezoid rule's error in the work of the
forces along the step's straight line. That is zero wherever the potential is quadratic along
the line, and O(h^3) where it is smooth; an element that crosses the kink of the slack law within
the step leaves an error of order (h omega)^2 of its kinetic energy, of either sign, and these
errors random-walk (what made a flickering string gain energy). Per element, with s = |x| - u,
the tension T = kappa max(s, 0) and g = T x / |x| = dV/dx, the step owes

    e_a = V_a(x_{k+1}) - V_a(x_k) - 1/2 (g_a(x_k) + g_a(x_{k+1})) . (x_{k+1} - x_k)   [J],

and, while the winch reels (rest length u_k -> u_{k+1}), also its share of the winch's work as
the step counts it (the midpoint rule of dV_a/dl, kernels/step/winch.py): + dl (EA/N) (eps + eps^2/2)
at the midpoint where it is taut there.

After the step, an extra tension d along the element's direction n at r_{k+1}, as the impulse
d j with j = h/2 (n on node a, -n on node a+1), changes the kinetic energy by
d (j . v) + d^2 (j . A j)/2, v the velocities at the new state: the root of smaller magnitude of
that quadratic = -e_a settles the switch. An impulse along the element is internal: it keeps the
linear momentum and the angular momentum about every point. Where no real root exists (the
element's ends nearly at rest relative to each other along it), the largest removable share is
settled and the rest is owed (``S.owed``), to be settled at the next steps.
"""
import math

from ..jit import kernel
from .diagnostics import node_velocities


@kernel(inline="always")
def switch_errors(r0, r1, kappa0, u0, kappa1, u1, reel_work, owed, errors):
    """``errors[a]`` = e_a (module docstring) [J] of each element whose slack/taut state differs
    between the positions ``r0`` (r_k, rest length u0, stiffness kappa0 = EA/u0) and ``r1``
    (r_{k+1}; u1, kappa1), or, while reeling, at the midpoint; plus what it ``owed``. 0 for the
    others. ``reel_work`` = dl EA/N [J] (0 at a fixed length). Returns the number of elements
    with an error to settle."""
    n = r0.shape[0] - 1
    um = 0.5 * (u0 + u1)
    reeling = reel_work != 0.0
    count = 0
    for a in range(n):
        x0 = r0[a + 1, 0] - r0[a, 0]
        x1 = r0[a + 1, 1] - r0[a, 1]
        x2 = r0[a + 1, 2] - r0[a, 2]
        y0 = r1[a + 1, 0] - r1[a, 0]
        y1 = r1[a + 1, 1] - r1[a, 1]
        y2 = r1[a + 1, 2] - r1[a, 2]
        L0 = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        L1 = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
        switched = (L0 < u0) != (L1 < u1)
        Lm = 0.0
        if reeling:
            m0 = 0.5 * (x0 + y0)
            m1 = 0.5 * (x1 + y1)
            m2 = 0.5 * (x2 + y2)
            Lm = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            switched = switched or (Lm < um) != (L1 < u1)
        e = owed[a]
        if switched:
            s0 = max(L0 - u0, 0.0)
            s1 = max(L1 - u1, 0.0)
            c0 = kappa0 * s0 / L0
            c1 = kappa1 * s1 / L1
            work = 0.5 * ((c0 * x0 + c1 * y0) * (y0 - x0) + (c0 * x1 + c1 * y1) * (y1 - x1)
                          + (c0 * x2 + c1 * y2) * (y2 - x2))
            e += 0.5 * (kappa1 * s1 * s1 - kappa0 * s0 * s0) - work
            if reeling and Lm >= um:
                eps = Lm / um - 1.0
                e += reel_work * (eps + 0.5 * eps * eps)
        errors[a] = e
        if e != 0.0:
            count += 1
    return count


@kernel(inline="always")
def switch_root(e, B, A):
    """The extra tension d [N] whose impulse d j changes the kinetic energy by d B + d^2 A = -e
    (``B`` = j . v [J/N], ``A`` = j . M^-1 j / 2 [J/N^2], ``e`` the error [J]): the root of smaller
    magnitude, written without cancellation; where there is none, the vertex -B / 2A, which
    removes the most it can. Returns ``(d, what is still owed [J])``."""
    disc = B * B - 4.0 * A * e
    if disc >= 0.0:
        return -2.0 * e / (B + math.copysign(math.sqrt(disc), B)), 0.0
    return -B / (2.0 * A), e - B * B / (4.0 * A)


# Not inlined: it runs only on steps with a switch, and inlined into every specialised step it
# cost 20 % more compile time at the first step (docs/performance.md).
@kernel
def settle_switches(S, P, h, momenta, errors, owed, V, Z):
    """Settle the ``errors`` (:func:`switch_errors`) [J] of a step just committed to ``S``: per
    element with an error, the impulse along it that changes the kinetic energy by -error
    (module docstring), added to ``S.p``; what cannot be settled goes to ``owed``, whose other
    entries are zeroed. The velocities of the new state [m/s] come from ``momenta`` (``S.p``, or
    the winch's shifted ones) with the mass matrix of ``P`` (its Thomas factors, ``w``,
    ``Jeff``) into ``V`` (N+1, 3); ``Z`` (N+1, 3) is scratch."""
    r = S.r
    p = S.p
    n = r.shape[0] - 1
    first = P.first
    hh = 0.5 * h
    node_velocities(momenta, S.Pi[0], S.Pi[1], S.Pi[2], S.R, P, V)
    for a in range(n):
        e = errors[a]
        owed[a] = 0.0
        if e == 0.0:
            continue
        x0 = r[a + 1, 0] - r[a, 0]
        x1 = r[a + 1, 1] - r[a, 1]
        x2 = r[a + 1, 2] - r[a, 2]
        L = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        j0 = hh * x0 / L
        j1 = hh * x1 / L
        j2 = hh * x2 / L
        for b in range(n + 1):
            Z[b, 0] = 0.0
            Z[b, 1] = 0.0
            Z[b, 2] = 0.0
        if a >= first:
            Z[a, 0] = j0
            Z[a, 1] = j1
            Z[a, 2] = j2
        Z[a + 1, 0] = -j0
        Z[a + 1, 1] = -j1
        Z[a + 1, 2] = -j2
        # B = j . v and A = j . M^-1 j / 2, Z <- M^-1 j in place (the solve reads a row first)
        B = -(j0 * V[a + 1, 0] + j1 * V[a + 1, 1] + j2 * V[a + 1, 2])
        if a >= first:
            B += j0 * V[a, 0] + j1 * V[a, 1] + j2 * V[a, 2]
        node_velocities(Z, 0.0, 0.0, 0.0, S.R, P, Z)
        A = -0.5 * (j0 * Z[a + 1, 0] + j1 * Z[a + 1, 1] + j2 * Z[a + 1, 2])
        if a >= first:
            A += 0.5 * (j0 * Z[a, 0] + j1 * Z[a, 1] + j2 * Z[a, 2])
        d, owed[a] = switch_root(e, B, A)
        if a >= first:
            p[a, 0] += d * j0
            p[a, 1] += d * j1
            p[a, 2] += d * j2
        p[a + 1, 0] -= d * j0
        p[a + 1, 1] -= d * j1
        p[a + 1, 2] -= d * j2
        for b in range(first, n + 1):
            V[b, 0] += d * Z[b, 0]
            V[b, 1] += d * Z[b, 1]
            V[b, 2] += d * Z[b, 2]
