"""A team environment's control step in one compiled call (esp_gym/kernels/team/env.py): the
Python face that builds its arrays for a :class:`~esp_gym.team.core.TeamCore`'s simulator and
task, and makes the call (docs/team.md, "Speed")."""
from __future__ import annotations

import numpy as np

from ..kernels.jit import bound_entry
from ..physics.arrays import copy_into, team_env_arrays
from ..kernels.team.env import (TD_HOVER_THRUST, TD_MAX_THRUST, TE_ENERGY_SCALE, TE_FORCE_SCALE, TE_HOVER_FORCE,
                                TE_MOVING, TE_RATE_LIMIT, TE_WATCHDOG)


class TeamControl:
    """One team's compiled control step: ``rig`` the team's (esp_gym/physics/rig.py; its entry point
    ``step``), ``sim`` a :class:`~esp_gym.team.simulator.TeamSimulator`
    whose strings keep their scenes' lengths, ``task`` its task's arrays (kernels/team/task.py
    ``TeamTaskArrays``, the env's observation), ``action_size`` the size of each agent's action,
    ``substeps`` physics steps per control step, ``force_scale`` and ``hover`` each point pivot's
    force at action 1 and its hover force [N], ``formation`` (K, 3) each pivot's target from the
    load's [m], ``drive`` a drone team's :class:`~esp_gym.team.spaces.DroneDrive` (None for point
    pivots), ``disturbed`` whether a force on the load is held over each step (the wind)."""

    def __init__(self, rig, sim, task, action_size: int, substeps: int, force_scale: float, hover: float,
                 formation: np.ndarray, drive, disturbed: bool):
        self.rig, self.sim = rig, sim
        fleet = sim.fleet
        K = task.obs.shape[0]
        #: whether the drones' actions set the rate controller's setpoints (``thrust_rates``)
        self.rates = drive is not None and drive.actuation == "thrust_rates"
        #: the env's arrays (kernels/team/env.py ``TeamEnvArrays``)
        self.arrays = E = team_env_arrays(K, 0 if fleet is None else len(fleet), action_size)
        E.params[TE_FORCE_SCALE] = force_scale
        E.params[TE_HOVER_FORCE] = hover
        E.params[TE_WATCHDOG], E.params[TE_ENERGY_SCALE] = sim.watchdog_constants()
        E.formation[...] = formation
        if drive is not None:
            E.params[TE_RATE_LIMIT:TE_RATE_LIMIT + 3] = drive.rate_limit
            E.drive[:, TD_HOVER_THRUST] = drive.hover
            E.drive[:, TD_MAX_THRUST] = drive.max_thrust
        self.substeps, self.disturbed = int(substeps), bool(disturbed)
        self._structs = (sim.compiled(), (tuple(task), tuple(E)))
        self._entry = None  # the step's machine code, bound at the first step (kernels/jit.py bound_entry)

    def use_reference(self, reference) -> np.ndarray:
        """Follow ``reference`` (a TARGET vector, kernels/env/arrays.py; copied), or a fixed target
        (None); returns the array the step moves (the episode's reference), or None."""
        E = self.arrays
        E.params[TE_MOVING] = 0.0 if reference is None else 1.0
        if reference is None:
            return None
        E.reference[...] = reference
        return E.reference

    def hold_load_force(self, load_force) -> None:
        """The force on the load (3,) (spatial) [N] held over the next step (when disturbed)."""
        self.arrays.load_force[...] = load_force

    def step(self, raw: np.ndarray, time: float) -> bool:
        """One control step from the raw actions (K, n_a) (clipped in the call), ``time`` the step's
        end [s] (a moving target's), the load force held (:meth:`hold_load_force`) when disturbed.
        False, with nothing changed, if an action is not finite. The report is in ``arrays.report``,
        the applied action in ``arrays.action``; :meth:`finish` next."""
        if self._entry is None:
            self._entry = self._bind(raw)
        return self._entry(*self._structs, raw, self.substeps, self.disturbed, self.rates, float(time))

    def finish(self) -> None:
        """After a compiled control step (this one's, or a batch's): the simulator counts its steps."""
        self.sim.count_control_step()
        if self.rates:
            self.sim.fleet.rates = True  # as Fleet.command with rates leaves it

    def use_rows(self, task, env) -> None:
        """Step with the task's arrays ``task`` and the env's ``env`` (a batch's row views,
        esp_gym/team/batch.py; the env's current arrays copied into ``env``) and the simulator's
        structs as they now are."""
        copy_into(self.arrays, env)
        self.arrays = env
        self._structs = (self.sim.compiled(), (tuple(task), tuple(env)))

    def _bind(self, raw: np.ndarray):
        """The entry point's machine code for these structs and ``raw``'s type (float64, C-contiguous,
        writeable: esp_gym/pendulum/control.py ``raw_actions`` makes every action so)."""
        if not (raw.dtype == np.float64 and raw.flags.c_contiguous and raw.flags.writeable and raw.ndim == 2):
            raise TypeError("the raw actions must be a writeable, C-contiguous float64 array (K, n_a)")
        return bound_entry(self.rig.entries.step, *self._structs, raw, self.substeps, self.disturbed, self.rates, 0.0)
