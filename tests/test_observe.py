"""Observation modes (``observation="hook"``), sensor noise and action latency
(esp_gym/pendulum/observe.py, esp_gym/pendulum/control.py). The batched envs with all of it on: tests/test_env.py."""
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import esp_gym  # noqa: F401  (registers the env)
from esp_gym.pendulum.env import ElasticStringPendulumEnv
from esp_gym.kernels.env.arrays import HOOK_OBSERVATION, OBSERVATION, TARGET
from esp_gym.pendulum.observe import UNIT_NOISE

ENV_ID = "ElasticStringPendulum-v0"
ACTIONS = np.random.default_rng(4).uniform(-1, 1, (60, 6))


def _first_element_force(env) -> np.ndarray:
    """The string's pull on the pivot from the state, written from the element law: kappa
    (|x_0| - u)_+ x_0/|x_0| (slack law)."""
    scene = env.scene
    r = env.sim.state.r
    x = r[1] - r[0]
    length = np.linalg.norm(x)
    return scene.string.kappa * max(length - scene.string.u, 0.0) * x / length


@pytest.mark.parametrize("randomize", [False, True])
def test_the_hook_tension_is_the_first_elements_force(randomize):
    env = gym.make(ENV_ID, observation="hook", randomize=randomize).unwrapped
    obs, _ = env.reset(seed=5)
    hook = HOOK_OBSERVATION["hook_tension"]
    for a in ACTIONS[:30]:
        force = _first_element_force(env)
        assert np.allclose(obs[hook], force, rtol=1e-6, atol=1e-6 * np.linalg.norm(force))  # float32
        assert np.allclose(env.control.sensors[:3], force, rtol=1e-12, atol=1e-12 * np.linalg.norm(force))
        obs, *_ = env.step(a)
    # negative control: the pivot node's whole force (gravity on the pivot included) is not it
    whole = env.sim.buffers.state.f[0]
    assert not np.allclose(env.control.sensors[:3], whole, rtol=1e-3)


def test_the_hook_observation_has_no_load_state_and_shares_the_pivots_fields():
    full = gym.make(ENV_ID).unwrapped
    hook = gym.make(ENV_ID, observation="hook").unwrapped
    assert hook.observation_space.shape == (HOOK_OBSERVATION.size,) == (12,)
    assert hook.observation_structure == HOOK_OBSERVATION.structure()
    assert not {"load_position_error", "load_velocity", "attitude_6d", "angular_velocity"} & set(
        hook.observation_structure)
    of, _ = full.reset(seed=2)
    oh, _ = hook.reset(seed=2)
    for a in ACTIONS[:10]:
        for name in ("pivot_position_error", "pivot_velocity"):
            assert np.array_equal(of[OBSERVATION[name]], oh[HOOK_OBSERVATION[name]])
        offset = hook.target[TARGET["load"]] - hook.sim.state.r[0]
        assert np.array_equal(oh[HOOK_OBSERVATION["load_target_offset"]], offset.astype(np.float32))
        of, *_ = full.step(a)
        oh, *_ = hook.step(a)


@pytest.mark.parametrize("mode", ["full", "hook"])
def test_sensor_noise_has_its_documented_deviation_and_leaves_the_physics_alone(mode):
    """Noise comes from np_random after the step: within an episode the state is that of the
    noiseless env bit for bit, and (noisy - clean) / std is standard normal."""
    clean = gym.make(ENV_ID, observation=mode).unwrapped
    noisy = gym.make(ENV_ID, observation=mode, sensor_noise=2.0).unwrapped
    std = noisy.setup.observer.noise_std
    layout = noisy.setup.observer.layout
    assert all(np.all(std[layout[name]] == 2.0 * UNIT_NOISE[name]) for name in layout.names)
    oc, _ = clean.reset(seed=9)
    on, _ = noisy.reset(seed=9)
    z = [(on.astype(float) - oc) / std]
    for a in ACTIONS:
        oc, *_ = clean.step(a)
        on, *_ = noisy.step(a)
        z.append((on.astype(float) - oc) / std)
        assert np.array_equal(clean.sim.state.r, noisy.sim.state.r)
    z = np.concatenate(z)
    assert abs(z.mean()) < 0.1 and abs(z.std() - 1.0) < 0.1  # 61 x 12..22 samples


def test_an_action_is_applied_latency_steps_later():
    """With action_latency=2 the env applies a_{t-2} (hover before that): its states equal those
    of an env without latency fed (0, 0, a_0, a_1, ...), bit for bit."""
    late = gym.make(ENV_ID, action_latency=2).unwrapped
    now = gym.make(ENV_ID).unwrapped
    late.reset(seed=1)
    now.reset(seed=1)
    delayed = np.concatenate([np.zeros((2, 6)), ACTIONS])
    for a, d in zip(ACTIONS[:40], delayed):
        late.step(a)
        now.step(d)
        assert np.array_equal(late.sim.state.r, now.sim.state.r)
        assert np.array_equal(late.control.action, now.control.action)  # the applied action
    # negative control: without the delay the states part
    free = gym.make(ENV_ID).unwrapped
    free.reset(seed=1)
    for a in ACTIONS[:3]:
        free.step(a)
    late.reset(seed=1)
    for a in ACTIONS[:3]:
        late.step(a)
    assert not np.array_equal(free.sim.state.r, late.sim.state.r)


def test_a_bad_action_with_latency_changes_nothing_not_even_the_queue():
    env, twin = (gym.make(ENV_ID, action_latency=3).unwrapped for _ in range(2))
    env.reset(seed=0)
    twin.reset(seed=0)
    for a in ACTIONS[:2]:
        env.step(a)
        twin.step(a)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.0, 0.0, np.nan, 0.0, 0.0, 0.0]))
    for a in ACTIONS[2:8]:
        assert np.array_equal(env.step(a)[0], twin.step(a)[0])


@pytest.mark.parametrize("options", [{"observation": "hook"},
                                     {"observation": "hook", "sensor_noise": 1.0, "action_latency": 2}])
def test_env_checkers_pass_in_the_hook_mode(options):
    gym_check_env(gym.make(ENV_ID, **options).unwrapped, skip_render_check=True)
    sb3_check_env(gym.make(ENV_ID, **options).unwrapped, warn=True)


@pytest.mark.parametrize("kwargs, match", [
    (dict(observation="camera"), "observation"),
    (dict(sensor_noise=-1.0), "sensor_noise must be finite and >= 0"),
    (dict(sensor_noise=True), "sensor_noise must be a real number"),
    (dict(sensor_noise=float("nan")), "sensor_noise must be finite"),
    (dict(observation="hook", sensor_noise={"load_velocity": 0.1}), "'load_velocity' is not a field of the 'hook'"),
    (dict(sensor_noise={"pivot_velocity": -0.1}), r"sensor_noise\['pivot_velocity'\] must be finite and >= 0"),
    (dict(action_latency=-1), "action_latency"),
    (dict(action_latency=1.5), "action_latency"),
    (dict(action_latency=True), "action_latency"),
    (dict(action_latency=51), "action_latency"),
])
def test_bad_observation_options_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ElasticStringPendulumEnv(**kwargs)
