"""A team's step while its winches reel (docs/physics.md, "Winches on a team's strings").

Every string k has its own winch at its pivot, with its unstretched length l_k and reel speed
v_k (a string whose reel is at rest takes the fixed-length step at its length). Each string's
step matrix is the single winch's (1w), A_k = Mbar_k - (h c_k / 2)(C_k - C_k^T), factored every
step (kernels/step/winch.py :func:`~.winch.factor_string`): strings 1..K-1 on their rows before the
slaved end, which reduces each to an end mass mu_k and a coupling, and string 0 with the body
whose inertia carries those end masses (as kernels/team/step.py's, recomputed per step). The stages
after Newton are kernels/team/step.py's with the step's constants (a :data:`~esp_gym.kernels.team.step.TeamParams` of
this step's arrays); the convective terms join the loads and impulses:
the left load h/2 f~_e(r_k) - c*_k - c_k (C^T r_k)_e, the right one
h/2 (f~_e(r_{k+1}) + (2/h) c_k (C dr)_e) + c*_k + c_k (C^T r_k)_e.

With K = 1 the step is the single winch's :func:`~.winch.winch_substep`, bit for bit.
"""
from collections import namedtuple

from ..jit import kernel
from ..layout import (B_GRAVITY_IMPULSE, B_WINCH_WORK, WN_EA, WN_END_SHARE, WN_LENGTH, WN_MASS_PER_LENGTH,
                      WN_MAX_LENGTH, WN_MAX_STRETCH, WN_MIN_LENGTH, WN_OFF_SHARE, WN_REEL_SPEED)
from ..so3 import cross, unrotated
from ..status import OK
from ..step.lgvi import rigid_increments
from ..step.step_shared import guarded_forces, held_inputs, left_torque, new_positions, next_attitude
from ..step.string import nodal_forces
from ..sums import kahan_add
from .arrays import TeamParams, add_end_loads, pivot_rows
from .step import add_left_load, commit_team_step, other_forces, other_increments
from .switch import settle_team_switches, team_switch_errors
from ..step.winch import (add_convective_forces, add_convective_impulse, body_schur, convective_momentum, convective_solve,
                          factor_string, length_params, midpoint_dH_dl)

#: A team's winches: ``lead`` string 0's :data:`~.layout.WinchArrays` (its ``state`` row 0 of
#: ``state``); ``state`` (K, WINCH.size) every string's WINCH vector (length, reel speed, its
#: constants, its range); per stacked row of strings 1..K-1 (kernels/team/step.py's rows) the
#: convective weights ``coef`` (row s + e: element e of the string starting at row s), the step's
#: factors ``lower``, ``upper``, ``diag``, ``inv``, ``cp``, the block's last column ``w`` and the
#: forces ``fl`` = f~ at r_k, ``fr`` = f~ at r_{k+1} with the convective impulse (2/h) c C dr;
#: per string 1..K-1 its end mass ``mu`` [kg], its coupling ``off`` = A_{e-1,e} [kg] and its
#: constants at the step's end length ``kappa`` [N/m], ``u`` [m], ``m`` [kg], ``max_len2``
#: [m^2]; the body's inertia with the end masses ``body`` (M' [kg], rho' (3) [m]) and ``J`` J'
#: (3, 3) [kg m^2]; ``target`` (K,) each string's length at the step's end [m].
TeamWinch = namedtuple("TeamWinch", "lead state coef lower upper diag inv cp w fl fr mu off kappa u m max_len2 body J "
                                    "target")


@kernel(inline="always")
def reel_terms(st, l0, l1, h, n):
    """A string's ``(v, c = mu v / N, the mean length's element mass m [kg])`` over a step
    l0 -> l1 of length ``h`` [m/s, kg/s, kg]."""
    mu = st[WN_MASS_PER_LENGTH]
    v = (l1 - l0) / h
    return v, mu * v / n, mu * (0.5 * (l0 + l1)) / n


@kernel(forceinline=True)
def reduce_others(T, TW, h, symmetric):
    """Each string j >= 1's step matrix factored on its rows before the end
    (:func:`~.winch.factor_string`), its end mass mu_j = A_ee - A_{e,e-1} A_{e-1,e} (A_II^-1)_{last,last}
    (into ``TW.mu``), its coupling A_{e-1,e} (``TW.off``; A_{e,e-1} into ``TW.lower`` at its end
    row) and its constants at the step's end length (``TW.kappa``, ``u``, ``m``, ``max_len2``).
    ``symmetric``: its mass matrix at that length instead (the velocities of the step's new
    state: :func:`settle_reeling_team`)."""
    for j in range(T.first.shape[0]):
        st = TW.state[j + 1]
        s = T.start[j]
        e = T.start[j + 1]
        n = e - s - 1  # elements; the end's local row
        first = pivot_rows(T, j)
        l0 = st[WN_LENGTH]
        l1 = TW.target[j + 1]
        _, c, m = reel_terms(st, l0, l1, h, n)
        skew = 0.5 * h * c
        if symmetric:
            m = st[WN_MASS_PER_LENGTH] * l1 / n
            skew = 0.0
        end = st[WN_END_SHARE] * m
        coef = TW.coef[s:e - 1]
        lower = TW.lower[s:e]
        upper = TW.upper[s:e]
        w = TW.w[s:e]
        mu = end
        coupling = 0.0
        lower[n] = 0.0
        if n - 1 >= first:  # a moving row next to the end
            factor_string(m, skew, st[WN_END_SHARE], st[WN_OFF_SHARE], coef, first, n - 1, T.Mp[j], end, lower, upper,
                          TW.diag[s:e], TW.inv[s:e], TW.cp[s:e], w)
            lower[n] = st[WN_OFF_SHARE] * m - skew * (coef[n - 1, 0] + coef[n - 1, 1])
            coupling = upper[n - 1]
            mu = end - lower[n] * coupling * w[n - 1]
        TW.mu[j] = mu
        TW.off[j] = coupling
        u = l1 / n
        TW.u[j] = u
        TW.m[j] = st[WN_MASS_PER_LENGTH] * u
        TW.kappa[j] = st[WN_EA] / u
        TW.max_len2[j] = (st[WN_MAX_STRETCH] * u) ** 2


@kernel(forceinline=True)
def assemble_body(P, T, TW):
    """The body's inertia with the other strings' end masses (docs/physics.md, "The assembled
    body", with this step's mu_j): M' and rho' into ``TW.body``, J' into ``TW.J``. With K = 1,
    P's own M, rho and J, bit for bit. Returns M'."""
    mass = P.M
    s0 = s1 = s2 = 0.0
    J = TW.J
    for a in range(3):
        for b in range(3):
            J[a, b] = P.J[a, b]
    for j in range(T.first.shape[0]):
        mu = TW.mu[j]
        rho = T.rho[j]
        mass += mu
        s0 += mu * (rho[0] - P.rho[0])
        s1 += mu * (rho[1] - P.rho[1])
        s2 += mu * (rho[2] - P.rho[2])
        rr = rho[0] * rho[0] + rho[1] * rho[1] + rho[2] * rho[2]
        for a in range(3):
            for b in range(3):
                J[a, b] += mu * ((rr if a == b else 0.0) - rho[a] * rho[b])
    TW.body[0] = mass
    TW.body[1] = P.rho[0] + s0 / mass
    TW.body[2] = P.rho[1] + s1 / mass
    TW.body[3] = P.rho[2] + s2 / mass
    return mass


@kernel(forceinline=True)
def reeling_forces(S, W, T, A, TW, h, first):
    """f~ = f + grad T0 at every string's r_k and l_0 (the reel's at rest: f itself): string
    0's into ``W.fl``, the others' into ``TW.fl``."""
    st = TW.state[0]
    n = S.r.shape[0] - 1
    for a in range(n + 1):
        for i in range(3):
            W.fl[a, i] = S.f[a, i]
    l0 = st[WN_LENGTH]
    v = (TW.target[0] - l0) / h
    if v != 0.0:
        add_convective_forces(S.r, TW.lead.coef, st[WN_MASS_PER_LENGTH] * v * v / (n * l0), W.fl, first)
    for a in range(A.f.shape[0]):
        for i in range(3):
            TW.fl[a, i] = A.f[a, i]
    for j in range(T.first.shape[0]):
        st = TW.state[j + 1]
        s = T.start[j]
        e = T.start[j + 1]
        nj = e - s - 1
        l0 = st[WN_LENGTH]
        v = (TW.target[j + 1] - l0) / h
        if v != 0.0:
            add_convective_forces(A.r[s:e], TW.coef[s:e - 1], st[WN_MASS_PER_LENGTH] * v * v / (nj * l0),
                                  TW.fl[s:e], pivot_rows(T, j))


@kernel(forceinline=True)
def reeling_end_loads(R, T, A, TW, h, forced):
    """Each string j >= 1 reduced to its end with its step's matrix: X_I = A_II^-1 B_I
    (:func:`~.winch.convective_solve`), its coupling momentum c*_j = A_{e,e-1} X_last plus its end's
    convective momentum c_j (C^T r_k)_e (into ``A.c``) and its left load h/2 f~_e - A.c[j].
    Returns as kernels/team/step.py's ``end_loads``: the sum of the left loads and their torque."""
    hh = 0.5 * h
    E0 = E1 = E2 = 0.0
    t0 = t1 = t2 = 0.0
    for j in range(T.first.shape[0]):
        st = TW.state[j + 1]
        s = T.start[j]
        e = T.start[j + 1]
        n = e - s - 1
        first = pivot_rows(T, j)
        _, c, _ = reel_terms(st, st[WN_LENGTH], TW.target[j + 1], h, n)
        r = A.r[s:e]
        X = A.X[s:e]
        coef = TW.coef[s:e - 1]
        up = (A.force[j, 0, 0], A.force[j, 0, 1], A.force[j, 0, 2])
        convective_solve(A.p[s:e], r, TW.fl[s:e], coef, c, hh, TW.lower[s:e], TW.inv[s:e], TW.cp[s:e], up,
                         first == 0 and forced, first, n - 1, X)
        lower = TW.lower[s + n]
        c0 = c * convective_momentum(r, coef, n, 0)
        c1 = c * convective_momentum(r, coef, n, 1)
        c2 = c * convective_momentum(r, coef, n, 2)
        if n - 1 >= first:
            c0 += lower * X[n - 1, 0]
            c1 += lower * X[n - 1, 1]
            c2 += lower * X[n - 1, 2]
        E0, E1, E2, t0, t1, t2 = add_left_load(A, T, R, j, (c0, c1, c2), TW.fl[e - 1], hh, (E0, E1, E2, t0, t1, t2))
    return E0, E1, E2, t0 / hh, t1 / hh, t2 / hh


@kernel(forceinline=True)
def reeling_right_forces(T, A, TW, h):
    """``TW.fr`` = f~ at r_{k+1} and l_1 plus the convective impulse (2/h) c C dr on every row
    of strings 1..K-1 that moves (``A.fn`` the forces at the new positions, ``A.Y`` the
    increments)."""
    for a in range(A.fn.shape[0]):
        for i in range(3):
            TW.fr[a, i] = A.fn[a, i]
    for j in range(T.first.shape[0]):
        st = TW.state[j + 1]
        s = T.start[j]
        e = T.start[j + 1]
        n = e - s - 1
        l1 = TW.target[j + 1]
        v, c, _ = reel_terms(st, st[WN_LENGTH], l1, h, n)
        if v != 0.0:
            add_convective_impulse(A.X[s:e], A.Y[s:e], TW.coef[s:e - 1], st[WN_MASS_PER_LENGTH] * v * v / (n * l1), c,
                                   h, TW.fr[s:e], pivot_rows(T, j))


@kernel(forceinline=True)
def factor_reeling_step(S, W, P, T, A, TW, h, first):
    """A reeling team step's matrices: the forces at the state's lengths with the convective ones
    (:func:`reeling_forces`), each other string reduced to its end (:func:`reduce_others`), the
    assembled body and string 0's step matrix factored with it (kernels/step/winch.py
    ``factor_string``, ``body_schur``) into ``TW``. Returns ``(v, c, m)`` of string 0's reel
    (:func:`reel_terms`) and the assembled body's M' [kg] and rho' (3,) [m]."""
    n = S.r.shape[0] - 1
    WA = TW.lead
    st = TW.state[0]
    v, c, m_mean = reel_terms(st, st[WN_LENGTH], TW.target[0], h, n)
    reeling_forces(S, W, T, A, TW, h, first)
    reduce_others(T, TW, h, False)
    mass = assemble_body(P, T, TW)
    rho_inertial = TW.body[1:]
    factor_string(m_mean, 0.5 * h * c, st[WN_END_SHARE], st[WN_OFF_SHARE], WA.coef, first, n, P.Mp, mass, WA.lower,
                  WA.upper, WA.diag, WA.inv, WA.cp, WA.w)
    body_schur(WA.jeff, TW.J, mass, rho_inertial, WA.inv[n])
    return v, c, m_mean, mass, rho_inertial


@kernel(forceinline=True)
def team_winch_substep(S, W, P, T, A, TW, inputs, h, free, forced, coupled, compensated):
    """Advance a team by one step of length ``h`` while string k's length goes
    ``TW.state[k, length] -> TW.target[k]``, in place (docs/physics.md, "Winches on a team's
    strings"); as kernels/team/step.py's ``team_substep`` otherwise (``S.f``, ``A.f`` the forces at
    the state's lengths on entry and at the targets on success; a failure leaves everything
    untouched, lengths too). Returns ``(status, newton_iterations)``."""
    R = S.R
    n = S.r.shape[0] - 1
    first = 0 if free else 1
    hh = 0.5 * h
    WA = TW.lead
    st = TW.state[0]
    l1 = TW.target[0]
    v, c, m_mean, mass, rho_inertial = factor_reeling_step(S, W, P, T, A, TW, h, first)
    held = held_inputs(inputs, forced)
    up0, up1, up2, _, _, _, tb0, tb1, tb2, ts0, ts1, ts2 = held
    l_0, l_1, l_2, t0, t1, t2 = left_torque(R, P, tb0, tb1, tb2, ts0, ts1, ts2, forced, coupled)
    E0, E1, E2, a0, a1, a2 = reeling_end_loads(R, T, A, TW, h, forced)
    t0 = t0 + a0
    t1 = t1 + a1
    t2 = t2 + a2
    convective_solve(S.p, S.r, W.fl, WA.coef, c, hh, WA.lower, WA.inv, WA.cp, (up0, up1, up2), free and forced, first,
                     n, W.X)
    add_end_loads(W.X, WA.w, (E0, E1, E2), first, T.first.shape[0])
    c0, c1, c2, e0, e1, e2, dr00, dr01, dr02, iters, status = rigid_increments(
        S, W, P, h, mass, rho_inertial, WA.jeff, WA.w, t0, t1, t2, free, forced, coupled)
    if status != OK:
        return status, iters
    Ts = TeamParams(T.start, T.first, TW.kappa, TW.u, TW.m, T.Mp, TW.off, T.slack, TW.max_len2, T.rho, TW.inv, TW.cp,
                    TW.w, mass, rho_inertial, WA.jeff, WA.inv, WA.cp, WA.w, T.settle)
    other_increments(S, W, Ts, A, h, forced, compensated)
    new_positions(S, W, first, compensated)
    # string 0's impulse h/2 (f~_k + f~_{k+1}) + c C dr, f_{k+1} added by the commit (as winch_substep)
    if v != 0.0:
        add_convective_impulse(W.X, W.Y, WA.coef, st[WN_MASS_PER_LENGTH] * v * v / (n * l1), c, h, W.fl, first)
    P1 = length_params(P, WA, l1, m_mean, first, n, False)
    status = guarded_forces(W.X, P1, W.fn)
    if status != OK:
        return status, iters
    next_attitude(S.R, S.Rc, W.FmI, W.RF, W.Rn, compensated)
    status = other_forces(S, W, P, Ts, A)
    if status != OK:
        return status, iters
    unsettled = team_switch_errors(S, W, P, Ts, A, TW)  # with each reel's share (kernels/team/switch.py)
    reeling_right_forces(T, A, TW, h)
    status = commit_team_step(S, W, P, P1, Ts, A, h, held, (c0, c1, c2), (l_0, l_1, l_2), (t0, t1, t2), (e0, e1, e2),
                              (dr00, dr01, dr02), W.fl, (TW.fl, TW.fr), (free, forced, coupled, compensated))
    if status != OK:
        return status, iters
    weight_at_mean_lengths(S, P, T, TW, h, m_mean, P1.m)
    if unsettled > 0:
        settle_reeling_team(S, W, P, T, A, TW, h)
    return OK, iters


# Not inlined, as kernels/step/switch.py's settle_switches: it runs only on steps with a switch.
@kernel
def settle_reeling_team(S, W, P, T, A, TW, h):
    """:func:`~esp_gym.kernels.team.switch.settle_team_switches` of a reeling step just committed, with the team's
    inverse Legendre transform at every string's new length (:func:`velocity_params`) on the
    momenta less the flow's (:func:`flow_free_momenta`), as kernels/step/winch.py's
    ``settle_reeling_switches``."""
    first = 0 if P.first == 0 else 1
    Td, off0 = velocity_params(S, P, T, TW, h, first)
    Pi = flow_free_momenta(S, T, A, TW, h, first)
    settle_team_switches(S, W, P, Td, A, h, TW.lead.pshift, TW.fl, Pi, off0)


@kernel(inline="always")
def velocity_params(S, P, T, TW, h, first):
    """The team's constants at every string's length ``TW.target`` with its symmetric mass matrix
    (the continuous Legendre transform's), the body's with those end masses: into the step's
    factors (made anew by the next step), string 0's into the diagnostics' ``TW.lead.d*``.
    Returns ``(TeamParams, string 0's off-diagonal [kg])``."""
    n = S.r.shape[0] - 1
    WA = TW.lead
    st = TW.state[0]
    reduce_others(T, TW, h, True)
    mass = assemble_body(P, T, TW)
    rho = TW.body[1:]
    m = st[WN_MASS_PER_LENGTH] * TW.target[0] / n
    factor_string(m, 0.0, st[WN_END_SHARE], st[WN_OFF_SHARE], WA.coef, first, n, P.Mp, mass, WA.lower, WA.upper,
                  WA.diag, WA.dinv, WA.dcp, WA.dw)
    body_schur(WA.djeff, TW.J, mass, rho, WA.dinv[n])
    return TeamParams(T.start, T.first, TW.kappa, TW.u, TW.m, T.Mp, TW.off, T.slack, TW.max_len2, T.rho, TW.inv,
                      TW.cp, TW.w, mass, rho, WA.djeff, WA.dinv, WA.dcp, WA.dw, T.settle), st[WN_OFF_SHARE] * m


@kernel(inline="always")
def flow_free_momenta(S, T, A, TW, h, first):
    """The momenta less the material's flow, p - c C^T r, at the step's reel speeds (docs/physics.md,
    "Winches on a team's strings"): string 0's into ``TW.lead.pshift`` (N+1, 3), the others' rows
    before their ends into ``TW.fl`` (their ends' rows 0), each end's flow c_j (C^T r)_e taken out
    of the body's p_x (string 0's last row) and, with its moment rho_j x R^T(.), out of Pi, which
    is returned (body frame) [kg m^2/s]."""
    n = S.r.shape[0] - 1
    ps = TW.lead.pshift
    st = TW.state[0]
    _, c, _ = reel_terms(st, st[WN_LENGTH], TW.target[0], h, n)
    for a in range(n + 1):
        for i in range(3):
            ps[a, i] = S.p[a, i] - (c * convective_momentum(S.r, TW.lead.coef, a, i) if a >= first else 0.0)
    t0, t1, t2 = S.Pi[0], S.Pi[1], S.Pi[2]
    for j in range(T.first.shape[0]):
        s = T.start[j]
        e = T.start[j + 1] - 1  # the end's row
        st = TW.state[j + 1]
        _, c, _ = reel_terms(st, st[WN_LENGTH], TW.target[j + 1], h, e - s)
        r = A.r[s:e + 1]
        coef = TW.coef[s:e]
        fj = pivot_rows(T, j)
        for a in range(e - s):
            for i in range(3):
                TW.fl[s + a, i] = A.p[s + a, i] - (c * convective_momentum(r, coef, a, i) if a >= fj else 0.0)
        q = (c * convective_momentum(r, coef, e - s, 0), c * convective_momentum(r, coef, e - s, 1),
             c * convective_momentum(r, coef, e - s, 2))
        for i in range(3):
            ps[n, i] -= q[i]
            TW.fl[e, i] = 0.0
        m0, m1, m2 = cross(T.rho[j], unrotated(S.R, q))
        t0 -= m0
        t1 -= m1
        t2 -= m2
    return t0, t1, t2


@kernel(forceinline=True)
def weight_at_mean_lengths(S, P, T, TW, h, m_mean, m1):
    """The commit counted each string's weight impulse at its end length; the step's is at its
    mean length (as the single winch's)."""
    n = S.r.shape[0] - 1
    kahan_add(S.acc, S.accc, B_GRAVITY_IMPULSE + 2, h * P.g * n * (m_mean - m1))
    for j in range(T.first.shape[0]):
        st = TW.state[j + 1]
        nj = T.start[j + 1] - T.start[j] - 1
        _, _, mj = reel_terms(st, st[WN_LENGTH], TW.target[j + 1], h, nj)
        kahan_add(S.acc, S.accc, B_GRAVITY_IMPULSE + 2, h * P.g * nj * (mj - TW.m[j]))


@kernel(inline="always")
def reeled_work(S, W, P, T, A, TW, h):
    """After a step: each reeling string's winch work, the midpoint rule h v dH/dl
    (:func:`~.winch.midpoint_dH_dl`), into ``S.acc`` (B_WINCH_WORK), and its length moved to
    its target."""
    first = 0 if P.first == 0 else 1
    for k in range(TW.state.shape[0]):
        st = TW.state[k]
        l0 = st[WN_LENGTH]
        l1 = TW.target[k]
        if l1 != l0:
            v = (l1 - l0) / h
            if k == 0:
                dH = midpoint_dH_dl(S.r, W.Y, st, TW.lead.coef, P.slack, P.g, h, l0, l1, first)
            else:
                s = T.start[k - 1]
                e = T.start[k]
                dH = midpoint_dH_dl(A.r[s:e], A.Y[s:e], st, TW.coef[s:e - 1], T.slack[k - 1], P.g, h, l0, l1,
                                    pivot_rows(T, k - 1))
            kahan_add(S.acc, S.accc, B_WINCH_WORK, h * v * dH)
        st[WN_LENGTH] = l1


@kernel(inline="always")
def reel_targets(TW, h):
    """Each string's length after the next step at its reel speed (WINCH ``reel_speed``), into
    ``TW.target``, held in its winch's range. Returns False if one was held there (that step's
    speed is not the state's: the Python side takes it, with H's jump; esp_gym/team/winches.py)."""
    inside = True
    for k in range(TW.state.shape[0]):
        st = TW.state[k]
        l1 = st[WN_LENGTH] + h * st[WN_REEL_SPEED]
        if l1 > st[WN_MAX_LENGTH]:
            l1 = st[WN_MAX_LENGTH]
            inside = False
        elif l1 < st[WN_MIN_LENGTH]:
            l1 = st[WN_MIN_LENGTH]
            inside = False
        TW.target[k] = l1
    return inside


@kernel(entry=True)
def team_winch_forces(S, P, T, A, TW):
    """The forces at the state's positions and every string's length: string 0's into ``S.f``,
    the others' into ``A.f`` (a state just set)."""
    n = S.r.shape[0] - 1
    Pl = length_params(P, TW.lead, TW.state[0, WN_LENGTH], 0.0, P.first, n, False)
    nodal_forces(S.r, Pl.kappa, Pl.u, Pl.m, Pl.M, Pl.Mp, Pl.g, Pl.slack, S.f)
    for j in range(T.first.shape[0]):
        st = TW.state[j + 1]
        s = T.start[j]
        e = T.start[j + 1]
        u = st[WN_LENGTH] / (e - s - 1)
        nodal_forces(A.r[s:e], st[WN_EA] / u, u, st[WN_MASS_PER_LENGTH] * u, 0.0, T.Mp[j], P.g, T.slack[j], A.f[s:e])
