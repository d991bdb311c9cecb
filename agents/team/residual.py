"""A residual team: every agent's action is the team's baseline's command for its pivot plus
``scale`` times the network's, the sum clipped to the box (residual policy learning, as
agents/residual.py does for one string). The baseline is the centralised one of the observation
mode (agents/team/evaluate.py :func:`~agents.team.evaluate.team_baselines`: the LQR, or with the
hook observation the LQG); it is told the action actually applied, so the LQG's filter predicts
with it.

A drone team's baseline is the drones' cascade (agents/baselines/team/cascade.py), its command
each drone's four numbers. Each agent sees its own observation, then its baseline command (3, or
4 for a drone) and, from a stateful baseline (the LQG, the cascade's filter), the filter's estimate of the team's reduced state (agents/baselines/team/lqr.py
``reduced_layout``) with the pivots' blocks rolled so that its own pivot comes first: one shared
network reads every agent's the same way.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np
from pettingzoo import ParallelEnv

from agents.baselines.team.lqr import reduced_layout
from agents.team.evaluate import team_baselines

#: The network's share of the action box by default: its unit action moves a pivot's command by this much.
RESIDUAL_SCALE = 0.3
#: The largest share: the box [-1, 1] is 2 wide, so at 2 the residual alone takes any command to
#: either end; a larger scale only saturates the sum at the network's smaller outputs.
MAX_RESIDUAL_SCALE = 2.0
RESIDUAL_FILE = "residual.json"


class TeamBase:
    """The centralised baseline of a team core's observation mode (of its drones, with ``drones``;
    of its winches, the lift's hoist, with ``winch``), acting for every agent at once."""

    def __init__(self, observation: str, drones: bool = False, winch: bool = False):
        self.policy = next(iter(team_baselines(observation, drones, winch).values()))

    def act(self, obs: np.ndarray, core) -> np.ndarray:
        """The baseline's (K, a) command for the agents' (K, n) observations (a: an agent's action
        size); a new episode at ``core.steps == 0``."""
        return self.policy.act(np.asarray(obs, dtype=np.float64).ravel(), core).reshape(core.size, core.action_size)

    def observe(self, obs: np.ndarray, core) -> tuple:
        """``(command, inputs)`` for the agents' (K, n) observations: the baseline's (K, 3) command
        and each agent's observation followed by its :meth:`features`, (K, n + a + e) in float64."""
        agents = np.asarray(obs, dtype=np.float64).reshape(core.size, -1)
        command = self.act(agents, core)
        return command, np.concatenate([agents, self.features(core, command)], axis=1)

    def apply(self, command: np.ndarray, residual: np.ndarray, scale: float) -> np.ndarray:
        """The (K, a) action :func:`combine` makes of ``command`` and ``residual``, told to the
        baseline's filter (its model's input for the next estimate)."""
        total = combine(command, np.asarray(residual, dtype=np.float64).reshape(command.shape), scale)
        self.policy.design.record_applied(total.ravel())
        return total

    def features(self, core, command: np.ndarray) -> np.ndarray:
        """(K, a + e): each agent's command, then the filter's estimate (e = 0 without one) with its pivot first."""
        estimate = getattr(self.policy.design, "estimate", None)
        if estimate is None:
            return np.asarray(command, dtype=np.float64)
        K, Z = core.size, reduced_layout(core.size)
        pivots = [estimate[Z[name]].reshape(K, 3) for name in ("pivot_error", "pivot_velocity")]
        load = estimate[Z["load_error"].start:]
        rows = [np.concatenate([command[k], *(np.roll(p, -k, axis=0).ravel() for p in pivots), load]) for k in range(K)]
        return np.stack(rows)


def feature_size(size: int, observation: str, action_size: int = 3) -> int:
    """The length a + e of :meth:`TeamBase.features` for a team of ``size`` in ``observation`` mode
    whose agents act with ``action_size`` numbers."""
    return action_size + (reduced_layout(size).size if observation != "full" else 0)


class TeamResidualParallelEnv(ParallelEnv):
    """``env`` (an :class:`~esp_gym.team.parallel.ElasticStringTeamParallelEnv`) stepped with the
    baseline's command plus ``scale`` x each agent's action (module docstring); its observations
    carry :meth:`TeamBase.features`."""

    metadata = {"name": "elastic_string_team_residual_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, env, scale: float = RESIDUAL_SCALE):
        if not 0 < scale <= MAX_RESIDUAL_SCALE:  # NaN fails too
            raise ValueError(f"residual_scale must be in (0, {MAX_RESIDUAL_SCALE:g}], got {scale!r}")
        self.env, self.scale = env, float(scale)
        self.core = env.core
        self.base = TeamBase(self.core.observation, self.core.drones, self.core.winch)
        self.possible_agents = list(env.possible_agents)
        self.agents = []
        self.render_mode = None
        #: the baseline's command (K, a) for the last observations
        self.command = None
        self._extra = feature_size(self.core.size, self.core.observation, self.core.action_size)
        # the spaces by name, as the team's own ParallelEnv gives them (esp_gym/team/parallel.py)
        self.observation_spaces = {a: gym.spaces.Box(-np.inf, np.inf, (env.observation_space(a).shape[0] + self._extra,),
                                                     np.float32) for a in self.possible_agents}
        self.action_spaces = {a: env.action_space(a) for a in self.possible_agents}
        self.state_space = env.state_space

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    def _observe(self, obs: dict) -> dict:
        self.command, inputs = self.base.observe(np.stack([obs[a] for a in self.possible_agents]), self.core)
        return {a: inputs[k].astype(np.float32) for k, a in enumerate(self.possible_agents) if a in obs}

    def reset(self, seed: Optional[int] = None, options: Optional[dict] = None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        return self._observe(obs), infos

    def step(self, actions: dict):
        total = self.base.apply(self.command, np.stack([np.asarray(actions[a]).reshape(-1) for a in self.possible_agents]),
                                self.scale)
        obs, rewards, terminations, truncations, infos = self.env.step(
            {a: total[k] for k, a in enumerate(self.possible_agents)})
        self.agents = list(self.env.agents)
        return self._observe(obs), rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        return self.env.state()


def combine(command: np.ndarray, residual: np.ndarray, scale: float) -> np.ndarray:
    """clip(command + scale clip(residual, -1, 1), -1, 1), each (K, a)."""
    return np.clip(command + scale * np.clip(residual, -1.0, 1.0), -1.0, 1.0)


def write_residual(directory: Path, scale: float) -> None:
    (Path(directory) / RESIDUAL_FILE).write_text(json.dumps({"base": "team_baseline", "scale": scale}) + "\n")


def read_residual(directory: Path) -> Optional[float]:
    """The residual scale recorded in ``directory`` (a run or a shipped model), or None for a plain policy."""
    path = Path(directory) / RESIDUAL_FILE
    return float(json.loads(path.read_text())["scale"]) if path.is_file() else None
