"""Integrator variants chosen by the scene: symmetric compositions of the LGVI (order 4 and 6)
and the lumped-mass string. Each keeps the geometric invariants; each composition's order is
measured against the order it declares (esp_gym/scene/compositions.py)."""
import numpy as np
import pytest

import esp_gym
from conftest import drift_ratio, state_distance
from esp_gym.scene.compositions import COMPOSITIONS
from esp_gym.physics.simulator import SimulationError

ORDER4 = {"solver": {"order": 4}}
ORDER6 = {"solver": {"order": 6}}
LUMPED = {"string": {"mass_model": "lumped"}}


def _final(name, h, T, **kw):
    sim = esp_gym.Simulator(esp_gym.load_scene(name, h=h, **kw))
    sim.step(int(round(T / h)))
    return sim.state


def _composition(name):
    c = COMPOSITIONS[name]
    return {"solver": {"order": c.order, "composition": name}}


@pytest.mark.parametrize("scheme", ["triple_jump", "suzuki5", "wide5", "kahan_li9", "kahan_li17"])
@pytest.mark.parametrize("name", ["paper_example", "large_offset"])
def test_composition_has_its_declared_order(name, scheme):
    """Global error slope over halvings of h equals the declared order +- 0.35 (measured
    slopes in the assertion message; see README). The reference is the same
    scheme at h/8 of the finest; the coarsest h sits well inside the stability bound, the
    finest keeps the error above round-off."""
    kw = _composition(scheme)
    order = COMPOSITIONS[scheme].order
    T = 0.05
    bound = esp_gym.load_scene(name, **kw).stability_bound
    h0 = bound / {4: 4.0, 6: 1.5, 8: 1.2}[order]
    hs = [T / round(T / (h0 / 2 ** i)) for i in range(4 if order == 4 else 3)]
    ref = _final(name, hs[-1] / 8, T, **kw)
    errs = [state_distance(_final(name, h, T, **kw), ref) for h in hs]
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    print(f"{name} {scheme}: slope {slope:.3f}, errors {errs}")
    assert abs(slope - order) <= 0.35, (slope, errs)


def test_compositions_are_palindromic_and_consistent():
    """Weights sum to 1 (consistency) and read the same backwards (symmetry, hence even order);
    order >= 4 needs sum gamma^3 = 0 (the h^3 error of the LGVI cancels)."""
    for c in COMPOSITIONS.values():
        g = np.array(c.gammas)
        assert abs(g.sum() - 1.0) <= 4e-16 * c.stages, c.name
        assert np.array_equal(g, g[::-1]), c.name
        if c.order >= 4:
            assert abs((g ** 3).sum()) <= 4e-15, c.name


def test_wide5_trades_error_constant_for_stability():
    """wide5's interval is 22 % wider than Suzuki's per stage, its phase error on the linear
    oscillator (theta/x - 1 = C x^4) 6x larger: the trade it is there for."""
    from esp_gym.scene.compositions import _trace

    def phase_constant(c, x=0.05):
        theta = np.arccos(_trace(c.gammas, np.array([x]))[0] / 2)
        return (theta / x - 1) / x ** 4

    wide, suzuki = COMPOSITIONS["wide5"], COMPOSITIONS["suzuki5"]
    assert wide.stability_interval / suzuki.stability_interval == pytest.approx(1.22, abs=0.01)
    assert phase_constant(wide) / phase_constant(suzuki) == pytest.approx(6.1, abs=0.3)


def test_composition_must_match_the_order():
    with pytest.raises(esp_gym.SceneError, match="has order 6"):
        esp_gym.load_scene("paper_example", solver={"order": 4, "composition": "kahan_li9"})
    with pytest.raises(esp_gym.SceneError, match="composition"):
        esp_gym.load_scene("paper_example", solver={"order": 4, "composition": "leapfrog"})
    scene = esp_gym.load_scene("paper_example", solver={"order": 4})
    assert scene.solver.scheme.name == "suzuki5"
    # the stable h scales with the composition's stability interval on q'' = -omega^2 q
    base = esp_gym.load_scene("paper_example").stability_bound  # the LGVI's: the assembled string's
    assert scene.stability_bound == pytest.approx(base * COMPOSITIONS["suzuki5"].stability_interval / 2, rel=1e-12)


@pytest.mark.parametrize("scheme", ["triple_jump", "suzuki5", "wide5", "kahan_li9", "kahan_li17"])
def test_stability_interval_is_exact_on_the_linear_oscillator(scheme):
    """Independent check of the interval: step x' = v, v' = -x with the composed velocity
    Verlet at h just inside / outside the interval for 2,000 steps: bounded inside (|x| < 10),
    growing outside (|x| > 10). Interval (in h omega): triple jump 1.573 (> 2/1.702: a product
    of maps can be stable although one is not), Suzuki 2.721 (< 2/0.658: the reverse), wide5
    3.319."""
    c = COMPOSITIONS[scheme]
    xc = c.stability_interval

    def amplitude(hw):
        x, v = 1.0, 0.0
        for _ in range(2000):
            for g in c.gammas:
                t = g * hw
                v -= 0.5 * t * x
                x += t * v
                v -= 0.5 * t * x
        return abs(x) if np.isfinite(x) else np.inf  # fast growth overflows to nan

    assert amplitude(0.99 * xc) < 10.0
    assert amplitude(1.01 * xc) > 10.0


def test_suzuki_blows_up_above_its_interval_on_the_string_but_not_below():
    """On the paper example itself: 1.05 times the interval-based bound ends in a
    SimulationError within 2 s; 0.95 runs 2 s (the nominal bound 2 / max|gamma| would have
    allowed 1.12 times the interval-based one)."""
    scene = esp_gym.load_scene("paper_example", **ORDER4)
    for factor, fails in ((0.95, False), (1.05, True)):
        h = factor * scene.stability_bound
        sim = esp_gym.Simulator(esp_gym.load_scene("paper_example", h=h, allow_unstable_h=True, **ORDER4))
        if fails:
            with pytest.raises(SimulationError):
                sim.step(int(2.0 / h))
        else:
            sim.step(int(2.0 / h))


@pytest.mark.parametrize("variant", [ORDER4, ORDER6, LUMPED], ids=["order4", "order6", "lumped"])
@pytest.mark.parametrize("name", ["paper_example", "large_offset"])
def test_variants_keep_the_invariants(name, variant):
    """pi3 to round-off, orthogonality <= 1e-13, bounded energy without drift over 3e4 steps."""
    scene = esp_gym.load_scene(name, **variant)
    sim = esp_gym.Simulator(scene)
    tr = sim.run(t_final=30_000 * scene.h, record_every=1000, every_step=True)
    assert np.abs(tr.pi3_every_step - tr.pi3[0]).max() <= 1e-13
    assert tr.orthogonality_every_step.max() <= 1e-13
    de = tr.energy_every_step - tr.energy[0]
    assert drift_ratio(tr.t_every_step, de) < 0.5
    assert np.abs(de).max() < 1e-2 * np.max(tr.kinetic_string + tr.kinetic_body)


def test_lumped_mass_is_second_order_and_allows_sqrt3_larger_steps():
    """Lumped mass: one element's omega = 2 sqrt(kappa/m) instead of sqrt(12 kappa/m), so h may be
    sqrt(3) larger (the assembled N = 20 chain's: 1.72x). At 1.4x the consistent bound the lumped
    string runs 1 s with a small energy error; the consistent one blows up (negative control)."""
    consistent = esp_gym.load_scene("paper_example")
    lumped = esp_gym.load_scene("paper_example", **LUMPED)
    assert lumped.string.element_bound == pytest.approx(np.sqrt(3) * consistent.string.element_bound, rel=1e-12)
    assert 1.7 < lumped.stability_bound / consistent.stability_bound < np.sqrt(3)
    h = 1e-3 / round(1e-3 / (1.4 * consistent.stability_bound))  # divides 1 ms
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example", h=h, **LUMPED))
    tr = sim.run(t_final=1.0, record_every=10)
    assert np.abs(tr.energy - tr.energy[0]).max() < 0.05 * tr.kinetic_body.max()
    bad = esp_gym.Simulator(esp_gym.load_scene("paper_example", h=h, allow_unstable_h=True))
    with pytest.raises(SimulationError):
        bad.step(int(round(1.0 / h)))
    T = 0.05
    hs = [T / round(T / (lumped.stability_bound / 8 / 2 ** i)) for i in range(4)]
    ref = _final("paper_example", hs[-1] / 32, T, **LUMPED)
    errs = [state_distance(_final("paper_example", h, T, **LUMPED), ref) for h in hs]
    assert abs(np.polyfit(np.log(hs), np.log(errs), 1)[0] - 2) <= 0.15


def test_order4_failure_restores_the_step_start():
    """A failing substep of the composition restores the state at the start of the step: the
    simulator then holds exactly the state after the last completed step."""
    scene = esp_gym.load_scene("paper_example", h=4 * esp_gym.load_scene("paper_example", **ORDER4).stability_bound,
                               allow_unstable_h=True, **ORDER4)
    sim = esp_gym.Simulator(scene)
    with pytest.raises(SimulationError):
        sim.step(10_000)
    k = sim.step_count
    assert k > 0
    again = esp_gym.Simulator(scene)
    again.step(k)
    a, b = sim.state, again.state
    assert np.array_equal(a.r, b.r) and np.array_equal(a.p, b.p) and np.array_equal(a.Pi, b.Pi)
    assert np.isfinite(sim.diagnostics()["energy"])


@pytest.mark.parametrize("use_run", [False, True], ids=["step", "run"])
def test_composed_failure_after_checkpoints_holds_the_last_good_step(use_run):
    """A composed step that fails part-way is undone by rewinding to the last checkpoint
    (every 64 steps) and replaying: after a failure well past the first checkpoint, through
    both the plain and the recording loop, the simulator holds exactly (bit for bit) the state
    a fresh run of the completed steps reaches."""
    base = esp_gym.load_scene("paper_example", **ORDER4)
    # just above its bound Suzuki's composition blows up after a few hundred steps (the energy
    # watchdog, which would stop it sooner, off: the failure is what is tested)
    solver = {"solver": {"order": 4, "energy_watchdog": None}}
    scene = esp_gym.load_scene("paper_example", h=1.03 * base.stability_bound, allow_unstable_h=True, **solver)
    sim = esp_gym.Simulator(scene)
    with pytest.raises(SimulationError):
        if use_run:
            sim.run(t_final=20_000 * scene.h, record_every=10, every_step=True)
        else:
            sim.step(20_000)
    k = sim.step_count
    assert k > 64 and k % 64 != 0, k  # the failure is past a checkpoint, inside an interval
    again = esp_gym.Simulator(scene)
    again.step(k)
    a, b = sim.state, again.state
    for name in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert all(np.array_equal(x, y) for x, y in zip(a.remainders, b.remainders))
