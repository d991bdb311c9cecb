"""The team's LQG for the hook observation (the hard preset): the team's LQR
(agents/baselines/team/lqr.py) acting on a steady-state Kalman filter's estimate of its reduced
state from every agent's hook observation, as agents/baselines/lqg.py does for one string.

The measurement model is the observation of the lifted state, differentiated by central
differences at the formation (y = y0 + C z: the pivots' position errors and velocities, their
strings' pull, the load's target relative to them, the neighbours); its noise is the sensor
noise's (TEAM_UNIT_NOISE x sensor_noise, with a floor); the process noise is the actions' (a
spread of ``ACTION_SPREAD`` on each) through B plus a small floor on every state. The filter
predicts with the action applied over the last step (with a latency, the queue's oldest) and
starts from the team at rest in formation where its pivots measure their errors, corrected by the
first observation.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from agents.baselines.team.lqr import TeamLQR, lift, probe, reduced_layout, reference_feedforward, relative_to_reference
from esp_gym.team.core import TeamCore
from esp_gym.team.spaces import TEAM_UNIT_NOISE

#: The process noise's spread of each action [action units] and its floor on every state.
ACTION_SPREAD = 0.3
STATE_FLOOR = 1e-6
#: The measurement noise's floors [per field unit]: TEAM_UNIT_NOISE's, and for the hook tension
#: what the linear model does not hold: the strings' axial waves ring at +-1-2 N on a settled load.
NOISE_FLOORS = {"hook_tension": 1.0}


def measurement_model(core: TeamCore, step: float = 1e-5):
    """``(y0, C)``: the centralised observation of ``core``'s mode (without noise) at the lifted
    formation, and its derivative in the reduced state (central differences)."""
    observed = probe(core, core.observation)

    def observe(z):
        lift(observed, z)
        return observed.observations(noisy=False).astype(np.float64).ravel()

    n = reduced_layout(core.size).size
    y0 = observe(np.zeros(n))
    C = np.column_stack([(observe(step * e) - observe(-step * e)) / (2 * step) for e in np.eye(n)])
    return y0, C


class TeamLQG:
    """The team's LQR on a Kalman filter's estimate (module docstring). Build with
    :meth:`design`; ``act(obs, core)`` takes the centralised observation."""

    def __init__(self, lqr: TeamLQR, y0: np.ndarray, C: np.ndarray, gain: np.ndarray):
        self.lqr, self.y0, self.C, self.gain = lqr, y0, C, gain
        n = C.shape[1]
        self.A, self.B = lqr.A[:n, :n], (lqr.A[:n, n:n + 3 * lqr.size] if lqr.latency else lqr.B[:n])
        self.reset()

    @classmethod
    def design(cls, core: TeamCore, latency: int = 0) -> "TeamLQG":
        """For ``core``'s team (its mode, noise and targets), the LQR designed with ``latency``."""
        lqr = TeamLQR.design(core, latency=latency)
        y0, C = measurement_model(core)
        n = C.shape[1]
        A = lqr.A[:n, :n]
        B = lqr.A[:n, n:n + 3 * core.size] if latency else lqr.B[:n]
        std = np.concatenate([np.full(s.stop - s.start, max(core.sensor_noise * TEAM_UNIT_NOISE[name],
                                                              NOISE_FLOORS.get(name, TEAM_UNIT_NOISE[name])))
                              for name, s in core.layout.structure().items()])
        V = np.diag(np.tile(std, core.size) ** 2)
        W = ACTION_SPREAD ** 2 * B @ B.T + STATE_FLOOR * np.eye(n)
        P = scipy.linalg.solve_discrete_are(A.T, C.T, W, V)
        gain = P @ C.T @ np.linalg.inv(C @ P @ C.T + V)
        return cls(lqr, y0, C, gain)

    def reset(self) -> None:
        """A new episode: no estimate yet, the action queue empty."""
        self.estimate = None
        self.applied = np.zeros(3 * self.lqr.size)
        self.feedforward = np.zeros(3 * self.lqr.size)
        self.lqr.reset()

    def record_applied(self, action: np.ndarray) -> None:
        """The action given at the last :meth:`act` was ``action`` (a residual's sum), not the
        design's: the filter predicts with what was applied."""
        action = np.asarray(action, dtype=np.float64).ravel() - self.feedforward
        if self.lqr.latency:
            self.lqr.queue[-1] = action
        else:
            self.applied = action

    def act(self, obs: np.ndarray, core: TeamCore) -> np.ndarray:
        """The centralised action (3K,) for the centralised observation: the LQR's on the estimate,
        plus a moving reference's feedforward; the filter works relative to the reference (as
        :meth:`TeamLQR.act`) and predicts with the actions less their feedforward."""
        obs = relative_to_reference(obs, core, core.layout)
        self.feedforward = reference_feedforward(core, self.lqr.latency)
        y = obs - self.y0
        if self.estimate is None:  # an episode starts at rest in formation: the load where the pivots say
            prior = np.zeros(self.C.shape[1])
            Z = reduced_layout(self.lqr.size)
            errors = np.asarray(obs, dtype=np.float64).reshape(self.lqr.size, -1)[:, core.layout["pivot_position_error"]]
            prior[Z["pivot_error"]] = errors.ravel()
            prior[Z["load_error"]] = errors.mean(axis=0)
            self.estimate = prior + self.gain @ (y - self.C @ prior)
        else:
            predicted = self.A @ self.estimate + self.B @ self.applied
            self.estimate = predicted + self.gain @ (y - self.C @ predicted)
        queue = list(self.lqr.queue)
        action = np.clip(-(self.lqr.K @ np.concatenate([self.estimate] + queue)) + self.feedforward, -1.0, 1.0)
        # the model's input over the next step: the queue's oldest (or this one without a latency)
        self.applied = queue[0] if queue else action - self.feedforward
        if self.lqr.latency:
            self.lqr.queue = queue[1:] + [action - self.feedforward]
        return action
