"""Wind and pushes (``wind=``, esp_gym/pendulum/wind.py, kernels/step/disturbance.py): the balances close with
the drag and push forces in them (energy at O(h^2), momentum and pi3 to round-off), the drag is
the documented law, seeded episodes repeat bit for bit past a block of draws, and bad options
are errors naming them. (Batched against single envs with wind: tests/test_env.py.)"""
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import esp_gym  # noqa: F401  (registers the env)
from benchmarks.wind_balance import WIND, balances
from esp_gym.kernels.step.disturbance import load_area
from esp_gym.kernels.env.arrays import OBSERVATION, TARGET
from esp_gym.kernels.step.disturbance import DISTURBANCE, DISTURBANCE_PARAMS
from esp_gym.scene.params import scene_from_dict
from esp_gym.pendulum.env_setup import PRESETS
from esp_gym.physics.state import State
from esp_gym.pendulum.vector import ElasticStringPendulumVectorEnv
from esp_gym.pendulum.wind import BLOCK, LINE_DENSITY, Wind, WindOptions, drag_areas

ENV_ID = "ElasticStringPendulum-v0"
GUSTY = WIND  # 6 m/s, 1.5 m/s gusts, five pushes a second
#: The pivot's position error and velocity: the same slices in the full and the hook observation.
ERROR, VELOCITY = OBSERVATION["pivot_position_error"], OBSERVATION["pivot_velocity"]


def test_energy_balance_with_wind_and_pushes_closes_at_order_two():
    """The residual E - E0 - W (W: the inputs' work and the held drag and push forces', exact
    for a held force: Phi(end) - Phi(start)) is the scheme's energy error, O(h^2): measured
    ratios 3.94 and 4.02 per halving (h = 556, 278, 139 us), while the external forces do
    work of order 1 J."""
    rows = [balances(nsub, 100) for nsub in (36, 72, 144)]
    ratios = [rows[i]["energy_residual_J"] / rows[i + 1]["energy_residual_J"] for i in range(2)]
    assert all(3.5 < q < 4.5 for q in ratios), ratios
    assert rows[0]["energy_residual_J"] < 1e-5 < 1.0 < abs(rows[0]["work_J"])


def test_momentum_and_pi3_balances_close_to_round_off_with_drag_and_push_impulses():
    row = balances(36, 150)
    # round-off of ~5e3 kicks of momenta ~1 kg m/s
    assert row["momentum_residual"] < 1e-11 and row["pi3_residual"] < 1e-11
    # negative control: without the external impulse the balance is off by it
    assert np.abs(row["external_impulse"]).max() > 0.1


def _still_env(speed=5.0, direction=0.0, **wind):
    """An env whose state is a straight vertical string at rest under the load (R = I)."""
    env = gym.make(ENV_ID, wind={"speed": speed, "direction": direction, "gust_std": 0.0, **wind}).unwrapped
    env.reset(seed=0)
    scene = env.scene
    n, length = scene.string.elements, scene.string.length
    r = np.zeros((n + 1, 3))
    r[:, 2] = np.linspace(0.0, length, n + 1)
    env.control.reset(State(r, np.zeros((n + 1, 3)), np.eye(3), np.zeros(3)), np.zeros(TARGET.size))
    return env


def test_drag_of_a_still_system_in_steady_wind_is_the_documented_law():
    """Line: cross-flow drag rho C_d d L |w| w / 2 with d from the mass per length; load: rho C_d
    A |w| w / 2 with A the box's face across the wind."""
    env = _still_env(speed=5.0, direction=0.0)
    env.step(np.zeros(6))
    ds = env.control.disturbance
    scene, o = env.scene, WindOptions()
    d = math.sqrt(4 * scene.string.mass_per_length / (math.pi * LINE_DENSITY))
    line = 0.5 * o.air_density * o.line_drag_coefficient * d * scene.string.length * 25.0
    np.testing.assert_allclose(ds[DISTURBANCE["line_drag"]], [line, 0, 0], rtol=1e-12, atol=1e-15)
    x, y, z = scene.body.shape.size
    load = 0.5 * o.air_density * o.load_drag_coefficient * y * z * 25.0
    np.testing.assert_allclose(ds[DISTURBANCE["load_drag"]], [load, 0, 0], rtol=1e-12, atol=1e-15)


def _projected_area(shape, n, samples=400):
    """Half the surface integral of |n . dA| (a convex body's projected area), by quadrature."""
    from esp_gym.scene.params import Box
    if isinstance(shape, Box):
        size = np.asarray(shape.size)
        return sum(size[(i + 1) % 3] * size[(i + 2) % 3] * abs(n[i]) for i in range(3))
    a, b = (shape.radius, shape.radius) if hasattr(shape, "radius") else shape.semi_axes
    t = (np.arange(samples) + 0.5) * 2 * np.pi / samples
    # lateral surface: outward normal of the ellipse (b cos t, a sin t) per unit t, times the height
    lateral = shape.height * np.sum(np.abs(n[0] * b * np.cos(t) + n[1] * a * np.sin(t))) * 2 * np.pi / samples
    return 0.5 * (lateral + 2 * np.pi * a * b * abs(n[2]))


@pytest.mark.parametrize("shape", [{"kind": "box", "size": [0.2, 0.15, 0.1]},
                                   {"kind": "cylinder", "radius": 0.07, "height": 0.2},
                                   {"kind": "elliptic_cylinder", "semi_axes": [0.1, 0.04], "height": 0.15}])
def test_load_drag_area_is_the_projected_area(shape):
    scene = scene_from_dict({"string": {"length": 1.0, "mass_per_length": 0.05, "EA": 200.0, "elements": 4},
                             "body": {"mass": 0.5, "rho_c": [0.0, 0.0, 0.05], "shape": shape},
                             "pivot": {"kind": "free", "mass": 1.0}, "h": 5e-4})
    dp = np.zeros(DISTURBANCE_PARAMS.size)
    areas = drag_areas(scene)
    dp[DISTURBANCE_PARAMS["load_faces"]] = areas.faces
    dp[DISTURBANCE_PARAMS["load_side"]] = areas.side
    dp[DISTURBANCE_PARAMS["load_semi_axes"]] = areas.semi_axes
    for n in np.random.default_rng(1).normal(size=(20, 3)):
        n /= np.linalg.norm(n)
        assert load_area(dp, *n) == pytest.approx(_projected_area(scene.body.shape, n), rel=1e-4)


def test_pushes_are_horizontal_and_of_the_documented_size():
    env = gym.make(ENV_ID, wind={"speed": 0.0, "gust_std": 0.0, "push_rate": 1e4, "push_speed": 0.5}).unwrapped
    env.reset(seed=1)
    mean = env.scene.body.mass * 0.5 / env.setup.control_period
    sizes = []
    for _ in range(40):
        env.step(np.zeros(6))
        push = env.control.disturbance[DISTURBANCE["push"]]
        assert push[2] == 0.0
        sizes.append(np.hypot(push[0], push[1]) / mean)
    assert 0.5 <= min(sizes) and max(sizes) <= 1.5 and max(sizes) - min(sizes) > 0.5


def _episode(env, seed, steps):
    """A seeded episode under a PD law on the pivot's (observed) position error and velocity,
    plus small random actions: (reset info, observations and rewards)."""
    obs, info = env.reset(seed=seed)
    out = [obs]
    noise = np.random.default_rng(2).uniform(-0.1, 0.1, (steps, 6))
    for k in range(steps):
        a = noise[k].copy()
        a[:3] -= np.clip(1.0 * obs[ERROR] + 0.9 * obs[VELOCITY], -0.8, 0.8)
        obs, r, te, tr, _ = env.step(a)
        out.append(np.append(obs, r))
        if te:
            break
    return info, np.concatenate(out)


def test_seeded_windy_episodes_repeat_bit_for_bit_past_a_block_of_draws():
    steps = BLOCK + 44
    ia, a = _episode(gym.make(ENV_ID, preset="hard"), 5, steps)
    ib, b = _episode(gym.make(ENV_ID, preset="hard"), 5, steps)
    assert ia == ib and np.array_equal(a, b) and a.size > BLOCK * 12
    ic, c = _episode(gym.make(ENV_ID, preset="hard"), 6, steps)  # negative control
    assert ic != ia and not np.array_equal(a[:c.size], c[:a.size])
    assert set(ia["scene_params"]) >= {"string_length", "EA", "load_mass", "wind_speed", "wind_direction"}


def test_batched_env_equals_single_envs_past_a_block_of_draws():
    B, steps = 2, BLOCK + 20
    venv = ElasticStringPendulumVectorEnv(num_envs=B, max_episode_steps=None, wind=GUSTY, randomize=True)
    envs = [gym.make(ENV_ID, wind=GUSTY, randomize=True).unwrapped for _ in range(B)]
    obs, _ = venv.reset(seed=11)
    assert np.array_equal(obs, np.stack([e.reset(seed=11 + i)[0] for i, e in enumerate(envs)]))
    noise = np.random.default_rng(3).uniform(-0.1, 0.1, (steps, B, 6))
    for k in range(steps):
        a = noise[k].copy()
        a[:, :3] -= np.clip(obs[:, ERROR] + 0.9 * obs[:, VELOCITY], -0.8, 0.8)  # a PD law: no episode ends
        obs, _, terminated, *_ = venv.step(a)
        single = np.stack([e.step(a[i])[0] for i, e in enumerate(envs)])
        assert np.array_equal(obs, single) and not terminated.any()


def test_env_checkers_pass_with_the_hard_preset():
    gym_check_env(gym.make(ENV_ID, preset="hard").unwrapped, skip_render_check=True)
    sb3_check_env(gym.make(ENV_ID, preset="hard").unwrapped, warn=True)


def test_nan_action_with_wind_changes_nothing():
    env = gym.make(ENV_ID, wind=GUSTY).unwrapped
    env.reset(seed=0)
    env.step(np.zeros(6))
    before = (env.sim.state, env.control.disturbance.copy())
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0, 0, 0, 0, 0]))
    after = env.sim.state
    assert np.array_equal(before[0].p, after.p) and np.array_equal(before[1], env.control.disturbance)


@pytest.mark.parametrize("wind, match", [
    (True, "wind must be a speed"), ("5", "wind must be a speed"), (-1.0, "wind: speed"),
    (float("nan"), "wind: speed"), ({"sped": 3.0}, "unknown argument 'sped'"),
    ({"gust_time": 0.0}, "wind: gust_time"), ({"push_rate": -1}, "wind: push_rate"),
    ({"speed": 2.0, "line_diameter": "thin"}, "wind: line_diameter")])
def test_bad_wind_options_are_errors_naming_them(wind, match):
    with pytest.raises(ValueError, match=match):
        gym.make(ENV_ID, wind=wind)


def test_wind_needs_the_load_shape_and_presets_are_checked():
    shapeless = scene_from_dict({"string": {"length": 1.0, "mass_per_length": 0.05, "EA": 200.0, "elements": 4},
                                 "body": {"mass": 0.5, "rho_c": [0.0, 0.0, 0.05], "inertia": np.diag([3e-3, 3e-3, 1e-3])},
                                 "pivot": {"kind": "free", "mass": 1.0}, "h": 5e-4})
    gym.make(ENV_ID, scene=shapeless)
    with pytest.raises(ValueError, match="body.shape"):
        gym.make(ENV_ID, wind=3.0, scene=shapeless)
    with pytest.raises(ValueError, match="preset"):
        gym.make(ENV_ID, preset="easy")
    env = gym.make(ENV_ID, preset="hard").unwrapped
    assert env.setup.observer.mode == "hook" and env.setup.randomizer is not None
    assert env.setup.wind.options == WindOptions(**PRESETS["hard"]["wind"])
    assert env.setup.action_latency == 1


def test_options_given_with_a_preset_replace_its_own_even_at_their_defaults():
    """The preset fills only the options not given: an explicit value, the usual default
    included, wins (a hard environment with the full observation is what it says)."""
    full = gym.make(ENV_ID, preset="hard", observation="full").unwrapped.setup
    assert full.observer.mode == "full"
    assert full.randomizer is not None and full.wind is not None and full.action_latency == 1
    calm = gym.make(ENV_ID, preset="hard", wind=0.0, randomize=False, action_latency=0, sensor_noise=0.0).unwrapped.setup
    assert calm.wind is None and calm.randomizer is None and calm.action_latency == 0
    assert calm.observer.mode == "hook"
    assert gym.make(ENV_ID, preset="hard", randomize={"EA": (150.0, 250.0)}).unwrapped.setup.randomizer is not None
    # without a preset the options keep their usual defaults
    plain = gym.make(ENV_ID).unwrapped.setup
    assert plain.observer.mode == "full" and plain.wind is None and plain.randomizer is None


def test_still_air_is_the_plain_environment():
    """wind=0.0 (and a mapping with nothing on) runs the plain kernels: the same bits."""
    a, b = gym.make(ENV_ID), gym.make(ENV_ID, wind={"speed": 0.0, "gust_std": 0.0})
    assert b.unwrapped.setup.wind is None
    _, xa = _episode(a, 4, 30)
    _, xb = _episode(b, 4, 30)
    assert np.array_equal(xa, xb)


def test_wind_draws_come_from_the_generator_in_blocks():
    wind = Wind(WindOptions(speed=2.0), 0.02)
    assert Wind.draws(np.random.default_rng(0)).shape == (BLOCK, 6)
    scene = gym.make(ENV_ID).unwrapped.scene
    dp, ds, draws, info = wind.episode(scene, np.random.default_rng(0))
    assert info["wind_speed"] == 2.0 and 0 <= info["wind_direction"] < 2 * math.pi
    assert np.hypot(*dp[DISTURBANCE_PARAMS["mean_wind"]][:2]) == pytest.approx(2.0)
    assert np.all((draws[:, 3:] >= 0) & (draws[:, 3:] < 1))
