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

#: The damper's state of an element (``W.dset``): slack (carries nothing), active (T_d = c e), or
#: held at T_d = -T_e.
SLACK = 0.0
ACTIVE = 1.0
HELD = 2.0
#: Solves of one half step at most (each changes the set of at least one element).
MAX_SOLVES = 8


@kernel(forceinline=True)
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
def outer(W, a, q):
    """q n_a n_a^T of element a if it is active, else 0: its 6 entries (00, 01, 02, 11, 12, 22)."""
    if W.dset[a] != ACTIVE:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    n0 = W.ddir[a, 0]
    n1 = W.ddir[a, 1]
    n2 = W.ddir[a, 2]
    return q * n0 * n0, q * n0 * n1, q * n0 * n2, q * n1 * n1, q * n1 * n2, q * n2 * n2


@kernel(forceinline=True)
def row_blocks(S, W, P, a, n, q, eta):
    """Row ``a`` of the half step's system, symmetric blocks by their 6 entries (00, 01, 02, 11, 12,
    22): the diagonal block D, the coupling C to the next node (0 at the attachment node) and the
    right-hand side r (3). Returns the 15 scalars."""
    d = P.mdiag[a]
    off = P.off
    b = outer(W, a - 1, q) if a > 0 else (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    t = outer(W, a, q) if a < n else (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    D = (d + b[0] + t[0], b[1] + t[1], b[2] + t[2], d + b[3] + t[3], b[4] + t[4], d + b[5] + t[5])
    C = (off - t[0], -t[1], -t[2], off - t[3], -t[4], off - t[5]) if a < n else (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    r0 = 0.0
    r1 = 0.0
    r2 = 0.0
    if a > 0:
        s = eta * driving_tension(W, P, a - 1)
        r0 -= s * W.ddir[a - 1, 0]
        r1 -= s * W.ddir[a - 1, 1]
        r2 -= s * W.ddir[a - 1, 2]
    if a < n:
        s = eta * driving_tension(W, P, a)
        r0 += s * W.ddir[a, 0]
        r1 += s * W.ddir[a, 1]
        r2 += s * W.ddir[a, 2]
    else:  # the load's rotation takes its share of the attachment node's mass: R turn_mass R^T
        R = S.R
        T = P.turn_mass
        m = W.dmat[3]
        for i in range(3):
            for j in range(3):
                m[i, j] = T[i, 0] * R[j, 0] + T[i, 1] * R[j, 1] + T[i, 2] * R[j, 2]  # T R^T
        D = (D[0] - (R[0, 0] * m[0, 0] + R[0, 1] * m[1, 0] + R[0, 2] * m[2, 0]),
             D[1] - (R[0, 0] * m[0, 1] + R[0, 1] * m[1, 1] + R[0, 2] * m[2, 1]),
             D[2] - (R[0, 0] * m[0, 2] + R[0, 1] * m[1, 2] + R[0, 2] * m[2, 2]),
             D[3] - (R[1, 0] * m[0, 1] + R[1, 1] * m[1, 1] + R[1, 2] * m[2, 1]),
             D[4] - (R[1, 0] * m[0, 2] + R[1, 1] * m[1, 2] + R[1, 2] * m[2, 2]),
             D[5] - (R[2, 0] * m[0, 2] + R[2, 1] * m[1, 2] + R[2, 2] * m[2, 2]))
    return D, C, (r0, r1, r2)


@kernel(forceinline=True)
def eliminate_row(W, a, first, n, D, C, r):
    """Block elimination of row ``a`` (its blocks from :func:`row_blocks`): the previous row's
    coupling O (``W.dmat[2]``) times E_{a-1} and z_{a-1} taken off D and r; then E_a = D^-1 C into
    ``W.dfac[a]`` and z_a = D^-1 r into ``W.dinc[a]``; C kept as the next row's O."""
    E = W.dfac
    z = W.dinc
    O = W.dmat[2]
    d00, d01, d02, d11, d12, d22 = D
    r0, r1, r2 = r
    if a > first:  # D - O E_{a-1} = D - O D_{a-1}^-1 O: symmetric, its 6 entries
        e = E[a - 1]
        d00 -= O[0, 0] * e[0, 0] + O[0, 1] * e[1, 0] + O[0, 2] * e[2, 0]
        d01 -= O[0, 0] * e[0, 1] + O[0, 1] * e[1, 1] + O[0, 2] * e[2, 1]
        d02 -= O[0, 0] * e[0, 2] + O[0, 1] * e[1, 2] + O[0, 2] * e[2, 2]
        d11 -= O[1, 0] * e[0, 1] + O[1, 1] * e[1, 1] + O[1, 2] * e[2, 1]
        d12 -= O[1, 0] * e[0, 2] + O[1, 1] * e[1, 2] + O[1, 2] * e[2, 2]
        d22 -= O[2, 0] * e[0, 2] + O[2, 1] * e[1, 2] + O[2, 2] * e[2, 2]
        r0 -= O[0, 0] * z[a - 1, 0] + O[0, 1] * z[a - 1, 1] + O[0, 2] * z[a - 1, 2]
        r1 -= O[1, 0] * z[a - 1, 0] + O[1, 1] * z[a - 1, 1] + O[1, 2] * z[a - 1, 2]
        r2 -= O[2, 0] * z[a - 1, 0] + O[2, 1] * z[a - 1, 1] + O[2, 2] * z[a - 1, 2]
    # the symmetric inverse by cofactors
    i00 = d11 * d22 - d12 * d12
    i01 = d02 * d12 - d01 * d22
    i02 = d01 * d12 - d02 * d11
    det = 1.0 / (d00 * i00 + d01 * i01 + d02 * i02)
    i00 *= det
    i01 *= det
    i02 *= det
    i11 = (d00 * d22 - d02 * d02) * det
    i12 = (d01 * d02 - d00 * d12) * det
    i22 = (d00 * d11 - d01 * d01) * det
    z[a, 0] = i00 * r0 + i01 * r1 + i02 * r2
    z[a, 1] = i01 * r0 + i11 * r1 + i12 * r2
    z[a, 2] = i02 * r0 + i12 * r1 + i22 * r2
    if a < n:
        c00, c01, c02, c11, c12, c22 = C
        E[a, 0, 0] = i00 * c00 + i01 * c01 + i02 * c02
        E[a, 0, 1] = i00 * c01 + i01 * c11 + i02 * c12
        E[a, 0, 2] = i00 * c02 + i01 * c12 + i02 * c22
        E[a, 1, 0] = i01 * c00 + i11 * c01 + i12 * c02
        E[a, 1, 1] = i01 * c01 + i11 * c11 + i12 * c12
        E[a, 1, 2] = i01 * c02 + i11 * c12 + i12 * c22
        E[a, 2, 0] = i02 * c00 + i12 * c01 + i22 * c02
        E[a, 2, 1] = i02 * c01 + i12 * c11 + i22 * c12
        E[a, 2, 2] = i02 * c02 + i12 * c12 + i22 * c22
        O[0, 0] = c00
        O[0, 1] = c01
        O[0, 2] = c02
        O[1, 0] = c01
        O[1, 1] = c11
        O[1, 2] = c12
        O[2, 0] = c02
        O[2, 1] = c12
        O[2, 2] = c22


@kernel(forceinline=True)
def velocity_increments(S, W, P, first, q, eta):
    """Solve the half step's system for dv into ``W.dinc`` (rows below ``first`` 0) by block
    elimination, pivot -> attachment node, and back substitution (``W.dfac`` the eliminated blocks,
    ``W.dmat`` scratch)."""
    n = W.dinc.shape[0] - 1
    for a in range(first, n + 1):
        D, C, r = row_blocks(S, W, P, a, n, q, eta)
        eliminate_row(W, a, first, n, D, C, r)
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


@kernel(forceinline=True)
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


@kernel(forceinline=True)
def add_momentum(p, pc, a, d0, d1, d2, compensated):
    """p[a] += d (3) (:func:`add_to`)."""
    add_to(p, pc, a, 0, d0, compensated)
    add_to(p, pc, a, 1, d1, compensated)
    add_to(p, pc, a, 2, d2, compensated)


@kernel(forceinline=True)
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
