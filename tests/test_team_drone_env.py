"""A drone team's environments (esp_gym/team/env.py with ``actuation``, esp_gym/team/spaces.py;
docs/team.md): PettingZoo's API and seed tests, both Gymnasium env checkers, the centralised env
equal to the parallel one, the drones' observation fields and action paths, the flip, the errors,
and the cascade baseline (agents/baselines/team/cascade.py) with its negative control."""
import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import esp_gym  # noqa: F401 (registers ElasticStringTeam-v0)
from agents.baselines.team.cascade import TeamCascade, point_twin
from agents.baselines.team.lqr import TeamLQR
from agents.team.evaluate import TeamZero, run_team_episodes
from esp_gym.pendulum.env_setup import DRONE_RATE_LIMIT
from esp_gym.team import parallel_env
from esp_gym.team.env import ElasticStringTeamEnv
from esp_gym.team.scene import team_scene

DRONES = {"actuation": "thrust_rates"}


def test_the_drone_teams_parallel_env_passes_pettingzoos_api_and_seed_tests():
    parallel_api_test(parallel_env(team=3, **DRONES), num_cycles=60)
    parallel_seed_test(lambda: parallel_env(team=3, **DRONES))


@pytest.mark.filterwarnings("ignore:.*Box observation space.*infinity")
def test_the_drone_teams_centralised_env_passes_both_checkers():
    env = gym.make("ElasticStringTeam-v0", team=3, **DRONES)
    check_env(env.unwrapped, skip_render_check=True)
    check_env(gym.make("ElasticStringTeam-v0", team=3, render_mode="rgb_array", **DRONES).unwrapped)
    sb3_check_env(ElasticStringTeamEnv(3, **DRONES))
    assert env.action_space.shape == (12,) and env.observation_space.shape == (3 * 42,)  # 27 + 6 + 9 each


def test_the_drone_teams_centralised_env_is_the_parallel_env():
    central = ElasticStringTeamEnv(3, **DRONES)
    team = parallel_env(team=3, **DRONES)
    obs_c, _ = central.reset(seed=5)
    obs_p, _ = team.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = rng.uniform(-0.2, 0.2, 12).astype(np.float32)
        obs_c, r_c, *_ = central.step(a)
        obs_p, r_p, *_ = team.step({f"pivot_{k}": a[4 * k:4 * k + 4] for k in range(3)})
        assert np.array_equal(obs_c, np.concatenate([obs_p[a] for a in team.possible_agents]))
        assert all(r == r_c for r in r_p.values())


def test_a_drone_agent_observes_its_drone_and_its_action_sets_its_rotors():
    team = parallel_env(team=3, **DRONES)
    team.reset(seed=1)
    core, L = team.core, team.core.layout
    action = np.array([0.2, 0.5, -0.25, 0.1], np.float32)
    obs, *_ = team.step({a: action for a in team.agents})
    fleet = core.sim.fleet
    d = fleet.diagnostics()
    for k, agent in enumerate(team.possible_agents):
        R = d["drone_attitudes"][k]
        assert np.allclose(obs[agent][L["drone_attitude_6d"]], R[:, :2].T.ravel(), atol=1e-6)
        assert np.allclose(obs[agent][L["drone_rates"]], d["drone_rates"][k], atol=1e-6)
        assert abs(R[0, 2]) > 1e-3  # it turned
    setpoints = fleet.arrays.arrays.setpoint
    assert np.allclose(setpoints[:, 0], 1.2 * fleet.shares())
    assert np.allclose(setpoints[:, 1:], np.asarray(DRONE_RATE_LIMIT) * action[1:].astype(float))
    assert fleet.rates


@pytest.mark.parametrize("actuation", ["thrust_rates", "thrust_torque", "motors"])
def test_a_zero_action_hovers_each_drone_on_its_share(actuation):
    core = ElasticStringTeamEnv(3, actuation=actuation).core
    core.reset(seed=0)
    core.step(np.zeros((3, 4)))
    thrust = core.sim.fleet.diagnostics()["drone_thrust"]
    assert np.allclose(thrust, core.drive.hover, rtol=1e-9)
    # negative control: a full roll in every mode tips the drones until one flips
    core.reset(seed=0)
    roll = np.tile([0.0, 1.0, 0.0, 0.0] if actuation != "motors" else [-1.0, 1.0, -1.0, 1.0], (3, 1))
    for _ in range(100):
        _, _, terminated, _, info = core.step(roll)
        if terminated:
            break
    assert info["termination_reason"] in ("drone_flipped", "collision", "left_workspace", "string_overstretched")


def test_a_drone_that_tips_past_the_horizontal_ends_the_episode():
    env = ElasticStringTeamEnv(3, **DRONES)
    env.reset(seed=0)
    roll = np.tile([0.0, 1.0, 0.0, 0.0], 3)
    for _ in range(60):
        _, _, terminated, _, info = env.step(roll)
        if terminated:
            break
    assert info["termination_reason"] == "drone_flipped"
    assert np.any(env.core.sim.fleet.diagnostics()["drone_attitudes"][:, 2, 2] < 0.0)


def test_a_drone_team_env_refuses_bad_arguments():
    with pytest.raises(ValueError, match="actuation: Input should be 'force', 'thrust_torque'"):
        ElasticStringTeamEnv(3, actuation="jets")
    with pytest.raises(ValueError, match="actuation 'force' does not fly the team's drones"):
        ElasticStringTeamEnv(team_scene(3, drones=True), actuation="force")
    with pytest.raises(ValueError, match="does not fly the team's point pivots"):
        ElasticStringTeamEnv(team_scene(3), actuation="motors")
    drones = team_scene(2, drones=True)
    mixed = drones.model_copy(update={"strings": [s.model_copy(update={"pivot": team_scene(2).strings[0].pivot})
                                                  for s in drones.strings]})
    with pytest.raises(ValueError, match=r"all free points or all drones, got \['drone', 'free'\]"):
        ElasticStringTeamEnv(mixed)
    env = ElasticStringTeamEnv(3, **DRONES)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(12,\)"):
        env.step(np.zeros(9))
    with pytest.raises(ValueError, match=r"\(one drone action per agent\) must have shape \(3, 4\)"):
        env.core.step(np.zeros((3, 3)))


def test_the_cascade_carries_the_load_where_the_twins_own_lqr_drops_it():
    """The cascade (its outer loop designed with the thrust's lag) carries the load on transport;
    the point twin's own LQR, which assumes its forces at once, behind the same inner loops loses
    the team in the first seconds (the negative control)."""
    env = ElasticStringTeamEnv(3, **DRONES)
    env.reset(seed=0)
    cascade = TeamCascade.design(env.core)
    zero = [r.ret for r in run_team_episodes(TeamZero(), 3, "transport", 2, seed=100, env_kwargs=DRONES)]

    class Policy:
        def __init__(self, design):
            self.design = design

        def act(self, obs, core):
            return self.design.act(obs, core)

    rows = run_team_episodes(Policy(cascade), 3, "transport", 2, seed=100, env_kwargs=DRONES)
    assert min(r.ret for r in rows) > 380.0 > 50.0 > max(zero)  # measured: 434 over 8 validation episodes
    twin_lqr = TeamLQR.design(cascade.twin)
    unaware = TeamCascade(cascade.gain, cascade.twin)
    unaware.gain = np.hstack([twin_lqr.K, np.zeros((9, 9))])  # the twin's LQR: no lag, no applied force
    rows = run_team_episodes(Policy(unaware), 3, "transport", 2, seed=100, env_kwargs=DRONES)
    assert max(r.ret for r in rows) < 100.0
    assert point_twin(env.core.scene).pivots()[0].kind == "free"


def test_compare_takes_a_drone_team(capsys):
    from agents.compare import main

    c = main(["--team", "2", "--actuation", "thrust_rates", "--task", "stabilize", "--episodes", "2", "--json",
              "--no-progress"])
    printed = json.loads(capsys.readouterr().out)
    assert printed["actuation"] == "thrust_rates" and printed["best_baseline"] == "cascade"
    assert set(c["policies"]) == {"zero", "cascade"}
    with pytest.raises(SystemExit):
        main(["--team", "2", "--task", "stabilize", "--episodes", "2", "--actuation", "force"])
    assert "--actuation: with --team" in capsys.readouterr().err


def test_the_cascades_filter_estimates_the_load_the_drones_do_not_see():
    """The hook observation, sensor noise and a latency of one step: the cascade on its filter's
    estimate carries the load, and the estimate of the load's place comes within a few cm."""
    from agents.baselines.team.lqr import reduced_layout
    from agents.team.evaluate import TeamCascadeLQGPolicy

    env = ElasticStringTeamEnv(3, observation="hook", sensor_noise=1.0, action_latency=1, **DRONES)
    policy = TeamCascadeLQGPolicy()
    obs, _ = env.reset(seed=100001)
    total, errors = 0.0, []
    load = reduced_layout(3)["load_error"]
    for _ in range(500):
        obs, reward, terminated, _, _ = env.step(policy.act(obs, env.core))
        total += reward
        errors.append(np.linalg.norm(policy.design.estimate[load] - (env.core.load_position() - env.core.load_target)))
        assert not terminated
    assert total > 380.0  # measured 419.7
    assert np.median(errors[250:]) < 0.04  # measured 0.018 m


def test_a_residual_drone_team_adds_its_actions_to_the_cascades():
    """agents/team/residual.py on drones (the hard preset): PettingZoo's API test passes, each agent
    sees its observation, its cascade command (4) and the filter's estimate, and a zero residual
    flies the cascade's episode, bit for bit."""
    from agents.team.evaluate import TeamCascadeLQGPolicy
    from agents.team.residual import TeamResidualParallelEnv, feature_size

    def residual_env():
        return TeamResidualParallelEnv(parallel_env(team=3, preset="hard", **DRONES))

    parallel_api_test(residual_env(), num_cycles=20)
    env = residual_env()
    obs, _ = env.reset(seed=100002)
    n = env.env.observation_space("pivot_0").shape[0]
    assert env.observation_space("pivot_0").shape == (n + feature_size(3, "hook", 4),)
    total = 0.0
    for _ in range(40):
        obs, rewards, *_ = env.step({a: np.zeros(4, np.float32) for a in env.possible_agents})
        total += rewards["pivot_0"]
    alone = ElasticStringTeamEnv(3, preset="hard", **DRONES)
    obs, _ = alone.reset(seed=100002)
    policy, expected = TeamCascadeLQGPolicy(), 0.0
    for _ in range(40):
        obs, reward, *_ = alone.step(policy.act(obs, alone.core))
        expected += reward
    assert total == expected
    # negative control: a residual of 0.1 on every thrust flies another episode
    env.reset(seed=100002)
    moved = sum(env.step({a: np.array([0.1, 0.0, 0.0, 0.0], np.float32) for a in env.possible_agents})[1]["pivot_0"]
                for _ in range(40))
    assert moved != expected
