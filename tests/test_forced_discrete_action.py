"""The forced kernel satisfies the discrete Lagrange-d'Alembert principle of its L_d.

docs/physics.md, "Inputs through the discrete Lagrange–d'Alembert principle": inputs u (pivot
force u_p on node 0 of a free pivot, spatial frame [N]; body torque tau, body frame [N m];
spatial torque T [N m]) are held over a step and enter as the discrete forces

    f_d^-(k) = f_d^+(k) = (h/2) u    on r_0,
    tau_d^-(k) = (h/2)(tau + R_k^T T),    tau_d^+(k) = (h/2)(tau + R_{k+1}^T T)    on eta,

paired with delta r_0 and with the left-trivialised variation delta R = R eta^. The principle
delta sum_k L_d(q_k, q_{k+1}) + sum_k [f_d^-(k) . delta q_k + f_d^+(k) . delta q_{k+1}] = 0 gives

* the forced discrete Euler-Lagrange equations at every interior time j,
  D_2 L_d(q_{j-1}, q_j) + D_1 L_d(q_j, q_{j+1}) + f_d^+(j-1) + f_d^-(j) = 0
  (for each free node and, left-trivialised, for R_j), checked along kernel trajectories;
* the forced discrete Legendre transforms p_k = -D_1 L_d(q_k, q_{k+1}) - f_d^-(k),
  p_{k+1} = D_2 L_d(q_k, q_{k+1}) + f_d^+(k), checked on each kernel step of the same runs
  (the first one from a state whose momenta were not made by the kernel).

L_d is the quadrature one of tests/discrete_lagrangian.py (free pivot and slack law included);
the kernel never forms it. Only L_d(q_{j-1}, q_j) and L_d(q_j, q_{j+1}) depend on q_j, so the
derivative of the action with respect to q_j is the sum of those two terms' derivatives; each is
taken separately (D_2 of one step, D_1 of the next) so the residual can be measured against the
size of its terms. Differences are central with d = 1e-6 u for nodes and 1e-6 rad for rotations
(R_j -> R_j exp(eta^), i.e. F_{j-1} -> F_{j-1} exp(eta^), F_j -> exp(-eta^) F_j).

Tolerance. A residual of one row (a node's 3-vector, or the rotation's) passes when

    |residual| <= RTOL max(|D_2 L_d|, |D_1 L_d|, |f_d|) + floor,      RTOL = 1e-9,

the floor being the rounding of the central differences of the L_d involved:
ROUNDOFF eps S / d for nodes (d = 1e-6 u) and ROUNDOFF eps S_rot / 1e-6 for the rotation,
ROUNDOFF = 4. Each L_d value is rounded to eps times the size S of the terms it sums, which can
exceed |L_d|: S = |L_d| + G, G = h g (M + M_p + mu l)(max |r| + max |dr| + |rho_c|) bounding the
gravity terms (signed heights, so they cancel among themselves and against the kinetic terms); S_rot = S + |J_d| |F - I| / h, because perturbing F rounds
F - I (entries ~h Omega) to eps relative, and tr((I - F) J_d)/h amplifies that by |J_d|/h (this
dominates with the small geometric J, where |L_d| alone under-predicted the noise 200-fold).
Truncation is below RTOL: L_d is quadratic in dr, the elastic term varies on the length u and the
rotational ones on the radian scale, so (d^2/6) |D^3 L_d| / |D L_d| ~ (d/u)^2 = 1e-12 (measured:
at d = 1e-5 u the residuals grow to ~1e-10, as (d/u)^2 says). The kernel solves its step to
Newton's tolerance (1e-14 relative) and sums with compensation, ~1e-12 of the momenta. With these
the measured excess, residual / (RTOL size + floor), is at most 0.06 in every case (largest
relative residual 1.2e-9, in rows whose terms are small enough for the floor to dominate), and
at most 0.15 over 4 other seeds of each configuration at h = 1e-4 and 1e-3. Every deliberate error misses the bound by far
more (test_forced_checks_detect_deliberate_errors). The slack law's energy is only C^1; the slack
run is checked to keep each element length more than 2 d away from u, where the differences would
straddle the jump of its second derivative.
"""
import functools
from collections import namedtuple

import numpy as np
import pytest

import esp_gym
from esp_gym.kernels.layout import Layout

from discrete_lagrangian import (
    GEOMETRIC_OVERRIDES, discrete_lagrangian, expm, left_perturbed, random_nodes, random_rotation,
    random_state, right_perturbed,
)

REL_STEP = 1e-6  # FD step: times u [m] for node displacements, in rad for rotations
RTOL = 1e-9  # see the module docstring
ROUNDOFF = 4.0  # rounding floor of a central difference, in units of eps S / d (module docstring)
EPS = np.finfo(float).eps


# -- discrete forces --------------------------------------------------------------------------------
#: How the inputs of a step become (f_d^-, f_d^+). "split" is the scheme; the others are the
#: deliberate errors of the negative controls.
FORCE_RULES = ("split", "omitted", "spatial torque right half with R_k^T", "wholly at the left end",
               "wholly at the right end")


def discrete_forces(scene, R0, R1, inputs, rule="split"):
    """The discrete forces of one step from R0 = R_k to R1 = R_{k+1} with ``inputs`` (9,)
    = (u_p [N], tau [N m] body frame, T [N m] spatial): ``((f^- nodes (N+1, 3), tau^- (3,)),
    (f^+ nodes, tau^+))`` [kg m/s], [kg m^2/s] (body frame), per ``rule`` (FORCE_RULES)."""
    h, n = scene.h, scene.string.elements
    up, tau, T = (inputs[STEP_INPUTS[name]] for name in STEP_INPUTS.names)
    nodes = np.zeros((n + 1, 3))
    nodes[0] = 0.5 * h * up
    left = (nodes, 0.5 * h * (tau + R0.T @ T))
    right = (nodes, 0.5 * h * (tau + R1.T @ T))
    zero = (np.zeros((n + 1, 3)), np.zeros(3))
    if rule == "split":
        return left, right
    if rule == "omitted":
        return zero, zero
    if rule == "spatial torque right half with R_k^T":
        return left, (nodes, 0.5 * h * (tau + R0.T @ T))
    if rule == "wholly at the left end":
        return (2.0 * nodes, h * (tau + R0.T @ T)), zero
    if rule == "wholly at the right end":
        return zero, (2.0 * nodes, h * (tau + R1.T @ T))
    raise ValueError(rule)


# -- finite differences of one step's L_d -------------------------------------------------------------
#: Central differences of one L_d(q_k, q_{k+1}) [kg m/s], [kg m^2/s]: D_1 (w.r.t. q_k), D_2 (w.r.t.
#: q_{k+1}) for nodes (N+1, 3; a fixed pivot's row 0 left 0) and rotation (3,), left-trivialised;
#: ``floor``/``floor_rot`` their rounding error (module docstring).
StepDerivatives = namedtuple("StepDerivatives", "D1 D1_rot D2 D2_rot floor floor_rot")


def central(fun, d):
    """(fun(d) - fun(-d)) / 2d."""
    return (fun(d) - fun(-d)) / (2.0 * d)


def exact_step(x, d):
    """A step near ``d`` by which ``x`` moves exactly: (x + d) - x, so that r_k + t e and
    dr - t e move by the same t (otherwise r_k + d is rounded to the ulp of r_k, ~1e-16 m, a
    relative error ~5e-10 in the r_k-part of D_1 L_d)."""
    return (x + d) - x


def rounding_scales(scene, r, dr, FmI, L_value):
    """Sizes [J s] of the rounding of L_d under a node and a rotation perturbation (module
    docstring): |L_d| + G, G = h g (M + M_p + mu l)(max_a |r_a| + |dr|_max + |rho_c|) bounding the
    gravity terms that cancel inside L_d; the rotation adds |J_d| |F - I| / h, the change of
    tr((I - F) J_d)/h when F - I (entries ~h Omega) is rounded to eps."""
    h, g = scene.h, scene.gravity
    mass = scene.body.mass + (scene.pivot.mass or 0.0) + scene.string.mass_per_length * scene.string.length
    reach = np.abs(r).max() + np.abs(dr).max() + np.linalg.norm(scene.body.rho_c)
    J = scene.body.J
    Jd = 0.5 * np.trace(J) * np.eye(3) - J
    nodes = abs(L_value) + h * g * mass * reach
    return nodes, nodes + np.abs(Jd).max() * np.abs(FmI).max() / h


def fd_step_derivatives(scene, q0, q1, L=discrete_lagrangian):
    """:class:`StepDerivatives` of L_d(q_k, q_{k+1}), q = (r, R). With L_d(q_k, q_{k+1}) =
    L(r_k, R_k, r_{k+1} - r_k, R_k^T R_{k+1} - I): moving r_k by e at fixed r_{k+1} moves dr by
    -e; R_k -> R_k exp(w^) at fixed R_{k+1} turns F_k into exp(-w^) F_k and R_{k+1} ->
    R_{k+1} exp(w^) turns it into F_k exp(w^)."""
    (r0, R0), (r1, R1) = q0, q1
    n = scene.string.elements
    first = 0 if scene.pivot.is_free else 1
    d = REL_STEP * scene.string.u
    dr = r1 - r0
    FmI = R0.T @ (R1 - R0)
    F = np.eye(3) + FmI
    D1, D2 = np.zeros((n + 1, 3)), np.zeros((n + 1, 3))
    for a in range(first, n + 1):
        for i in range(3):
            e = np.zeros((n + 1, 3))
            e[a, i] = 1.0
            D1[a, i] = central(lambda t: L(scene, r0 + t * e, R0, dr - t * e, FmI), exact_step(r0[a, i], d))
            D2[a, i] = central(lambda t: L(scene, r0, R0, dr + t * e, FmI), exact_step(dr[a, i], d))
    basis = np.eye(3)
    D1_rot = np.array([central(lambda t: L(scene, r0, R0 @ expm(t * basis[i]), dr,
                                           left_perturbed(F, FmI, -t * basis[i])), REL_STEP)
                       for i in range(3)])
    D2_rot = np.array([central(lambda t: L(scene, r0, R0, dr, right_perturbed(F, FmI, t * basis[i])),
                               REL_STEP) for i in range(3)])
    nodes, rot = rounding_scales(scene, r0, dr, FmI, L(scene, r0, R0, dr, FmI))
    return StepDerivatives(D1, D1_rot, D2, D2_rot, ROUNDOFF * EPS * nodes / d, ROUNDOFF * EPS * rot / REL_STEP)


def row_excess(residual, terms, floor):
    """max over rows of |residual_a| / (RTOL max_t |term_a| + floor), and of the relative residual
    |residual_a| / max_t |term_a|. Rows are node 3-vectors (all-zero rows, a fixed pivot's, are
    skipped) or one rotation 3-vector."""
    residual = np.atleast_2d(residual)
    size = np.max([np.linalg.norm(np.atleast_2d(t), axis=1) for t in terms], axis=0)
    rows = size > 0
    err = np.linalg.norm(residual, axis=1)[rows]
    return float(np.max(err / (RTOL * size[rows] + floor))), float(np.max(err / size[rows]))


# -- the forced equations along a run --------------------------------------------------------------
def kernel_run(scene, state, inputs):
    """States q_0..q_K of the compiled integrator from ``state``, step k with ``inputs[k]`` (9,)."""
    sim = esp_gym.Simulator(scene)
    sim.set_state(state)
    states = [sim.state]
    for u in inputs:
        sim.step(1, **{name: u[STEP_INPUTS[name]] for name in STEP_INPUTS.names})
        states.append(sim.state)
    return states


def forced_defects(scene, states, inputs, derivs, rule="split"):
    """Excess (residual over tolerance, module docstring; below 1 passes) and max relative
    residual of the forced equations along a run, with the discrete forces of ``rule``:

    * "DEL": D_2 L_d(q_{j-1}, q_j) + D_1 L_d(q_j, q_{j+1}) + f_d^+(j-1) + f_d^-(j) = 0 at every
      interior j, every free node and the rotation;
    * "Legendre": p_k + D_1 L_d(q_k, q_{k+1}) + f_d^-(k) = 0 and
      p_{k+1} - D_2 L_d(q_k, q_{k+1}) - f_d^+(k) = 0 for every step k, nodes and Pi.

    ``derivs[k]``: :class:`StepDerivatives` of step k. Returns {"DEL": (excess, relative),
    "Legendre": (excess, relative)}.
    """
    forces = [discrete_forces(scene, states[k].R, states[k + 1].R, inputs[k], rule)
              for k in range(len(states) - 1)]
    checks = {"DEL": [], "Legendre": []}
    for k, D in enumerate(derivs):
        (fn, ft), (gn, gt) = forces[k]  # f_d^-(k), f_d^+(k)
        s0, s1 = states[k], states[k + 1]
        checks["Legendre"] += [
            (s0.p + D.D1 + fn, (s0.p, D.D1, fn), D.floor),
            (s0.Pi + D.D1_rot + ft, (s0.Pi, D.D1_rot, ft), D.floor_rot),
            (s1.p - D.D2 - gn, (s1.p, D.D2, gn), D.floor),
            (s1.Pi - D.D2_rot - gt, (s1.Pi, D.D2_rot, gt), D.floor_rot),
        ]
        if k + 1 < len(derivs):
            E = derivs[k + 1]
            (hn, ht), _ = forces[k + 1]  # f_d^-(k+1)
            checks["DEL"] += [
                (D.D2 + E.D1 + gn + hn, (D.D2, E.D1, gn + hn), D.floor + E.floor),
                (D.D2_rot + E.D1_rot + gt + ht, (D.D2_rot, E.D1_rot, gt + ht), D.floor_rot + E.floor_rot),
            ]
    out = {}
    for name, rows in checks.items():
        worst = np.array([row_excess(*row) for row in rows])
        out[name] = (float(worst[:, 0].max()), float(worst[:, 1].max()))
    return out


# -- the runs ------------------------------------------------------------------------------------------
STEPS = 20
#: The held inputs of a run's steps, as Simulator.step takes them.
STEP_INPUTS = Layout(("pivot_force", 3), ("body_torque", 3), ("spatial_torque", 3))
#: Constant inputs (u_p [N] spatial, tau [N m] body, T [N m] spatial): a push of the 0.5 kg pivot
#: against part of its weight, and torques that change the paper body's spin (J ~ 0.4 kg m^2) by
#: O(1) rad/s^2; the geometric body (J ~ 1e-3 kg m^2) gets torques 1/30 of those.
PUSH_AND_TORQUES = np.array([2.0, -1.0, -3.0, 0.2, -0.1, 0.3, -0.3, 0.2, 0.4])
SMALL_TORQUES = np.array([0.0, 0.0, 0.0, 0.01, -0.005, 0.008, -0.01, 0.006, 0.012])


def pushed_pivot_state(scene, rng, speed):
    """A free pivot moving at ``speed`` [m/s] into its taut string: elements stretched 0-0.4%,
    other node speeds up to 0.2 m/s, random attitude and spin; momenta by the continuous Legendre
    transform. The first elements go slack within a few steps."""
    from esp_gym.physics.simulator import State, legendre_momenta

    r = random_nodes(scene, rng, stretch=(1.0, 1.004))
    v = rng.uniform(-0.2, 0.2, size=r.shape)
    v[0] = speed * (r[1] - r[0]) / np.linalg.norm(r[1] - r[0])
    R = random_rotation(rng)
    p, Pi = legendre_momenta(scene, r, v, R, rng.uniform(-2.0, 2.0, size=3))
    return State(r, p, R, Pi, 0)


def _case(case_id):
    """(scene, initial state, inputs per step) of a run. h = 1e-3 (0.35 of the N = 5 stability
    bound) where the O(h^2) spatial-torque control must show; the scene's h = 1e-4 elsewhere."""
    free = "paper_example_free_pivot"
    if case_id == "free-pivot":
        scene = esp_gym.load_scene(free, N=5, h=1e-3)
        return scene, random_state(scene, np.random.default_rng(31)), [PUSH_AND_TORQUES] * STEPS
    if case_id == "fixed-pivot":
        scene = esp_gym.load_scene("paper_example", N=5, **GEOMETRIC_OVERRIDES)
        return scene, random_state(scene, np.random.default_rng(32)), [SMALL_TORQUES] * STEPS
    if case_id == "slack-free-pivot":  # the variational step (the settled one leaves it where an
        # element switches: tests/test_switch.py)
        scene = esp_gym.load_scene(free, N=5, **{"string.law": "slack", "solver.slack_switch": "plain"})
        u = np.array([3.0, 0.0, -4.0, 0.2, -0.1, 0.3, -0.3, 0.2, 0.4])  # pushes the pivot on
        return scene, pushed_pivot_state(scene, np.random.default_rng(33), 3.0), [u] * STEPS
    if case_id == "free-pivot-varying-inputs":  # inputs alternate between 1/2 and 3/2 of (a)'s
        scene = esp_gym.load_scene(free, N=5, h=1e-3)
        inputs = [PUSH_AND_TORQUES * (1.0 + 0.5 * (-1) ** k) for k in range(STEPS)]
        return scene, random_state(scene, np.random.default_rng(34)), inputs
    raise ValueError(case_id)


@functools.lru_cache(maxsize=None)
def case_run(case_id):
    """(scene, states, inputs, StepDerivatives per step) of a kernel run, computed once."""
    scene, state, inputs = _case(case_id)
    states = kernel_run(scene, state, inputs)
    derivs = [fd_step_derivatives(scene, (states[k].r, states[k].R), (states[k + 1].r, states[k + 1].R))
              for k in range(len(inputs))]
    return scene, states, inputs, derivs


def defects(case_id, rule="split"):
    """:func:`forced_defects` of a cached run with the discrete forces of ``rule``."""
    scene, states, inputs, derivs = case_run(case_id)
    return forced_defects(scene, states, inputs, derivs, rule)


CASES = ["free-pivot", "fixed-pivot", "slack-free-pivot", "free-pivot-varying-inputs"]


# -- (i) and (iii): the kernel satisfies the forced equations ---------------------------------------
@pytest.mark.parametrize("case_id", CASES)
def test_forced_discrete_action_is_stationary_along_kernel_trajectory(case_id):
    """Lagrange-d'Alembert: along 20 kernel steps with nonzero inputs, the FD derivative of
    sum_k L_d [J s] w.r.t. every interior free node coordinate and R_j exp(eta^), plus
    f_d^+(j-1) + f_d^-(j) (module docstring), vanishes to RTOL of its terms plus the rounding floor.
    Measured max relative residual (excess): free-pivot 1.1e-9 (0.043), fixed-pivot 6.9e-11
    (0.042), slack-free-pivot 9.2e-10 (0.044), free-pivot-varying-inputs 1.2e-9 (0.024)."""
    excess, rel = defects(case_id)["DEL"]
    assert excess < 1.0, rel


@pytest.mark.parametrize("case_id", CASES)
def test_kernel_steps_satisfy_forced_discrete_legendre_transforms(case_id):
    """For every kernel step (q_k, p_k) -> (q_{k+1}, p_{k+1}) of the runs, with the inputs:
    p_k = -D_1 L_d - f_d^-(k) and p_{k+1} = D_2 L_d + f_d^+(k) [kg m/s] for every free node (the
    free pivot's too) and likewise for Pi [kg m^2/s], left-trivialised, L_d by quadrature.
    Measured max relative residual (excess), cases in that order: 8.8e-10 (0.045), 5.4e-11
    (0.043), 6.3e-10 (0.054), 8.4e-10 (0.027)."""
    excess, rel = defects(case_id)["Legendre"]
    assert excess < 1.0, rel


def test_slack_run_has_elements_going_slack_away_from_the_kink():
    """The slack case exercises the law: no element is slack at the start, some are (and some are
    not) during the run; and no element length is within 2 d of u, where the central differences
    would straddle the jump of the second derivative of 1/2 kappa max(|x| - u, 0)^2."""
    scene, states, _, _ = case_run("slack-free-pivot")
    extension = np.array([np.linalg.norm(np.diff(s.r, axis=0), axis=1) for s in states]) - scene.string.u
    slack = extension < 0.0
    assert not slack[0].any()
    assert slack.any() and not slack.all(axis=1).any(), slack.sum(axis=1)
    assert np.abs(extension).min() > 2.0 * REL_STEP * scene.string.u


# -- (ii) each check can fail ----------------------------------------------------------------------------
#: (case, deliberately wrong discrete forces, check). For constant inputs the forced DEL cannot see
#: where a step's impulse sits (f_d^+(j-1) + f_d^-(j) = h u either way; only the momenta can), so
#: the "wholly at one end" controls use the Legendre transforms or the varying-input run.
MUTANTS = [
    ("free-pivot", "omitted", "DEL"),
    ("fixed-pivot", "omitted", "DEL"),
    ("slack-free-pivot", "omitted", "DEL"),
    ("free-pivot", "omitted", "Legendre"),
    ("free-pivot", "spatial torque right half with R_k^T", "DEL"),
    ("free-pivot", "spatial torque right half with R_k^T", "Legendre"),
    ("free-pivot", "wholly at the left end", "Legendre"),
    ("free-pivot", "wholly at the right end", "Legendre"),
    ("free-pivot-varying-inputs", "wholly at the left end", "DEL"),
    ("free-pivot-varying-inputs", "wholly at the right end", "DEL"),
]


@pytest.mark.parametrize("case_id, rule, check", MUTANTS)
def test_forced_checks_detect_deliberate_errors(case_id, rule, check):
    """Each check fails, by at least 10x its tolerance, with deliberately wrong discrete forces.
    Measured excess: omitted 1.4e5-1.4e7; spatial torque right half with R_k^T 275 (DEL), 351
    (Legendre) -- the two rules differ by (h/2)(R_{k+1} - R_k)^T T = O(h^2 |Omega| |T|), hence
    h = 1e-3 here; at the scene's h = 1e-4 it is only 15-19 (fixed-pivot, J ~ 1e-3) and 0.7-0.9
    (slack-free-pivot, the paper's J ~ 0.4), too close to call; wholly at one end 8e6 (Legendre),
    6e6 (DEL, varying inputs)."""
    assert defects(case_id, rule)[check][0] > 10.0


def test_constant_inputs_do_not_reveal_the_split_in_the_discrete_euler_lagrange_equations():
    """With constant inputs f_d^+(j-1) + f_d^-(j) is h u_p, h tau and h R_j^T T whether the forces
    are split or put wholly at one end, so the forced DEL holds either way (the same residuals up
    to the rounding of h/2 + h/2 against h): the split is a statement about the momenta, checked by the Legendre transforms."""
    split = defects("free-pivot")["DEL"]
    for rule in ("wholly at the left end", "wholly at the right end"):
        assert defects("free-pivot", rule)["DEL"] == pytest.approx(split, rel=1e-6)
