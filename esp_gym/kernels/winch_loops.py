"""The winch's loops: steps reeling at a held speed, within the winch's range, with the winch's
work in the balances (docs/physics.md, "The winch"); the explicit string's step is
kernels/winch.py's, the implicit one's kernels/winch_implicit.py's."""
from .disturbance import kick
from .jit import kernel
from .layout import (B_WINCH_WORK, OK, R_NEWTON_MAX, R_NEWTON_TOTAL, R_STATUS, R_STEPS, WN_LENGTH, WN_MAX_LENGTH,
                     WN_MIN_LENGTH, WN_SPEED)
from .sums import kahan_add
from .loops import restore_state, save_state
from .winch import midpoint_dH_dl, winch_energy, winch_substep
from .winch_implicit import winch_implicit_substep


@kernel(inline="always")
def winch_loop(S, W, P, WA, D, inputs, speed, nsteps, stats, disturbed, implicit=False):
    """Take up to ``nsteps`` steps reeling at ``speed`` [m/s] (held; each step's speed is cut so
    the length stays in the winch's range, and is 0 at an end), with constant ``inputs``; stop at
    the first failure with the last good state. ``stats`` as :func:`~.loops.advance_loop`'s. The
    winch's work joins ``S.acc`` (B_WINCH_WORK). Every term is computed (the general path).
    ``disturbed`` (a constant in the simulator's kernels below; an argument in the environment's,
    which calls it through :func:`shared_winch_loop`): the held external forces ``W.ext`` kick as in :func:`~.loops.advance_loop` (h/2 before the
    first step and after the last, h between). ``implicit`` (likewise): the implicit string's
    step (kernels/winch_implicit.py, order 2), which may cut itself back, so each step is
    checkpointed."""
    free = P.first == 0
    first = 0 if free else 1
    compensated = P.compensated
    st = WA.state
    gammas = P.gammas
    composed = gammas.shape[0] > 1 or implicit
    h = P.h
    total = 0
    most = 0
    if disturbed and nsteps > 0:
        kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, 0.5 * h, first)
    for k in range(nsteps):
        length = st[WN_LENGTH]
        v = speed
        end = length + h * v
        if end >= st[WN_MAX_LENGTH]:
            end = st[WN_MAX_LENGTH]
            v = (end - length) / h
        elif end <= st[WN_MIN_LENGTH]:
            end = st[WN_MIN_LENGTH]
            v = (end - length) / h
        if v != st[WN_SPEED]:  # H jumps at fixed (q, p) when the reel speed changes
            H_old, _ = winch_energy(S, P, WA, D, length, st[WN_SPEED])
            H_new, _ = winch_energy(S, P, WA, D, length, v)
            kahan_add(S.acc, S.accc, B_WINCH_WORK, H_new - H_old)
            st[WN_SPEED] = v
        if composed:
            save_state(S, W.backup)
            for i in range(st.shape[0]):
                WA.backup[i] = st[i]
        iters = 0
        status = OK
        reached = 0.0
        for i in range(gammas.shape[0]):
            hi = gammas[i] * h
            la = length + reached * h * v
            reached += gammas[i]
            lb = end if i == gammas.shape[0] - 1 else length + reached * h * v
            if implicit:  # its pieces add their work and move the length
                status, it = winch_implicit_substep(S, W, P, WA, D, inputs, hi, la, lb, free, True, True, compensated)
            else:
                status, it = winch_substep(S, W, P, WA, inputs, hi, la, lb, free, True, True, compensated)
            iters += it
            if status != OK:
                break
            if not implicit:
                if v != 0.0:
                    kahan_add(S.acc, S.accc, B_WINCH_WORK, hi * v * midpoint_dH_dl(S, W, P, WA, hi, la, lb, first))
                st[WN_LENGTH] = lb
        total += iters
        most = max(most, iters)
        if status != OK:
            if composed:
                restore_state(S, W.backup)
                for i in range(st.shape[0]):
                    st[i] = WA.backup[i]
            if disturbed:  # take the pending half kick back
                kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, -0.5 * h, first)
            stats[R_STATUS] = status
            stats[R_STEPS] = k
            stats[R_NEWTON_TOTAL] = total
            stats[R_NEWTON_MAX] = most
            return
        if disturbed:
            kick(S.r, S.p, S.R, S.Pi, S.acc, S.accc, P.rho, W.ext, h if k + 1 < nsteps else 0.5 * h, first)
    stats[R_STATUS] = OK
    stats[R_STEPS] = nsteps
    stats[R_NEWTON_TOTAL] = total
    stats[R_NEWTON_MAX] = most


def shared_winch_loop(implicit: bool):
    """:func:`winch_loop` compiled as a function of its own for one string scheme (``implicit`` a
    closure constant), ``disturbed`` an argument with both branches kept (the environment's
    step, kernels/env_step.py)."""

    @kernel
    def winch_loop_shared(S, W, P, WA, D, inputs, speed, nsteps, stats, disturbed):
        winch_loop(S, W, P, WA, D, inputs, speed, nsteps, stats, disturbed, implicit)

    return winch_loop_shared


#: The environment's winch loops, one per string scheme (module globals, see kernels/loops.py).
winch_loop_explicit = shared_winch_loop(False)
winch_loop_implicit = shared_winch_loop(True)


@kernel
def winch_advance(S, W, P, WA, D, inputs, speed, nsteps, stats):
    """:func:`winch_loop` without external forces: ``Simulator.step``'s winch (explicit string)."""
    winch_loop(S, W, P, WA, D, inputs, speed, nsteps, stats, False, False)


@kernel
def winch_advance_implicit(S, W, P, WA, D, inputs, speed, nsteps, stats):
    """:func:`winch_advance` for the implicit string."""
    winch_loop(S, W, P, WA, D, inputs, speed, nsteps, stats, False, True)
