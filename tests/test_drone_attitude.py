"""A drone's rotation at the default hook (esp_gym/kernels/drone/quadrotor.py; docs/physics.md, "A drone at
the pivot"): the free rigid body's LGVI under the rotors' torque. Torque-free it keeps the
spatial angular momentum and R_q's orthogonality at round-off and its energy without drift; under
torques the spatial angular momentum changes by exactly the step's impulse
h/2 (R_k tau^- + R_{k+1} tau^+); it converges at order 2 and is reversible."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from esp_gym.kernels.drone.quadrotor import attitude_step
from esp_gym.kernels.jit import python_callable

#: A Crazyflie-class drone's inertia about its centre of mass [kg m^2], with unequal moments so
#: that a spin tumbles.
INERTIA = np.diag([1.4e-5, 1.6e-5, 2.17e-5])
SOLVER = (1e-14, 30)
STEP = python_callable(attitude_step)


def new_body(omega0=(3.0, 0.5, 8.0)):
    """(R, Rc, Pi, Pic) at R = I spinning at ``omega0`` [rad/s]."""
    return np.eye(3), np.zeros((3, 3)), INERTIA @ np.asarray(omega0, dtype=np.float64), np.zeros(3)


def scratch():
    return tuple(np.zeros((3, 3)) for _ in range(4))


def torque(t):
    """A smooth body torque [N m] (a rotor-like wobble), body frame."""
    return (2e-6 * np.sin(7.0 * t), -1e-6 * np.cos(5.0 * t), 5e-7 * np.sin(3.0 * t + 0.3))


def run(body, h, nsteps, torqued=False, compensated=True):
    """Step ``body`` in place ``nsteps`` times; returns the spatial angular momenta R Pi (nsteps + 1, 3)
    and the impulses h/2 (R_k tau^- + R_{k+1} tau^+) of each step (nsteps, 3)."""
    R, _, Pi, _ = body
    work = scratch()
    momenta, impulses = [R @ Pi], []
    for k in range(nsteps):
        left = torque(k * h) if torqued else (0.0, 0.0, 0.0)
        right = torque((k + 1) * h) if torqued else (0.0, 0.0, 0.0)
        R_before = R.copy()
        status, _ = STEP(body, INERTIA, h, (left, right), work, SOLVER, compensated)
        assert status == 0
        momenta.append(R @ Pi)
        impulses.append(0.5 * h * (R_before @ np.array(left) + R @ np.array(right)))
    return np.array(momenta), np.array(impulses)


def energy(Pi):
    return 0.5 * Pi @ np.linalg.solve(INERTIA, Pi)


def test_torque_free_the_spatial_angular_momentum_and_orthogonality_stay_at_round_off():
    """A tumbling spin (about all three axes, unequal moments), 20,000 steps of 1 ms: R Pi within
    1e-14 of its start relative to its size, ||I - R^T R|| below 1e-14, and the energy bounded
    with no drift (its error in the second half no larger than in the first, within 10 %)."""
    body = new_body()
    E0 = energy(body[2])
    energies = []
    R, _, Pi, _ = body
    work = scratch()
    m0 = R @ Pi
    worst = 0.0
    for _ in range(20000):
        STEP(body, INERTIA, 1e-3, ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)), work, SOLVER, True)
        worst = max(worst, np.max(np.abs(R @ Pi - m0)))
        energies.append(energy(Pi) - E0)
    assert worst <= 1e-14 * np.linalg.norm(m0)
    assert np.linalg.norm(np.eye(3) - R.T @ R) < 1e-14
    errors = np.abs(np.array(energies))
    assert 0.0 < errors.max() < 1e-3 * E0
    assert errors[10000:].max() <= 1.1 * errors[:10000].max()


def test_under_torque_the_momentum_changes_by_exactly_the_steps_impulse():
    """With left and right torques from the state at each end, R_{k+1} Pi_{k+1} - R_k Pi_k =
    h/2 (R_k tau^- + R_{k+1} tau^+) at round-off, every step. Negative control: the impulse
    counted with R_k on both halves misses by far more than round-off."""
    body = new_body()
    momenta, impulses = run(body, 2e-3, 2000, torqued=True)
    steps = np.diff(momenta, axis=0)
    scale = np.max(np.abs(momenta))
    assert np.max(np.abs(steps - impulses)) < 1e-15 * scale * 10
    # negative control: R_k for the right half too
    body = new_body()
    R, _, Pi, _ = body
    work = scratch()
    misses = []
    for k in range(200):
        left, right = torque(k * 2e-3), torque((k + 1) * 2e-3)
        before, R_before = R @ Pi, R.copy()
        STEP(body, INERTIA, 2e-3, (left, right), work, SOLVER, True)
        wrong = 0.5 * 2e-3 * (R_before @ np.array(left) + R_before @ np.array(right))
        misses.append(np.max(np.abs(R @ Pi - before - wrong)))
    assert max(misses) > 1e3 * 1e-15 * scale


def reference(t_final, omega0=(3.0, 0.5, 8.0)):
    """R and Pi at ``t_final`` from Euler's equations and dR/dt = R Omega^ under :func:`torque`,
    integrated to 1e-13."""
    def rhs(t, y):
        R = y[:9].reshape(3, 3)
        Pi = y[9:]
        omega = np.linalg.solve(INERTIA, Pi)
        hat = np.array([[0.0, -omega[2], omega[1]], [omega[2], 0.0, -omega[0]], [-omega[1], omega[0], 0.0]])
        return np.concatenate([(R @ hat).ravel(), np.cross(Pi, omega) + np.array(torque(t))])
    y0 = np.concatenate([np.eye(3).ravel(), INERTIA @ np.asarray(omega0)])
    y = solve_ivp(rhs, (0.0, t_final), y0, method="DOP853", rtol=1e-13, atol=1e-16).y[:, -1]
    return y[:9].reshape(3, 3), y[9:]


def test_the_rotation_converges_at_order_two():
    """Attitude error at t = 0.2 s against a tight reference, h = 2, 1, 0.5 ms: each halving cuts
    it by 4 (asserted 3.6-4.4)."""
    R_ref, _ = reference(0.2)
    errors = []
    for h in (2e-3, 1e-3, 5e-4):
        body = new_body()
        run(body, h, int(round(0.2 / h)), torqued=True)
        errors.append(Rotation.from_matrix(R_ref.T @ body[0]).magnitude())
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert all(3.6 < r < 4.4 for r in ratios), (errors, ratios)


def test_the_torque_free_step_is_reversible():
    """500 steps forward, then 500 with -h (momentum negated, as the reversal demands): back at
    the start to round-off."""
    body = new_body()
    R, _, Pi, _ = body
    R0, Pi0 = R.copy(), Pi.copy()
    work = scratch()
    zero = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    for _ in range(500):
        STEP(body, INERTIA, 1e-3, zero, work, SOLVER, False)
    Pi *= -1.0
    for _ in range(500):
        STEP(body, INERTIA, 1e-3, zero, work, SOLVER, False)
    Pi *= -1.0
    assert np.max(np.abs(R - R0)) < 1e-12
    assert np.max(np.abs(Pi - Pi0)) < 1e-12 * np.max(np.abs(Pi0))


def test_a_failed_newton_leaves_the_body_untouched():
    """An iteration cap of one cannot converge: the status says so and nothing moved."""
    body = new_body()
    before = [a.copy() for a in body]
    status, _ = STEP(body, INERTIA, 1e-3, ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)), scratch(), (1e-14, 1), True)
    assert status != 0
    for a, b in zip(body, before):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("compensated", [True, False])
def test_both_sum_modes_step_the_same_motion(compensated):
    """Compensated and plain sums agree to round-off growth over 2,000 steps."""
    a, b = new_body(), new_body()
    run(a, 1e-3, 2000, torqued=True, compensated=True)
    run(b, 1e-3, 2000, torqued=True, compensated=compensated)
    assert np.max(np.abs(a[0] - b[0])) < 1e-12
