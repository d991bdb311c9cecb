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

from .env import ACTION_SIZE, TERMINATION_REASONS, EnvSetup, make_setup, raw_actions
from .kernels.diagnostics import DiagWork
from .kernels.lgvi import StateArrays, Work
from .kernels.task import OBS_SIZE, REWARD_TERMS, actions_finite, env_reset_observe, env_step_batch
from .model import Simulator
from .tasks import sample_episode


class BatchPhysics:
    """Stacked state of ``num_envs`` simulators of one setup and the batched compiled step."""

    def __init__(self, setup: EnvSetup, num_envs: int):
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        self.setup = setup
        self.num_envs = n = int(num_envs)
        template = Simulator(setup.scene)
        S, W, P, D = template.kernel_args
        self.params = P

        def stack(t):
            return type(t)(*(np.zeros((n,) + a.shape) for a in t))

        self.S, self.W, self.D = stack(S), stack(W), stack(D)
        self.inputs = np.zeros((n, 9))
        self.target = np.zeros((n, 6))
        self.action = np.zeros((n, ACTION_SIZE))
        self.obs = np.zeros((n, OBS_SIZE))
        self.terms = np.zeros((n, len(REWARD_TERMS)))
        self.result = np.zeros((n, 5), dtype=np.int64)

    def env_views(self, i: int):
        """The kernel arrays of sub-environment ``i`` (views)."""
        return (StateArrays(*(a[i] for a in self.S)), Work(*(a[i] for a in self.W)),
                self.params, DiagWork(*(a[i] for a in self.D)))

    def reset_env(self, i: int, rng: np.random.Generator) -> None:
        """Sample a new episode for sub-environment ``i`` and compute its observation."""
        state, target = sample_episode(self.setup.task, self.setup.scene, rng)
        S, _, P, D = self.env_views(i)
        S.r[...], S.p[...], S.R[...], S.Pi[...] = state.r, state.p, state.R, state.Pi
        for a in (S.rc, S.pc, S.Rc, S.Pic, S.acc, S.accc):
            a[...] = 0.0
        self.target[i] = target
        self.action[i] = 0.0
        env_reset_observe(S, P, D, self.target[i], self.setup.task_params, self.action[i], self.obs[i], self.terms[i])

    def step(self, raw: np.ndarray, active: np.ndarray) -> None:
        """One control step of every active sub-environment; ``raw`` from
        :func:`_checked_actions` (clipped and mapped to inputs in the compiled step)."""
        env_step_batch(*self.S, *self.W, *self.D, self.params, raw, self.setup.action_params, self.inputs, active,
                       self.setup.substeps, self.target, self.setup.task_params, self.action, self.obs, self.terms,
                       self.result)

    def rewards(self) -> np.ndarray:
        """Sum of the reward terms in REWARD_TERMS order (the single env's order)."""
        out = np.zeros(self.num_envs)
        for j in range(len(REWARD_TERMS)):
            out += self.terms[:, j]
        return out


def _checked_actions(actions, space, num_envs) -> np.ndarray:
    """Raw actions (num_envs, 6) for :meth:`BatchPhysics.step`: shape and finiteness checked
    (ValueError, before anything changes); clipped in the compiled step."""
    raw = raw_actions(actions, (num_envs,) + space.shape, "actions")
    if not actions_finite(raw):
        raise ValueError("actions must be finite")
    return raw


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

    def __init__(self, num_envs: int = 1, max_episode_steps: Optional[int] = 500, render_mode=None, **kwargs: Any):
        if render_mode is not None:
            raise ValueError("the vector environment does not render; use the single environment")
        self.setup = make_setup(**kwargs)
        self.num_envs = int(num_envs)
        self.batch = BatchPhysics(self.setup, self.num_envs)
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
            self.batch.reset_env(i, self._rngs[i])
        self._elapsed[:] = 0
        self._autoreset[:] = False
        return self.batch.obs.astype(np.float32), {}

    def step(self, actions):
        a = _checked_actions(actions, self.single_action_space, self.num_envs)
        resetting = self._autoreset.copy()
        for i in np.flatnonzero(resetting):
            self.batch.reset_env(i, self._rngs[i])
            self._elapsed[i] = 0
        active = ~resetting
        self.batch.step(a, active)
        rewards = np.where(active, self.batch.rewards(), 0.0)
        code = np.where(active, self.batch.result[:, 4], 0)
        terminated = code != 0
        self._elapsed[active] += 1
        truncated = active & (self._elapsed >= self.max_episode_steps) if self.max_episode_steps else np.zeros_like(active)
        self._autoreset = terminated | truncated
        infos: dict = {}
        for j, name in enumerate(REWARD_TERMS):
            infos["reward_" + name] = np.where(active, self.batch.terms[:, j], 0.0)
            infos["_reward_" + name] = active.copy()
        if terminated.any():
            infos["termination_reason"] = np.array([TERMINATION_REASONS.get(int(c), "") for c in code], dtype=object)
            infos["_termination_reason"] = terminated.copy()
        return self.batch.obs.astype(np.float32), rewards, terminated, truncated, infos


try:  # SB3 is a dependency, but keep the Gymnasium vector env importable without it
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv as _SB3VecEnv
except ImportError:  # pragma: no cover
    _SB3VecEnv = object


class ElasticStringPendulumSB3VecEnv(_SB3VecEnv):
    """Stable-Baselines3 ``VecEnv`` over :class:`BatchPhysics` (same physics, same seeds).

    Done sub-environments reset at once: the returned observation is the new episode's first,
    the final one is in ``infos[i]["terminal_observation"]``, and
    ``infos[i]["TimeLimit.truncated"]`` tells a time-limit end from a termination.
    """

    def __init__(self, num_envs: int = 1, max_episode_steps: Optional[int] = 500, **kwargs: Any):
        self.setup = make_setup(**kwargs)
        self.batch = BatchPhysics(self.setup, num_envs)
        super().__init__(int(num_envs), self.setup.observation_space, self.setup.action_space)
        self.max_episode_steps = max_episode_steps
        self._rngs = [np.random.default_rng() for _ in range(self.num_envs)]
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._actions = np.zeros((self.num_envs, ACTION_SIZE))
        self._all = np.ones(self.num_envs, dtype=bool)

    def reset(self):
        for i, s in enumerate(self._seeds):
            if s is not None:
                self._rngs[i] = gym.utils.seeding.np_random(int(s))[0]
            self.batch.reset_env(i, self._rngs[i])
        self._reset_seeds()
        self._reset_options()
        self._elapsed[:] = 0
        return self.batch.obs.astype(np.float32)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = _checked_actions(actions, self.action_space, self.num_envs)

    def step_wait(self):
        b = self.batch
        b.step(self._actions, self._all)
        rewards = b.rewards().astype(np.float32)
        terminated = b.result[:, 4] != 0
        self._elapsed += 1
        truncated = self._elapsed >= self.max_episode_steps if self.max_episode_steps else np.zeros_like(terminated)
        dones = terminated | truncated
        obs = b.obs.astype(np.float32)
        infos = [{"reward_" + name: float(b.terms[i, j]) for j, name in enumerate(REWARD_TERMS)}
                 for i in range(self.num_envs)]
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = obs[i].copy()
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            if terminated[i]:
                infos[i]["termination_reason"] = TERMINATION_REASONS[int(b.result[i, 4])]
            b.reset_env(i, self._rngs[i])
            obs[i] = b.obs[i]
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
