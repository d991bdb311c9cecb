"""Automatic time step (esp_gym.physics.pilot.choose_h): stability-limited where the target is loose,
accuracy-limited where it is tight, and then the error it promises is the error obtained,
measured against an independent reference (DOP853 on the same model written as an ODE)."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import esp_gym
from esp_gym.verify.ode import ElasticStringODE

HORIZON = 0.3
SAMPLE = 0.01


@pytest.fixture(scope="module")
def reference():
    scene = esp_gym.load_scene("paper_example")
    ode = ElasticStringODE(scene)
    t = np.arange(round(HORIZON / SAMPLE) + 1) * SAMPLE
    sol = solve_ivp(ode.rhs, (0.0, HORIZON), ode.y0(), method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t)
    return ode.attach_position(sol.y.T)


def _error(scene, h, reference):
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example", h=h, solver=scene.solver.model_dump()))
    every = int(round(SAMPLE / h))
    x = sim.run(HORIZON, record_every=every).nodes[:, -1]
    return float(np.linalg.norm(x - reference, axis=1).max())


@pytest.mark.parametrize("order, accuracy", [(2, 1e-7), (4, 1e-9)])
def test_chosen_h_meets_the_accuracy_target(reference, order, accuracy):
    """The chosen h is accuracy-limited, divides the sampling period, and the measured error
    is below the target and within 2x of the prediction (measured: within 5 %)."""
    scene = esp_gym.load_scene("paper_example", solver={"order": order})
    choice = esp_gym.choose_h(scene, accuracy=accuracy, horizon=HORIZON, divides=SAMPLE)
    assert choice.limited_by == "accuracy" and choice.h < choice.h_stable
    assert abs(SAMPLE / choice.h - round(SAMPLE / choice.h)) < 1e-9
    err = _error(scene, choice.h, reference)
    assert err <= accuracy, (err, choice)
    assert 0.5 <= err / choice.error_estimate <= 2.0, (err, choice)


def test_loose_target_gives_the_stable_step():
    scene = esp_gym.load_scene("paper_example")
    choice = esp_gym.choose_h(scene, accuracy=1.0, horizon=HORIZON)
    assert choice.limited_by == "stability"
    assert choice.h == pytest.approx(0.7 * scene.stability_bound, rel=1e-12)
    assert esp_gym.choose_h(scene).h == choice.h  # no target: stability alone, no pilot runs
    assert esp_gym.choose_h(scene).error_estimate is None
    # a composition with a wide stability interval (Suzuki: 2.72 in h omega) is allowed a larger step
    suzuki = esp_gym.load_scene("paper_example", solver={"order": 4})
    assert esp_gym.choose_h(suzuki).h > choice.h
    assert choice.scene(scene).h == choice.h


@pytest.mark.parametrize("kwargs,name", [
    ({"accuracy": 0.0}, "accuracy"), ({"accuracy": -1e-6}, "accuracy"), ({"accuracy": math.nan}, "accuracy"),
    ({"accuracy": True}, "accuracy must be a real number"), ({"accuracy": "1e-6"}, "accuracy must be a real number"),
    ({"accuracy": 1e-20}, "at least 1e-12 m"), ({"horizon": 0.0}, "horizon"), ({"safety": 1.5}, "safety"),
    ({"safety": "0.7"}, "safety"), ({"divides": -0.01}, "divides")])
def test_bad_arguments_raise_naming_themselves(kwargs, name):
    """Each is a ValueError naming the argument, at once (True was taken as 1 m, "1e-6" raised a
    TypeError, and 1e-20 m ran its pilot runs for over 20 minutes)."""
    with pytest.raises(ValueError, match=name):
        esp_gym.choose_h(esp_gym.load_scene("paper_example"), **kwargs)
