"""Wind and pushes: external forces held over a control step, entering through the discrete
Lagrange-d'Alembert principle (docs/physics.md, "Wind and pushes").

At the start of a control step :func:`disturb` advances the gusts (an Ornstein-Uhlenbeck process
sampled exactly at the control period T: g <- a g + sigma sqrt(1 - a^2) xi, a = exp(-T/tau))
and computes, from the state's velocities (the diagnostics' ``D.V``, ``D.omega``), the forces
held until the next control step (``W.ext``, spatial frame [N]):

* on the line, per element e (nodes e, e+1; x_e = r_e+1 - r_e, tangent t_e): the cross-flow
  drag F_e = (rho C_d d / 2) |x_e| |v_n| v_n, v_n = v_rel - (v_rel . t_e) t_e the relative wind
  normal to the element (v_rel = wind - the mean of the two nodes' velocities), half to each node;
* on the load's centre of mass: the quadratic drag (rho C_d / 2) c(n) |v_rel| v_rel with c(n) the
  load's projected area across the relative wind's direction n (body frame; exact for the box,
  cylinders and the sphere: DISTURBANCE_PARAMS), plus a push when one falls in this step.

A force F held over a step of length h, applied at a point x(q), is the discrete force
f^- = f^+ = (h/2) (dx/dq)^T F: for a node a momentum kick, for the load's centre x = r_N + R rho_c
a kick of node N and of Pi by rho_c x (R^T F). The forced step therefore splits exactly into
kick(h/2) - unforced step - kick(h/2) (:func:`kick`; the kicks of consecutive steps merge). The
work of the held forces over the control step is Phi(end) - Phi(start), Phi = sum F_a . r_a +
F_L . (r_N + R rho_c) (:func:`external_potential`), exact for held forces.
"""
import math

from ..jit import kernel
from ..layout import B_ANGULAR_IMPULSE_Z, B_EXTERNAL_IMPULSE, Layout
from ..status import OK
from ..sums import kahan_add

#: An episode's wind and pushes (esp_gym/pendulum/wind.py; kernels/step/disturbance.py): the mean wind [m/s]
#: (spatial), the gusts' decay a = exp(-T/tau) per control step T and innovation sigma sqrt(1 -
#: a^2) [m/s] per axis; the line's drag per length and speed^2, rho_air C_d d / 2 [kg/m^2];
#: the load's drag area law c(n) = faces . |n| + side sqrt(a^2 n_y^2 + b^2 n_x^2) + round
#: (n the unit relative wind, body frame), each coefficient x rho_air C_d / 2 [kg/m] but the
#: semi-axes (a, b) [m]; the chance of a push per control step and its mean force [N].
DISTURBANCE_PARAMS = Layout(("mean_wind", 3), ("gust_decay", 1), ("gust_innovation", 3), ("line_drag", 1),
                            ("load_faces", 3), ("load_side", 1), ("load_semi_axes", 2), ("load_round", 1),
                            ("push_chance", 1), ("push_force", 1))
DP_MEAN_WIND = DISTURBANCE_PARAMS.start("mean_wind")
DP_GUST_DECAY = DISTURBANCE_PARAMS.scalar("gust_decay")
DP_GUST_INNOVATION = DISTURBANCE_PARAMS.start("gust_innovation")
DP_LINE_DRAG = DISTURBANCE_PARAMS.scalar("line_drag")
DP_LOAD_FACES = DISTURBANCE_PARAMS.start("load_faces")
DP_LOAD_SIDE = DISTURBANCE_PARAMS.scalar("load_side")
DP_LOAD_SEMI_AXES = DISTURBANCE_PARAMS.start("load_semi_axes")
DP_LOAD_ROUND = DISTURBANCE_PARAMS.scalar("load_round")
DP_PUSH_CHANCE = DISTURBANCE_PARAMS.scalar("push_chance")
DP_PUSH_FORCE = DISTURBANCE_PARAMS.scalar("push_force")

#: The wind and the external forces of the current control step, spatial frame: the gust and
#: the wind (mean + gust) [m/s], the drag on the load and the push on it, and the line's drag
#: summed over its nodes [N].
DISTURBANCE = Layout(("gust", 3), ("wind", 3), ("load_drag", 3), ("push", 3), ("line_drag", 3))
DS_GUST = DISTURBANCE.start("gust")
DS_WIND = DISTURBANCE.start("wind")
DS_LOAD_DRAG = DISTURBANCE.start("load_drag")
DS_PUSH = DISTURBANCE.start("push")
DS_LINE_DRAG = DISTURBANCE.start("line_drag")

#: The random numbers of one control step's disturbance, drawn ahead from np_random: standard
#: normal gust innovations, and uniforms on [0, 1) for a push's occurrence, azimuth and size.
DRAWS = Layout(("gust", 3), ("push_chance", 1), ("push_azimuth", 1), ("push_scale", 1))
DR_GUST = DRAWS.start("gust")
DR_PUSH_CHANCE = DRAWS.scalar("push_chance")
DR_PUSH_AZIMUTH = DRAWS.scalar("push_azimuth")
DR_PUSH_SCALE = DRAWS.scalar("push_scale")


@kernel(inline="always")
def load_area(dp, n0, n1, n2):
    """The load's drag area x rho C_d / 2 across the unit direction n (body frame) [kg/m]."""
    a = dp[DP_LOAD_SEMI_AXES]
    b = dp[DP_LOAD_SEMI_AXES + 1]
    return (dp[DP_LOAD_FACES] * abs(n0) + dp[DP_LOAD_FACES + 1] * abs(n1) + dp[DP_LOAD_FACES + 2] * abs(n2)
            + dp[DP_LOAD_SIDE] * math.sqrt(a * a * n1 * n1 + b * b * n0 * n0) + dp[DP_LOAD_ROUND])


# a called function, not numba-inlined: spliced into the batch's prange loop as numba IR
# (``inline="always"``, numba 0.68), its writes after the element loop were lost (the last
# node's and the load's rows stayed 0); once per control step, a call costs nothing here
@kernel
def disturb(r, R, V, om, rho, dp, ds, draw, ext):
    """One control step's gusts and held forces (module docstring) at the state's positions r,
    attitude R and attachment offset rho (rho_c) with its velocities from the diagnostics: node
    velocities V [m/s], body rate om (Omega, body frame) [rad/s]. ``dp`` the episode's
    DISTURBANCE_PARAMS, ``ds`` the DISTURBANCE state (gust in, everything out), ``draw`` this
    step's DRAWS, ``ext`` (N+2, 3) the held forces out [N]."""
    wind = gust(dp, ds, draw)
    n = r.shape[0] - 1
    line_drag(r, V, wind, dp[DP_LINE_DRAG], ds, ext)
    f0, f1, f2 = load_drag(R, V[n], om, rho, wind, dp, ds)
    q0, q1 = push(dp, draw, ds)
    ext[n + 1, 0] = f0 + q0
    ext[n + 1, 1] = f1 + q1
    ext[n + 1, 2] = f2


@kernel(inline="always")
def gust(dp, ds, draw):
    """The gust's next value (a first-order process driven by ``draw``) and the wind it makes with
    the mean, into ``ds``; returns the wind (3,) [m/s]."""
    a = dp[DP_GUST_DECAY]
    for i in range(3):
        g = a * ds[DS_GUST + i] + dp[DP_GUST_INNOVATION + i] * draw[DR_GUST + i]
        ds[DS_GUST + i] = g
        ds[DS_WIND + i] = dp[DP_MEAN_WIND + i] + g
    return ds[DS_WIND], ds[DS_WIND + 1], ds[DS_WIND + 2]


@kernel(inline="always")
def line_drag(r, V, wind, k, ds, ext):
    """Each element's drag across it, k |x| |v_n| v_n (v_n the wind relative to the element's mean
    velocity, less its part along x), half to each of its nodes, into ``ext`` rows 0..N; the sum
    into ``ds`` [N]."""
    w0, w1, w2 = wind
    n = r.shape[0] - 1
    s0 = s1 = s2 = 0.0
    h0 = h1 = h2 = 0.0  # the previous element's half
    for e in range(n):
        x0 = r[e + 1, 0] - r[e, 0]
        x1 = r[e + 1, 1] - r[e, 1]
        x2 = r[e + 1, 2] - r[e, 2]
        length = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        v0 = w0 - 0.5 * (V[e, 0] + V[e + 1, 0])
        v1 = w1 - 0.5 * (V[e, 1] + V[e + 1, 1])
        v2 = w2 - 0.5 * (V[e, 2] + V[e + 1, 2])
        if length > 0.0:
            along = (v0 * x0 + v1 * x1 + v2 * x2) / (length * length)
            v0 -= along * x0
            v1 -= along * x1
            v2 -= along * x2
        c = 0.5 * k * length * math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)  # half to each node
        f0 = c * v0
        f1 = c * v1
        f2 = c * v2
        ext[e, 0] = h0 + f0
        ext[e, 1] = h1 + f1
        ext[e, 2] = h2 + f2
        h0 = f0
        h1 = f1
        h2 = f2
        s0 += 2.0 * f0
        s1 += 2.0 * f1
        s2 += 2.0 * f2
    ext[n, 0] = h0
    ext[n, 1] = h1
    ext[n, 2] = h2
    ds[DS_LINE_DRAG] = s0
    ds[DS_LINE_DRAG + 1] = s1
    ds[DS_LINE_DRAG + 2] = s2


@kernel(inline="always")
def load_drag(R, v_end, om, rho, wind, dp, ds):
    """The load's drag, its area across the air relative to its centre of mass (moving at the
    end node's ``v_end`` + R (om x rho)) times that air's speed and velocity, into ``ds``;
    returns it (3,) [N]."""
    w0, w1, w2 = wind
    c0 = om[1] * rho[2] - om[2] * rho[1]
    c1 = om[2] * rho[0] - om[0] * rho[2]
    c2 = om[0] * rho[1] - om[1] * rho[0]
    v0 = w0 - (v_end[0] + R[0, 0] * c0 + R[0, 1] * c1 + R[0, 2] * c2)
    v1 = w1 - (v_end[1] + R[1, 0] * c0 + R[1, 1] * c1 + R[1, 2] * c2)
    v2 = w2 - (v_end[2] + R[2, 0] * c0 + R[2, 1] * c1 + R[2, 2] * c2)
    speed = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    f0 = f1 = f2 = 0.0
    if speed > 0.0:
        b0 = (R[0, 0] * v0 + R[1, 0] * v1 + R[2, 0] * v2) / speed  # R^T v_rel / |v_rel|
        b1 = (R[0, 1] * v0 + R[1, 1] * v1 + R[2, 1] * v2) / speed
        b2 = (R[0, 2] * v0 + R[1, 2] * v1 + R[2, 2] * v2) / speed
        c = load_area(dp, b0, b1, b2) * speed
        f0 = c * v0
        f1 = c * v1
        f2 = c * v2
    ds[DS_LOAD_DRAG] = f0
    ds[DS_LOAD_DRAG + 1] = f1
    ds[DS_LOAD_DRAG + 2] = f2
    return f0, f1, f2


@kernel(inline="always")
def push(dp, draw, ds):
    """This step's push, if ``draw`` says one comes: horizontal, 0.5-1.5 x the mean force, at a
    drawn azimuth, into ``ds``; returns its two horizontal components [N]."""
    q0 = q1 = 0.0
    if draw[DR_PUSH_CHANCE] < dp[DP_PUSH_CHANCE]:
        size = dp[DP_PUSH_FORCE] * (0.5 + draw[DR_PUSH_SCALE])
        azimuth = 2.0 * math.pi * draw[DR_PUSH_AZIMUTH]
        q0 = size * math.cos(azimuth)
        q1 = size * math.sin(azimuth)
    ds[DS_PUSH] = q0
    ds[DS_PUSH + 1] = q1
    ds[DS_PUSH + 2] = 0.0
    return q0, q1


@kernel(inline="always")
def load_point(r, R, rho, i):
    """Coordinate ``i`` of the load's centre of mass r_N + R rho_c [m]."""
    n = r.shape[0] - 1
    return r[n, i] + (R[i, 0] * rho[0] + R[i, 1] * rho[1] + R[i, 2] * rho[2])


@kernel(inline="always")
def external_potential(S, P, ext, first):
    """Phi = sum_{a >= first} F_a . r_a + F_L . (r_N + R rho_c) [J] of the held forces ``ext``."""
    r = S.r
    n = r.shape[0] - 1
    phi = 0.0
    for a in range(first, n + 1):
        phi += ext[a, 0] * r[a, 0] + ext[a, 1] * r[a, 1] + ext[a, 2] * r[a, 2]
    for i in range(3):
        phi += ext[n + 1, i] * load_point(r, S.R, P.rho, i)
    return phi


# inlined by LLVM (``forceinline``, kernels/jit.py), not as numba IR (see disturb): as a call in
# every physics step it added 49 % to a batched control step, inlined 14 % (9 % single); it takes the arrays it
# needs only (a namedtuple argument of a call is copied field by field)
@kernel(forceinline=True)
def kick(r, p, R, Pi, acc, accc, rho, ext, c, first):
    """The held forces' half of a step, scaled: p_a += c F_a (nodes a >= first), p_N += c F_L,
    Pi += c rho_c x (R^T F_L) (c = h/2 for one side of one step [s]); their impulse c sum F and
    angular impulse about e3, c e3 . sum x x F, join the balances ``acc`` (remainders ``accc``)."""
    n = r.shape[0] - 1
    t0 = t1 = t2 = ang = 0.0
    for a in range(first, n + 1):
        e0 = ext[a, 0]
        e1 = ext[a, 1]
        e2 = ext[a, 2]
        p[a, 0] += c * e0
        p[a, 1] += c * e1
        p[a, 2] += c * e2
        ang += r[a, 0] * e1 - r[a, 1] * e0
        t0 += e0
        t1 += e1
        t2 += e2
    F0 = ext[n + 1, 0]
    F1 = ext[n + 1, 1]
    F2 = ext[n + 1, 2]
    p[n, 0] += c * F0
    p[n, 1] += c * F1
    p[n, 2] += c * F2
    b0 = R[0, 0] * F0 + R[1, 0] * F1 + R[2, 0] * F2  # R^T F_L
    b1 = R[0, 1] * F0 + R[1, 1] * F1 + R[2, 1] * F2
    b2 = R[0, 2] * F0 + R[1, 2] * F1 + R[2, 2] * F2
    Pi[0] += c * (rho[1] * b2 - rho[2] * b1)
    Pi[1] += c * (rho[2] * b0 - rho[0] * b2)
    Pi[2] += c * (rho[0] * b1 - rho[1] * b0)
    ang += load_point(r, R, rho, 0) * F1 - load_point(r, R, rho, 1) * F0
    kahan_add(acc, accc, B_EXTERNAL_IMPULSE, c * (t0 + F0))
    kahan_add(acc, accc, B_EXTERNAL_IMPULSE + 1, c * (t1 + F1))
    kahan_add(acc, accc, B_EXTERNAL_IMPULSE + 2, c * (t2 + F2))
    kahan_add(acc, accc, B_ANGULAR_IMPULSE_Z, c * ang)


# The kicks around a run of steps, for every loop (kernels/step/loops.py, kernels/drone/env.py,
# kernels/team/loops.py): the held forces act as kicks of h/2 on both sides of each step, the two
# between consecutive steps merged into one of h.
@kernel(inline="always")
def kick_before(S, W, P, nsteps, disturbed):
    """The first step's first half kick (h/2) of a run of ``nsteps`` steps (``disturbed``)."""
    if disturbed and nsteps > 0:
        kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, 0.5 * P.h, 0 if P.first == 0 else 1)


@kernel(inline="always")
def kick_back(S, W, P, disturbed):
    """Take the pending half kick back (-h/2): after a failed step, or where a run stops early."""
    if disturbed:
        kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, -0.5 * P.h, 0 if P.first == 0 else 1)


@kernel(inline="always")
def kick_next(S, W, P, k, nsteps, disturbed):
    """After step ``k`` of ``nsteps`` succeeded (``disturbed``): its second half and the next
    step's first (h), or the run's last half (h/2)."""
    if disturbed:
        c = P.h if k < nsteps - 1 else 0.5 * P.h
        kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, c, 0 if P.first == 0 else 1)


@kernel(inline="always")
def kick_after(S, W, P, status, k, nsteps, disturbed):
    """After step ``k`` of ``nsteps`` with ``status``: :func:`kick_next` on success, else
    :func:`kick_back`."""
    if status != OK:
        kick_back(S, W, P, disturbed)
    else:
        kick_next(S, W, P, k, nsteps, disturbed)
