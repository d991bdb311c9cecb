"""What RLlib's side of the agents shares: the run configuration (configs/agents/rllib_ppo.yaml
with ``--set`` overrides), the PPO configuration built from it, the environment creator the env
runners call, and a trained checkpoint as a policy for agents/evaluate.py.

The environment on an env runner: with ``batched: true`` (the default) RLlib builds each runner's
``num_envs_per_env_runner`` sub-environments through the registration's vector entry point
(``gym_env_vectorize_mode="vector_entry_point"``), which is esp_gym's batched
:class:`~esp_gym.pendulum.vector.ElasticStringPendulumVectorEnv`: all sub-environments of a runner step in
one compiled call. ``batched: false`` gives Gymnasium's SyncVectorEnv of single environments
(one compiled call each), the setting RLlib uses for any environment.
"""
from __future__ import annotations

import copy
import dataclasses
import inspect
from pathlib import Path
from typing import Annotated, Optional, Union

import gymnasium as gym
import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

import esp_gym
from agents.common import CONFIG_DIR, ConfigError, ValueLoader, apply_override, first_unknown_key, valid_keys
from esp_gym.scene.scene_input import Count, Real

CONFIG_FILE = CONFIG_DIR / "rllib_ppo.yaml"
#: The name the environment creator is registered under with Ray Tune's registry.
ENV_NAME = "esp_gym_rllib"
#: PPOConfig.training() arguments that are not hyper-parameters a config file may set: old-stack,
#: deprecated, or objects rather than values.
NOT_TRAINING_KEYS = {"self", "kwargs", "model", "train_batch_size", "num_sgd_iter", "lr_schedule",
                     "max_requests_in_flight_per_sampler_worker", "learner_class", "learner_connector",
                     "add_default_connectors_to_learner_pipeline", "entropy_coeff_schedule",
                     "vf_share_layers"}  # vf_share_layers: a model setting (model.vf_share_layers)
#: The keys of ``normalize`` (RLlib's MeanStdFilter on observations).
NORMALIZE_KEYS = {"de_mean_to_zero", "de_std_to_one", "clip_by_value"}


class RLlibRunConfig(BaseModel):
    """The validated settings of one RLlib run; ``training`` holds PPOConfig.training()'s."""

    model_config = ConfigDict(extra="forbid")
    #: env runners (Ray actors of one CPU each, placed anywhere on the cluster); 0 samples in the driver
    num_env_runners: int = Field(ge=0)
    #: sub-environments of each env runner
    num_envs_per_env_runner: int = Field(ge=1)
    #: one compiled call for a runner's sub-environments (esp_gym's vector env), or one per sub-environment
    batched: bool = True
    #: MeanStdFilter's arguments (observations normalised by running statistics), or None
    normalize: Optional[dict] = None
    env_kwargs: dict = {}
    #: RLlib's DefaultModelConfig (fcnet_hiddens, vf_share_layers, ...)
    model: dict = {}
    training: dict = {}


#: A rate, a clip or a target: a positive, finite number.
Positive = Annotated[Real, Field(gt=0, allow_inf_nan=False)]
#: A loss coefficient: a finite number >= 0.
NonNegative = Annotated[Real, Field(ge=0, allow_inf_nan=False)]
#: A discount or GAE's lambda: a number from 0 to 1.
Fraction = Annotated[Real, Field(ge=0, le=1)]
#: A number of samples or epochs: a whole number >= 1.
Samples = Annotated[Count, Field(ge=1)]


class PPOTraining(BaseModel):
    """Bounds on the PPOConfig.training() values RLlib takes unchecked (``lr=-1`` was accepted, and
    would train away from the objective). Other keys pass: their names are checked by
    :func:`rllib_valid_keys`, their values by RLlib; so are ``lr``'s and ``entropy_coeff``'s
    schedules (RLlib's ``[[step, value], ...]``)."""

    model_config = ConfigDict(extra="allow")
    lr: Optional[Union[Positive, list]] = None
    entropy_coeff: Optional[Union[NonNegative, list]] = None
    gamma: Optional[Fraction] = None
    lambda_: Optional[Fraction] = None
    clip_param: Optional[Positive] = None
    vf_clip_param: Optional[Positive] = None
    grad_clip: Optional[Positive] = None  #: None: no clipping
    kl_coeff: Optional[NonNegative] = None
    kl_target: Optional[Positive] = None
    vf_loss_coeff: Optional[NonNegative] = None
    train_batch_size_per_learner: Optional[Samples] = None
    minibatch_size: Optional[Samples] = None
    num_epochs: Optional[Samples] = None


def _training_keys() -> set:
    from ray.rllib.algorithms.algorithm_config import AlgorithmConfig
    from ray.rllib.algorithms.ppo import PPOConfig

    return (set(inspect.signature(PPOConfig.training).parameters)
            | set(inspect.signature(AlgorithmConfig.training).parameters)) - NOT_TRAINING_KEYS


def rllib_valid_keys(path: tuple) -> Optional[set]:
    """The keys a mapping at dotted ``path`` of an RLlib run config may hold (None: not checked here)."""
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    if path == ():
        return (set(RLlibRunConfig.model_fields) - {"training"}) | _training_keys()
    if path == ("normalize",):
        return NORMALIZE_KEYS
    if path == ("model",):
        return {f.name for f in dataclasses.fields(DefaultModelConfig)}
    if path == ("env_kwargs",):
        return valid_keys("ppo", path, {})  # the environment's arguments, as on the SB3 side
    return None


def rllib_keys(path: tuple, root: dict) -> Optional[set]:
    """:func:`rllib_valid_keys` as an agents.common.KeyRule."""
    return rllib_valid_keys(path)


def apply_rllib_override(tree: dict, item: str) -> None:
    """Set ``KEY=VALUE`` in ``tree`` as agents.common.apply_override does for SB3 (a YAML value,
    a dotted key into nested mappings, each key checked), with the keys of an RLlib run."""
    apply_override(rllib_keys, tree, item, example="model.fcnet_hiddens=[64,64]")


def _build(raw: dict) -> RLlibRunConfig:
    top = set(RLlibRunConfig.model_fields) - {"training"}
    training = {k: v for k, v in raw.items() if k not in top}
    try:
        PPOTraining.model_validate(training)
        return RLlibRunConfig(**{k: v for k, v in raw.items() if k in top}, training=training)
    except ValidationError as err:
        first = {}  # a key's first error: a number-or-schedule key fails both ways
        for e in err.errors():
            first.setdefault(e["loc"][0], e)
        raise ValueError("; ".join(f"{key}: {e['msg'].removeprefix('Value error, ')} (got {e.get('input')!r})"
                                   for key, e in first.items())) from None


def load_rllib_config(task: str, overrides: list, path: Path = CONFIG_FILE, env_id: str = esp_gym.ENV_ID) -> RLlibRunConfig:
    """The run config of ``task`` from ``path`` [env_id][task] with ``KEY=VALUE`` overrides applied
    in order; a bad key or value raises agents.common.ConfigError naming it."""
    data = yaml.load(Path(path).read_text(), Loader=ValueLoader)
    try:
        raw = copy.deepcopy(dict(data[env_id][task]))
    except (KeyError, TypeError):
        raise ConfigError(f"{path} has no entry {env_id}/{task}") from None
    where = f"{path} [{env_id}][{task}]"
    found = first_unknown_key(rllib_keys, raw)
    if found:
        raise ConfigError(f"{where}: {found}")
    try:
        cfg = _build(raw)
    except ValueError as err:
        raise ConfigError(f"{where}: {err}") from None
    for item in overrides:
        apply_rllib_override(raw, item)
        try:
            cfg = _build(raw)
        except ValueError as err:
            raise ConfigError(f"{err} (after {item!r})", item) from None
    return cfg


# -- the environment on the env runners ------------------------------------------------------------

class StepCount:
    """Environment steps taken in this process (an env runner) by the environments
    :func:`make_env` made: what shows where sampling happened."""

    steps = 0


class _CountedVector(gym.vector.VectorWrapper):
    def step(self, actions):
        StepCount.steps += self.num_envs
        return self.env.step(actions)


class _Counted(gym.Wrapper):
    def step(self, action):
        StepCount.steps += 1
        return self.env.step(action)


def make_env(env_config: dict):
    """RLlib's environment creator: ``env_config`` holds the environment's arguments (``task``
    and the options); with ``num_envs`` (RLlib's vector entry point) the batched vector env."""
    from esp_gym.pendulum.vector import ElasticStringPendulumVectorEnv

    kwargs = dict(env_config)
    num_envs = kwargs.pop("num_envs", None)
    if num_envs is None:
        return _Counted(gym.make(esp_gym.ENV_ID, **kwargs))
    return _CountedVector(ElasticStringPendulumVectorEnv(num_envs=num_envs, **kwargs))


def runner_steps(env_runner) -> dict:
    """Run on an env runner (EnvRunnerGroup.foreach_env_runner): its node and the steps it sampled."""
    import ray

    return {"node_id": ray.get_runtime_context().get_node_id(), "env_steps": StepCount.steps}


class ObservationFilter:
    """The env-to-module connector factory: RLlib's MeanStdFilter with ``normalize``'s arguments
    (``update_stats=False`` for evaluation: the statistics stay the checkpoint's)."""

    def __init__(self, normalize: dict, update_stats: bool = True):
        self.normalize, self.update_stats = dict(normalize), update_stats

    def __call__(self, env=None, spaces=None, device=None):
        from ray.rllib.connectors.env_to_module.mean_std_filter import MeanStdFilter

        return MeanStdFilter(**self.normalize, update_stats=self.update_stats)


def ppo_config(cfg: RLlibRunConfig, task: str, seed: int, update_stats: bool = True):
    """RLlib's PPOConfig (new API stack) for a run config; the environment creator is registered
    under :data:`ENV_NAME` (in the cluster's registry, so every env runner finds it)."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.tune.registry import register_env

    register_env(ENV_NAME, make_env)
    config = (PPOConfig()
              .environment(env=ENV_NAME, env_config={"task": task, **cfg.env_kwargs})
              .env_runners(num_env_runners=cfg.num_env_runners, num_envs_per_env_runner=cfg.num_envs_per_env_runner,
                           gym_env_vectorize_mode="vector_entry_point" if cfg.batched else "sync",
                           env_to_module_connector=(ObservationFilter(cfg.normalize, update_stats)
                                                    if cfg.normalize is not None else None))
              .training(**cfg.training)
              .rl_module(model_config=DefaultModelConfig(**cfg.model))
              .debugging(seed=seed, log_level="ERROR"))
    return config


class RLlibPolicy:
    """A checkpoint of :func:`ppo_config`'s PPO as a deterministic policy of agents/evaluate.py
    (``act(obs, setup)``): the checkpoint's observation filter, frozen, its RLModule's
    deterministic action, and its module-to-env connectors (the action clipped to its space)."""

    def __init__(self, checkpoint: str | Path, cfg: RLlibRunConfig, task: str):
        from ray.rllib.core import COMPONENT_ENV_RUNNER, COMPONENT_ENV_TO_MODULE_CONNECTOR, DEFAULT_MODULE_ID
        from ray.rllib.core.rl_module.rl_module import RLModule

        checkpoint = Path(checkpoint)
        env = gym.make(esp_gym.ENV_ID, task=task, **cfg.env_kwargs)
        config = ppo_config(cfg, task, seed=0, update_stats=False)
        self.module = RLModule.from_checkpoint(checkpoint / "learner_group" / "learner" / "rl_module"
                                               / DEFAULT_MODULE_ID)
        self.env_to_module = config.build_env_to_module_connector(env=env)
        self.env_to_module.restore_from_path(checkpoint / COMPONENT_ENV_RUNNER / COMPONENT_ENV_TO_MODULE_CONNECTOR)
        self.module_to_env = config.build_module_to_env_connector(env=env)
        self.spaces = env.observation_space, env.action_space
        env.close()

    def act(self, obs, setup=None) -> np.ndarray:
        import torch
        from ray.rllib.core.columns import Columns
        from ray.rllib.env.single_agent_episode import SingleAgentEpisode

        episode = SingleAgentEpisode(observations=[np.asarray(obs, dtype=np.float32)],
                                     observation_space=self.spaces[0], action_space=self.spaces[1])
        common = dict(rl_module=self.module, episodes=[episode], explore=False, shared_data={})
        with torch.no_grad():
            batch = self.env_to_module(batch={}, **common)
            out = self.module.forward_inference(batch)
        out = self.module_to_env(batch=out, **common)
        return np.asarray(out[Columns.ACTIONS_FOR_ENV][0], dtype=np.float32)
