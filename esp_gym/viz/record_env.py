"""Recording runs to Rerun: rollouts of ElasticStringPendulum-v0 (the Gymnasium wrapper
:class:`RecordRerun`) and free simulations (:func:`record_simulation`).
"""
from __future__ import annotations

import time as _time
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np

from ..kernels.drone.quadrotor import DRONE_DIAG
from ..kernels.env.arrays import ACTION, TARGET
from ..pendulum.control import ControlStep, read_only
from .recorder import Recorder


class RecordRerun(gym.Wrapper):
    """Records rollouts of ElasticStringPendulum-v0 to a Rerun ``.rrd`` at the control rate.

    Every ``reset`` and every ``step`` adds one sample: the state and its diagnostics, and for
    steps the applied (clipped) action, the reward and its terms (``info["reward_*"]``) and
    the mean Newton iterations per physics step, and for both the hook tension, the wind, the
    drag and the push (``control.sensors``, ``control.disturbance``); each episode's targets
    are logged at its reset (and at every step while they move: ``track``), and so is its body
    (its shape and rho_c, randomised with ``randomize``: :meth:`Recorder.log_body`). Episodes
    follow each other on the ``step`` timeline (one step apart) and ``time`` is ``step`` times
    the control period. Samples are buffered and written every ``flush_every`` samples, after
    ``flush_seconds`` of wall time, when an episode ends (``flush_on_episode_end``), on
    :meth:`close`, at exit and on SIGTERM/SIGINT. A failed write raises
    :class:`~esp_gym.viz.lifecycle.RecordingError` from the next ``step`` (or ``reset``, or
    :meth:`close`) and stops the recording; the file keeps what came before.

    There is no every-physics-step option: the environment advances its physics steps inside
    one compiled call (kernels/env/step.py), so the intermediate states never reach Python;
    recording them would mean re-stepping the physics outside the environment's own kernel.

    The sample is copied by one compiled call (:meth:`Recorder.add_sample`) from the env's
    live arrays, read through its :class:`~esp_gym.pendulum.control.ControlStep` (``env.unwrapped.control``):
    the simulator's state and diagnostics (which the step leaves current), the clipped action,
    the reward terms, the inputs, the sensors, the disturbance and the step report (the same
    numbers as the clipped action, ``info["reward_*"]`` and the control step's sensors and
    disturbance, which the tests check). ``recorder_kwargs`` go to :class:`Recorder`
    (``flush_every``, ``flush_seconds``, ``trail_seconds``, ``strain_scale``, ``force_scale``,
    ``wind_scale``, ``torque_scale``, ...).
    """

    def __init__(self, env: gym.Env, path, *, flush_on_episode_end: bool = False, **recorder_kwargs):
        super().__init__(env)
        control = getattr(env.unwrapped, "control", None)
        if not isinstance(control, ControlStep) or control.num_envs is not None:
            raise TypeError("RecordRerun records ElasticStringPendulum-v0 (an env with one ControlStep, `control`)")
        self.control = control
        setup = control.setup
        self.flush_on_episode_end = bool(flush_on_episode_end)
        drone = None
        #: a drone's action, padded to the point pivot's size (the sample row's action field)
        self._drone_action = np.zeros(ACTION.size) if setup.drone else None
        if setup.drone:
            drone = (setup.actuation, setup.scene.pivot.drone.rotor_positions())
        self.recorder = Recorder(path, setup.scene, env=True, winch=setup.winch, sample_period=setup.control_period,
                                 force_offset=setup.hover, action_scale=(setup.force_limit, setup.torque_limit),
                                 drone=drone, **recorder_kwargs)
        self._live = None  # the simulator's live (StateArrays, DiagWork), from the first reset on
        self._rho = None  # the episode's rho_c (body frame [m]), read-only float64 (one compiled signature)
        self._episode = -1
        self._step = -1  # step index of the last sample

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        rec = self.recorder
        if not rec.closed:
            if rec.buffered and self.flush_on_episode_end:
                rec.flush(wait=True)
            control = self.control
            self._live = (control.sim.buffers.state, control.sim.buffers.diag)
            self._episode += 1
            self._step += 1
            body = control.scene.body  # the episode's (randomised) load
            self._rho = read_only(np.array(body.rho_c, dtype=float))
            rec.start_episode(control.sim)
            rec.log_body(body, self._rho, self._step, self._step * rec.sample_period)
            self._add(stepped=False, reward=float("nan"), target=control.target)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._live is not None and not self.recorder.closed:
            self._step += 1
            moving = self.control.target[TARGET.scalar("rate")] != 0.0  # track: log the moving targets
            self._add(stepped=True, reward=reward, inputs=self.control.inputs,
                      **({"target": self.control.target} if moving else {}))
            if self.flush_on_episode_end and (terminated or truncated):
                self.recorder.flush(wait=True)  # on disk when the episode ends
        return obs, reward, terminated, truncated, info

    def _add(self, **sample) -> None:
        control, rec = self.control, self.recorder
        state, diag = self._live
        action = control.action
        if self._drone_action is not None:  # four entries, in the row's six
            self._drone_action[:action.size] = action
            action = read_only(self._drone_action)
            drone = control.sim.drone
            rec.add_drone(drone.R, drone.diag[DRONE_DIAG["rates"]], drone.speed)
        rec.add_sample(state, diag, report=control.report, step=self._step, time=self._step * rec.sample_period,
                       episode=self._episode, action=action, terms=control.reward_terms,
                       sensors=control.sensors, disturbance=control.disturbance, rho=self._rho,
                       winch=control.sim.winch.vector, **sample)

    def close(self):
        try:
            self.recorder.close()  # RecordingError if the file could not be completed
        finally:
            super().close()


# -- free simulations -----------------------------------------------------------------------------

def default_record_every(h: float, rate: float = 50.0) -> int:
    """Physics steps between samples for ~``rate`` samples per simulated second."""
    return max(1, int(round(1.0 / (rate * h))))


def record_simulation(sim, path, t_final: float, record_every: Optional[int] = None, progress: bool = False,
                      pivot_force=None, body_torque=None, **recorder_kwargs) -> dict:
    """Advance ``sim`` by ``t_final`` seconds (a whole number of steps) with constant inputs
    (as in ``Simulator.step``: pivot force spatial [N], body torque body frame [N m]) and
    record it to ``path``: the current state, then every ``record_every`` physics steps
    (default: ~50 samples per simulated second) and at the end. Returns a summary (samples,
    steps, wall time, largest |E - E0 - W| and |pi3 - pi3_0 - impulse| at the samples). A
    :class:`~esp_gym.physics.simulator.SimulationError` propagates after the recording of the steps before
    it is closed."""
    from tqdm.auto import tqdm

    nsteps = int(round(t_final / sim.h))
    if nsteps < 0 or abs(nsteps * sim.h - t_final) > 1e-9 * max(1.0, abs(t_final)):
        raise ValueError(f"t_final = {t_final} s is not a whole number of steps h = {sim.h} s")
    record_every = default_record_every(sim.h) if record_every is None else int(record_every)
    if record_every < 1:
        raise ValueError(f"record_every must be >= 1, got {record_every}")
    start = _time.perf_counter()
    with Recorder(path, sim.scene, sample_period=record_every * sim.h, **recorder_kwargs) as rec:
        rec.start_episode(sim)
        rec.sample(sim, pivot_force=pivot_force, body_torque=body_torque)
        done = 0
        with tqdm(total=nsteps, disable=not progress, unit="step", unit_scale=True,
                  desc=f"{sim.scene.name} -> {Path(path).name}") as bar:
            while done < nsteps:
                k = min(record_every, nsteps - done)
                sim.step(k, pivot_force=pivot_force, body_torque=body_torque)
                rec.sample(sim, pivot_force=pivot_force, body_torque=body_torque)
                done += k
                bar.update(k)
        samples = rec.samples
        worst = rec.max_abs_residuals
    return {"path": str(path), "scene": sim.scene.name, "steps": nsteps, "record_every": record_every,
            "samples": samples, "wall_time_s": _time.perf_counter() - start,
            "max_abs_energy_balance_residual": float(worst[0]), "max_abs_pi3_balance_residual": float(worst[1])}
