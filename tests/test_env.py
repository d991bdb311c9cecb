"""ElasticStringPendulum-v0: API conformance, determinism, reward bookkeeping, failure paths,
and the batched environments against the single one."""
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import esp_gym
from esp_gym.pendulum.env import ElasticStringPendulumEnv
from esp_gym.kernels.env.arrays import REWARD_TERMS
from esp_gym.pendulum.sb3_vector import ElasticStringPendulumSB3VecEnv

ENV_ID = "ElasticStringPendulum-v0"


def _rollout(env, actions, seed):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, te, tr, info = env.step(a)
        out.append((obs, r, te, tr))
        if te or tr:
            break
    return out


def _same(a, b):
    return all(np.array_equal(x[0], y[0]) and x[1:] == y[1:] for x, y in zip(a[1:], b[1:])) and np.array_equal(a[0], b[0])


@pytest.mark.parametrize("task", ["stabilize", "transport"])
def test_gymnasium_env_checker_passes(task):
    env = gym.make(ENV_ID, task=task)
    gym_check_env(env.unwrapped, skip_render_check=True)


def test_sb3_env_checker_passes():
    sb3_check_env(gym.make(ENV_ID).unwrapped, warn=True)


def test_make_with_module_prefix_and_spaces():
    env = gym.make("esp_gym:ElasticStringPendulum-v0")
    assert env.spec.max_episode_steps == 500
    assert env.action_space.shape == (6,) and env.action_space.dtype == np.float32
    assert env.observation_space.shape == (22,) and env.observation_space.dtype == np.float32
    u = env.unwrapped
    assert u.setup.substeps * u.scene.h == pytest.approx(0.02, rel=1e-12)
    assert u.scene.h <= 0.5 * u.scene.stability_bound
    assert (u.setup.substeps - 1) * 0.5 * u.scene.stability_bound < 0.02  # the largest such h


def test_zero_action_holds_the_system_up():
    """The hover feed-forward equals the total weight: with a = 0 the vertical momentum of the
    whole system does not change (only the initial velocities move it)."""
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=3)
    p0 = env.sim.diagnostics()["linear_momentum"][2]
    for _ in range(50):
        env.step(np.zeros(6))
    assert env.sim.diagnostics()["linear_momentum"][2] == pytest.approx(p0, abs=1e-12)


def test_seeded_rollouts_are_deterministic():
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (100, 6)).astype(np.float32)
    a = _rollout(gym.make(ENV_ID), actions, seed=42)
    b = _rollout(gym.make(ENV_ID), actions, seed=42)
    c = _rollout(gym.make(ENV_ID), actions, seed=43)
    assert _same(a, b)
    assert not np.array_equal(a[0], c[0])


def test_pickle_round_trip_continues_identically():
    env = gym.make(ENV_ID)
    env.reset(seed=5)
    env.action_space.seed(5)
    for _ in range(10):
        env.step(env.action_space.sample())
    clone = pickle.loads(pickle.dumps(env))
    rng = np.random.default_rng(1)
    for _ in range(30):
        a = rng.uniform(-1, 1, 6)
        x, y = env.step(a), clone.step(a)
        assert np.array_equal(x[0], y[0]) and x[1:4] == y[1:4]


@pytest.mark.parametrize("task", ["stabilize", "transport"])
def test_reward_terms_sum_exactly_and_are_bounded(task):
    env = gym.make(ENV_ID, task=task)
    env.reset(seed=7)
    env.action_space.seed(7)
    w_max = env.unwrapped.setup.task.max_reward
    for _ in range(100):
        _, r, te, tr, info = env.step(env.action_space.sample())
        terms = [info["reward_" + k] for k in REWARD_TERMS]
        assert sum(terms) == r
        assert -0.1 <= r <= w_max <= 1.0
        if te or tr:
            env.reset()


def test_the_features_the_reward_reads_are_the_states():
    """``load_position()`` and ``swing_angle()`` read the features the compiled step computed for
    the reward (kernels/env/task_terms.py): the load's centre r_N + R rho_c and the angle of
    (load - pivot) from +e3 agree with the state to 1e-12 after reset and every step, and the
    swing term is its weight times the tolerance 1/(1 + (swing/scale)^2) to round-off.
    Negative control: after the state is moved behind the environment's back, the features
    keep the last step's values."""
    env = gym.make(ENV_ID, task="transport").unwrapped
    env.reset(seed=3)
    task = env.setup.task
    for k in range(30):
        if k:
            _, _, terminated, _, info = env.step(np.full(6, 0.4 * (-1) ** (k // 10), dtype=np.float32))
            assert not terminated
            shaped = task.w_swing / (1.0 + (env.swing_angle() / task.scale_swing) ** 2)
            assert info["reward_swing"] == pytest.approx(shaped, rel=1e-14, abs=1e-15)
        state = env.sim.state
        load = state.r[-1] + state.R @ np.asarray(env.scene.body.rho_c)
        d = load - state.r[0]
        assert np.max(np.abs(env.load_position() - load)) < 1e-12
        assert abs(env.swing_angle() - np.arctan2(np.hypot(d[0], d[1]), d[2])) < 1e-12
    assert env.swing_angle() > 0.01
    moved = env.sim.state
    moved.r[:, 0] += 0.5
    env.sim.set_state(moved)
    assert np.max(np.abs(env.load_position() - (moved.r[-1] + moved.R @ np.asarray(env.scene.body.rho_c)))) > 0.4


@pytest.mark.parametrize("bad, match", [
    (np.zeros(5), "shape"), (np.zeros((1, 6)), "shape"),
    (np.array([0, 0, np.nan, 0, 0, 0]), "finite"), (np.array([np.inf, 0, 0, 0, 0, 0]), "finite"),
])
def test_bad_actions_raise_and_leave_the_state_untouched(bad, match):
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=0)
    before = env.sim.state
    with pytest.raises(ValueError, match=match):
        env.step(bad)
    after = env.sim.state
    assert np.array_equal(before.r, after.r) and before.step == after.step


def test_out_of_range_actions_are_clipped():
    a, b = gym.make(ENV_ID).unwrapped, gym.make(ENV_ID).unwrapped
    a.reset(seed=1)
    b.reset(seed=1)
    big = np.array([3.0, -7.0, 2.0, 1.5, -1.5, 9.0])
    assert np.array_equal(a.step(big)[0], b.step(np.clip(big, -1, 1))[0])


def test_any_array_layout_of_an_action_steps_the_same():
    """The compiled step takes C-contiguous writeable float64: strided, read-only, float32 and
    list actions are converted, and step exactly as the plain array does."""
    base = np.array([0.375, -0.25, 0.5, 0.125, -0.375, 0.25])  # exact in float32
    strided = np.zeros(12)
    strided[::2] = base
    frozen = base.copy()
    frozen.flags.writeable = False
    results = []
    for action in (base, strided[::2], frozen, base.astype(np.float32), base.tolist()):
        env = gym.make(ENV_ID).unwrapped
        env.reset(seed=4)
        results.append(env.step(action)[0])
    for obs in results[1:]:
        assert np.array_equal(obs, results[0])


def test_physics_failure_terminates_with_a_reason_and_reset_recovers():
    env = gym.make(ENV_ID, torque_limit=1e4)  # absurd torque: Newton cannot follow the spin
    env.reset(seed=1)
    obs, r, terminated, truncated, info = env.step(np.array([0, 0, 0, 1, 1, 1.0]))
    assert terminated and not truncated
    assert info["termination_reason"].startswith("physics_failure")
    assert np.all(np.isfinite(obs)) and np.isfinite(r)
    obs, _ = env.reset(seed=2)
    assert np.all(np.isfinite(obs))
    assert not env.step(np.zeros(6))[2]


def test_overstretch_terminates():
    env = gym.make(ENV_ID, force_limit=1e4)
    env.reset(seed=1)
    _, _, terminated, _, info = env.step(np.array([1.0, 0, 0, 0, 0, 0]))
    assert terminated and info["termination_reason"] == "string_overstretched"


def test_time_limit_truncates():
    env = gym.make(ENV_ID, max_episode_steps=5)
    env.reset(seed=0)
    flags = [env.step(np.zeros(6))[3] for _ in range(5)]
    assert flags == [False] * 4 + [True]


@pytest.mark.parametrize("kwargs, match", [
    (dict(task="juggle"), "unknown task"),
    (dict(scene="paper_example"), "needs pivot.kind: free"),
    (dict(h=3e-3), "must divide the control period"),
    (dict(h=2e-3), "exceeds the stability bound"),
    (dict(control_period=-1.0), "control_period"),
    (dict(scene_overrides={"N": 0}), "string.elements"),
    (dict(render_mode="ansi"), "render_mode"),
])
def test_bad_arguments_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ElasticStringPendulumEnv(**kwargs)


@pytest.mark.parametrize("kind", ["gymnasium", "sb3"])
def test_vector_bad_actions_raise_and_change_nothing(kind):
    """A NaN in one row, or a wrong shape, raises before any sub-environment steps or
    autoresets: the next good step equals that of a twin that never saw the bad call (with
    episodes of 2 steps, so sub-environments are due to reset when the bad call comes)."""
    def make():
        if kind == "gymnasium":
            env = gym.make_vec(ENV_ID, num_envs=3, max_episode_steps=2)
            env.reset(seed=5)
            return lambda a: env.step(a)[0]
        env = ElasticStringPendulumSB3VecEnv(num_envs=3, max_episode_steps=2)
        env.seed(5)
        env.reset()
        return lambda a: env.step(a)[0]

    good = np.full((3, 6), 0.25)
    bad = good.copy()
    bad[1, 4] = np.nan
    step, twin = make(), make()
    for _ in range(2):
        assert np.array_equal(step(good), twin(good))
    with pytest.raises(ValueError, match="finite"):
        step(bad)
    with pytest.raises(ValueError, match="shape"):
        step(good[:2])
    assert np.array_equal(step(good), twin(good))


#: The options the batched envs must reproduce bit for bit: the plain env, and every episode's
#: physics drawn anew (each sub-environment then runs its own constants and step count).
VECTOR_OPTIONS = [{}, {"randomize": True},
                  {"randomize": True, "observation": "hook", "sensor_noise": 1.0, "action_latency": 2},
                  {"preset": "hard"}, {"task": "track", "randomize": True},
                  {"task": "lower", "winch": True, "preset": "hard"},
                  {"task": "lower", "scene_overrides": {"solver": {"string": "implicit"}, "EA": 2e4}},
                  {"randomize": True, "scene_overrides": {"string": {"EA": 2e5, "elements": "auto"}}},
                  {"scene": "quadrotor_load"}, {"scene": "quadrotor_load", "actuation": "motors", "preset": "hard"},
                  {"scene": "quadrotor_load", "task": "lower", "preset": "hard"},
                  {"scene": "quadrotor_load", "preset": "hard",
                   "scene_overrides": {"pivot": {"drone": {"rho_q": [0.02, -0.01, -0.06]}}}}]
VECTOR_IDS = ["plain", "randomize", "hook-noise-latency", "hard", "track", "winch-lower-hard", "winch-lower-implicit",
              "randomize-auto", "drone-rates", "drone-motors-hard", "drone-winch-lower-hard", "drone-offset-hook-hard"]


@pytest.mark.parametrize("options", VECTOR_OPTIONS, ids=VECTOR_IDS)
def test_vector_env_equals_single_envs_bit_for_bit(options):
    """gymnasium.make_vec uses the batched entry point; with seeds s+i and the same actions each
    sub-environment reproduces a single env exactly, through next-step autoresets (and reports
    the same scene_params at each reset)."""
    B, T = 4, 60
    venv = gym.make_vec(ENV_ID, num_envs=B, max_episode_steps=T, **options)
    assert type(venv).__name__ == "ElasticStringPendulumVectorEnv"
    envs = [gym.make(ENV_ID, max_episode_steps=T, **options) for _ in range(B)]
    vo, vinfo = venv.reset(seed=10)
    singles = [e.reset(seed=10 + i) for i, e in enumerate(envs)]
    assert np.array_equal(vo, np.stack([o for o, _ in singles]))
    for name, values in vinfo["scene_params"].items():
        assert values.tolist() == [info["scene_params"][name] for _, info in singles]
    rng = np.random.default_rng(0)
    done = [False] * B
    ended = 0
    for _ in range(150):
        a = rng.uniform(-1.2, 1.2, (B,) + venv.single_action_space.shape).astype(np.float32)
        vo, vr, vte, vtr, vi = venv.step(a)
        for i, e in enumerate(envs):
            if done[i]:
                o, info = e.reset()
                r, te, tr = 0.0, False, False
                assert vi["_scene_params"][i]
                assert {k: v[i] for k, v in vi["scene_params"].items()} == info["scene_params"]
            else:
                o, r, te, tr, _ = e.step(a[i])
            assert np.array_equal(o, vo[i]) and (r, te, tr) == (vr[i], vte[i], vtr[i])
            done[i] = te or tr
            ended += done[i]
    assert ended >= B  # autoreset was exercised


@pytest.mark.parametrize("options", VECTOR_OPTIONS, ids=VECTOR_IDS)
def test_sb3_vec_env_equals_single_envs_with_immediate_reset(options):
    B, T = 3, 40
    vec = ElasticStringPendulumSB3VecEnv(num_envs=B, max_episode_steps=T, **options)
    vec.seed(20)
    envs = [gym.make(ENV_ID, max_episode_steps=T, **options) for _ in range(B)]
    singles = [e.reset(seed=20 + i) for i, e in enumerate(envs)]
    assert np.array_equal(vec.reset(), np.stack([o for o, _ in singles]))
    assert vec.reset_infos == [info for _, info in singles]
    rng = np.random.default_rng(2)
    for _ in range(100):
        a = rng.uniform(-1, 1, (B,) + vec.action_space.shape).astype(np.float32)
        obs, rew, dones, infos = vec.step(a)
        for i, e in enumerate(envs):
            o, r, te, tr, _ = e.step(a[i])
            assert np.float32(r) == rew[i] and (te or tr) == dones[i]
            if te or tr:
                assert np.array_equal(infos[i]["terminal_observation"], o)
                assert infos[i]["TimeLimit.truncated"] == (tr and not te)
                o, info = e.reset()
                assert vec.reset_infos[i] == info
            assert np.array_equal(o, obs[i])


def test_rgb_array_render_gives_frames():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    env.action_space.seed(0)
    frames = []
    for _ in range(3):
        env.step(env.action_space.sample())
        frames.append(env.render())
    assert all(f.dtype == np.uint8 and f.ndim == 3 and f.shape[2] == 3 for f in frames)
    assert not np.array_equal(frames[0], frames[-1])  # the scene moves
    assert gym.make(ENV_ID).unwrapped.render() is None  # no render_mode: nothing


def test_observation_structure_names_the_observation_of_a_known_state():
    """Each named slice of ``observation_structure`` holds what its name says, recomputed in
    NumPy from the simulator's state and diagnostics (a swapped or shifted slice fails)."""
    env = gym.make(ENV_ID).unwrapped
    obs, _ = env.reset(seed=11)
    obs, *_ = env.step(np.array([0.3, -0.2, 0.1, 0.5, -0.4, 0.2]))
    structure = env.observation_structure
    # the slices tile the observation in order
    stops = [0] + [s.stop for s in structure.values()]
    assert [s.start for s in structure.values()] == stops[:-1] and stops[-1] == env.observation_space.shape[0]
    st, d = env.sim.state, env.sim.diagnostics()
    rho = np.asarray(env.scene.body.rho_c)
    target = env.target
    expected = {
        "pivot_position_error": st.r[0] - target[:3],
        "pivot_velocity": _pivot_velocity(env),
        "load_position_error": st.r[-1] + st.R @ rho - target[3:],
        "load_velocity": d["attach_velocity"] + st.R @ np.cross(d["omega"], rho),
        "attitude_6d": np.concatenate([st.R[:, 0], st.R[:, 1]]),
        "angular_velocity": d["omega"],
        "string_stretch": [d["stretched_length"] / env.scene.string.length - 1.0],
    }
    assert set(expected) == set(structure)
    for name, value in expected.items():
        # float32 observation of float64 values computed in another order: a few ulps of float32
        np.testing.assert_allclose(obs[structure[name]], value, rtol=1e-6, atol=1e-6, err_msg=name)
    # negative control: a neighbouring slice does not match (the test can fail)
    assert not np.allclose(obs[structure["pivot_velocity"]], expected["load_velocity"], rtol=1e-6, atol=1e-6)


def _pivot_velocity(env) -> np.ndarray:
    """Velocity of node 0 (the free pivot) from the simulator's live diagnostics arrays."""
    env.sim.diagnostics()
    return env.sim.buffers.diag.V[0].copy()
