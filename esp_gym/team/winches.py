"""A team's winches, one at each string's pivot (docs/physics.md, "Winches on a team's strings"):
their arrays for the compiled step (esp_gym/kernels/team/winch.py), their lengths and reel
speeds, their checks, and the reeling strings' share of a team's diagnostics.

Every string of a team has a winch (its scene's ``winch`` section: the range and the top speed),
idle until :meth:`TeamSimulator.step <esp_gym.team.simulator.TeamSimulator.step>` is given
``reel_speeds``; while every string is at its scene's length and at rest, the team runs its
fixed-length step, bit for bit as without winches.
"""
from __future__ import annotations

import numpy as np

from ..kernels.layout import WINCH
from ..kernels.step.winch import convective_weights
from ..physics.arrays import team_winch_arrays, winch_arrays
from ..physics.winch import winch_state
from ..scene.scene_input import real_number
from ..scene.stepsize import shortest
from .scene import TeamScene

LENGTH, SPEED = WINCH.scalar("length"), WINCH.scalar("reel_speed")


class TeamWinches:
    """The winches of a team's K strings: ``arrays`` (:data:`~esp_gym.kernels.team.winch.TeamWinch`),
    each string's unstretched length [m] and the state's reel speed [m/s]."""

    def __init__(self, team: TeamScene, max_len2: np.ndarray, start: np.ndarray):
        """``max_len2`` (K,): each string's blow-up guard at its scene's length [m^2]; ``start``
        the team's stacked rows of strings 1..K-1 (TeamParams.start)."""
        self.team = team
        self.scenes = [team.member_scene(k) for k in range(team.size)]
        rows = int(start[-1])
        self.state = np.array([winch_state(s, float(g)) for s, g in zip(self.scenes, max_len2)])
        z = np.zeros
        n0 = team.scene.string.elements
        lead = winch_arrays(self.state[0], convective_weights(n0, team.scene.string.mass_model == "consistent"))
        coef = z((rows, 3))
        for j, s in enumerate(team.strings):
            coef[start[j]:start[j + 1] - 1] = convective_weights(s.string.elements, s.string.mass_model == "consistent")
        self.arrays = team_winch_arrays(lead, self.state, coef)
        self.start = start
        self.scene_lengths = np.array([s.string.length for s in self.scenes])
        self.ranges = np.array([s.winch_range for s in self.scenes])
        self.max_speeds = np.array([float(s.winch.max_speed) for s in self.scenes])
        self._checked_h = None

    # -- the state ------------------------------------------------------------------------------
    @property
    def lengths(self) -> np.ndarray:
        """Each string's unstretched length (K,) [m] (a copy)."""
        return self.state[:, LENGTH].copy()

    @property
    def reel_speeds(self) -> np.ndarray:
        """Each string's reel speed of the state (K,) [m/s] (a copy): its momenta were made with it."""
        return self.state[:, SPEED].copy()

    @property
    def idle(self) -> bool:
        """Every string at its scene's length and at rest: the fixed-length step runs."""
        return not ((self.state[:, LENGTH] != self.scene_lengths).any() or self.state[:, SPEED].any())

    def use_speeds(self, speeds: np.ndarray) -> None:
        """Set the state's reel speeds (K,) [m/s], unchecked (the simulator's own: :meth:`held`, :meth:`cut_speeds`)."""
        self.state[:, SPEED] = speeds

    def set(self, lengths=None, reel_speeds=None) -> None:
        """Set the lengths (K,) [m] (None: the scenes') and the state's reel speeds (K,) [m/s]
        (None: at rest), checked before any change."""
        lengths = self.scene_lengths.copy() if lengths is None else self._vector("lengths", lengths)
        speeds = np.zeros(self.team.size) if reel_speeds is None else self.check_speeds(reel_speeds)
        low, high = self.ranges[:, 0], self.ranges[:, 1]
        for k in range(self.team.size):
            if not low[k] <= lengths[k] <= high[k]:
                raise ValueError(f"lengths[{k}] = {lengths[k]:g} m lies outside string {k}'s winch range "
                                 f"[{low[k]:g}, {high[k]:g}] m")
        self.state[:, LENGTH] = lengths
        self.state[:, SPEED] = speeds

    def _vector(self, name: str, values) -> np.ndarray:
        """``values`` (K,) as floats: ValueError naming ``name`` (or its entry) unless K finite reals."""
        K = self.team.size
        if isinstance(values, (str, bytes)) or np.ndim(values) != 1 or len(values) != K:
            raise ValueError(f"{name} must be {K} numbers, one per string; got {values!r}")
        return np.array([real_number(f"{name}[{k}]", values[k]) for k in range(K)])

    def check_speeds(self, reel_speeds) -> np.ndarray:
        """``reel_speeds`` (K,) [m/s] as floats: ValueError naming the entry unless each is a
        finite real of magnitude at most its string's ``winch.max_speed``."""
        v = self._vector("reel_speeds", reel_speeds)
        for k in range(self.team.size):
            if abs(v[k]) > self.max_speeds[k]:
                raise ValueError(f"reel_speeds[{k}] = {v[k]:g} m/s exceeds string {k}'s winch.max_speed = "
                                 f"{self.max_speeds[k]:g} m/s")
        return v

    def check_scene(self, h: float) -> None:
        """ValueError unless every string can reel at step ``h``: the explicit string's h stable at
        its winch's shortest length (docs/physics.md, "The winch", "Limits")."""
        if self._checked_h == h:
            return
        for k, scene in enumerate(self.scenes):
            bound = shortest(scene).stability_bound
            if h > bound and not self.team.scene.allow_unstable_h:
                name = "scene" if k == 0 else f"strings[{k - 1}]"
                raise ValueError(f"reel_speeds: h = {h:g} s exceeds string {k}'s stability bound {bound:.4g} s at its "
                                 f"winch's shortest length {name}.winch.min_length = {self.ranges[k, 0]:g} m; raise "
                                 "it or take a smaller h")
        self._checked_h = h

    def held(self, speeds: np.ndarray) -> np.ndarray:
        """``speeds`` with 0 for a string at an end of its range that would reel past it."""
        lengths = self.state[:, LENGTH]
        out = speeds.copy()
        out[(lengths >= self.ranges[:, 1]) & (out > 0.0)] = 0.0
        out[(lengths <= self.ranges[:, 0]) & (out < 0.0)] = 0.0
        return out

    def cut_speeds(self, h: float) -> np.ndarray:
        """The state's reel speeds, but (end - length) / h for a string whose next step would pass
        an end of its range: the speed of the step that ends on it (kernels/team/winch.py
        ``reel_targets`` holds it there)."""
        lengths, speeds = self.state[:, LENGTH], self.state[:, SPEED]
        targets = lengths + h * speeds
        ends = np.clip(targets, self.ranges[:, 0], self.ranges[:, 1])
        return np.where(targets != ends, (ends - lengths) / h, speeds)

    # -- the diagnostics' share -----------------------------------------------------------------
    def strings_at_length(self) -> list:
        """Each string's section (esp_gym/scene/params.py StringParams) at its current length."""
        return [s.string.model_copy(update={"length": float(l)}) for s, l in zip(self.scenes, self.state[:, LENGTH])]

    def flow_momenta(self, lead_r, others_r, speeds) -> tuple:
        """The momenta of the material's flow, c C^T r per node (docs/physics.md, "The winch"), at
        reel speeds ``speeds`` (K,): ``(string 0's (N+1, 3), the others' stacked rows with each
        end's row (rows, 3))`` [kg m/s]; rows below a fixed pivot 0 (they are not unknowns)."""
        members = [(lead_r, self.arrays.lead.coef, self.team.scene)]
        members += [(others_r[self.start[j]:self.start[j + 1]], self.arrays.coef[self.start[j]:self.start[j + 1] - 1],
                     s) for j, s in enumerate(self.team.strings)]
        out = []
        for (r, coef, section), v in zip(members, speeds):
            q = np.zeros_like(r)
            if v != 0.0:
                n = r.shape[0] - 1
                x = np.diff(r, axis=0)
                q[:-1] += coef[:, 0:1] * x
                q[1:] += coef[:, 1:2] * x
                q *= section.string.mass_per_length * v / n
                if not section.pivot.is_free:
                    q[0] = 0.0
            out.append(q)
        lead, *others = out
        return lead, (np.concatenate(others) if others else np.zeros((0, 3)))

    def convective_energy(self, lead_r, others_r, speeds) -> float:
        """T0 = sum over strings of theta/2 sum_e gamma_e |x_e|^2, theta = mu v^2 / (N l) [J]."""
        total = 0.0
        members = [(lead_r, self.arrays.lead.coef)] + [
            (others_r[self.start[j]:self.start[j + 1]], self.arrays.coef[self.start[j]:self.start[j + 1] - 1])
            for j in range(self.team.size - 1)]
        for (r, coef), v, l, scene in zip(members, speeds, self.state[:, LENGTH], self.scenes):
            if v != 0.0:
                n = r.shape[0] - 1
                x2 = np.sum(np.diff(r, axis=0) ** 2, axis=1)
                total += 0.5 * scene.string.mass_per_length * v * v / (n * l) * float(coef[:, 2] @ x2)
        return total

