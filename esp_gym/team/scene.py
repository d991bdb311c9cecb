"""A team's scene: one body held by K = 1..6 strings, each from its own pivot to its own
attachment point (docs/physics.md, "A team: several strings on one body").

A :class:`TeamScene` is a single-string :class:`~esp_gym.scene.params.Scene` (string 0, the body, its
pivot, gravity, the step, the solver and the initial state) plus the other strings
(:class:`TeamString`). With no other strings it is that scene, and steps as it does, bit for bit.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Optional

import numpy as np
from pydantic import Field, ValidationError, model_validator

from ..physics.rig import find_rig
from ..scene.params import PivotParams, Scene, StringParams, WinchParams
from ..scene.scene_input import Frozen, vector
from ..scene.stepsize import explicit_substeps, rate_loops, shortest

Point3 = vector("coordinate")

#: The most strings a team has.
MAX_STRINGS = 6


class TeamString(Frozen):
    """One more string of a team: its string, its pivot (fixed, or a free point mass), its
    winch at the pivot (range and top speed, as a scene's) and its attachment point on the body
    (body frame, from the body's centre of mass) [m]. It starts straight from its pivot to that
    point, at rest but for its end, which moves with the body."""

    string: StringParams
    pivot: PivotParams = PivotParams()
    winch: WinchParams = WinchParams()
    attachment: Point3 = Field(description="attachment point, body frame, from the centre of mass [m]")


class TeamScene(Frozen):
    """``scene``: string 0 and everything the team shares (the body, with ``body.rho_c`` from
    string 0's attachment point to the centre of mass; gravity, h, the solver, the initial state);
    ``strings``: strings 1..K-1."""

    scene: Scene
    strings: list[TeamString] = Field(default_factory=list)

    @model_validator(mode="before")
    @classmethod
    def _resolve_auto_elements(cls, data: Any) -> Any:
        """``elements: auto`` in a string of ``strings``: its N by esp_gym.choose_resolution as for a
        single string (with the team's body, pivot and solver), and the team's h the smallest of
        the strings' chosen steps (string 0's ``auto`` is the lead scene's own)."""
        if not isinstance(data, Mapping) or not isinstance(data.get("strings"), (list, tuple)):
            return data
        lead = data.get("scene")
        lead = lead if isinstance(lead, Scene) else Scene.model_validate(lead)
        strings, steps = [], []
        for i, entry in enumerate(data["strings"]):
            entry = entry.model_dump() if isinstance(entry, TeamString) else dict(entry)
            string = entry.get("string")
            string = string.model_dump() if isinstance(string, StringParams) else dict(string or {})
            if string.get("elements") == "auto":
                member = {**lead.model_dump(), "string": string, "name": f"{lead.name}[{i + 1}]", "initial": {}}
                pivot = entry.get("pivot", {})
                member["pivot"] = pivot.model_dump() if isinstance(pivot, PivotParams) else dict(pivot)
                try:
                    chosen = Scene.model_validate(member)
                except (ValidationError, ValueError) as err:
                    raise ValueError(f"strings[{i}]: {err}") from None
                string = chosen.string.model_dump()
                steps.append(chosen.h)
            strings.append({**entry, "string": string})
        if steps and min(steps) < lead.h:
            lead = lead.model_copy(update={"h": min(steps)})
        return {**data, "scene": lead, "strings": strings}

    @model_validator(mode="after")
    def _a_team_the_step_supports(self) -> "TeamScene":
        lead = self.scene
        if len(self.strings) + 1 > MAX_STRINGS:
            raise ValueError(f"strings: a team has at most {MAX_STRINGS} strings, got {len(self.strings) + 1}")
        if lead.solver.scheme.stages != 1:
            raise ValueError(f"scene.solver.order: a team steps at order 2 only, got order {lead.solver.order}")
        pivots = [("scene.pivot", lead.pivot)] + [(f"strings[{i}].pivot", s.pivot) for i, s in enumerate(self.strings)]
        damped = [name for name, string in [("scene.string", lead.string)]
                  + [(f"strings[{i}].string", s.string) for i, s in enumerate(self.strings)] if string.damped]
        for name, pivot in pivots:  # the string scheme and each pivot a team rig's (esp_gym/physics/rig.py)
            hooked = pivot.is_drone and pivot.drone.offset_hook
            find_rig("drone" if pivot.is_drone else "point", lead.solver.string, False, hooked, team=True,
                     settings=f"scene.solver.string {lead.solver.string!r}" + (
                         f", {name}.drone.rho_q = {list(pivot.drone.rho_q)}" if hooked else "")
                     + (f", {damped[0]}.damping_time > 0" if damped else "")
                     + "; docs/physics.md, \"What a team does not do yet\"", damped=bool(damped))
        for i, s in enumerate(self.strings):
            try:
                self.member_scene(i + 1)  # the string's own stability bound and ranges at this h
            except (ValidationError, ValueError) as err:
                raise ValueError(f"strings[{i}]: {err}") from None
        return self

    @property
    def size(self) -> int:
        """K, the number of strings."""
        return 1 + len(self.strings)

    @property
    def h(self) -> float:
        return self.scene.h

    def pivots(self) -> list:
        """Every string's pivot section (esp_gym/scene/pivot_params.py ``PivotParams``), string 0's first."""
        return [self.scene.pivot] + [s.pivot for s in self.strings]

    def attachments(self) -> np.ndarray:
        """Every string's attachment point (K, 3), body frame, from the centre of mass [m]."""
        rows = [-np.asarray(self.scene.body.rho_c, dtype=float)]
        rows += [np.asarray(s.attachment, dtype=float) for s in self.strings]
        return np.array(rows)

    def offsets(self) -> np.ndarray:
        """rho_k (K, 3): string k's attachment point from string 0's, body frame [m] (rho_0 = 0)."""
        rho_c = np.asarray(self.scene.body.rho_c, dtype=float)
        return np.array([np.zeros(3)] + [np.asarray(s.attachment, dtype=float) + rho_c for s in self.strings])

    def member_scene(self, k: int) -> Scene:
        """String k as a single-string scene with the team's body, step and solver (for its ranges
        and stability bound; string 0's is :attr:`scene`)."""
        if k == 0:
            return self.scene
        s = self.strings[k - 1]
        data = self.scene.model_dump()
        data.update(string=s.string.model_dump(), pivot=s.pivot.model_dump(), winch=s.winch.model_dump(),
                    name=f"{self.scene.name}[{k}]")
        data["initial"] = {}
        return Scene.model_validate(data)


def symmetric_team(size: int = 3, length: float = 1.0, mass_per_length: float = 0.05, EA: float = 2000.0,
                   elements=8, body_mass: float = 1.0, body_size=(0.4, 0.4, 0.1), pivot_radius: float = 0.6,
                   attachment_radius: float = 0.2, pivot: Optional[dict] = None, h: float = 2e-4,
                   stretch=1.0, law: str = "elastic", **scene) -> TeamScene:
    """A team of ``size`` equal strings symmetric about the e3 axis: pivots on a circle of
    ``pivot_radius`` in the plane z = 0, attachment points on a circle of ``attachment_radius``
    on the top face of a box load (``body_size`` [m], ``body_mass`` [kg]), string k at the angle
    2 pi k / size; each string straight from its pivot to its attachment point, of unstretched
    ``length`` [m] stretched by ``stretch`` (``"static"``: about where the strings carry the load
    at rest, :func:`static_stretch`). ``pivot``: the pivots' section (default fixed; e.g.
    ``{"kind": "free", "mass": 0.5}``); ``law`` the strings' (``slack``: their switches settled,
    or ``solver: {slack_switch: plain}`` in ``scene``). ``scene``: more of the lead scene's sections
    (solver, gravity, ...)."""
    if not 1 <= int(size) <= MAX_STRINGS:
        raise ValueError(f"size must be 1..{MAX_STRINGS}, got {size}")
    size = int(size)
    if stretch == "static":
        stretch = static_stretch(size, length, mass_per_length, EA, body_mass, pivot_radius - attachment_radius,
                                 scene.get("gravity", 9.81))
    angles = 2.0 * np.pi * np.arange(size) / size
    # the C library's cos and sin: NumPy's take processor-specific paths (agents/baselines/libm.py)
    ring = np.array([[math.cos(a), math.sin(a), 0.0] for a in angles])
    attach = attachment_radius * ring - np.array([0.0, 0.0, 0.5 * body_size[2]])
    pivots = pivot_radius * ring
    span = np.hypot(pivot_radius - attachment_radius, 0.0)
    drop = np.sqrt(max((length * stretch) ** 2 - span ** 2, 0.0))
    if drop <= 0.0:
        raise ValueError(f"length * stretch = {length * stretch} m cannot reach from the pivots' circle to the "
                         f"attachments' ({span} m apart)")
    centre = np.array([0.0, 0.0, drop + 0.5 * body_size[2]])  # e3 down: the load hangs at z > 0
    pivot = dict(pivot or {"kind": "fixed"})
    string = dict(length=length, mass_per_length=mass_per_length, EA=EA, elements=elements, law=law)
    direction = centre + attach[0] - pivots[0]
    lead = Scene.model_validate({
        "name": f"team{size}", "h": h,
        "string": string,
        "body": {"mass": body_mass, "rho_c": list(map(float, -attach[0])),
                 "shape": {"kind": "box", "size": list(map(float, body_size))}},
        "pivot": {**pivot, "position": list(map(float, pivots[0]))},
        "initial": {"direction": list(map(float, direction)), "stretch": float(stretch)},
        **scene})
    others = [{"string": dict(string), "pivot": {**pivot, "position": tuple(pivots[k])}, "attachment": tuple(attach[k])}
              for k in range(1, size)]
    return TeamScene.model_validate({"scene": lead, "strings": others})


def static_stretch(size: int, length: float, mass_per_length: float, EA: float, body_mass: float, span: float,
                   gravity: float = 9.81) -> float:
    """The stretch at which ``size`` equal strings, ``span`` [m] apart horizontally from pivot to
    attachment, hold a load of ``body_mass`` [kg] at rest: each carries its share of the weight
    and half its own along its slope, T = (M g / K + mu l g / 2) / cos(theta), stretch = 1 + T/EA
    (a fixed point; the strings' sag neglected)."""
    stretch = 1.0
    for _ in range(50):
        cos = np.sqrt(max(1.0 - (span / (length * stretch)) ** 2, 1e-12))
        tension = (body_mass * gravity / size + 0.5 * mass_per_length * length * gravity) / cos
        stretch = 1.0 + tension / EA
    return float(stretch)


#: The default team's strings, pivots and load (:func:`team_scene`).
NOMINAL = dict(length=1.0, mass_per_length=0.05, EA=200.0, pivot_mass=1.0, body_mass=1.0)


def quadrotor() -> tuple:
    """``(mass [kg], DroneParams)`` of the quadrotor of ``quadrotor_load`` (esp_gym/scenes: PX4's
    1.5 kg x500), a team's drone by default, its rate loop at every physics step: the team's
    baselines and shipped policy were tuned and trained so (a team's steps divide a sampled loop's
    period when its drones have one: :func:`team_substeps`)."""
    from ..scene.params import load_scene

    pivot = load_scene("quadrotor_load").pivot
    return float(pivot.mass), pivot.drone.model_copy(update={"rate_loop_period": None})


def team_scene(size: int, strings=None, pivot_masses=None, body_mass: float = NOMINAL["body_mass"],
               drones: bool = False, allow_unstable_h: bool = False) -> TeamScene:
    """A team of ``size`` free pivots holding a 1 kg-class box (0.4 x 0.4 x 0.1 m) at points 0.15 m
    from its centre line on its top face, each on a tension-only string (``drone_load``'s by
    default: 1 m, 50 g/m, EA = 200 N, 8 elements) from a pivot (1 kg; with ``drones``, the
    :func:`quadrotor` of 1.5 kg, its hook at its centre of mass) on a circle of 0.6 m radius at
    rest. ``strings``: per string ``{length, mass_per_length, EA}``, ``pivot_masses`` per pivot
    [kg]: each string keeps its nominal direction from its attachment point and starts at the
    stretch that carries its share of the load (its pivot moved along it); ``allow_unstable_h``:
    its h (the default team's) need not be stable for those strings, as where an environment
    chooses each episode's own (esp_gym/team/randomize.py)."""
    size = int(size)
    if drones:
        mass, drone = quadrotor()
        kind = {"kind": "drone", "drone": drone.model_dump()}
    else:
        mass, kind = NOMINAL["pivot_mass"], {"kind": "free"}
    nominal = symmetric_team(size, length=NOMINAL["length"], mass_per_length=NOMINAL["mass_per_length"],
                             EA=NOMINAL["EA"], elements=8, body_mass=NOMINAL["body_mass"], body_size=(0.4, 0.4, 0.1),
                             pivot_radius=0.6, attachment_radius=0.15, pivot={**kind, "mass": mass}, h=2e-4,
                             stretch="static", law="slack")
    if strings is None and pivot_masses is None and body_mass == NOMINAL["body_mass"]:
        return nominal
    strings = strings or [{k: NOMINAL[k] for k in ("length", "mass_per_length", "EA")}] * size
    pivot_masses = pivot_masses if pivot_masses is not None else [mass] * size
    lead = nominal.scene
    g = lead.gravity
    attachments = nominal.attachments()
    centre = lead.initial_nodes()[-1] + np.asarray(lead.body.rho_c)
    pivots = np.array([lead.pivot.position] + [s.pivot.position for s in nominal.strings], dtype=float)
    members = []
    for k in range(size):
        d = centre + attachments[k] - pivots[k]
        d /= np.linalg.norm(d)
        s = strings[k]
        tension = (body_mass * g / size + 0.5 * s["mass_per_length"] * s["length"] * g) / d[2]
        stretch = 1.0 + tension / s["EA"]
        members.append((dict(nominal.scene.string.model_dump(), **s), centre + attachments[k] - d * s["length"] * stretch,
                        d, stretch, float(pivot_masses[k])))
    (string0, pivot0, d0, stretch0, mass0), others = members[0], members[1:]
    body = lead.body.model_dump()
    body["mass"] = float(body_mass)
    scene = lead.model_validate({**lead.model_dump(), "string": string0, "body": body,
                                 "pivot": {**kind, "mass": mass0, "position": list(pivot0)},
                                 "initial": {"direction": list(d0), "stretch": stretch0},
                                 "allow_unstable_h": allow_unstable_h})
    return TeamScene(scene=scene, strings=[
        TeamString(string=string, pivot={**kind, "mass": mass, "position": tuple(pivot)},
                   attachment=tuple(attachments[k + 1]))
        for k, (string, pivot, _, _, mass) in enumerate(others)])


def given_team(team, drones: bool, randomized: bool) -> TeamScene:
    """The team of an environment's ``team`` argument: a :class:`TeamScene` (not with
    ``randomized``: a randomised team is drawn from K) or K, the default team of K strings
    (:func:`team_scene`, of ``drones``). ValueError naming ``team`` (or ``randomize``) unless its
    pivots are all free points or all drones."""
    if isinstance(team, TeamScene):
        if randomized:
            raise ValueError("randomize: a randomised team is drawn from team = K, not from a given TeamScene")
        scene = team
    elif isinstance(team, (int, np.integer)) and not isinstance(team, bool) and 1 <= team <= MAX_STRINGS:
        scene = team_scene(int(team), drones=drones)
    else:
        raise ValueError(f"team must be a number of strings (1-{MAX_STRINGS}) or a TeamScene, got {team!r}")
    kinds = {p.kind for p in scene.pivots()}
    if kinds not in ({"free"}, {"drone"}):
        raise ValueError(f"team: a team environment's pivots are all free points or all drones, got {sorted(kinds)}")
    return scene


#: A team's default margin under its strings' stability bounds (the environment's ``safety``): a
#: team's balance at it and below, docs/physics.md ("The slack switch of a team's strings").
TEAM_SAFETY = 0.5


def team_substeps(scene: TeamScene, control_period: float, winch: bool, safety: float = TEAM_SAFETY) -> int:
    """Physics steps per control period of ``scene``: the fewest that keep h within ``safety`` x
    every string's stability bound (with ``winch``, at its winch's shortest length), a whole number
    per each drone's rate-loop period (esp_gym/scene/stepsize.py ``rate_loops``)."""
    members = [scene.member_scene(k) for k in range(scene.size)]
    if winch:
        members = [shortest(m) for m in members]
    steps = max(explicit_substeps(m, control_period, safety) for m in members)
    loops = math.lcm(*(rate_loops(m, control_period) for m in members))
    return loops * math.ceil(steps / loops - 1e-9)
