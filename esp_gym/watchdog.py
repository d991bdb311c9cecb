"""The energy watchdog (docs/physics.md, "The energy watchdog"): the balance |E - E0 - W| of a
run (W the inputs', the wind's and the winch's work) against f (scale + |W|), f the scene's
``solver.energy_watchdog`` and the scale :func:`energy_scale`. The environment checks it in its
compiled step (kernels/env_step.py, ``energy_watchdog``, from the constants :func:`task_constants`
gives); the simulator after its compiled calls (:func:`check_balance`)."""
from __future__ import annotations

import math

from .errors import SimulationError
from .kernels.status import ENERGY_BALANCE
from .params import Scene

#: g0 [m/s^2]: the energy scale's gravity (standard, so that a scene without gravity has one).
STANDARD_GRAVITY = 9.80665
#: The simulator checks the balance at the end of the compiled call in which this many steps have
#: passed since it last did: one diagnostics call (~7 us) per 64 steps or more.
WATCH_EVERY = 64


def energy_scale(scene: Scene) -> float:
    """The watchdog's energy unit [J]: the mass the string carries (the load, the string and a
    free pivot) lifted by one string length under standard gravity, (M + mu l + M_p) g0 l."""
    s = scene.string
    carried = scene.body.mass + s.mass_per_length * s.length + (scene.pivot.mass if scene.pivot.is_free else 0.0)
    return carried * STANDARD_GRAVITY * s.length


def task_constants(scene: Scene) -> tuple:
    """``(f, f x scale)`` [-, J] for the environment's task parameters (TASK_PARAMS
    energy_watchdog, energy_bound): ``(0, inf)`` without a watchdog."""
    fraction = scene.solver.energy_watchdog
    return (0.0, math.inf) if fraction is None else (fraction, fraction * energy_scale(scene))


def check_balance(scene: Scene, residual: float, work: float, step: int, time: float,
                  stability_bound: float) -> None:
    """SimulationError (ENERGY_BALANCE), naming the bound, its parts and what to change (h against
    ``stability_bound`` [s], the one at the string's current length), unless |``residual``| <=
    f (scale + |``work``|) [J] (``scene`` with a watchdog)."""
    fraction = scene.solver.energy_watchdog
    scale = energy_scale(scene)
    if abs(residual) <= fraction * (scale + abs(work)):
        return
    ratio = scene.h / stability_bound
    where = f"h = {scene.h:g} s is {ratio:.2g} x the stability bound" if ratio > 0 else f"h = {scene.h:g} s"
    raise SimulationError(ENERGY_BALANCE, step, time, 0, (
        f"|E - E0 - W| = {abs(residual):.4g} J > solver.energy_watchdog {fraction:g} x (the energy scale "
        f"{scale:.4g} J, the carried mass lifted one string length, + |W| = {abs(work):.4g} J, the inputs' and the "
        f"winch's work). {where}: take a smaller h, or fewer elements with the tension-only law "
        f"(docs/physics.md, \"The energy watchdog\"); solver.energy_watchdog: null runs on without it."))
