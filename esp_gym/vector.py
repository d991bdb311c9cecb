"""Batched ElasticStringPendulum-v0: all sub-environments step in one compiled, parallel call.

* :class:`ElasticStringPendulumVectorEnv` is a Gymnasium ``VectorEnv`` (the registration's
  ``vector_entry_point``, so ``gymnasium.make_vec("ElasticStringPendulum-v0", num_envs=8)``
  uses it), with Gymnasium's default next-step autoreset.
* :class:`ElasticStringPendulumSB3VecEnv` is a Stable-Baselines3 ``VecEnv`` (SB3 cannot use
  Gymnasium vector envs): done environments reset at once and the final observation goes to
  ``info["terminal_observation"]``.

Each sub-environment runs the same compiled step as :class:`~esp_gym.env.ElasticStringPendulumEnv`
from its own ``np_random`` (seeded ``seed + i``), so results equal the single env's bit for bit.
"""
from __future__ import annotations

from typing import Any, Optional, Sequence

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import MAX_EPISODE_STEPS
from .control import INFO_REWARD_KEYS, ControlStep, make_setup
from .kernels.layout import termination_reason
from .tasks import sample_episode


def _reset_env(control: ControlStep, i: int, rng: np.random.Generator) -> None:
    """Sample a new episode for sub-environment ``i`` of the batch ``control``."""
    state, target = sample_episode(control.setup.task, control.setup.scene, rng)
    control.reset(state, target, index=i)


def _seeds(seed, n) -> list:
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)):
        return [int(seed) + i for i in range(n)]
    seeds = list(seed)
    if len(seeds) != n:
        raise ValueError(f"need {n} seeds, got {len(seeds)}")
    return seeds


class ElasticStringPendulumVectorEnv(VectorEnv):
    """``num_envs`` ElasticStringPendulum-v0 environments stepped in one parallel compiled call.

    Takes the single environment's arguments plus ``num_envs`` and ``max_episode_steps``.
    Autoreset: next step (Gymnasium's default) -- the step after an episode ends resets that
    sub-environment and returns its first observation with reward 0.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, max_episode_steps: Optional[int] = MAX_EPISODE_STEPS, render_mode=None, **kwargs: Any):
        if render_mode is not None:
            raise ValueError("the vector environment does not render; use the single environment")
        self.setup = make_setup(**kwargs)
        self.num_envs = int(num_envs)
        self.control = ControlStep(self.setup, self.num_envs)
        self.single_observation_space = self.setup.observation_space
        self.single_action_space = self.setup.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.max_episode_steps = max_episode_steps
        self._rngs = [np.random.default_rng() for _ in range(self.num_envs)]
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)

    def reset(self, *, seed=None, options: Optional[dict] = None):
        seeds = _seeds(seed, self.num_envs)
        if seed is not None:
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(seeds[0])
        for i, s in enumerate(seeds):
            if s is not None:  # like Env.reset: a seed restarts the generator, None continues it
                self._rngs[i] = gym.utils.seeding.np_random(s)[0]
            _reset_env(self.control, i, self._rngs[i])
        self._elapsed[:] = 0
        self._autoreset[:] = False
        return self.control.observation.astype(np.float32), {}

    def step(self, actions):
        control = self.control
        resetting = self._autoreset.copy()
        active = ~resetting
        # step first (it checks the actions: a bad call raises before anything changes), then
        # reset the sub-environments whose episodes ended; the step leaves those untouched
        control.step(actions, active)
        for i in np.flatnonzero(resetting):
            _reset_env(control, i, self._rngs[i])
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
        if terminated.any():
            infos["termination_reason"] = np.array([termination_reason(c) for c in code], dtype=object)
            infos["_termination_reason"] = terminated.copy()
        return control.observation.astype(np.float32), rewards, terminated, truncated, infos


try:  # SB3 is a dependency, but keep the Gymnasium vector env importable without it
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv as _SB3VecEnv
except ImportError:  # pragma: no cover
    _SB3VecEnv = object


class ElasticStringPendulumSB3VecEnv(_SB3VecEnv):
    """Stable-Baselines3 ``VecEnv`` over a batched :class:`~esp_gym.control.ControlStep` (same
    physics, same seeds).

    Done sub-environments reset at once: the returned observation is the new episode's first,
    the final one is in ``infos[i]["terminal_observation"]``, and
    ``infos[i]["TimeLimit.truncated"]`` tells a time-limit end from a termination.
    """

    def __init__(self, num_envs: int = 1, max_episode_steps: Optional[int] = MAX_EPISODE_STEPS, **kwargs: Any):
        self.setup = make_setup(**kwargs)
        self.control = ControlStep(self.setup, int(num_envs))
        super().__init__(int(num_envs), self.setup.observation_space, self.setup.action_space)
        self.max_episode_steps = max_episode_steps
        self._rngs = [np.random.default_rng() for _ in range(self.num_envs)]
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._actions = np.zeros((self.num_envs,) + self.setup.action_space.shape)
        self._all = np.ones(self.num_envs, dtype=bool)

    def reset(self):
        for i, s in enumerate(self._seeds):
            if s is not None:
                self._rngs[i] = gym.utils.seeding.np_random(int(s))[0]
            _reset_env(self.control, i, self._rngs[i])
        self._reset_seeds()
        self._reset_options()
        self._elapsed[:] = 0
        return self.control.observation.astype(np.float32)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions  # checked by the step (step_wait), before anything changes

    def step_wait(self):
        control = self.control
        control.step(self._actions, self._all)
        rewards = control.reward().astype(np.float32)
        terminated = control.termination != 0
        self._elapsed += 1
        truncated = self._elapsed >= self.max_episode_steps if self.max_episode_steps else np.zeros_like(terminated)
        dones = terminated | truncated
        obs = control.observation.astype(np.float32)
        infos = [dict(zip(INFO_REWARD_KEYS, terms)) for terms in control.reward_terms.tolist()]
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = obs[i].copy()
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            if terminated[i]:
                infos[i]["termination_reason"] = termination_reason(control.termination[i])
            _reset_env(control, i, self._rngs[i])
            obs[i] = control.observation[i]
            self._elapsed[i] = 0
        return obs, rewards, dones, infos

    def close(self) -> None:
        pass

    def get_attr(self, attr_name: str, indices=None) -> list:
        return [getattr(self.setup, attr_name, None) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        raise AttributeError("sub-environments of the batched VecEnv share one frozen setup")

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list:
        raise AttributeError(f"the batched VecEnv has no per-environment method {method_name!r}")

    def env_is_wrapped(self, wrapper_class, indices=None) -> list:
        return [False for _ in self._get_indices(indices)]

    def _get_indices(self, indices) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices
