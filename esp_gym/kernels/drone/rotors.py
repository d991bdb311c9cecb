"""A drone's rotors (docs/physics.md, "Rotors" and "Actuation and the rate controller"): the
motors' first-order lag, stepped exactly; the wrench the mixer makes of the rotor speeds; the
motor commands of a wrench; and the rate controller that turns a collective thrust and body rates
into motor commands.

Rotor i turns at omega_i [rad/s] and pushes with T_i = k_f omega_i^2 [N] along the body's -b3;
the mixer A (4, 4) maps the thrusts to the wrench (f [N], tau [N m], body frame), and its
inverse back (esp_gym/scene/rotors.py builds both from the rotor layout). Small inlined kernels on flat
arrays: the environment's step calls them once per physics step.
"""
import math

from ..jit import kernel


@kernel(inline="always")
def motor_lag(speed, command, decay_up, decay_down):
    """The rotor speed [rad/s] one step after ``speed`` under the held ``command``: the exact
    solution of d(omega)/dt = (command - omega) / t_m, omega_c + (omega - omega_c) e^(-h/t_m),
    with ``decay_up`` = e^(-h/t_up) while spinning up and ``decay_down`` = e^(-h/t_down) while
    spinning down (the sign of command - omega holds along the solution, so either is exact).
    A decay of 0 (t_m = 0) gives the command itself."""
    decay = decay_up if command > speed else decay_down
    return command + (speed - command) * decay


@kernel(inline="always")
def rotor_wrench(speeds, kf, scale, mixer, wrench):
    """``wrench`` (4) = A (k_f omega_i^2 s_i): the collective thrust [N] along -b3, then the body
    torque [N m], from the rotor ``speeds`` (4) [rad/s], ``kf`` [N s^2/rad^2], each rotor's
    thrust ``scale`` s_i (4; 1: its nominal thrust, bit for bit; the environment's thrust noise)
    and the ``mixer`` A (4, 4)."""
    for row in range(4):
        total = 0.0
        for i in range(4):
            total += mixer[row, i] * ((kf * speeds[i] * speeds[i]) * scale[i])
        wrench[row] = total


@kernel(inline="always")
def rate_command(rates, target_rates, thrust, inertia, gain, allocation, max_thrust, kf, commands):
    """Motor commands [rad/s] into ``commands`` (4) that track the body ``target_rates`` (3)
    [rad/s] with the collective ``thrust`` [N]: the torque tau_c = J K (Omega_d - Omega) +
    Omega x J Omega (``inertia`` J (3, 3) [kg m^2], ``gain`` K (3) [1/s], ``rates`` Omega the
    body rates now), the rotor thrusts A^-1 (f, tau_c) (``allocation`` A^-1 (4, 4)) clipped to
    [0, ``max_thrust``] [N], and omega_c = sqrt(T / k_f). Unsaturated and without lag, Euler's
    equation then gives dOmega/dt = K (Omega_d - Omega)."""
    e0 = gain[0] * (target_rates[0] - rates[0])
    e1 = gain[1] * (target_rates[1] - rates[1])
    e2 = gain[2] * (target_rates[2] - rates[2])
    j0 = inertia[0, 0] * rates[0] + inertia[0, 1] * rates[1] + inertia[0, 2] * rates[2]
    j1 = inertia[1, 0] * rates[0] + inertia[1, 1] * rates[1] + inertia[1, 2] * rates[2]
    j2 = inertia[2, 0] * rates[0] + inertia[2, 1] * rates[1] + inertia[2, 2] * rates[2]
    t0 = inertia[0, 0] * e0 + inertia[0, 1] * e1 + inertia[0, 2] * e2 + (rates[1] * j2 - rates[2] * j1)
    t1 = inertia[1, 0] * e0 + inertia[1, 1] * e1 + inertia[1, 2] * e2 + (rates[2] * j0 - rates[0] * j2)
    t2 = inertia[2, 0] * e0 + inertia[2, 1] * e1 + inertia[2, 2] * e2 + (rates[0] * j1 - rates[1] * j0)
    wrench_command(thrust, (t0, t1, t2), allocation, max_thrust, kf, commands)


@kernel(inline="always")
def largest_share(allocation, base, extra, top):
    """The largest alpha in [0, 1] with 0 <= (A^-1 base)_i + alpha (A^-1 extra)_i <= ``top`` [N] for
    every rotor i (``allocation`` A^-1; ``base``, ``extra``: wrenches (f, tau), 4-tuples)."""
    share = 1.0
    for i in range(4):
        b = allocation[i, 0] * base[0] + allocation[i, 1] * base[1] + allocation[i, 2] * base[2] + \
            allocation[i, 3] * base[3]
        e = allocation[i, 0] * extra[0] + allocation[i, 1] * extra[1] + allocation[i, 2] * extra[2] + \
            allocation[i, 3] * extra[3]
        if b + e > top and e > 0.0:
            share = min(share, (top - b) / e)
        elif b + e < 0.0 and e < 0.0:
            share = min(share, -b / e)
    return max(share, 0.0)


@kernel(inline="always")
def wrench_command(thrust, torque, allocation, max_thrust, kf, commands):
    """Motor commands [rad/s] into ``commands`` (4) for the wrench (``thrust`` [N], ``torque`` (3)
    [N m], body frame): the rotor thrusts A^-1 (f, tau) (``allocation`` A^-1 (4, 4)), each in
    [0, ``max_thrust``] [N], and omega_c = sqrt(T / k_f) (``kf`` [N s^2/rad^2]). Where the rotors
    would saturate, the yaw torque gives way first, then roll and pitch together, never the
    collective thrust (docs/physics.md, "Actuation and the rate controller"): each is scaled by
    :func:`largest_share`; unsaturated, both shares are 1 and T = A^-1 (f, tau) bit for bit."""
    t0, t1, t2 = torque
    tilt = largest_share(allocation, (thrust, 0.0, 0.0, 0.0), (0.0, t0, t1, 0.0), max_thrust)
    r0 = tilt * t0
    r1 = tilt * t1
    yaw = largest_share(allocation, (thrust, r0, r1, 0.0), (0.0, 0.0, 0.0, t2), max_thrust) * t2
    for i in range(4):
        t = allocation[i, 0] * thrust + allocation[i, 1] * r0 + allocation[i, 2] * r1 + allocation[i, 3] * yaw
        t = min(max(t, 0.0), max_thrust)
        commands[i] = math.sqrt(t / kf)
