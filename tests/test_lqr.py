"""The LQR baseline (agents/baselines/lqr.py): its model is the control step's linearisation, its closed
loop is stable, its gains reproduce, and it beats the zero action on every task."""
import gymnasium as gym
import numpy as np
import pytest

import esp_gym
from agents.baselines.pd import ZeroPolicy
from agents.evaluate import evaluate_policy
from agents.baselines.lqr import LQR, REDUCED, LQRTracker, lift, linearize, reduced_state
from esp_gym.control import ControlStep
from esp_gym.kernels.env_arrays import TARGET
from esp_gym.tasks import hanging_axis, hanging_depth


def _setup(task="stabilize", **kw):
    return gym.make(esp_gym.ENV_ID, task=task, **kw).unwrapped.setup


def test_lift_and_reduce_are_inverse_and_the_equilibrium_is_one():
    setup = _setup()
    control = ControlStep(setup)
    target = np.zeros(TARGET.size)
    target[TARGET["load"]] = (0.0, 0.0, hanging_depth(setup.scene))
    axis = hanging_axis(setup.scene.body.rho_c)
    z = 0.01 * np.random.default_rng(0).normal(size=REDUCED.size)
    control.reset(lift(z, setup.scene), target)
    assert np.abs(reduced_state(control.observation, axis) - z).max() < 1e-14
    control.reset(lift(np.zeros(REDUCED.size), setup.scene), target)
    control.step(np.zeros(6))
    assert np.abs(reduced_state(control.observation, axis)).max() < 1e-13  # at rest, stays at rest


def test_the_linearisation_is_second_order_in_its_step():
    """Central differences: halving the step changes A and B by ~1/4 as much (O(delta^2))."""
    setup = _setup()
    coarse = linearize(setup, z_step=4e-3, a_step=4e-2)
    mid = linearize(setup, z_step=2e-3, a_step=2e-2)
    fine = linearize(setup, z_step=1e-3, a_step=1e-2)
    for c, m, f in zip(coarse, mid, fine):
        ratio = np.abs(c - m).max() / np.abs(m - f).max()
        assert 3.0 < ratio < 5.0, ratio


def test_closed_loop_is_stable_and_the_gains_reproduce():
    setup = _setup()
    lqr = LQR.design(setup, control_weight=100.0)
    assert lqr.closed_loop_radius() < 0.99
    assert np.max(np.abs(np.linalg.eigvals(lqr.A))) > 0.9999  # the open loop is not (pendulum, free pivot)
    again = LQR.design(setup, control_weight=100.0)
    assert np.array_equal(lqr.K, again.K)
    # a known scene's gains (drone_load, stabilize): the pivot's x gain on its own position error
    # and on the load's, in action units per metre
    assert lqr.K[0, REDUCED.start("pivot_error")] == pytest.approx(6.192, abs=1e-3)
    assert lqr.K[0, REDUCED.start("load_error")] == pytest.approx(-3.629, abs=1e-3)
    flipped = np.max(np.abs(np.linalg.eigvals(lqr.A + lqr.B @ lqr.K)))
    assert flipped > 1.0  # negative control: the gains with the wrong sign destabilise


@pytest.mark.parametrize("task, weight", [("stabilize", 100.0), ("transport", 100.0), ("track", 300.0)])
def test_lqr_beats_the_zero_action(task, weight):
    setup = _setup(task)
    policy = (LQRTracker if task == "track" else LQR).design(setup, control_weight=weight)
    lqr = evaluate_policy(policy, task=task, episodes=4, seed=123)
    zero = evaluate_policy(ZeroPolicy(), task=task, episodes=4, seed=123)
    assert lqr["mean_return"] > zero["mean_return"] + 100
