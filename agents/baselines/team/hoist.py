"""A team's lift baseline (esp_gym/team/tasks.py ``lift``): the team's LQR (or, on the hook
observation, its LQG) on the pivots' forces, blind to the load's depth (its vertical error and
velocity taken out of the full observation), and on every winch a proportional reel law toward
the length at which its string would hold the load at its target.

String k's reel speed is v_k = -k_length (l_k - l*_k) [m/s], l*_k = |t - p_k + a_k| / s_k: the
straight chord from its pivot p_k to its attachment point a_k (body frame from the centre of
mass, the load hanging level) on the load at its target t, over the string's stretch
s_k = 1 + |T_k| / EA_k read from its hook tension T_k. Every term is in both observation modes
(the target relative to the pivot: ``load_target_offset``, or ``load_offset`` less
``load_position_error``), so the law is the same with and without the load's position.
"""
from __future__ import annotations

import numpy as np

from esp_gym.team.spaces import agent_layout


def layout_of(obs: np.ndarray, core):
    """The agents' layout of a centralised observation: the env's, or the ``full`` one of
    :meth:`~esp_gym.team.core.TeamCore.true_observations` (a baseline reading the true state)."""
    if np.size(obs) == core.size * core.layout.size:
        return core.layout
    return agent_layout(core.size, "full", core.drones, core.winch)


class TeamHoist:
    """``base`` (a TeamLQR or TeamLQG design: its ``act`` gives the pivots' forces (3K,)) and the
    reel law (module docstring) for a team of ``attachments`` (K, 3) [m], ``EA`` (K,) [N] and
    winches of top speed ``max_speeds`` (K,) [m/s]; ``k_length`` [1/s]."""

    def __init__(self, base, attachments: np.ndarray, EA: np.ndarray, max_speeds: np.ndarray, k_length: float = 2.0):
        self.base, self.k_length = base, float(k_length)
        self.attachments, self.EA, self.max_speeds = np.asarray(attachments), np.asarray(EA), np.asarray(max_speeds)

    @classmethod
    def design(cls, base, core, k_length: float = 2.0) -> "TeamHoist":
        """On ``core``'s (nominal) team: its attachment points, its strings' EA and winches."""
        scene = core.scene
        EA = np.array([scene.scene.string.EA] + [s.string.EA for s in scene.strings])
        return cls(base, scene.attachments(), EA, core.sim.winches.max_speeds, k_length)

    def reset(self) -> None:
        self.base.reset()

    @property
    def estimate(self):
        """The base's filter estimate of the reduced state (the LQG's; None for the LQR)."""
        return getattr(self.base, "estimate", None)

    def record_applied(self, action: np.ndarray) -> None:
        """The action given was ``action`` (K x 4, a residual's sum): the base hears its forces."""
        self.base.record_applied(np.asarray(action, dtype=np.float64).reshape(self.attachments.shape[0], 4)[:, :3])

    def reel(self, obs: np.ndarray, core) -> np.ndarray:
        """Each winch's action (K,) in [-1, 1] for the centralised observation."""
        K, L = core.size, layout_of(obs, core)
        o = np.asarray(obs, dtype=np.float64).reshape(K, L.size)
        if "load_target_offset" in L:
            offset = o[:, L["load_target_offset"]]
        else:
            offset = o[:, L["load_offset"]] - o[:, L["load_position_error"]]
        chord = np.linalg.norm(offset + self.attachments, axis=1)
        stretch = 1.0 + np.linalg.norm(o[:, L["hook_tension"]], axis=1) / self.EA
        error = o[:, L["string_length"]][:, 0] - chord / stretch
        return np.clip(-self.k_length * error / self.max_speeds, -1.0, 1.0)

    @staticmethod
    def level(obs: np.ndarray, core) -> np.ndarray:
        """``obs`` with the load's vertical error and velocity taken out (the ``full`` mode): what
        the base sees, the depth being the winches' to close."""
        L = layout_of(obs, core)
        if "load_position_error" not in L:
            return obs
        o = np.array(obs, dtype=np.float64).reshape(core.size, L.size)
        o[:, L.start("load_position_error") + 2] = 0.0
        o[:, L.start("load_velocity") + 2] = 0.0
        return o.ravel()

    def act(self, obs: np.ndarray, core) -> np.ndarray:
        """The centralised action (4K,): each agent's force (3), the base's on :meth:`level`
        ``obs``, and reel speed (1)."""
        forces = np.asarray(self.base.act(self.level(obs, core), core), dtype=np.float64).reshape(core.size, 3)
        return np.column_stack([forces, self.reel(obs, core)]).ravel()
