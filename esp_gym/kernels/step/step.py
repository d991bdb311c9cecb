"""One step of length h for each string scheme, the unit the loops of kernels/step/loops.py repeat:
:func:`lgvi_step` at a fixed length (the LGVI of kernels/step/lgvi.py, or the symmetric composition of
its substeps, or the implicit string's step) and :func:`winch_step` while the winch reels
(kernels/step/winch.py, kernels/step/winch_implicit.py).

The implicit string's step is cut back where it fails (docs/physics.md, "Cutting the step back"):
where its Newton does not converge, or (variational form) its tension breaks the transverse
limit, the rest of the step is taken in steps of half the length, down to h / 2**CUTBACKS. One
driver, :func:`cut_back`, serves the step at a fixed length (kernels/step/implicit.py) and the step
while the winch reels (kernels/step/winch_implicit.py), each piece then reeling its share at the same
speed and adding its share of the winch's work.
"""
from ..jit import kernel
from ..layout import B_WINCH_WORK, WN_LENGTH, WN_MAX_LENGTH, WN_MIN_LENGTH, WN_REEL_SPEED
from ..status import NEWTON_FAILED, OK
from ..sums import kahan_add
from .damper import damper_half_step
from .implicit import CUTBACKS, TOO_TENSE, implicit_step_once
from .lgvi import lgvi_substep
from .winch import length_shift, midpoint_dH_dl, winch_energy, winch_substep
from .winch_implicit import winch_implicit_once


@kernel(inline="always")
def cut_back(S, W, P, WA, D, inputs, h, l0, l1, free, forced, coupled, compensated, winched):
    """A step of the implicit string of length ``h`` [s], cut back where it fails: the rest in
    halves, to h / 2**CUTBACKS (time counted in units of that, so the pieces add up exactly). A
    failure past that leaves the state after the last good piece (the loops rewind it:
    kernels/step/loops.py). ``winched`` (a constant: the wrappers below): the winch takes the
    unstretched length ``l0 -> l1`` [m] over the step, and a piece from state z_k to z_k+1,
    la -> lb, adds the winch's work: the elastic energy's share exactly
    (:func:`~.winch_implicit.elastic_winch_work`) plus the mean of H's change with the length
    alone at z_k and at z_k+1 (:func:`~.winch.length_shift`, a discrete gradient in l: with the
    energy-momentum string it closes the balance at every reel speed, where the midpoint rule
    of dH/dl erred by O(h^3) per step with the sign of the reel, and so drifted under a reel that
    keeps reversing); the winch's length follows. ``WA``, ``D`` (the winch's arrays, the
    diagnostics' scratch) are None without it. Returns ``(status, newton_iterations)``."""
    v = (l1 - l0) / h
    full = 1 << CUTBACKS
    left = full
    size = full
    done = 0
    cuts = 0
    total = 0
    while left > 0:
        piece = h * (size / full)
        if winched:
            la = l0 + (l1 - l0) * (done / full)
            lb = l1 if done + size == full else l0 + (l1 - l0) * ((done + size) / full)
            before = length_shift(S, P, WA, D, la, lb, v) if lb != la else 0.0
            status, iters, elastic = winch_implicit_once(S, W, P, WA, inputs, piece, la, lb, free, forced, coupled,
                                                         compensated, cuts < CUTBACKS)
        else:
            status, iters = implicit_step_once(S, W, P, inputs, piece, free, forced, coupled, compensated,
                                               cuts < CUTBACKS)
        total += iters
        if (status == NEWTON_FAILED or status == TOO_TENSE) and cuts < CUTBACKS:
            cuts += 1
            size >>= 1
            continue
        if status != OK:
            return status, total
        if winched:
            if lb != la:
                after = length_shift(S, P, WA, D, la, lb, v)
                kahan_add(S.acc, S.accc, B_WINCH_WORK, elastic + 0.5 * (before + after))
            WA.state[WN_LENGTH] = lb
        left -= size
        done += size
    return OK, total


@kernel(forceinline=True)
def implicit_substep(S, W, P, inputs, h, free, forced, coupled, compensated):
    """One step of the implicit string at a fixed length, in place, cut back where it fails
    (:func:`cut_back`); the contract of :func:`~.lgvi.lgvi_substep` (flags, inputs,
    compensation, ``S.f`` the forces at the state). Returns ``(status, newton_iterations)``."""
    return cut_back(S, W, P, None, None, inputs, h, 0.0, 0.0, free, forced, coupled, compensated, False)


@kernel(forceinline=True)
def winch_implicit_substep(S, W, P, WA, D, inputs, h, l0, l1, free, forced, coupled, compensated):
    """A step of the implicit string reeling ``l0 -> l1`` [m] over ``h`` [s], cut back where it
    fails (:func:`cut_back`), its winch work in the balances and the winch's length moved.
    Returns ``(status, newton_iterations)``."""
    return cut_back(S, W, P, WA, D, inputs, h, l0, l1, free, forced, coupled, compensated, True)


@kernel(inline="always")
def lgvi_step(S, W, P, inputs, free, forced, coupled, compensated, implicit=False, damped=False, lead=True,
              merge=False):
    """One step of length ``P.h``: the LGVI itself (one weight ``P.gammas == [1]``) or the
    symmetric composition of LGVI substeps of lengths ``gamma_i h`` (esp_gym/scene/compositions.py);
    with ``implicit`` (a compile-time constant) the implicit string's step
    (kernels/step/implicit.py; order 2 only). With ``damped`` (a compile-time constant: the damped
    rigs' and simulators' kernels; ``P.damping`` > 0) the damper's flow over half of each (sub)step
    on both sides of it (kernels/step/damper.py: a symmetric splitting, of order 2); without it the
    damper is not compiled in. Between two steps of a run the two halves at the same configuration
    are taken as one flow over gamma h (the weights are palindromic): ``lead`` False, the previous
    step's last half took this step's first; ``merge``, the last half takes the next step's first
    too (:func:`~esp_gym.kernels.step.loops.advance_loop`). Flags as in :func:`lgvi_substep`.
    A failing LGVI step leaves the state untouched; a composed or damped step that fails in a later
    stage leaves it after the last good one, and the loops below bring it back
    (:func:`advance_loop`). Returns ``(status, newton_iterations)``."""
    gammas = P.gammas
    last = gammas.shape[0] - 1
    total = 0
    for i in range(gammas.shape[0]):  # one substep site: the substep is inlined once
        # gamma = 1.0 for the plain LGVI, and 1.0 * h == h exactly
        h = gammas[i] * P.h
        if damped and (lead or i > 0):
            damper_half_step(S, W, P, 0.5 * h, free, compensated)
        if implicit:
            status, iters = implicit_substep(S, W, P, inputs, h, free, forced, coupled, compensated)
        else:
            status, iters = lgvi_substep(S, W, P, inputs, h, free, forced, coupled, compensated)
        total += iters
        if status != OK:
            return status, total
        if damped:
            damper_half_step(S, W, P, h if merge and i == last else 0.5 * h, free, compensated)
    return OK, total


@kernel(inline="always")
def winch_step(S, W, P, WA, D, inputs, speed, free, compensated, implicit):
    """One step of length ``P.h`` while the winch reels at ``speed`` [m/s], cut to end on the
    winch's range (and then 0); H's jump at fixed (q, p) where the reel speed changes, and each
    (sub)step's winch work, join ``S.acc`` (B_WINCH_WORK); the length follows. The explicit
    string's steps (gamma_i h each, composed) count the midpoint rule of dH/dl; the implicit
    string's pieces count their own (kernels/step/winch_implicit.py). Returns ``(status,
    newton_iterations)``; a failing substep leaves the state as the fixed-length step's does."""
    first = 0 if free else 1
    st = WA.state
    gammas = P.gammas
    h = P.h
    length = st[WN_LENGTH]
    v = speed
    end = length + h * v
    if end >= st[WN_MAX_LENGTH]:
        end = st[WN_MAX_LENGTH]
        v = (end - length) / h
    elif end <= st[WN_MIN_LENGTH]:
        end = st[WN_MIN_LENGTH]
        v = (end - length) / h
    if v != st[WN_REEL_SPEED]:  # H jumps at fixed (q, p) when the reel speed changes
        H_old, _ = winch_energy(S, P, WA, D, length, st[WN_REEL_SPEED])
        H_new, _ = winch_energy(S, P, WA, D, length, v)
        kahan_add(S.acc, S.accc, B_WINCH_WORK, H_new - H_old)
        st[WN_REEL_SPEED] = v
    total = 0
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
        total += it
        if status != OK:
            break
        if not implicit:
            if v != 0.0:
                dH_dl = midpoint_dH_dl(S.r, W.Y, st, WA.coef, P.slack, P.g, hi, la, lb, first)
                kahan_add(S.acc, S.accc, B_WINCH_WORK, hi * v * dH_dl)
            st[WN_LENGTH] = lb
    return status, total
