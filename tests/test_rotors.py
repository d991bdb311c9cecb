"""The drone's rotors (esp_gym/scene/rotors.py, esp_gym/kernels/drone/rotors.py; docs/physics.md, "Rotors"):
the motor lag is the ODE's exact solution, a lag of zero is the command, the mixer maps thrusts
to the documented wrench and refuses a layout it cannot invert, and the rate controller makes
Euler's equation the first-order tracking law it is documented to be."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from esp_gym.kernels.drone.rotors import motor_lag, rate_command, rotor_wrench, wrench_command
from esp_gym.scene.rotors import X_SPINS, allocation, mixer, x_layout

#: A Crazyflie-class rotor: k_f [N s^2/rad^2] (3.16e-10 N/rpm^2), k_m/k_f [m], arm [m].
KF = 3.16e-10 * (60.0 / (2.0 * np.pi)) ** 2
TORQUE_RATIO = 7.94e-12 / 3.16e-10
ARM = 0.0397


def lag_ode(command, t_up, t_down, speed0, t_final):
    """omega(t_final) from the lag's ODE, integrated to 1e-12 (a command held)."""
    def rhs(_, w):
        t_m = t_up if command > w[0] else t_down
        return [(command - w[0]) / t_m]
    return solve_ivp(rhs, (0.0, t_final), [speed0], rtol=1e-12, atol=1e-12, method="DOP853").y[0, -1]


@pytest.mark.parametrize("speed0, command", [(500.0, 2000.0), (2000.0, 500.0)])
def test_the_motor_lag_is_the_odes_exact_solution_at_any_step(speed0, command):
    """Up and down, with different time constants: one step of 20 ms, ten of 2 ms and the ODE
    agree to round-off (a scheme with a discretisation error would differ by O(h))."""
    t_up, t_down, t_final = 0.0125, 0.025, 0.02
    exact = lag_ode(command, t_up, t_down, speed0, t_final)
    one = motor_lag(speed0, command, np.exp(-t_final / t_up), np.exp(-t_final / t_down))
    ten = speed0
    for _ in range(10):
        ten = motor_lag(ten, command, np.exp(-t_final / 10 / t_up), np.exp(-t_final / 10 / t_down))
    assert abs(one - exact) <= 1e-9 * command and abs(ten - exact) <= 1e-9 * command
    # negative control: explicit Euler on the same ten steps is off by far more
    euler = speed0
    t_m = t_up if command > speed0 else t_down
    for _ in range(10):
        euler += t_final / 10 * (command - euler) / t_m
    assert abs(euler - exact) > 1e-3 * command


def test_a_lag_of_zero_is_the_command_itself():
    """t_m = 0: e^(-h/t_m) = 0, and the speed is the command bit for bit (direct thrust)."""
    for speed0, command in ((0.0, 1234.5), (3000.0, 17.25)):
        assert motor_lag(speed0, command, 0.0, 0.0) == command


def test_the_x_mixer_makes_the_documented_wrench():
    """Equal thrusts: collective only. Thrust (along -b3, up) moved from the left rotors to the
    right ones rolls the drone left (-tau_1; b1 forward, b2 right, b3 down), from the back to the
    front pitches its nose up (+tau_2), from one spin direction to the other yaws it; the
    allocation inverts the mixer."""
    A = mixer(x_layout(ARM), X_SPINS, TORQUE_RATIO)
    np.testing.assert_allclose(A @ np.full(4, 0.1), [0.4, 0.0, 0.0, 0.0], atol=1e-15)
    a = ARM / np.sqrt(2.0)
    # rotors: front right, back left, front left, back right (x forward, y right)
    right_minus_left = np.array([1.0, -1.0, -1.0, 1.0]) * 0.01  # more thrust on the right (y > 0)
    np.testing.assert_allclose(A @ right_minus_left, [0.0, -4 * a * 0.01, 0.0, 0.0], atol=1e-15)
    front_minus_back = np.array([1.0, -1.0, 1.0, -1.0]) * 0.01
    np.testing.assert_allclose(A @ front_minus_back, [0.0, 0.0, 4 * a * 0.01, 0.0], atol=1e-15)
    spin = np.array([1.0, 1.0, -1.0, -1.0]) * 0.01
    np.testing.assert_allclose(A @ spin, [0.0, 0.0, 0.0, 4 * TORQUE_RATIO * 0.01], atol=1e-15)
    np.testing.assert_allclose(allocation(A) @ A, np.eye(4), atol=1e-12)
    wrench = np.empty(4)
    speeds = np.array([1500.0, 1600.0, 1700.0, 1800.0])
    rotor_wrench(speeds, KF, np.ones(4), A, wrench)
    np.testing.assert_allclose(wrench, A @ (KF * speeds ** 2), rtol=1e-14)


def test_a_layout_the_controller_cannot_invert_is_refused():
    """Negative control: all four rotors spinning one way cannot make a yaw torque without a
    collective thrust, and the error names the layout; bad shapes and values name themselves."""
    with pytest.raises(ValueError, match="cannot be inverted"):
        mixer(x_layout(ARM), (1.0, 1.0, 1.0, 1.0), TORQUE_RATIO)
    with pytest.raises(ValueError, match="rotor spins"):
        mixer(x_layout(ARM), (1.0, 0.5, -1.0, -1.0), TORQUE_RATIO)
    with pytest.raises(ValueError, match="rotor positions"):
        mixer(np.zeros((3, 2)), X_SPINS, TORQUE_RATIO)
    with pytest.raises(ValueError, match="arm_length"):
        x_layout(float("nan"))
    with pytest.raises(ValueError, match="torque_ratio"):
        mixer(x_layout(ARM), X_SPINS, -1.0)


def _closed_loop_rates(inertia, gain, target, rates0, thrust, feedforward=True, t_final=0.2):
    """Euler's equation J dOmega/dt + Omega x J Omega = tau, with tau the wrench of the rate
    controller's commands (no lag), integrated to 1e-12; returns (times, rates)."""
    A = mixer(x_layout(ARM), X_SPINS, TORQUE_RATIO)
    A_inv = allocation(A)
    commands, wrench = np.empty(4), np.empty(4)

    def rhs(_, w):
        rate_command(w, target, thrust, inertia, gain, A_inv, 1.0, KF, commands)
        rotor_wrench(commands, KF, np.ones(4), A, wrench)
        tau = wrench[1:] - (0.0 if feedforward else np.cross(w, inertia @ w))
        return np.linalg.solve(inertia, tau - np.cross(w, inertia @ w))

    t = np.linspace(0.0, t_final, 41)
    return t, solve_ivp(rhs, (0.0, t_final), rates0, t_eval=t, rtol=1e-12, atol=1e-14, method="DOP853").y.T


def test_the_rate_controller_makes_the_rates_first_order():
    """Unsaturated, with the gyroscopic feed-forward: Omega(t) - Omega_d = e^(-K t) (Omega(0) -
    Omega_d) per axis, for an unequal inertia and a large initial spin. Negative control:
    without the feed-forward the axes couple and the law is off by far more."""
    inertia = np.diag([1.4e-5, 1.6e-5, 2.17e-5])
    gain = np.array([20.0, 25.0, 10.0])
    target = np.array([1.0, -2.0, 0.5])
    rates0 = np.array([-3.0, 4.0, 6.0])
    thrust = 0.027 * 9.81
    t, rates = _closed_loop_rates(inertia, gain, target, rates0, thrust)
    law = target + np.exp(-np.outer(t, gain)) * (rates0 - target)
    assert np.max(np.abs(rates - law)) < 1e-8
    _, uncompensated = _closed_loop_rates(inertia, gain, target, rates0, thrust, feedforward=False)
    assert np.max(np.abs(uncompensated - law)) > 1e-2


def test_the_rate_controllers_commands_stay_in_the_motors_range():
    """A torque the rotors cannot make saturates each thrust in [0, T_max]: commands in
    [0, sqrt(T_max / k_f)], never NaN."""
    A_inv = allocation(mixer(x_layout(ARM), X_SPINS, TORQUE_RATIO))
    commands = np.empty(4)
    max_thrust = 0.15
    rate_command(np.zeros(3), np.array([500.0, -500.0, 500.0]), 0.3, np.diag([1.4e-5, 1.4e-5, 2.17e-5]),
                 np.full(3, 20.0), A_inv, max_thrust, KF, commands)
    assert np.all(np.isfinite(commands))
    assert np.all(commands >= 0.0) and np.all(commands <= np.sqrt(max_thrust / KF) * (1 + 1e-15))
    assert np.any(commands == 0.0) and np.any(commands == np.sqrt(max_thrust / KF))


def wrench_of(commands, A):
    """The wrench (f, tau) [N, N m] the rotors make at speeds ``commands``."""
    out = np.zeros(4)
    rotor_wrench(np.asarray(commands), KF, np.ones(4), A, out)
    return out


def test_saturated_rotors_give_up_yaw_first_then_tilt_never_the_thrust():
    """An X Crazyflie at hover asked for a yaw torque no rotor split can make: the thrust and the
    roll-pitch torque come out exact (1e-12) and the yaw takes what is left, in range; asked
    for too much roll as well, roll and pitch shrink together (their ratio kept) and yaw gets
    nothing. Negative control: clipping each rotor alone loses the roll torque."""
    A = mixer(x_layout(ARM), X_SPINS, TORQUE_RATIO)
    Ainv = allocation(A)
    top = 0.15  # [N] per rotor
    commands = np.zeros(4)
    thrust, roll = 0.3, 2e-3
    wrench_command(thrust, (roll, 0.0, 0.05), Ainv, top, KF, commands)
    made = wrench_of(commands, A)
    np.testing.assert_allclose(made[:3], [thrust, roll, 0.0], rtol=1e-12, atol=1e-15)
    assert 0.0 < made[3] < 0.05
    assert np.all(KF * commands ** 2 <= top * (1 + 1e-12))
    wrench_command(thrust, (0.02, -0.01, 0.05), Ainv, top, KF, commands)
    made = wrench_of(commands, A)
    assert made[0] == pytest.approx(thrust, rel=1e-12)
    assert made[1] / made[2] == pytest.approx(-2.0, rel=1e-12) and abs(made[3]) <= 1e-15
    naive = np.sqrt(np.clip(Ainv @ [thrust, roll, 0.0, 0.05], 0.0, top) / KF)
    assert abs(wrench_of(naive, A)[1] - roll) > 0.5 * roll
