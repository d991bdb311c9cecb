"""The LQR baseline (agents/baselines/lqr.py): its model is the control step's linearisation, its closed
loop is stable, its gains reproduce, and it beats the zero action on every task."""
import gymnasium as gym
import numpy as np
import pytest

import esp_gym
from agents.baselines.pd import ZeroPolicy
from agents.evaluate import evaluate_policy
from agents.baselines.lqr import LQR, REDUCED, LQRTracker, lift, linearize, reduced_state
from esp_gym.pendulum.control import ControlStep
from esp_gym.kernels.env.arrays import TARGET
from esp_gym.pendulum.tasks import hanging_axis, hanging_depth


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


def test_the_reference_preview_is_the_150_step_sum_as_a_map_of_the_phase():
    """ReferencePreview (the tracking LQR's feed-forward, first drift and reference context as
    matrices on b(t)) equals the direct 150-step preview sum over the reference's drifts and the
    context read from the curve, at random references and clocks, to 1e-12 of their size; a
    reference drawn for another episode (the negative control) does not."""
    from agents.baselines.lqr import (REFERENCE_CONTEXT, ReferencePreview, preview_feedforward, reference_basis,
                                      reference_context, reference_drift)
    from esp_gym.pendulum.env_setup import make_setup
    from esp_gym.pendulum.tasks import track_reference

    setup = make_setup(task="track")
    law = LQRTracker.design(setup, None, 300.0)
    rng = np.random.default_rng(3)
    targets = [track_reference(rng, 1.0) for _ in range(4)]
    for target in targets:
        preview = ReferencePreview(target, law.A, law._preview, law.period)
        for clock in rng.uniform(0.0, 20.0, 3):
            target[TARGET.scalar("clock")] = clock
            drifts = reference_drift(target, law.A, law.period, len(law._preview[1]))
            feedforward = preview_feedforward(law._preview, drifts)
            context = reference_context(target, feedforward)
            b = preview.now()
            assert np.allclose(preview.context @ b, context, rtol=0, atol=1e-12 * np.abs(context).max())
            assert np.allclose(preview.drift @ b, drifts[0], rtol=0, atol=1e-12 * np.abs(drifts[0]).max())
            assert np.abs(feedforward).max() > 1e-3  # a moving reference asks for a feed-forward
    other = ReferencePreview(targets[1], law.A, law._preview, law.period)
    targets[0][TARGET.scalar("clock")] = 1.0
    drifts = reference_drift(targets[0], law.A, law.period, len(law._preview[1]))
    assert not np.allclose(other.feedforward @ reference_basis(targets[0]),
                           preview_feedforward(law._preview, drifts), atol=1e-3)
    assert REFERENCE_CONTEXT.size == preview.context.shape[0]

