"""Batched ElasticStringPendulum-v0: all sub-environments step in one compiled call.

:class:`ElasticStringPendulumVectorEnv` is a Gymnasium ``VectorEnv`` (the registration's
``vector_entry_point``, so ``gymnasium.make_vec("ElasticStringPendulum-v0", num_envs=8)`` uses
it), with Gymnasium's default next-step autoreset. The Stable-Baselines3 ``VecEnv`` over the same
batch is :class:`esp_gym.pendulum.sb3_vector.ElasticStringPendulumSB3VecEnv`, in its own module so that
``make_vec`` does not import SB3 and torch (1.4 s of a 2.3 s warm start).

Each sub-environment runs the same compiled step as :class:`~esp_gym.pendulum.env.ElasticStringPendulumEnv`
from its own ``np_random`` (seeded ``seed + i``), so results equal the single env's bit for bit.
"""
from __future__ import annotations

from typing import Any, Optional

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .. import MAX_EPISODE_STEPS
from ..errors import termination_reason
from .control import INFO_REWARD_KEYS, ControlStep
from .env_setup import make_setup
from .options import check_count


def reset_sub_env(control: ControlStep, i: int, rng: np.random.Generator) -> None:
    """Start a new episode in sub-environment ``i`` of the batch ``control``."""
    control.start_episode(rng, index=i)


def scene_params_info(control: ControlStep, which: np.ndarray) -> dict:
    """``info["scene_params"]``: name -> (num_envs,) values of the current episodes, with the
    ``"_scene_params"`` mask ``which`` (Gymnasium's vector info convention)."""
    values = control.scene_params
    return {"scene_params": {name: values[:, j].copy() for j, name in enumerate(control.setup.param_names)},
            "_scene_params": which.copy()}


def sub_env_seeds(seed, n) -> list:
    """Seeds of ``n`` sub-environments from one ``seed``: ``seed + i``, a sequence of ``n``, or
    None for each."""
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)):
        return [int(seed) + i for i in range(n)]
    seeds = list(seed)
    if len(seeds) != n:
        raise ValueError(f"need {n} seeds, got {len(seeds)}")
    return seeds


class ElasticStringPendulumVectorEnv(VectorEnv):
    """``num_envs`` ElasticStringPendulum-v0 environments stepped in one compiled call.

    Takes the single environment's arguments plus ``num_envs``, ``max_episode_steps`` and
    ``threads``: the numba threads the batch steps on (default 1, its own thread; more pay only on
    a machine with CPUs to spare: docs/performance.md, "Threads").
    Autoreset: next step (Gymnasium's default) -- the step after an episode ends resets that
    sub-environment and returns its first observation with reward 0.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, max_episode_steps: Optional[int] = MAX_EPISODE_STEPS, render_mode=None,
                 threads: int = 1, **kwargs: Any):
        if render_mode is not None:
            raise ValueError("the vector environment does not render; use the single environment")
        self.num_envs = check_count("num_envs", num_envs)
        if max_episode_steps is not None:
            max_episode_steps = check_count("max_episode_steps", max_episode_steps)
        self.setup = make_setup(**kwargs)
        self.control = ControlStep(self.setup, self.num_envs, threads)
        self.single_observation_space = self.setup.observation_space
        self.single_action_space = self.setup.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.max_episode_steps = max_episode_steps
        self._rngs = [np.random.default_rng() for _ in range(self.num_envs)]
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)

    def reset(self, *, seed=None, options: Optional[dict] = None):
        seeds = sub_env_seeds(seed, self.num_envs)
        if seed is not None:
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(seeds[0])
        for i, s in enumerate(seeds):
            if s is not None:  # like Env.reset: a seed restarts the generator, None continues it
                self._rngs[i] = gym.utils.seeding.np_random(s)[0]
            reset_sub_env(self.control, i, self._rngs[i])
        self._elapsed[:] = 0
        self._autoreset[:] = False
        return self._observe(), scene_params_info(self.control, np.ones(self.num_envs, dtype=bool))

    def _observe(self) -> np.ndarray:
        control = self.control
        return self.setup.observer.observe_batch(control.observation, control.sensors, self._rngs)

    def step(self, actions):
        control = self.control
        resetting = self._autoreset.copy()
        active = ~resetting
        # step first (it checks the actions: a bad call raises before anything changes), then
        # reset the sub-environments whose episodes ended; the step leaves those untouched
        control.step(actions, active)
        for i in np.flatnonzero(resetting):
            reset_sub_env(control, i, self._rngs[i])
            self._elapsed[i] = 0
        rewards = np.where(active, control.reward(), 0.0)
        code = np.where(active, control.termination, 0)
        terminated = code != 0
        self._elapsed[active] += 1
        truncated = active & (self._elapsed >= self.max_episode_steps) if self.max_episode_steps else np.zeros_like(active)
        self._autoreset = terminated | truncated
        infos: dict = {}
        for j, key in enumerate(INFO_REWARD_KEYS):
            infos[key] = np.where(active, control.reward_terms[:, j], 0.0)
            infos["_" + key] = active.copy()
        if resetting.any():
            infos.update(scene_params_info(control, resetting))
        if terminated.any():
            infos["termination_reason"] = np.array([termination_reason(c) for c in code], dtype=object)
            infos["_termination_reason"] = terminated.copy()
        return self._observe(), rewards, terminated, truncated, infos
