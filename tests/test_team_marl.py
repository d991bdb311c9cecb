"""The team's PettingZoo face as multi-agent libraries read it (docs/team.md, "Multi-agent
libraries"): TorchRL's PettingZooWrapper rolls it out (every info a number of fixed shape, the same
keys at reset and at every step, the team's state with its space), skrl's IPPO and MAPPO train on
it for a few steps (the spaces by name, MAPPO's critic on ``state()``), and SuperSuit's vector env
trains Stable-Baselines3's PPO on it. Negative control: an info holding a nested dict is what
TorchRL cannot read."""
import warnings

import numpy as np
import pytest
import torch

from esp_gym.team import parallel_env
from esp_gym.errors import termination_reason
from esp_gym.kernels.status import TERM_COLLISION
from esp_gym.team.parallel import ElasticStringTeamParallelEnv

warnings.filterwarnings("ignore", category=DeprecationWarning)


def test_every_agents_info_has_the_same_numbers_at_reset_and_at_each_step():
    env = parallel_env(team=3, actuation="thrust_rates")
    _, first = env.reset(seed=1)
    shapes = {k: np.shape(v) for k, v in first["pivot_2"].items()}
    for _ in range(3):
        *_, infos = env.step({a: np.zeros(4, np.float32) for a in env.agents})
        for a in env.possible_agents:
            assert {k: np.shape(v) for k, v in infos[a].items()} == shapes
            assert all(np.issubdtype(np.asarray(v).dtype, np.number) for v in infos[a].values())
    assert shapes["applied_action"] == (4,) and first["pivot_2"]["agent"] == 2
    assert env.state().shape == env.state_space.shape and env.termination_reason == ""
    assert first["pivot_0"]["termination"] == 0 and termination_reason(0) == ""


def test_a_collision_ends_with_its_code_and_its_reason():
    env = parallel_env(team=2)
    env.reset(seed=0)
    toward = {"pivot_0": np.array([-1.0, 0.0, 0.0], np.float32), "pivot_1": np.array([1.0, 0.0, 0.0], np.float32)}
    for _ in range(200):
        _, _, terminated, _, infos = env.step(toward)
        if terminated["pivot_0"]:
            break
    assert env.termination_reason == "collision" == termination_reason(infos["pivot_1"]["termination"])
    assert infos["pivot_0"]["termination"] == TERM_COLLISION


def test_torchrl_rolls_the_team_out_with_its_infos_and_state():
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    env = PettingZooWrapper(parallel_env(team=2), return_state=True)
    td = env.rollout(3)
    group = td["next", "pivot"] if ("next", "pivot") in td.keys(True) else td["next", "agents"]
    assert group["observation"].shape[:2] == (3, 2) and td["next", "state"].shape == (3, 60)
    assert group["info", "tension"].shape == (3, 2, 3) and torch.isfinite(group["info", "reward_tilt"]).all()


class NestedInfo(ElasticStringTeamParallelEnv):
    """Negative control: a nested dict in every step's infos, as the team's infos were."""

    def step(self, actions):
        out = super().step(actions)
        for info in out[-1].values():
            info["agent_load_position"] = {"nested": 1.0}
        return out


def test_torchrl_cannot_read_a_nested_info():
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    with pytest.raises((RuntimeError, TypeError, ValueError)):
        PettingZooWrapper(NestedInfo(team=2)).rollout(2)


def _skrl_models(env, critic_reads_state: bool):
    from skrl.models.torch import DeterministicMixin, GaussianMixin, Model

    class Policy(GaussianMixin, Model):
        def __init__(self, observation_space, action_space):
            Model.__init__(self, observation_space=observation_space, action_space=action_space, device="cpu")
            GaussianMixin.__init__(self, clip_actions=True)
            self.net = torch.nn.Linear(self.num_observations, self.num_actions)
            self.log_std = torch.nn.Parameter(torch.zeros(self.num_actions))

        def compute(self, inputs, role=""):
            return self.net(inputs["observations"]), {"log_std": self.log_std}

    class Value(DeterministicMixin, Model):
        def __init__(self, observation_space, state_space):
            Model.__init__(self, observation_space=observation_space, state_space=state_space, device="cpu")
            DeterministicMixin.__init__(self)
            self.net = torch.nn.Linear(self.num_states if critic_reads_state else self.num_observations, 1)

        def compute(self, inputs, role=""):
            return self.net(inputs["states"] if critic_reads_state else inputs["observations"]), {}

    return {a: {"policy": Policy(env.observation_space(a), env.action_space(a)),
                "value": Value(env.observation_space(a), env.state_space(a))} for a in env.possible_agents}


@pytest.mark.parametrize("algorithm", ["ippo", "mappo"])
def test_skrl_trains_on_the_team_for_a_few_steps(algorithm):
    from skrl.envs.wrappers.torch import wrap_env
    from skrl.memories.torch import RandomMemory
    from skrl.multi_agents.torch.ippo import IPPO
    from skrl.multi_agents.torch.mappo import MAPPO
    from skrl.trainers.torch import SequentialTrainer

    env = wrap_env(parallel_env(team=2), wrapper="pettingzoo")
    rollouts = 4
    memories = {a: RandomMemory(memory_size=rollouts, num_envs=env.num_envs, device="cpu")
                for a in env.possible_agents}
    kind = IPPO if algorithm == "ippo" else MAPPO
    agent = kind(possible_agents=env.possible_agents, models=_skrl_models(env, algorithm == "mappo"),
                 memories=memories, observation_spaces=env.observation_spaces, state_spaces=env.state_spaces,
                 action_spaces=env.action_spaces, device="cpu",
                 cfg={"rollouts": rollouts, "learning_epochs": 1, "mini_batches": 1,
                      # skrl 2.1 reads an empty dict as per-agent settings missing every agent
                      **{f"{what}_kwargs": {a: {} for a in env.possible_agents} for what in
                         ("learning_rate_scheduler", "observation_preprocessor", "state_preprocessor",
                          "value_preprocessor")}})
    before = {a: [p.detach().clone() for p in agent.models[a]["policy"].parameters()] for a in env.possible_agents}
    SequentialTrainer(env=env, agents=agent, cfg={"timesteps": 2 * rollouts, "headless": True,
                                                  "disable_progressbar": True,
                                                  "close_environment_at_exit": False}).train()
    moved = [not all(torch.equal(b, p) for b, p in zip(before[a], agent.models[a]["policy"].parameters()))
             for a in env.possible_agents]
    assert all(moved)  # each agent's policy took its updates


def test_supersuit_vectorises_the_team_for_stable_baselines3():
    import supersuit
    from stable_baselines3 import PPO

    venv = supersuit.concat_vec_envs_v1(supersuit.pettingzoo_env_to_vec_env_v1(parallel_env(team=2)), 1,
                                        base_class="stable_baselines3")
    assert venv.num_envs == 2  # one per agent, sharing the policy
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, n_epochs=1, policy_kwargs={"net_arch": [8]},
                device="cpu")
    model.learn(32)
    assert model.num_timesteps >= 32
