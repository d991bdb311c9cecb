"""A team's per-episode draws (``randomize=`` of ElasticStringTeam-v0; docs/team.md, "The hard
preset"), read and drawn by the single env's code (esp_gym/pendulum/randomize.py: the same names, the same
reading of ``randomize`` and of each range, the same draw):

===================  =====  ===========  ==================================================
name                 unit   draw         default range (of the default team's value)
===================  =====  ===========  ==================================================
``EA``               N      log-uniform  x [0.5, 2], each string's
``mass_per_length``  kg/m   log-uniform  x [0.5, 2], each string's
``string_length``    m      uniform      x [0.9, 1.1], each string's
``pivot_mass``       kg     uniform      x [0.8, 1.25], each pivot's (a drone's: of its 1.5 kg)
``load_mass``        kg     uniform      x [0.7, 1.5]
===================  =====  ===========  ==================================================

An episode draws, in this order, each string's EA, mass per length and length, each pivot's mass
and the load's mass, one uniform number each (``draw_in_ranges``). A user's range
(``randomize={"EA": (500.0, 800.0)}``) is absolute, replaces the default of its name and holds for
every string (or pivot), each drawn on its own by the law above; a pair (v, v) fixes v. A default
range is drawn as a factor of the default team's value, then scaled (the product the hard preset's
documented episodes were drawn with). The load's box and attachment points, and a drone's
inertia, rotors and motors, stay the default team's: the single env's names for them are refused
with the reason. When the environment is made, the teams at the ranges' corners are built (each a
valid :class:`~esp_gym.team.scene.TeamScene`), the stiffest sets the most physics steps a control
step may need and the heaviest what each drone must lift (esp_gym/team/core.py).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import ValidationError

from ..pendulum.randomize import BOX_ONLY, DRONE_RANGES, draw_in_ranges, user_ranges
from ..scene.scene_input import validation_message
from .scene import NOMINAL, TeamScene, quadrotor, team_scene

#: name -> (low, high, law) of the default draws, as factors of the default team's values.
RANDOM_FACTORS = {"EA": (0.5, 2.0, "log"), "mass_per_length": (0.5, 2.0, "log"), "string_length": (0.9, 1.1, "uniform"),
                  "pivot_mass": (0.8, 1.25, "uniform"), "load_mass": (0.7, 1.5, "uniform")}
#: Each string's draws, in their order, and their keys in :func:`~esp_gym.team.scene.team_scene`'s strings.
STRING_DRAWS = {"EA": "EA", "mass_per_length": "mass_per_length", "string_length": "length"}
#: The single env's names a team does not draw, and why (the message after the name).
NOT_DRAWN = {**{name: "is not drawn for a team: its load keeps the default team's box and attachment points"
                for name in sorted(BOX_ONLY)},
             **{name: "is not drawn for a team: its drones keep quadrotor_load's inertia, rotors and motors"
                for name in DRONE_RANGES}}


class TeamRandomizer:
    """The ranges of a team's episodes (``size`` strings; ``drones``: its pivots are quadrotors)
    and the draw of each episode's team. ``spec``: True (the defaults) or a mapping name ->
    (low, high) overriding them; ValueError naming the bad entry (esp_gym/pendulum/randomize.py
    ``user_ranges``), or the corner of the ranges that is not a valid team."""

    def __init__(self, size: int, drones: bool, spec: Any):
        self.size, self.drones = int(size), bool(drones)
        nominal = {"EA": NOMINAL["EA"], "mass_per_length": NOMINAL["mass_per_length"],
                   "string_length": NOMINAL["length"], "load_mass": NOMINAL["body_mass"],
                   "pivot_mass": quadrotor()[0] if drones else NOMINAL["pivot_mass"]}
        refused = {name: why for name, why in NOT_DRAWN.items() if drones or name not in DRONE_RANGES}
        given = user_ranges(spec, tuple(RANDOM_FACTORS), refused)
        # each name's draw: scale x a value of [low, high], a default's the nominal value x a factor,
        # a user's range 1 x itself
        draws = {name: (1.0, *given[name]) if name in given else (nominal[name], low, high)
                 for name, (low, high, _) in RANDOM_FACTORS.items()}
        #: name -> (low, high) [SI]
        self.ranges = {name: (scale * low, scale * high) for name, (scale, low, high) in draws.items()}
        order = [name for _ in range(self.size) for name in STRING_DRAWS] + ["pivot_mass"] * self.size + ["load_mass"]
        self._scale, self._low, self._high = (np.array([draws[name][i] for name in order]) for i in range(3))
        self._log = np.array([RANDOM_FACTORS[name][2] == "log" for name in order])
        low = {name: lo for name, (lo, _) in self.ranges.items()}
        high = {name: hi for name, (_, hi) in self.ranges.items()}
        self._corner(low, "lows")
        #: the team of the ranges' heaviest pivots, strings and load (each drone's heaviest share)
        self.heaviest = self._corner(high, "highs")
        #: the team whose strings need the smallest step: the shortest, lightest and stiffest, with the
        #: lightest ends (esp_gym/pendulum/randomize.py, ``Randomizer.stiffest``)
        self.stiffest = self._corner({**low, "EA": high["EA"]}, "stiffest corner")

    def _corner(self, values: dict, what: str) -> TeamScene:
        try:
            return self.team(values, values["pivot_mass"], values["load_mass"])
        except ValidationError as error:
            raise ValueError(validation_message(error, f"at the {what} of the randomize ranges")) from None

    def team(self, strings, pivot_masses, load_mass: float) -> TeamScene:
        """The default team with these strings (a mapping of :data:`STRING_DRAWS`' names each, or
        one for all), pivot masses (each pivot's, or one for all) [kg] and load mass [kg]; its h is
        the environment's to choose."""
        strings = [strings] * self.size if isinstance(strings, dict) else strings
        pivot_masses = np.broadcast_to(pivot_masses, (self.size,)).tolist()
        return team_scene(self.size, [{key: float(s[name]) for name, key in STRING_DRAWS.items()} for s in strings],
                          pivot_masses, float(load_mass), self.drones, allow_unstable_h=True)

    def draw(self, rng: np.random.Generator) -> tuple:
        """One episode's team and its draws by name (``{"strings": [{EA, mass_per_length,
        length}, ...], "pivot_masses": [...], "body_mass": ...}``, SI)."""
        values = (self._scale * draw_in_ranges(rng, self._low, self._high, self._log)).tolist()
        n = len(STRING_DRAWS)
        strings = [dict(zip(STRING_DRAWS, values[n * k:n * (k + 1)])) for k in range(self.size)]
        pivot_masses, load_mass = values[n * self.size:-1], values[-1]
        team = self.team(strings, pivot_masses, load_mass)
        return team, {"strings": [{STRING_DRAWS[name]: v for name, v in s.items()} for s in strings],
                      "pivot_masses": pivot_masses, "body_mass": load_mass}
