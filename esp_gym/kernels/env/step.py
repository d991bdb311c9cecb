"""The environment's compiled control step: the raw action -> the inputs -> the physics' loop ->
the balances closed -> the tasks' stages (kernels/env/task_terms.py: features, observation, reward
terms, termination) -> the energy watchdog. The single and the batched environments call the
same :func:`control_step`, so their results agree bit for bit; esp_gym/pendulum/control.py is their
Python face, and the point pivot's entry points at the end, one per rig (``point_explicit``,
``point_implicit``, ``point_explicit_winch``, ``point_implicit_winch``), are the compiled calls it
makes.

The arrays are named structs (kernels/env/arrays.py's EnvArrays and the physics' in
kernels/layout.py); every packed vector is laid out by name: the action parameters
(ACTION_PARAMS) and the task parameters (TASK_PARAMS, from esp_gym/pendulum/tasks.py) in
kernels/env/arrays.py, the inputs (INPUTS) and the step report (REPORT) in kernels/layout.py.
"""
from typing import Any, NamedTuple

import numpy as np
from numba import prange

from ..jit import announce_compile, kernel
from ..step.diagnostics import diagnostics
from ..step.disturbance import disturb, external_potential
from ..sums import kahan_add
from ..layout import (B_DISSIPATION, B_WINCH_WORK, B_WORK, D_ENERGY, IN_BODY_TORQUE, IN_PIVOT_FORCE, IN_PIVOT_FORCE_END,
                      IN_SPATIAL_TORQUE, R_STATUS,
                      R_STEPS, R_TERMINATION, WN_LENGTH, WN_MASS_PER_LENGTH, WN_REEL_SPEED, DiagWork, LGVIParams,
                      StateArrays, WinchArrays, Work)
from .arrays import (A_BODY_TORQUE, A_PIVOT_FORCE, A_REEL_SPEED, ACTION_SIZE, AP_FORCE_LIMIT, AP_HIGH,
                     AP_HOVER_FORCE, AP_LOW, AP_MAX_REEL_SPEED, AP_TORQUE_LIMIT, O_UNSTRETCHED_LENGTH,
                     SCHEME_DISTURBED, TP_ENERGY_BOUND, TP_ENERGY_ORIGIN, TP_ENERGY_WATCHDOG, TP_STRING_LENGTH)
from ..rows import row_function
from ..status import ENERGY_BALANCE, OK
from ..step.loops import (advance_loop_explicit, advance_loop_explicit_damped, advance_loop_implicit,
                          advance_loop_implicit_damped, winch_loop_explicit, winch_loop_implicit)
from ..step.winch import length_params, winch_energy
from .arrays import EnvArrays
from .task_terms import observe_and_score
from .track_curve import advance_reference


@kernel(inline="always")
def energy_watchdog(S, D, tp, code):
    """``code``, or ENERGY_BALANCE where the energy balance of the state just observed (``D``
    filled) broke the episode's bound: |E - E0 - W| > f (scale + |W|), W the inputs' and the
    winch's work less what the string's dampers took, E0 the reset's energy (docs/physics.md,
    "The energy watchdog"). It outranks the task's terminations."""
    work = S.acc[B_WORK] + S.acc[B_WINCH_WORK] - S.acc[B_DISSIPATION]
    residual = D.out[D_ENERGY] - tp[TP_ENERGY_ORIGIN] - work
    if not (abs(residual) <= tp[TP_ENERGY_BOUND] + tp[TP_ENERGY_WATCHDOG] * abs(work)):
        return ENERGY_BALANCE
    return code


@kernel(inline="always")
def action_inputs(action, ap, inputs):
    """Clipped action (ACTION) -> kernel inputs (INPUTS): pivot force hover + force_limit x
    the action's pivot force [N] (spatial), body torque torque_limit x its body torque [N m],
    no spatial torque."""
    for i in range(3):
        inputs[IN_PIVOT_FORCE + i] = ap[AP_HOVER_FORCE + i] + ap[AP_FORCE_LIMIT] * action[A_PIVOT_FORCE + i]
        inputs[IN_PIVOT_FORCE_END + i] = inputs[IN_PIVOT_FORCE + i]  # held over the step
        inputs[IN_BODY_TORQUE + i] = ap[AP_TORQUE_LIMIT] * action[A_BODY_TORQUE + i]
        inputs[IN_SPATIAL_TORQUE + i] = 0.0


@kernel(entry=True)
def actions_finite(raw):
    """Whether every entry of the raw actions (B, ACTION) is finite (the batched envs check this
    before any sub-environment resets, so a bad call changes nothing)."""
    for b in range(raw.shape[0]):
        for i in range(raw.shape[1]):
            if not np.isfinite(raw[b, i]):
                return False
    return True


@kernel(inline="always")
def take_action(raw, ap, action, inputs):
    """Check, clip and map a raw action (ACTION, or WINCH_ACTION: ``action``'s size says): False,
    touching nothing, if any entry is not finite; else ``action`` = raw clipped to [low, high] (as
    np.clip; the reel speed's box is [-1, 1]) and ``inputs`` from it. Returns the reel speed
    [m/s] (0 without a winch) as a float, or -inf for an action that is not finite."""
    size = action.shape[0]
    for i in range(size):
        if not np.isfinite(raw[i]):
            return -np.inf
    for i in range(ACTION_SIZE):
        a = raw[i]
        if a < ap[AP_LOW + i]:
            a = ap[AP_LOW + i]
        elif a > ap[AP_HIGH + i]:
            a = ap[AP_HIGH + i]
        action[i] = a
    action_inputs(action, ap, inputs)
    if size == ACTION_SIZE:
        return 0.0
    action[A_REEL_SPEED] = min(max(raw[A_REEL_SPEED], -1.0), 1.0)
    return ap[AP_MAX_REEL_SPEED] * action[A_REEL_SPEED]


@kernel
def env_prepare(S, W, P, D, E, disturbed):
    """Before a control step's physics: with ``disturbed``, wind and pushes (kernels/step/disturbance.py)
    from the episode's DISTURBANCE_PARAMS ``E.dp``, the DISTURBANCE state ``E.ds`` and the next
    row ``E.drawn[0]`` of the random ``E.draws`` (rows of DRAWS; ``E.drawn[0]`` is then advanced)
    into ``W.ext``. Returns their potential at the start [J] (0 without)."""
    if not disturbed:
        return 0.0
    disturb(S.r, S.R, D.V, D.omega, P.rho, E.dp, E.ds, E.draws[E.drawn[0]], W.ext)
    E.drawn[0] += 1
    return external_potential(S, P, W.ext, 0 if P.first == 0 else 1)


@kernel(inline="always")
def control_step(S, W, P, D, WA, E, reel, disturbed, winched, implicit, damped=False):
    """One control step of one environment (``E``: its :class:`~esp_gym.kernels.env.arrays.EnvArrays`, the
    inputs already taken from the action, ``reel`` the reel speed [m/s]): :func:`env_prepare`,
    ``E.nsub[0]`` physics steps with constant inputs by the loop of the configuration,
    :func:`env_finish` (or :func:`env_finish_winched`). ``winched``, ``implicit`` and ``damped`` (the
    string's damper: kernels/step/damper.py; not with the winch) are the entry point's closure
    constants: inlined there, the other loops' calls are pruned and never compiled."""
    phi = env_prepare(S, W, P, D, E, disturbed)
    nsub = E.nsub[0]
    # the general loop: an environment always has inputs and, as a rule, an off-centre load
    if winched:
        if implicit:
            winch_loop_implicit(S, W, P, WA, D, E.inputs, reel, nsub, E.result, disturbed)
        else:
            winch_loop_explicit(S, W, P, WA, D, E.inputs, reel, nsub, E.result, disturbed)
        env_finish_winched(S, W, P, D, WA, E, phi, disturbed)
        return
    free = P.first == 0
    if implicit and damped:
        advance_loop_implicit_damped(S, W, P, E.inputs, nsub, E.result, free, True, True, P.compensated, False,
                                     disturbed)
    elif implicit:
        advance_loop_implicit(S, W, P, E.inputs, nsub, E.result, free, True, True, P.compensated, False, disturbed)
    elif damped:
        advance_loop_explicit_damped(S, W, P, E.inputs, nsub, E.result, free, True, True, P.compensated, False,
                                     disturbed)
    else:
        advance_loop_explicit(S, W, P, E.inputs, nsub, E.result, free, True, True, P.compensated, False, disturbed)
    env_finish(S, W, P, D, E, phi, disturbed)


@kernel(inline="always")
def close_balances(S, W, P, E, phi, disturbed):
    """After a control step's physics (``E.result``: its REPORT, int64): the external forces'
    work joins the balances (``disturbed``; ``phi`` their potential at the start) and the
    tracking reference advances. Returns the step's status."""
    if disturbed:
        kahan_add(S.acc, S.accc, B_WORK, external_potential(S, P, W.ext, 0 if P.first == 0 else 1) - phi)
    advance_reference(E.target, E.result[R_STEPS] * P.h)
    return E.result[R_STATUS]


@kernel
def env_finish(S, W, P, D, E, phi, disturbed):
    """After a control step's physics, without the winch: :func:`close_balances`, then the
    observation, reward terms and termination code."""
    status = close_balances(S, W, P, E, phi, disturbed)
    diagnostics(S, P, D)
    code = observe_and_score(S, P, D, E, E.tp[TP_STRING_LENGTH])
    E.result[R_TERMINATION] = status if status != OK else energy_watchdog(S, D, E.tp, code)


@kernel
def env_finish_winched(S, W, P, D, WA, E, phi, disturbed):
    """:func:`env_finish` with the winch: the energy and the observation at the unstretched length
    the step ended at, which ends the observation."""
    status = close_balances(S, W, P, E, phi, disturbed)
    length = WA.state[WN_LENGTH]
    winch_energy(S, P, WA, D, length, WA.state[WN_REEL_SPEED])
    n = S.r.shape[0] - 1
    Pl = length_params(P, WA, length, WA.state[WN_MASS_PER_LENGTH] * length / n, 0 if P.first == 0 else 1, n, False)
    code = observe_and_score(S, Pl, D, E, length)
    E.obs[O_UNSTRETCHED_LENGTH] = length
    E.result[R_TERMINATION] = status if status != OK else energy_watchdog(S, D, E.tp, code)


@kernel(entry=True)
def env_reset_observe(S, P, D, WA, E, winched):
    """Observation of a freshly set state (no step; a winch at the scene's length and at rest),
    whose energy becomes the episode's E0 (TP_ENERGY_ORIGIN). Returns the termination code."""
    diagnostics(S, P, D)
    E.tp[TP_ENERGY_ORIGIN] = D.out[D_ENERGY]
    code = observe_and_score(S, P, D, E, E.tp[TP_STRING_LENGTH])
    if winched:
        E.obs[O_UNSTRETCHED_LENGTH] = WA.state[WN_LENGTH]
    return code


#: Sub-environment b's row of each stacked struct (kernels/rows.py).
state_row = row_function(StateArrays)
work_row = row_function(Work)
diag_row = row_function(DiagWork)
winch_row = row_function(WinchArrays)
params_row = row_function(LGVIParams)
env_row = row_function(EnvArrays)


@kernel(inline="always")
def batch_loop(S, W, P, D, WA, E, raw, active, disturbed, winched, implicit, damped=False):
    """:func:`take_action` and :func:`control_step` for every environment b with ``active[b]``
    (each struct's row b by its row function, kernels/rows.py). A ``prange``: on numba's threads
    in an entry compiled with ``parallel=True``, a plain loop in one without."""
    for b in prange(raw.shape[0]):
        if active[b]:
            Eb = env_row(E, b)
            reel = take_action(raw[b], Eb.ap, Eb.action, Eb.inputs)
            if reel != -np.inf:
                control_step(state_row(S, b), work_row(W, b), params_row(P, b), diag_row(D, b), winch_row(WA, b),
                             Eb, reel, disturbed, winched, implicit, damped)


class EntryPoints(NamedTuple):
    """A rig's compiled entry points: one environment's step, a batch's in one thread, and a
    batch's on numba's threads (a vector env's ``threads`` > 1)."""

    step: Any
    batch: Any
    threaded_batch: Any


def _entry_points(winched: bool, implicit: bool, damped: bool = False):
    """:class:`EntryPoints` ``(step, batch, threaded_batch)``, the compiled entry points of the environment without or with the winch,
    on the explicit or the implicit string, without or with its damper (closure constants: each
    configuration compiles only its own loop and string step, when it is first asked for:
    :func:`control_step`).

    ``step(s, w, p, d, wa, e, raw, scheme)``: :func:`take_action` of the raw action (ACTION),
    then the control step (:func:`control_step`), for one environment (one compiled call per
    control step). Returns False, with nothing changed, if the raw action is not finite.
    ``s, w, p, d, wa, e`` are the fields of StateArrays, Work, LGVIParams, DiagWork, WinchArrays
    (read only when ``winched``) and EnvArrays (kernels/env/arrays.py) as *plain* tuples: numba's
    dispatcher types a plain tuple about twice as fast as a namedtuple (3 us less per call here),
    and the namedtuples are rebuilt for free in compiled code.

    ``scheme`` (int, bits SCHEME_*) turns on wind and pushes. It is an argument, not a
    compile-time constant: their code is small, and one compile serves both values.

    ``batch(s, w, p, d, wa, e, raw, active, scheme)``: :func:`batch_loop`, the same for every
    environment b with ``active[b]`` in turn (the raw actions (B, ACTION) must be finite:
    :func:`actions_finite`); every array of the six structs carries a leading batch axis (the
    constants of LGVIParams too). ``threaded_batch``, the same on numba's threads, is what a vector
    env with ``threads`` > 1 calls: on a machine shared with other work its threads wait for each
    other, so one thread is the default (docs/performance.md, "Threads").
    """

    # Both take control_step with ``winched``, ``implicit`` and ``damped`` as closure constants (numba
    # prunes the other loops' calls); the closures hold nothing but the three bools, so numba caches them (it
    # keys a closure by its cells, and a compiled function in a cell is another key in every process),
    # and kernel() names each configuration after them (jit.name_closure: step__implicit0_winched1).

    @kernel(entry=True)
    def step(s, w, p, d, wa, e, raw, scheme):
        E = EnvArrays(*e)
        reel = take_action(raw, E.ap, E.action, E.inputs)
        if reel == -np.inf:
            return False
        control_step(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), WinchArrays(*wa), E, reel,
                     (scheme & SCHEME_DISTURBED) != 0, winched, implicit, damped)
        return True

    @kernel(entry=True)
    def batch(s, w, p, d, wa, e, raw, active, scheme):
        batch_loop(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), WinchArrays(*wa), EnvArrays(*e), raw,
                   active, (scheme & SCHEME_DISTURBED) != 0, winched, implicit, damped)

    # another function, not batch with another option: numba's cache keys a function by its code,
    # not by its options, so the two would load each other's machine code
    @kernel(parallel=True, entry=True)
    def threaded_batch(s, w, p, d, wa, e, raw, active, scheme):
        batch_loop(StateArrays(*s), Work(*w), LGVIParams(*p), DiagWork(*d), WinchArrays(*wa), EnvArrays(*e), raw,
                   active, (scheme & SCHEME_DISTURBED) != 0, winched, implicit, damped)

    # the cold first steps of benchmarks.cold_start (docs/performance.md, "Start-up")
    which = ("the environment's step" + (" on the implicit string" if implicit else "")
             + (" with the winch" if winched else "") + (" with the string's damper" if damped else ""))
    return EntryPoints(announce_compile(step, which, COLD_ENV_STEP_S),
                       announce_compile(batch, "the batched " + which[4:], COLD_BATCH_STEP_S),
                       announce_compile(threaded_batch, "the threaded batched " + which[4:], COLD_THREADED_BATCH_STEP_S))


#: The seconds to the first step of an environment and of a vector environment on an empty cache
#: (2 cores; docs/performance.md, "Start-up"), said when their entry points first compile.
COLD_ENV_STEP_S = 30
COLD_BATCH_STEP_S = 30
#: ... and of a vector environment with threads > 1 (its threaded entry: numba's parallel transforms)
COLD_THREADED_BATCH_STEP_S = 42

# The point pivot's entry points ``(step, batch, threaded_batch)`` (:func:`_entry_points`), each
# named after its rig (esp_gym/physics/rig.py: a rig's name with "_" for "-"); each compiles only for the
# environments that use it.
point_explicit = _entry_points(winched=False, implicit=False)
point_implicit = _entry_points(winched=False, implicit=True)
point_explicit_winch = _entry_points(winched=True, implicit=False)
point_implicit_winch = _entry_points(winched=True, implicit=True)
point_explicit_damped = _entry_points(winched=False, implicit=False, damped=True)
point_implicit_damped = _entry_points(winched=False, implicit=True, damped=True)
