"""The implicit string (``solver.string: implicit``, kernels/implicit.py, docs/physics.md "The
implicit string"): its step is the discrete Euler-Lagrange flow of its discrete Lagrangian,
written from the definition in tests/discrete_lagrangian.py; it conserves pi3 and orthogonality
to round-off, converges at order 2, runs past the explicit string's stability bound, and the
scene option is validated.
"""
import numpy as np
import pytest

import esp_gym
from esp_gym.params import SceneError
from discrete_lagrangian import GEOMETRIC_OVERRIDES, random_state
from test_discrete_lagrangian import RTOL, kernel_step, legendre_errors

IMPLICIT = {"solver": {"string": "implicit"}}


@pytest.mark.parametrize("overrides, seed", [
    (dict(N=5), 21),
    (dict(N=3, **GEOMETRIC_OVERRIDES), 22),
    (dict(N=4, string={"law": "slack"}, **GEOMETRIC_OVERRIDES), 23),  # compressed elements slack
    (dict(N=4, h=2e-3, allow_unstable_h=True), 24),  # 2.8x the explicit string's bound
])
def test_implicit_step_satisfies_its_discrete_legendre_transforms(overrides, seed):
    """p_k = -D_1 L_d and p_{k+1} = D_2 L_d (finite differences of L_d from its definition, with
    the elastic energy at the elements' mean stretches) at random perturbed states: the kernel's
    Newton solves the right equations, to RTOL per node."""
    scene = esp_gym.load_scene("paper_example", **IMPLICIT, **overrides)
    before = random_state(scene, np.random.default_rng(seed))
    errors = legendre_errors(scene, before, kernel_step(scene, before))
    assert max(errors.values()) < RTOL, errors


def test_the_check_sees_the_explicit_lagrangian_as_wrong():
    """Negative control: the explicit step does not satisfy the implicit L_d's transforms (nor the
    reverse), so the test above can fail."""
    scene = esp_gym.load_scene("paper_example", N=4, **IMPLICIT)
    explicit = esp_gym.load_scene("paper_example", N=4)
    before = random_state(scene, np.random.default_rng(5))
    assert max(legendre_errors(scene, before, kernel_step(explicit, before)).values()) > 1e3 * RTOL
    assert max(legendre_errors(explicit, before, kernel_step(scene, before)).values()) > 1e3 * RTOL


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
    bound = esp_gym.load_scene("paper_example", **stiff, h=1e-6).string.stability_bound
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
