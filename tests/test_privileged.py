"""The asymmetric actor-critic (agents/privileged.py): the critic sees the simulator's state, the
actor only the observation, and a deployed policy needs only the observation."""
import numpy as np
import pytest
import torch

from agents.privileged import PrivilegedVecEnv, privileged_size
from agents.train import Settings, prepare, train
from esp_gym.kernels.env.arrays import HOOK_OBSERVATION
from esp_gym.pendulum.sb3_vector import ElasticStringPendulumSB3VecEnv

HARD_HOOK = ["env_kwargs={observation: hook, sensor_noise: 1.0, wind: {speed: 4.0}}"]
TINY = ["total_timesteps=256", "n_envs=2", "n_steps=128", "batch_size=128", "n_epochs=1"]


def test_privileged_entries_are_the_simulators_state():
    venv = ElasticStringPendulumSB3VecEnv(num_envs=2, task="stabilize", observation="hook", wind={"speed": 4.0})
    venv.seed(3)
    wrapped = PrivilegedVecEnv(venv, venv.control)
    obs = wrapped.reset()
    hook = venv.observation_space.shape[0]
    assert obs.shape == (2, hook + privileged_size(venv.control))
    assert np.array_equal(obs[:, hook:hook + venv.control.observation.shape[-1]],
                          venv.control.observation.astype(np.float32))
    for _ in range(3):
        obs, _, _, _ = wrapped.step(np.zeros((2, 6), np.float32))
    assert np.array_equal(obs[:, -venv.control.disturbance.shape[-1]:], venv.control.disturbance.astype(np.float32))


def test_actor_ignores_the_privileged_entries_and_the_critic_reads_them(tmp_path):
    p = prepare(Settings(task="stabilize", runs=str(tmp_path), run_name="p", progress=False,
                         set=TINY + HARD_HOOK + ["privileged_critic=true", "frame_stack=2"]))
    policy = p.model.policy
    assert policy.frame_size > policy.actor_size == HOOK_OBSERVATION.size
    obs = np.random.default_rng(0).standard_normal((4,) + p.model.observation_space.shape).astype(np.float32)
    scrambled = obs.copy()
    for frame in range(2):  # change only the privileged entries of each stacked frame
        start = frame * policy.frame_size + policy.actor_size
        scrambled[:, start:(frame + 1) * policy.frame_size] = 5.0
    with torch.no_grad():
        a, _ = p.model.predict(obs, deterministic=True)
        b, _ = p.model.predict(scrambled, deterministic=True)
        v_a = policy.predict_values(torch.as_tensor(obs))
        v_b = policy.predict_values(torch.as_tensor(scrambled))
    assert np.array_equal(a, b)
    assert not torch.allclose(v_a, v_b)  # negative control: the critic does read them
    changed = obs.copy()
    changed[:, 0] += 1.0  # and the actor does read the observation
    with torch.no_grad():
        assert not np.array_equal(p.model.predict(changed, deterministic=True)[0], a)


def test_trained_asymmetric_policy_acts_on_the_observation_alone(tmp_path):
    from agents.evaluate import SB3Policy

    run = train(Settings(task="stabilize", runs=str(tmp_path), run_name="p", progress=False, eval_freq=10_000,
                         reference_episodes=1, set=TINY + HARD_HOOK + ["privileged_critic=true"]))
    policy = SB3Policy(run / "model.zip")
    assert (policy.model.policy.frame_size, policy.model.policy.actor_size) == (policy.input_size, HOOK_OBSERVATION.size)
    venv = ElasticStringPendulumSB3VecEnv(num_envs=1, task="stabilize", observation="hook", wind={"speed": 4.0})
    venv.seed(1)
    obs = venv.reset()[0]
    padded = np.concatenate([obs, np.zeros(policy.input_size - obs.size)])
    expected, _ = policy.model.predict(policy.normalization.normalize_obs(padded).astype(np.float32),
                                       deterministic=True)
    assert np.allclose(policy.act(obs, venv.setup), expected, rtol=0, atol=1e-7)


def test_privileged_critic_needs_ppo(tmp_path):
    from agents.cli import SettingsError

    with pytest.raises(SettingsError, match="privileged_critic"):
        prepare(Settings(algo="sac", task="stabilize", runs=str(tmp_path),
                         set=["total_timesteps=256", "privileged_critic=true"]))


def test_a_residual_policy_starts_at_its_base(tmp_path):
    p = prepare(Settings(task="stabilize", runs=str(tmp_path), run_name="r", progress=False,
                         set=TINY + HARD_HOOK + ["residual=pd"]))
    obs = np.random.default_rng(1).standard_normal((3,) + p.model.observation_space.shape).astype(np.float32)
    assert np.array_equal(p.model.predict(obs, deterministic=True)[0], np.zeros((3, 6), np.float32))
