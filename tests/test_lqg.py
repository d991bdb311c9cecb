"""The hook observation's LQG (agents/baselines/lqg.py): the delayed system is the latency, the
measurement model is the observation's, the estimator and the controller close a stable loop
on the linear model (separation principle), and the law beats the zero action in the hard
preset."""
import numpy as np
import pytest

from agents.baselines.pd import ZeroPolicy

from agents.baselines.registry import LQG_TUNING
from agents.evaluate import evaluate_policy
from agents.baselines.lqg import HookLQG, delayed_system, measurement_model
from agents.baselines.lqr import REDUCED
from esp_gym.kernels.env.arrays import HOOK_OBSERVATION
from esp_gym.pendulum.env_setup import make_setup


def test_delayed_system_applies_each_action_latency_steps_late():
    rng = np.random.default_rng(0)
    A, B = rng.normal(size=(5, 5)) * 0.3, rng.normal(size=(5, 2))
    actions = rng.normal(size=(8, 2))
    for latency in (0, 1, 3):
        Ax, Bx = delayed_system(A, B, latency)
        x, z = np.zeros(Ax.shape[0]), np.zeros(5)
        for k, a in enumerate(actions):
            x = Ax @ x + Bx @ a
            z = A @ z + (B @ actions[k - latency] if k >= latency else 0.0)
            assert np.allclose(x[:5], z, rtol=0, atol=1e-14)


def test_measurement_model_reads_the_hook():
    """The hook measures its own error and velocity directly (identity rows), and the string's
    pull at rest is vertical, between the load's weight and the whole hanging weight."""
    setup = make_setup(task="stabilize", observation="hook")
    C, y0 = measurement_model(setup)
    z = np.arange(REDUCED.size)
    for hook, state in (("pivot_position_error", "pivot_error"), ("pivot_velocity", "pivot_velocity")):
        assert np.allclose(C[HOOK_OBSERVATION[hook]], np.eye(REDUCED.size)[z[REDUCED[state]]], atol=1e-8)
    tension = y0[HOOK_OBSERVATION["hook_tension"]]
    scene = setup.scene
    g = scene.gravity
    assert abs(tension[0]) < 1e-12 and abs(tension[1]) < 1e-12
    load = g * scene.body.mass
    assert load < tension[2] < load + g * scene.string.mass_per_length * scene.string.length


def closed_loop(law: HookLQG, L=None) -> np.ndarray:
    """The linear closed loop of the plant x (no load force) and the predicted estimate [x; f]."""
    L = law.L if L is None else L
    nx = law.K.shape[1]
    ne = law.A_est.shape[0]
    Ax, Bx, Cx = law.A_est[:nx, :nx], law.B_est[:nx], law.C_est[:, :nx]
    gain = np.hstack((law.K, law.K_force))  # u = -gain (xhat + L (C x - C xhat))
    update = np.eye(ne) - L @ law.C_est
    M = np.zeros((nx + ne, nx + ne))
    M[:nx, :nx] = Ax - Bx @ gain @ L @ Cx
    M[:nx, nx:] = -Bx @ gain @ update
    M[nx:, :nx] = law.A_est @ L @ Cx - law.B_est @ gain @ L @ Cx
    M[nx:, nx:] = law.A_est @ update - law.B_est @ gain @ update
    return M


def test_lqg_closes_a_stable_loop_on_the_linear_model():
    law = HookLQG.design(make_setup(task="stabilize", preset="hard"), **LQG_TUNING)
    radius = np.max(np.abs(np.linalg.eigvals(closed_loop(law))))
    assert radius < 0.999
    # negative control: the filter's correction with the wrong sign diverges
    assert np.max(np.abs(np.linalg.eigvals(closed_loop(law, -law.L)))) > 1.0


@pytest.mark.parametrize("task", ["stabilize", "transport", "track"])
def test_lqg_beats_the_zero_action_in_the_hard_preset(task):
    hard = {"preset": "hard"}
    law = HookLQG.design(make_setup(task=task, **hard), **LQG_TUNING)
    lqg = evaluate_policy(law, task, 4, 2000, env_kwargs=hard)
    zero = evaluate_policy(ZeroPolicy(), task, 4, 2000, env_kwargs=hard)
    assert lqg["mean_return"] > zero["mean_return"] + 50, (lqg["mean_return"], zero["mean_return"])


def test_lqg_takes_one_observation_at_a_time():
    setup = make_setup(task="stabilize", preset="hard")
    law = HookLQG.design(setup, **LQG_TUNING)
    with pytest.raises(ValueError, match="one environment"):
        law.act(np.zeros((2, HOOK_OBSERVATION.size)), setup)


@pytest.mark.parametrize("factor, index", [(0.5, 0), (1.0, 2), (2.0, 4)])
def test_scheduled_lqg_weighs_the_load(factor, index):
    """The schedule picks the design of the load's mass from the first hook tension: pinned
    masses 0.5, 1 and 2 times the nominal one select the designs made for them."""
    import gymnasium as gym

    import esp_gym
    from agents.baselines.lqg import ScheduledLQG

    mass = make_setup().scene.body.mass
    kw = {"observation": "hook", "sensor_noise": 1.0, "randomize": {"load_mass": (factor * mass, factor * mass)}}
    law = ScheduledLQG(make_setup(task="stabilize", **kw), **LQG_TUNING)
    env = gym.make(esp_gym.ENV_ID, task="stabilize", **kw)
    obs, _ = env.reset(seed=3)
    law.reset(env.unwrapped)
    law.act(obs, env.unwrapped.setup)
    assert law.current is law.laws[index]
