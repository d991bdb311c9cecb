"""Bad arguments get clear errors that name them (issue 12): environment options, actions, batch
sizes, states, sizes the machine cannot hold; and what used to fail on valid input now runs
(centred loads, long strings, long step-size pilots)."""
from __future__ import annotations

import time
import tracemalloc

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import esp_gym
from esp_gym.physics import pilot
from esp_gym.pendulum.env import ElasticStringPendulumEnv
from esp_gym.kernels.step.string import tridiag_factor
from esp_gym.pendulum.options import MAX_SUBSTEPS
from esp_gym.pendulum.sb3_vector import ElasticStringPendulumSB3VecEnv
from esp_gym.physics.state import BYTES_PER_NODE, DAMPER_BYTES_PER_NODE, attachment_column, check_memory, mass_matrix
from esp_gym.pendulum.vector import ElasticStringPendulumVectorEnv


def _scene(name: str, elements: int):
    return esp_gym.load_scene(name, N=elements, allow_unstable_h=True)  # h is not used here


# -- environment options: one validation path --------------------------------------------------
@pytest.mark.parametrize("kwargs, named", [
    (dict(h=0.0), "h"), (dict(h=float("nan")), "h"), (dict(h=-1e-4), "h"),
    (dict(control_period="0.02"), "control_period"), (dict(control_period=True), "control_period"),
    (dict(control_period=0.0), "control_period"), (dict(control_period=float("inf")), "control_period"),
    (dict(safety=0.0), "safety"), (dict(safety=1.5), "safety"), (dict(safety=float("nan")), "safety"),
    (dict(force_limit=float("inf")), "force_limit"), (dict(force_limit=0.0), "force_limit"),
    (dict(torque_limit=float("inf")), "torque_limit"), (dict(torque_limit=-1.0), "torque_limit"),
    (dict(torque_limit="big"), "torque_limit"),
    # bounds that keep the observations and forces finite (a larger value meant NaN or inf)
    (dict(wind=1e160), "wind: speed"), (dict(wind={"speed": 5.0, "gust_std": 1e3}), "gust_std"),
    (dict(wind={"speed": 5.0, "air_density": 1e9}), "air_density"),
    (dict(wind={"push_rate": 1.0, "push_speed": 1e5}), "push_speed"),
    (dict(sensor_noise=1e40), r"sensor_noise must be finite and >= 0, at most 1e\+06"),
    (dict(observation="hook", sensor_noise={"hook_tension": 1e9}), "sensor_noise\\['hook_tension'\\]"),
])
def test_bad_environment_options_are_named(kwargs, named):
    with pytest.raises(ValueError, match=named):
        ElasticStringPendulumEnv(**kwargs)


def test_too_many_substeps_is_refused_with_the_reason():
    # safety = 1e-6 asked for 17.5 million physics steps per control step (14 s per step)
    with pytest.raises(ValueError, match=r"physics steps per step \(at most 100,000\).*safety"):
        ElasticStringPendulumEnv(safety=1e-6)
    with pytest.raises(ValueError, match=r"h = 1e-08 s"):
        ElasticStringPendulumEnv(h=1e-8)
    # negative control: just under the bound is accepted
    h = 0.02 / MAX_SUBSTEPS
    assert ElasticStringPendulumEnv(h=h).setup.substeps == MAX_SUBSTEPS


@pytest.mark.parametrize("num_envs", [2.5, True, "2", 0, -1])
def test_a_batch_size_must_be_a_whole_number(num_envs):
    for cls in (ElasticStringPendulumVectorEnv, ElasticStringPendulumSB3VecEnv):
        with pytest.raises(ValueError, match="num_envs"):
            cls(num_envs=num_envs)
    assert ElasticStringPendulumVectorEnv(num_envs=2.0).num_envs == 2  # an integral float is a count


def test_a_batch_too_large_for_memory_says_how_many_environments_were_asked_for():
    with pytest.raises(MemoryError, match=r"num_envs = 1000000000 environments .* GiB"):
        ElasticStringPendulumVectorEnv(num_envs=1e9)


@pytest.mark.parametrize("action", [
    np.zeros(6, dtype=complex) + 1j, np.ma.masked_array(np.zeros(6), mask=[1, 0, 0, 0, 0, 0]),
    np.array([None] * 6, dtype=object), np.zeros(6, dtype=bool)])
def test_actions_that_would_lose_information_are_refused(action):
    env = ElasticStringPendulumEnv()
    env.reset(seed=0)
    before = env.sim.state
    with pytest.raises(TypeError, match="action"):
        env.step(action)
    np.testing.assert_array_equal(env.sim.state.r, before.r)  # nothing changed
    env.step(np.zeros(6, dtype=np.int64))  # integers are real numbers: accepted


def test_stepping_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match=r"reset\(\) before step"):
        ElasticStringPendulumEnv().step(np.zeros(6))
    venv = ElasticStringPendulumSB3VecEnv(num_envs=2)
    venv.step_async(np.zeros((2, 6)))
    with pytest.raises(RuntimeError, match="reset"):
        venv.step_wait()


def test_a_centred_load_runs():
    """rho_c = 0 validated, then reset divided by |rho_c|: the episode sampler now puts a centred
    load's body z axis along the string. The actions are seeded: the residual after 50 random
    steps spreads from 2e-6 to 1.4e-3 J over action seeds 0-29 (median 4.5e-6 J), so an unseeded
    draw made the bound a lottery."""
    env = gym.make("ElasticStringPendulum-v0", scene_overrides={"rho_c": [0.0, 0.0, 0.0]})
    env.action_space.seed(1)
    obs, _ = env.reset(seed=1)
    for _ in range(50):
        obs, reward, terminated, _, _ = env.step(env.action_space.sample())
        assert np.all(np.isfinite(obs)) and not terminated
    assert abs(env.unwrapped.sim.diagnostics()["energy_balance_residual"]) < 1e-3  # J; O(h^2), E ~ 3 J


# -- states ---------------------------------------------------------------------------------------
def test_set_state_refuses_a_non_rotation():
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example"))
    st0 = sim.state
    sim.set_state(st0)  # negative control: its own state is accepted
    for R, why in ((2.0 * st0.R, "rotation"), (-st0.R, "det"), (st0.R + 1e-6, "rotation"),
                   (st0.R @ (np.eye(3) + 1e-6 * np.eye(3, k=1)), r"R\^T R - I")):  # sheared by 1e-6
        with pytest.raises(ValueError, match=why):
            sim.set_state(type(st0)(st0.r, st0.p, R, st0.Pi, 0))
    with pytest.raises(ValueError, match="real"):
        sim.set_state(type(st0)(st0.r.astype(complex), st0.p, st0.R, st0.Pi, 0))


# -- size: O(N) construction and a clear refusal ---------------------------------------------------
@pytest.mark.parametrize("name", ["paper_example", "paper_example_free_pivot", "drone_load", "short_stiff"])
@pytest.mark.parametrize("elements", [1, 7, 20, 300])
def test_the_attachment_column_solves_the_mass_matrix(name, elements):
    """w = M_tot^-1 e_{N+1} in O(N): it solves the tridiagonal system to round-off and has the
    bits of the dense LU solve it replaced (so the rollout hashes stay)."""
    scene = _scene(name, elements)
    diag, off, _ = mass_matrix(scene)
    first = 0 if scene.pivot.is_free else 1
    inv, cp = tridiag_factor(diag, off)
    w = attachment_column(diag, off, cp, first)
    k = diag.size - first
    dense = np.diag(diag[first:]) + off * (np.eye(k, k=1) + np.eye(k, k=-1))
    e = np.zeros(k)
    e[-1] = 1.0
    assert np.abs(dense @ w[first:] - e).max() < 1e-12 * np.abs(dense).max() * np.abs(w).max() * k
    np.testing.assert_array_equal(w[first:], np.linalg.solve(dense, e))
    assert np.all(w[:first] == 0.0)


@pytest.mark.parametrize("damped", [False, True])
def test_a_long_string_builds_in_linear_time_and_memory(damped):
    """N = 100,000 asked for 74.5 GiB (a dense (N+1)^2 solve); N = 8,000 took 23 s. A damped
    string holds its damper's arrays too, an undamped one none of them."""
    scene = _scene("paper_example", 100_000)
    if damped:
        scene = scene.model_copy(update={"string": scene.string.model_copy(update={"damping_time": 1e-3})})
    tracemalloc.start()
    start = time.perf_counter()
    esp_gym.Simulator(scene)
    seconds = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert seconds < 5.0
    assert peak < (BYTES_PER_NODE + (DAMPER_BYTES_PER_NODE if damped else 0)) * 100_001


def test_a_string_the_machine_cannot_hold_is_refused_before_allocating():
    with pytest.raises(MemoryError, match=r"string.elements = 1000000000000: .* GiB"):
        esp_gym.Simulator(_scene("paper_example", 10**12))
    with pytest.raises(MemoryError, match="num_envs = 1000000 environments"):
        check_memory(10**6, num_envs=10**6)
    check_memory(20)  # negative control


# -- choose_h: memory independent of the horizon ---------------------------------------------------
def test_the_step_size_pilot_memory_does_not_grow_with_the_horizon(monkeypatch):
    """choose_h kept every step's node positions (a 10 s horizon at 1e-6 m needed 11 GiB): its
    pilot pair now advances side by side in chunks."""
    scene = esp_gym.load_scene("paper_example")
    h = 5e-4
    whole = pilot.pilot_error(scene, h, 1.6)  # one chunk
    monkeypatch.setattr(pilot, "PILOT_CHUNK_FLOATS", 3 * 21 * 50)  # chunks of 50 steps
    peaks = []
    for horizon in (0.1, 1.6):
        tracemalloc.start()
        error = pilot.pilot_error(scene, h, horizon)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert error == whole  # chunking changes nothing, bit for bit
    # 16x the steps; keeping the path would take 16x the ~0.2 MB (3,200 samples x 2 runs x 504 B)
    assert peaks[1] < 1.5 * peaks[0], peaks


# -- fuzz: every outcome is a working env or a clear error -----------------------------------------
_numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 5), st.booleans(),
                     st.text(max_size=3), st.none())
_options = st.fixed_dictionaries({}, optional={
    "control_period": st.one_of(_numbers, st.sampled_from([0.01, 0.02, 0.05])),
    "h": st.one_of(_numbers, st.sampled_from([1e-3, 5e-4, 1e-4])),
    "safety": st.one_of(_numbers, st.floats(0.05, 1.0)),
    "force_limit": st.one_of(_numbers, st.floats(0.1, 50.0)),
    "torque_limit": st.one_of(_numbers, st.floats(0.0, 1.0)),
    "task": st.sampled_from(["stabilize", "transport", "hover", ""]),
})


@settings(max_examples=60, deadline=None)
@given(_options)
def test_fuzzed_environment_options_give_a_working_env_or_a_named_error(options):
    try:
        env = ElasticStringPendulumEnv(**options)
    except ValueError as e:
        message = str(e)
        assert any(name in message for name in list(options) + ["h ="]), message
        return
    obs, _ = env.reset(seed=0)
    obs, reward, *_ = env.step(np.full(6, 0.5))
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)


# -- worker counts (issue 54): as many as the work needs, never more than the CPUs ----------------
def test_a_worker_count_is_at_most_the_work_and_refused_above_the_cpus(monkeypatch):
    from esp_gym import workers

    monkeypatch.setattr(workers, "available_cpus", lambda: 4)  # the same answer on any machine
    assert workers.worker_count("jobs", 4, tasks=2) == 2  # no idle worker per missing task
    assert workers.worker_count("jobs", 4, tasks=17) == 4  # negative control: the CPUs' count passes
    with pytest.raises(ValueError, match=r"jobs must be at most the 4 CPUs .*got 5"):
        workers.worker_count("jobs", 5, tasks=17)
    for bad in (0, 2.5, True, "2"):
        with pytest.raises(ValueError, match="jobs must be a whole number"):
            workers.worker_count("jobs", bad, tasks=17)
