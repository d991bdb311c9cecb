"""A drone whose hook is off its centre of mass (esp_gym/kernels/drone/hook.py; docs/physics.md, "A
drone at the pivot", "The offset hook"): the compiled step against finite differences of the rig's
discrete Lagrangian with the drone's (Ldkrb)-copy (a Lagrangian without the hook's cross term as
the negative control), the inverse Legendre transform of the diagnostics against the forward one,
and pi3's balance rebuilt from the drone's state with the thrust's moment about the hook (left
out: the negative control). The balances, order 2 and reversibility run in tests/test_drone.py
with the offset hook among their scenes."""
import numpy as np
import pytest

import esp_gym
from esp_gym.physics.drone import DroneSimulator, pivot_column
from esp_gym.physics.state import mass_matrix

from discrete_lagrangian import (E3, expm, left_perturbed, random_rotation, random_state, right_perturbed,
                                 rigid_body_lagrangian, string_lagrangian)
from test_discrete_lagrangian import REL_STEP, RTOL, central
from test_drone import wobbling_commands

#: The hook 6 cm below the drone's centre of mass and off its axes (hook -> centre, body frame).
RHO_Q = [0.02, -0.01, -0.06]


def hooked_scene(rho_q=RHO_Q, **overrides):
    return esp_gym.load_scene("quadrotor_load", **{"pivot.drone.rho_q": list(rho_q), **overrides})


def hook_inertia(scene) -> np.ndarray:
    """J_q^h = J_q + m_q (|rho_q|^2 I - rho_q rho_q^T), by its definition."""
    rho = np.array(scene.pivot.drone.rho_q)
    return np.diag(scene.pivot.drone.inertia) + scene.pivot.mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))


def drone_lagrangian(scene, r1, Rq, dr1, FqmI, rho=None) -> float:
    """The drone's copy of (Ldkrb) at the hook r1 [J s]: (r_{N+1}, R, M, J, rho_c) -> (r_1, R_q, m_q,
    J_q^h, rho_q); ``rho`` overrides rho_q in the cross and gravity terms only (negative control)."""
    h, m, g = scene.h, scene.pivot.mass, scene.gravity
    J = hook_inertia(scene)
    Jd = 0.5 * np.trace(J) * np.eye(3) - J
    rho = np.array(scene.pivot.drone.rho_q if rho is None else rho, dtype=float)
    return float(0.5 / h * m * dr1 @ dr1 + np.trace(-FqmI @ Jd) / h + m / h * dr1 @ (Rq @ (FqmI @ rho))
                 + 0.5 * h * m * g * (r1 + Rq @ rho) @ E3 + 0.5 * h * m * g * (r1 + dr1 + Rq @ rho + Rq @ (FqmI @ rho)) @ E3)


def rig_lagrangian(scene, r, R, Rq, dr, FmI, FqmI, rho=None) -> float:
    return (string_lagrangian(scene, r, dr) + rigid_body_lagrangian(scene, r[-1], R, dr[-1], FmI)
            + drone_lagrangian(scene, r[0], Rq, dr[0], FqmI, rho))


def fd_momenta(scene, before, after, rho=None):
    """(p_k, Pi_k, Pi_q,k, p_{k+1}, Pi_{k+1}, Pi_q,k+1) as -D_1 L_d and D_2 L_d by central
    differences (left-trivialised for the rotations), every node free."""
    (r0, R0, Q0), (r1, R1, Q1) = before, after
    n1 = r0.shape[0]
    d = REL_STEP * scene.string.u
    dr = r1 - r0
    FmI, FqmI = R0.T @ (R1 - R0), Q0.T @ (Q1 - Q0)
    F, Fq = np.eye(3) + FmI, np.eye(3) + FqmI

    def L(r, R, Rq, dr_, FmI_, FqmI_):
        return rig_lagrangian(scene, r, R, Rq, dr_, FmI_, FqmI_, rho)

    def nodes(fun):
        out = np.zeros((n1, 3))
        for a in range(n1):
            for i in range(3):
                unit = np.zeros((n1, 3))
                unit[a, i] = 1.0
                out[a, i] = central(lambda t: fun(t * unit), d)
        return out

    def turns(fun):
        return np.array([central(lambda t: fun(t * np.eye(3)[i]), REL_STEP) for i in range(3)])

    p0 = -nodes(lambda e: L(r0 + e, R0, Q0, dr - e, FmI, FqmI))
    Pi0 = -turns(lambda w: L(r0, R0 @ expm(w), Q0, dr, left_perturbed(F, FmI, -w), FqmI))
    Pq0 = -turns(lambda w: L(r0, R0, Q0 @ expm(w), dr, FmI, left_perturbed(Fq, FqmI, -w)))
    p1 = nodes(lambda e: L(r0, R0, Q0, dr + e, FmI, FqmI))
    Pi1 = turns(lambda w: L(r0, R0, Q0, dr, right_perturbed(F, FmI, w), FqmI))
    Pq1 = turns(lambda w: L(r0, R0, Q0, dr, FmI, right_perturbed(Fq, FqmI, w)))
    return p0, Pi0, Pq0, p1, Pi1, Pq1


def unforced_step(seed):
    """A random state of the hooked rig (string, load, drone attitude and spin), rotors stopped,
    and one compiled step: ``(scene, (r, R, R_q) before and after, the momenta before and after)``."""
    scene = hooked_scene(**{"string.law": "elastic"})  # the slack law's settled switch is not variational
    rng = np.random.default_rng(seed)
    sim = DroneSimulator(scene)
    sim.set_state(random_state(scene, rng))
    sim.set_drone_state(R=random_rotation(rng, 0.5), Pi=rng.uniform(-0.05, 0.05, size=3), rotor_speeds=np.zeros(4))
    s0, q0 = sim.state, sim.drone_state
    sim.step(1, rotor_commands=np.zeros(4))
    s1, q1 = sim.state, sim.drone_state
    return scene, ((s0.r, s0.R, q0.R), (s1.r, s1.R, q1.R)), (s0.p, s0.Pi, q0.Pi, s1.p, s1.Pi, q1.Pi)


NAMES = ("p_k", "Pi_k", "Pi_q,k", "p_k+1", "Pi_k+1", "Pi_q,k+1")


def relative_errors(fd, got):
    return {name: float(np.max(np.linalg.norm(np.atleast_2d(a - b), axis=-1)
                               / np.linalg.norm(np.atleast_2d(b), axis=-1)))
            for name, a, b in zip(NAMES, fd, got)}


@pytest.mark.parametrize("seed", [3, 4])
def test_the_step_satisfies_the_discrete_legendre_transforms_of_the_hooked_rig(seed):
    """p_k = -D_1 L_d and p_{k+1} = D_2 L_d for every node (the hook's too), the load's Pi and the
    drone's Pi_q, L_d the string's quadrature plus both bodies' (Ldkrb): relative errors below
    RTOL = 1e-7 (measured 7e-9). Without the hook's cross and gravity terms in L_d (rho_q = 0 there)
    the drone's momenta miss by more than 0.1 (measured 1.08)."""
    scene, (before, after), got = unforced_step(seed)
    errors = relative_errors(fd_momenta(scene, before, after), got)
    assert max(errors.values()) < RTOL, errors
    wrong = relative_errors(fd_momenta(scene, before, after, rho=np.zeros(3)), got)
    assert min(wrong["Pi_q,k"], wrong["Pi_q,k+1"]) > 0.1, wrong


def test_the_diagnostics_invert_the_legendre_transform_at_both_ends():
    """Momenta built from chosen velocities by the continuous Legendre transform (docs/physics.md),
    then the diagnostics: the drone's rates are the chosen Omega_q and the kinetic energy the
    Lagrangian's, to 1e-12 relative (and the pivot's column of M_tot^-1 is the dense solve's); the default hook's J_q^-1 Pi_q misses the rates by > 1e-3."""
    scene = hooked_scene()
    rng = np.random.default_rng(5)
    sim = DroneSimulator(scene)
    st = sim.state
    n = st.r.shape[0] - 1
    v, omega, omega_q = rng.uniform(-0.5, 0.5, (n + 1, 3)), rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
    R, Rq = random_rotation(rng, 0.6), random_rotation(rng, 0.6)
    diag, off, _ = mass_matrix(scene)
    Mtot = np.diag(diag) + off * (np.eye(n + 1, k=1) + np.eye(n + 1, k=-1))
    column = np.linalg.solve(Mtot, np.eye(n + 1)[:, 0])
    assert np.abs(pivot_column(scene) - column).max() <= 1e-12 * np.abs(column).max()
    M, mq = scene.body.mass, scene.pivot.mass
    rc, rq = np.array(scene.body.rho_c), np.array(scene.pivot.drone.rho_q)
    J, Jh = scene.body.J, hook_inertia(scene)
    p = Mtot @ v
    p[n] -= M * R @ np.cross(rc, omega)
    p[0] -= mq * Rq @ np.cross(rq, omega_q)
    Pi = J @ omega + M * np.cross(rc, R.T @ v[n])
    Pi_q = Jh @ omega_q + mq * np.cross(rq, Rq.T @ v[0])
    st.p[...] = p
    st.Pi[...] = Pi
    st.R[...] = R
    st.remainders = None
    sim.set_state(st)
    sim.set_drone_state(R=Rq, Pi=Pi_q)
    d = sim.diagnostics()
    kinetic = (0.5 * v.ravel() @ np.kron(Mtot, np.eye(3)) @ v.ravel() + 0.5 * omega @ J @ omega
               + M * v[n] @ R @ np.cross(omega, rc) + 0.5 * omega_q @ Jh @ omega_q
               + mq * v[0] @ Rq @ np.cross(omega_q, rq))
    assert np.abs(d["drone_rates"] - omega_q).max() <= 1e-12 * np.abs(omega_q).max()
    got = d["kinetic_string"] + d["kinetic_body"] + d["kinetic_pivot"] + d["kinetic_drone"]
    assert got == pytest.approx(kinetic, rel=1e-12)
    assert np.abs(np.linalg.solve(np.diag(scene.pivot.drone.inertia), Pi_q) - omega_q).max() > 1e-3


def pi3_defects(sim, steps, with_moment):
    """Step ``sim`` one step at a time under changing motor commands; per step, pi3's change against
    e3 . [h/2 (r_1 x u)_k + (r_1 x u)_{k+1}) + h/2 (R_q tau_q)_k + (R_q tau_q)_{k+1})], u = -f R_q e3
    and tau_q = tau + rho_q x (-f e3) (``with_moment``) or tau alone, rebuilt here from the state.
    Returns the largest defect and the largest impulse [kg m^2/s]."""
    h = sim.h
    rho = np.array(sim.scene.pivot.drone.rho_q)

    def impulse(d):
        Rq, f = d["drone_attitude"], d["thrust"]
        u = -f * Rq @ E3
        tau = d["drone_torque"] + (np.cross(rho, -f * E3) if with_moment else 0.0)
        return np.cross(d["pivot_position"], u)[2] + (Rq @ tau)[2]

    defect = size = 0.0
    for k in range(steps):
        d0 = sim.diagnostics()
        sim.step(1, rotor_commands=wobbling_commands(sim, k))
        d1 = sim.diagnostics()
        expected = 0.5 * h * (impulse(d0) + impulse(d1))
        defect = max(defect, abs(d1["pi3"] - d0["pi3"] - expected))
        size = max(size, abs(expected))
    return defect, size


@pytest.mark.parametrize("with_moment, agrees", [(True, True), (False, False)])
def test_pi3_moves_by_the_thrusts_moment_about_the_hook(with_moment, agrees):
    """pi3's change per step is the rotors' angular impulse about e3 with the thrust's moment about
    the offset hook in it, to 1e-11 of the impulse (measured 5.5e-13); left out (the negative
    control), it misses by more than 1e-3 of it (measured 1.1)."""
    sim = DroneSimulator(hooked_scene())
    sim.set_drone_state(Pi=np.array([0.01, -0.02, 0.005]))
    defect, size = pi3_defects(sim, 40, with_moment)
    if agrees:
        assert defect <= 1e-11 * size
    else:
        assert defect > 1e-3 * size


def test_the_hooked_step_at_a_vanishing_offset_is_the_default_step():
    """rho_q = 0 runs the default hook's step (kernels/drone/quadrotor.py); the hooked step at rho_q = 1e-300
    gives the same rollout to round-off (1e-12): the two paths are one model."""
    runs = []
    for rho in ([0.0, 0.0, 0.0], [0.0, 0.0, 1e-300]):
        sim = DroneSimulator(hooked_scene(rho))
        for k in range(20):
            sim.step(10, rotor_commands=wobbling_commands(sim, 10 * k))
        runs.append(np.concatenate([sim.state.r.ravel(), sim.drone_state.R.ravel(), sim.drone_state.Pi]))
    assert np.abs(runs[0] - runs[1]).max() <= 1e-12
