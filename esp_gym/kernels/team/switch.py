"""The slack switch of a team's strings (docs/physics.md, "The slack switch of a team's strings"):
kernels/step/switch.py's settling, with the team's inverse mass matrix.

An element a of string k with a switch error e_a [J] (:func:`~.switch.switch_errors`) gets the
impulse d j along it, j = h/2 (n on node a, -n on node a+1), n its direction at r_{k+1}. Where
node a+1 is string k's end (on the body at x + R rho_k), its share -h/2 d n joins the body's
momenta as every end's row does: p_x (string 0's last row of ``S.p``) and Pi += rho_k x R^T(.).
The kinetic energy changes by d (j . v) + d^2 (j . A j)/2 with A the team's inverse Legendre
transform (:func:`team_node_velocities`) and both products read as node velocities (the end's:
v_x + R (Omega x rho_k)); kernels/step/switch.py's root settles it.

String 0's errors and debts are the single string's (``W.switch``, ``S.owed``); the other
strings' are per stacked row of :data:`~esp_gym.kernels.team.arrays.TeamArrays` (``A.switch``, ``A.owed``: string j's
element a at row start[j] + a). The settling runs after the step is committed, only on a step
with an error, and borrows scratch the committed step no longer reads: string 0's ``W.dy``,
``W.fr`` (as the single string's), the others' ``A.X`` and ``A.fn``.
"""
import math

from ..jit import kernel
from ..layout import WN_EA, WN_LENGTH
from ..so3 import cross, rotated, unrotated
from ..step.diagnostics import body_velocities
from ..step.string import tridiag_solve
from ..step.switch import switch_errors, switch_root
from .arrays import add_end_loads, pivot_rows


# Not inlined: the same signature serves the state's velocities and each impulse's, compiled once.
@kernel
def team_node_velocities(p0, po, Pi, R, first, off0, T, V0, Vo):
    """The team's continuous Legendre transform inverted (docs/physics.md, "Diagnostics of a
    team"), with the step's factors ``T`` (:data:`~esp_gym.kernels.team.arrays.TeamParams`: each string's M_II, the
    assembled body's M', rho', J'_eff and string 0's factors with M' on its last row): node
    velocities [m/s] of string 0 into ``V0`` (N+1, 3) from its momenta ``p0`` (last row: the body's
    p_x with every end's share) and of the others into ``Vo`` (rows, 3, their ends' rows the ends'
    velocities v_x + R (Omega x rho_j)) from ``po`` (ends' rows ignored), the body's ``Pi`` (3,,
    body frame) [kg m^2/s] at the attitude ``R``; ``first``: string 0's first moving row, ``off0``
    its mass matrix's off-diagonal [kg]. In place (``V0`` is ``p0``, ``Vo`` is ``po``) too.
    Returns Omega (body frame) [rad/s]."""
    E0 = E1 = E2 = 0.0  # -sum c_j on string 0's last row, and -sum rho_j x R^T c_j on Pi
    t0, t1, t2 = Pi[0], Pi[1], Pi[2]
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1] - 1  # the end's row
        fj = pivot_rows(T, j)
        for a in range(s, s + fj):  # a fixed pivot
            for i in range(3):
                Vo[a, i] = 0.0
        c0 = c1 = c2 = 0.0
        if e - 1 >= s + fj:  # a moving row next to the end: y = M_II^-1 p_I, c_j = off y_last
            tridiag_solve(T.inv[s:e], T.cp[s:e], T.off[j], fj, po[s:e], Vo[s:e])
            c0 = T.off[j] * Vo[e - 1, 0]
            c1 = T.off[j] * Vo[e - 1, 1]
            c2 = T.off[j] * Vo[e - 1, 2]
        E0 -= c0
        E1 -= c1
        E2 -= c2
        m0, m1, m2 = cross(T.rho[j], unrotated(R, (c0, c1, c2)))
        t0 -= m0
        t1 -= m1
        t2 -= m2
    n = p0.shape[0] - 1
    tridiag_solve(T.inv0, T.cp0, off0, first, p0, V0)
    for a in range(first):
        for i in range(3):
            V0[a, i] = 0.0
    add_end_loads(V0, T.w0, (E0, E1, E2), first, T.first.shape[0])
    w0, w1, w2, _, _, _ = body_velocities(V0, t0, t1, t2, R, T.mass, T.rho_inertial, T.jeff, T.w0, first)
    other_velocities(T, R, (V0[n, 0], V0[n, 1], V0[n, 2]), (w0, w1, w2), Vo)
    return w0, w1, w2


@kernel(entry=True)
def node_velocities_entry(p0, po, Pi, R, first, off0, T, V0, Vo):
    """:func:`team_node_velocities` called from Python (its tests), compiled and cached as an
    entry point."""
    return team_node_velocities(p0, po, Pi, R, first, off0, T, V0, Vo)


@kernel(inline="always")
def other_velocities(T, R, vx, omega, Vo):
    """Each other string's end velocity v_x + R (Omega x rho_j) into its end row of ``Vo`` and its
    interior's y - off w_end v_e (``Vo`` holding y = M_II^-1 p_I) [m/s]."""
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1] - 1
        q0, q1, q2 = rotated(R, cross(omega, T.rho[j]))
        v0 = vx[0] + q0
        v1 = vx[1] + q1
        v2 = vx[2] + q2
        Vo[e, 0] = v0
        Vo[e, 1] = v1
        Vo[e, 2] = v2
        o = T.off[j]
        for a in range(s + pivot_rows(T, j), e):
            Vo[a, 0] -= o * T.w_end[a] * v0
            Vo[a, 1] -= o * T.w_end[a] * v1
            Vo[a, 2] -= o * T.w_end[a] * v2


@kernel(forceinline=True)
def team_switch_errors(S, W, P, T, A, TW):
    """Every settled string's switch errors of the step just solved (:func:`~.switch.switch_errors`
    of its nodes before, ``S.r`` and ``A.r``, and after, ``W.X`` and ``A.X`` with the ends placed):
    string 0's into ``W.switch`` when ``P.settle``, string j's into its rows of ``A.switch`` when
    ``T.settle`` and its law is slack. With the winches of ``TW`` (None: fixed lengths) each at
    its lengths l0 = ``TW.state`` -> l1 = ``TW.target`` with its reel's share. Returns how many
    elements have one."""
    count = 0
    if P.settle:
        if TW is None:
            count += switch_errors(S.r, W.X, P.kappa, P.u, P.kappa, P.u, 0.0, S.owed, W.switch)
        else:
            k0, u0, k1, u1, reel = reeled_constants(TW, 0, S.r.shape[0] - 1)
            count += switch_errors(S.r, W.X, k0, u0, k1, u1, reel, S.owed, W.switch)
    if T.settle:
        for j in range(T.first.shape[0]):
            if T.slack[j]:
                s = T.start[j]
                e = T.start[j + 1]
                k0 = k1 = T.kappa[j]
                u0 = u1 = T.u[j]
                reel = 0.0
                if TW is not None:
                    k0, u0, k1, u1, reel = reeled_constants(TW, j + 1, e - s - 1)
                count += switch_errors(A.r[s:e], A.X[s:e], k0, u0, k1, u1, reel, A.owed[s:e], A.switch[s:e])
    return count


@kernel(inline="always")
def reeled_constants(TW, k, n):
    """String k's ``(kappa0 [N/m], u0 [m], kappa1, u1, dl EA/N [J])`` over a reeling step of its
    ``n`` elements (kernels/step/winch.py's ``winch_substep``)."""
    st = TW.state[k]
    l0 = st[WN_LENGTH]
    l1 = TW.target[k]
    u0 = l0 / n
    u1 = l1 / n
    return st[WN_EA] / u0, u0, st[WN_EA] / u1, u1, (l1 - l0) * st[WN_EA] / n


@kernel(inline="always")
def place(Z0, Zo, T, k, b, j, R):
    """The impulse ``j`` (3,) [N s] on node ``b`` of string ``k`` (-1: string 0) into the momenta
    ``Z0``, ``Zo``; string k >= 1's end (b its element count) onto string 0's last row, its moment
    rho_k x R^T j returned (else 0) [kg m^2/s]."""
    if k < 0:
        for i in range(3):
            Z0[b, i] += j[i]
        return 0.0, 0.0, 0.0
    s = T.start[k]
    e = T.start[k + 1] - 1
    if s + b < e:
        for i in range(3):
            Zo[s + b, i] += j[i]
        return 0.0, 0.0, 0.0
    n = Z0.shape[0] - 1
    for i in range(3):
        Z0[n, i] += j[i]
    return cross(T.rho[k], unrotated(R, j))


@kernel(inline="always")
def node_row(V0, Vo, T, k, b):
    """Node ``b`` of string ``k``'s row (-1: string 0's ``V0``; else its row of ``Vo``, the end's
    row holding the end's velocity)."""
    if k < 0:
        return V0[b]
    return Vo[T.start[k] + b]


# Not inlined, and called from one site: compiled once per team (inlined at two sites, the
# reeling team's first start compiled 39 s longer).
@kernel
def settle_element(S, P, T, A, W, h, k, a, errors, owed, off0, Vo, Zo):
    """Settle element ``a`` of string ``k`` (-1: string 0) with ``errors[a]`` [J] (module
    docstring): its impulse into ``S.p``, ``A.p`` (and the body's ``S.Pi`` at the end), the
    velocities ``W.dy``, ``Vo`` moved with it, what has no root into ``owed[a]``."""
    e = errors[a]
    owed[a] = 0.0
    if e == 0.0:
        return
    r = S.r if k < 0 else A.r[T.start[k]:T.start[k + 1]]
    first = P.first if k < 0 else pivot_rows(T, k)
    moves = a >= first
    V0 = W.dy
    Z0 = W.fr
    R = S.R
    x0 = r[a + 1, 0] - r[a, 0]
    x1 = r[a + 1, 1] - r[a, 1]
    x2 = r[a + 1, 2] - r[a, 2]
    L = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    hh = 0.5 * h
    j = (hh * x0 / L, hh * x1 / L, hh * x2 / L)
    m = (-j[0], -j[1], -j[2])
    Z0[:, :] = 0.0
    Zo[:, :] = 0.0
    if moves:
        place(Z0, Zo, T, k, a, j, R)
    z0, z1, z2 = place(Z0, Zo, T, k, a + 1, m, R)
    va = node_row(V0, Vo, T, k, a)
    vb = node_row(V0, Vo, T, k, a + 1)
    B = -(j[0] * vb[0] + j[1] * vb[1] + j[2] * vb[2])
    if moves:
        B += j[0] * va[0] + j[1] * va[1] + j[2] * va[2]
    team_node_velocities(Z0, Zo, (z0, z1, z2), R, P.first, off0, T, Z0, Zo)
    za = node_row(Z0, Zo, T, k, a)
    zb = node_row(Z0, Zo, T, k, a + 1)
    Ahalf = -0.5 * (j[0] * zb[0] + j[1] * zb[1] + j[2] * zb[2])
    if moves:
        Ahalf += 0.5 * (j[0] * za[0] + j[1] * za[1] + j[2] * za[2])
    d, owed[a] = switch_root(e, B, Ahalf)
    dj = (d * j[0], d * j[1], d * j[2])
    if moves:
        place(S.p, A.p, T, k, a, dj, R)
    p0, p1, p2 = place(S.p, A.p, T, k, a + 1, (-dj[0], -dj[1], -dj[2]), R)
    if k >= 0 and a + 1 == r.shape[0] - 1:  # the end's moment on the body
        S.Pi[0] += p0
        S.Pi[1] += p1
        S.Pi[2] += p2
    for b in range(P.first, V0.shape[0]):
        for i in range(3):
            V0[b, i] += d * Z0[b, i]
    for b in range(Vo.shape[0]):
        for i in range(3):
            Vo[b, i] += d * Zo[b, i]


# Not inlined, as kernels/step/switch.py's settle_switches: it runs only on steps with a switch.
@kernel
def settle_team_switches(S, W, P, T, A, h, p0, po, Pi, off0):
    """Settle the switch errors (:func:`team_switch_errors`) of a team step just committed to
    ``S``, ``A``: per element with an error, string 0's first, the impulse along it that changes
    the team's kinetic energy by -error (module docstring), into ``S.p``, ``A.p``, ``S.Pi``; what
    has no root into the owed energies (whose other entries are zeroed). The velocities of the new
    state come from the momenta ``p0`` (N+1, 3), ``po`` (rows, 3) and ``Pi`` (3,) (``S.p``,
    ``A.p``, ``S.Pi``, or a reeling team's less the flow's) with the factors of ``T`` and string
    0's off-diagonal ``off0`` [kg]."""
    team_node_velocities(p0, po, Pi, S.R, P.first, off0, T, W.dy, A.X)
    for k in range(-1, T.first.shape[0]):  # string 0 (k = -1), then the others: one call site
        errors = W.switch
        owed = S.owed
        settled = P.settle
        if k >= 0:
            errors = A.switch[T.start[k]:T.start[k + 1]]
            owed = A.owed[T.start[k]:T.start[k + 1]]
            settled = T.settle and T.slack[k]
        if settled:
            for a in range(errors.shape[0] - (0 if k < 0 else 1)):
                settle_element(S, P, T, A, W, h, k, a, errors, owed, off0, A.X, A.fn)
