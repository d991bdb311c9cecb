"""The energy watchdog (docs/physics.md, "The energy watchdog"): the balance |E - E0 - W| of a
run (W the inputs', the wind's and the winch's work) against f (scale + |W|), f the scene's
``solver.energy_watchdog`` and the scale :func:`energy_scale`. The environment checks it in its
compiled step (kernels/env/step.py, ``energy_watchdog``, from the constants :func:`task_constants`
gives); the simulator, and a team's (esp_gym/team/simulator.py), after its compiled calls
(:func:`check_balance`)."""
from __future__ import annotations

import math
from typing import Optional

from ..errors import SimulationError
from ..kernels.status import ENERGY_BALANCE
from ..scene.params import Scene
from ..scene.stepsize import at_length

#: g0 [m/s^2]: the energy scale's gravity (standard, so that a scene without gravity has one).
STANDARD_GRAVITY = 9.80665
#: The simulator checks the balance at the end of the compiled call in which this many steps have
#: passed since it last did: one diagnostics call (~7 us) per 64 steps or more.
WATCH_EVERY = 64


def energy_scale(scene: Scene) -> float:
    """The watchdog's energy unit [J]: the mass the string carries (the load, the string and a
    free pivot) lifted by one string length under standard gravity, (M + mu l + M_p) g0 l."""
    return lifted(scene.body.mass, [(scene.string, scene.pivot)])


def team_energy_scale(team) -> float:
    """:func:`energy_scale` of a team (esp_gym/team/scene.py ``TeamScene``): the load, every
    string and every free pivot lifted by the longest string [J]."""
    return lifted(team.scene.body.mass, [(team.scene.string, team.scene.pivot)]
                  + [(s.string, s.pivot) for s in team.strings])


def lifted(body_mass: float, members) -> float:
    """(M + sum (mu l + M_p)) g0 max l [J]: a load of ``body_mass`` [kg] and ``members``, each
    ``(string section, pivot section)`` (a fixed pivot carries nothing of its own)."""
    carried = body_mass
    for s, pivot in members:
        carried += s.mass_per_length * s.length
        carried += pivot.mass if pivot.is_free else 0.0
    return carried * STANDARD_GRAVITY * max(s.length for s, _ in members)


def task_constants(scene: Scene) -> tuple:
    """``(f, f x scale)`` [-, J] for the environment's task parameters (TASK_PARAMS
    energy_watchdog, energy_bound): ``(0, inf)`` without a watchdog."""
    fraction = scene.solver.energy_watchdog
    return (0.0, math.inf) if fraction is None else (fraction, fraction * energy_scale(scene))


def check_balance(scene: Scene, residual: float, work: float, step: int, time: float,
                  stability_bound, scale: Optional[float] = None) -> None:
    """SimulationError (ENERGY_BALANCE), naming the bound, its parts and what to change (h against
    ``stability_bound`` [s], the one at the string's current length, or a function giving it),
    unless |``residual``| <= f (scale + |``work``|) [J] (``scene`` with a watchdog; ``scale``
    :func:`energy_scale` unless given: a team's, :func:`team_energy_scale`)."""
    fraction = scene.solver.energy_watchdog
    scale = energy_scale(scene) if scale is None else scale
    if abs(residual) <= fraction * (scale + abs(work)):
        return
    ratio = scene.h / (stability_bound() if callable(stability_bound) else stability_bound)
    where = f"h = {scene.h:g} s is {ratio:.2g} x the stability bound" if ratio > 0 else f"h = {scene.h:g} s"
    raise SimulationError(ENERGY_BALANCE, step, time, 0, (
        f"|E - E0 - W| = {abs(residual):.4g} J > solver.energy_watchdog {fraction:g} x (the energy scale "
        f"{scale:.4g} J, the carried mass lifted one string length, + |W| = {abs(work):.4g} J, the inputs' and the "
        f"winch's work). {where}: take a smaller h, or fewer elements with the tension-only law "
        f"(docs/physics.md, \"The energy watchdog\"); solver.energy_watchdog: null runs on without it."))


def check_team_balance(team, balance, step: int, time: float, lengths, scale: float) -> None:
    """:func:`check_balance` of a team (esp_gym/team/simulator.py): its lead scene's f, its energy
    ``scale`` (:func:`team_energy_scale`), ``balance()``'s ``(residual, work)`` [J], h against the
    smallest of its strings' stability bounds at their ``lengths`` (K,) [m]."""
    if team.scene.solver.energy_watchdog is None:
        return
    residual, work = balance()

    def bound():
        return min(at_length(team.member_scene(k), length).stability_bound for k, length in enumerate(lengths))
    check_balance(team.scene, residual, work, step, time, bound, scale)
