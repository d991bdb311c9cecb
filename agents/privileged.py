"""An asymmetric actor-critic for partial observations: during training the critic also sees what
the simulator knows and a sensor does not (the load's state, the episode's parameters, the wind
now), the actor only the observation. A run with ``privileged_critic: true`` in its config trains
through :class:`PrivilegedVecEnv` with :class:`AsymmetricPolicy`; the deployed policy needs only
the observation (agents.evaluate.SB3Policy fills the privileged entries with zeros, which the actor
never reads).

Why: with ``observation="hook"`` under wind, pushes and randomised parameters, the return of an
episode depends on much the critic cannot infer from the hook, so advantages computed from an
observation-only value function are mostly noise (Pinto et al. 2018, "Asymmetric actor critic
for image-based robot learning"). The policy gradient stays unbiased for any baseline; a better
one only lowers its variance.
"""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, FlattenExtractor
from stable_baselines3.common.vec_env import VecEnvWrapper


def privileged_size(control) -> int:
    """Entries :class:`PrivilegedVecEnv` appends for a batched ControlStep ``control``."""
    return sum(view.shape[-1] for view in _views(control))


def _views(control) -> tuple:
    # the full noiseless OBSERVATION, the episode's SCENE_PARAMS, the wind and push state now
    return control.observation, control.scene_params, control.disturbance


class PrivilegedVecEnv(VecEnvWrapper):
    """Appends the privileged entries of the batched esp_gym VecEnv ``control`` to each
    observation of ``venv`` (which steps that ControlStep, possibly through wrappers). A
    terminal observation gets those of the step before (the environment has already reset)."""

    def __init__(self, venv, control):
        self.control = control
        space = venv.observation_space
        size = space.shape[0] + privileged_size(control)
        super().__init__(venv, observation_space=gym.spaces.Box(-np.inf, np.inf, (size,), dtype=space.dtype))
        self._last = None

    def _privileged(self) -> np.ndarray:
        return np.concatenate([np.asarray(v, dtype=np.float64).reshape(self.num_envs, -1) for v in _views(self.control)],
                              axis=-1)

    def reset(self):
        obs = self.venv.reset()
        self._last = self._privileged()
        return np.concatenate([obs, self._last], axis=-1).astype(obs.dtype)

    def step_async(self, actions):
        self.venv.step_async(actions)

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        for i in np.flatnonzero(dones):
            if "terminal_observation" in infos[i]:
                last = infos[i]["terminal_observation"]
                infos[i]["terminal_observation"] = np.concatenate([last, self._last[i]]).astype(last.dtype)
        self._last = self._privileged()
        return np.concatenate([obs, self._last], axis=-1).astype(obs.dtype), rewards, dones, infos


class MaskedFlatten(BaseFeaturesExtractor):
    """The flattened observation with the entries where ``keep`` is 0 set to 0 (the actor's view)."""

    def __init__(self, observation_space: gym.spaces.Box, keep):
        super().__init__(observation_space, int(np.prod(observation_space.shape)))
        self.register_buffer("keep", th.as_tensor(np.asarray(keep, dtype=np.float32)))

    def forward(self, observations: th.Tensor) -> th.Tensor:
        return th.flatten(observations, start_dim=1) * self.keep


class AsymmetricPolicy(ActorCriticPolicy):
    """SB3's MLP actor-critic whose actor reads only the first ``actor_size`` entries of each of
    the stacked frames of ``frame_size`` entries, and whose critic reads everything."""

    def __init__(self, observation_space, action_space, lr_schedule, frame_size: int, actor_size: int, **kwargs):
        total = int(np.prod(observation_space.shape))
        if not (0 < actor_size <= frame_size and total % frame_size == 0):
            raise ValueError(f"AsymmetricPolicy: actor_size {actor_size} and frame_size {frame_size} do not fit an "
                             f"observation of {total} entries")
        self.frame_size, self.actor_size = int(frame_size), int(actor_size)
        keep = np.tile(np.arange(frame_size) < actor_size, total // frame_size)
        kwargs.update(features_extractor_class=MaskedFlatten, features_extractor_kwargs={"keep": keep},
                      share_features_extractor=False)
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)
        self.vf_features_extractor = FlattenExtractor(observation_space)  # parameter-free: the optimiser is unchanged

    def _get_constructor_parameters(self) -> dict:
        data = super()._get_constructor_parameters()
        for key in ("features_extractor_class", "features_extractor_kwargs", "share_features_extractor"):
            data.pop(key, None)
        return {**data, "frame_size": self.frame_size, "actor_size": self.actor_size}
