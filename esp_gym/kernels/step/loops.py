"""The loops around the step of kernels/step/step.py: many steps in one compiled call with failure
recovery, at a fixed length (:func:`advance_loop` of ``lgvi_step``) or while the winch reels
(:func:`winch_loop` of ``winch_step``), and the same with snapshots for a recorded run
(:func:`record_loop`). A step that can fail part-way (composed, or cut back) is undone from a
checkpoint (:func:`_checkpoint`, :func:`_rewind`): saved every ``CHECKPOINT`` steps with a replay
at a fixed length, before every step while reeling (see :func:`winch_loop` for why). The drone's
loop (kernels/drone/loops.py ``drone_steps``) and the team's (kernels/team/loops.py ``team_steps``)
need no recovery: their steps fail without moving the state. Every loop takes the held forces'
kicks from kernels/step/disturbance.py (``kick_before``, ``kick_next``, ``kick_after``,
``kick_back``). Also the general-path entry points :func:`lgvi_advance`, :func:`lgvi_record`,
:func:`winch_advance` (the specialised ones are in kernels/step/specialise.py) and the environment's
loops, one per configuration (:func:`shared_advance_loop`, :func:`shared_winch_loop`).

``stats`` is the first ``LOOP_REPORT_SIZE`` entries of a :data:`~.layout.REPORT` (int64).
"""
from ..jit import kernel
from .diagnostics import diagnostics
from ..layout import (D_ENERGY, D_ORTHOGONALITY, D_PI3, R_NEWTON_MAX, R_NEWTON_TOTAL, R_STATUS, R_STEPS, SD_ENERGY,
                      SD_ORTHOGONALITY, SD_PI3)
from ..status import OK
from .disturbance import kick_after, kick_back, kick_before, kick_next
from .step import lgvi_step, winch_step
from .string import nodal_forces


@kernel(entry=True)
def state_size(S):
    """Number of floats :func:`save_state` writes."""
    return 5 * S.r.size + 2 * S.R.size + 2 * S.Pi.size + 2 * S.acc.size + S.owed.size


@kernel(forceinline=True)
def _rows_out(a, buf, k):
    """Copy the (rows, 3) array ``a`` to ``buf[k:]``; returns the next offset. One call per array
    with the 3 columns spelled out: a loop over a tuple of arrays compiled to ~5x slower code,
    which cost 13 % of a composed step. Compiled once and inlined by LLVM (``forceinline``):
    numba-inlined, the copies were 3 s of the first start."""
    for i in range(a.shape[0]):
        buf[k] = a[i, 0]
        buf[k + 1] = a[i, 1]
        buf[k + 2] = a[i, 2]
        k += 3
    return k


@kernel(forceinline=True)
def _rows_in(a, buf, k):
    """Inverse of :func:`_rows_out`."""
    for i in range(a.shape[0]):
        a[i, 0] = buf[k]
        a[i, 1] = buf[k + 1]
        a[i, 2] = buf[k + 2]
        k += 3
    return k


@kernel(forceinline=True)
def _vector_out(a, buf, k):
    """Copy the vector ``a`` to ``buf[k:]``; returns the next offset."""
    for i in range(a.shape[0]):
        buf[k + i] = a[i]
    return k + a.shape[0]


@kernel(forceinline=True)
def _vector_in(a, buf, k):
    """Inverse of :func:`_vector_out`."""
    for i in range(a.shape[0]):
        a[i] = buf[k + i]
    return k + a.shape[0]


@kernel
def save_state(S, buf):
    """Copy the whole state (with remainders, balances and the forces ``S.f``) into ``buf``."""
    k = _rows_out(S.r, buf, 0)
    k = _rows_out(S.p, buf, k)
    k = _rows_out(S.rc, buf, k)
    k = _rows_out(S.pc, buf, k)
    k = _rows_out(S.R, buf, k)
    k = _rows_out(S.Rc, buf, k)
    k = _vector_out(S.Pi, buf, k)
    k = _vector_out(S.Pic, buf, k)
    k = _vector_out(S.acc, buf, k)
    k = _vector_out(S.accc, buf, k)
    k = _vector_out(S.owed, buf, k)
    _rows_out(S.f, buf, k)


@kernel
def restore_state(S, buf):
    """Inverse of :func:`save_state`."""
    k = _rows_in(S.r, buf, 0)
    k = _rows_in(S.p, buf, k)
    k = _rows_in(S.rc, buf, k)
    k = _rows_in(S.pc, buf, k)
    k = _rows_in(S.R, buf, k)
    k = _rows_in(S.Rc, buf, k)
    k = _vector_in(S.Pi, buf, k)
    k = _vector_in(S.Pic, buf, k)
    k = _vector_in(S.acc, buf, k)
    k = _vector_in(S.accc, buf, k)
    k = _vector_in(S.owed, buf, k)
    _rows_in(S.f, buf, k)


#: Composed steps are checkpointed every this many steps (see advance_loop).
CHECKPOINT = 64


@kernel
def finish(stats, status, steps, total, most):
    stats[R_STATUS] = status
    stats[R_STEPS] = steps
    stats[R_NEWTON_TOTAL] = total
    stats[R_NEWTON_MAX] = most


@kernel(inline="always")
def step_taken(S, W, P, stats, status, iters, k, nsteps, total, most, disturbed):
    """After step ``k`` of a run of ``nsteps`` ended with ``status`` and ``iters`` Newton iterations:
    those counted into ``total`` and ``most``, the held forces' kicks after it
    (kernels/step/disturbance.py ``kick_after``) and, on a failure, ``stats`` filled with the ``k`` good
    steps. Returns ``(failed, total, most)``."""
    total += iters
    most = max(most, iters)
    kick_after(S, W, P, status, k, nsteps, disturbed)
    if status != OK:
        finish(stats, status, k, total, most)
        return True, total, most
    return False, total, most


@kernel(inline="always")
def _checkpoint(S, W, WA, winched):
    """Save the state (with its forces ``S.f``) and, ``winched``, the winch's state (its length
    and reel speed) for a replay."""
    save_state(S, W.backup)
    if winched:
        st = WA.state
        for i in range(st.shape[0]):
            WA.backup[i] = st[i]


@kernel(inline="always")
def _rewind(S, W, WA, winched):
    """Back to the last checkpoint, with its forces ``S.f`` (for the implicit string they are
    the last step's, its first guess, so a replay needs the saved ones) and the winch's state."""
    restore_state(S, W.backup)
    if winched:
        st = WA.state
        for i in range(st.shape[0]):
            st[i] = WA.backup[i]


@kernel(inline="always")
def advance_loop(S, W, P, inputs, nsteps, stats, free, forced, coupled, compensated, forces_ready=False,
                 implicit=False, disturbed=False, damped=False):
    """Take up to ``nsteps`` steps (:func:`lgvi_step`) with constant ``inputs``; stop at the
    first failure with the last good state. ``stats`` (int64, >= 4): status, steps taken, total
    Newton iterations, max per step. The flags are constants in the simulator's specialised
    kernels, which inline this loop and prune its dead branches; the environment's step calls
    it through :func:`shared_advance_loop`, ``implicit`` compiled in and the other flags
    arguments.

    A composed step (or a cut-back implicit one) that fails part-way has moved the state.
    Instead of copying the state before every step (that cost 13 % of a composed step), the
    state is saved every ``CHECKPOINT`` steps; after a failure the loop rewinds to the
    checkpoint and replays the steps that had succeeded. The replay is deterministic (same
    state bits, inputs and code), so it ends on exactly the state after the last good step. One
    call site of the step keeps the inlined code single. ``forces_ready``: ``S.f`` already
    holds the forces at ``S.r`` (as it does after any successful step), so they are not
    recomputed. ``implicit``: the implicit string's step; its ``S.f`` is part of the state (the
    last step's forces, its first guess: kernels/step/implicit.py) and is never recomputed here.
    ``disturbed``: the held external forces ``W.ext`` act too, as kicks of h/2 on both sides of
    every step (kernels/step/disturbance.py), the kicks between two steps merged into one; after a
    failure the pending half kick is taken back. ``damped`` (a constant): the string's damper on both
    sides of every step (kernels/step/damper.py; a step that can fail part-way), its halves between two
    steps one flow over h (not across kicks): D_{h/2} L (D_h L)^(k-1) D_{h/2} from each checkpoint."""
    kick_before(S, W, P, nsteps, disturbed)
    if not forces_ready and not implicit:
        nodal_forces(S.r, P.kappa, P.u, P.m, P.M, P.Mp, P.g, P.slack, S.f)
    composed = P.gammas.shape[0] > 1 or implicit or damped
    total = 0
    most = 0
    failed = OK
    target = nsteps
    k = 0
    k0 = 0
    while k < target:
        if composed and failed == OK and k % CHECKPOINT == 0:
            _checkpoint(S, W, None, False)
            k0 = k
        lead = disturbed or k % CHECKPOINT == 0
        merge = not disturbed and k + 1 < target and (k + 1) % CHECKPOINT != 0
        status, iters = lgvi_step(S, W, P, inputs, free, forced, coupled, compensated, implicit, damped, lead,
                                  merge)
        if failed == OK:
            total += iters
            most = max(most, iters)
        if status != OK:
            if failed != OK or not composed:  # (a replayed step cannot fail: it did not before)
                kick_back(S, W, P, disturbed)
                finish(stats, status, k, total, most)
                return
            failed = status
            target = k
            _rewind(S, W, None, False)
            k = k0
            continue
        kick_next(S, W, P, k, target, disturbed)
        k += 1
    if failed != OK and target == k0:  # rewound to a checkpoint, no step to replay
        kick_back(S, W, P, disturbed)
    finish(stats, failed, target, total, most)


@kernel(inline="always")
def winch_loop(S, W, P, WA, D, inputs, speed, nsteps, stats, disturbed, implicit=False):
    """Take up to ``nsteps`` :func:`winch_step` s reeling at ``speed`` [m/s] (held; each step's
    speed is cut so the length stays in the winch's range, and is 0 at an end), every term
    computed (the general path), ``S.f`` the forces at the state; stop at the first failure with
    the last good state. ``stats``, ``disturbed`` and ``implicit`` as for :func:`advance_loop`
    (constants in the simulator's kernels below; in the environment's, ``implicit`` compiled in
    and ``disturbed`` an argument: :func:`shared_winch_loop`).

    A step that can fail part-way (composed, or the implicit string's, which cuts itself back)
    is checkpointed before it (:func:`_checkpoint`, the winch's state with it) and rewound on
    failure: every step, not every ``CHECKPOINT`` steps with a replay as in
    :func:`advance_loop`, whose loop structure ran the explicit winch's environment step 4.5 %
    slower (49.05 -> 51.24 us, medians of 5 interleaved runs); a copy of the state is a small
    share of a reeling step."""
    free = P.first == 0
    composed = P.gammas.shape[0] > 1 or implicit
    total = 0
    most = 0
    kick_before(S, W, P, nsteps, disturbed)
    for k in range(nsteps):
        if composed:
            _checkpoint(S, W, WA, True)
        status, iters = winch_step(S, W, P, WA, D, inputs, speed, free, P.compensated, implicit)
        if status != OK and composed:
            _rewind(S, W, WA, True)
        failed, total, most = step_taken(S, W, P, stats, status, iters, k, nsteps, total, most, disturbed)
        if failed:  # (its kick took the pending half back)
            return
    finish(stats, OK, nsteps, total, most)


def shared_advance_loop(implicit: bool, damped: bool = False):
    """:func:`advance_loop` compiled as a function of its own for one string scheme (``implicit``
    and ``damped`` closure constants, their other branches pruned), the other flags arguments with
    every branch kept: one compile per scheme serves every value of them (the environment's step,
    kernels/env/step.py; docs/performance.md, "Start-up")."""

    @kernel
    def advance_loop_shared(S, W, P, inputs, nsteps, stats, free, forced, coupled, compensated, forces_ready,
                            disturbed):
        advance_loop(S, W, P, inputs, nsteps, stats, free, forced, coupled, compensated, forces_ready, implicit,
                     disturbed, damped)

    return advance_loop_shared


#: The environment's loops, one per string scheme and damper (module globals, so that the entry
#: points that call them are cached: numba does not cache a function with a compiled function in
#: its closure).
advance_loop_explicit = shared_advance_loop(False)
advance_loop_implicit = shared_advance_loop(True)
advance_loop_explicit_damped = shared_advance_loop(False, True)
advance_loop_implicit_damped = shared_advance_loop(True, True)


@kernel(inline="always")
def record_loop(S, W, P, inputs, every, D, snap, stats, free, forced, coupled, compensated, implicit=False,
                damped=False):
    """Take ``len(snap.r) * every`` steps, storing a snapshot after every ``every`` steps
    (``D`` is the diagnostics scratch, see kernels/step/diagnostics.py) and, if ``snap.step_diag``
    has rows, energy, pi3 and orthogonality after every step. The steps are taken by
    :func:`advance_loop` (one step at a time when every step is recorded), so failures and
    their recovery are its; ``stats`` as there (steps counts steps taken in this call).
    """
    n = S.r.shape[0] - 1
    per_step = snap.step_diag.shape[0] > 0
    chunk = 1 if per_step else every
    if not implicit:
        nodal_forces(S.r, P.kappa, P.u, P.m, P.M, P.Mp, P.g, P.slack, S.f)
    total = 0
    most = 0
    k = 0
    for j in range(snap.r.shape[0]):
        for _ in range(every // chunk):
            advance_loop(S, W, P, inputs, chunk, stats, free, forced, coupled, compensated, True, implicit, False,
                         damped)
            total += stats[R_NEWTON_TOTAL]
            most = max(most, stats[R_NEWTON_MAX])
            if stats[R_STATUS] != OK:
                finish(stats, stats[R_STATUS], k + stats[R_STEPS], total, most)
                return
            k += chunk
            if per_step:
                diagnostics(S, P, D)
                snap.step_diag[k - 1, SD_ENERGY] = D.out[D_ENERGY]
                snap.step_diag[k - 1, SD_PI3] = D.out[D_PI3]
                snap.step_diag[k - 1, SD_ORTHOGONALITY] = D.out[D_ORTHOGONALITY]
        diagnostics(S, P, D)
        # element loops, not slice assignment: the kernels run without numba's runtime (NRT)
        for a in range(n + 1):
            for i in range(3):
                snap.r[j, a, i] = S.r[a, i]
        for i in range(3):
            for c in range(3):
                snap.R[j, i, c] = S.R[i, c]
            snap.omega[j, i] = D.omega[i]
            snap.v[j, i] = D.V[n, i]
        for i in range(D.out.shape[0]):
            snap.diag[j, i] = D.out[i]
        for i in range(n):
            snap.strain[j, i] = D.strain[i]
        for i in range(S.acc.shape[0]):
            snap.acc[j, i] = S.acc[i]
    finish(stats, OK, k, total, most)


@kernel(entry=True)
def lgvi_advance(S, W, P, inputs, nsteps, stats):
    """The general path: :func:`advance_loop` with every term in, the pivot and the
    compensation read from ``P``."""
    advance_loop(S, W, P, inputs, nsteps, stats, P.first == 0, True, True, P.compensated)


@kernel(entry=True)
def lgvi_record(S, W, P, inputs, every, D, snap, stats):
    """The general path of :func:`record_loop`."""
    record_loop(S, W, P, inputs, every, D, snap, stats, P.first == 0, True, True, P.compensated)


def shared_winch_loop(implicit: bool):
    """:func:`winch_loop` compiled as a function of its own for one string scheme (``implicit`` a
    closure constant), ``disturbed`` an argument with both branches kept (the environment's
    step, kernels/env/step.py)."""

    @kernel
    def winch_loop_shared(S, W, P, WA, D, inputs, speed, nsteps, stats, disturbed):
        winch_loop(S, W, P, WA, D, inputs, speed, nsteps, stats, disturbed, implicit)

    return winch_loop_shared


#: The environment's winch loops, one per string scheme (module globals, as the loops above).
winch_loop_explicit = shared_winch_loop(False)
winch_loop_implicit = shared_winch_loop(True)


@kernel(entry=True)
def winch_advance(S, W, P, WA, D, inputs, speed, nsteps, stats):
    """:func:`winch_loop` without external forces: ``Simulator.step``'s winch (explicit string)."""
    winch_loop(S, W, P, WA, D, inputs, speed, nsteps, stats, False, False)


@kernel(entry=True)
def winch_advance_implicit(S, W, P, WA, D, inputs, speed, nsteps, stats):
    """:func:`winch_advance` for the implicit string."""
    winch_loop(S, W, P, WA, D, inputs, speed, nsteps, stats, False, True)
