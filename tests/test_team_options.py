"""A team's arguments, actions and vector env are checked as the single env's are, by the same code
(issue 54, items 3, 7 and 8; docs/team.md, "Arguments"): ``randomize`` through esp_gym/pendulum/randomize.py,
the options through esp_gym/pendulum/options.py, the actions through esp_gym/pendulum/control.py's ``raw_actions``,
the drones' lift through esp_gym/pendulum/env_setup.py; the vector env's infos in Gymnasium's convention and its
refusal of a step before ``reset``. Each refusal has a negative control: the good value runs."""
import gymnasium as gym
import numpy as np
import pytest

import esp_gym
from esp_gym.pendulum.env import ElasticStringPendulumEnv
from esp_gym.pendulum.options import MAX_SUBSTEPS
from esp_gym.team import parallel_env
from esp_gym.team.core import TeamCore
from esp_gym.team.env import ElasticStringTeamEnv
from esp_gym.team.scene import TEAM_SAFETY


def detail(error: pytest.ExceptionInfo) -> str:
    """An error's message without the environment's name in front."""
    message = str(error.value)
    for env_id in (esp_gym.ENV_ID, esp_gym.TEAM_ENV_ID):
        message = message.removeprefix(env_id + ": ")
    return message


# -- randomize (item 3) ---------------------------------------------------------------------------
def test_a_teams_randomize_ranges_are_drawn_for_every_string():
    team = parallel_env(team=3, randomize={"EA": (1000.0, 1000.0), "load_mass": (2.0, 3.0),
                                           "mass_per_length": [0.02, 0.03]})
    masses = set()
    for seed in range(3):
        team.reset(seed=seed)
        draws = team.episode_info["team_draws"]
        assert [s["EA"] for s in draws["strings"]] == [1000.0] * 3  # a pair (v, v) fixes v
        assert [s.string.EA for s in team.core.scene.strings] == [1000.0] * 2
        assert 2.0 <= draws["body_mass"] <= 3.0 and team.core.scene.scene.body.mass == draws["body_mass"]
        per_string = [s["mass_per_length"] for s in draws["strings"]]
        assert all(0.02 <= m <= 0.03 for m in per_string) and len(set(per_string)) == 3  # one draw each
        masses.update(draws["pivot_masses"])  # a name not given keeps its default range
    assert len(masses) == 9 and all(0.8 <= m <= 1.25 for m in masses)
    # negative control: the defaults draw each string's EA around the nominal 200 N
    team = parallel_env(team=3, randomize=True)
    team.reset(seed=0)
    EAs = [s["EA"] for s in team.episode_info["team_draws"]["strings"]]
    assert len(set(EAs)) == 3 and all(100.0 <= e <= 400.0 for e in EAs)


@pytest.mark.parametrize("randomize", ["yes", 1, np.True_, {"EA": "big"}, {"EA": (2000.0, 1000.0)},
                                       {"EA": (0.0, 1.0)}, {"EA": (1.0, float("inf"))}, {"EA": {1.0, 2.0}},
                                       {"EA": (True, 2.0)}, {"stiffness": (1.0, 2.0)}])
def test_a_bad_randomize_is_refused_by_a_team_as_by_the_single_env(randomize):
    with pytest.raises(ValueError) as single:
        ElasticStringPendulumEnv(randomize=randomize)
    with pytest.raises(ValueError) as team:
        TeamCore(2, randomize=randomize)
    # the same words: one parser (an unknown name lists each env's own names after the ";")
    assert detail(team).split(";")[0] == detail(single).split(";")[0]


def test_draws_a_team_does_not_make_are_refused_with_the_reason():
    for name in ("load_size_x", "attachment_offset_y"):
        with pytest.raises(ValueError, match=f"randomize: {name} .*team"):
            TeamCore(2, randomize={name: (0.1, 0.2)})
    with pytest.raises(ValueError, match="randomize: motor_lag_scale .*team"):
        TeamCore(2, actuation="thrust_rates", randomize={"motor_lag_scale": (0.9, 1.1)})
    TeamCore(2, randomize={"string_length": (0.9, 1.0), "pivot_mass": (0.5, 0.6)})  # negative control
    assert TeamCore(2, randomize={}).randomizer is not None  # an empty mapping: the default ranges, as the single env's


def test_ranges_whose_corner_is_no_valid_team_are_refused_naming_the_corner():
    # EA = 1 mN stretches each string 4,000 times under its share of the load
    with pytest.raises(ValueError, match="invalid scene at the lows of the randomize ranges:\n  initial.stretch"):
        TeamCore(2, randomize={"EA": (1e-3, 200.0)})
    TeamCore(2, randomize={"EA": (50.0, 200.0)})  # negative control


def test_a_drone_team_that_cannot_lift_its_heaviest_draw_is_refused():
    # one drone under the hard preset: 1.875 kg of drone, 1.5 kg of load and 0.11 kg of string
    # at the ranges' heaviest corner against 34.2 N of thrust (1.0 times the weight)
    with pytest.raises(ValueError, match="drone 0 cannot carry .* 1.2 times the weight"):
        TeamCore(1, actuation="thrust_rates", preset="hard")
    TeamCore(3, actuation="thrust_rates", preset="hard")  # negative control: three share the load
    TeamCore(1, actuation="thrust_rates")  # and one carries the nominal rig (1.37 times its weight)


# -- the options (item 8) -------------------------------------------------------------------------
#: Options both environments take, refused alike (the same words after the environment's name).
SHARED_BAD = [dict(control_period=True), dict(control_period="0.02"), dict(control_period=float("nan")),
              dict(control_period=0.0), dict(action_latency=1.5), dict(action_latency=True), dict(action_latency=51),
              dict(observation="camera"), dict(sensor_noise=True), dict(sensor_noise="1"), dict(sensor_noise=-1.0),
              dict(sensor_noise=1e40), dict(winch="yes"), dict(preset="easy"), dict(actuation="jets")]


@pytest.mark.parametrize("options", SHARED_BAD + [dict(force_limit=True), dict(force_limit=float("inf")),
                                                  dict(force_limit=0.0)])
def test_bad_team_options_are_refused_naming_them(options):
    (name,) = options
    with pytest.raises(ValueError, match=name) as team:
        TeamCore(2, **options)
    if options in SHARED_BAD:
        with pytest.raises(ValueError) as single:
            ElasticStringPendulumEnv(**options)
        assert detail(team) == detail(single)


def test_a_force_past_any_actuator_is_refused_by_both_envs():
    # force_limit = 1e300 was accepted, and the first push overflowed the step (the team's and the single env's)
    with pytest.raises(ValueError, match=r"force_limit: .* 1000"):
        TeamCore(2, force_limit=1e300)
    with pytest.raises(ValueError, match=r"force_limit = 1e\+300 N .* above the 1000 times"):
        ElasticStringPendulumEnv(force_limit=1e300)
    TeamCore(2, force_limit=1000.0)  # negative controls: the bound itself, and 500 times drone_load's weight
    ElasticStringPendulumEnv(force_limit=1e4)


def test_good_team_options_are_read_as_numbers():
    # negative control of the refusals above: NumPy's numbers are numbers
    core = TeamCore(2, control_period=np.float64(0.04), force_limit=np.float32(0.5), action_latency=np.int64(2),
                    sensor_noise=np.float32(1.0), observation="hook", winch=np.True_)
    assert (core.control_period, core.force_limit, core.action_latency, core.sensor_noise, core.winch) == (
        0.04, 0.5, 2, 1.0, True)
    assert type(core.control_period) is float and type(core.sensor_noise) is float


@pytest.mark.parametrize("name, value", [("h", 1e-4), ("torque_limit", 0.01),
                                         ("thrust_noise", 0.05), ("moving_target", True)])
def test_options_a_team_lacks_are_refused_with_the_reason(name, value):
    with pytest.raises(ValueError, match=rf"^{esp_gym.TEAM_ENV_ID}: {name}: a team"):
        TeamCore(2, **{name: value})
    TeamCore(2, **{name: None})  # negative control: not given


def test_safety_sets_the_teams_margin_under_every_strings_stability_bound():
    """The fewest steps that keep h within ``safety`` x each string's bound: twice as many at
    half the safety, or one more (the count is whole); a bad one is named, as the single env's."""
    nominal, finer = TeamCore(2), TeamCore(2, safety=0.25)
    assert nominal.safety == TEAM_SAFETY == 0.5 and finer.safety == 0.25
    assert 2 * nominal.substeps - 1 <= finer.substeps <= 2 * nominal.substeps
    bound = min(finer.scene.member_scene(k).stability_bound for k in range(2))
    assert finer.scene.scene.h <= 0.25 * bound < nominal.scene.scene.h <= 0.5 * bound
    for bad in (0.0, 1.5, float("nan"), True, "0.3"):
        with pytest.raises(ValueError, match=rf"^{esp_gym.TEAM_ENV_ID}: safety: "):
            TeamCore(2, safety=bad)
        with pytest.raises(ValueError, match=rf"^{esp_gym.ENV_ID}: safety: "):  # the single env's, alike
            gym.make(esp_gym.ENV_ID, safety=bad)


def test_an_unknown_team_option_is_named():
    with pytest.raises(ValueError, match=rf"^{esp_gym.TEAM_ENV_ID}: unknown argument 'speed'"):
        parallel_env(team=2, speed=3.0)


def test_a_team_needing_too_many_physics_steps_per_step_is_refused():
    # control_period = 100 s asked for 165,726 physics steps per step
    with pytest.raises(ValueError, match=r"control_period = 100.0 s .* physics steps per step \(at most 100,000\)"):
        TeamCore(2, control_period=100.0)
    # and so does the stiffest string of the randomize ranges (h at EA = 1e11 N: 3.8e-8 s)
    with pytest.raises(ValueError, match=r"physics steps per step \(at most 100,000\)"):
        TeamCore(2, randomize={"EA": (200.0, 1e11)})
    assert TeamCore(2, control_period=1.0).substeps <= MAX_SUBSTEPS  # negative controls
    TeamCore(2, randomize={"EA": (200.0, 1e7)})


# -- the actions (item 8) -------------------------------------------------------------------------
LOSSY = {"complex": lambda n: np.full(n, 0.1 + 1j), "bool": lambda n: np.ones(n, dtype=bool),
         "object": lambda n: np.array([0.1] * n, dtype=object), "str": lambda n: np.array(["0.1"] * n),
         "masked": lambda n: np.ma.masked_array(np.full(n, 0.1), mask=[True] + [False] * (n - 1))}


@pytest.mark.parametrize("kind", sorted(LOSSY))
def test_actions_that_would_lose_information_are_refused_by_both_team_faces(kind):
    central = ElasticStringTeamEnv(2)
    central.reset(seed=0)
    with pytest.raises(TypeError, match="action"):
        central.step(LOSSY[kind](6))
    team = parallel_env(team=2)
    team.reset(seed=0)
    with pytest.raises(TypeError, match=r"actions\['pivot_0'\]"):
        team.step({a: LOSSY[kind](3) for a in team.agents})
    assert central.core.steps == team.core.steps == 0  # nothing moved
    central.step(np.zeros(6, dtype=np.float32))  # negative control: real numbers of any width
    team.step({a: np.zeros(3, dtype=np.int64) for a in team.agents})
    assert central.core.steps == team.core.steps == 1


# -- the vector env (item 7) ----------------------------------------------------------------------
def _same(a, b) -> bool:
    """Two vector infos hold the same keys and values (arrays compared entry by entry)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) and a.dtype == object:
        return a.shape == b.shape and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return bool(np.array_equal(a, b))


def test_the_team_vector_env_reports_every_info_in_gymnasiums_convention():
    """Sub-env 0 is pushed out of its workspace (terminated every 6 steps), sub-env 1 hovers
    (truncated every 8): the infos are Gymnasium's own vector env's over the single envs, each
    termination with its reason and its ``_termination_reason`` mask."""
    kwargs = dict(team=2, task="stabilize", force_limit=10.0, max_episode_steps=8)
    venv = gym.make_vec(esp_gym.TEAM_ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.vector.SyncVectorEnv([lambda: gym.make(esp_gym.TEAM_ENV_ID, **kwargs)] * 2)
    _, info = venv.reset(seed=3)
    assert _same(info, sync.reset(seed=3)[1]) and info["_load_target"].all()
    actions = np.zeros((2, 6))
    actions[0, [0, 3]] = 1.0
    reasons, truncations = [], 0
    for _ in range(20):
        obs, rewards, terminated, truncated, info = venv.step(actions)
        s_obs, s_rewards, s_terminated, s_truncated, s_info = sync.step(actions)
        assert np.array_equal(obs, s_obs) and np.array_equal(rewards, s_rewards)
        assert np.array_equal(terminated, s_terminated) and np.array_equal(truncated, s_truncated)
        assert _same(info, s_info)
        if terminated.any():
            assert np.array_equal(info["_termination_reason"], terminated)
            reasons += list(info["termination_reason"][terminated])
        else:
            assert "termination_reason" not in info
        truncations += int(truncated.sum())
    assert len(reasons) >= 3 and all(isinstance(r, str) and r for r in reasons) and truncations >= 2


@pytest.mark.parametrize("env_id", [esp_gym.ENV_ID, esp_gym.TEAM_ENV_ID])
def test_a_vector_env_refuses_a_step_before_reset(env_id):
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    zeros = np.zeros(venv.action_space.shape)
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
        venv.step(zeros)
    venv.reset(seed=0)
    venv.step(zeros)  # negative control
