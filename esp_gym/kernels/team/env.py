"""A team environment's compiled control step (docs/team.md, "Speed"): the agents' actions ->
the pivots' forces or the drones' setpoints -> the team's run of physics steps
(kernels/team/loops.py ``team_steps``) -> the read-out (kernels/team/readout.py) -> the energy
watchdog -> the moving target -> the task (kernels/team/task.py), in one call per control step.
esp_gym/team/control.py is its Python face.

It serves a team whose strings keep their scenes' lengths (a team with winches steps in Python:
its runs are cut at the ends of the winches' ranges). A drone team's ``thrust_torque`` and
``motors`` actions become motor commands in Python (esp_gym/team/spaces.py ``DroneDrive``), held
over the step; ``thrust_rates`` sets the rate controller's setpoints here.

The entry points take their structs as plain tuples (numba's dispatcher types a plain tuple about
twice as fast as a namedtuple, kernels/env/step.py) and rebuild the namedtuples inside, for free.
"""
from collections import namedtuple

import numpy as np

from ..drone.quadrotor import DroneArrays
from ..env.arrays import T_LOAD, T_VELOCITY
from ..env.step import EntryPoints, params_row, state_row, work_row
from ..jit import announce_compile, kernel
from ..layout import (B_WINCH_WORK, B_WORK, IN_PIVOT_FORCE, IN_PIVOT_FORCE_END, R_STATUS, Layout, LGVIParams,
                      StateArrays, Work)
from ..env.track_curve import reference_at
from ..rows import row_function
from ..so3 import rotated
from ..status import ENERGY_BALANCE, OK, TERM_NONE
from .arrays import TeamArrays, TeamParams
from .drones import TeamDrones
from .loops import team_steps
from .readout import (TB_ENERGY_ORIGIN, TB_LOAD_WORK, TB_WINCH_JUMPS, TR_ELASTIC, TR_GRAVITY, TR_KINETIC,
                      TeamReadArrays, team_read)
from .task import TeamTaskArrays, team_task

#: A team environment's constants: each point pivot's force at action 1 ``force_scale`` and its
#: hover force ``hover_force`` (up: -e3) [N]; the energy watchdog's fraction f (``watchdog``, -1:
#: off) and its energy scale [J]; a drone's body rates at action 1 ``rate_limit`` (3,) [rad/s];
#: ``moving`` 1 when the target follows a reference (the ``track`` task).
TEAM_ENV = Layout(("force_scale", 1), ("hover_force", 1), ("watchdog", 1), ("energy_scale", 1), ("rate_limit", 3),
                  ("moving", 1))
TE_FORCE_SCALE = TEAM_ENV.scalar("force_scale")
TE_HOVER_FORCE = TEAM_ENV.scalar("hover_force")
TE_WATCHDOG = TEAM_ENV.scalar("watchdog")
TE_ENERGY_SCALE = TEAM_ENV.scalar("energy_scale")
TE_RATE_LIMIT = TEAM_ENV.start("rate_limit")
TE_MOVING = TEAM_ENV.scalar("moving")

#: Each drone's thrust at action 0 (its hover share) and its largest thrust [N].
TEAM_DRIVE = Layout(("hover_thrust", 1), ("max_thrust", 1))
TD_HOVER_THRUST = TEAM_DRIVE.scalar("hover_thrust")
TD_MAX_THRUST = TEAM_DRIVE.scalar("max_thrust")

#: A control step's report: the ``reward``, the smallest distance between two pivots
#: ``smallest`` [m], the termination ``code`` (kernels/status.py; -1: an action not finite, nothing
#: changed), the energy balance's ``residual`` E - E0 - W - W_winch and ``work`` W + W_winch [J].
TEAM_STEP = Layout(("reward", 1), ("smallest", 1), ("code", 1), ("residual", 1), ("work", 1))
TS_REWARD = TEAM_STEP.scalar("reward")
TS_SMALLEST = TEAM_STEP.scalar("smallest")
TS_CODE = TEAM_STEP.scalar("code")
TS_RESIDUAL = TEAM_STEP.scalar("residual")
TS_WORK = TEAM_STEP.scalar("work")

#: A team environment's arrays: its constants ``params`` (:data:`TEAM_ENV`), each drone's
#: ``drive`` (n, :data:`TEAM_DRIVE`), the clipped ``action`` (K, n_a) applied, the formation
#: ``formation`` (K, 3) (each pivot's target from the load's) [m], the ``reference`` (TARGET,
#: kernels/env/arrays.py; read when moving), the force on the load ``load_force`` (3,) (spatial)
#: [N], each drone's body rates ``drone_rates`` (n, 3) [rad/s] and the step's ``report``
#: (:data:`TEAM_STEP`).
TeamEnvArrays = namedtuple("TeamEnvArrays", "params drive action formation reference load_force drone_rates report")

#: A team simulator's structs, in the entry points' order (esp_gym/team/simulator.py
#: ``TeamSimulator.compiled``): string 0 and the body (StateArrays, Work, LGVIParams), the team's
#: TeamParams and TeamArrays, its drones (TeamDrones; None for point pivots), its read-out
#: (TeamReadArrays), the inputs (INPUTS), the loop's report (REPORT, int64) and the balance
#: (TEAM_BALANCE, kernels/team/readout.py).
TeamStructs = namedtuple("TeamStructs", "state work params team arrays drones read inputs stats balance")


@kernel(inline="always")
def clip_actions(raw, action):
    """``action`` = ``raw`` (K, n_a) clipped to [-1, 1] (as np.clip); False, touching nothing, if
    an entry is not finite."""
    for k in range(raw.shape[0]):
        for i in range(raw.shape[1]):
            if not np.isfinite(raw[k, i]):
                return False
    for k in range(raw.shape[0]):
        for i in range(raw.shape[1]):
            action[k, i] = min(max(raw[k, i], -1.0), 1.0)
    return True


@kernel(inline="always")
def pivot_forces(E, A, inputs, drones):
    """Each pivot's held force (spatial) [N]: a point pivot's force_scale x its action's first
    three less its hover force along e3 (e3 down); a drone's 0 (its thrust pair is set by its
    solve, kernels/team/drones.py). String 0's into ``inputs``, string j's into ``A.force[j - 1]``."""
    scale = E.params[TE_FORCE_SCALE]
    hover = E.params[TE_HOVER_FORCE]
    for k in range(E.action.shape[0]):
        for i in range(3):
            u = 0.0
            if not drones:
                u = scale * E.action[k, i]
                if i == 2:
                    u -= hover
            if k == 0:
                inputs[IN_PIVOT_FORCE + i] = u
                inputs[IN_PIVOT_FORCE_END + i] = u
            else:
                A.force[k - 1, 0, i] = u
                A.force[k - 1, 1, i] = u


@kernel(inline="always")
def rate_setpoints(E, TD):
    """Each drone's ``thrust_rates`` setpoint: the collective thrust clip(f_hover (1 + a_0), 0,
    f_max) [N] and the body rates rate_limit a_1..3 [rad/s] (esp_gym/team/spaces.py ``DroneDrive``)."""
    D = TD.arrays
    for d in range(TD.pivot.shape[0]):
        a = E.action[TD.pivot[d]]
        drive = E.drive[d]
        D.setpoint[d, 0] = min(max(drive[TD_HOVER_THRUST] * (1.0 + a[0]), 0.0), drive[TD_MAX_THRUST])
        for i in range(3):
            D.setpoint[d, 1 + i] = E.params[TE_RATE_LIMIT + i] * a[1 + i]


@kernel(inline="always")
def load_centre(S, P):
    """The load's centre of mass x + R rho_c (spatial) [m]."""
    n = S.r.shape[0] - 1
    q = rotated(S.R, (P.rho[0], P.rho[1], P.rho[2]))
    return S.r[n, 0] + q[0], S.r[n, 1] + q[1], S.r[n, 2] + q[2]


@kernel(inline="always")
def hold_load_force(W, F):
    """The held force ``F`` (3,) on the load's centre of mass into ``W.ext``'s last row, the rest 0."""
    n = W.ext.shape[0] - 1
    for a in range(n + 1):
        for i in range(3):
            W.ext[a, i] = F[i] if a == n else 0.0


@kernel(inline="always")
def drone_rates(TD, out):
    """Each drone's body rates Omega_q = J_q^-1 Pi_q (n, 3) into ``out`` (body frame) [rad/s], in
    the order of esp_gym/team/fleet.py ``Fleet.body_rates``. Returns their rotations' kinetic
    energy sum_q 1/2 Pi_q . Omega_q [J]."""
    D = TD.arrays
    kinetic = 0.0
    for d in range(TD.pivot.shape[0]):
        inv = D.inertia_inv[d]
        Pi = D.Pi[d]
        for i in range(3):
            out[d, i] = inv[i, 0] * Pi[0] + inv[i, 1] * Pi[1] + inv[i, 2] * Pi[2]
        kinetic += 0.5 * (Pi[0] * out[d, 0] + Pi[1] * out[d, 1] + Pi[2] * out[d, 2])
    return kinetic


@kernel(inline="always")
def balance_broken(residual, work, fraction, scale):
    """Whether an energy balance's ``residual`` breaks the watchdog's bound f (scale + |work|) [J]
    (esp_gym/physics/watchdog.py ``check_balance``; a NaN residual breaks it)."""
    return not (abs(residual) <= fraction * (scale + abs(work)))


@kernel(inline="always")
def team_watchdog(S, RD, E, B, drones_kinetic):
    """The energy balance of the state just read (``RD``): E - E0 - W - W_winch and W + W_winch
    into ``E.report`` (E with the drones' rotations, ``drones_kinetic`` [J]; W the inputs' work and
    the load force's, W_winch the winches'). Returns ENERGY_BALANCE if it breaks the bound, else
    TERM_NONE (docs/physics.md, "The energy watchdog")."""
    out = RD.out
    energy = out[TR_KINETIC] + drones_kinetic + out[TR_ELASTIC] + out[TR_GRAVITY]
    work = S.acc[B_WORK] + B[TB_LOAD_WORK]
    winch_work = S.acc[B_WINCH_WORK] + B[TB_WINCH_JUMPS]
    residual = energy - B[TB_ENERGY_ORIGIN] - work - winch_work
    E.report[TS_RESIDUAL] = residual
    E.report[TS_WORK] = work + winch_work
    fraction = E.params[TE_WATCHDOG]
    if fraction >= 0.0 and balance_broken(residual, work + winch_work, fraction, E.params[TE_ENERGY_SCALE]):
        return ENERGY_BALANCE
    return TERM_NONE


@kernel(inline="always")
def follow_reference(E, TK, time):
    """A moving target at ``time`` [s]: the reference (kernels/env/track_curve.py) into the load's target
    and its velocity, each pivot's target the load's plus its place in the formation."""
    reference_at(E.reference, time)
    for i in range(3):
        TK.load_target[i] = E.reference[T_LOAD + i]
        TK.target_velocity[i] = E.reference[T_VELOCITY + i]
    for k in range(TK.pivot_targets.shape[0]):
        for i in range(3):
            TK.pivot_targets[k, i] = TK.load_target[i] + E.formation[k, i]


@kernel(forceinline=True)
def team_control(S, W, P, T, A, TD, RD, TK, E, B, inputs, stats, nsteps, disturbed, rates, time):
    """One control step of a team (module docstring) after the action was clipped into
    ``E.action``: ``nsteps`` physics steps with the load force ``E.load_force`` held when
    ``disturbed`` (its work F . the centre's displacement into the balance ``B``), the drones' rate
    controller on when ``rates``; ``time`` the step's end [s]. The report into ``E.report``.
    Compiled once per signature: ``TD`` None (point pivots) prunes the drones' branches."""
    pivot_forces(E, A, inputs, TD is not None)
    if TD is not None:
        if rates:
            rate_setpoints(E, TD)
    if disturbed:
        hold_load_force(W, E.load_force)
        x0, x1, x2 = load_centre(S, P)
    team_steps(S, W, P, T, A, TD, None, inputs, nsteps, stats, disturbed, rates)
    if disturbed:
        y0, y1, y2 = load_centre(S, P)
        F = E.load_force
        B[TB_LOAD_WORK] += F[0] * (y0 - x0) + F[1] * (y1 - x1) + F[2] * (y2 - x2)
    team_read(S, P, T, A, RD)
    kinetic = 0.0
    if TD is not None:
        kinetic = drone_rates(TD, E.drone_rates)
    status = stats[R_STATUS]
    code = TERM_NONE if status == OK else status
    if code == TERM_NONE:
        code = team_watchdog(S, RD, E, B, kinetic)
    if E.params[TE_MOVING] != 0.0:
        follow_reference(E, TK, time)
    if TD is not None:
        drone_R = TD.arrays.R
    else:  # no drones: (0, 3, 3)
        drone_R = E.drone_rates.reshape((0, 3, 3))
    reward, smallest, code = team_task(RD, drone_R, E.drone_rates, E.action, TK, code)
    E.report[TS_REWARD] = reward
    E.report[TS_SMALLEST] = smallest
    E.report[TS_CODE] = code


@kernel(inline="always")
def team_structs(sim, env):
    """The namedtuples of an entry point's plain tuples ``sim`` (:data:`TeamStructs`, its drones
    apart) and ``env`` ((TeamTaskArrays, TeamEnvArrays)): ``(S, W, P, T, A, RD, TK, E, balance,
    inputs, stats)``, the order :func:`team_control` takes them in (its drones after ``A``)."""
    return (StateArrays(*sim[0]), Work(*sim[1]), LGVIParams(*sim[2]), TeamParams(*sim[3]), TeamArrays(*sim[4]),
            TeamReadArrays(*sim[6]), TeamTaskArrays(*env[0]), TeamEnvArrays(*env[1]), sim[9], sim[7], sim[8])


@kernel(inline="always")
def team_drones(sim):
    """The drones (:data:`~esp_gym.kernels.team.drones.TeamDrones`) of an entry point's plain tuples ``sim``."""
    td = sim[5]
    return TeamDrones(DroneArrays(*td[0]), td[1], td[2])


@kernel(entry=True)
def team_points_step(sim, env, raw, nsteps, disturbed, rates, time):
    """A point team's control step (:func:`team_control`) from the raw actions (K, n_a): ``sim``
    the simulator's :data:`TeamStructs` (its drones None), ``env`` the task's and the env's arrays
    ``(TeamTaskArrays, TeamEnvArrays)``, as plain tuples. Returns False, changing nothing, if an
    action is not finite. ``rates`` is unread (a drone team's: one signature for every team rig,
    esp_gym/physics/rig.py)."""
    S, W, P, T, A, RD, TK, E, B, inputs, stats = team_structs(sim, env)
    if not clip_actions(raw, E.action):
        return False
    team_control(S, W, P, T, A, None, RD, TK, E, B, inputs, stats, nsteps, disturbed, False, time)
    return True


@kernel(entry=True)
def team_drones_step(sim, env, raw, nsteps, disturbed, rates, time):
    """:func:`team_points_step` of a drone team: ``rates`` True sets the rate controller's
    setpoints from the actions (``thrust_rates``), False flies the motor commands held."""
    S, W, P, T, A, RD, TK, E, B, inputs, stats = team_structs(sim, env)
    if not clip_actions(raw, E.action):
        return False
    team_control(S, W, P, T, A, team_drones(sim), RD, TK, E, B, inputs, stats, nsteps, disturbed, rates, time)
    return True


#: Team b's row of each stacked struct (kernels/rows.py; the lead string's from kernels/env/step.py).
team_params_row = row_function(TeamParams)
team_arrays_row = row_function(TeamArrays)
team_read_row = row_function(TeamReadArrays)
team_task_row = row_function(TeamTaskArrays)
team_env_row = row_function(TeamEnvArrays)
drone_arrays_row = row_function(DroneArrays)


@kernel(inline="always")
def team_drones_row(TD, b):
    """Team b's drones of a stacked :data:`~esp_gym.kernels.team.drones.TeamDrones` (its ``arrays`` stacked too)."""
    return TeamDrones(drone_arrays_row(TD.arrays, b), TD.pivot[b], TD.pending[b])


@kernel(forceinline=True)
def team_batch_loop(S, W, P, T, A, TD, RD, TK, E, B, inputs, stats, raw, active, nsteps, disturbed, rates, times):
    """:func:`team_control` of every team b with ``active[b]`` in turn, each struct's row b
    (``TD`` None: point pivots; the raw actions (B, K, n_a) finite), team b's ``nsteps[b]`` physics
    steps ending at ``times[b]`` [s]. Compiled once per signature, as :func:`team_control`."""
    for b in range(raw.shape[0]):
        if active[b]:
            Eb = team_env_row(E, b)
            clip_actions(raw[b], Eb.action)
            Sb, Wb, Pb, Tb, Ab = state_row(S, b), work_row(W, b), params_row(P, b), team_params_row(T, b), \
                team_arrays_row(A, b)
            RDb, TKb = team_read_row(RD, b), team_task_row(TK, b)
            if TD is None:  # pruned at compile time: one of the two calls is compiled
                team_control(Sb, Wb, Pb, Tb, Ab, None, RDb, TKb, Eb, B[b], inputs[b], stats[b], nsteps[b], disturbed,
                             rates, times[b])
            else:
                team_control(Sb, Wb, Pb, Tb, Ab, team_drones_row(TD, b), RDb, TKb, Eb, B[b], inputs[b], stats[b],
                             nsteps[b], disturbed, rates, times[b])


@kernel(entry=True)
def team_points_batch(sim, env, raw, active, nsteps, disturbed, rates, times):
    """:func:`team_points_step` of a batch: every struct stacked along a leading (B,) axis (the
    constants too), the raw actions (B, K, n_a) finite, ``active`` (B,) bool the teams to step,
    ``nsteps`` (B,) int64 and ``times`` (B,) each team's physics steps and the step's end [s]."""
    S, W, P, T, A, RD, TK, E, B, inputs, stats = team_structs(sim, env)
    team_batch_loop(S, W, P, T, A, None, RD, TK, E, B, inputs, stats, raw, active, nsteps, disturbed, False, times)


@kernel(entry=True)
def team_drones_batch(sim, env, raw, active, nsteps, disturbed, rates, times):
    """:func:`team_drones_step` of a batch (:func:`team_points_batch`)."""
    S, W, P, T, A, RD, TK, E, B, inputs, stats = team_structs(sim, env)
    team_batch_loop(S, W, P, T, A, team_drones(sim), RD, TK, E, B, inputs, stats, raw, active, nsteps, disturbed,
                    rates, times)


#: The seconds to the first step of a team environment on an empty cache (2 cores;
#: benchmarks.cold_start's "team env (3)"), said when its entry point first compiles.
COLD_TEAM_STEP_S = 44
#: The team rigs' entry points (esp_gym/physics/rig.py), each the module-level name of its rig's name.
team_point_explicit = EntryPoints(announce_compile(team_points_step, "the team environment's step", COLD_TEAM_STEP_S),
                                  announce_compile(team_points_batch, "the batched team environment's step",
                                                   COLD_TEAM_STEP_S), None)
team_drone_explicit = EntryPoints(announce_compile(team_drones_step, "the drone team environment's step",
                                                   COLD_TEAM_STEP_S),
                                  announce_compile(team_drones_batch, "the batched drone team environment's step",
                                                   COLD_TEAM_STEP_S), None)
