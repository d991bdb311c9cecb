"""The assembled string's stability bound (esp_gym/scene/stability.py, docs/physics.md "The stability
bound"): exact where it can be checked by hand, a bound for every orientation, and sharp: a run
just under it keeps its energy, a run just over it blows up."""
import math

import numpy as np
import pytest

import esp_gym
from esp_gym.physics.simulator import SimulationError
from esp_gym.scene.stability import MAX_SOLVED_ELEMENTS, attachment_mass, explicit_bound, transverse_bound
from esp_gym.scene.stability import hat


def softest_direction(body) -> np.ndarray:
    """The body-frame direction in which the load's effective mass at its attachment is least."""
    M, rho, J = body.mass, hat(np.asarray(body.rho_c, dtype=float)), body.J
    effective = M * np.eye(3) + M * M * rho @ np.linalg.solve(J, rho)
    return np.linalg.eigh(effective)[1][:, 0]


def test_one_element_on_a_fixed_pivot_is_a_mass_on_a_spring():
    """N = 1, fixed pivot: one moving node of mass 2m/6 + m_eff on a spring kappa."""
    scene = esp_gym.load_scene("paper_example", N=1, allow_unstable_h=True)
    s = scene.string
    omega = math.sqrt(s.kappa / (2.0 * s.m / 6.0 + attachment_mass(scene.body)))
    assert scene.stability_bound == pytest.approx(2.0 / omega, rel=1e-12)


def full_chain_omega2(scene) -> float:
    """omega_max^2 of the whole linearised system, built independently of esp_gym.scene.stability: the
    3(N+1) node coordinates and the body's 3 rotation coordinates, the consistent (or lumped)
    string mass in each direction, the body's mass matrix [[M I, -M hat(rho)], [M hat(rho), J]]
    at the attachment node, the axial stiffness kappa in every direction (its upper bound), and
    SciPy's generalised symmetric eigensolver (the rotation coordinates carry no stiffness)."""
    from scipy.linalg import eigh
    s, n = scene.string, scene.string.elements
    size = 3 * (n + 1) + 3
    mass, stiffness = np.zeros((size, size)), np.zeros((size, size))
    element = s.m / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]]) if s.mass_model == "consistent" else np.diag([s.m / 2] * 2)
    spring = s.kappa * np.array([[1.0, -1.0], [-1.0, 1.0]])
    for a in range(n):
        for i in range(2):
            for j in range(2):
                rows, cols = slice(3 * (a + i), 3 * (a + i) + 3), slice(3 * (a + j), 3 * (a + j) + 3)
                mass[rows, cols] += element[i, j] * np.eye(3)
                stiffness[rows, cols] += spring[i, j] * np.eye(3)
    node, body = slice(3 * n, 3 * n + 3), slice(3 * n + 3, 3 * n + 6)
    M, rho = scene.body.mass, hat(np.asarray(scene.body.rho_c, dtype=float))
    mass[node, node] += M * np.eye(3)
    mass[node, body] += -M * rho
    mass[body, node] += M * rho
    mass[body, body] += scene.body.J
    keep = np.arange(size)
    if scene.pivot.is_free:
        mass[0:3, 0:3] += scene.pivot.mass * np.eye(3)
    else:
        keep = keep[3:]
    mass, stiffness = mass[np.ix_(keep, keep)], stiffness[np.ix_(keep, keep)]
    return float(eigh(stiffness, mass, eigvals_only=True)[-1])


@pytest.mark.parametrize("name", ["paper_example", "paper_example_free_pivot", "drone_load", "large_offset"])
@pytest.mark.parametrize("n", [1, 2, 8, 32])
def test_the_bound_is_the_whole_systems_highest_frequency(name, n):
    """The scalar chain with the load's least effective mass equals the full 3-D eigenproblem with
    the body's rotation: K is the same in every direction, so rotating into M_eff's eigenvectors
    splits it into three scalar chains, and the softest is the highest."""
    scene = esp_gym.load_scene(name, N=n, allow_unstable_h=True)
    assert scene.stability_bound == pytest.approx(2.0 / math.sqrt(full_chain_omega2(scene)), rel=1e-9)


def test_attachment_mass_is_the_mass_for_a_centred_load_and_less_off_centre():
    centred = esp_gym.load_scene("drone_load", **{"body.rho_c": [0.0, 0.0, 0.0]}).body
    assert attachment_mass(centred) == pytest.approx(centred.mass, rel=1e-14)
    body = esp_gym.load_scene("drone_load").body
    assert 0.0 < attachment_mass(body) < 0.5 * body.mass  # the box turns: 0.444 M


@pytest.mark.parametrize("name", ["paper_example", "paper_example_free_pivot", "drone_load", "short_stiff",
                                  "large_offset"])
@pytest.mark.parametrize("n", [1, 2, 8, 32, 256, 4096, 4097, 10 ** 12])
def test_the_one_element_bound_is_a_lower_bound(name, n):
    scene = esp_gym.load_scene(name, N=n, allow_unstable_h=True)
    element = scene.string.element_bound * scene.solver.bound_factor
    assert explicit_bound(scene) >= element * (1 - 1e-12)
    if 32 <= n <= MAX_SOLVED_ELEMENTS:  # the ends matter less as N grows: 1.004 at 32, 6e-5 at 256, 2e-7 at 4096
        assert explicit_bound(scene) < (1.0 + 5.0 / n ** 2) * element
    if n > MAX_SOLVED_ELEMENTS:  # beyond, the one-element bound, in no time (a string of 1e12 elements)
        assert explicit_bound(scene) == element


def test_lumped_mass_and_compositions_scale_the_bound():
    base = esp_gym.load_scene("paper_example", N=2, allow_unstable_h=True)
    suzuki = esp_gym.load_scene(base, solver={"order": 4})
    assert suzuki.stability_bound == pytest.approx(base.stability_bound * suzuki.solver.bound_factor, rel=1e-14)
    lumped = esp_gym.load_scene(base, string={"mass_model": "lumped"})
    assert lumped.stability_bound > base.stability_bound


def test_transverse_bound_falls_with_tension_and_matches_the_axial_one_at_kappa_u():
    scene = esp_gym.load_scene("drone_load", N=4)
    assert transverse_bound(scene, 10.0) > transverse_bound(scene, 40.0)
    assert transverse_bound(scene, scene.string.kappa * scene.string.u) == pytest.approx(scene.stability_bound,
                                                                                         rel=1e-12)


CASES = [("paper_example", 1), ("paper_example", 2), ("paper_example", 8), ("paper_example", 32),
         ("paper_example", 20),  # the paper's scene as printed
         ("paper_example_free_pivot", 1), ("paper_example_free_pivot", 2), ("paper_example_free_pivot", 8),
         ("paper_example_free_pivot", 32), ("drone_load", 1), ("drone_load", 2), ("drone_load", 8)]


def worst_case_run(name: str, n: int, factor: float, steps: int, gravity: float = 0.0) -> float:
    """|E - E0| / E0 after ``steps`` steps at ``factor`` x the bound of ``name`` with N = n, the
    two-sided elastic law and no gravity (the linearisation about the straight, unstretched
    string is then the whole story), the string along the load's softest direction, where the
    bound is reached; the node velocities, 1 mm/s, seed every mode."""
    base = esp_gym.load_scene(name, N=n, allow_unstable_h=True, gravity=gravity, string={"law": "elastic"})
    direction = softest_direction(base.body)
    rng = np.random.default_rng(n)
    velocities = 1e-3 * rng.standard_normal((n + 1, 3))
    if not base.pivot.is_free:
        velocities[0] = 0.0
    scene = esp_gym.load_scene(base, h=factor * base.stability_bound,
                               initial={"direction": direction.tolist(), "node_velocities": velocities.tolist()})
    sim = esp_gym.Simulator(scene)
    e0 = sim.diagnostics()["energy"]
    sim.step(steps)  # SimulationError if it blows up
    return abs(sim.diagnostics()["energy"] - e0) / abs(e0)


@pytest.mark.parametrize("name,n", CASES)
def test_stable_just_under_the_bound(name, n):
    # 2000 steps at 0.97 of the bound: bounded. Near h omega = 2 the scheme's energy of the
    # highest mode swings by (h omega/2)^2 / (1 - (h omega/2)^2) = 16x its own size at 0.97
    assert worst_case_run(name, n, 0.97, 2000) < 20.0


@pytest.mark.parametrize("name,n", CASES)
def test_unstable_just_over_the_bound(name, n):
    # at 1.03 of the bound the highest mode grows by |lambda| = 1.63 per step (Verlet's
    # characteristic roots at h omega = 2.06): from the seed to the blow-up guard in ~100 steps
    with pytest.raises(SimulationError, match="stretch|not finite|Newton"):
        worst_case_run(name, n, 1.03, 2000)


def test_negative_control_the_softest_direction_is_where_the_bound_is_reached():
    """drone_load, N = 1: with the string along the load's *stiffest* direction, 1.03 x the bound
    runs stably (the load resists with more than its least mass): the test above is not a
    blow-up of any h over the bound, and the bound is sharp only where it says it is."""
    base = esp_gym.load_scene("drone_load", N=1, allow_unstable_h=True, string={"law": "elastic"})
    M, rho, J = base.body.mass, hat(np.asarray(base.body.rho_c)), base.body.J
    stiffest = np.linalg.eigh(M * np.eye(3) + M * M * rho @ np.linalg.solve(J, rho))[1][:, 2]
    scene = esp_gym.load_scene(base, h=1.03 * base.stability_bound, initial={"direction": stiffest.tolist()})
    sim = esp_gym.Simulator(scene)
    sim.step(2000)
    assert np.isfinite(sim.diagnostics()["energy"])


@pytest.mark.parametrize("factor,stable", [(0.97, True), (1.03, False)])
def test_the_papers_scene_as_printed_at_the_bound(factor, stable):
    """The paper's example itself (gravity, its initial velocity, N = 20): 0.5 s just under the
    bound keeps the energy, just over it blows up."""
    base = esp_gym.load_scene("paper_example")
    scene = esp_gym.load_scene(base, h=factor * base.stability_bound, allow_unstable_h=True)
    sim = esp_gym.Simulator(scene)
    e0 = sim.diagnostics()["energy"]
    steps = int(0.5 / scene.h)
    if stable:
        sim.step(steps)
        # the scheme's O(h^2) energy error at this h: 3.1e-6 J measured, against E0 = -0.034 J
        assert abs(sim.diagnostics()["energy"] - e0) < 3e-5
    else:
        with pytest.raises(SimulationError, match="stretch|not finite|Newton"):
            sim.step(steps)
