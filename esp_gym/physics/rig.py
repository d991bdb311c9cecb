"""The rigs of ElasticStringPendulum-v0 and ElasticStringTeam-v0: which combinations of pivot, string
scheme, winch and hook exist, and for each the compiled entry points, the reset kernel and the
structs they take.

A rig is chosen once, from the environment's resolved setup (:func:`find_rig`), and then called
at one site for one environment and one for a batch (esp_gym/pendulum/control.py; a team's in
esp_gym/team/control.py and esp_gym/team/batch.py): every entry point takes the structs its rig
names, in the one order of :data:`STRUCTS`, then the raw action(s) (and a batch's ``active``
mask) and the step's run-time switches. A team whose strings reel steps in Python (its rig has no
entry points). A combination that is not in :data:`RIGS` is refused with one error that lists the
rigs there are. ``python -c "import esp_gym; print(esp_gym.rigs())"``
prints the table (docs/environment.md, "Rigs").
"""
from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module

#: Every struct an entry point may take, in the order they are passed (kernels/layout.py,
#: kernels/env/arrays.py, kernels/drone/quadrotor.py, kernels/drone/hook.py): the state, the work arrays,
#: the stepper's constants, the diagnostics' scratch, the winch's arrays, the environment's
#: arrays, the drone's, the offset hook's; a team's simulator's structs (kernels/team/env.py
#: ``TeamStructs``) and its task's and environment's arrays (``TeamTaskArrays``, ``TeamEnvArrays``).
STRUCTS = ("state", "work", "params", "diag", "winch", "env", "drone", "hook", "team", "team_env")
#: The module that holds the entry points of each pivot's rigs (and of a team's), each named after its rig.
ENTRY_MODULES = {"point": "esp_gym.kernels.env.step", "drone": "esp_gym.kernels.drone.env",
                 "team": "esp_gym.kernels.team.env"}
#: The environment each kind of rig belongs to.
ENVIRONMENTS = {False: "ElasticStringPendulum-v0", True: "ElasticStringTeam-v0"}


@dataclass(frozen=True)
class Rig:
    """One rig: what it is (``pivot``: ``"point"`` or ``"drone"``; ``string``: ``"explicit"`` or
    ``"implicit"``; ``winch``; ``hook``: a drone's hook off its centre of mass) and the structs
    its entry points take (a subsequence of :data:`STRUCTS`; none for a rig that steps in Python);
    ``team``: a team's rig (ElasticStringTeam-v0, every pivot of the one kind); ``damper``: its
    step damps the string (``string.damping_time`` > 0, kernels/step/damper.py), a step of its own
    (an undamped rig's compiled step has no damper in it)."""

    pivot: str
    string: str
    winch: bool
    hook: bool
    structs: tuple
    team: bool = False
    damper: bool = False

    @property
    def name(self) -> str:
        """e.g. ``drone-explicit-winch``, ``point-implicit``, ``drone-explicit-offset-hook``,
        ``team-drone-explicit``, ``point-explicit-damped``."""
        return "-".join((("team",) if self.team else ()) + (self.pivot, self.string) + (("winch",) if self.winch else ())
                        + (("offset-hook",) if self.hook else ()) + (("damped",) if self.damper else ()))

    @property
    def environment(self) -> str:
        """The environment id whose rig this is."""
        return ENVIRONMENTS[self.team]

    @property
    def compiled(self) -> bool:
        """Whether a control step is one compiled call (False: a team whose strings reel, stepped
        in Python by esp_gym/team/simulator.py)."""
        return bool(self.structs)

    @property
    def entries(self):
        """``(step, batch, threaded_batch)`` (kernels/env/step.py's EntryPoints; a team has no
        threaded batch), each compiled when first called: the module-level name of :attr:`name`
        (``-`` read as ``_``) in kernels/env/step.py for a point pivot, kernels/drone/env.py for a
        drone, kernels/team/env.py for a team (imported only when a rig asks: a point pivot's
        environment loads no drone kernel). None for a rig that steps in Python."""
        if not self.compiled:
            return None
        module = import_module(ENTRY_MODULES["team" if self.team else self.pivot])
        return getattr(module, self.name.replace("-", "_"))

    def reset_observe(self, S, P, D, WA, E, DR, HK) -> int:
        """The observation, reward terms and energy origin of a freshly set state (structs this
        rig does not take are ignored); returns its termination code. (A team resets in Python.)"""
        if self.pivot == "point":
            from ..kernels.env.step import env_reset_observe

            return int(env_reset_observe(S, P, D, WA, E, self.winch))
        from ..kernels.drone.env import drone_reset_observe

        return int(drone_reset_observe(S, P, D, WA if self.winch else None, DR, HK if self.hook else None, E))


_POINT = ("state", "work", "params", "diag", "winch", "env")
_TEAM = ("team", "team_env")
#: Every rig: ElasticStringPendulum-v0's, then ElasticStringTeam-v0's.
RIGS = tuple([Rig("point", scheme, winch, False, _POINT) for winch in (False, True)
              for scheme in ("explicit", "implicit")]
             + [Rig("point", scheme, False, False, _POINT, damper=True) for scheme in ("explicit", "implicit")]
             + [Rig("drone", "explicit", False, False, ("state", "work", "params", "diag", "env", "drone")),
                Rig("drone", "explicit", True, False, ("state", "work", "params", "diag", "winch", "env", "drone")),
                Rig("drone", "explicit", False, True, ("state", "work", "params", "diag", "env", "drone", "hook")),
                Rig("drone", "explicit", False, False, ("state", "work", "params", "diag", "env", "drone"), damper=True),
                Rig("point", "explicit", False, False, _TEAM, team=True),
                Rig("drone", "explicit", False, False, _TEAM, team=True),
                Rig("point", "explicit", True, False, (), team=True)])


def rigs() -> str:
    """The table of :data:`RIGS`: each rig's name, environment, pivot, string scheme, winch, offset
    hook and the structs its entry points take (or that it steps in Python)."""
    rows = [("rig", "environment", "pivot", "string", "winch", "offset hook", "damper",
             "structs its entry points take")]
    rows += [(r.name, r.environment, r.pivot, r.string, "yes" if r.winch else "no", "yes" if r.hook else "no",
              "yes" if r.damper else "no", ", ".join(r.structs) if r.compiled else "none: steps in Python")
             for r in RIGS]
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows)


def scene_rig(scene, winch: bool) -> Rig:
    """The rig of a scene (its pivot, its solver's string scheme, a drone's hook) with or without
    the winch; ValueError naming the scene's settings if there is none (:func:`find_rig`)."""
    pivot = scene.pivot
    hooked = pivot.is_drone and pivot.drone.offset_hook
    damped = scene.string.damped
    return find_rig("drone" if pivot.is_drone else "point", scene.solver.string, winch, hooked,
                    f"scene {scene.name!r}: solver.string {scene.solver.string!r}, winch={winch}"
                    + (f", pivot.drone.rho_q = {list(pivot.drone.rho_q)}" if hooked else "")
                    + (f", string.damping_time = {scene.string.damping_time:g} s" if damped else ""), damped=damped)


def find_rig(pivot: str, string: str, winch: bool, hook: bool, settings: str = "", team: bool = False,
             damped: bool = False) -> Rig:
    """The rig of ``pivot`` (``"point"`` or ``"drone"``), ``string`` (``"explicit"`` or
    ``"implicit"``), ``winch`` and ``hook``, a team's if ``team``; ValueError naming the
    combination (and the ``settings`` that asked for it) and listing the environment's rigs of
    :data:`RIGS` if there is none (``damped``: the string's damper, a rig of its own)."""
    combination = (pivot, string, bool(winch), bool(hook), bool(team), bool(damped))
    for rig in RIGS:
        if (rig.pivot, rig.string, rig.winch, rig.hook, rig.team, rig.damper) == combination:
            return rig
    asked = Rig(pivot, string, bool(winch), bool(hook), (), bool(team), bool(damped))
    raise ValueError(f"{asked.environment}: no rig is {asked.name}" + (f" ({settings})" if settings else "")
                     + "; the rigs are " + ", ".join(rig.name for rig in RIGS if rig.team == asked.team)
                     + " (esp_gym.rigs())")
