"""Kelvin–Voigt damping of the string's elements (docs/physics.md, "Material damping").

A taut element of length L > u carries, beside its elastic tension T_e = kappa (L - u), the
damper's T_d = c e, with e = n . (v_{a+1} - v_a) its extension rate [m/s], n = x_a / L its
direction and c = EA tau / u [N s/m] (tau = ``string.damping_time``, ``P.damping`` = c); with the
slack law T_d is held to T_d >= -T_e (a damper does not pull on an element that unloads fast) and
a slack element (L <= u) carries nothing. The paper's two-sided law damps every element.

The damper's flow at a fixed configuration (p' = -sum_a T_d g_a, g_a = -n on node a and +n on
node a+1, Pi fixed) is taken over ``eta`` = h/2 on each side of every (sub)step of the
conservative scheme (a symmetric splitting: kernels/step/step.py). Its midpoint rule, v the
node velocities of the state and dv their increment, is the 3x3-block tridiagonal system

    (M_v + eta/2 c sum_active g g^T) dv = -eta sum_a s_a g_a,   s_a = c g_a . v (active), -T_e (held),

M_v the node mass matrix with Pi held: M_tot, less at the attachment node the share of the
load's mass its rotation takes, R (M^2 rho^ J^-1 rho^T) R^T (``P.turn_mass`` in the body frame).
Then T_d = c g . (v + dv/2) (active) or -T_e (held); an element whose T_d breaks its hold, or whose
hold is no longer needed, changes set and the system is solved again (an active set, rarely a
second solve). The momenta take the impulses -eta T_d g_a: internal pairs along the elements, so
the linear momentum and pi3 are untouched, and the kinetic energy falls by exactly
eta sum_a T_d g_a . (v + dv/2) >= 0, which joins the balances' dissipation (B_DISSIPATION).
"""
import math

from ..jit import kernel
from ..layout import B_DISSIPATION
from ..sums import kahan_add
from .diagnostics import node_velocities
from .implicit_newton import eliminate_previous, forward_row, store_row
from .implicit_terms import inverse3

#: The damper's state of an element (``W.dset``): slack (carries nothing), active (T_d = c e), or
#: held at T_d = -T_e.
SLACK = 0.0
ACTIVE = 1.0
HELD = 2.0
#: Solves of one half step at most (each changes the set of at least one element).
MAX_SOLVES = 8
ZERO9 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@kernel(inline="always")
def element_directions(r, P, dirs, tension, dset):
    """Per element a: its unit direction into ``dirs[a]``, its elastic tension T_e [N] into
    ``tension[a]`` and its damper's state (slack, else active) into ``dset[a]``."""
    u = P.u
    for a in range(r.shape[0] - 1):
        x0 = r[a + 1, 0] - r[a, 0]
        x1 = r[a + 1, 1] - r[a, 1]
        x2 = r[a + 1, 2] - r[a, 2]
        length = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        dirs[a, 0] = x0 / length
        dirs[a, 1] = x1 / length
        dirs[a, 2] = x2 / length
        tension[a] = P.kappa * (length - u)
        dset[a] = SLACK if P.slack and length <= u else ACTIVE


@kernel(inline="always")
def extension_rate(V, dirs, a):
    """n_a . (V_{a+1} - V_a) [m/s] (rows of fixed nodes hold 0)."""
    return (dirs[a, 0] * (V[a + 1, 0] - V[a, 0]) + dirs[a, 1] * (V[a + 1, 1] - V[a, 1])
            + dirs[a, 2] * (V[a + 1, 2] - V[a, 2]))


@kernel(inline="always")
def driving_tension(W, P, a):
    """s_a of the right-hand side [N]: c e_a at the state's velocities (active), -T_e (held), 0 (slack)."""
    st = W.dset[a]
    if st == ACTIVE:
        return P.damping * extension_rate(W.dvel, W.ddir, a)
    if st == HELD:
        return -W.dten[a]
    return 0.0


@kernel(inline="always")
def element_block(W, a, q):
    """q n_a n_a^T (9, row-major) if element a is active, else zeros."""
    if W.dset[a] != ACTIVE:
        return ZERO9
    n0 = W.ddir[a, 0]
    n1 = W.ddir[a, 1]
    n2 = W.ddir[a, 2]
    return (q * n0 * n0, q * n0 * n1, q * n0 * n2, q * n1 * n0, q * n1 * n1, q * n1 * n2,
            q * n2 * n0, q * n2 * n1, q * n2 * n2)


@kernel(inline="always")
def rotated_entry(R, T, i, j):
    """(R T R^T)_ij."""
    s = 0.0
    for k in range(3):
        s += R[i, k] * (T[k, 0] * R[j, 0] + T[k, 1] * R[j, 1] + T[k, 2] * R[j, 2])
    return s


@kernel(inline="always")
def turn_block(R, T):
    """R T R^T (9, row-major) for the body-frame ``T`` (3, 3)."""
    return (rotated_entry(R, T, 0, 0), rotated_entry(R, T, 0, 1), rotated_entry(R, T, 0, 2),
            rotated_entry(R, T, 1, 0), rotated_entry(R, T, 1, 1), rotated_entry(R, T, 1, 2),
            rotated_entry(R, T, 2, 0), rotated_entry(R, T, 2, 1), rotated_entry(R, T, 2, 2))


@kernel(inline="always")
def row_blocks(S, W, P, a, n, q, eta):
    """Row ``a`` of the half step's system: its diagonal block (9), right-hand side (3) and
    coupling to the next node (9; zeros at the attachment node)."""
    d = P.mdiag[a]
    below = element_block(W, a - 1, q) if a > 0 else ZERO9
    above = element_block(W, a, q) if a < n else ZERO9
    turn = turn_block(S.R, P.turn_mass) if a == n else ZERO9
    diag = (d + below[0] + above[0] - turn[0], below[1] + above[1] - turn[1], below[2] + above[2] - turn[2],
            below[3] + above[3] - turn[3], d + below[4] + above[4] - turn[4], below[5] + above[5] - turn[5],
            below[6] + above[6] - turn[6], below[7] + above[7] - turn[7], d + below[8] + above[8] - turn[8])
    s_below = driving_tension(W, P, a - 1) if a > 0 else 0.0
    s_above = driving_tension(W, P, a) if a < n else 0.0
    rhs = (0.0, 0.0, 0.0)
    if a > 0:
        rhs = (-eta * s_below * W.ddir[a - 1, 0], -eta * s_below * W.ddir[a - 1, 1], -eta * s_below * W.ddir[a - 1, 2])
    if a < n:
        rhs = (rhs[0] + eta * s_above * W.ddir[a, 0], rhs[1] + eta * s_above * W.ddir[a, 1],
               rhs[2] + eta * s_above * W.ddir[a, 2])
    off = P.off
    couple = (off - above[0], -above[1], -above[2], -above[3], off - above[4], -above[5], -above[6], -above[7],
              off - above[8])
    return diag, rhs, couple


@kernel(inline="always")
def velocity_increments(S, W, P, first, q, eta):
    """Solve the half step's system for dv into ``W.dinc`` (rows below ``first`` 0) by block
    elimination, pivot -> attachment node, and back substitution (``W.dfac`` the eliminated blocks)."""
    n = W.dinc.shape[0] - 1
    prev = ZERO9
    e = ZERO9
    z = (0.0, 0.0, 0.0)
    for a in range(first, n + 1):
        s, r, couple = row_blocks(S, W, P, a, n, q, eta)
        if a > first:
            s, r = eliminate_previous(s, r, prev, e, z)
        if a < n:
            e, z = forward_row(s, r, couple)
            store_row(W.dfac, W.dinc, a, e, z)
            prev = couple
        else:
            i = inverse3(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8])
            z = (i[0] * r[0] + i[1] * r[1] + i[2] * r[2], i[3] * r[0] + i[4] * r[1] + i[5] * r[2],
                 i[6] * r[0] + i[7] * r[1] + i[8] * r[2])
            W.dinc[n, 0] = z[0]
            W.dinc[n, 1] = z[1]
            W.dinc[n, 2] = z[2]
    E = W.dfac
    X = W.dinc
    for k in range(n - first):
        a = n - 1 - k
        for i in range(3):
            X[a, i] -= E[a, i, 0] * X[a + 1, 0] + E[a, i, 1] * X[a + 1, 1] + E[a, i, 2] * X[a + 1, 2]
    for a in range(first):
        X[a, 0] = 0.0
        X[a, 1] = 0.0
        X[a, 2] = 0.0


@kernel(inline="always")
def midpoint_rate(W, a):
    """e_a at the half step's mean velocities v + dv/2 [m/s]."""
    return extension_rate(W.dvel, W.ddir, a) + 0.5 * extension_rate(W.dinc, W.ddir, a)


@kernel(inline="always")
def update_holds(W, P):
    """Move the elements whose damper breaks its hold (active, c e < -T_e) to held, and those held
    that no longer need it back; returns how many moved (0 with the two-sided law)."""
    if not P.slack:
        return 0
    moved = 0
    c = P.damping
    for a in range(W.dset.shape[0]):
        st = W.dset[a]
        if st == SLACK:
            continue
        pull = c * midpoint_rate(W, a) < -W.dten[a]
        if st == ACTIVE and pull:
            W.dset[a] = HELD
            moved += 1
        elif st == HELD and not pull:
            W.dset[a] = ACTIVE
            moved += 1
    return moved


@kernel(inline="always")
def add_to(p, pc, a, i, d, compensated):
    """p[a, i] += d, with Kahan's compensation (remainder in ``pc``) if ``compensated``."""
    if compensated:
        y = d + pc[a, i]
        t = p[a, i] + y
        pc[a, i] = (p[a, i] - t) + y
        p[a, i] = t
    else:
        p[a, i] += d


@kernel(inline="always")
def add_momentum(p, pc, a, d0, d1, d2, compensated):
    """p[a] += d (3) (:func:`add_to`)."""
    add_to(p, pc, a, 0, d0, compensated)
    add_to(p, pc, a, 1, d1, compensated)
    add_to(p, pc, a, 2, d2, compensated)


@kernel(inline="always")
def apply_damper(S, W, P, first, eta, compensated):
    """The momenta take the damper's impulses -eta T_d g_a; the dissipation eta sum T_d e_mid [J]
    joins ``S.acc`` (B_DISSIPATION)."""
    c = P.damping
    lost = 0.0
    for a in range(W.dset.shape[0]):
        st = W.dset[a]
        if st == SLACK:
            continue
        rate = midpoint_rate(W, a)
        T = c * rate if st == ACTIVE else -W.dten[a]
        if P.slack and T < -W.dten[a]:  # only if the active set did not settle (MAX_SOLVES)
            T = -W.dten[a]
        lost += T * rate
        j = eta * T
        n0 = j * W.ddir[a, 0]
        n1 = j * W.ddir[a, 1]
        n2 = j * W.ddir[a, 2]
        if a >= first:
            add_momentum(S.p, S.pc, a, n0, n1, n2, compensated)
        add_momentum(S.p, S.pc, a + 1, -n0, -n1, -n2, compensated)
    kahan_add(S.acc, S.accc, B_DISSIPATION, eta * lost)


# LLVM-inlined, compiled once per signature (kernels/jit.py): every kernel that steps a damped
# string shares it.
@kernel(forceinline=True)
def damper_half_step(S, W, P, eta, free, compensated):
    """The damper's flow over ``eta`` [s] at the state's configuration (module docstring), in
    place: the momenta ``S.p`` and the dissipation in ``S.acc``; positions, ``S.f`` and Pi as they are."""
    first = 0 if free else 1
    node_velocities(S.p, S.Pi[0], S.Pi[1], S.Pi[2], S.R, P, W.dvel)
    element_directions(S.r, P, W.ddir, W.dten, W.dset)
    q = 0.5 * eta * P.damping
    for _ in range(MAX_SOLVES):
        velocity_increments(S, W, P, first, q, eta)
        if update_holds(W, P) == 0:
            break
    apply_damper(S, W, P, first, eta, compensated)
