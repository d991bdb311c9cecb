"""What a team's state reads out, compiled (docs/physics.md, "Diagnostics of a team"): the node and
body velocities by the step's own factors (:func:`~esp_gym.kernels.team.switch.team_node_velocities`), the energy
terms, momenta and pi3 the watchdog weighs, and what an environment observes of each string and of
the load, in one call per control step.

It reads a team whose strings are at their scenes' lengths with the winches at rest (the factors
of :data:`~esp_gym.kernels.team.arrays.TeamParams` are those strings'); a team whose winches have reeled reads
out in Python (esp_gym/team/readout.py), with its Hamiltonian's flow terms.
"""
import math
from collections import namedtuple

from ..jit import kernel
from ..layout import Layout
from ..so3 import cross, rotated
from ..step.string import element_strain
from .switch import team_node_velocities

#: The read-out's packed scalars: the energy terms [J] (``kinetic`` of every node and the body's
#: rotation, not a drone's; ``potential_elastic``, ``potential_gravity``), ``pi3`` (e3 . (sum r x p
#: + R Pi)) [kg m^2/s], ``linear_momentum`` (3,) [kg m/s], the body's ``omega`` (3,, body frame)
#: [rad/s], the load's centre of mass ``load`` (3,) [m] and its ``load_velocity`` (3,) [m/s]
#: (spatial).
TEAM_READ = Layout(("kinetic", 1), ("potential_elastic", 1), ("potential_gravity", 1), ("pi3", 1),
                   ("linear_momentum", 3), ("omega", 3), ("load", 3), ("load_velocity", 3))
TR_KINETIC = TEAM_READ.scalar("kinetic")
TR_ELASTIC = TEAM_READ.scalar("potential_elastic")
TR_GRAVITY = TEAM_READ.scalar("potential_gravity")
TR_PI3 = TEAM_READ.scalar("pi3")
TR_MOMENTUM = TEAM_READ.start("linear_momentum")
TR_OMEGA = TEAM_READ.start("omega")
TR_LOAD = TEAM_READ.start("load")
TR_LOAD_VELOCITY = TEAM_READ.start("load_velocity")

#: The balance terms a team's simulator keeps beside its state's (esp_gym/team/simulator.py): the
#: energy at the last reset ``energy_origin``, the load force's work ``load_work`` and the jumps of
#: H at fixed (q, p) where the reel speeds changed ``winch_jumps`` since then [J].
TEAM_BALANCE = Layout(("energy_origin", 1), ("load_work", 1), ("winch_jumps", 1))
TB_ENERGY_ORIGIN = TEAM_BALANCE.scalar("energy_origin")
TB_LOAD_WORK = TEAM_BALANCE.scalar("load_work")
TB_WINCH_JUMPS = TEAM_BALANCE.scalar("winch_jumps")

#: A team's read-out (string 0 first in every per-string field): the node velocities ``V0``
#: (N+1, 3) of string 0 and ``Vo`` (rows, 3) of the others, stacked as
#: :data:`~esp_gym.kernels.team.arrays.TeamArrays`' rows [m/s]; per string its pivot's position ``pivot`` (K, 3)
#: [m] and velocity ``pivot_velocity`` (K, 3) [m/s], the pull of its first element on the pivot
#: ``tension`` (K, 3) [N] (kappa max(|x| - u, 0) x / |x|, x = r_1 - r_0: spatial), its stretched
#: over its unstretched length ``stretch`` (K,) [-], its unstretched ``length`` (K,) [m] (the
#: compiled read's input: the scenes'); the body's attitude ``R`` (3, 3); ``out`` the packed
#: :data:`TEAM_READ`; ``strain`` scratch of a string's elements' strain energies [J].
TeamReadArrays = namedtuple("TeamReadArrays", "V0 Vo pivot pivot_velocity tension stretch length R out strain")


@kernel(entry=True)
def team_read(S, P, T, A, RD):
    """Fill ``RD`` (:data:`TeamReadArrays`) from the team's state ``S`` (string 0 and the body),
    ``A`` (the others) with the lead's constants ``P`` and the team's ``T``."""
    R = S.R
    for i in range(3):
        for j in range(3):
            RD.R[i, j] = R[i, j]
    out = RD.out
    w = team_node_velocities(S.p, A.p, (S.Pi[0], S.Pi[1], S.Pi[2]), R, P.first, P.off, T, RD.V0, RD.Vo)
    for i in range(3):
        out[TR_OMEGA + i] = w[i]
    elastic, weighted = string_read(S.r, RD.V0, 0, P.kappa, P.u, P.slack, P.m, P.Mp, RD)
    for j in range(T.first.shape[0]):
        s, e = T.start[j], T.start[j + 1]
        x, z = string_read(A.r[s:e], RD.Vo[s:e], j + 1, T.kappa[j], T.u[j], T.slack[j], T.m[j], T.Mp[j], RD)
        elastic += x
        weighted += z
    load_z = body_read(S, P, RD, w)
    out[TR_ELASTIC] = elastic
    out[TR_GRAVITY] = -P.g * (weighted + P.M * load_z)
    momenta(S, A, RD, w)


@kernel(inline="always")
def string_read(r, V, k, kappa, u, slack, m, Mp, RD):
    """String ``k``'s pivot, its velocity, its first element's pull and its stretch into ``RD``
    from its nodes ``r`` (n+1, 3) and their velocities ``V``; returns its elastic potential [J]
    and its masses' weighted height sum_a w_a z_a [kg m] (w_a = m, halved at the ends, the pivot's
    ``Mp`` added to node 0's)."""
    n = r.shape[0] - 1
    for i in range(3):
        RD.pivot[k, i] = r[0, i]
        RD.pivot_velocity[k, i] = V[0, i]
    x0 = r[1, 0] - r[0, 0]
    x1 = r[1, 1] - r[0, 1]
    x2 = r[1, 2] - r[0, 2]
    first = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    pull = kappa * max(first - u, 0.0) / first
    RD.tension[k, 0] = pull * x0
    RD.tension[k, 1] = pull * x1
    RD.tension[k, 2] = pull * x2
    elastic, stretched = element_strain(r, kappa, u, slack, RD.strain)
    RD.stretch[k] = stretched / RD.length[k]
    weighted = (0.5 * m + Mp) * r[0, 2] + 0.5 * m * r[n, 2]
    for a in range(1, n):
        weighted += m * r[a, 2]
    return elastic, weighted


@kernel(inline="always")
def body_read(S, P, RD, w):
    """The load's centre of mass x + R rho_c and its velocity v_x + R (Omega x rho_c) into ``RD.out``
    (``w`` Omega, body frame [rad/s]); returns the centre's height (its e3 component) [m]."""
    n = S.r.shape[0] - 1
    out = RD.out
    q = rotated(S.R, (P.rho[0], P.rho[1], P.rho[2]))
    dq = rotated(S.R, cross(w, (P.rho[0], P.rho[1], P.rho[2])))
    for i in range(3):
        out[TR_LOAD + i] = S.r[n, i] + q[i]
        out[TR_LOAD_VELOCITY + i] = RD.V0[n, i] + dq[i]
    return out[TR_LOAD + 2]


@kernel(inline="always")
def momenta(S, A, RD, w):
    """The kinetic energy 1/2 (sum p . v + Pi . Omega) [J], the linear momentum sum p and pi3 into
    ``RD.out`` (the others' ends' rows of ``A.p`` are 0: each end's share is on the body's)."""
    out = RD.out
    kinetic = S.Pi[0] * w[0] + S.Pi[1] * w[1] + S.Pi[2] * w[2]
    R = S.R
    pi3 = R[2, 0] * S.Pi[0] + R[2, 1] * S.Pi[1] + R[2, 2] * S.Pi[2]
    p0 = p1 = p2 = 0.0
    for r, p, V in ((S.r, S.p, RD.V0), (A.r, A.p, RD.Vo)):
        for a in range(r.shape[0]):
            kinetic += p[a, 0] * V[a, 0] + p[a, 1] * V[a, 1] + p[a, 2] * V[a, 2]
            pi3 += r[a, 0] * p[a, 1] - r[a, 1] * p[a, 0]
            p0 += p[a, 0]
            p1 += p[a, 1]
            p2 += p[a, 2]
    out[TR_KINETIC] = 0.5 * kinetic
    out[TR_PI3] = pi3
    out[TR_MOMENTUM] = p0
    out[TR_MOMENTUM + 1] = p1
    out[TR_MOMENTUM + 2] = p2
