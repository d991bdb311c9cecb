"""A drone's rotor layout: the mixer that maps the four rotor thrusts to the collective thrust and
the body torque, and its inverse (docs/physics.md, "Rotors"). The compiled pieces that use them
are in esp_gym/kernels/drone/rotors.py.
"""
from __future__ import annotations

import numpy as np

#: Spin directions of the X layout's rotors, in the order of :func:`x_layout`: front right,
#: back left, front left, back right (diagonal rotors spin alike).
X_SPINS = (1.0, 1.0, -1.0, -1.0)

#: A mixer whose condition number passes this cannot be inverted reliably: its layout is refused.
MAX_MIXER_CONDITION = 1e8


def x_layout(arm_length: float) -> np.ndarray:
    """The rotor positions (4, 2) [m] in the body's (b1, b2) plane of an X quadrotor whose rotors
    sit ``arm_length`` [m] from the centre of mass, at 45 degrees to the axes: front right, back
    left, front left, back right (b1 forward, b2 right, b3 down)."""
    if not (np.isfinite(arm_length) and arm_length > 0.0):
        raise ValueError(f"arm_length must be a finite length > 0 [m], got {arm_length!r}")
    a = arm_length / np.sqrt(2.0)
    return np.array([[a, a], [-a, -a], [a, -a], [-a, a]])


def mixer(positions, spins, torque_ratio: float) -> np.ndarray:
    """The mixer A (4, 4): (f, tau_1, tau_2, tau_3) = A (T_1..T_4), for rotors at ``positions``
    (4, 2) [m] (body frame, about the centre of mass) spinning in directions ``spins`` (4, +-1)
    with drag torque ``torque_ratio`` = k_m / k_f [m] times their thrust: f = sum T_i,
    tau = (-sum y_i T_i, sum x_i T_i, k_m/k_f sum s_i T_i). Raises ValueError, naming the
    layout, if A cannot be inverted (the rate controller needs A^-1)."""
    positions = np.asarray(positions, dtype=np.float64)
    spins = np.asarray(spins, dtype=np.float64)
    if positions.shape != (4, 2) or not np.all(np.isfinite(positions)):
        raise ValueError(f"rotor positions must be 4 finite (x, y) pairs [m], got {positions.tolist()!r}")
    if spins.shape != (4,) or not np.all(np.abs(spins) == 1.0):
        raise ValueError(f"rotor spins must be four of +1 or -1, got {spins.tolist()!r}")
    if not (np.isfinite(torque_ratio) and torque_ratio > 0.0):
        raise ValueError(f"torque_ratio k_m/k_f must be a finite length > 0 [m], got {torque_ratio!r}")
    A = np.vstack([np.ones(4), -positions[:, 1], positions[:, 0], torque_ratio * spins])
    if np.linalg.cond(A) > MAX_MIXER_CONDITION:
        raise ValueError(f"the rotor layout (positions {positions.tolist()}, spins {spins.tolist()}) gives a "
                         "mixer that cannot be inverted: no set of rotor thrusts makes every collective thrust "
                         "and body torque")
    return A


def allocation(mixer_matrix) -> np.ndarray:
    """A^-1 (4, 4): the rotor thrusts [N] that make a wrench (f [N], tau [N m])."""
    return np.linalg.inv(np.asarray(mixer_matrix, dtype=np.float64))
