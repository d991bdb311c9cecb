"""The loops around the LGVI step (kernels/lgvi.py): many steps in one compiled call with
failure recovery (:func:`advance_loop`), and the same with snapshots for a recorded run
(:func:`record_loop`); the checkpoint (save/restore) they need for composed steps; and the
general-path entry points :func:`lgvi_advance`, :func:`lgvi_record` (the specialised ones are
in kernels/specialise.py).

``stats`` is the first ``LOOP_REPORT_SIZE`` entries of a :data:`~.layout.REPORT` (int64).
"""
from .jit import kernel
from .diagnostics import diagnostics
from .layout import (D_ENERGY, D_ORTHOGONALITY, D_PI3, OK, R_NEWTON_MAX, R_NEWTON_TOTAL, R_STATUS, R_STEPS, SD_ENERGY,
                     SD_ORTHOGONALITY, SD_PI3)
from .disturbance import kick
from .implicit import implicit_substep
from .lgvi import lgvi_substep
from .string import nodal_forces


@kernel(inline="always")
def lgvi_step(S, W, P, inputs, free, forced, coupled, compensated, implicit=False):
    """One step of length ``P.h``: the LGVI itself (one weight ``P.gammas == [1]``) or the
    symmetric composition of LGVI substeps of lengths ``gamma_i h`` (esp_gym/compositions.py);
    with ``implicit`` (a compile-time constant) the implicit string's step
    (kernels/implicit.py; order 2 only). Flags as in :func:`lgvi_substep`. A failing LGVI step
    leaves the state untouched; a composed step that fails in a later substep leaves it after
    the last good substep, and the loops below bring it back (:func:`advance_loop`). Returns
    ``(status, newton_iterations)``."""
    if implicit:
        return implicit_substep(S, W, P, inputs, P.h, free, forced, coupled, compensated)
    gammas = P.gammas
    total = 0
    for i in range(gammas.shape[0]):  # one substep site: the substep is inlined once
        # gamma = 1.0 for the plain LGVI, and 1.0 * h == h exactly
        status, iters = lgvi_substep(S, W, P, inputs, gammas[i] * P.h, free, forced, coupled, compensated)
        total += iters
        if status != OK:
            return status, total
    return OK, total


@kernel
def state_size(S):
    """Number of floats :func:`save_state` writes."""
    return 5 * S.r.size + 2 * S.R.size + 2 * S.Pi.size + 2 * S.acc.size + S.owed.size


@kernel(inline="always")
def _move_rows(a, buf, k, to_buf):
    """Copy the (rows, 3) array ``a`` to ``buf[k:]`` (or back, if not ``to_buf``); returns the
    next offset. Per-array calls with the 3 columns spelled out: a loop over a tuple of arrays
    compiled to ~5x slower code, which cost 13 % of a composed step."""
    for i in range(a.shape[0]):
        if to_buf:
            buf[k] = a[i, 0]
            buf[k + 1] = a[i, 1]
            buf[k + 2] = a[i, 2]
        else:
            a[i, 0] = buf[k]
            a[i, 1] = buf[k + 1]
            a[i, 2] = buf[k + 2]
        k += 3
    return k


@kernel(inline="always")
def _move_vector(a, buf, k, to_buf):
    for i in range(a.shape[0]):
        if to_buf:
            buf[k + i] = a[i]
        else:
            a[i] = buf[k + i]
    return k + a.shape[0]


@kernel(inline="always")
def _move_state(S, buf, to_buf):
    k = _move_rows(S.r, buf, 0, to_buf)
    k = _move_rows(S.p, buf, k, to_buf)
    k = _move_rows(S.rc, buf, k, to_buf)
    k = _move_rows(S.pc, buf, k, to_buf)
    k = _move_rows(S.R, buf, k, to_buf)
    k = _move_rows(S.Rc, buf, k, to_buf)
    k = _move_vector(S.Pi, buf, k, to_buf)
    k = _move_vector(S.Pic, buf, k, to_buf)
    k = _move_vector(S.acc, buf, k, to_buf)
    k = _move_vector(S.accc, buf, k, to_buf)
    k = _move_vector(S.owed, buf, k, to_buf)
    _move_rows(S.f, buf, k, to_buf)


@kernel
def save_state(S, buf):
    """Copy the whole state (with remainders, balances and the forces ``S.f``) into ``buf``."""
    _move_state(S, buf, True)


@kernel
def restore_state(S, buf):
    """Inverse of :func:`save_state`."""
    _move_state(S, buf, False)


#: Composed steps are checkpointed every this many steps (see advance_loop).
CHECKPOINT = 64


@kernel
def _finish(stats, status, steps, total, most):
    stats[R_STATUS] = status
    stats[R_STEPS] = steps
    stats[R_NEWTON_TOTAL] = total
    stats[R_NEWTON_MAX] = most


@kernel(inline="always")
def _rewind(S, W):
    """Back to the last checkpoint, with its forces ``S.f`` (for the implicit string they are
    the last step's, its first guess, so a replay needs the saved ones)."""
    restore_state(S, W.backup)


@kernel(inline="always")
def advance_loop(S, W, P, inputs, nsteps, stats, free, forced, coupled, compensated, forces_ready=False,
                 implicit=False, disturbed=False):
    """Take up to ``nsteps`` steps with constant ``inputs``; stop at the first failure with
    the last good state. ``stats`` (int64, >= 4): status, steps taken, total Newton iterations,
    max per step. The flags are constants in the simulator's specialised kernels, which inline
    this loop and prune its dead branches; the environment's step calls it through
    :func:`shared_advance_loop`, ``implicit`` compiled in and the other flags arguments.

    A composed step (or a cut-back implicit one) that fails part-way has moved the state. Instead of copying the state
    before every step (that cost 13 % of a composed step), the state is saved every
    ``CHECKPOINT`` steps; after a failure the loop rewinds to the checkpoint and replays the
    steps that had succeeded. The replay is deterministic (same state bits, inputs and code),
    so it ends on exactly the state after the last good step. One call site of the step keeps
    the inlined code single. ``forces_ready``: ``S.f`` already holds the forces at ``S.r`` (as
    it does after any successful step), so they are not recomputed. ``implicit``: the implicit
    string's step; its ``S.f`` is part of the state
    (the last step's midpoint forces, its first guess: kernels/implicit.py) and is never
    recomputed here. ``disturbed``: the held external forces ``W.ext``
    act too, as kicks of h/2 on both sides of every step (kernels/disturbance.py), the kicks
    between two steps merged into one; after a failure the pending half kick is taken back.
    """
    first = 0 if free else 1
    hh = 0.5 * P.h
    if disturbed and nsteps > 0:
        kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, hh, first)
    if not forces_ready and not implicit:
        nodal_forces(S.r, P.kappa, P.u, P.m, P.M, P.Mp, P.g, P.slack, S.f)
    # a composed step, and an implicit one that cut itself back (kernels/implicit.py), can
    # fail part-way
    composed = P.gammas.shape[0] > 1 or implicit
    total = 0
    most = 0
    failed = OK
    target = nsteps
    k = 0
    k0 = 0
    while k < target:
        if composed and failed == OK and k % CHECKPOINT == 0:
            save_state(S, W.backup)
            k0 = k
        status, iters = lgvi_step(S, W, P, inputs, free, forced, coupled, compensated, implicit)
        if failed == OK:
            total += iters
            most = max(most, iters)
        if status != OK:
            if failed != OK or not composed:  # (a replayed step cannot fail: it did not before)
                if disturbed:
                    kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, -hh, first)
                _finish(stats, status, k, total, most)
                return
            failed = status
            target = k
            _rewind(S, W)
            k = k0
            continue
        k += 1
        if disturbed:
            kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, P.h if k < target else hh, first)
    if disturbed and failed != OK and target == k0:  # rewound to a checkpoint, no step to replay
        kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, -hh, first)
    _finish(stats, failed, target, total, most)



def shared_advance_loop(implicit: bool):
    """:func:`advance_loop` compiled as a function of its own for one string scheme (``implicit``
    a closure constant, its other branch pruned), the other flags arguments with every branch
    kept: one compile per scheme serves every value of them (the environment's step,
    kernels/env_step.py; docs/performance.md, "Start-up")."""

    @kernel
    def advance_loop_shared(S, W, P, inputs, nsteps, stats, free, forced, coupled, compensated, forces_ready,
                            disturbed):
        advance_loop(S, W, P, inputs, nsteps, stats, free, forced, coupled, compensated, forces_ready, implicit,
                     disturbed)

    return advance_loop_shared


#: The environment's loops, one per string scheme (module globals, so that the entry points that
#: call them are cached: numba does not cache a function with a compiled function in its closure).
advance_loop_explicit = shared_advance_loop(False)
advance_loop_implicit = shared_advance_loop(True)


@kernel(inline="always")
def record_loop(S, W, P, inputs, every, D, snap, stats, free, forced, coupled, compensated, implicit=False):
    """Take ``len(snap.r) * every`` steps, storing a snapshot after every ``every`` steps
    (``D`` is the diagnostics scratch, see kernels/diagnostics.py) and, if ``snap.step_diag``
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
            advance_loop(S, W, P, inputs, chunk, stats, free, forced, coupled, compensated, True, implicit)
            total += stats[R_NEWTON_TOTAL]
            most = max(most, stats[R_NEWTON_MAX])
            if stats[R_STATUS] != OK:
                _finish(stats, stats[R_STATUS], k + stats[R_STEPS], total, most)
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
    _finish(stats, OK, k, total, most)


@kernel
def lgvi_advance(S, W, P, inputs, nsteps, stats):
    """The general path: :func:`advance_loop` with every term in, the pivot and the
    compensation read from ``P``."""
    advance_loop(S, W, P, inputs, nsteps, stats, P.first == 0, True, True, P.compensated)


@kernel
def lgvi_record(S, W, P, inputs, every, D, snap, stats):
    """The general path of :func:`record_loop`."""
    record_loop(S, W, P, inputs, every, D, snap, stats, P.first == 0, True, True, P.compensated)

