"""The team's centralised LQR: one gain on the whole team's reduced state, from the linearisation of
the team environment's own control step (esp_gym/team/core.py) about the hanging formation, as
agents/baselines/lqr.py does for one string.

Reduced state z (:func:`reduced_layout`, spatial frame, relative to the targets): every pivot's
position error and velocity, the load's (centre of mass) position error and velocity, its attitude
as a rotation vector (the hanging attitude is R = I) and its spatial angular velocity R Omega. A
reduced state is lifted to a full one with each string straight from its pivot to its attachment
point and its velocities interpolated (``TeamSimulator.lifted_state``). The control step is
differentiated by central differences; the cost is the reward's local quadratic expansion
(w / (1 + (x/s)^2) = w - (w/s^2) x^2 + ...), with small weights on what the reward leaves free
(the pivots' velocities, the load's yaw); the gains are the discrete algebraic Riccati equation's,
on the normalised action.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.spatial.transform import Rotation

from esp_gym.layouts import Layout
from esp_gym.pendulum.tasks import reference_acceleration
from esp_gym.team.core import TeamCore
from esp_gym.team.spaces import agent_layout

#: Weight on what the reward does not see (pivot velocities, the load's yaw) [per unit^2].
SMALL = 1e-3


def reduced_layout(size: int) -> Layout:
    return Layout(("pivot_error", 3 * size), ("pivot_velocity", 3 * size), ("load_error", 3), ("load_velocity", 3),
                  ("attitude", 3), ("rates", 3))


def full_layout(obs: np.ndarray, core: TeamCore) -> Layout:
    """The agents' ``full`` layout of a centralised observation of ``core``'s team: its own (with its
    drones' fields and its strings' lengths), or its point twin's (the drones' cascade,
    agents/baselines/team/cascade.py, hands the LQR a point pivots' observation)."""
    for drones in (core.drones, False):
        layout = agent_layout(core.size, "full", drones, core.winch)
        if layout.size * core.size == np.size(obs):
            return layout
    raise ValueError(f"obs has {np.size(obs)} entries: no full observation of a team of {core.size}")


def reduced_from_observation(obs: np.ndarray, core: TeamCore) -> np.ndarray:
    """z from the centralised ``full`` observation (the agents' observations one after the other)."""
    K, L = core.size, full_layout(obs, core)
    o = np.asarray(obs, dtype=np.float64).reshape(K, L.size)
    Z = reduced_layout(K)
    z = np.empty(Z.size)
    z[Z["pivot_error"]] = o[:, L["pivot_position_error"]].ravel()
    z[Z["pivot_velocity"]] = o[:, L["pivot_velocity"]].ravel()
    z[Z["load_error"]] = o[0, L["load_position_error"]]
    z[Z["load_velocity"]] = o[0, L["load_velocity"]]
    first, second = o[0, L["load_attitude_6d"]].reshape(2, 3)
    R = np.stack((first, second, np.cross(first, second)), axis=1)
    z[Z["attitude"]] = Rotation.from_matrix(R).as_rotvec()
    z[Z["rates"]] = R @ o[0, L["load_rates"]]
    return z


def relative_to_reference(obs: np.ndarray, core: TeamCore, layout: Layout) -> np.ndarray:
    """The centralised observation ``obs`` (agents' ``layout`` one after the other) with the
    targets' velocity taken from every velocity it holds: the state relative to a moving
    reference (``track``), where the linearisation about the formation at rest holds."""
    if core.reference is None:  # a fixed target: nothing moves
        return np.asarray(obs, dtype=np.float64).ravel()
    o = np.array(obs, dtype=np.float64).reshape(core.size, layout.size)
    for name in ("pivot_velocity", "load_velocity"):
        if name in layout.structure():
            o[:, layout[name]] -= core.target_velocity
    return o.ravel()


def reference_feedforward(core: TeamCore, delay: int = 0) -> np.ndarray:
    """The action (3K,) that accelerates the whole team with a moving reference over the control
    step that an action given now acts on (``delay`` steps later): each pivot's share of the rig's
    mass times the reference's acceleration at the step's middle, over its force at action 1
    (force_limit x its share of the weight), so a_ref / (force_limit g) whatever the masses.
    Zero for a fixed target."""
    if core.reference is None:
        return np.zeros(3 * core.size)
    t = (core.steps + delay + 0.5) * core.control_period
    accel = reference_acceleration(core.reference, t) / (core.force_limit * core.scene.scene.gravity)
    return np.tile(accel, core.size)


def probe(core: TeamCore, observation: str = "full") -> TeamCore:
    """A core of ``core``'s team, control period, force limit and targets, in the ``observation``
    mode, noiseless: where a design lifts reduced states (:func:`lift`) and steps or observes them."""
    out = TeamCore(core.scene, core.task.name, control_period=core.control_period, force_limit=core.force_limit,
                   observation=observation, winch=core.winch)
    out.load_target, out.pivot_targets = core.load_target.copy(), core.pivot_targets.copy()
    return out


def lift(core: TeamCore, z: np.ndarray) -> None:
    """Set ``core``'s team to the reduced state ``z`` (module docstring), relative to its targets."""
    K = core.size
    Z = reduced_layout(K)
    R = Rotation.from_rotvec(z[Z["attitude"]]).as_matrix()
    sim = core.sim
    sim.set_state(sim.lifted_state(core.pivot_targets + z[Z["pivot_error"]].reshape(K, 3),
                                   z[Z["pivot_velocity"]].reshape(K, 3), core.load_target + z[Z["load_error"]],
                                   z[Z["load_velocity"]], R, R.T @ z[Z["rates"]]))


def reduced_state(core: TeamCore) -> np.ndarray:
    """``core``'s team's reduced state now, relative to its targets."""
    kin = core.kinematics()
    Z = reduced_layout(core.size)
    z = np.empty(Z.size)
    z[Z["pivot_error"]] = (kin["pivot"] - core.pivot_targets).ravel()
    z[Z["pivot_velocity"]] = kin["pivot_velocity"].ravel()
    z[Z["load_error"]] = kin["load"] - core.load_target
    z[Z["load_velocity"]] = kin["load_velocity"]
    z[Z["attitude"]] = Rotation.from_matrix(kin["R"]).as_rotvec()
    z[Z["rates"]] = kin["R"] @ kin["Omega"]
    return z


def linearize(core: TeamCore, z_step: float = 1e-5, a_step: float = 1e-4):
    """``(A, B)``: central differences of the control step z -> z' about the formation at rest
    (hover forces), with ``core``'s targets."""
    lifted = probe(core)
    K = core.size

    def step(z, action):
        lift(lifted, z)
        forces = lifted.force_scale * action.reshape(K, 3)
        forces[:, 2] -= lifted.hover
        lifted.sim.step(lifted.substeps, pivot_forces=forces)
        return reduced_state(lifted)

    n = reduced_layout(K).size
    zero_z, zero_a = np.zeros(n), np.zeros(3 * K)
    A = np.column_stack([(step(zero_z + z_step * e, zero_a) - step(zero_z - z_step * e, zero_a)) / (2 * z_step)
                         for e in np.eye(n)])
    B = np.column_stack([(step(zero_z, a_step * e) - step(zero_z, -a_step * e)) / (2 * a_step)
                         for e in np.eye(3 * K)])
    return A, B


def reward_weights(core: TeamCore):
    """``(Q, R)``: the reward's quadratic expansion (module docstring)."""
    task, K = core.task, core.size
    Z = reduced_layout(K)
    q = np.full(Z.size, SMALL)
    q[Z["pivot_error"]] = task.w_pivot_position / (K * task.scale_position ** 2)
    q[Z["load_error"]] = task.w_load_position / task.scale_position ** 2
    q[Z["load_velocity"]] = task.w_load_velocity / task.scale_velocity ** 2
    q[Z.start("attitude"):Z.start("attitude") + 2] = task.w_tilt / task.scale_tilt ** 2
    q[Z["rates"]] = task.w_spin / task.scale_spin ** 2
    return np.diag(q), np.eye(3 * K) * task.w_control / (3.0 * K)


@dataclass
class TeamLQR:
    """The team's centralised LQR (module docstring): action -K [z; the actions still queued],
    clipped to the box. With an action latency of d control steps the model carries the d
    actions given but not yet applied (z+ = A z + B u_{k-d}), and the law keeps them."""

    K: np.ndarray  #: (3K, 6K + 12 + 3K d) gains, action units
    A: np.ndarray
    B: np.ndarray
    size: int
    latency: int = 0

    @classmethod
    def design(cls, core: TeamCore, control_weight: float = 1.0, latency: int = 0) -> "TeamLQR":
        A, B = linearize(core)
        Q, R = reward_weights(core)
        R = control_weight * R
        n, m = B.shape
        if latency:  # the queue of given actions joins the state; the newest enters it
            Aa = np.zeros((n + m * latency, n + m * latency))
            Aa[:n, :n] = A
            Aa[:n, n:n + m] = B  # the oldest queued action is applied now
            for i in range(latency - 1):  # the queue moves up
                Aa[n + m * i:n + m * (i + 1), n + m * (i + 1):n + m * (i + 2)] = np.eye(m)
            Ba = np.zeros((n + m * latency, m))
            Ba[n + m * (latency - 1):] = np.eye(m)
            Qa = np.zeros_like(Aa)
            Qa[:n, :n] = Q
            A, B, Q = Aa, Ba, Qa
        P = scipy.linalg.solve_discrete_are(A, B, Q, R)
        K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        design = cls(K, A, B, core.size, int(latency))
        design.reset()
        return design

    def reset(self) -> None:
        """Empty the queue of actions given and not yet applied (an episode's start)."""
        self.queue = [np.zeros(3 * self.size) for _ in range(self.latency)]
        self.feedforward = np.zeros(3 * self.size)

    def closed_loop_radius(self) -> float:
        """Spectral radius of A - B K (< 1: the linear closed loop is stable)."""
        return float(np.max(np.abs(np.linalg.eigvals(self.A - self.B @ self.K))))

    def record_applied(self, action: np.ndarray) -> None:
        """The action given at the last :meth:`act` was ``action`` (a residual's sum), not the design's."""
        if self.latency:
            self.queue[-1] = np.asarray(action, dtype=np.float64).ravel() - self.feedforward

    def act(self, obs: np.ndarray, core: TeamCore) -> np.ndarray:
        """The centralised action (3K,) for the centralised ``full`` observation: -K [z; queue]
        plus the moving reference's :func:`reference_feedforward`, z relative to the reference
        (:func:`relative_to_reference`). The queue holds the actions less their feedforward (the
        model's input: the error dynamics)."""
        obs = relative_to_reference(obs, core, full_layout(obs, core))
        self.feedforward = reference_feedforward(core, self.latency)
        state = np.concatenate([reduced_from_observation(obs, core)] + self.queue)
        action = np.clip(-(self.K @ state) + self.feedforward, -1.0, 1.0)
        if self.latency:
            self.queue = self.queue[1:] + [action - self.feedforward]
        return action
