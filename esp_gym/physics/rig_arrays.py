"""Every physics struct a rig's compiled entry points take, made from a scene in one place
(:func:`make_arrays`): the string's state, work arrays, stepper constants and diagnostics, the
winch's arrays, and a drone's and its offset hook's, for one environment or stacked for a batch.
The environment's own arrays (kernels/env/arrays.py ``EnvArrays``) depend on its task and
options, not only on the scene, and are its (esp_gym/pendulum/control.py)."""
from __future__ import annotations

from typing import NamedTuple, Optional

from ..scene.params import Scene
from .arrays import repeated, stacked
from .drone import DroneSimulator
from .simulator import Simulator


class RigArrays(NamedTuple):
    """A rig's physics structs, named as esp_gym/physics/rig.py ``STRUCTS`` names them (``drone`` and
    ``hook`` None where the rig has none), and the simulator they came from."""

    state: object
    work: object
    params: object
    diag: object
    winch: object
    drone: object
    hook: object
    sim: Simulator

    def structs(self, names, **others) -> tuple:
        """The structs ``names`` (a rig's, in esp_gym/physics/rig.py STRUCTS' order), ``others`` (the
        environment's ``env``) among them, each as the plain tuple an entry point takes."""
        arrays = {**self._asdict(), **others}
        return tuple(tuple(arrays[name]) for name in names)


def make_arrays(scene: Scene, batch: Optional[int] = None) -> RigArrays:
    """The physics structs of ``scene``'s rig: for one environment (``batch`` None) the live
    arrays of a :class:`~esp_gym.physics.simulator.Simulator` (a :class:`~esp_gym.physics.drone.DroneSimulator` with a
    drone at the pivot) made at the scene's initial state, which then steps in them; for a batch
    of ``batch`` sub-environments each struct stacked along a leading axis, zeros where a state
    is set at reset and the constants (the stepper's, the winch's weights, the drone's and the
    hook's) the scene's in every row, the simulator their template. The winch's arrays are made
    in either case (a rig without a winch passes them unread)."""
    drone = scene.pivot.is_drone
    sim = DroneSimulator(scene) if drone else Simulator(scene)
    state, work, params, diag = sim.buffers
    winch = sim.winch.arrays
    drones = sim.drone if drone else None
    hook = sim.hook if drone and scene.pivot.drone.offset_hook else None
    if batch is None:
        return RigArrays(state, work, params, diag, winch, drones, hook, sim)
    rows = (batch,)
    stacked_winch = stacked(winch, rows)
    stacked_winch.coef[...] = winch.coef
    return RigArrays(stacked(state, rows), stacked(work, rows), repeated(params, batch), stacked(diag, rows),
                     stacked_winch, None if drones is None else repeated(drones, batch),
                     None if hook is None else repeated(hook, batch), sim)
