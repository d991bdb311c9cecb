"""Specialised entry points: the loops of kernels/step/loops.py compiled for one kind of scene, with
what it does not need compiled out."""
from ..jit import announce_compile, kernel
from .loops import advance_loop, lgvi_advance, lgvi_record, record_loop


def _compile_specialised(coupled: bool, compensated: bool, implicit: bool, damped: bool):
    """``(advance, record)`` compiled with the flags as constants (closure variables are
    compile-time constants in numba, and its cache keys closures by their values). The pivot
    (``P.first``) is read at run time and the inputs are always added (all zero, they add exact
    zeros): a free pivot or inputs saved at most 7 % of a step as constants, and each was another
    compile of the whole loop (docs/performance.md, "Specialised kernels")."""

    @kernel(entry=True)
    def advance(S, W, P, inputs, nsteps, stats):
        advance_loop(S, W, P, inputs, nsteps, stats, P.first == 0, True, coupled, compensated, False, implicit,
                     False, damped)

    @kernel(entry=True)
    def record(S, W, P, inputs, every, D, snap, stats):
        record_loop(S, W, P, inputs, every, D, snap, stats, P.first == 0, True, coupled, compensated, implicit,
                    damped)

    return announced(advance, record)


#: The seconds to the simulator's first step on an empty cache (2 cores; docs/performance.md,
#: "Start-up"), said when its loops first compile.
COLD_SIMULATOR_STEP_S = 22


def announced(advance, record):
    """``(advance, record)``, registered to say so when they first compile."""
    return (announce_compile(advance, "the simulator's step", COLD_SIMULATOR_STEP_S),
            announce_compile(record, "the simulator's recording step", COLD_SIMULATOR_STEP_S))


def _compile_general(implicit: bool, damped: bool):
    """The general path of the implicit string or of a damped one: every term in, the pivot and the
    compensation read from ``P`` (as :func:`~.loops.lgvi_advance` for the explicit one)."""

    @kernel(entry=True)
    def advance(S, W, P, inputs, nsteps, stats):
        advance_loop(S, W, P, inputs, nsteps, stats, P.first == 0, True, True, P.compensated, False, implicit, False,
                     damped)

    @kernel(entry=True)
    def record(S, W, P, inputs, every, D, snap, stats):
        record_loop(S, W, P, inputs, every, D, snap, stats, P.first == 0, True, True, P.compensated, implicit, damped)

    return announced(advance, record)


def general_kernels(implicit: bool = False, damped: bool = False):
    """``(advance, record)`` of the general path (every term computed) for the explicit string
    (:func:`~.loops.lgvi_advance`, :func:`~.loops.lgvi_record`), the implicit one, or either damped."""
    if not implicit and not damped:
        return _GENERAL_EXPLICIT
    key = ("general", bool(implicit), bool(damped))
    if key not in _SPECIALISED:
        _SPECIALISED[key] = _compile_general(*key[1:])
    return _SPECIALISED[key]


_SPECIALISED = {}
_GENERAL_EXPLICIT = announced(lgvi_advance, lgvi_record)


def specialised_kernels(coupled: bool, compensated: bool = True, implicit: bool = False, damped: bool = False):
    """``(advance, record)`` with the signatures of :func:`lgvi_advance`/:func:`lgvi_record`,
    compiled for one kind of scene: body ``coupled`` to the string (rho_c != 0) or not, state
    updates ``compensated`` or plain (as ``P.compensated`` must say), the string ``implicit`` or
    explicit (the scheme, not a term), ``damped`` or not (``P.damping`` > 0: kernels/step/damper.py). What a flag turns off is not computed at all; the results
    are those of the general path (tests/test_specialised.py). Compiled on first use (and cached
    on disk); created once per process."""
    key = (bool(coupled), bool(compensated), bool(implicit), bool(damped))
    if key not in _SPECIALISED:
        _SPECIALISED[key] = _compile_specialised(*key)
    return _SPECIALISED[key]
