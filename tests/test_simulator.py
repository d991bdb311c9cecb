"""Simulator behaviour: determinism, chunking, recording, failure handling."""
import numpy as np
import pytest

import esp_gym
from esp_gym.physics.simulator import SimulationError


def _same(a, b):
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("r", "p", "R", "Pi")) and a.step == b.step


def test_reruns_are_bit_identical():
    states = []
    for _ in range(2):
        sim = esp_gym.Simulator(esp_gym.load_scene("paper_example"))
        sim.step(20_000)
        states.append(sim.state)
    assert _same(*states)


def test_step_chunks_and_run_give_identical_states():
    """One call of n steps, n calls of one step and a recorded run end bit for bit equal."""
    scene = esp_gym.load_scene("large_offset")
    a, b, c = (esp_gym.Simulator(scene) for _ in range(3))
    a.step(3000)
    for _ in range(3000):
        b.step()
    traj = c.run(t_final=3000 * scene.h, record_every=250, every_step=True)
    assert _same(a.state, b.state) and _same(a.state, c.state)
    np.testing.assert_array_equal(traj.nodes[-1], a.state.r)
    assert traj.energy_every_step[-1] == a.diagnostics()["energy"]
    assert traj.nodes.shape == (13, 11, 3) and traj.t[-1] == pytest.approx(3000 * scene.h)


def test_trajectory_matches_diagnostics():
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example"))
    traj = sim.run(t_final=0.1, record_every=100)
    d = sim.diagnostics()
    for key in ("energy", "pi3", "orthogonality", "kinetic_body", "potential_elastic", "stretched_length"):
        assert getattr(traj, key)[-1] == d[key]
    np.testing.assert_array_equal(traj.strain_energy[-1], d["strain_energy"])
    np.testing.assert_array_equal(traj.omega[-1], d["omega"])
    assert traj.t[0] == 0.0 and len(traj.t) == 11


def test_run_rejects_bad_arguments():
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example"))
    with pytest.raises(ValueError, match="whole number of steps"):
        sim.run(t_final=1.00005e-2)
    with pytest.raises(ValueError, match="record_every"):
        sim.run(t_final=0.01, record_every=0)
    with pytest.raises(ValueError):
        sim.step(-1)


def test_unstable_step_raises_and_keeps_last_good_state():
    """Beyond the stability bound the string blows up: a SimulationError, never a silent NaN."""
    scene = esp_gym.load_scene("paper_example", allow_unstable_h=True)
    scene = esp_gym.load_scene("paper_example", h=2.5 * scene.string.element_bound, allow_unstable_h=True)
    sim = esp_gym.Simulator(scene)
    with pytest.raises(SimulationError, match="failed") as err:
        sim.step(100_000)
    st = sim.state
    assert st.step == err.value.step < 100_000
    assert all(np.all(np.isfinite(getattr(st, k))) for k in ("r", "p", "R", "Pi"))
    assert np.isfinite(sim.diagnostics()["energy"])


@pytest.mark.parametrize("factor", [1.03, 1.5])
def test_blow_up_guard_stops_an_unstable_run_while_it_is_finite(factor):
    """Just above the bound the instability grows slowly; the guard (an element past
    solver.max_stretch = 10 rest lengths) stops it with its own status while every element is
    still far from overflow; with the guard relaxed to 1e6 the same run goes on for more steps
    (negative control: the guard, not something else, stopped it)."""
    bound = esp_gym.load_scene("paper_example").string.element_bound
    scene = esp_gym.load_scene("paper_example", h=factor * bound, allow_unstable_h=True)
    sim = esp_gym.Simulator(scene)
    with pytest.raises(SimulationError, match="max_stretch") as err:
        sim.step(1_000_000)
    assert err.value.status == 5
    st = sim.state
    assert np.abs(st.r).max() < 20.0 and np.all(np.isfinite(st.p))
    loose = esp_gym.Simulator(esp_gym.load_scene("paper_example", h=factor * bound, allow_unstable_h=True,
                                                 solver={"max_stretch": 1e6}))
    with pytest.raises(SimulationError) as err_loose:
        loose.step(1_000_000)
    assert err_loose.value.step > err.value.step


def test_overrides_reach_the_simulator():
    scene = esp_gym.load_scene("paper_example", h=2.5e-5, N=40)
    sim = esp_gym.Simulator(scene)
    assert sim.state.r.shape == (41, 3) and sim.h == 2.5e-5
    assert sim.diagnostics()["stretched_length"] == pytest.approx(1.0)


def test_state_save_and_restore_is_bit_exact():
    """State carries the summation remainders, so a restore continues bit for bit."""
    scene = esp_gym.load_scene("paper_example")
    a, b = esp_gym.Simulator(scene), esp_gym.Simulator(scene)
    a.step(2000)
    b.step(1000)
    saved = b.state
    b.step(500)
    b.set_state(saved)
    b.step(1000)
    assert _same(a.state, b.state)


def test_failure_advice_fits_the_failure():
    """"A smaller h usually helps" was said of every failure; now h is blamed only where it is
    near or past the stability bound."""
    bound = esp_gym.load_scene("paper_example").string.element_bound
    unstable = esp_gym.Simulator(esp_gym.load_scene("paper_example", h=2.5 * bound, allow_unstable_h=True))
    with pytest.raises(SimulationError, match=r"x the stability bound .*use h <= 0.7") as err:
        unstable.step(100_000)
    assert err.value.status in (5, 3)
    pushed = esp_gym.Simulator(esp_gym.load_scene("paper_example_free_pivot"))
    with pytest.raises(SimulationError) as err:
        pushed.step(100_000, pivot_force=[1e9, 0.0, 0.0])
    assert "use h <=" not in str(err.value) and ("inputs" in str(err.value) or "overflowed" in str(err.value))
