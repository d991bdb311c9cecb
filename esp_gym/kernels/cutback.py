"""Cutting a step back (docs/physics.md, "Cutting the step back"): where the implicit string's
Newton does not converge, or (variational form) its tension breaks the transverse limit, the
rest of the step is taken in steps of half the length, down to h / 2**CUTBACKS. One driver,
:func:`cut_back`, serves the step at a fixed length (kernels/implicit.py) and the step while
the winch reels (kernels/winch_implicit.py), each piece then reeling its share at the same
speed and adding its share of the winch's work.
"""
from .implicit import CUTBACKS, TOO_TENSE, implicit_step_once
from .jit import kernel
from .layout import B_WINCH_WORK, WN_LENGTH
from .status import NEWTON_FAILED, OK
from .sums import kahan_add
from .winch import length_shift
from .winch_implicit import winch_implicit_once


@kernel(inline="always")
def cut_back(S, W, P, WA, D, inputs, h, l0, l1, free, forced, coupled, compensated, winched):
    """A step of the implicit string of length ``h`` [s], cut back where it fails: the rest in
    halves, to h / 2**CUTBACKS (time counted in units of that, so the pieces add up exactly). A
    failure past that leaves the state after the last good piece (the loops rewind it:
    kernels/loops.py). ``winched`` (a constant: the wrappers below): the winch takes the
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
