"""A drone at the pivot, the Python face: :class:`DroneSimulator` steps a scene whose ``pivot.kind``
is ``drone`` (esp_gym/scene/pivot_params.py) with the compiled step of esp_gym/kernels/drone/quadrotor.py, the
rotors driven by motor commands or a wrench (docs/physics.md, "A drone at the pivot").

The drone's hook is its centre of mass (the step of esp_gym/kernels/drone/quadrotor.py) or a point of its body
away from it (``pivot.drone.rho_q``: esp_gym/kernels/drone/hook.py, the rotation coupled to the
string); the string is explicit, of order 2, at a fixed length.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from ..kernels.drone.hook import HookArrays, hook_diagnostics
from ..kernels.drone.loops import drone_advance
from ..kernels.drone.quadrotor import DRONE, DRONE_DIAG, DroneArrays, drone_diagnostics
from ..kernels.layout import DIAG
from ..kernels.step.string import tridiag_factor
from ..scene.params import Scene, check_rotation
from ..scene.stability import hat
from .arrays import row, stacked_drone_arrays
from .simulator import ROTATION_TOL, Simulator
from .state import attachment_column, mass_matrix, total_weight

#: The drone's state: attitude R_q (3, 3) (body to spatial), body angular momentum Pi_q (3,)
#: [kg m^2/s] about the hook, and the rotor speeds (4,) [rad/s].
DroneState = namedtuple("DroneState", "R Pi rotor_speeds")


def drone_arrays(scene: Scene) -> DroneArrays:
    """A :class:`DroneArrays` for ``scene``'s drone (:func:`use_drone_scene`), at rest
    (:func:`hover_at_rest`)."""
    arrays = row(stacked_drone_arrays(1), 0)
    use_drone_scene(arrays, scene)
    hover_at_rest(arrays, scene)
    return arrays


def pivot_column(scene: Scene) -> np.ndarray:
    """M_tot^-1 e_1 (N+1,) [1/kg], the pivot's column of the inverse mass matrix of a free pivot's
    ``scene``: the attachment's column (esp_gym/physics/state.py) of the string read from its other end."""
    diag, off, _ = mass_matrix(scene)
    reversed_diag = diag[::-1].copy()
    _, cp = tridiag_factor(reversed_diag, off)
    return attachment_column(reversed_diag, off, cp, 0)[::-1].copy()


def hook_arrays(scene: Scene) -> HookArrays:
    """The :class:`~esp_gym.kernels.drone.hook.HookArrays` of ``scene``'s drone (:func:`use_hook_scene`)."""
    n = scene.string.elements
    arrays = HookArrays(rho=np.zeros(3), inertia=np.zeros((3, 3)), jeff=np.zeros((3, 3)), column=np.zeros(n + 1))
    use_hook_scene(arrays, scene)
    return arrays


def use_hook_scene(arrays: HookArrays, scene: Scene) -> None:
    """Write ``scene``'s hook into ``arrays``: rho_q, J_q^h, the reduced inertia of the drone's
    Cayley equation J_q^h + m_q^2 (M_tot^-1)_{11} rho_q^ rho_q^ and the pivot's column of M_tot^-1."""
    drone, mass = scene.pivot.drone, scene.pivot.mass
    column = pivot_column(scene)
    arrays.rho[...] = drone.rho_q
    arrays.inertia[...] = drone.hook_inertia(mass)
    arrays.jeff[...] = arrays.inertia + mass * mass * column[0] * hat(arrays.rho) @ hat(arrays.rho)
    arrays.column[...] = column


def use_drone_scene(arrays: DroneArrays, scene: Scene) -> None:
    """Write ``scene``'s drone into the constants of ``arrays`` (:func:`use_drone`)."""
    use_drone(arrays, scene.pivot.drone, scene.h)


def use_drone(arrays: DroneArrays, drone, h: float) -> None:
    """Write ``drone`` (esp_gym/scene/pivot_params.py ``DroneParams``) into the constants of ``arrays``
    (:data:`DRONE` with the motor lag's decays over the step ``h`` [s], J_q and its inverse, the
    mixer and its inverse)."""
    J = drone.inertia_matrix()
    consts = arrays.consts
    consts[DRONE.scalar("thrust_coefficient")] = drone.thrust_coefficient
    consts[DRONE.scalar("decay_up")], consts[DRONE.scalar("decay_down")] = drone.decays(h)
    consts[DRONE.scalar("max_rotor_speed")] = drone.max_rotor_speed
    consts[DRONE["rate_gain"]] = drone.rate_gain
    consts[DRONE.scalar("rate_loop_steps")] = drone.rate_loop_steps(h)
    arrays.inertia[...] = J
    arrays.inertia_inv[...] = np.linalg.inv(J)
    arrays.mixer[...] = drone.mixer()
    arrays.allocation[...] = drone.allocation()


def hover_at_rest(arrays: DroneArrays, scene: Scene) -> None:
    """:func:`hover_level` carrying the whole rig (drone, string and load)."""
    hover_level(arrays, scene.pivot.drone, total_weight(scene))


def hover_level(arrays: DroneArrays, drone, weight: float) -> None:
    """The drone level (R_q = I) and not turning, its remainders cleared, its rotors and their
    commands at the speed whose thrust is ``weight`` [N], the setpoint cleared, the thrust noise
    off."""
    hover = drone.rotor_speed_for(weight)
    arrays.R[...] = np.eye(3)
    for a in (arrays.Rc, arrays.Pi, arrays.Pic, arrays.setpoint):
        a[...] = 0.0
    arrays.speed[...] = hover
    arrays.command[...] = hover
    arrays.thrust_scale[...] = 1.0


class DroneSimulator(Simulator):
    """A :class:`~esp_gym.physics.simulator.Simulator` whose pivot is a drone (``pivot.kind: drone``).

    >>> sim = DroneSimulator(load_scene("quadrotor_load"))
    >>> sim.step(100)                             # hover: the rotors at the rig's hover speed
    >>> sim.step(100, rotor_commands=[...])       # four motor commands [rad/s]
    >>> sim.step(100, thrust=20.0, torque=[0, 0.01, 0])  # a wrench, through A^-1
    >>> sim.diagnostics()["orthogonality_drone"]
    """

    def __init__(self, scene: Scene, specialise: bool = True):
        if not scene.pivot.is_drone:
            raise ValueError(f"DroneSimulator needs pivot.kind: drone; scene {scene.name!r} has "
                             f"{scene.pivot.kind!r} (use Simulator)")
        if scene.solver.string != "explicit" or scene.solver.scheme.order != 2:
            raise ValueError(f"a drone's scene takes the explicit string of order 2 for now; scene {scene.name!r} "
                             f"has solver.string {scene.solver.string!r} of order {scene.solver.scheme.order}")
        #: The drone's arrays (esp_gym/kernels/drone/quadrotor.py), advanced by the compiled step.
        self.drone = drone_arrays(scene)
        #: The hook's constants (esp_gym/kernels/drone/hook.py), read when it is off the centre of mass.
        self.hook = hook_arrays(scene)
        self._hooked = scene.pivot.drone.offset_hook
        super().__init__(scene, specialise)
        self._coupled = bool(np.any(self.params.rho != 0.0))

    def use_scene(self, scene: Scene, params=None) -> None:
        """:meth:`Simulator.use_scene`, the drone's constants too (its motor lag over the new h)."""
        if not scene.pivot.is_drone:
            raise ValueError(f"use_scene: pivot.kind must stay 'drone', got {scene.pivot.kind!r}")
        super().use_scene(scene, params)
        use_drone_scene(self.drone, scene)
        self._hooked = scene.pivot.drone.offset_hook
        if self._hooked:  # the hook's constants are read only then (an O(N) column per episode)
            use_hook_scene(self.hook, scene)

    # -- state ------------------------------------------------------------------------------
    @property
    def drone_state(self) -> DroneState:
        """A copy of the drone's state (:data:`DroneState`)."""
        d = self.drone
        return DroneState(d.R.copy(), d.Pi.copy(), d.speed.copy())

    def set_drone_state(self, R=None, Pi=None, rotor_speeds=None) -> None:
        """Replace parts of the drone's state (``None`` keeps a part): R_q a rotation to
        ``ROTATION_TOL``, Pi_q (3,) [kg m^2/s], rotor speeds (4,) in [0, max_rotor_speed]
        [rad/s]; the remainders are cleared and the balances restart."""
        d = self.drone
        if R is not None:
            R = self._finite("R", R, (3, 3))
            check_rotation("R", R, ROTATION_TOL)
            d.R[...] = R
            d.Rc[...] = 0.0
        if Pi is not None:
            d.Pi[...] = self._finite("Pi", Pi, (3,))
            d.Pic[...] = 0.0
        if rotor_speeds is not None:
            d.speed[...] = self._speeds("rotor_speeds", rotor_speeds)
        self.reset_balances()

    @staticmethod
    def _finite(name: str, value, shape: tuple) -> np.ndarray:
        arr = np.asarray(value, dtype=np.float64)
        if arr.shape != shape or not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite of shape {shape}, got {value!r}")
        return arr

    def _speeds(self, name: str, value) -> np.ndarray:
        speeds = self._finite(name, value, (4,))
        top = self.scene.pivot.drone.max_rotor_speed
        if np.any(speeds < 0.0) or np.any(speeds > top):
            raise ValueError(f"{name} must lie in [0, max_rotor_speed = {top:g}] rad/s, got {speeds.tolist()}")
        return speeds

    def commands_for(self, thrust: float, torque=(0.0, 0.0, 0.0)) -> np.ndarray:
        """The motor commands [rad/s] whose rotor thrusts A^-1 (f, tau), clipped to [0, k_f
        omega_max^2], make the collective ``thrust`` [N] and body ``torque`` [N m]."""
        wrench = np.concatenate([[float(thrust)], self._finite("torque", torque, (3,))])
        drone = self.scene.pivot.drone
        thrusts = np.clip(self.drone.allocation @ wrench, 0.0, drone.thrust_coefficient * drone.max_rotor_speed ** 2)
        return np.sqrt(thrusts / drone.thrust_coefficient)

    # -- stepping ---------------------------------------------------------------------------
    def step(self, n: int = 1, rotor_commands=None, thrust=None, torque=None) -> None:
        """Advance ``n`` steps with the motor commands held: ``rotor_commands`` (4,) [rad/s] in
        [0, max_rotor_speed], or a wrench, ``thrust`` [N] and ``torque`` (3,) [N m] (body frame),
        made by :meth:`commands_for`; neither keeps the commands of the last call (at first the
        rig's hover). Raises :class:`~esp_gym.errors.SimulationError` on failure (the simulator
        then holds the last good state)."""
        n = int(n)
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        if rotor_commands is not None and (thrust is not None or torque is not None):
            raise ValueError("give rotor_commands or a wrench (thrust, torque), not both")
        if rotor_commands is not None:
            self.drone.command[...] = self._speeds("rotor_commands", rotor_commands)
        elif thrust is not None or torque is not None:
            self.drone.command[...] = self.commands_for(0.0 if thrust is None else thrust,
                                                        (0.0, 0.0, 0.0) if torque is None else torque)
        while n > 0:
            k = min(n, self.steps_per_call)
            n -= k
            self._timed(drone_advance, (self._arrays, self._work, self.params, self._diag, self.drone,
                                        self.hook if self._hooked else None, self._inputs, k, self._stats,
                                        self._coupled, True if self.scene.string.damped else None), k)

    def run(self, *args, **kwargs):
        raise NotImplementedError("DroneSimulator records no trajectory yet: call step() and diagnostics()")

    # -- diagnostics ------------------------------------------------------------------------
    def _update_diag(self) -> float:
        if self._hooked:
            hook_diagnostics(self._arrays, self.params, self._diag, self.drone, self.hook)
        else:
            super()._update_diag()
            drone_diagnostics(self.drone, self._diag.out)
        return float(self._diag.out[DIAG.scalar("energy")])

    def diagnostics(self) -> dict:
        """:meth:`Simulator.diagnostics` of the whole rig (energy and pi3 include the drone's
        rotation; work, the angular impulse and the pivot impulse the rotors' thrust and torque),
        plus the drone's: kinetic_drone [J], pi3_drone [kg m^2/s], orthogonality_drone, thrust [N];
        vectors drone_rates (body frame) [rad/s], drone_torque [N m], rotor_speeds (4,) [rad/s],
        and drone_attitude R_q (3, 3)."""
        out = super().diagnostics()
        d = self.drone.diag
        for name in ("kinetic", "pi3", "orthogonality"):
            out[f"{name}_drone"] = float(d[DRONE_DIAG.scalar(name)])
        out["thrust"] = float(d[DRONE_DIAG.scalar("thrust")])
        out["drone_rates"] = d[DRONE_DIAG["rates"]].copy()
        out["drone_torque"] = d[DRONE_DIAG["torque"]].copy()
        out["rotor_speeds"] = self.drone.speed.copy()
        out["drone_attitude"] = self.drone.R.copy()
        return out

