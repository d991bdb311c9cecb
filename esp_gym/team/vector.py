"""``gym.make_vec("ElasticStringTeam-v0", num_envs=n)``: n teams in one process, with Gymnasium's
next-step autoreset, each from its own seed (``seed + i``), so that every sub-env repeats the single
env's episodes bit for bit, and their infos in Gymnasium's vector convention (each key an array over
the sub-envs with its ``_key`` mask, as ``ElasticStringPendulum-v0``'s vector env gives them;
docs/team.md). Teams without winches step in one compiled call for the batch
(esp_gym/team/batch.py); teams with winches one by one.
"""
from __future__ import annotations

from typing import Optional

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .. import MAX_EPISODE_STEPS
from ..errors import termination_reason
from ..kernels.status import TERM_NONE
from ..pendulum.control import raw_actions
from ..pendulum.vector import sub_env_seeds
from .batch import TeamBatch
from .env import ElasticStringTeamEnv
from .stepping import AGENT_KEYS, REWARD_KEYS


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
        #: the teams' compiled batch (esp_gym/team/batch.py); None where the teams step one by one
        #: (winches)
        self.batch = TeamBatch([env.core for env in self.envs]) if self.envs[0].core.control is not None else None

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
        if self.batch is not None:
            for i in range(self.num_envs):
                self.batch.reset(i)
        return np.stack(obs), infos

    def step(self, actions):
        if not self._was_reset:
            raise RuntimeError("call reset() before step()")
        actions = raw_actions(actions, self.action_space.shape, "actions")
        if self.batch is None:
            return self._step_one_by_one(actions)
        stepping = ~self._autoreset
        if not np.all(np.isfinite(actions[stepping])):  # before any team steps or resets
            raise ValueError("actions must be finite")
        core = self.envs[0].core
        raw = actions.reshape(self.num_envs, core.size, core.action_size).copy()
        outcomes = self.batch.step(raw, stepping)
        obs = np.empty(self.observation_space.shape, dtype=np.float32)
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        codes = np.zeros(self.num_envs, dtype=np.int64)
        separations = np.zeros(self.num_envs)
        for i in np.flatnonzero(stepping):
            o, rewards[i], separations[i], codes[i] = outcomes[i]
            obs[i] = o.ravel()
        terminated[stepping] = codes[stepping] != TERM_NONE
        self._elapsed[stepping] += 1
        truncated[stepping] = self._elapsed[stepping] >= self.max_episode_steps
        infos = step_infos(self.batch, stepping, codes, separations) if stepping.any() else {}
        for i in np.flatnonzero(~stepping):  # the reset's info, as Gymnasium's own vector envs give it
            o, info = self.envs[i].reset()
            self.batch.reset(i)
            obs[i] = o
            self._elapsed[i] = 0
            infos = self._add_info(infos, info, i)
        self._autoreset = terminated | truncated
        return obs, rewards, terminated, truncated, infos

    def _step_one_by_one(self, actions):
        """:meth:`step` of teams with winches, each team's step in turn."""
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


def step_infos(batch: TeamBatch, stepping: np.ndarray, codes: np.ndarray, separations: np.ndarray) -> dict:
    """The infos of the teams ``stepping`` (B,) bool in Gymnasium's vector convention, each key an
    array over the sub-envs (zeros where a team did not step, None in an object array) with its
    ``_key`` mask: as Gymnasium's ``_add_info`` gathers the single env's (TeamStepping.task_info)."""
    task, B = batch.task, stepping.shape[0]
    infos = {}

    def put(key, values, mask=stepping):
        array = np.zeros_like(values)
        array[mask] = values[mask]
        infos[key], infos["_" + key] = array, mask.copy()

    for j, key in enumerate(REWARD_KEYS):
        put(key, task.terms[:, j])
    for j, key in enumerate(AGENT_KEYS):
        put(key, task.agent[:, :, j])
    put("min_separation", separations)
    put("tension", batch.structs.read.tension)
    put("applied_action", batch.env.action)
    put("termination", codes)
    ended = stepping & (codes != TERM_NONE)
    if ended.any():
        reasons = np.full(B, None, dtype=object)
        for i in np.flatnonzero(ended):
            reasons[i] = termination_reason(int(codes[i]))
        infos["termination_reason"], infos["_termination_reason"] = reasons, ended
    return infos
