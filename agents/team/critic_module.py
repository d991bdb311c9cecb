"""The RLlib module of a team with a centralised critic (agents/team/critic.py): one shared
network per agent whose actor reads the agent's own observation and whose critic reads it with the
team's true state appended. Its own module, as it imports torch and RLlib."""
from __future__ import annotations

import torch.nn as nn
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.core.rl_module.torch import TorchRLModule


def _mlp(inputs: int, hiddens: list, outputs: int, activation: str, last_gain: float) -> nn.Sequential:
    act = {"tanh": nn.Tanh, "relu": nn.ReLU}[activation]
    layers, width = [], inputs
    for h in hiddens:
        layers += [nn.Linear(width, h), act()]
        width = h
    last = nn.Linear(width, outputs)
    nn.init.orthogonal_(last.weight, gain=last_gain)  # a small first action: the baseline's, for a residual
    nn.init.zeros_(last.bias)
    return nn.Sequential(*layers, last)


class CentralCriticModule(TorchRLModule, ValueFunctionAPI):
    """The shared module of a team with a centralised critic (module docstring). model_config:
    ``actor_inputs`` (int), ``fcnet_hiddens`` (list), ``fcnet_activation`` (``tanh`` or
    ``relu``). The actor's output is a diagonal Gaussian's (mean, log std), RLlib's default for a
    box of actions."""

    def setup(self):
        cfg = self.model_config
        self.actor_inputs = int(cfg["actor_inputs"])
        hiddens, activation = list(cfg.get("fcnet_hiddens", [128, 128])), cfg.get("fcnet_activation", "tanh")
        self.pi = _mlp(self.actor_inputs, hiddens, 2 * self.action_space.shape[0], activation, 0.01)
        self.vf = _mlp(self.observation_space.shape[0], hiddens, 1, activation, 1.0)

    def _forward(self, batch, **kwargs):
        return {Columns.ACTION_DIST_INPUTS: self.pi(batch[Columns.OBS][..., :self.actor_inputs])}

    def _forward_train(self, batch, **kwargs):
        return self._forward(batch)

    def compute_values(self, batch, embeddings=None):
        return self.vf(batch[Columns.OBS]).squeeze(-1)
