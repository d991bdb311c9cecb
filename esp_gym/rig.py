"""The rigs of ElasticStringPendulum-v0: which combinations of pivot, string scheme, winch and hook
exist, and for each the compiled entry points, the reset kernel and the structs they take.

A rig is chosen once, from the environment's resolved setup (:func:`find_rig`), and then called
at one site for one environment and one for a batch (esp_gym/control.py): every entry point
takes the structs its rig names, in the one order of :data:`STRUCTS`, then the raw action(s)
(and a batch's ``active`` mask) and the scheme. A combination that is not in :data:`RIGS` is
refused with one error that lists the rigs there are. ``python -c "import esp_gym; print(esp_gym.rigs())"``
prints the table (docs/environment.md, "Rigs").
"""
from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module

#: Every struct an entry point may take, in the order they are passed (kernels/layout.py,
#: kernels/env_arrays.py, kernels/drone.py, kernels/drone_hook.py): the state, the work arrays,
#: the stepper's constants, the diagnostics' scratch, the winch's arrays, the environment's
#: arrays, the drone's, the offset hook's.
STRUCTS = ("state", "work", "params", "diag", "winch", "env", "drone", "hook")
#: The module that holds each pivot's rigs' entry points, each named after its rig.
ENTRY_MODULES = {"point": ".kernels.env_step", "drone": ".kernels.drone_env"}


@dataclass(frozen=True)
class Rig:
    """One rig: what it is (``pivot``: ``"point"`` or ``"drone"``; ``string``: ``"explicit"`` or
    ``"implicit"``; ``winch``; ``hook``: a drone's hook off its centre of mass) and the structs
    its entry points take (a subsequence of :data:`STRUCTS`)."""

    pivot: str
    string: str
    winch: bool
    hook: bool
    structs: tuple

    @property
    def name(self) -> str:
        """e.g. ``drone-explicit-winch``, ``point-implicit``, ``drone-explicit-offset-hook``."""
        return "-".join((self.pivot, self.string) + (("winch",) if self.winch else ())
                        + (("offset-hook",) if self.hook else ()))

    @property
    def entries(self):
        """``(step, batch, threaded_batch)`` (kernels/env_step.py's EntryPoints), each compiled
        when first called: the module-level name of :attr:`name` (``-`` read as ``_``) in
        kernels/env_step.py for a point pivot, kernels/drone_env.py for a drone (imported only
        when a rig asks: a point pivot's environment loads no drone kernel)."""
        module = import_module(ENTRY_MODULES[self.pivot], __package__)
        return getattr(module, self.name.replace("-", "_"))

    def reset_observe(self, S, P, D, WA, E, DR, HK) -> int:
        """The observation, reward terms and energy origin of a freshly set state (structs this
        rig does not take are ignored); returns its termination code."""
        if self.pivot == "point":
            from .kernels.env_step import env_reset_observe

            return int(env_reset_observe(S, P, D, WA, E, self.winch))
        from .kernels.drone_env import drone_reset_observe

        return int(drone_reset_observe(S, P, D, WA if self.winch else None, DR, HK if self.hook else None, E))


_POINT = ("state", "work", "params", "diag", "winch", "env")
#: Every rig of ElasticStringPendulum-v0 (a team's are esp_gym/team's).
RIGS = tuple([Rig("point", scheme, winch, False, _POINT) for winch in (False, True)
              for scheme in ("explicit", "implicit")]
             + [Rig("drone", "explicit", False, False, ("state", "work", "params", "diag", "env", "drone")),
                Rig("drone", "explicit", True, False, ("state", "work", "params", "diag", "winch", "env", "drone")),
                Rig("drone", "explicit", False, True, ("state", "work", "params", "diag", "env", "drone", "hook"))])


def rigs() -> str:
    """The table of :data:`RIGS`: each rig's name, pivot, string scheme, winch, offset hook and the
    structs its entry points take."""
    rows = [("rig", "pivot", "string", "winch", "offset hook", "structs its entry points take")]
    rows += [(r.name, r.pivot, r.string, "yes" if r.winch else "no", "yes" if r.hook else "no", ", ".join(r.structs))
             for r in RIGS]
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows)


def scene_rig(scene, winch: bool) -> Rig:
    """The rig of a scene (its pivot, its solver's string scheme, a drone's hook) with or without
    the winch; ValueError naming the scene's settings if there is none (:func:`find_rig`)."""
    pivot = scene.pivot
    hooked = pivot.is_drone and pivot.drone.offset_hook
    return find_rig("drone" if pivot.is_drone else "point", scene.solver.string, winch, hooked,
                    f"scene {scene.name!r}: solver.string {scene.solver.string!r}, winch={winch}"
                    + (f", pivot.drone.rho_q = {list(pivot.drone.rho_q)}" if hooked else ""))


def find_rig(pivot: str, string: str, winch: bool, hook: bool, settings: str = "",
             where: str = "ElasticStringPendulum-v0") -> Rig:
    """The rig of ``pivot`` (``"point"`` or ``"drone"``), ``string`` (``"explicit"`` or
    ``"implicit"``), ``winch`` and ``hook``; ValueError naming the combination (and the
    ``settings`` that asked for it) and listing :data:`RIGS` if there is none."""
    for rig in RIGS:
        if (rig.pivot, rig.string, rig.winch, rig.hook) == (pivot, string, bool(winch), bool(hook)):
            return rig
    asked = Rig(pivot, string, bool(winch), bool(hook), ()).name
    raise ValueError(f"{where}: no rig is {asked}" + (f" ({settings})" if settings else "")
                     + "; the rigs are " + ", ".join(rig.name for rig in RIGS) + " (esp_gym.rigs())")
