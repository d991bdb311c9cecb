"""Input shaping (agents/baselines/shaping.py): the shaped path leaves no residual vibration on the
linearised pendulum at the design frequency (simulated, not by the shaper's own formula), the
formula V(w) matches the simulation off design, ZVD is flatter than ZV, and the scene's
pendulum mode from the linearised control step is the pendulum's."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from agents.baselines.lqr import linearize
from agents.baselines.shaping import Shaper, pendulum_mode
from esp_gym.pendulum.env_setup import make_setup
from esp_gym.pendulum.tasks import hanging_depth

OMEGA, MOVE = 3.0, 0.4  # [rad/s], ramp [s]


def residual(shaper: Shaper, omega: float, zeta: float = 0.0) -> float:
    """Amplitude of the load's swing about the pivot after the shaped move of 1 m, for the
    linear pendulum y'' = -w^2 (y - p) - 2 zeta w (y' - p') with the pivot path p(t)."""
    def rhs(t, s):
        p, v = shaper.progress(np.array([t]), MOVE)
        return [s[1], -omega ** 2 * (s[0] - p[0]) - 2 * zeta * omega * (s[1] - v[0])]

    end = shaper.duration + MOVE
    sol = solve_ivp(rhs, (0.0, end), [0.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-14, max_step=0.01)
    y, v = sol.y[:, -1]
    wd = omega * math.sqrt(1 - zeta ** 2)
    x = y - 1.0  # the free oscillation about the end point
    return math.hypot(x, (v + zeta * omega * x) / wd)


@pytest.mark.parametrize("zeta", [0.0, 0.05])
@pytest.mark.parametrize("kind", ["zv", "zvd"])
def test_shaped_path_leaves_no_residual_vibration(kind, zeta):
    unshaped = residual(Shaper.design("none", OMEGA, zeta), OMEGA, zeta)
    assert unshaped > 0.05  # negative control: the plain ramp rings on
    shaped = residual(Shaper.design(kind, OMEGA, zeta), OMEGA, zeta)
    assert shaped < 1e-9 * unshaped  # measured 4e-12: the ODE solver's tolerance


@pytest.mark.parametrize("kind, ratio", [("zv", 0.8), ("zvd", 1.2)])
def test_residual_formula_matches_the_simulation_off_design(kind, ratio):
    shaper = Shaper.design(kind, OMEGA)
    plain = Shaper.design("none", OMEGA)
    w = ratio * OMEGA
    assert residual(shaper, w) / residual(plain, w) == pytest.approx(shaper.residual(w), rel=1e-6)


def test_zvd_is_flat_at_the_design_frequency():
    zv, zvd = Shaper.design("zv", OMEGA), Shaper.design("zvd", OMEGA)
    for ratio in (0.9, 1.1):
        assert zvd.residual(ratio * OMEGA) < 0.25 * zv.residual(ratio * OMEGA)
    h = 1e-4 * OMEGA
    assert abs(zvd.residual(OMEGA + h) - zvd.residual(OMEGA - h)) / (2 * h) < 1e-6
    assert abs(sum(zvd.amplitudes) - 1.0) < 1e-15 and abs(sum(zv.amplitudes) - 1.0) < 1e-15


def test_pendulum_mode_is_the_scenes_pendulum():
    """The slowest mode of the linearised step with the pivot held: sqrt(g / depth) to 1 % (the
    body's rocking and the string's stretch make it a compound pendulum), undamped."""
    setup = make_setup(task="transport")
    A, _ = linearize(setup)
    omega, zeta = pendulum_mode(A, setup.control_period)
    assert omega == pytest.approx(math.sqrt(setup.scene.gravity / hanging_depth(setup.scene)), rel=0.01)
    assert zeta < 1e-4


def test_bad_shaper_is_named():
    with pytest.raises(ValueError, match="shaper"):
        Shaper.design("ei", OMEGA)
    with pytest.raises(ValueError, match="omega"):
        Shaper.design("zv", -1.0)


def test_shaping_script_reports_the_spread(tmp_path):
    from agents.baselines.shaping import main

    result = main(["--draws", "3", "--out", str(tmp_path)])
    low, _, median, _, high = result["spread_percentiles_0_5_50_95_100"]
    assert 0.5 * result["omega"] < low <= median <= high < 1.5 * result["omega"]
    assert (tmp_path / "shaping.png").stat().st_size > 10_000
