"""The team as a PettingZoo ``ParallelEnv`` (docs/team.md): agents ``pivot_0 .. pivot_{K-1}``, each
pushing its own pivot or flying its drone and observing what :func:`~esp_gym.team.spaces.agent_layout`
names; the reward
is the team's, given to every agent, with each agent's own terms in its ``infos`` entry."""
from __future__ import annotations

import functools
from typing import Optional

import gymnasium as gym
import numpy as np

from ..control import raw_actions
from ..extras import require
from .env import MAX_EPISODE_STEPS, TeamCore

ParallelEnv = require("pettingzoo", "esp_gym.team.parallel_env").ParallelEnv


class ElasticStringTeamParallelEnv(ParallelEnv):
    """K point pivots or K drones carrying one load on tension-only elastic strings. Each agent's
    action is ``Box(-1, 1, (3,))``, its pivot's force (spatial) on top of its hover force
    (``force_limit`` of it at 1), or with drones ``Box(-1, 1, (4,))``, its drone's
    (esp_gym/team/spaces.py ``DroneDrive``); its observation is ``Box(-inf, inf, (n,))`` with
    n = 27 + 3 (K - 1) (+ 9 with drones), named by :attr:`observation_structure`
    (``preset="hard"``: the hook observation, 12 + 3 (K - 1) (+ 9)). An episode is truncated
    after ``max_cycles`` steps (500: 10 s) and terminated for the whole team (collision, an
    overstretched string, the workspace left, a drone flipped, a failed step:
    ``infos[agent]["termination_reason"]``). Arguments (``options``: control_period,
    force_limit, preset, randomize, observation, sensor_noise, action_latency, wind, actuation,
    winch) as :class:`~esp_gym.team.env.TeamCore`'s, checked alike."""

    metadata = {"name": "elastic_string_team_v0", "render_modes": ["rgb_array"], "render_fps": 50,
                "is_parallelizable": True}

    def __init__(self, team=3, task: str = "transport", max_cycles: int = MAX_EPISODE_STEPS,
                 render_mode: Optional[str] = None, **options):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if isinstance(max_cycles, bool) or not isinstance(max_cycles, (int, np.integer)) or max_cycles < 1:
            raise ValueError(f"max_cycles must be a whole number >= 1, got {max_cycles!r}")
        self.core = TeamCore(team, task, **options)
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.core.control_period}  # a frame per step
        self.max_cycles = int(max_cycles)
        self.render_mode = render_mode
        self.possible_agents = [f"pivot_{k}" for k in range(self.core.size)]
        self.agents = []
        #: name -> slice of one agent's observation
        self.observation_structure = self.core.layout.structure()

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent):
        return gym.spaces.Box(-np.inf, np.inf, (self.core.layout.size,), np.float32)

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent):
        return gym.spaces.Box(-1.0, 1.0, (self.core.action_size,), np.float32)

    def reset(self, seed: Optional[int] = None, options: Optional[dict] = None):
        obs, info = self.core.reset(seed=seed)
        self.agents = list(self.possible_agents)
        return ({a: obs[k] for k, a in enumerate(self.agents)},
                {a: {**info, "agent": k} for k, a in enumerate(self.agents)})

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("step: the episode has ended; call reset()")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"actions: every agent acts in a team, missing {missing}")
        unknown = [a for a in actions if a not in self.possible_agents]
        if unknown:
            raise ValueError(f"actions: unknown agents {unknown}")
        shape = (self.core.action_size,)
        action = np.stack([raw_actions(actions[a], shape, f"actions[{a!r}]") for a in self.possible_agents])
        obs, reward, terminated, _, info = self.core.step(action)
        truncated = not terminated and self.core.steps >= self.max_cycles
        agents = list(self.agents)
        infos = {}
        for k, a in enumerate(agents):
            infos[a] = {"terms": info["agents"][k], "reward_terms": info["reward_terms"],
                        "min_separation": info["min_separation"]}
            if terminated:
                infos[a]["termination_reason"] = info["termination_reason"]
        out = ({a: obs[k] for k, a in enumerate(agents)}, {a: reward for a in agents},
               {a: terminated for a in agents}, {a: truncated for a in agents}, infos)
        if terminated or truncated:
            self.agents = []
        return out

    def render(self):
        """The team's frame (:meth:`~esp_gym.team.env.TeamCore.frame`) with ``render_mode="rgb_array"``, else None."""
        return self.core.frame() if self.render_mode == "rgb_array" else None

    def state(self) -> np.ndarray:
        """The team's true state as every agent's ``full`` observation without noise, one after the
        other (a centralised critic's input)."""
        return self.core.true_observations().ravel()


def parallel_env(team=3, task: str = "transport", **kwargs) -> ElasticStringTeamParallelEnv:
    """A team of ``team`` point pivots (or drones: ``actuation="thrust_rates"``) as a PettingZoo
    ParallelEnv (:class:`ElasticStringTeamParallelEnv`)."""
    return ElasticStringTeamParallelEnv(team=team, task=task, **kwargs)
