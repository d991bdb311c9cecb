"""Per-episode randomisation (``randomize=``, esp_gym/pendulum/randomize.py): seeded draws, the drawn
physics is what the compiled step runs, validation, and the cost of a reset.
(The batched environments against single ones with randomisation: tests/test_env.py.)"""
import math
import time

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import esp_gym  # noqa: F401  (registers the env)
from esp_gym import load_scene
from esp_gym.physics.state import total_weight
from esp_gym.pendulum.env import ElasticStringPendulumEnv
from esp_gym.kernels.layout import INPUTS
from esp_gym.kernels.env.arrays import SCENE_PARAMS
from esp_gym.physics.simulator import Simulator
from esp_gym.scene.params import scene_from_dict
from esp_gym.pendulum.randomize import LOG_UNIFORM, default_ranges, nominal_values
from esp_gym.scene.stepsize import scheme_substeps

ENV_ID = "ElasticStringPendulum-v0"


def _episode(env, seed, actions):
    obs, info = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, te, tr, _ = env.step(a)
        out.append(np.append(obs, [r, te]))
    return info["scene_params"], np.concatenate(out)


def test_same_seed_same_episodes_and_other_seeds_other_tethers():
    actions = np.random.default_rng(0).uniform(-1, 1, (40, 6)).astype(np.float32)
    a, b = gym.make(ENV_ID, randomize=True), gym.make(ENV_ID, randomize=True)
    pa, xa = _episode(a, 7, actions)
    pb, xb = _episode(b, 7, actions)
    assert pa == pb and np.array_equal(xa, xb)
    pc, xc = _episode(b, 8, actions)
    assert all(pc[k] != pa[k] for k in SCENE_PARAMS.names)  # every parameter is drawn
    # the next episode of a seeded generator is drawn anew, the same in both
    a.reset(seed=1)
    b.reset(seed=1)
    assert a.reset()[1] == b.reset()[1] != a.unwrapped.reset(seed=1)[1]


def test_draws_cover_the_documented_ranges():
    """Every value lies in its default range; log-uniform names are uniform in log (their
    median is the ranges' geometric mean), the others in value."""
    env = gym.make(ENV_ID, randomize=True).unwrapped
    ranges = default_ranges(env.setup.scene)
    draws = np.array([[env.reset(seed=s)[1]["scene_params"][k] for k in SCENE_PARAMS.names] for s in range(400)])
    for j, name in enumerate(SCENE_PARAMS.names):
        lo, hi = ranges[name]
        assert lo <= draws[:, j].min() and draws[:, j].max() <= hi, name
        mid = math.sqrt(lo * hi) if name in LOG_UNIFORM else 0.5 * (lo + hi)
        # 400 draws: the sample median of a uniform variable is within ~0.1 of its range's middle
        frac = (np.median(draws[:, j]) - mid) / (hi - lo)
        assert abs(frac) < 0.1, (name, frac)


def test_the_compiled_step_runs_the_drawn_scene():
    """One control step of a randomised env equals the substeps of a Simulator of the scene
    rebuilt from the reported values and validated, with the same inputs: the run-time
    constants, the step count and the hover force are the episode's. Negative control: the
    nominal scene does not reproduce it."""
    env = gym.make(ENV_ID, randomize=True).unwrapped
    _, info = env.reset(seed=3)
    values = info["scene_params"]
    nominal = env.setup.scene
    data = nominal.model_dump()
    data["string"].update(length=values["string_length"], EA=values["EA"], mass_per_length=values["mass_per_length"])
    size = (values["load_size_x"], values["load_size_y"], values["load_size_z"])
    data["body"].update(mass=values["load_mass"], shape={"kind": "box", "size": size},
                        rho_c=(values["attachment_offset_x"], values["attachment_offset_y"],
                               nominal.body.rho_c[2] * size[2] / nominal.body.shape.size[2]))
    data["pivot"]["mass"] = values["pivot_mass"]
    rebuilt = scene_from_dict({**data, "allow_unstable_h": True})
    substeps = scheme_substeps(rebuilt, 0.02, 0.5)
    rebuilt = scene_from_dict({**data, "h": 0.02 / substeps})
    assert env.scene.h == rebuilt.h
    state = env.sim.state
    action = np.array([0.3, -0.2, 0.5, 0.1, -0.4, 0.2])
    env.step(action)
    force = np.array([0.0, 0.0, -total_weight(rebuilt)]) + env.setup.force_limit * action[:3]
    assert np.array_equal(env.control.inputs[INPUTS["pivot_force"]], force)

    def free_run(scene):
        sim = Simulator(scene, specialise=False)
        sim.set_state(state)
        sim.step(substeps, pivot_force=force, body_torque=env.setup.torque_limit * action[3:])
        return sim.state.r

    assert np.array_equal(free_run(rebuilt), env.sim.state.r)
    assert not np.allclose(free_run(nominal.model_copy(update={"h": rebuilt.h})), env.sim.state.r, atol=1e-9)


def test_without_randomize_the_info_reports_the_nominal_scene():
    env = gym.make(ENV_ID)
    _, info = env.reset(seed=0)
    assert info["scene_params"] == nominal_values(load_scene("drone_load"))


def test_user_ranges_replace_the_defaults_and_a_fixed_value_stays():
    env = gym.make(ENV_ID, randomize={"EA": (1e3, 4e3), "load_mass": (0.8, 0.8)}).unwrapped
    p = [env.reset(seed=s)[1]["scene_params"] for s in range(30)]
    assert all(1e3 <= q["EA"] <= 4e3 and q["load_mass"] == 0.8 for q in p)
    assert len({q["string_length"] for q in p}) == 30  # the others keep their default ranges
    # the step is each episode's own: the largest dividing 20 ms under half its stability bound
    steps = set()
    for s in range(30):
        env.reset(seed=s)
        steps.add(round(0.02 / env.scene.h))
        assert 0.02 / env.scene.h == pytest.approx(scheme_substeps(env.scene, 0.02, 0.5), abs=1e-9)
    assert len(steps) > 5


@pytest.mark.parametrize("randomize, match", [
    ({"stiffness": (1.0, 2.0)}, "unknown parameter 'stiffness'"),
    ({"EA": 200.0}, "EA must be a pair"),
    ({"EA": (400.0, 200.0)}, "EA: low 400.0 > high 200.0"),
    ({"EA": (-1.0, 200.0)}, "EA must be > 0"),
    ({"EA": (True, 200.0)}, "EA must hold two real numbers"),
    ({"EA": ("100", 200.0)}, "EA must hold two real numbers"),
    ({"load_mass": (0.1, math.inf)}, "load_mass must be finite"),
    ({"load_mass": (1e-12, 1.0)}, "(?s)invalid scene at the lows of the randomize ranges.*body.mass"),
    ({"attachment_offset_x": (-1e4, 1e4)}, "attachment_offset_x reaches 10000 m, off the load's face"),
    ({"attachment_offset_y": (0.0, 0.06)}, r"attachment_offset_y reaches 0.06 m, off the load's face \(half its y"),
    ({"EA": {100.0, 200.0}}, "EA must be a pair .* a tuple, list or array"),
    # ranges under which the load cannot hang: every episode would end at its first step
    ({"EA": (1e-3, 1e-2)}, "the load cannot hang: .*\\(EA = 0.001 N\\)"),
    ({"load_mass": (1e9, 1e9)}, "the load cannot hang"),
    ({"string_length": (1e5, 1e5)}, "the load cannot hang"),
    ({"EA": (1e9, 1e9)}, "physics steps per step"),
    (1, "randomize must be False, True or a mapping"),
    ("yes", "randomize must be False, True or a mapping"),
])
def test_bad_ranges_are_named(randomize, match):
    with pytest.raises(ValueError, match=match):
        ElasticStringPendulumEnv(randomize=randomize)


@pytest.mark.parametrize("randomize, match", [
    # was accepted: every episode ended at step 1 (the drone's Cayley Newton did not converge)
    ({"drone_inertia_scale": (1e300, 1e300)}, "(?s)at the lows of the randomize ranges.*pivot.drone.inertia"),
    # the highs alone pass: the bound is m_q (2 l)^2, and here the lightest drone carries the largest inertia
    ({"drone_inertia_scale": (1.0, 5.0), "pivot_mass": (0.3, 1.5)},
     "(?s)largest drone inertia, lightest drone.*pivot.drone.inertia"),
])
def test_drone_ranges_beyond_a_drone_are_named(randomize, match):
    with pytest.raises(ValueError, match=match):
        ElasticStringPendulumEnv(scene="quadrotor_load", randomize=randomize)
    # negative control: the same scales on a drone heavy enough for them (m_q (2 l)^2 = 0.363 kg m^2
    # at 1.5 kg against 5 x 0.0552), and the defaults
    ElasticStringPendulumEnv(scene="quadrotor_load", randomize={"drone_inertia_scale": (1.0, 5.0)})
    ElasticStringPendulumEnv(scene="quadrotor_load", randomize=True)


def test_the_hanging_check_has_its_edge_where_it_says():
    """The stretch g (M + mu l) / EA of the ranges' worst corner against half the task's limit
    (0.25 of the length): just under it the environment is made, just over it refused; the
    nominal scene is checked the same way."""
    weight = 9.81 * (2 * 0.5 + 2 * 0.05 * 1.25)  # the default ranges' heaviest load and string
    ElasticStringPendulumEnv(randomize={"EA": (weight / 0.2499, 200.0)})
    with pytest.raises(ValueError, match="the load cannot hang"):
        ElasticStringPendulumEnv(randomize={"EA": (weight / 0.2501, 200.0)})
    nominal = 9.81 * (0.5 + 0.05)
    ElasticStringPendulumEnv(scene_overrides={"string": {"EA": nominal / 0.2499}})
    with pytest.raises(ValueError, match="the load cannot hang: its weight 5.396 N"):
        ElasticStringPendulumEnv(scene_overrides={"string": {"EA": nominal / 0.2501}})


def test_a_box_only_range_on_another_load_is_refused():
    overrides = {"body": {"shape": {"kind": "sphere", "radius": 0.1}}}
    env = ElasticStringPendulumEnv(scene_overrides=overrides, randomize=True)  # sizes are left out
    assert math.isnan(env.reset(seed=0)[1]["scene_params"]["load_size_x"])
    with pytest.raises(ValueError, match="load_size_x needs a box-shaped load"):
        ElasticStringPendulumEnv(scene_overrides=overrides, randomize={"load_size_x": (0.1, 0.2)})


def test_a_fixed_h_must_be_stable_for_the_stiffest_string_of_the_ranges():
    ElasticStringPendulumEnv(h=0.0005, randomize={"EA": (100.0, 250.0)})
    with pytest.raises(ValueError, match="stiffest string of the randomize ranges"):
        ElasticStringPendulumEnv(h=0.0005, randomize={"EA": (100.0, 1000.0)})


@pytest.mark.parametrize("task", ["stabilize", "transport"])
def test_env_checkers_pass_with_randomize(task):
    gym_check_env(gym.make(ENV_ID, task=task, randomize=True).unwrapped, skip_render_check=True)
    sb3_check_env(gym.make(ENV_ID, task=task, randomize=True).unwrapped, warn=True)


def test_a_nan_action_changes_nothing_with_randomize():
    env = gym.make(ENV_ID, randomize=True).unwrapped
    env.reset(seed=2)
    before = env.sim.state
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.0, np.nan, 0, 0, 0, 0]))
    assert np.array_equal(before.r, env.sim.state.r) and np.array_equal(before.p, env.sim.state.p)


def test_a_randomised_reset_costs_at_most_two_and_a_half_plain_ones():
    """Draw, scene, constants, step count, state and first observation, against a plain reset:
    medians of 200 each, interleaved in one run (the machine's speed swings 2x between runs:
    0.29-0.62 ms plain, 0.61-1.2 ms randomised; the ratio stays 1.9-2.1)."""
    envs = [gym.make(ENV_ID, randomize=randomize).unwrapped for randomize in (False, True)]
    times = [[], []]
    for env in envs:
        env.reset(seed=0)
    for _ in range(200):
        for env, kept in zip(envs, times):
            t = time.perf_counter()
            env.reset()
            kept.append(time.perf_counter() - t)
    plain, randomised = (np.median(kept) for kept in times)
    assert randomised < 2.5 * plain, (randomised, plain)
