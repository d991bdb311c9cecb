"""The drone's run of steps (docs/physics.md, "A drone at the pivot", "A drone at an offset hook"):
one loop, :func:`drone_steps`, for every drone rig, its optional structs pruned where they are
None (the winch ``WA``, the offset hook ``HK``: compiled once per rig, as
kernels/team/loops.py's loop is), served to the environment's control step
(kernels/drone/env.py) and to the drone's simulator (:func:`drone_advance`, esp_gym/physics/drone.py).
A drone step fails without moving the state, so the loop needs no checkpoint (kernels/step/loops.py
has the loops that do).
"""
from ..jit import kernel
from ..status import OK
from ..step.disturbance import kick_before
from ..step.damper import damper_half_step
from ..step.loops import finish, restore_state, save_state, step_taken
from ..step.string import nodal_forces
from .hook import hook_substep, hook_velocities
from .quadrotor import THRUST_RATES, actuate, drone_substep, drone_winch_step, rate_actuate, rate_loop_due, start_wrench


# A function of its own, not inlined, with the rig's structs as None-or-struct arguments: a runtime
# flag for the hook had doubled the loop's compile (3.7 -> 7.4 s).
@kernel
def drone_steps(S, W, P, WA, D, DR, HK, inputs, nsteps, stats, reel, coupled, disturbed, rates, damped):
    """Up to ``nsteps`` steps of :func:`~esp_gym.kernels.drone.quadrotor.drone_substep` with the ``inputs``
    held, or with the winch ``WA`` of :func:`~esp_gym.kernels.drone.quadrotor.drone_winch_step` reeling at
    ``reel`` [m/s], or at the offset hook ``HK`` of :func:`~esp_gym.kernels.drone.hook.hook_substep` (``WA``,
    ``HK`` None where the rig has none);
    ``rates``: the rate controller before each step its loop samples at (every step, or every
    ``rate_loop_steps``), at the body rates J_q^-1 Pi_q, or at an
    offset hook the Legendre transform's (``D.V`` its scratch); the held external forces
    (``disturbed``) as kicks of h/2 on both sides of each step (kernels/step/disturbance.py). Stops at
    the first failure with the last good state (its pending half kick taken back). ``stats``
    (int64, REPORT's first four): status, steps taken, total and largest Newton iterations per
    step (the drone's and the load's together). ``damped`` (None, or True for the damped rig: a
    type, so the damper is compiled only there): the string's damper over h/2 on both sides of each
    step (kernels/step/damper.py), its two halves between two steps taken as one flow over h (not
    across a held force's kick): a run is D_{h/2} L (D_h L)^(k-1) D_{h/2}. The state is saved before a
    step's first half, or before the last step's merged half (``W.backup``), and put back if the
    step fails (then with the last good step's closing half), so a failed step has moved nothing."""
    kick_before(S, W, P, nsteps, disturbed)
    start_wrench(DR)
    total = 0
    most = 0
    for k in range(nsteps):
        if rates and rate_loop_due(DR, k):
            if HK is not None:
                _, _, omega_q, _ = hook_velocities(S, P, DR, HK, D.V)
                rate_actuate(DR, omega_q)
            else:
                actuate(DR, THRUST_RATES)
        # the damper's halves between two steps are one flow over h, but not across a held force's kick
        lead = disturbed or k == 0
        merge = not disturbed and k + 1 < nsteps
        if damped is not None and lead:
            save_state(S, W.backup)
            damper_half_step(S, W, P, 0.5 * P.h, True, P.compensated)
        if WA is not None:
            status, iters = drone_winch_step(S, W, P, WA, D, DR, inputs, reel, P.compensated)
        elif HK is not None:
            status, iters = hook_substep(S, W, P, DR, HK, inputs, P.h, coupled, P.compensated)
        else:
            status, iters = drone_substep(S, W, P, DR, inputs, P.h, coupled, P.compensated)
        if damped is not None:
            # W.backup: the state before the step's first half, else the last step's before its
            # merged half, which then closes that step with h/2 if this one failed
            closing = status == OK or not lead
            if status != OK:
                restore_state(S, W.backup)
            elif merge:
                save_state(S, W.backup)
            if closing:
                damper_half_step(S, W, P, P.h if status == OK and merge else 0.5 * P.h, True, P.compensated)
        failed, total, most = step_taken(S, W, P, stats, status, iters, k, nsteps, total, most, disturbed)
        if failed:
            return
    finish(stats, OK, nsteps, total, most)


@kernel(entry=True)
def drone_advance(S, W, P, D, DR, HK, inputs, nsteps, stats, coupled, damped):
    """The drone simulator's steps (esp_gym/physics/drone.py): up to ``nsteps`` :func:`drone_steps` of
    length ``P.h`` with the motor commands held (``HK``: the offset hook, or None; ``damped``: None,
    or True with the string's damper), ``S.f`` first the forces at the state."""
    nodal_forces(S.r, P.kappa, P.u, P.m, P.M, P.Mp, P.g, P.slack, S.f)
    drone_steps(S, W, P, None, D, DR, HK, inputs, nsteps, stats, 0.0, coupled, False, False, damped)
