"""The discrete Lagrangian, its derivative formulas and the compiled step agree.

Three independent pieces are compared:

* ``discrete_lagrangian.discrete_lagrangian`` -- L_d from the paper's integral definition
  (Gauss-Legendre quadrature, errata applied), tests/discrete_lagrangian.py;
* ``esp_gym.verify.reference`` -- the paper's derivative formulas (DdrLd), D_r, (DFLd), (AdDFLd), (DRLd);
* the numba kernel (``esp_gym.Simulator``), which never forms L_d.

Finite differences are central, ``(L(+d) - L(-d)) / 2d``, with d = 1e-6 u for node
displacements (u the element length, the length scale of L_d's nonlinearity) and d = 1e-6 rad
for rotations (variations delta F = F zeta^, delta R = R eta^ through the exponential map).

Tolerance. The truncation error (d^2/6) times the third derivative is below 1e-11 relative
(L_d is quadratic in dr; the elastic term's third derivative scales as h kappa/u; the rotation
terms vary on the radian scale). The rounding error of a central difference is about
eps |L_d| / d: each evaluation of L_d sums terms of size up to |L_d|, rounded to eps relative.
So a derivative D agrees when, node by node,

    |FD - D| <= RTOL |D| + ROUNDOFF eps |L_d| / d,      RTOL = 1e-7, ROUNDOFF = 4.

The second term matters only where D is tiny next to L_d, e.g. (DRLd) (gravity torques, below
1e-2 |L_d| with the paper's large J, whose rotational term dominates L_d). A wrong formula or
an unapplied erratum misses the bound by orders of magnitude
(test_checks_detect_deliberate_errors).
"""
import numpy as np
import pytest

import esp_gym
from esp_gym.verify import reference as ref
from esp_gym.verify.reference import Constants

from discrete_lagrangian import (
    GEOMETRIC_OVERRIDES, discrete_lagrangian, expm, expm_minus_identity, left_perturbed,
    random_nodes, random_rotation, random_state, right_perturbed, string_kinetic,
    string_lagrangian,
)

REL_STEP = 1e-6  # FD step: times u [m] for node displacements, in rad for rotations
RTOL = 1e-7  # see the module docstring
ROUNDOFF = 4.0  # rounding floor of a central difference, in units of eps |L_d| / d
EPS = np.finfo(float).eps


# -- finite differences ---------------------------------------------------------------------------
def central(fun, d):
    """(fun(d) - fun(-d)) / 2d."""
    return (fun(d) - fun(-d)) / (2.0 * d)


def fd_node_gradient(fun, n, d):
    """Central differences of ``fun(delta)`` for delta (N+1, 3) moving one free node coordinate."""
    out = np.zeros((n + 1, 3))
    for a in range(1, n + 1):
        for i in range(3):
            def shifted(t, a=a, i=i):
                delta = np.zeros((n + 1, 3))
                delta[a, i] = t
                return fun(delta)
            out[a, i] = central(shifted, d)
    return out


def fd_rotation_gradient(fun, d=REL_STEP):
    """Central differences of ``fun(w)`` along w = t e_i, i = 1..3 (left-trivialised derivative)."""
    return np.array([central(lambda t: fun(t * np.eye(3)[i]), d) for i in range(3)])


def _rows(fd, exact):
    """Node rows of two gradients; a 3-vector is one row, row 0 (the pivot) of (N+1, 3) is dropped."""
    fd, exact = np.atleast_2d(fd), np.atleast_2d(exact)
    return (fd[1:], exact[1:]) if fd.shape[0] > 1 else (fd, exact)


def max_relative_error(fd, exact):
    """max over nodes of |fd_a - exact_a| / |exact_a|."""
    fd, exact = _rows(fd, exact)
    return float(np.max(np.linalg.norm(fd - exact, axis=1) / np.linalg.norm(exact, axis=1)))


def excess(fd, exact, floor=0.0):
    """max over nodes of |fd_a - exact_a| / (RTOL |exact_a| + floor); below 1 means agreement."""
    fd, exact = _rows(fd, exact)
    return float(np.max(np.linalg.norm(fd - exact, axis=1) / (RTOL * np.linalg.norm(exact, axis=1) + floor)))


# -- configurations -------------------------------------------------------------------------------
#: Scenes of the formula checks. h = 1e-2 puts a rotation F of a few degrees (Omega of a few
#: rad/s) and dr = h v (v <= 1 m/s) on the scales of real motion, so no term of L_d dwarfs the
#: others; the formulas hold for any h (stability does not matter for a single L_d).
FORMULA_SCENES = {
    "paper-N1": dict(N=1),
    "paper-N2": dict(N=2),
    "paper-N5": dict(N=5),
    "geometric-N3": dict(N=3, **GEOMETRIC_OVERRIDES),
}


def formula_scene(scene_id):
    return esp_gym.load_scene("paper_example", h=1e-2, allow_unstable_h=True, **FORMULA_SCENES[scene_id])


def random_configuration(scene, seed):
    """(r, R, dr, F - I): elements stretched and compressed (0.8-1.25 u) at k and near it at k+1,
    node speeds up to 1 m/s (dr = h v), R_k random, F a rotation by 1-5 degrees."""
    rng = np.random.default_rng(seed)
    r = random_nodes(scene, rng)
    dr = scene.h * rng.uniform(-1.0, 1.0, size=r.shape)
    dr[0] = 0.0
    R = random_rotation(rng)
    axis = rng.normal(size=3)
    w = np.deg2rad(rng.uniform(1.0, 5.0)) * axis / np.linalg.norm(axis)
    return r, R, dr, expm_minus_identity(w)


def formula_and_fd(name, scene, r, R, dr, FmI, L=discrete_lagrangian):
    """(formula from esp_gym.verify.reference, central difference of L, rounding floor) for one derivative."""
    c = Constants.from_scene(scene)
    n = scene.string.elements
    d = REL_STEP * scene.string.u
    F = np.eye(3) + FmI
    floor_r = ROUNDOFF * EPS * abs(L(scene, r, R, dr, FmI)) / d
    floor_w = floor_r * d / REL_STEP
    if name == "D_dr":  # (DdrLd) for a = 2..N and the node-(N+1) formula
        return (ref.D_dr_Ld(c, r, R, dr, FmI),
                fd_node_gradient(lambda e: L(scene, r, R, dr + e, FmI), n, d), floor_r)
    if name == "D_r":  # at fixed dr
        return (ref.D_r_Ld(c, r, R, dr, FmI),
                fd_node_gradient(lambda e: L(scene, r + e, R, dr, FmI), n, d), floor_r)
    if name == "DFLd":  # delta F = F zeta^
        return (ref.DF_Ld(c, R, dr[-1], FmI),
                fd_rotation_gradient(lambda w: L(scene, r, R, dr, right_perturbed(F, FmI, w))), floor_w)
    if name == "AdDFLd":  # delta F = eta^ F
        return (ref.AdDF_Ld(c, R, dr[-1], FmI),
                fd_rotation_gradient(lambda w: L(scene, r, R, dr, left_perturbed(F, FmI, w))), floor_w)
    if name == "DRLd":  # delta R = R eta^ at fixed F
        return (ref.DR_Ld(c, R, dr[-1], FmI),
                fd_rotation_gradient(lambda w: L(scene, r, R @ expm(w), dr, FmI)), floor_w)
    raise ValueError(name)


# -- (i) the derivative formulas ------------------------------------------------------------------
FORMULA_CASES = [("paper-N1", 0), ("paper-N2", 1), ("paper-N5", 2), ("geometric-N3", 3)]


@pytest.mark.parametrize("scene_id, seed", FORMULA_CASES)
@pytest.mark.parametrize("formula", ["D_dr", "D_r", "DFLd", "AdDFLd", "DRLd"])
def test_derivative_formula_matches_finite_differences_of_Ld(formula, scene_id, seed):
    """Each derivative formula of the paper (string rows [kg m/s], rotation [kg m^2/s]) equals the
    central difference of the quadrature L_d [J s] at a random configuration, within
    RTOL |D| + ROUNDOFF eps |L_d|/d (module docstring). Measured: max relative error 3e-8
    ((DRLd), paper J), 2e-9 for the others."""
    scene = formula_scene(scene_id)
    exact, fd, floor = formula_and_fd(formula, scene, *random_configuration(scene, seed))
    assert excess(fd, exact, floor) < 1.0, max_relative_error(fd, exact)


def closed_form_Ldka(scene, r, dr, kappa_in_last_line=True):
    """sum_a (Ldka) [J s], erratum 2 applied unless ``kappa_in_last_line`` is False::

        m/(6h) (|dr_a|^2 + dr_a.dr_{a+1} + |dr_{a+1}|^2) + h/4 m g (2 r_a + 2 r_{a+1} + dr_a + dr_{a+1}).e3
        - h/4 kappa (|r_{a+1} - r_a| - u)^2 - h/4 kappa (|r_{a+1} + dr_{a+1} - r_a - dr_a| - u)^2
    """
    h, m, kappa, u, g = scene.h, scene.string.m, scene.string.kappa, scene.string.u, scene.gravity
    a, b, da, db = r[:-1], r[1:], dr[:-1], dr[1:]
    s0 = np.linalg.norm(b - a, axis=1) - u
    s1 = np.linalg.norm(b + db - a - da, axis=1) - u
    return float(np.sum(m / (6 * h) * (np.sum(da * da, 1) + np.sum(da * db, 1) + np.sum(db * db, 1))
                        + h / 4 * m * g * (2 * a + 2 * b + da + db)[:, 2]
                        - h / 4 * kappa * s0 ** 2 - h / 4 * (kappa if kappa_in_last_line else 1.0) * s1 ** 2))


@pytest.mark.parametrize("scene_id, seed", [("paper-N1", 0), ("paper-N5", 2)])
def test_quadrature_string_Ld_equals_closed_form_Ldka_with_erratum_2(scene_id, seed):
    """The integral definition of L_{d_{k,a}} (h/2 kinetic prefactor, erratum 1) by quadrature
    equals the closed form (Ldka) with kappa restored in its last line (erratum 2) [J s], to
    round-off; without kappa it does not."""
    scene = formula_scene(scene_id)
    r, _, dr, _ = random_configuration(scene, seed)
    quad = string_lagrangian(scene, r, dr)
    assert abs(quad - closed_form_Ldka(scene, r, dr)) <= 1e-13 * abs(quad)
    assert abs(quad - closed_form_Ldka(scene, r, dr, kappa_in_last_line=False)) > 1e-6 * abs(quad)


def test_co_ad_maps_DFLd_to_AdDFLd():
    """Ad^*_{F^{-1}} (DFLd) = F (DFLd) equals (AdDFLd) [kg m^2/s] (round-off only)."""
    scene = formula_scene("paper-N5")
    r, R, dr, FmI = random_configuration(scene, 7)
    c = Constants.from_scene(scene)
    lhs = ref.co_Ad(FmI, ref.DF_Ld(c, R, dr[-1], FmI))
    rhs = ref.AdDF_Ld(c, R, dr[-1], FmI)
    assert np.linalg.norm(lhs - rhs) <= 1e-13 * np.linalg.norm(rhs)


# -- (ii) the compiled step -----------------------------------------------------------------------
def fd_legendre_momenta(scene, r0, R0, r1, R1, L=discrete_lagrangian):
    """Central differences of L_d(q_k, q_{k+1}) = L(r_k, R_k, r_{k+1} - r_k, R_k^T R_{k+1} - I):
    ``(p_k, Pi_k, p_{k+1}, Pi_{k+1})`` with p_k = -D_1 L_d, p_{k+1} = D_2 L_d (left-trivialised
    for R: R_k -> R_k exp(eta^) at fixed R_{k+1} turns F_k into exp(-eta^) F_k)."""
    n = scene.string.elements
    d = REL_STEP * scene.string.u
    dr = r1 - r0
    FmI = R0.T @ (R1 - R0)
    F = np.eye(3) + FmI
    p0 = -fd_node_gradient(lambda e: L(scene, r0 + e, R0, dr - e, FmI), n, d)
    Pi0 = -fd_rotation_gradient(lambda w: L(scene, r0, R0 @ expm(w), dr, left_perturbed(F, FmI, -w)))
    p1 = fd_node_gradient(lambda e: L(scene, r0, R0, dr + e, FmI), n, d)
    Pi1 = fd_rotation_gradient(lambda w: L(scene, r0, R0, dr, right_perturbed(F, FmI, w)))
    return p0, Pi0, p1, Pi1


def kernel_step(scene, state):
    """One step of the compiled integrator from ``state``."""
    sim = esp_gym.Simulator(scene)
    sim.set_state(state)
    sim.step(1)
    return sim.state


def legendre_errors(scene, before, after, L=discrete_lagrangian):
    """Max relative errors of the kernel's (p_k, Pi_k, p_{k+1}, Pi_{k+1}) against FD of L."""
    fd = fd_legendre_momenta(scene, before.r, before.R, after.r, after.R, L=L)
    got = (before.p, before.Pi, after.p, after.Pi)
    return {name: max_relative_error(a, b) for name, a, b in zip(("p_k", "Pi_k", "p_k+1", "Pi_k+1"), fd, got)}


KERNEL_SCENES = {
    "paper-N5": dict(N=5),
    "geometric-N3": dict(N=3, **GEOMETRIC_OVERRIDES),
    "lumped-paper-N5": dict(N=5, string={"mass_model": "lumped"}),
    "lumped-geometric-N3": dict(N=3, string={"mass_model": "lumped"}, **GEOMETRIC_OVERRIDES),
}


@pytest.mark.parametrize("scene_id, seed", [("paper-N5", 11), ("geometric-N3", 12), ("lumped-paper-N5", 13),
                                            ("lumped-geometric-N3", 14)])
def test_kernel_step_satisfies_discrete_legendre_transforms(scene_id, seed):
    """The kernel's step (q_k, p_k) -> (q_{k+1}, p_{k+1}) satisfies p_k = -D_1 L_d and
    p_{k+1} = D_2 L_d [kg m/s, kg m^2/s], L_d from the quadrature, at a random perturbed state
    (h = 1e-4 as in the scene file). Relative tolerance RTOL per node; measured: 5e-11."""
    scene = esp_gym.load_scene("paper_example", **KERNEL_SCENES[scene_id])
    before = random_state(scene, np.random.default_rng(seed))
    errors = legendre_errors(scene, before, kernel_step(scene, before))
    assert max(errors.values()) < RTOL, errors


# -- (iii) the discrete action --------------------------------------------------------------------
def kernel_trajectory(scene, state, nsteps):
    """States 0..nsteps of the compiled integrator from ``state``."""
    sim = esp_gym.Simulator(scene)
    sim.set_state(state)
    states = [sim.state]
    for _ in range(nsteps):
        sim.step(1)
        states.append(sim.state)
    return states


def action(scene, rs, Rs, Es, L=discrete_lagrangian):
    """sum_k L_d(g_k, f_k) [J s] over the trajectory (positions rs, attitudes Rs, F_k - I = Es)."""
    return sum(L(scene, rs[k], Rs[k], rs[k + 1] - rs[k], Es[k]) for k in range(len(Es)))


def action_gradients(scene, states, L=discrete_lagrangian):
    """FD derivatives of the action with respect to every interior configuration g_j (j = 1..K-1):
    ``[(dS/dr_j (N+1, 3), dS/dR_j (3,) left-trivialised)]``. Varying R_j -> R_j exp(eta^) changes
    F_{j-1} -> F_{j-1} exp(eta^) and F_j -> exp(-eta^) F_j."""
    n = scene.string.elements
    d = REL_STEP * scene.string.u
    rs = [s.r for s in states]
    Rs = [s.R for s in states]
    Es = [Rs[k].T @ (Rs[k + 1] - Rs[k]) for k in range(len(states) - 1)]
    Fs = [np.eye(3) + E for E in Es]
    out = []
    for j in range(1, len(states) - 1):
        def moved(e, j=j):
            return action(scene, rs[:j] + [rs[j] + e] + rs[j + 1:], Rs, Es, L)

        def turned(w, j=j):
            Es_w = list(Es)
            Es_w[j - 1] = right_perturbed(Fs[j - 1], Es[j - 1], w)
            Es_w[j] = left_perturbed(Fs[j], Es[j], -w)
            return action(scene, rs, Rs[:j] + [Rs[j] @ expm(w)] + Rs[j + 1:], Es_w, L)

        out.append((fd_node_gradient(moved, n, d), fd_rotation_gradient(turned)))
    return out


def stationarity_defect(scene, states, L=discrete_lagrangian):
    """max over interior j and nodes of |dS/dq_j| relative to the size of the two terms that
    cancel in it, |D_2 L_d(g_{j-1}, f_{j-1})| = |p_j| (string rows) and |Pi_j| (rotation)."""
    worst = 0.0
    for (dr_grad, dR_grad), s in zip(action_gradients(scene, states, L), states[1:-1]):
        string = np.linalg.norm(dr_grad[1:], axis=1) / np.linalg.norm(s.p[1:], axis=1)
        worst = max(worst, float(np.max(string)), float(np.linalg.norm(dR_grad) / np.linalg.norm(s.Pi)))
    return worst


def test_discrete_action_is_stationary_along_kernel_trajectory():
    """Discrete Hamilton's principle: for 20 kernel steps (paper scene, N = 5, h = 1e-4, random
    start) the FD derivative of sum_k L_d [J s] with respect to every interior r_{j,a} [m] and
    R_j exp(eta^) is below RTOL |p_j|, RTOL |Pi_j|. Measured: 6e-10."""
    scene = esp_gym.load_scene("paper_example", N=5)
    states = kernel_trajectory(scene, random_state(scene, np.random.default_rng(21)), 20)
    assert stationarity_defect(scene, states) < RTOL


# -- each check can fail ----------------------------------------------------------------------------
def L_without_erratum_1(scene, r, R, dr, FmI):
    """L_d with the printed kinetic prefactor 1/h instead of h/2 (erratum 1 not applied)."""
    h = scene.h
    return discrete_lagrangian(scene, r, R, dr, FmI) + (2.0 / h ** 2 - 1.0) * string_kinetic(scene, dr)


def L_without_erratum_2(scene, r, R, dr, FmI):
    """L_d with the printed closed form's last line, -(h/4)(|x_{k+1}| - u)^2 without kappa."""
    x = (r + dr)[1:] - (r + dr)[:-1]
    s = np.linalg.norm(x, axis=1) - scene.string.u
    missing = 0.25 * scene.h * (scene.string.kappa - 1.0) * np.sum(s * s)
    return discrete_lagrangian(scene, r, R, dr, FmI) + missing


def _formula_mutant(name):
    """excess() of a (formula, L_d) pair with one deliberate error, at the paper-N5 configuration."""
    scene = formula_scene("paper-N5")
    r, R, dr, FmI = random_configuration(scene, 2)
    c = Constants.from_scene(scene)
    if name == "DRLd gravity sign flipped":
        _, fd, floor = formula_and_fd("DRLd", scene, r, R, dr, FmI)
        wrong = ref.DR_Ld(c, R, dr[-1], FmI) - c.h * c.M * c.g * ref.cross(c.rho, R.T @ ref.E3)
        return excess(fd, wrong, floor)
    if name == "DFLd with J_d F_0 (erratum 3 read literally)":
        _, fd, floor = formula_and_fd("DFLd", scene, r, R, dr, FmI)
        F = np.eye(3) + FmI
        A = c.M / c.h * R.T @ dr[-1] + 0.5 * c.h * c.M * c.g * R.T @ ref.E3
        wrong = ref.vee(c.Jd - F.T @ c.Jd) / c.h + ref.cross(c.rho, F.T @ A)
        return excess(fd, wrong, floor)
    if name in ("L_d without erratum 1", "L_d without erratum 2"):
        L = L_without_erratum_1 if name.endswith("1") else L_without_erratum_2
        exact, fd, floor = formula_and_fd("D_dr", scene, r, R, dr, FmI, L=L)
        return excess(fd, exact, floor)
    raise ValueError(name)


def _step_mutant(name):
    """The kernel-step or action check's error / RTOL with one deliberate error (paper scene, N = 5)."""
    scene = esp_gym.load_scene("paper_example", N=5)
    before = random_state(scene, np.random.default_rng(11))
    after = kernel_step(scene, before)
    if name == "kernel step against L_d without erratum 2":
        return max(legendre_errors(scene, before, after, L=L_without_erratum_2).values()) / RTOL
    if name == "kernel step with Pi_k+1 gravity torque sign flipped":
        c = Constants.from_scene(scene)
        after.Pi = after.Pi - c.h * c.M * c.g * ref.cross(c.rho, after.R.T @ ref.E3)
        return max(legendre_errors(scene, before, after).values()) / RTOL
    if name == "action along a trajectory with one node moved by 1e-9 u":
        states = kernel_trajectory(scene, before, 4)
        states[2].r[3, 1] += 1e-9 * scene.string.u
        return stationarity_defect(scene, states) / RTOL
    raise ValueError(name)


@pytest.mark.parametrize("mutant", [
    "DRLd gravity sign flipped",
    "DFLd with J_d F_0 (erratum 3 read literally)",
    "L_d without erratum 1",
    "L_d without erratum 2",
    "kernel step against L_d without erratum 2",
    "kernel step with Pi_k+1 gravity torque sign flipped",
    "action along a trajectory with one node moved by 1e-9 u",
])
def test_checks_detect_deliberate_errors(mutant):
    """Each check above fails, by at least 10x its tolerance, on a deliberately wrong formula, an
    unapplied erratum or a perturbed trajectory (so the passing checks are not vacuous)."""
    run = _step_mutant if mutant.startswith(("kernel", "action")) else _formula_mutant
    assert run(mutant) > 10.0
