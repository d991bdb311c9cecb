"""``gym.make_vec("ElasticStringTeam-v0", num_envs=n)``: n teams stepped in turn in one process, with
Gymnasium's next-step autoreset, each from its own seed (``seed + i``), so that every sub-env
repeats the single env's episodes bit for bit, and their infos in Gymnasium's vector convention
(each key an array over the sub-envs with its ``_key`` mask, as ``ElasticStringPendulum-v0``'s
vector env gives them; docs/team.md). The teams' steps are not yet one compiled call for the
batch, as ``ElasticStringPendulum-v0``'s are."""
from __future__ import annotations

from typing import Optional

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..control import raw_actions
from ..vector import sub_env_seeds
from .. import MAX_EPISODE_STEPS
from .env import ElasticStringTeamEnv


class ElasticStringTeamVectorEnv(VectorEnv):
    """``num_envs`` :class:`~esp_gym.team.env.ElasticStringTeamEnv` (arguments as its), truncated
    after ``max_episode_steps`` as the registered single env is."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, team=3, task: str = "transport",
                 max_episode_steps: int = MAX_EPISODE_STEPS, **options):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a whole number >= 1, got {num_envs!r}")
        if isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, (int, np.integer)) \
                or max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be a whole number >= 1, got {max_episode_steps!r}")
        self.envs = [ElasticStringTeamEnv(team, task, **options) for _ in range(int(num_envs))]
        self.num_envs = int(num_envs)
        self.max_episode_steps = int(max_episode_steps)
        self.single_action_space = self.envs[0].action_space
        self.single_observation_space = self.envs[0].observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._was_reset = False  # stepping teams that were never reset is an error

    def reset(self, *, seed=None, options: Optional[dict] = None):
        seeds = sub_env_seeds(seed, self.num_envs)
        obs, infos = [], {}
        for i, (env, s) in enumerate(zip(self.envs, seeds)):
            o, info = env.reset(seed=s)
            obs.append(o)
            infos = self._add_info(infos, info, i)
        self._autoreset[:] = False
        self._elapsed[:] = 0
        self._was_reset = True
        return np.stack(obs), infos

    def step(self, actions):
        if not self._was_reset:
            raise RuntimeError("call reset() before step()")
        actions = raw_actions(actions, self.action_space.shape, "actions")
        obs = np.empty(self.observation_space.shape, dtype=np.float32)
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        infos = {}
        for i, env in enumerate(self.envs):
            if self._autoreset[i]:  # the reset's info, as Gymnasium's own vector envs give it
                obs[i], info = env.reset()
                self._elapsed[i] = 0
            else:
                obs[i], rewards[i], terminated[i], truncated[i], info = env.step(actions[i])
                self._elapsed[i] += 1
                truncated[i] |= self._elapsed[i] >= self.max_episode_steps
            infos = self._add_info(infos, info, i)
        self._autoreset = terminated | truncated
        return obs, rewards, terminated, truncated, infos
