"""The ``track`` task (esp_gym/pendulum/tasks.py, kernels/env/track_curve.py): the reference is the documented
circle or figure-eight, the environment's targets follow it in time, the observed velocities are
relative to it, and following it pays. (Batched against single envs: tests/test_env.py.)"""
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import esp_gym  # noqa: F401  (registers the env)
from esp_gym.kernels.env.arrays import OBSERVATION, TARGET
from esp_gym.kernels.env.track_curve import reference_at
from esp_gym.pendulum.tasks import TRACK_PERIOD, TRACK_SIZE, track_reference

ENV_ID = "ElasticStringPendulum-v0"


def _plane(t):
    """The pivot target's offset from the centre in the curve's own (unrotated) frame."""
    x, y, _ = t[TARGET["pivot"]] - t[TARGET["centre"]]
    c, s = math.cos(t[TARGET.scalar("orientation")]), math.sin(t[TARGET.scalar("orientation")])
    return c * x + s * y, -s * x + c * y


@pytest.mark.parametrize("seed", range(8))
def test_reference_is_a_circle_or_a_figure_eight_of_the_documented_family(seed):
    t = track_reference(np.random.default_rng(seed), depth=1.1)
    a = t[TARGET["amplitude"]][0]
    omega = t[TARGET.scalar("rate")]
    period = 2 * math.pi / abs(omega)
    assert TRACK_SIZE[0] <= a <= TRACK_SIZE[1] and TRACK_PERIOD[0] <= period <= TRACK_PERIOD[1]
    eight = t[TARGET.scalar("harmonic")] == 2.0
    for time in np.linspace(0.0, period, 17):
        reference_at(t, time)
        x, y = _plane(t)
        if eight:  # Gerono's lemniscate: a^2 y^2 = x^2 (a^2 - x^2)
            assert a * a * y * y == pytest.approx(x * x * (a * a - x * x), abs=1e-12)
        else:
            assert math.hypot(x, y) == pytest.approx(a, rel=1e-12)
        load = t[TARGET["load"]] - t[TARGET["pivot"]]
        assert np.allclose(load, [0.0, 0.0, 1.1], atol=1e-15) and t[TARGET["pivot"]][2] == 0.0
    start = track_reference(np.random.default_rng(seed), depth=1.1)
    reference_at(t, period)  # closed: back at the start after a period
    np.testing.assert_allclose(t[TARGET["pivot"]], start[TARGET["pivot"]], atol=1e-12)


def test_reference_velocity_is_the_derivative_of_its_position():
    t = track_reference(np.random.default_rng(3), depth=1.0)
    eps = 1e-6
    for time in (0.3, 1.7, 4.2):
        reference_at(t, time + eps)
        ahead = t[TARGET["pivot"]].copy()
        reference_at(t, time - eps)
        behind = t[TARGET["pivot"]].copy()
        reference_at(t, time)
        np.testing.assert_allclose(t[TARGET["velocity"]], (ahead - behind) / (2 * eps), atol=1e-8)


def test_track_targets_follow_the_reference_in_time_and_velocities_are_relative():
    env = gym.make(ENV_ID, task="track").unwrapped
    obs, _ = env.reset(seed=5)
    t0 = env.control.target.copy()
    np.testing.assert_allclose(env.pivot_position(), t0[TARGET["pivot"]], atol=1e-12)  # starts on it
    for k in range(1, 31):
        obs, *_ = env.step(np.zeros(6))
    expected = t0.copy()
    reference_at(expected, 30 * env.setup.control_period)
    np.testing.assert_allclose(env.control.target, expected, rtol=1e-12, atol=1e-12)
    assert np.linalg.norm(env.target[:3] - t0[TARGET["pivot"]]) > 0.05  # it moved
    pivot_v = env.sim.buffers.diag.V[0] - expected[TARGET["velocity"]]  # the step's diagnostics
    np.testing.assert_allclose(obs[OBSERVATION["pivot_velocity"]], pivot_v, rtol=1e-6, atol=1e-6)


def test_fixed_tasks_targets_do_not_move():
    env = gym.make(ENV_ID, task="transport").unwrapped
    env.reset(seed=1)
    before = env.control.target.copy()
    for _ in range(5):
        env.step(np.zeros(6))
    assert np.array_equal(before, env.control.target) and before[TARGET.scalar("rate")] == 0.0


def test_track_reward_is_on_the_load_error_from_the_moving_reference():
    """info["reward_load_position"] = w tol(|load - reference's load target now|, 0.2 m), and
    the load velocity term uses the velocity relative to the reference's."""
    env = gym.make(ENV_ID, task="track").unwrapped
    env.reset(seed=2)
    task = env.setup.task
    for _ in range(40):
        _, _, _, _, info = env.step(np.zeros(6))
    error = np.linalg.norm(env.load_position() - env.target[3:])
    assert error > 0.05  # the reference went on without the load
    expected = task.w_load_position / (1 + (error / task.scale_position) ** 2)
    assert info["reward_load_position"] == pytest.approx(expected, rel=1e-12)
    relative = env.control.observation[OBSERVATION["load_velocity"]]
    expected = task.w_load_velocity / (1 + (np.linalg.norm(relative) / task.scale_velocity) ** 2)
    assert info["reward_load_velocity"] == pytest.approx(expected, rel=1e-12)


def test_env_checkers_pass_with_track():
    gym_check_env(gym.make(ENV_ID, task="track").unwrapped, skip_render_check=True)
    sb3_check_env(gym.make(ENV_ID, task="track", preset="hard").unwrapped, warn=True)
