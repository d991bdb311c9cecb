"""agents/distill.py: the teacher's episodes are the optimised feed-forward's episodes, recorded as
the student sees them, and the fitted actor, shipped with its statistics, acts as the teacher did."""
import json

import numpy as np
import pytest

from agents.distill import teacher_episode
from agents.residual import base_policy


def test_the_teacher_records_the_students_inputs_and_the_feedforward_it_applied():
    """Replaying base + recorded target gives the optimised return (>= the base's); the target is
    zero off the driven axes; the inputs are observation + base features (track: the reference's
    context), the first one the reset's."""
    import gymnasium as gym

    import esp_gym
    from agents.baselines.lqr import REFERENCE_CONTEXT

    inputs, targets, gain = teacher_episode("track", "lqr", None, 300_123, 3, 15)
    assert gain >= 0.0 and targets.shape == (500, 6) and np.all(targets[:, 3:] == 0.0)
    env = gym.make(esp_gym.ENV_ID, task="track")
    obs, _ = env.reset(seed=300_123)
    assert inputs.shape == (500, obs.size + REFERENCE_CONTEXT.size)
    np.testing.assert_array_equal(inputs[0, :obs.size], obs)
    law = base_policy("lqr", "track")
    law.reset(env.unwrapped)
    replay, base = 0.0, 0.0
    for k in range(500):
        obs, r, *_ = env.step(np.clip(law.act(obs, env.unwrapped.setup) + targets[k], -1, 1))
        replay += r
    obs, _ = env.reset(seed=300_123)
    law.reset(env.unwrapped)
    for k in range(500):
        obs, r, *_ = env.step(law.act(obs, env.unwrapped.setup))
        base += r
    assert replay == pytest.approx(base + gain, abs=1e-9)


def test_a_distilled_run_ships_an_actor_that_acts_as_its_teacher(tmp_path):
    """``distill_episodes``: the shipped model (SB3Policy: its statistics, its base) acts as base +
    the teacher's feed-forward on the teacher's inputs, to the fit's error; the statistics are the
    teacher data's; a model that was not distilled acts as its base (negative control)."""
    from agents.distill import DISTILL_SEED
    from agents.evaluate import SB3Policy
    from agents.train import Settings, train

    common = ["total_timesteps=256", "n_envs=2", "n_steps=128", "batch_size=128", "n_epochs=1", "residual=lqr",
              "critic_warmup=256"]
    runs = {}
    for name, extra in (("taught", ["distill_episodes=2", "distill_evaluations=25", "distill_knots=3"]), ("plain", [])):
        runs[name] = train(Settings(task="transport", seed=1, runs=str(tmp_path), run_name=name, progress=False,
                                    eval_freq=10_000, reference_episodes=1, set=common + extra))
    summary = json.loads((runs["taught"] / "training.json").read_text())
    assert summary["distill_episodes"] == 2 and summary["distill_fit_loss"] < 0.1 * summary["distill_target_mean_square"]
    inputs, targets, _ = teacher_episode("transport", "lqr", None, DISTILL_SEED + 1000 * 1, 3, 25)  # the run's first
    obs = inputs[:, :22]
    import gymnasium as gym

    import esp_gym

    setup = gym.make(esp_gym.ENV_ID, task="transport").unwrapped.setup
    base = base_policy("lqr", "transport")
    taught, plain = SB3Policy(runs["taught"] / "model.zip"), SB3Policy(runs["plain"] / "model.zip")
    expected = np.clip(base.act(obs, setup) + targets, -1, 1)
    residual = np.abs(targets).max()
    assert residual > 1e-3
    assert np.abs(taught.act(obs, setup) - expected).max() < 0.3 * residual
    assert np.abs(plain.act(obs, setup) - base.act(obs, setup)).max() < 1e-6  # started at the base, held
    assert np.abs(plain.act(obs, setup) - expected).max() > 0.5 * residual


def test_distillation_refuses_what_it_cannot_fit(tmp_path):
    from agents.train import Settings, SettingsError, prepare

    with pytest.raises(SettingsError, match="distill_episodes fits a residual PPO actor"):
        prepare(Settings(task="transport", runs=str(tmp_path), run_name="x", progress=False,
                         set=["distill_episodes=2", "residual=lqr", "privileged_critic=true"]))
    with pytest.raises(SettingsError, match="residual=None"):
        prepare(Settings(task="transport", runs=str(tmp_path), run_name="y", progress=False, set=["distill_episodes=2"]))
