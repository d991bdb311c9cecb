"""Residual policies (agents/residual.py): training steps the environment with the baseline's
action plus the network's, and the evaluated policy adds the same baseline back."""
import numpy as np

from agents.baselines.registry import baseline
from agents.residual import ResidualVecEnv, residual_for
from esp_gym.pendulum.sb3_vector import ElasticStringPendulumSB3VecEnv


def vec_env():
    venv = ElasticStringPendulumSB3VecEnv(num_envs=3, task="transport", observation="hook", sensor_noise=1.0)
    venv.seed(11)
    return venv


def summed_rewards(wrapped, value: float, steps: int = 60):
    """Step a ResidualVecEnv ``steps`` times with the constant network action ``value``: the summed
    rewards and the last step's (obs, dones, infos)."""
    returns = np.zeros(wrapped.num_envs)
    for _ in range(steps):
        obs, rewards, dones, infos = wrapped.step(np.full((wrapped.num_envs,) + wrapped.action_space.shape, value,
                                                          np.float32))
        returns += rewards
    return returns, obs, dones, infos


def assert_zero_network_is_the_base(wrapped, venv, seed: int, single: list, steps: int = 60):
    """From its reset, ``wrapped`` with a zero network gives the base's own episodes' returns
    ``single`` (float32 rewards summed) and terminal observations of its shape; a small constant
    residual, reset to the same seed, does not (the negative control)."""
    returns, obs, dones, infos = summed_rewards(wrapped, 0.0, steps)
    assert dones.all() and all(info["terminal_observation"].shape == obs.shape[1:] for info in infos)
    assert np.allclose(returns, single, rtol=1e-5, atol=0)
    venv.seed(seed)
    wrapped.reset()
    assert not np.allclose(summed_rewards(wrapped, 0.05, steps)[0], single, rtol=1e-3, atol=0)


def test_residual_env_steps_with_the_baseline_added():
    pd = baseline("transport")
    wrapped, plain = ResidualVecEnv(vec_env(), pd, vec_env().setup), vec_env()
    obs_w, obs_p = wrapped.reset(), plain.reset()
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = rng.uniform(-0.3, 0.3, (3, 6)).astype(np.float32)
        total = np.clip(a + pd.act(obs_p, plain.setup), -1.0, 1.0).astype(np.float32)
        obs_w, r_w, _, _ = wrapped.step(a)
        obs_p, r_p, _, _ = plain.step(total)
        assert np.array_equal(obs_w, obs_p) and np.array_equal(r_w, r_p)
    # negative control: without the base the same actions give other states
    other = vec_env()
    other.reset()
    assert not np.array_equal(other.step(a)[0], obs_w)


def test_trained_residual_policy_adds_its_base(tmp_path):
    from agents.evaluate import SB3Policy
    from agents.train import Settings, train

    run = train(Settings(task="transport", runs=str(tmp_path), run_name="res", progress=False, eval_freq=10_000,
                         reference_episodes=1, set=["total_timesteps=256", "n_envs=2", "n_steps=128",
                                                    "batch_size=128", "n_epochs=1", "residual=pd",
                                                    "env_kwargs={observation: hook}"]))
    assert residual_for(run / "model.zip") is baseline("transport")
    policy = SB3Policy(run / "model.zip")
    venv = vec_env()
    obs = venv.reset()[0]
    net, _ = policy.model.predict(policy.normalization.normalize_obs(obs).astype(np.float32), deterministic=True)
    expected = np.clip(net + baseline("transport").act(obs, venv.setup), -1.0, 1.0)
    assert np.allclose(policy.act(obs, venv.setup), expected, rtol=0, atol=1e-7)
    assert not np.allclose(expected, np.clip(net, -1, 1))  # the base does act


def test_training_episodes_end_at_episode_steps_and_evaluations_run_full_episodes(tmp_path):
    """``episode_steps``: the training environments truncate their episodes after that many steps
    (monitor.csv), the evaluations keep the environment's 500 (evaluations.npz)."""
    import csv

    from agents.train import Settings, train

    run = train(Settings(task="transport", runs=str(tmp_path), run_name="short", progress=False, eval_freq=256,
                         eval_episodes=1, reference_episodes=1,
                         set=["total_timesteps=256", "n_envs=2", "n_steps=128", "batch_size=128", "n_epochs=1",
                              "residual=lqr", "episode_steps=40"]))
    with open(run / "monitor.csv") as f:
        lengths = [int(row["l"]) for row in csv.DictReader(line for line in f if not line.startswith("#"))]
    assert len(lengths) >= 4 and set(lengths) == {40}
    assert set(np.load(run / "evaluations.npz")["ep_lengths"].ravel()) == {500}


def test_lqg_residual_env_with_a_zero_network_is_the_lqg():
    """ResidualVecEnv over the scheduled LQG (one filter per environment, told the applied
    action) and a zero network action reproduces the LQG's own episodes on the same seeds (the
    batched and single environments are the same bit for bit); the observation carries the
    filter's features (its estimate and the reference's context: feed-forward, velocity and
    displacement ahead, agents/baselines/lqg.py), and so do terminal observations."""
    from agents.evaluate import run_episodes
    from agents.baselines.lqr import REFERENCE_CONTEXT
    from agents.residual import base_policy
    from esp_gym.kernels.env.arrays import TARGET

    kwargs = {"preset": "hard"}
    venv = ElasticStringPendulumSB3VecEnv(num_envs=2, task="track", max_episode_steps=60, **kwargs)
    venv.seed(500)
    wrapped = ResidualVecEnv(venv, base_policy("lqg", "track", kwargs), venv.setup)
    obs = wrapped.reset()
    law = wrapped.batch.copies[0]
    features = law.features
    assert features.size == law.estimate.size + REFERENCE_CONTEXT.size
    assert obs.shape == (2, venv.observation_space.shape[0] + features.size)
    assert np.array_equal(obs[0, -features.size:], features.astype(np.float32))
    context = features[law.estimate.size:]
    target = venv.control.target[0]
    assert np.allclose(context[REFERENCE_CONTEXT["reference_velocity"]], target[TARGET["velocity"]])
    assert np.linalg.norm(context[REFERENCE_CONTEXT["reference_ahead"]]) > 0.01  # the curve moves on
    single = [e.ret for e in run_episodes(base_policy("lqg", "track", kwargs), "track", 2, seed=500,
                                          env_kwargs={**kwargs, "max_episode_steps": 60})]
    assert_zero_network_is_the_base(wrapped, venv, 500, single)


def test_the_lqr_base_is_the_registrys_lqr_on_the_nominal_scene_and_refuses_elsewhere():
    """residual=lqr: one design for the nominal scene, the registry's per-episode LQR's actions on its
    episodes (a nominal configuration draws no scene); refused, by name, where one design would not
    be that LQR (randomize, hook observation) or where there is no LQR (the winch's tasks)."""
    import gymnasium as gym
    import pytest

    import esp_gym
    from agents.baselines.registry import baselines
    from agents.residual import base_policy

    env = gym.make(esp_gym.ENV_ID, task="transport").unwrapped
    fixed, per_episode = base_policy("lqr", "transport"), baselines("transport")["lqr"]
    for seed in (0, 1):
        obs, _ = env.reset(seed=seed)
        per_episode.reset(env)
        for _ in range(5):
            assert np.array_equal(fixed.act(obs, env.setup), per_episode.act(obs, env.setup))
            obs, *_ = env.step(fixed.act(obs, env.setup))
    for task, kwargs, message in (("stabilize", {"randomize": True}, "no randomize"),
                                  ("stabilize", {"observation": "hook"}, "full observation"),
                                  ("lift", {}, "task 'lift' has none")):
        with pytest.raises(ValueError, match=message):
            base_policy("lqr", task, kwargs)


def test_the_track_lqr_base_follows_each_episodes_reference_as_the_registrys_lqr():
    """residual=lqr on track: ResidualVecEnv with one LQRTracker per environment (each started on its
    own episode's reference) and a zero network reproduces the registry's per-episode LQR's returns
    on the same seeds, and the observation carries the reference's context; a small constant
    residual (the negative control) changes them."""
    from agents.baselines.lqr import REFERENCE_CONTEXT
    from agents.baselines.registry import baselines
    from agents.evaluate import run_episodes
    from agents.residual import base_policy
    from esp_gym.kernels.env.arrays import TARGET

    venv = ElasticStringPendulumSB3VecEnv(num_envs=2, task="track", max_episode_steps=60)
    venv.seed(700)
    wrapped = ResidualVecEnv(venv, base_policy("lqr", "track"), venv.setup)
    obs = wrapped.reset()
    assert obs.shape == (2, venv.observation_space.shape[0] + REFERENCE_CONTEXT.size)
    context = obs[1, -REFERENCE_CONTEXT.size:]
    assert np.allclose(context[REFERENCE_CONTEXT["reference_velocity"]],
                       venv.control.target[1][TARGET["velocity"]], atol=1e-6)
    single = [e.ret for e in run_episodes(baselines("track")["lqr"], "track", 2, seed=700,
                                          env_kwargs={"max_episode_steps": 60})]
    assert_zero_network_is_the_base(wrapped, venv, 700, single)


def test_a_drone_cascade_on_track_tells_its_network_the_reference():
    """residual=geometric on the drone's track (full observation): the cascade, which holds no
    reference, runs one ReferenceContext per environment; with a zero network the returns are the
    cascade's own, and the observation carries the reference's velocity (the TARGET's), its
    acceleration (the velocity's central difference over two control steps, to 1e-3 m/s^2) and its
    displacement ahead; a small constant residual (the negative control) changes the returns."""
    from agents.baselines.registry import baselines
    from agents.evaluate import run_episodes
    from agents.residual import TRACK_CONTEXT, base_policy
    from esp_gym.kernels.env.arrays import TARGET

    kwargs = {"scene": "quadrotor_load", "actuation": "thrust_rates"}
    venv = ElasticStringPendulumSB3VecEnv(num_envs=2, task="track", max_episode_steps=60, **kwargs)
    venv.seed(700)
    wrapped = ResidualVecEnv(venv, base_policy("geometric", "track", kwargs), venv.setup)
    size = sum(n for _, n in TRACK_CONTEXT)
    obs = wrapped.reset()
    assert obs.shape == (2, venv.observation_space.shape[0] + size)
    velocities, accelerations = [], []
    for _ in range(3):
        context = obs[1, -size:].astype(np.float64)
        assert np.allclose(context[:3], venv.control.target[1][TARGET["velocity"]], atol=1e-6)
        velocities.append(context[:3])
        accelerations.append(context[3:6])
        obs = wrapped.step(np.zeros((2, 4), np.float32))[0]
    dt = venv.setup.control_period
    assert np.allclose((velocities[2] - velocities[0]) / (2 * dt), accelerations[1], atol=1e-3)
    assert np.abs(accelerations[1]).max() > 0.05
    venv.seed(700)
    wrapped.reset()
    single = [e.ret for e in run_episodes(baselines("track", kwargs)["geometric"], "track", 2, seed=700,
                                          env_kwargs={"max_episode_steps": 60, **kwargs})]
    assert_zero_network_is_the_base(wrapped, venv, 700, single)


def test_the_critic_warmup_holds_the_actor_while_the_critic_learns():
    """critic_warmup (agents/common.py CriticWarmup): two PPO updates held from the start leave every
    actor parameter as it was and move the critic's; without the hold (the negative control) the
    actor moves too."""
    import torch
    from stable_baselines3 import PPO

    from agents.common import CriticWarmup

    def trained(hold_steps):
        torch.manual_seed(0)
        model = PPO("MlpPolicy", ElasticStringPendulumSB3VecEnv(num_envs=2, task="stabilize"), n_steps=32,
                    batch_size=64, n_epochs=2, seed=0, device="cpu")
        warmup = CriticWarmup(hold_steps)
        warmup.init_callback(model)
        actor = [p.detach().clone() for p in warmup._actor()]
        critic = [p.detach().clone() for p in model.policy.mlp_extractor.value_net.parameters()]
        model.learn(total_timesteps=128, callback=warmup)
        moved = lambda before, now: max(float((a - b).abs().max()) for a, b in zip(before, now))
        return (moved(actor, warmup._actor()),
                moved(critic, list(model.policy.mlp_extractor.value_net.parameters())))

    held_actor, held_critic = trained(10 ** 9)
    assert held_actor == 0.0 and held_critic > 0.0
    free_actor, _ = trained(0)
    assert free_actor > 0.0
