"""What each agent of a team sees and does (docs/team.md, "Spaces"): its observation's layout
(:func:`agent_layout`) and sensor noise, and its action: a point pivot's force (``force``) or a
drone's four numbers (``thrust_rates``, ``thrust_torque``, ``motors``: :class:`DroneDrive`)."""
from __future__ import annotations

import numpy as np

from ..kernels.drone.quadrotor import ACTUATIONS as DRONE_ACTUATIONS
from ..kernels.layout import Layout
from ..pendulum.env_setup import DRONE_RATE_LIMIT

#: A team's actuations: ``force`` pushes point pivots; the others fly drones.
ACTUATIONS = ("force",) + DRONE_ACTUATIONS

#: Sensor noise per field at ``sensor_noise=1`` (as esp_gym/pendulum/observe.py's UNIT_NOISE) [SI].
TEAM_UNIT_NOISE = {"pivot_position_error": 0.01, "pivot_velocity": 0.05, "hook_tension": 0.1, "load_offset": 0.01,
                   "load_position_error": 0.01, "load_velocity": 0.05, "load_attitude_6d": 0.01, "load_rates": 0.05,
                   "load_target_offset": 0.01, "neighbours": 0.01, "drone_attitude_6d": 0.01, "drone_rates": 0.05,
                   "string_length": 0.005}


def action_size(actuation: str, winch: bool = False) -> int:
    """One agent's action size: 3 for a point pivot's force, 4 for a drone; with ``winch`` one
    more, its string's reel speed."""
    return (3 if actuation == "force" else 4) + int(winch)


def agent_layout(size: int, observation: str = "full", drones: bool = False, winch: bool = False) -> Layout:
    """One agent's observation: its pivot's position error and velocity, with ``drones`` its
    drone's attitude (R_q's first two columns) and body rates, its string's hook tension (with
    ``winch`` and its unstretched length), then
    in the ``full`` mode the load relative to it and the load's error, velocity, attitude and
    rates, in the ``hook`` mode only the load's target relative to it; and the other pivots
    relative to it (the next one first)."""
    fields = [("pivot_position_error", 3), ("pivot_velocity", 3)]
    if drones:
        fields += [("drone_attitude_6d", 6), ("drone_rates", 3)]
    fields.append(("hook_tension", 3))
    if winch:
        fields.append(("string_length", 1))
    if observation == "full":
        fields += [("load_offset", 3), ("load_position_error", 3), ("load_velocity", 3), ("load_attitude_6d", 6),
                   ("load_rates", 3)]
    else:
        fields += [("load_target_offset", 3)]
    if size > 1:
        fields.append(("neighbours", 3 * (size - 1)))
    return Layout(*fields)


class DroneDrive:
    """A drone team's actions (K, 4) in [-1, 1] -> the motor commands of
    :meth:`~esp_gym.team.fleet.Fleet.command`, as the single drone's environment reads them
    (docs/environment.md, "Drone actuation") with each drone's hover thrust its
    :meth:`~esp_gym.team.fleet.Fleet.shares`: ``thrust_rates``, the collective thrust
    clip(f_hover (1 + a_0), 0, f_max) and the body rates DRONE_RATE_LIMIT a_1..3;
    ``thrust_torque``, that thrust and the body torque (f_hover/4 arm, f_hover/4 arm,
    f_hover/4 k_m/k_f) a_1..3; ``motors``, each rotor's thrust clip(f_hover/4 (1 + a_i), 0,
    k_f omega_max^2) as its speed's command."""

    def __init__(self, fleet, actuation: str):
        if actuation not in DRONE_ACTUATIONS:
            raise ValueError(f"actuation must be one of {DRONE_ACTUATIONS} for a drone team, got {actuation!r}")
        self.actuation = actuation
        #: each drone's hover thrust [N], and the body rates (3) [rad/s] and torques (K, 3) [N m] at action 1
        self.hover = fleet.shares()
        self.rate_limit = np.asarray(DRONE_RATE_LIMIT, dtype=float)
        drones = fleet.drone_params
        self.max_thrust = np.array([d.max_thrust for d in drones])  #: each drone's [N]
        self.torque_limit = np.array([(0.25 * w * d.arm_length, 0.25 * w * d.arm_length,
                                        0.25 * w * d.torque_coefficient / d.thrust_coefficient)
                                       for w, d in zip(self.hover, drones)])
        self._kf = np.array([d.thrust_coefficient for d in drones])
        self._rotor_max = np.array([d.thrust_coefficient * d.max_rotor_speed ** 2 for d in drones])

    def __call__(self, action: np.ndarray) -> dict:
        """The keyword arguments of TeamSimulator.step for the clipped ``action`` (K, 4)."""
        if self.actuation == "motors":
            thrusts = np.clip(0.25 * self.hover[:, None] * (1.0 + action), 0.0, self._rotor_max[:, None])
            return {"rotor_commands": np.sqrt(thrusts / self._kf[:, None])}
        thrust = np.clip(self.hover * (1.0 + action[:, 0]), 0.0, self.max_thrust)
        if self.actuation == "thrust_rates":
            return {"thrust": thrust, "rates": self.rate_limit * action[:, 1:]}
        return {"thrust": thrust, "torque": self.torque_limit * action[:, 1:]}
