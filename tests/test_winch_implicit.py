"""The implicit string with a winch (kernels/step/winch_implicit.py; docs/physics.md, "The winch"):
its step against finite differences of its discrete Lagrangian (the variational form) or of the
winch's Lagrangian without elastic energy forced by the elastic discrete gradient (the
energy-momentum form), the energy balance's order, the momentum balances, reversibility, and a
stiff string reeled far past the explicit bound."""
import numpy as np
import pytest

import esp_gym
from esp_gym.kernels.layout import DIAG
from esp_gym.kernels.step.winch import convective_weights, winch_energy
from esp_gym.physics.simulator import Simulator, State
from discrete_lagrangian import GEOMETRIC_OVERRIDES, random_state, winch_lagrangian
from test_discrete_lagrangian import legendre_errors
from test_implicit import lagrange_dalembert_errors
from test_winch import reel_balance_by_h, reel_step

IMPLICIT = {"solver": {"string": "implicit", "newton_tol": 1e-13}}
VARIATIONAL = {"solver": {"string": "implicit", "newton_tol": 1e-13, "implicit_form": "variational"}}

SCENES = {
    "paper-N5": dict(N=5),
    "geometric-N3": dict(N=3, **GEOMETRIC_OVERRIDES),
    "slack-N4": dict(N=4, string={"law": "slack"}, **GEOMETRIC_OVERRIDES),
    "lumped-free-N4": dict(N=4, string={"mass_model": "lumped"}, pivot={"kind": "free", "mass": 0.3}),
}


@pytest.mark.parametrize("scene_id, seed, length, speed", [
    ("paper-N5", 1, 1.0, 0.5), ("geometric-N3", 3, 0.7, -0.6), ("slack-N4", 5, 1.15, 0.5),
    ("lumped-free-N4", 4, 1.1, -0.4)])
def test_the_variational_step_satisfies_the_legendre_transforms_of_the_reeling_string(scene_id, seed, length, speed):
    """p_k = -D_1 L_d and p_{k+1} = D_2 L_d, L_d the winch's with the elastic energy at the
    elements' mean stretches over the step (rest lengths l_k/N and l_k+1/N at its ends), by finite
    differences at a random state, h = 1 ms (under the transverse limit: no step is cut back):
    relative 1e-7. Negative controls: the explicit winch's L_d, and the implicit one without the
    material's flow."""
    scene = esp_gym.load_scene("paper_example", h=1e-3, allow_unstable_h=True, **VARIATIONAL, **SCENES[scene_id])
    before = random_state(scene, np.random.default_rng(seed))
    after = reel_step(scene, before, length, speed)
    end = after.winch[0]
    assert end == pytest.approx(length + scene.h * speed, rel=1e-15)
    if scene.string.law == "slack":  # some elements slack, none switching (where L_d is the secant's)
        stretch = [np.linalg.norm(np.diff(s.r, axis=0), axis=1) - l / scene.string.elements
                   for s, l in ((before, length), (after, end))]
        assert np.any(stretch[0] < 0) and np.all((stretch[0] < 0) == (stretch[1] < 0))
    errors = legendre_errors(scene, before, after, L=winch_lagrangian(length, end))
    assert max(errors.values()) < 1e-7, errors
    static = legendre_errors(scene, before, after, L=winch_lagrangian(length, end, convective=False))
    assert max(static.values()) > 1e-4, static
    explicit = scene.model_copy(update={"solver": scene.solver.model_copy(update={"string": "explicit"})})
    assert max(legendre_errors(explicit, before, after, L=winch_lagrangian(length, end)).values()) > 1e-4


@pytest.mark.parametrize("scene_id, seed, length, speed", [
    ("paper-N5", 1, 1.0, 0.5), ("geometric-N3", 3, 0.7, -0.6), ("slack-N4", 5, 1.15, 0.5),
    ("lumped-free-N4", 4, 1.1, -0.4)])
def test_the_energy_momentum_step_of_the_reeling_string_is_forced_by_the_discrete_gradient(scene_id, seed, length,
                                                                                           speed):
    """p_k = -D_1 L0_d - h/2 F and p_{k+1} = D_2 L0_d + h/2 F, L0_d the winch's L_d without elastic
    energy and F the discrete gradient forces at rest lengths l_k/N and l_k+1/N (both from their
    definitions), at a random state, h = 1 ms: relative 1e-7. Negative control: the material's
    flow left out of L0_d."""
    scene = esp_gym.load_scene("paper_example", h=1e-3, allow_unstable_h=True, **IMPLICIT, **SCENES[scene_id])
    before = random_state(scene, np.random.default_rng(seed))
    after = reel_step(scene, before, length, speed)
    end = after.winch[0]
    errors = lagrange_dalembert_errors(scene, before, after, L=winch_lagrangian(length, end), lengths=(length, end))
    assert max(errors.values()) < 1e-7, errors
    static = lagrange_dalembert_errors(scene, before, after, L=winch_lagrangian(length, end, convective=False),
                                       lengths=(length, end))
    assert max(static.values()) > 1e-4, static


def test_the_energy_balance_with_the_winch_is_second_order_for_the_implicit_string_too():
    """The explicit winch's profile (out at 0.2 m/s, stop, in at 0.3 m/s; `paper_example`, N = 6)
    with the implicit string at h = 400, 200, 100 us: the balance's root mean square falls about
    4x per halving (measured 3.86, 4.00; 8.1e-9 J at 100 us against 12 mJ of winch work).
    Negative control: without W_winch it is O(1)."""
    rms, work, unbalanced = reel_balance_by_h(
        esp_gym.load_scene("paper_example", N=6, h=h, allow_unstable_h=True, **IMPLICIT) for h in (4e-4, 2e-4, 1e-4))
    ratios = [rms[i] / rms[i + 1] for i in range(2)]
    assert all(3.5 < q < 4.5 for q in ratios), (rms, ratios)
    assert rms[-1] < 1e-4 * abs(work[-1]) and abs(work[-1]) > 1e-3
    assert abs(unbalanced) > 1e3 * rms[-1]


def test_momentum_and_pi3_balance_for_the_reeling_implicit_string_with_every_input():
    """A free pivot pushed, the body turned, the string reeled in: the total momentum changes by
    the gravity and pivot impulses, pi3 by the angular impulse, to round-off."""
    scene = esp_gym.load_scene("paper_example", h=5e-4, allow_unstable_h=True, pivot={"kind": "free", "mass": 0.2}, **IMPLICIT)
    sim = Simulator(scene)
    for speed in (-0.4, 0.3):
        sim.step(200, pivot_force=(0.3, -0.2, -1.0), body_torque=(0.01, 0.0, 0.02), reel_speed=speed)
    d = sim.diagnostics()
    assert d["winch_work"] != 0.0
    assert np.max(np.abs(d["momentum_balance_residual"])) < 1e-11 * max(1.0, np.max(np.abs(d["linear_momentum"])))
    assert abs(d["pi3_balance_residual"]) < 1e-12


def test_reeling_out_then_in_with_the_momenta_reversed_returns_the_implicit_string():
    """The step is symmetric: out 500 steps, momenta and reel reversed, in 500 steps: back to the
    start (positions to 1e-10 m, measured 1.3e-13 m; Newton's tolerance 1e-13). Negative control:
    without the reversal the state does not return."""
    scene = esp_gym.load_scene("paper_example", h=1e-3, allow_unstable_h=True, **GEOMETRIC_OVERRIDES, **IMPLICIT)
    sim = Simulator(scene)
    start = sim.state
    sim.step(500, reel_speed=0.2)
    out = sim.state
    sim.set_state(State(out.r, -out.p, out.R, -out.Pi, winch=(out.winch[0], -0.2)))
    sim.step(500, reel_speed=-0.2)
    assert sim.winch.length == pytest.approx(scene.string.length, abs=1e-12)
    assert np.max(np.abs(sim.state.r - start.r)) < 1e-10
    sim.set_state(State(out.r, out.p, out.R, out.Pi, winch=out.winch))
    sim.step(500, reel_speed=-0.2)
    assert np.max(np.abs(sim.state.r - start.r)) > 1e-4


def test_a_stiff_string_reels_far_past_the_explicit_bound():
    """`drone_load` at EA = 2e5 N hovering (the pivot force holds the weight), reeled in from 1 m
    to 0.6 m at 0.5 m/s with the implicit string at h = 2.5 ms, more than 30x the explicit bound
    at 0.6 m: the length ends on the command and the balance is within 0.5 % of the winch's work
    (measured 0.11 %: 2.5 mJ of 2.2 J; the elastic share of the work is counted per step,
    kernels/step/winch_implicit.py, as a quadrature of dV/dl would alias the unresolved axial modes)."""
    scene = esp_gym.load_scene("drone_load", h=2.5e-3, string={"EA": 2e5}, solver={"string": "implicit"},
                               winch={"min_length": 0.5})
    explicit_bound = esp_gym.load_scene("drone_load", h=1e-5, string={"EA": 2e5}).stability_bound
    assert scene.h > 30 * explicit_bound * 0.6
    sim = Simulator(scene)
    sim.step(320, reel_speed=-0.5, pivot_force=(0.0, 0.0, -1.55 * scene.gravity))
    d = sim.diagnostics()
    assert d["unstretched_length"] == pytest.approx(scene.string.length - 0.4, rel=1e-12)
    assert abs(d["energy_balance_residual"]) < 5e-3 * abs(d["winch_work"]) and d["winch_work"] > 1.0


def midpoint_shift(scene, r0, r1, l0, l1, v, h):
    """The midpoint rule's count of the kinetic, T0 and weight share of the winch's work over a step
    r0 -> r1, l0 -> l1 at reel speed v [J] (positions at the middle, velocities (r1 - r0) / h, the
    length at the middle: the rule kernels/step/winch.py's midpoint_dH_dl applies to the explicit string)."""
    s, n = scene.string, scene.string.elements
    length = 0.5 * (l0 + l1)
    m = s.mass_per_length * length / n
    off = m / 6 if s.mass_model == "consistent" else 0.0
    end = 0.5 * m - off
    vel, mid = (r1 - r0) / h, 0.5 * (r0 + r1)
    kinetic = sum(end * (vel[e] @ vel[e] + vel[e + 1] @ vel[e + 1]) + 2 * off * vel[e] @ vel[e + 1] for e in range(n))
    gamma = convective_weights(n, s.mass_model == "consistent")[:, 2]
    x = np.diff(mid, axis=0)
    convective = s.mass_per_length * v * v / (n * length) * np.sum(gamma * np.sum(x * x, axis=1))
    weight = -scene.gravity * m * np.sum(mid[:-1, 2] + mid[1:, 2])
    return (l1 - l0) * (-0.5 * kinetic + 0.5 * convective + 0.5 * weight) / length


def non_elastic_energy(sim, length, speed):
    """H(q, p) at unstretched ``length`` and reel ``speed`` less the elastic energy [J]."""
    b = sim.buffers
    H, _ = winch_energy(b.state, b.params, sim.winch.arrays, b.diag, length, speed)
    return float(H) - float(b.diag.out[DIAG.scalar("potential_elastic")])


def test_a_reel_that_keeps_reversing_keeps_the_implicit_strings_balance():
    """`drone_load` at EA = 2e3 N, the implicit string at the environment's step (0.02 / 31 s),
    swung by the pivot force while the reel reverses (+-0.5 m/s) every 0.5 s, 4 s: the balance
    stays within 1e-4 J (measured 4.0e-5 J against 2.4 J of winch work). The winch's work per
    step is the elastic share exactly plus the mean of H's change with the length alone at the
    step's two states (kernels/step/winch_implicit.py). Negative control: the same steps counted by
    the midpoint rule of dH/dl, which errs by O(h^3) per step with the reel's sign, drift
    upward past 2e-3 J (measured 4.1e-3 J)."""
    scene = esp_gym.load_scene("drone_load", h=0.02 / 31, string={"EA": 2e3}, solver={"string": "implicit"},
                               **{"initial.direction": [0.3, 0.0, 1.0]})
    weight = scene.gravity * (scene.body.mass + scene.pivot.mass + scene.string.length * scene.string.mass_per_length)
    sim, h, period = Simulator(scene), scene.h, int(round(0.5 / scene.h))
    worst, recount = 0.0, 0.0
    for k in range(int(round(4.0 / h))):
        t, v = k * h, 0.5 if (k // period) % 2 == 0 else -0.5
        l0, r0 = sim.winch.length, sim.state.r
        before = non_elastic_energy(sim, l0 + h * v, v) - non_elastic_energy(sim, l0, v)
        sim.step(1, pivot_force=(3.0 * np.sin(2.0 * t), 2.0 * np.cos(1.3 * t), -weight), reel_speed=v)
        l1 = sim.winch.length
        after = non_elastic_energy(sim, l1, v) - non_elastic_energy(sim, l0, v)
        recount += 0.5 * (before + after) - midpoint_shift(scene, r0, sim.state.r, l0, l1, v, h)
        worst = max(worst, abs(sim.diagnostics()["energy_balance_residual"]))
    d = sim.diagnostics()
    assert worst < 1e-4 and abs(d["winch_work"]) > 1.0
    assert d["energy_balance_residual"] + recount > 2e-3
