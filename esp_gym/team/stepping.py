"""A team's control step (docs/team.md): :class:`TeamStepping` is the stepping half of
:class:`~esp_gym.team.core.TeamCore` (the episode's options, targets and resets are there). A team
without winches steps in one compiled call (esp_gym/team/control.py, alone or in a batch:
esp_gym/team/batch.py); a team with winches, or with ``compiled_steps`` off, through
:meth:`TeamSimulator.step <esp_gym.team.simulator.TeamSimulator.step>` and the compiled task.
"""
from __future__ import annotations

import numpy as np

from ..errors import SimulationError, termination_reason
from ..kernels.status import ENERGY_BALANCE, PHYSICS_FAILURES, TERM_NONE
from ..kernels.team.env import TS_CODE, TS_RESIDUAL, TS_REWARD, TS_SMALLEST, TS_WORK
from ..pendulum.control import raw_actions
from .tasks import AGENT_TERMS, REWARD_TERMS

#: The info keys of the team's reward terms and of each agent's shares, in the kernel's order.
REWARD_KEYS = tuple(f"reward_{name}" for name in REWARD_TERMS)
AGENT_KEYS = tuple(f"agent_{name}" for name in AGENT_TERMS)


class TeamStepping:
    """The control step of a :class:`~esp_gym.team.core.TeamCore` (module docstring)."""

    def step(self, action):
        """Apply each pivot's force (K, 3), or each drone's action (K, 4), in [-1, 1] (clipped;
        after ``action_latency`` steps) over one control period; returns ``(observations, reward,
        terminated, truncated, info)``: the team's reward terms ``info["reward_<term>"]``, each
        agent's own shares ``info["agent_<term>"]`` (K,), as the single env names them. One compiled
        call (:attr:`control`) where the team has no winch."""
        return self.step_raw(raw_actions(action, (self.size, self.action_size),
                                         f"action (one {'drone action' if self.drones else 'pivot force'} per agent)"))

    def step_raw(self, a: np.ndarray):
        """:meth:`step` of actions ``a`` already made raw (esp_gym/pendulum/control.py ``raw_actions``: float64,
        C-contiguous, writeable, (K, n_a))."""
        a = self.applied_action(a)
        if self.control is None:
            return self._step_in_python(a)
        self.prepare_step(a)
        if not self.control.step(a, (self.steps + 1) * self.control_period):
            raise ValueError(f"action must be finite, got {a.tolist()}")
        return self._outcome(self._tasks[self.observation], *self.counted())

    def applied_action(self, a: np.ndarray) -> np.ndarray:
        """The action to apply now for the raw ``a`` (K, n_a): ``a`` itself where the compiled step
        checks and clips it; else checked (ValueError if not finite, before anything is drawn or
        queued), clipped and, with ``action_latency``, the one queued that long ago."""
        if self.control is not None and not (self.action_latency or self.wind is not None or self.drive_held):
            return a
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action must be finite, got {a.tolist()}")
        a = np.clip(a, -1.0, 1.0)
        if self.action_latency:
            self._queue.append(a)
            a = self._queue.popleft()
        return a

    def prepare_step(self, a: np.ndarray) -> None:
        """Before a compiled control step of the applied action ``a``: a drone team's motor commands
        (``thrust_torque``, ``motors``) and the wind's force on the load, drawn for the step."""
        if self.drive_held:  # the motor commands, held over the step
            self.sim.fleet.command(**self.drive(a))
        if self.wind is not None:
            self.load_force = self._wind.force(self.np_random, self.kinematics(), self.scene.scene,
                                               self.control_period)
            self.control.hold_load_force(self.load_force)

    def counted(self) -> tuple:
        """After a compiled control step (alone or in a batch): the simulator's steps counted
        (TeamControl.finish) and the control step's, the action applied kept, a failure's error
        kept; returns ``(reward (0 after a physics failure), the smallest distance between two
        pivots [m], the termination code)``."""
        self.control.finish()
        self.steps += 1
        E = self.control.arrays
        self.last_action = E.action.copy()
        report = E.report.tolist()
        code = int(report[TS_CODE])
        reward = report[TS_REWARD]
        if code in PHYSICS_FAILURES or code == ENERGY_BALANCE:
            self.failure = self.sim.failure(code, report[TS_RESIDUAL], report[TS_WORK])
            reward = 0.0 if code in PHYSICS_FAILURES else reward
        return reward, report[TS_SMALLEST], code

    def _step_in_python(self, a: np.ndarray):
        """:meth:`step` of the clipped, applied action ``a`` through TeamSimulator.step (a team
        with winches, or :attr:`compiled_steps` off), then the compiled task."""
        if self.drones:
            drive = self.drive(a)
        else:
            forces = self.force_scale * a[:, :3]
            forces[:, 2] -= self.hover  # e3 points down: the hover force is -e3
            drive = {"pivot_forces": forces}
        if self.winch:
            drive["reel_speeds"] = self.sim.winches.max_speeds * a[:, -1]
        code = TERM_NONE
        if self.wind is not None:
            self.load_force = self._wind.force(self.np_random, self.kinematics(), self.scene.scene,
                                               self.control_period)
        try:
            self.sim.step(self.substeps, load_force=self.load_force if self.wind is not None else None, **drive)
        except SimulationError as error:  # a failed step, or the energy watchdog's energy_balance
            code, self.failure = error.status, error
        self.steps += 1
        self.last_action = a
        if self.reference is not None:
            self._follow_reference(self.steps * self.control_period)
        task, reward, smallest, code = self.evaluate(a, code)
        if code in PHYSICS_FAILURES:
            reward = 0.0
        return self._outcome(task, reward, smallest, code)

    def _outcome(self, task, reward: float, smallest: float, code: int):
        """A step's ``(observations, reward, terminated, truncated, info)`` from the task's arrays."""
        info = self.task_info(task, smallest)
        info["applied_action"] = self.last_action.copy()
        info["termination"] = code
        if code != TERM_NONE:
            info["termination_reason"] = termination_reason(code)
        return self.noisy(task.obs), reward, code != TERM_NONE, False, info

    def task_info(self, task, smallest: float) -> dict:
        """A step's ``reward_<term>`` (the team's), ``agent_<term>`` (K,) (each agent's share),
        ``min_separation`` [m] and each hook's ``tension`` (K, 3) [N] from :meth:`evaluate`'s arrays
        ``task`` and smallest distance, and the read-out they were taken from."""
        info = dict(zip(REWARD_KEYS, task.terms.tolist()))
        info.update(zip(AGENT_KEYS, task.agent.T.copy()))  # each term's row of one copy
        info["min_separation"] = float(smallest)
        info["tension"] = self.sim.read().tension.copy()
        return info
