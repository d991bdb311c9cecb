"""A drone team's classical controller: a load-level LQR allocates each pivot's force, and every
drone makes that force its thrust vector through the geometric inner loops
(agents/baselines/geometric.py ``inner_action``).

The load-level law is designed on the drone team's *point twin*: the same strings, load and pivot
masses with every drone a free point pushed by a force (:func:`point_twin`). A drone hooked at its
centre of mass translates exactly as that point under its thrust -f R_q e3. But its thrust
follows the force asked for only as fast as the inner loops turn it: the twin's own LQR
(agents/baselines/team_lqr.py), which assumes the force at once, is unstable behind a lag of
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

import numpy as np
import scipy.linalg

from agents.baselines.geometric import InnerLoops, inner_action
from agents.baselines.team_lqr import linearize, reduced_from_observation, reference_feedforward, \
    relative_to_reference, reward_weights
from esp_gym.team.env import TeamCore
from esp_gym.team.scene import TeamScene
from esp_gym.team.spaces import agent_layout

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


def point_fields(size: int) -> np.ndarray:
    """The indices of a drone agent's ``full`` observation that make a point pivot's (the LQR's)."""
    drone, point = agent_layout(size, "full", drones=True), agent_layout(size, "full")
    return np.concatenate([np.arange(drone[name].start, drone[name].stop) for name in point.structure()])


def lagged_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, decay: np.ndarray) -> np.ndarray:
    """The LQR gain on [z; u] for z+ = A z + B u, u+ = D u + (I - D) v with ``decay`` D's diagonal
    (the input v, the applied u lagging behind it), Q on z and R on v."""
    n, m = B.shape
    Aa = np.block([[A, B], [np.zeros((m, n)), np.diag(decay)]])
    Ba = np.vstack([np.zeros((n, m)), np.diag(1.0 - decay)])
    Qa = np.zeros((n + m, n + m))
    Qa[:n, :n] = Q
    P = scipy.linalg.solve_discrete_are(Aa, Ba, Qa, R)
    return np.linalg.solve(R + Ba.T @ P @ Ba, Ba.T @ P @ Aa)


@dataclass
class TeamCascade:
    """The cascade (module docstring): ``gain`` (3K, n + 3K) on the reduced state and the applied
    forces (both in the twin's action units), ``twin`` the point twin's core (its force scale and
    hover), ``inner`` the drones' inner-loop gains, ``max_tilt`` [rad] the largest tilt a force
    asks of a drone (its horizontal part cut to tan(max_tilt) x its vertical one)."""

    gain: np.ndarray
    twin: TeamCore
    inner: InnerLoops = INNER
    max_tilt: float = MAX_TILT

    @classmethod
    def design(cls, core: TeamCore, inner: InnerLoops = INNER, max_tilt: float = MAX_TILT,
               lag=LAG) -> "TeamCascade":
        """The cascade for ``core``'s drone team (its scene, task, control period, force limit and
        targets); ``lag`` (horizontal, vertical) [s]."""
        if not core.drones:
            raise ValueError("core: the cascade flies a drone team (TeamCore(..., actuation='thrust_rates'))")
        if core.action_latency:
            raise ValueError("core.action_latency: the cascade is designed without a latency yet")
        twin = TeamCore(point_twin(core.scene), core.task.name, control_period=core.control_period,
                        force_limit=core.force_limit)
        twin.load_target, twin.pivot_targets = core.load_target.copy(), core.pivot_targets.copy()
        A, B = linearize(twin)
        Q, R = reward_weights(twin)
        decay = np.tile(np.exp(-core.control_period / np.array([lag[0], lag[0], lag[1]])), core.size)
        return cls(lagged_gain(A, B, Q, R, decay), twin, inner, max_tilt)

    def reset(self) -> None:
        """A new episode (the cascade keeps no state between steps)."""

    def forces(self, obs: np.ndarray, core: TeamCore) -> np.ndarray:
        """Each pivot's force (K, 3) [N] the load-level law asks for, hover included, from the drone
        team's centralised ``full`` observation and its drones' thrust vectors now."""
        K = core.size
        point = np.asarray(obs, dtype=np.float64).reshape(K, -1)[:, point_fields(K)]
        point = relative_to_reference(point.ravel(), core, agent_layout(K))
        kin = core.kinematics()
        thrust = -kin["drone_attitudes"][:, :, 2] * kin["drone_thrust"][:, None]
        thrust[:, 2] += self.twin.hover
        applied = (thrust / self.twin.force_scale).ravel()
        feedforward = reference_feedforward(core)
        action = np.clip(-(self.gain @ np.concatenate([reduced_from_observation(point, core), applied - feedforward]))
                         + feedforward, -1.0, 1.0).reshape(K, 3)
        forces = self.twin.force_scale * action
        forces[:, 2] -= self.twin.hover
        vertical = np.maximum(-forces[:, 2], 0.0)
        horizontal = np.linalg.norm(forces[:, :2], axis=1)
        forces[:, :2] *= np.minimum(1.0, np.tan(self.max_tilt) * vertical / np.maximum(horizontal, 1e-12))[:, None]
        return forces

    def act(self, obs: np.ndarray, core: TeamCore) -> np.ndarray:
        """The drone team's action (4K,) for its centralised ``full`` observation."""
        kin = core.kinematics()
        forces = self.forces(obs, core)
        drive = core.drive
        return np.concatenate([
            inner_action(forces[k], kin["drone_attitudes"][k], kin["drone_rates"][k], core.actuation,
                         core.sim.fleet.drone_params[k], drive.hover[k], (drive.rate_limit, drive.torque_limit[k]),
                         self.inner) for k in range(core.size)])
