"""A centralised critic for a team (MAPPO with one shared network; docs/team.md, "Training"): each
agent's actor reads its own observation only, its critic (the value function PPO's advantages come
from) reads it with the team's true state appended: every agent's ``full`` observation without
noise (:meth:`~esp_gym.team.core.TeamCore.true_observations`), what the hook observation of the
hard preset hides (the load) included. Training alone reads the state; acting never does.

:class:`CentralCriticParallelEnv` appends the state to every agent's observation (after a
residual team's features, agents/team/residual.py), agents/team/critic_module.py's
``CentralCriticModule`` is the RLlib module that splits it: an MLP actor on the first
``actor_inputs`` numbers, an MLP critic on all (there, as it imports torch and RLlib).
A checkpoint trained so carries ``central_critic.json`` (the actor's and the state's lengths), and
:class:`~agents.team.train.TeamRLlibPolicy` feeds its actor zeros where the state was.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np
from pettingzoo import ParallelEnv

CRITIC_FILE = "central_critic.json"


class CentralCriticParallelEnv(ParallelEnv):
    """``env`` (a team's ParallelEnv, plain or residual; it has ``core``) with the team's true
    state appended to every agent's observation (module docstring)."""

    metadata = {"name": "elastic_string_team_central_critic_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, env):
        self.env, self.core = env, env.core
        self.possible_agents = list(env.possible_agents)
        self.agents = []
        self.render_mode = None
        #: the length of an agent's own observation (what its actor reads) and of the appended state
        self.actor_inputs = env.observation_space(self.possible_agents[0]).shape[0]
        self.state_size = self.core.true_observations().size
        # the spaces by name, as the team's own ParallelEnv gives them (esp_gym/team/parallel.py)
        self.observation_spaces = {a: gym.spaces.Box(-np.inf, np.inf, (self.actor_inputs + self.state_size,),
                                                     np.float32) for a in self.possible_agents}
        self.action_spaces = {a: env.action_space(a) for a in self.possible_agents}
        self.state_space = env.state_space

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    def _append(self, obs: dict) -> dict:
        state = self.core.true_observations().ravel().astype(np.float32)
        return {a: np.concatenate([np.asarray(o, dtype=np.float32), state]) for a, o in obs.items()}

    def reset(self, seed: Optional[int] = None, options: Optional[dict] = None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        return self._append(obs), infos

    def step(self, actions: dict):
        obs, rewards, terminations, truncations, infos = self.env.step(actions)
        self.agents = list(self.env.agents)
        return self._append(obs), rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        return self.env.state()


def write_critic(directory: Path, actor_inputs: int, state_size: int) -> None:
    (Path(directory) / CRITIC_FILE).write_text(json.dumps({"actor_inputs": actor_inputs,
                                                           "state_size": state_size}) + "\n")


def read_critic(directory: Path) -> Optional[dict]:
    """The lengths recorded in ``directory`` (a run's or a shipped checkpoint), or None without a
    centralised critic."""
    path = Path(directory) / CRITIC_FILE
    return json.loads(path.read_text()) if path.is_file() else None
