"""A team's drones, the Python face of esp_gym/kernels/team/drones.py (docs/physics.md, "Drones at a
team's pivots"): their arrays, states, motor commands and diagnostics, for
:class:`~esp_gym.team.simulator.TeamSimulator`."""
from __future__ import annotations

import numpy as np

from .. import TEAM_ENV_ID
from ..kernels.drone.quadrotor import Q_THRUST_COEFFICIENT
from ..kernels.team.drones import TeamDrones
from ..pendulum.env_setup import check_thrust
from ..physics.arrays import copy_into, row, stacked_drone_arrays
from ..physics.drone import DroneState, use_drone
from ..physics.simulator import ROTATION_TOL
from ..scene.params import check_rotation


def finite(name: str, value, shape: tuple) -> np.ndarray:
    """``value`` as a float array of ``shape``, or a ValueError naming ``name``."""
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite of shape {shape}, got {value!r}")
    return arr


def hover_shares(team) -> np.ndarray:
    """The weight each pivot of ``team`` (a :class:`~esp_gym.team.scene.TeamScene`) carries at
    hover (K,) [N]: its own, its string's and the load's K-th share."""
    sections = team.pivots()
    strings = [team.scene.string] + [s.string for s in team.strings]
    g = team.scene.gravity
    return np.array([g * (sections[k].mass + strings[k].length * strings[k].mass_per_length
                          + team.scene.body.mass / team.size) for k in range(team.size)])


def check_lift(team, where: str = "") -> None:
    """ValueError unless every drone of ``team`` lifts its :func:`hover_shares` with the single
    drone's margin (esp_gym/pendulum/env_setup.py ``check_thrust``); ``where``: which team, for the message."""
    shares = hover_shares(team)
    for k, pivot in enumerate(team.pivots()):
        if pivot.is_drone:
            check_thrust(f"{TEAM_ENV_ID}: drone {k}", pivot.drone.max_thrust, shares[k], where)


class Fleet:
    """The drones of a :class:`~esp_gym.team.scene.TeamScene` stepped at ``h`` [s]: ``pivots`` the
    pivots that are drones (0: string 0's), in the order of every per-drone array here;
    ``arrays`` the kernel's :data:`~esp_gym.kernels.team.drones.TeamDrones`; ``rates`` whether
    the rate controller sets the motor commands before every step."""

    def __init__(self, team, h: float):
        sections = team.pivots()
        self.pivots = [k for k, pivot in enumerate(sections) if pivot.is_drone]
        self._sections = [sections[k] for k in self.pivots]
        #: each drone's parameters (esp_gym/scene/pivot_params.py ``DroneParams``)
        self.drone_params = [pivot.drone for pivot in self._sections]
        self._shares = hover_shares(team)[self.pivots]
        n = len(self.pivots)
        self.arrays = TeamDrones(arrays=stacked_drone_arrays(n), pivot=np.array(self.pivots, dtype=np.int64),
                                 pending=np.zeros((n, 2, 3)))
        for d, pivot in enumerate(self._sections):
            use_drone(row(self.arrays.arrays, d), pivot.drone, h)
        self.rates = False

    def use_arrays(self, drones: TeamDrones) -> None:
        """Keep the drones in ``drones`` (a batch's row views: esp_gym/team/batch.py) from now on,
        the current arrays copied into them."""
        copy_into(self.arrays.arrays, drones.arrays)
        drones.pivot[...] = self.arrays.pivot
        drones.pending[...] = self.arrays.pending
        self.arrays = drones

    def __len__(self) -> int:
        return len(self.pivots)

    def shares(self) -> np.ndarray:
        """The weight each drone carries at hover [N]: its own, its string's and the load's K-th
        share (the rotor speed of :meth:`hovering`)."""
        return self._shares.copy()

    def hovering(self) -> tuple:
        """Every drone level and not turning, its rotors at the speed of its :meth:`shares`."""
        return tuple(DroneState(np.eye(3), np.zeros(3), np.full(4, pivot.drone.rotor_speed_for(w)))
                     for pivot, w in zip(self._sections, self._shares))

    def states(self) -> tuple:
        """A copy of every drone's :data:`~esp_gym.physics.drone.DroneState`."""
        D = self.arrays.arrays
        return tuple(DroneState(D.R[d].copy(), D.Pi[d].copy(), D.speed[d].copy()) for d in range(len(self)))

    def commands(self) -> np.ndarray:
        """The motor commands (n, 4) [rad/s] held now."""
        return self.arrays.arrays.command.copy()

    def _tops(self) -> np.ndarray:
        return np.array([pivot.drone.max_rotor_speed for pivot in self._sections])

    def set_states(self, drones) -> None:
        """Every drone's state (R_q a rotation to ROTATION_TOL, Pi_q (3,) [kg m^2/s], rotor speeds
        (4,) in [0, max_rotor_speed] [rad/s]), the motor commands those speeds, the remainders
        and the setpoints cleared, the rate controller off."""
        if len(drones) != len(self):
            raise ValueError(f"state.drones has {len(drones)} drones, the team {len(self)} (pivots {self.pivots})")
        checked = []
        for d, (drone, top) in enumerate(zip(drones, self._tops())):
            R, Pi, speeds = (finite(f"state.drones[{d}].{name}", value, shape)
                             for name, value, shape in zip(DroneState._fields, drone, ((3, 3), (3,), (4,))))
            check_rotation(f"state.drones[{d}].R", R, ROTATION_TOL)
            if np.any(speeds < 0.0) or np.any(speeds > top):
                raise ValueError(f"state.drones[{d}].rotor_speeds must lie in [0, max_rotor_speed = {top:g}] rad/s, "
                                 f"got {speeds.tolist()}")
            checked.append((R, Pi, speeds))
        D = self.arrays.arrays
        for d, (R, Pi, speeds) in enumerate(checked):
            D.R[d], D.Pi[d], D.speed[d], D.command[d] = R, Pi, speeds, speeds
            D.Rc[d] = 0.0
            D.Pic[d] = 0.0
            D.setpoint[d] = 0.0
        self.rates = False

    def command(self, rotor_commands=None, thrust=None, torque=None, rates=None) -> None:
        """The motor commands of :meth:`~esp_gym.team.simulator.TeamSimulator.step` (its
        docstring); none given keeps the last."""
        n = len(self)
        D = self.arrays.arrays
        if rotor_commands is not None:
            if thrust is not None or torque is not None or rates is not None:
                raise ValueError("give rotor_commands or a thrust with torque or rates, not both")
            commands = finite("rotor_commands", rotor_commands, (n, 4))
            tops = self._tops()
            if np.any(commands < 0.0) or np.any(commands > tops[:, None]):
                raise ValueError(f"rotor_commands must lie in [0, max_rotor_speed] rad/s per drone (max "
                                 f"{tops.tolist()}), got {commands.tolist()}")
            D.command[...] = commands
            self.rates = False
            return
        if thrust is None and torque is None and rates is None:
            return
        if torque is not None and rates is not None:
            raise ValueError("give the drones' torque or their rates, not both")
        f = finite("thrust", np.zeros(n) if thrust is None else thrust, (n,))
        if rates is not None:  # the rate controller sets the commands before every step
            D.setpoint[:, 0] = f
            D.setpoint[:, 1:] = finite("rates", rates, (n, 3))
            self.rates = True
            return
        tau = finite("torque", np.zeros((n, 3)) if torque is None else torque, (n, 3))
        for d, pivot in enumerate(self._sections):
            drone = pivot.drone
            thrusts = np.clip(D.allocation[d] @ np.concatenate([[f[d]], tau[d]]), 0.0,
                              drone.thrust_coefficient * drone.max_rotor_speed ** 2)
            D.command[d] = np.sqrt(thrusts / drone.thrust_coefficient)
        self.rates = False

    def body_rates(self) -> np.ndarray:
        """Each drone's body rates Omega_q = J_q^-1 Pi_q (n, 3) (body frame) [rad/s], summed in one
        order on every processor (einsum's would follow its SIMD path)."""
        D = self.arrays.arrays
        inv, Pi = D.inertia_inv, D.Pi
        return inv[:, :, 0] * Pi[:, None, 0] + inv[:, :, 1] * Pi[:, None, 1] + inv[:, :, 2] * Pi[:, None, 2]

    def kinetic_energies(self) -> np.ndarray:
        """Each drone's rotational kinetic energy 1/2 Pi_q . J_q^-1 Pi_q (n,) [J]."""
        return 0.5 * np.einsum("di,di->d", self.arrays.arrays.Pi, self.body_rates())

    def attitudes(self) -> np.ndarray:
        """Each drone's attitude R_q (n, 3, 3): the arrays' own (valid until the drones step)."""
        return self.arrays.arrays.R

    def diagnostics(self) -> dict:
        """Per drone (n,): ``kinetic_drones`` 1/2 Pi_q . J_q^-1 Pi_q [J], ``pi3_drones`` e3 . R_q Pi_q
        [kg m^2/s], ``orthogonality_drones`` ||R_q^T R_q - I||, ``drone_thrust`` [N]; and
        ``drone_rates`` (n, 3) (body frame) [rad/s], ``rotor_speeds`` (n, 4) [rad/s],
        ``drone_attitudes`` R_q (n, 3, 3)."""
        D = self.arrays.arrays
        rates = self.body_rates()
        thrust = D.consts[:, Q_THRUST_COEFFICIENT] * np.einsum("di,di->d", D.thrust_scale, D.speed ** 2)
        return dict(kinetic_drones=self.kinetic_energies(),
                    pi3_drones=np.einsum("i,dij,dj->d", np.array([0.0, 0.0, 1.0]), D.R, D.Pi),
                    orthogonality_drones=np.linalg.norm(np.swapaxes(D.R, 1, 2) @ D.R - np.eye(3), axis=(1, 2)),
                    drone_thrust=thrust,
                    drone_rates=rates, rotor_speeds=D.speed.copy(), drone_attitudes=D.R.copy())
