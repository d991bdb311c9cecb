"""A drone team's classical controller: a load-level LQR allocates each pivot's force, and every
drone makes that force its thrust vector through the geometric inner loops
(agents/baselines/geometric.py ``inner_action``).

The load-level law is designed on the drone team's *point twin*: the same strings, load and pivot
masses with every drone a free point pushed by a force (:func:`point_twin`). A drone hooked at its
centre of mass translates exactly as that point under its thrust -f R_q e3. But its thrust
follows the force asked for only as fast as the inner loops turn it: the twin's own LQR
(agents/baselines/team/lqr.py), which assumes the force at once, is unstable behind a lag of
30 ms already (closed-loop spectral radius 1.28 at 30 ms, 1.21 at 100 ms, for three drones on
``stabilize``). So the outer loop is an LQR on the twin's linearisation with each force reaching
its pivot through a first-order lag (time constants :data:`LAG`: the tilt's for the horizontal
axes, the rotors' for the vertical), and the lagged forces are the drones' thrust vectors now,
measured. The inner loops turn each drone until its thrust points along the force asked for
(b3_d = -u_d / |u_d|, heading nearest e1) and set the collective thrust to the force's component
along its body axis now.
"""
from __future__ import annotations

from dataclasses import dataclass

import math
import numpy as np
import scipy.linalg

from agents.baselines.geometric import InnerLoops, drone_attitude, inner_action
from agents.baselines.team.lqg import ACTION_SPREAD, NOISE_FLOORS, STATE_FLOOR, measurement_model
from agents.baselines.team.lqr import (linearize, reduced_from_observation, reduced_layout, reference_feedforward,
                                       relative_to_reference, reward_weights)
from esp_gym.team.core import TeamCore
from esp_gym.team.scene import TeamScene
from esp_gym.team.spaces import TEAM_UNIT_NOISE, agent_layout

#: The first-order lags [s] of a drone's thrust vector behind the force asked for: horizontal (its
#: tilt: the attitude loop's 1/k_R and the rate loop's) and vertical (its rotors'); the inner
#: loops' attitude gain, and the largest tilt asked. Chosen on the validation seeds 200000-200007
#: of nominal transport with three drones (mean return): lag 0.2 s 214, 0.3 s 324, 0.4 s 341 at
#: k_R = 8 and a tilt of 0.5 rad; k_R = 10 and 14 flip drones; k_R = 6 405, with a tilt of 0.35
#: rad 431, 0.3 rad 434, 0.25 rad 435; k_R = 4 424.
LAG = (0.4, 0.03)
INNER = InnerLoops(k_attitude=6.0)
MAX_TILT = 0.3


def point_twin(team: TeamScene) -> TeamScene:
    """``team`` with every drone a free point of the drone's mass at its place (module docstring)."""
    def pointed(pivot: dict) -> dict:
        return {**pivot, "kind": "free", "drone": None}

    data = team.model_dump()
    data["scene"]["pivot"] = pointed(data["scene"]["pivot"])
    for s in data["strings"]:
        s["pivot"] = pointed(s["pivot"])
    return TeamScene.model_validate(data)


def point_fields(size: int, observation: str = "full") -> np.ndarray:
    """The indices of a drone agent's observation (``observation`` mode) that make a point pivot's."""
    drone, point = agent_layout(size, observation, drones=True), agent_layout(size, observation)
    return np.concatenate([np.arange(drone[name].start, drone[name].stop) for name in point.structure()])


def lagged_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, decay: np.ndarray,
                latency: int = 0) -> np.ndarray:
    """The LQR gain on [z; u; q_1 .. q_d] for z+ = A z + B u, u+ = D u + (I - D) w with ``decay``
    D's diagonal (the applied u lagging behind the command w that acts now), Q on z and R on the
    command v given now; with a ``latency`` of d steps w = q_1 is the oldest queued command
    (q_i+ = q_{i+1}, q_d+ = v), without one w = v."""
    n, m = B.shape
    size = n + m * (1 + latency)
    Aa = np.zeros((size, size))
    Aa[:n, :n] = A
    Aa[:n, n:n + m] = B
    Aa[n:n + m, n:n + m] = np.diag(decay)
    Ba = np.zeros((size, m))
    if latency:
        Aa[n:n + m, n + m:n + 2 * m] = np.diag(1.0 - decay)  # the oldest queued command acts now
        for i in range(latency - 1):  # the queue moves up
            Aa[n + m * (1 + i):n + m * (2 + i), n + m * (2 + i):n + m * (3 + i)] = np.eye(m)
        Ba[n + m * latency:] = np.eye(m)
    else:
        Ba[n:n + m] = np.diag(1.0 - decay)
    Qa = np.zeros((size, size))
    Qa[:n, :n] = Q
    P = scipy.linalg.solve_discrete_are(Aa, Ba, Qa, R)
    return np.linalg.solve(R + Ba.T @ P @ Ba, Ba.T @ P @ Aa)


@dataclass
class TeamCascade:
    """The cascade (module docstring): ``gain`` (3K, n + 3K (1 + d)) on the reduced state, the
    applied forces and the d commands queued (all in the twin's action units), ``twin`` the point
    twin's core (its force scale and hover), ``inner`` the drones' inner-loop gains, ``max_tilt``
    [rad] the largest tilt a force asks of a drone (its horizontal part cut to tan(max_tilt) x its
    vertical one), ``latency`` d [control steps]."""

    gain: np.ndarray
    twin: TeamCore
    inner: InnerLoops = INNER
    max_tilt: float = MAX_TILT
    latency: int = 0
    model: tuple = ()  #: the twin's (A, B), for an estimator

    @classmethod
    def design(cls, core: TeamCore, inner: InnerLoops = INNER, max_tilt: float = MAX_TILT,
               lag=LAG) -> "TeamCascade":
        """The cascade for ``core``'s drone team (its scene, task, control period, force limit,
        targets and action latency); ``lag`` (horizontal, vertical) [s]."""
        if not core.drones:
            raise ValueError("core: the cascade flies a drone team (TeamCore(..., actuation='thrust_rates'))")
        twin = TeamCore(point_twin(core.scene), core.task.name, control_period=core.control_period,
                        force_limit=core.force_limit)
        twin.load_target, twin.pivot_targets = core.load_target.copy(), core.pivot_targets.copy()
        A, B = linearize(twin)
        Q, R = reward_weights(twin)
        decay = np.tile([math.exp(-core.control_period / tau) for tau in (lag[0], lag[0], lag[1])], core.size)
        return cls(lagged_gain(A, B, Q, R, decay, core.action_latency), twin, inner, max_tilt, core.action_latency,
                   (A, B))

    def __post_init__(self):
        self.reset()

    def reset(self) -> None:
        """A new episode: no command queued (each less its feedforward)."""
        m = self.gain.shape[0]
        self.queue = [np.zeros(m) for _ in range(self.latency)]

    def applied(self, attitudes: np.ndarray, thrusts: np.ndarray) -> np.ndarray:
        """The drones' thrust vectors -f R_q e3 above the twin's hover (3K,), in its action units,
        from their attitudes (K, 3, 3) and collective thrusts (K,) [N]."""
        u = -attitudes[:, :, 2] * thrusts[:, None]
        u[:, 2] += self.twin.hover
        return (u / self.twin.force_scale).ravel()

    def command(self, z: np.ndarray, applied: np.ndarray, core: TeamCore) -> np.ndarray:
        """Each pivot's force (K, 3) [N] the load-level law asks for, hover included, at the reduced
        state ``z`` (relative to the targets and the reference's velocity) with the ``applied``
        forces (:meth:`applied`); the queue moves on."""
        K = core.size
        feedforward = reference_feedforward(core, self.latency)
        state = np.concatenate([z, applied - feedforward] + self.queue)
        command = np.clip(-(self.gain @ state) + feedforward, -1.0, 1.0)
        if self.latency:
            self.queue = self.queue[1:] + [command - feedforward]
        forces = self.twin.force_scale * command.reshape(K, 3)
        forces[:, 2] -= self.twin.hover
        vertical = np.maximum(-forces[:, 2], 0.0)
        horizontal = np.linalg.norm(forces[:, :2], axis=1)
        forces[:, :2] *= np.minimum(1.0, math.tan(self.max_tilt) * vertical / np.maximum(horizontal, 1e-12))[:, None]
        return forces

    def drive(self, forces: np.ndarray, attitudes: np.ndarray, rates: np.ndarray, core: TeamCore) -> np.ndarray:
        """The drone team's action (4K,) making each drone's thrust vector its ``forces`` row, from
        its attitude (K, 3, 3) and body rates (K, 3) [rad/s]."""
        drive = core.drive
        return np.concatenate([
            inner_action(forces[k], attitudes[k], rates[k], core.actuation, core.sim.fleet.drone_params[k],
                         drive.hover[k], (drive.rate_limit, drive.torque_limit[k]), self.inner)
            for k in range(core.size)])

    def forces(self, obs: np.ndarray, core: TeamCore) -> np.ndarray:
        """:meth:`command` from the drone team's centralised ``full`` observation and its drones'
        thrust vectors now (the true state)."""
        K = core.size
        point = np.asarray(obs, dtype=np.float64).reshape(K, -1)[:, point_fields(K)]
        point = relative_to_reference(point.ravel(), core, agent_layout(K))
        kin = core.kinematics()
        return self.command(reduced_from_observation(point, core), self.applied(kin["drone_attitudes"],
                                                                                kin["drone_thrust"]), core)

    def record_applied(self, action: np.ndarray) -> None:
        """The action given at the last :meth:`act` was ``action`` (a residual's sum): nothing to
        keep, the law measures the thrusts it makes (its queue keeps the forces it asked for)."""

    def act(self, obs: np.ndarray, core: TeamCore) -> np.ndarray:
        """The drone team's action (4K,) for its centralised ``full`` observation."""
        kin = core.kinematics()
        return self.drive(self.forces(obs, core), kin["drone_attitudes"], kin["drone_rates"], core)


class TeamCascadeLQG:
    """The cascade on what the drones measure (the hook observation): the load-level law of
    :class:`TeamCascade` on a steady-state Kalman filter's estimate of the reduced state, as
    agents/baselines/team/lqg.py's for point pivots (its measurement model of the point twin's
    hook observation, its noises), predicting with the drones' thrust vectors; those are the
    observed attitudes (noisy) times the collective thrust of the action that acts now (the
    controller's own, ``latency`` steps old), and the inner loops read the observed attitudes and
    rates. Build with :meth:`design`."""

    def __init__(self, law: TeamCascade, y0: np.ndarray, C: np.ndarray, gain: np.ndarray):
        self.law, self.y0, self.C, self.gain = law, y0, C, gain
        self.A, self.B = law.model
        self.reset()

    @classmethod
    def design(cls, core: TeamCore) -> "TeamCascadeLQG":
        """For ``core``'s drone team (its observation mode, noise, latency and targets)."""
        law = TeamCascade.design(core)
        measured = TeamCore(law.twin.scene, core.task.name, control_period=core.control_period,
                            force_limit=core.force_limit, observation=core.observation,
                            sensor_noise=core.sensor_noise)
        measured.load_target, measured.pivot_targets = core.load_target.copy(), core.pivot_targets.copy()
        y0, C = measurement_model(measured)
        std = np.concatenate([np.full(s.stop - s.start, max(core.sensor_noise * TEAM_UNIT_NOISE[name],
                                                              NOISE_FLOORS.get(name, TEAM_UNIT_NOISE[name])))
                              for name, s in measured.layout.structure().items()])
        A, B = law.model
        W = ACTION_SPREAD ** 2 * B @ B.T + STATE_FLOOR * np.eye(A.shape[0])
        P = scipy.linalg.solve_discrete_are(A.T, C.T, W, np.diag(np.tile(std, core.size) ** 2))
        return cls(law, y0, C, P @ C.T @ np.linalg.inv(C @ P @ C.T + np.diag(np.tile(std, core.size) ** 2)))

    def reset(self) -> None:
        """A new episode: no estimate; every drone's thrust commands (the last ``latency`` + 1) its hover."""
        self.estimate = None
        self.last_applied = None
        self.thrusts = None
        self.law.reset()

    def given_thrusts(self, action: np.ndarray, core: TeamCore) -> np.ndarray:
        """Each drone's collective thrust (K,) [N] that the drone team's ``action`` (4K,) asks for."""
        a = np.asarray(action, dtype=np.float64).reshape(core.size, 4)
        hover = core.drive.hover
        if core.actuation == "motors":
            return 0.25 * hover * np.clip(1.0 + a, 0.0, None).sum(axis=1)
        return np.clip(hover * (1.0 + a[:, 0]), 0.0, None)

    def record_applied(self, action: np.ndarray) -> None:
        """The action given at the last :meth:`act` was ``action`` (a residual's sum): its thrusts
        are what the filter predicts with once they act."""
        self.thrusts[-1] = self.given_thrusts(action, self._core)

    def act(self, obs: np.ndarray, core: TeamCore) -> np.ndarray:
        """The drone team's action (4K,) for its centralised observation (hook or full)."""
        self._core = core
        K, L = core.size, core.layout
        agents = np.asarray(obs, dtype=np.float64).reshape(K, -1)
        if self.thrusts is None:
            self.thrusts = [core.drive.hover.copy() for _ in range(self.law.latency + 1)]
        attitudes = np.stack([drone_attitude(agents[k], L) for k in range(K)])
        rates = agents[:, L["drone_rates"]]
        applied = self.law.applied(attitudes, self.thrusts[0])
        y = relative_to_reference(agents[:, point_fields(K, core.observation)].ravel(), core,
                                  agent_layout(K, core.observation)) - self.y0
        if self.estimate is None:  # an episode starts at rest in formation: the load where the pivots say
            prior = np.zeros(self.C.shape[1])
            Z = reduced_layout(K)
            errors = agents[:, L["pivot_position_error"]]
            prior[Z["pivot_error"]] = errors.ravel()
            prior[Z["load_error"]] = errors.mean(axis=0)
        else:
            prior = self.A @ self.estimate + self.B @ (self.last_applied - reference_feedforward(core, -1))
        self.estimate = prior + self.gain @ (y - self.C @ prior)
        self.last_applied = applied
        action = self.law.drive(self.law.command(self.estimate, applied, core), attitudes, rates, core)
        self.thrusts = self.thrusts[1:] + [self.given_thrusts(action, core)]
        return action
