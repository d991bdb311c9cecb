"""A team's lift (esp_gym/team/core.py with winches; docs/team.md, "Tasks"): the environments with
a reel action per agent pass PettingZoo's and Gymnasium's checks, the lift's targets and the
observed lengths are what the docs say, the reel action reels, the hoist baseline lifts the load,
and what cannot reel is refused."""
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from agents.team.evaluate import TeamHoistPolicy, TeamZero, run_team_episodes
from esp_gym.team import parallel_env
from esp_gym.team.core import TeamCore
from esp_gym.team.env import ElasticStringTeamEnv
from esp_gym.team.tasks import hanging_rise


def test_the_lift_envs_pass_pettingzoos_and_gymnasiums_checks():
    parallel_api_test(parallel_env(team=3, task="lift"), num_cycles=40)
    parallel_seed_test(lambda: parallel_env(team=3, task="lift"))
    env = gym.make("ElasticStringTeam-v0", team=3, task="lift")
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(ElasticStringTeamEnv(3, task="lift"))
    assert env.action_space.shape == (12,) and env.observation_space.shape == (102,)


def test_the_lift_raises_the_target_and_holds_the_pivots_and_the_reel_reels():
    """The load's target is the start's raised by the hanging geometry at the drawn lengths (every
    string at 55-75 % of its length), the pivots' targets where they start; each agent observes its
    string's length; a full reel-in action for one control step shortens every string by
    max_speed x the control period, and a zero reel leaves it (negative control)."""
    core = TeamCore(3, "lift")
    obs, _ = core.reset(seed=4)
    L = core.layout
    start = core.kinematics()
    assert np.all((core.reel_targets >= 0.55 * start["lengths"]) & (core.reel_targets <= 0.75 * start["lengths"]))
    assert np.allclose(core.reel_targets, core.reel_targets[0])
    rise = hanging_rise(start, core.scene.attachments(), core.reel_targets)
    assert -0.45 < rise < -0.2
    assert np.allclose(core.load_target, start["load"] + [0.0, 0.0, rise]) and np.allclose(core.pivot_targets,
                                                                                          start["pivot"])
    assert np.allclose(obs[:, L["string_length"]][:, 0], start["lengths"])
    action = np.zeros((3, 4))
    action[:, 3] = -1.0
    obs, *_ = core.step(action)
    expected = start["lengths"] - core.sim.winches.max_speeds * core.control_period
    assert np.allclose(core.sim.winches.lengths, expected, atol=1e-12)
    assert np.allclose(obs[:, L["string_length"]][:, 0], expected, atol=1e-6)
    core.step(np.zeros((3, 4)))
    assert np.allclose(core.sim.winches.lengths, expected, atol=1e-12)


def test_the_hoist_lifts_the_load_and_the_zero_action_does_not():
    """Nominal lift, two episodes: the hoist (the team's LQR blind to the depth, a reel law per
    winch) reaches the target and returns above 470 of 500 (measured 478.0, 478.2); hovering
    without reeling returns about 21."""
    hoist = run_team_episodes(TeamHoistPolicy(), 3, "lift", episodes=2, seed=200000)
    assert all(e.success and e.ret > 470 for e in hoist), [e.ret for e in hoist]
    zero = run_team_episodes(TeamZero(), 3, "lift", episodes=2, seed=200000)
    assert all(e.ret < 50 for e in zero)


def test_what_cannot_lift_says_why():
    with pytest.raises(ValueError, match="winch.*needs winch=True"):
        TeamCore(3, "lift", winch=False)
    with pytest.raises(ValueError, match="winch: a team's drones do not reel"):
        TeamCore(3, "lift", actuation="thrust_rates")
    with pytest.raises(ValueError, match="winch: Input should be a valid boolean"):
        TeamCore(3, "transport", winch="yes")
    core = TeamCore(3, "transport", winch=True)  # any task may reel
    assert core.action_size == 4 and "string_length" in core.layout


def test_a_residual_lift_team_starts_as_the_hoist_and_tells_its_filter_the_forces():
    """agents/team/residual.py on the hard lift: with zero residual the team flies the hoist on the
    LQG bit for bit (rewards equal over 40 steps); each agent's command is its force and reel
    speed; a residual's forces reach the filter (its predicted input), a residual on the reel
    alone does not (negative control)."""
    from agents.team.residual import TeamResidualParallelEnv

    residual = TeamResidualParallelEnv(parallel_env(team=3, task="lift", preset="hard"), scale=0.3)
    central, hoist = ElasticStringTeamEnv(3, task="lift", preset="hard"), TeamHoistPolicy("lqg")
    obs_r, _ = residual.reset(seed=100003)
    obs_c, _ = central.reset(seed=100003)
    n = central.core.layout.size
    for _ in range(40):
        action = hoist.act(obs_c, central.core)
        rows = np.stack([obs_r[a] for a in residual.possible_agents])
        assert np.allclose(rows[:, n:n + 4], action.reshape(3, 4), atol=1e-6)
        obs_c, r_c, *_ = central.step(action)
        obs_r, r_r, *_ = residual.step({a: np.zeros(4) for a in residual.possible_agents})
        assert r_r["pivot_0"] == r_c
    filter_ = residual.base.policy.design.base
    command = residual.command.copy()
    residual.step({a: np.array([0.0, 0.0, 0.0, 1.0]) for a in residual.possible_agents})
    assert np.allclose(filter_.applied.reshape(3, 3), command[:, :3])
    command = residual.command.copy()
    residual.step({a: np.array([1.0, 0.0, 0.0, 0.0]) for a in residual.possible_agents})
    assert not np.allclose(filter_.applied.reshape(3, 3), command[:, :3])
