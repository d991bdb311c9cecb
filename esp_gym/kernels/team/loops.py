"""A team's runs of steps (docs/physics.md, "A team: several strings on one body", "Drones at a
team's pivots", "Winches on a team's strings"): one loop, :func:`team_steps`, serves the point
pivots' entry (:func:`team_advance`, compiled without drones and winches: their branches are
pruned for ``None``), the drones' (:func:`team_drone_advance`) and the winches'
(:func:`team_winch_advance`).
"""
from ..drone.quadrotor import drone_at, start_wrench
from ..jit import kernel
from ..status import OK
from ..step.disturbance import kick_back, kick_before
from ..step.loops import finish, step_taken
from .drones import drones_finish, drones_solve
from .step import team_substep
from .winch import reel_targets, reeled_work, team_winch_substep


@kernel(forceinline=True)
def team_steps(S, W, P, T, A, TD, TW, inputs, nsteps, stats, disturbed, rates):
    """Up to ``nsteps`` team steps (kernels/team/step.py ``team_substep``), each with the drones of
    ``TD`` (kernels/team/drones.py; ``None``: point pivots only) solved before it and committed
    after it, the rate controller first when ``rates``; with the winches of ``TW``
    (kernels/team/winch.py; ``None``: fixed lengths) each string reels at its reel speed, and the
    run stops before a step (after the first) that a winch's range would cut, with status OK
    and fewer steps (the cut step is the caller's). Stop at the first failure with the last
    good state (a failing step moves nothing). ``stats`` as kernels/step/loops.py's, the drones'
    Newton iterations with the team's. ``disturbed``: the held force on the load's centre of
    mass ``W.ext[N+1]`` acts too, as kicks of h/2 on both sides of every step, the pending half
    taken back after a failure or a stop."""
    free = P.first == 0
    if TD is not None:
        for d in range(TD.pivot.shape[0]):
            start_wrench(drone_at(TD.arrays, d))
    kick_before(S, W, P, nsteps, disturbed)
    total = 0
    most = 0
    for k in range(nsteps):
        status = OK
        iters = 0
        if TW is not None:
            if not reel_targets(TW, P.h) and k > 0:
                kick_back(S, W, P, disturbed)  # the next step's half kick, given after the last
                finish(stats, OK, k, total, most)
                return
        if TD is not None:
            status, iters = drones_solve(TD, P, A, inputs, P.h, rates, P.compensated, k)
        if status == OK:
            if TW is not None:
                status, team_iters = team_winch_substep(S, W, P, T, A, TW, inputs, P.h, free, True, True,
                                                        P.compensated)
                if status == OK:
                    reeled_work(S, W, P, T, A, TW, P.h)
            else:
                status, team_iters = team_substep(S, W, P, T, A, inputs, P.h, free, True, True, P.compensated)
            iters += team_iters
            if TD is not None and status == OK:
                drones_finish(S, TD, P.h, P.compensated)
        failed, total, most = step_taken(S, W, P, stats, status, iters, k, nsteps, total, most, disturbed)
        if failed:
            return
    finish(stats, OK, nsteps, total, most)


@kernel(entry=True)
def team_advance(S, W, P, T, A, inputs, nsteps, stats, disturbed):
    """Take up to ``nsteps`` team steps with constant inputs (:func:`team_steps`, no drones). Every
    term is in (the general path): forced, coupled, the pivot and the compensation read from
    ``P``; ``disturbed``: the held force on the load (string 0's rows of ``W.ext`` zero)."""
    team_steps(S, W, P, T, A, None, None, inputs, nsteps, stats, disturbed, False)


@kernel(entry=True)
def team_drone_advance(S, W, P, T, A, TD, inputs, nsteps, stats, disturbed, rates):
    """:func:`team_advance` with the drones of ``TD`` at their pivots, their motor commands held
    (``rates``: the rate controller sets them before every step from the setpoint); every other
    free pivot pushed by its held force."""
    team_steps(S, W, P, T, A, TD, None, inputs, nsteps, stats, disturbed, rates)


@kernel(entry=True)
def team_winch_advance(S, W, P, T, A, TW, inputs, nsteps, stats, disturbed):
    """:func:`team_advance` while the winches of ``TW`` reel, each string at its held reel speed;
    stops before a step that a winch's range would cut (:func:`team_steps`)."""
    team_steps(S, W, P, T, A, None, TW, inputs, nsteps, stats, disturbed, False)
