"""ElasticStringPendulum-v0 with a winch (``winch=True``): the 7th action reels, the observation
ends with the length, the tasks lift and lower, and the balances of the compiled step."""
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import esp_gym  # noqa: F401  (registers the environment)
from esp_gym.kernels.env.arrays import TARGET, WINCH_OBSERVATION
from esp_gym.kernels.env.track_curve import reference_at
from esp_gym.pendulum.tasks import hanging_depth

ENV_ID = "ElasticStringPendulum-v0"


def reel(a: float) -> np.ndarray:
    """The action that holds the system up and reels at ``a`` (x max_speed)."""
    action = np.zeros(7)
    action[6] = a
    return action


@pytest.mark.parametrize("task", ["lift", "lower", "stabilize"])
def test_the_winch_adds_an_action_and_an_observation(task):
    env = gym.make(ENV_ID, winch=True, task=task)
    assert env.action_space == gym.spaces.Box(-1, 1, (7,), np.float32)
    assert env.observation_space.shape == (WINCH_OBSERVATION.size,)
    assert env.unwrapped.observation_structure["unstretched_length"] == slice(22, 23)
    obs, _ = env.reset(seed=1)
    length = env.unwrapped.scene.string.length
    assert obs[-1] == np.float32(length)
    check_env(env.unwrapped, skip_render_check=True)
    hook = gym.make(ENV_ID, winch=True, task=task, observation="hook")
    assert hook.observation_space.shape == (13,) and hook.unwrapped.observation_structure["unstretched_length"] == slice(12, 13)


def test_the_reel_action_sets_the_speed_and_the_winch_stops_at_its_range():
    """Reel out at full speed (1 m/s x 20 ms per step): 2 cm per step until twice the length, then
    the winch stops there; the energy balance of the compiled step closes (E - E0 - W - W_winch,
    the inputs' and the winch's work, measured 2e-4 of the winch's work at the environment's h)."""
    env = gym.make(ENV_ID, winch=True, task="lower")
    env.reset(seed=2)
    sim = env.unwrapped.sim
    l0 = sim.winch.length
    obs, *_ = env.step(reel(1.0))
    assert obs[-1] == pytest.approx(l0 + 0.02, abs=1e-6)
    for _ in range(150):
        obs, r, term, trunc, info = env.step(reel(1.0))
        assert not term, info
    d = sim.diagnostics()
    assert d["unstretched_length"] == 2.0 * l0 and obs[-1] == np.float32(2.0 * l0)
    assert abs(d["energy_balance_residual"]) < 1e-3 * abs(d["winch_work"])
    obs, *_ = env.step(reel(-0.5))
    assert obs[-1] == pytest.approx(2.0 * l0 - 0.01, abs=1e-6)


def test_a_stiff_string_reels_with_the_implicit_scheme_in_the_environment():
    """`lower` with EA = 2e5 N and the implicit string: the environment sizes its step for the
    winch's shortest string (the transverse limit at half the length, under the load and half the
    string: 31 steps per 20 ms, against 16 at a fixed length), reels at full speed to twice the
    length, and its balance closes within 1 % of the winch's work (measured: see
    docs/physics.md)."""
    overrides = {"solver": {"string": "implicit"}, "EA": 2e5}
    fixed = gym.make(ENV_ID, task="transport", scene_overrides=overrides)
    env = gym.make(ENV_ID, winch=True, task="lower", scene_overrides=overrides)
    assert (env.unwrapped.setup.substeps, fixed.unwrapped.setup.substeps) == (31, 16)
    env.reset(seed=2)
    sim = env.unwrapped.sim
    l0 = sim.winch.length
    for _ in range(60):
        obs, r, term, trunc, info = env.step(reel(1.0))
        assert not term, info
    d = sim.diagnostics()
    assert d["unstretched_length"] == 2.0 * l0 and obs[-1] == np.float32(2.0 * l0)
    assert abs(d["energy_balance_residual"]) < 1e-2 * abs(d["winch_work"])


def test_lift_and_lower_put_the_target_where_a_string_of_another_length_hangs():
    for task, (low, high) in (("lift", (0.55, 0.75)), ("lower", (1.25, 1.6))):
        env = gym.make(ENV_ID, winch=True, task=task)
        depths = []
        for seed in range(20):
            env.reset(seed=seed)
            pivot, load = env.unwrapped.target[:3], env.unwrapped.target[3:]
            depths.append(load[2] - pivot[2])
            if task == "lift":
                assert np.array_equal(pivot, np.zeros(3))
        scene = env.unwrapped.scene
        assert hanging_depth(scene, low * scene.string.length) <= min(depths)
        assert max(depths) <= hanging_depth(scene, high * scene.string.length)


def test_the_hard_lift_follows_a_moving_target_at_the_shorter_strings_depth():
    """The hard preset's lift (moving_target): the pivot starts on a track reference and the
    targets move along it, the load's at the rest depth of a string 25-45 % shorter; an explicit
    moving_target=False gives the hard preset's fixed lift (negative control)."""
    env = gym.make(ENV_ID, task="lift", preset="hard").unwrapped
    assert env.setup.task.moving and env.setup.task.name == "lift"
    moved = []
    for seed in range(6):
        env.reset(seed=seed)
        start = env.control.target.copy()
        np.testing.assert_allclose(env.pivot_position(), start[TARGET["pivot"]], atol=1e-12)
        scene = env.scene  # this episode's draw
        depth = start[TARGET.scalar("depth")]
        assert hanging_depth(scene, 0.55 * scene.string.length) <= depth <= hanging_depth(scene, 0.75 * scene.string.length)
        for _ in range(20):
            env.step(np.zeros(7))
        expected = start.copy()
        reference_at(expected, 20 * env.setup.control_period)
        np.testing.assert_allclose(env.control.target, expected, rtol=1e-12, atol=1e-12)
        moved.append(np.linalg.norm(env.control.target[TARGET["pivot"]] - start[TARGET["pivot"]]))
    assert min(moved) > 0.01
    fixed = gym.make(ENV_ID, task="lift", preset="hard", moving_target=False).unwrapped
    fixed.reset(seed=0)
    before = fixed.control.target.copy()
    fixed.step(np.zeros(7))
    assert not fixed.setup.task.moving and np.array_equal(before, fixed.control.target)
    assert np.array_equal(before[TARGET["pivot"]], np.zeros(3))


@pytest.mark.parametrize("kwargs, match", [
    (dict(task="transport", moving_target=True), "moving_target=True: task 'transport' has fixed targets"),
    (dict(task="track", moving_target=False), "moving_target=False: task 'track' always moves"),
    (dict(task="lift", moving_target="yes"), "moving_target"),
    (dict(task="lift", winch=False), "winch=True"), (dict(task="lower", winch=False), "winch=True"),
    (dict(winch=1), "winch"),
    (dict(winch=True, h=1e-3), "winch.s shortest"),
])
def test_bad_winch_arguments_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(ENV_ID, **kwargs)


def test_a_bad_reel_action_raises_and_changes_nothing():
    env = gym.make(ENV_ID, winch=True, task="lift")
    env.reset(seed=3)
    env.step(reel(-0.5))
    before = env.unwrapped.sim.state
    for bad in (reel(np.nan), reel(np.inf), np.zeros(6)):
        with pytest.raises(ValueError):
            env.step(bad)
    after = env.unwrapped.sim.state
    assert np.array_equal(before.r, after.r) and before.winch == after.winch


@pytest.mark.parametrize("task", ["lift", "lower"])
def test_the_hoist_baseline_reels_the_load_to_its_target(task):
    """agents.baselines.pd.Hoist (the pivot's PD law and a reel law on the depth error) beats the
    zero action by far (10 episodes in the tuning: lift 488.9 against 285.0, lower 413.8 against
    197.0) and ends with the load near its target: 3 episodes here."""
    from agents.baselines.pd import ZeroPolicy
    from agents.baselines.registry import baselines
    from agents.evaluate import evaluate_policy

    hoist = baselines(task)["pd"]
    ours = evaluate_policy(hoist, task, 3, seed=1000)
    zero = evaluate_policy(ZeroPolicy(), task, 3, seed=1000)
    assert ours["mean_return"] > zero["mean_return"] + 100.0, (ours, zero)
    assert ours["success_rate"] == 1.0


def test_tune_sets_the_hoists_gains():
    """agents.baselines.gain_search reaches a Hoist's reel gain and its PD law's gains (one grid point, one episode)."""
    from agents.baselines.pd import Hoist
    from agents.baselines.gain_search import gain_names, with_gains

    law = Hoist()
    assert "k_length" in gain_names(law) and "kp" in gain_names(law)
    tuned = with_gains(law, {"k_length": 3.0, "kp": 5.0})
    assert (tuned.k_length, tuned.pd.kp, tuned.pd.kd) == (3.0, 5.0, law.pd.kd)
    assert with_gains(law, {"kd": 1.0}).k_length == law.k_length
