"""The batched ElasticStringPendulum-v0 as a Stable-Baselines3 ``VecEnv`` (SB3 cannot use
Gymnasium vector envs): the sub-environments step in one compiled call, on ``threads`` numba
threads (default 1: docs/performance.md, "Threads"; :class:`~esp_gym.pendulum.control.ControlStep`), done ones reset at once and their final observation goes
to ``info["terminal_observation"]``. Seeds and results are those of
:class:`esp_gym.pendulum.vector.ElasticStringPendulumVectorEnv` and of the single environment, bit for bit.
"""
from __future__ import annotations

from typing import Any, Optional, Sequence

import gymnasium as gym
import numpy as np

from .. import MAX_EPISODE_STEPS
from ..errors import termination_reason
from ..extras import require
from .control import INFO_REWARD_KEYS, ControlStep
from .env_setup import make_setup
from .options import check_count
from .vector import reset_sub_env

VecEnv = require("stable_baselines3.common.vec_env.base_vec_env", "esp_gym.pendulum.sb3_vector").VecEnv


class ElasticStringPendulumSB3VecEnv(VecEnv):
    """Stable-Baselines3 ``VecEnv`` over a batched :class:`~esp_gym.pendulum.control.ControlStep` (same
    physics, same seeds).

    Done sub-environments reset at once: the returned observation is the new episode's first,
    the final one is in ``infos[i]["terminal_observation"]``, and
    ``infos[i]["TimeLimit.truncated"]`` tells a time-limit end from a termination.
    """

    def __init__(self, num_envs: int = 1, max_episode_steps: Optional[int] = MAX_EPISODE_STEPS, threads: int = 1,
                 **kwargs: Any):
        num_envs = check_count("num_envs", num_envs)
        if max_episode_steps is not None:
            max_episode_steps = check_count("max_episode_steps", max_episode_steps)
        self.setup = make_setup(**kwargs)
        self.control = ControlStep(self.setup, num_envs, threads)
        super().__init__(num_envs, self.setup.observation_space, self.setup.action_space)
        self.max_episode_steps = max_episode_steps
        self._rngs = [np.random.default_rng() for _ in range(self.num_envs)]
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._actions = np.zeros((self.num_envs,) + self.setup.action_space.shape)
        self._all = np.ones(self.num_envs, dtype=bool)

    def reset(self):
        for i, s in enumerate(self._seeds):
            if s is not None:
                self._rngs[i] = gym.utils.seeding.np_random(int(s))[0]
            reset_sub_env(self.control, i, self._rngs[i])
            self.reset_infos[i] = self._scene_params(i)
        self._reset_seeds()
        self._reset_options()
        self._elapsed[:] = 0
        return self.setup.observer.observe_batch(self.control.observation, self.control.sensors, self._rngs)

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
        observer = self.setup.observer
        obs = observer.observe_batch(control.observation, control.sensors, self._rngs)
        infos = [dict(zip(INFO_REWARD_KEYS, terms)) for terms in control.reward_terms.tolist()]
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = obs[i].copy()
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            if terminated[i]:
                infos[i]["termination_reason"] = termination_reason(control.termination[i])
            reset_sub_env(control, i, self._rngs[i])
            self.reset_infos[i] = self._scene_params(i)
            obs[i] = observer.observe(control.observation[i], control.sensors[i], self._rngs[i])
            self._elapsed[i] = 0
        return obs, rewards, dones, infos

    def _scene_params(self, i: int) -> dict:
        """The reset info of sub-environment ``i``: its episode's ``scene_params``."""
        return {"scene_params": dict(zip(self.setup.param_names, self.control.scene_params[i].tolist()))}

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
