"""The implicit string (``solver.string: implicit``, kernels/step/implicit.py, docs/physics.md "The
implicit string"). Its energy-momentum form (the default) is the discrete Lagrange-d'Alembert
flow of the discrete Lagrangian without elastic energy, forced by the elastic discrete gradient,
both written from their definitions in tests/discrete_lagrangian.py, and conserves the string's
energy to round-off at any step; its variational form is the discrete Euler-Lagrange flow of the
mean-length Lagrangian. Both conserve pi3 and orthogonality to round-off, converge at order 2 and
run past the explicit string's stability bound; the scene option is validated.
"""
import numpy as np
import pytest

import esp_gym
from esp_gym.scene.params import SceneError
from discrete_lagrangian import GEOMETRIC_OVERRIDES, discrete_gradient_forces, discrete_lagrangian, random_state
from test_discrete_lagrangian import RTOL, fd_legendre_momenta, kernel_step, legendre_errors, max_relative_error

IMPLICIT = {"solver": {"string": "implicit"}}
VARIATIONAL = {"solver": {"string": "implicit", "implicit_form": "variational"}}


@pytest.mark.parametrize("overrides, seed", [
    (dict(N=5), 21),
    (dict(N=3, **GEOMETRIC_OVERRIDES), 22),
    (dict(N=4, string={"law": "slack"}, **GEOMETRIC_OVERRIDES), 23),  # compressed elements slack
    (dict(N=4, h=2e-3, allow_unstable_h=True), 24),  # 2.8x the explicit string's bound
])
def test_the_variational_step_satisfies_its_discrete_legendre_transforms(overrides, seed):
    """p_k = -D_1 L_d and p_{k+1} = D_2 L_d (finite differences of L_d from its definition, with
    the elastic energy at the elements' mean stretches) at random perturbed states: the kernel's
    Newton solves the right equations, to RTOL per node."""
    scene = esp_gym.load_scene("paper_example", **VARIATIONAL, **overrides)
    before = random_state(scene, np.random.default_rng(seed))
    after = kernel_step(scene, before)
    stretch = [np.linalg.norm(np.diff(state.r, axis=0), axis=1) - scene.string.u for state in (before, after)]
    if scene.string.law == "slack":  # some elements slack, none switching (where L_d is the secant's)
        assert np.any(stretch[0] < 0) and np.all((stretch[0] < 0) == (stretch[1] < 0))
    errors = legendre_errors(scene, before, after)
    assert max(errors.values()) < RTOL, errors


def test_the_check_sees_the_explicit_lagrangian_as_wrong():
    """Negative control: the explicit step does not satisfy the implicit L_d's transforms (nor the
    reverse), so the test above can fail."""
    scene = esp_gym.load_scene("paper_example", N=4, **VARIATIONAL)
    explicit = esp_gym.load_scene("paper_example", N=4)
    before = random_state(scene, np.random.default_rng(5))
    assert max(legendre_errors(scene, before, kernel_step(explicit, before)).values()) > 1e3 * RTOL
    assert max(legendre_errors(explicit, before, kernel_step(scene, before)).values()) > 1e3 * RTOL


def lagrange_dalembert_errors(scene, before, after, L=discrete_lagrangian, lengths=(None, None)):
    """Max relative errors of the kernel's (p_k, Pi_k, p_{k+1}, Pi_{k+1}) against the discrete
    Lagrange-d'Alembert equations p_k = -D_1 L0_d - h/2 F and p_{k+1} = D_2 L0_d + h/2 F, L0_d the
    discrete Lagrangian ``L`` without elastic energy (finite differences) and F the elastic
    discrete gradient forces (tests/discrete_lagrangian.py; ``lengths``: a winch's l_k, l_k+1)."""
    inelastic = scene.model_copy(update={"string": scene.string.model_copy(update={"EA": 0.0})})
    p0, Pi0, p1, Pi1 = fd_legendre_momenta(inelastic, before.r, before.R, after.r, after.R, L=L)
    push = 0.5 * scene.h * discrete_gradient_forces(scene, before.r, after.r, *lengths)
    got = (before.p, before.Pi, after.p, after.Pi)
    return {name: max_relative_error(a, b) for name, a, b in
            zip(("p_k", "Pi_k", "p_k+1", "Pi_k+1"), (p0 - push, Pi0, p1 + push, Pi1), got)}


@pytest.mark.parametrize("overrides, seed", [
    (dict(N=5), 21),
    (dict(N=3, **GEOMETRIC_OVERRIDES), 22),
    (dict(N=4, string={"law": "slack"}, **GEOMETRIC_OVERRIDES), 23),  # slack elements, some switching
    (dict(N=4, h=2e-3, allow_unstable_h=True), 24),  # 2.8x the explicit string's bound
])
def test_the_energy_momentum_step_is_forced_by_the_elastic_discrete_gradient(overrides, seed):
    """The energy-momentum form solves p_k = -D_1 L0_d - h/2 F, p_{k+1} = D_2 L0_d + h/2 F (L0_d
    without elastic energy, F the discrete gradient forces, both from their definitions) at random
    perturbed states, to RTOL per node."""
    scene = esp_gym.load_scene("paper_example", **IMPLICIT, **overrides)
    before = random_state(scene, np.random.default_rng(seed))
    errors = lagrange_dalembert_errors(scene, before, kernel_step(scene, before))
    assert max(errors.values()) < RTOL, errors


def test_the_check_sees_the_variational_step_as_wrong():
    """Negative control: the variational step (directions at both ends, not the discrete
    gradient's) does not satisfy the energy-momentum form's equations; they differ by the elements'
    turn over the step, so the step is 2.8x the explicit bound."""
    overrides = dict(N=4, h=2e-3, allow_unstable_h=True)
    scene = esp_gym.load_scene("paper_example", **IMPLICIT, **overrides)
    before = random_state(scene, np.random.default_rng(24))
    variational = esp_gym.load_scene("paper_example", **VARIATIONAL, **overrides)
    errors = lagrange_dalembert_errors(scene, before, kernel_step(variational, before))
    assert max(errors.values()) > 1e3 * RTOL, errors


def test_the_energy_momentum_step_conserves_the_energy_at_any_step():
    """A body without spin or offset (its attitude stays put, so the string and the body's
    translation are the whole system) on a string 100x stiffer than the paper's, at 10x the
    explicit bound, from a random state: the energy stays at round-off (1e-10 of the kinetic
    energy; measured 3e-11) over 2,000 steps. Negative control: the variational form, same start
    and step, moves it by more than 1e-4 (here it fails: its transverse step is explicit)."""
    stiff = dict(N=6, EA=100 * esp_gym.load_scene("paper_example").string.EA, body={"rho_c": [0.0, 0.0, 0.0]})
    bound = esp_gym.load_scene("paper_example", **stiff, h=1e-6).string.element_bound
    drift = {}
    for form in ("energy_momentum", "variational"):
        scene = esp_gym.load_scene("paper_example", **stiff, h=10 * bound,
                                   solver={"string": "implicit", "implicit_form": form})
        state = random_state(scene, np.random.default_rng(7), speed=2.0, spin=0.0)
        sim = esp_gym.Simulator(scene)
        sim.set_state(state)
        E0 = sim.diagnostics()["energy"]
        scale = sim.diagnostics()["kinetic_string"] + sim.diagnostics()["kinetic_body"]
        try:
            traj = sim.run(2000 * scene.h, record_every=20)
            drift[form] = np.max(np.abs(traj.energy - E0)) / scale
        except esp_gym.SimulationError:
            drift[form] = np.inf
    assert drift["energy_momentum"] < 1e-10, drift
    assert drift["variational"] > 1e-4, drift


def test_pi3_and_orthogonality_are_conserved_to_round_off():
    """No inputs, fixed pivot: the implicit L_d is invariant under rotations about e3, so pi3 is
    conserved (Noether) as far as Newton's tolerance and round-off allow; R stays orthogonal."""
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example", **IMPLICIT, **GEOMETRIC_OVERRIDES))
    pi3_0 = sim.diagnostics()["pi3"]
    traj = sim.run(0.5, record_every=500)
    assert np.max(np.abs(traj.pi3 - pi3_0)) < 1e-13 * max(1.0, abs(pi3_0))
    assert np.max(traj.orthogonality) < 1e-13
    assert np.max(np.abs(traj.energy - traj.energy[0])) < 1e-3 * np.max(np.abs(traj.kinetic_string + traj.kinetic_body))


def _final_positions(h, T=0.04):
    scene = esp_gym.load_scene("paper_example", N=6, h=h, **IMPLICIT, **GEOMETRIC_OVERRIDES)
    sim = esp_gym.Simulator(scene)
    sim.step(int(round(T / h)))
    return sim.state.r


def test_converges_at_order_two():
    """Errors against a fine run (h/32) at h = 4e-4 .. 1e-4: fitted slope 2 +- 0.15."""
    hs = [4e-4, 2e-4, 1e-4]
    ref = _final_positions(hs[-1] / 32)
    errs = [np.abs(_final_positions(h) - ref).max() for h in hs]
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(slope - 2.0) < 0.15, (errs, slope)


def test_runs_stably_past_the_explicit_stability_bound():
    """A string 100x stiffer than the paper's at h = 10x its explicit bound (h omega_max ~ 20):
    the explicit step blows up, the implicit one keeps the energy within 1 % over 0.5 s."""
    stiff = dict(N=6, EA=100 * esp_gym.load_scene("paper_example").string.EA, **GEOMETRIC_OVERRIDES)
    bound = esp_gym.load_scene("paper_example", **stiff, h=1e-6).string.element_bound
    h = 0.5 / round(0.5 / (10 * bound))  # about 10x the bound, dividing 0.5 s
    explicit = esp_gym.Simulator(esp_gym.load_scene("paper_example", **stiff, h=h, allow_unstable_h=True))
    with pytest.raises(esp_gym.SimulationError):
        explicit.step(int(0.5 / h))
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example", **stiff, h=h, **IMPLICIT))
    E0 = sim.diagnostics()["energy"]
    traj = sim.run(0.5, record_every=10)
    scale = np.max(traj.kinetic_string + traj.kinetic_body)
    assert np.max(np.abs(traj.energy - E0)) < 1e-2 * scale


def test_implicit_string_takes_order_two_only():
    with pytest.raises(SceneError, match="order: 2"):
        esp_gym.load_scene("paper_example", solver={"string": "implicit", "order": 4})
    assert esp_gym.load_scene("paper_example", **IMPLICIT).stability_bound == np.inf


def _element_tension(s0, s1, kappa=3.0, u=0.5, slack=True):
    """The kernel's tension and 2 dT/ds1 of one element stretched from s0 to s1 (along e3)."""
    from esp_gym.kernels.step.implicit_terms import element_vectors, secant_terms
    r = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, u + s0]])
    Y = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, s1 - s0]])
    T, _, _, _, _, _, _, stiffness, _, _ = secant_terms(*element_vectors(r, Y, 0), kappa, u, u, slack)
    return T, stiffness


def test_slack_switch_tension_is_the_energys_secant():
    """The tension over a step is (V(s1) - V(s0))/(s1 - s0), V = kappa/2 max(s, 0)^2 (docs/physics.md,
    "The slack switch"): the mean-length tension where both ends are on one side of the kink,
    energy-neutral across it; its derivative (the Jacobian's) matches finite differences there,
    and is continuous at the kink. Negative control: the mean-length tension kappa max(sbar, 0)
    is not energy-neutral across the kink."""
    kappa = 3.0
    V = lambda s: 0.5 * kappa * max(s, 0.0) ** 2
    pairs = [(-0.02, 0.03), (0.03, -0.02), (0.01, 0.04), (-0.01, -0.04), (-1e-3, 0.05), (0.05, -1e-3)]
    for s0, s1 in pairs:
        T, stiffness = _element_tension(s0, s1, kappa)
        assert T * (s1 - s0) == pytest.approx(V(s1) - V(s0), rel=1e-12, abs=1e-15), (s0, s1)
        eps = 1e-7
        fd = (_element_tension(s0, s1 + eps, kappa)[0] - _element_tension(s0, s1 - eps, kappa)[0]) / eps
        assert stiffness == pytest.approx(fd, rel=1e-6, abs=1e-9), (s0, s1)
    for s0 in (-0.02, 0.02):  # continuous at s1 = 0 and at s0 = 0
        assert _element_tension(s0, -1e-12, kappa)[0] == pytest.approx(_element_tension(s0, 1e-12, kappa)[0], abs=1e-9)
        assert _element_tension(s0, -1e-12, kappa)[1] == pytest.approx(_element_tension(s0, 1e-12, kappa)[1], abs=1e-9)
    assert _element_tension(-1e-12, 0.03, kappa)[0] == pytest.approx(_element_tension(1e-12, 0.03, kappa)[0], abs=1e-9)
    s0, s1 = -0.02, 0.03
    midpoint = kappa * max(0.5 * (s0 + s1), 0.0)
    assert abs(midpoint * (s1 - s0) - (V(s1) - V(s0))) > 1e3 * 1e-12 * (V(s1) - V(s0))


def test_free_fall_at_the_slack_kink_keeps_the_energy_balance_at_round_off():
    """A stiff string in free fall (EA = 2e5 N, h = 1 ms, 300 x its explicit bound): every element
    sits at the kink, where a midpoint tension gained energy at every switch and round-off grew
    1.3x per step. With the secant tension the energy balance stays at round-off, the elements at
    their rest length, and Newton converges (also in the round-off range)."""
    scene = esp_gym.load_scene("drone_load", EA=2e5, h=1e-3, **IMPLICIT)
    sim = esp_gym.Simulator(scene)
    sim.step(500)
    d = sim.diagnostics()
    assert abs(d["energy_balance_residual"]) < 1e-12 * max(1.0, abs(d["energy"]))
    strain = np.linalg.norm(np.diff(sim.state.r, axis=0), axis=1) / scene.string.u - 1
    assert np.max(np.abs(strain)) < 1e-8
    assert sim.newton_iterations / sim.step_count < 10


def _random_pivot_run(sim, seconds, seed=1):
    """drone_load's inputs as the environment applies them: hover plus uniform random pivot
    forces (0.6 W per axis) and body torques (0.02 N m), held for 20 ms each."""
    sc = sim.scene
    weight = sc.gravity * (sc.body.mass + sc.pivot.mass + sc.string.length * sc.string.mass_per_length)
    rng = np.random.default_rng(seed)
    per_period = int(round(0.02 / sc.h))
    for _ in range(int(round(seconds / 0.02))):
        a = rng.uniform(-1, 1, 6)
        sim.step(per_period, pivot_force=np.array([0.0, 0.0, -weight]) + 0.6 * weight * a[:3],
                 body_torque=0.02 * a[3:])


def test_a_step_whose_newton_fails_is_cut_back_not_lost():
    # EA = 2e5 N, h = 2.5 ms (750x the explicit bound) under the environment's random inputs:
    # before the cut-backs the run failed at t = 1.66 s (Newton cycling where elements switch
    # between slack and taut); now such a step is taken in halves, and the failed attempts show
    # as a step with more iterations than one Newton solve may take
    from esp_gym.physics.simulator import Simulator
    sc = esp_gym.load_scene("drone_load", EA=2e5, h=0.0025, solver={"string": "implicit"})
    sim = Simulator(sc)
    _random_pivot_run(sim, 3.0)
    assert sim.time == pytest.approx(3.0)
    assert sim.newton_iterations_max > sc.solver.newton_max_iter
    d = sim.diagnostics()
    assert abs(d["energy_balance_residual"]) < 1e-2 * abs(d["work"]) + 1e-3


def test_the_environment_runs_the_implicit_string_where_asked_and_keeps_the_explicit_default():
    import gymnasium as gym
    from esp_gym.scene.stepsize import choose_scheme
    # an EA override alone needs no h: the scene's own h is replaced by the environment's
    env = gym.make(esp_gym.ENV_ID, scene_overrides={"string": {"EA": 2e4}})
    assert env.unwrapped.scene.solver.string == "explicit"
    assert env.unwrapped.setup.substeps == choose_scheme(env.unwrapped.scene, 0.02, 0.5).explicit_substeps == 332
    overrides = {"string": {"EA": 2e5}, "solver": {"string": "implicit"}}
    env = gym.make(esp_gym.ENV_ID, scene_overrides=overrides)
    scene = env.unwrapped.scene
    assert scene.solver.string == "implicit"
    assert env.unwrapped.setup.substeps == choose_scheme(scene, 0.02, 0.5).implicit_substeps == 16
    vec = gym.make_vec(esp_gym.ENV_ID, num_envs=2, scene_overrides=overrides)
    obs, _ = env.reset(seed=5)
    vobs, _ = vec.reset(seed=[5, 6])
    np.testing.assert_array_equal(vobs[0], obs)
    rng = np.random.default_rng(0)
    for _ in range(60):
        a = rng.uniform(-1, 1, 6).astype(np.float32)
        obs, _, term, trunc, info = env.step(a)
        vobs, _, vterm, _, _ = vec.step(np.stack([a, a]))
        assert not info.get("termination_reason", "").startswith("physics_failure")
        np.testing.assert_array_equal(vobs[0], obs)  # the batched kernel is the single one, bit for bit
        if term or trunc or vterm.any():
            break


def test_the_environments_implicit_string_keeps_its_energy_under_a_controller_with_noise():
    """The defect of the variational form (docs/physics.md, "The transverse step"): the PD law with
    +-0.5 action noise at EA = 1e7 N, the environment's step, 5,000 control steps (100 s): the
    energy-momentum form's balance stays under 1e-3 J (measured 8.4e-5 J; the episode's energy
    scale is about 10 J). Negative control: the variational form passes 0.05 J within 1,000 steps
    (measured 0.10-0.14 J over 3 seeds, 3.8 J over 5,000 steps)."""
    from benchmarks.implicit_energy import episode
    import gymnasium as gym
    substeps = gym.make(esp_gym.ENV_ID, scene_overrides={"string": {"EA": 1e7}, "solver": {"string": "implicit"}},
                        disable_env_checker=True).unwrapped.setup.substeps
    assert substeps == 16
    run = episode(1e7, substeps, 0, 5000)
    assert run["steps"] == 5000 and run["reason"] == "" and run["worst"] < 1e-3, run
    variational = episode(1e7, substeps, 0, 1000, form="variational")
    assert variational["worst"] > 0.05, variational
