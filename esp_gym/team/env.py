"""A team's environments: K point pivots (crane hooks, or drones flown as points) carry one load on
elastic tension-only strings (docs/team.md).

:class:`TeamCore` is the episode: the team's physics (:class:`~esp_gym.team.TeamSimulator`), the
task's targets, each agent's observation, the team's reward with its per-agent terms, and the
episode's end. Two faces share it: :class:`ElasticStringTeamEnv`, the centralised Gymnasium env
``ElasticStringTeam-v0`` (the agents' actions and observations concatenated), and
:class:`~esp_gym.team.parallel.ElasticStringTeamParallelEnv`, PettingZoo's ParallelEnv.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import gymnasium as gym
import numpy as np

from ..kernels.layout import Layout
from ..model import SimulationError
from ..stepsize import explicit_substeps
from .scene import TeamScene, symmetric_team
from .simulator import TeamSimulator

#: Pivots closer than this are penalised (the reward's separation term) [m].
SEPARATION = 0.4
#: Pivots closer than this have collided: the episode ends [m].
COLLISION = 0.15
#: The time limit of an episode [control steps]: 10 s at the default 20 ms.
MAX_EPISODE_STEPS = 500


@dataclass(frozen=True)
class TeamTask:
    """Reward weights and scales, and the start and target distributions, of a team task.

    Each tracking term is ``weight / (1 + (x/scale)^2)``; the control term is
    ``-w_control mean_k |a_k|^2 / 3``; the separation term ``-w_separation sum over pairs of
    max(0, 1 - d/SEPARATION)^2``. So a step's reward is at most
    w_load_position + w_load_velocity + w_pivot_position + w_tilt + w_spin."""

    name: str
    w_load_position: float = 0.45
    w_load_velocity: float = 0.1
    w_pivot_position: float = 0.2
    w_tilt: float = 0.2
    w_spin: float = 0.05
    w_control: float = 0.1
    w_separation: float = 0.5
    scale_position: float = 0.2  #: [m]
    scale_velocity: float = 0.5  #: [m/s]
    scale_tilt: float = 0.2  #: [rad]
    scale_spin: float = 1.0  #: [rad/s]
    max_speed: float = 0.05  #: the load's initial speed, up to this per axis [m/s]
    max_spin: float = 0.1  #: the load's initial body rates, up to this per axis [rad/s]
    target_box: tuple = (0.0, 0.0, 0.0)  #: the load's target, uniform in +-box about its start [m]
    max_stretch: float = 1.5  #: the episode ends when a string is longer than this times its l
    workspace_radius: float = 4.0  #: the episode ends when the load or a pivot is this far from its target [m]

    @property
    def max_reward(self) -> float:
        return self.w_load_position + self.w_load_velocity + self.w_pivot_position + self.w_tilt + self.w_spin


TEAM_TASKS = {
    # bring a load knocked into motion (up to 0.5 m/s, 1 rad/s) to rest, the pivots held in formation
    "stabilize": TeamTask("stabilize", max_speed=0.5, max_spin=1.0, w_load_position=0.35, w_load_velocity=0.2,
                          w_tilt=0.15, w_spin=0.1),
    # carry a load hanging at rest to a random target, the pivots in formation around it
    "transport": TeamTask("transport", target_box=(1.0, 1.0, 0.5)),
}


def get_team_task(name: str) -> TeamTask:
    if name not in TEAM_TASKS:
        raise ValueError(f"task must be one of {sorted(TEAM_TASKS)}, got {name!r}")
    return TEAM_TASKS[name]


def agent_layout(size: int) -> Layout:
    """One agent's observation (:attr:`TeamCore.observation_structure`): its pivot's position
    error and velocity, its string's hook tension, the load relative to it, the load's error,
    velocity, attitude and rates, and the other pivots relative to it (the next one first)."""
    fields = [("pivot_position_error", 3), ("pivot_velocity", 3), ("hook_tension", 3), ("load_offset", 3),
              ("load_position_error", 3), ("load_velocity", 3), ("load_attitude_6d", 6), ("load_rates", 3)]
    if size > 1:
        fields.append(("neighbours", 3 * (size - 1)))
    return Layout(*fields)


def team_scene(size: int) -> TeamScene:
    """The default team: ``size`` free 1 kg pivots 1.2 m apart across, each holding a 1 m,
    50 g/m, EA = 200 N tension-only string (drone_load's) to a 1 kg box (0.4 x 0.4 x 0.1 m) at
    points 0.15 m from its centre line on its top face, hanging at rest."""
    return symmetric_team(size, length=1.0, mass_per_length=0.05, EA=200.0, elements=8, body_mass=1.0,
                          body_size=(0.4, 0.4, 0.1), pivot_radius=0.6, attachment_radius=0.15,
                          pivot={"kind": "free", "mass": 1.0}, h=2e-4, stretch="static",
                          law="slack", solver={"slack_switch": "plain"})


class TeamCore:
    """A team's episode (module docstring). ``team``: K or a :class:`TeamScene` whose pivots are
    all free; ``task``: a name of :data:`TEAM_TASKS`; ``force_limit``: each pivot's force at
    action 1, as a share of its hover force (its share of the rig's weight) [-]."""

    def __init__(self, team=3, task: str = "transport", control_period: float = 0.02, force_limit: float = 0.6):
        if isinstance(team, TeamScene):
            scene = team
        elif isinstance(team, (int, np.integer)) and not isinstance(team, bool):
            scene = team_scene(int(team))
        else:
            raise ValueError(f"team must be a number of strings (1-6) or a TeamScene, got {team!r}")
        pivots = [scene.scene.pivot] + [s.pivot for s in scene.strings]
        if not all(p.is_free for p in pivots):
            raise ValueError("team: every pivot of a team environment must be free (pivot.kind: free)")
        if not (np.isfinite(control_period) and control_period > 0):
            raise ValueError(f"control_period must be > 0 s, got {control_period}")
        if not (np.isfinite(force_limit) and force_limit > 0):
            raise ValueError(f"force_limit must be > 0, got {force_limit}")
        self.task = get_team_task(task)
        self.size = scene.size
        substeps = max(explicit_substeps(scene.member_scene(k), control_period, 0.5) for k in range(self.size))
        scene = scene.model_copy(update={"scene": scene.scene.model_copy(update={"h": control_period / substeps})})
        self.scene, self.substeps, self.control_period = scene, substeps, control_period
        self.sim = TeamSimulator(scene)
        self.layout = agent_layout(self.size)
        strings = [scene.scene.string] + [s.string for s in scene.strings]
        weight = scene.scene.gravity * (scene.scene.body.mass + sum(p.mass for p in pivots)
                                        + sum(s.length * s.mass_per_length for s in strings))
        #: each pivot's hover force (its share of the weight, up: -e3) [N] and force at action 1 [N]
        self.hover = weight / self.size
        self.force_scale = force_limit * self.hover
        self._start = self.sim.state
        self._formation = self.pivot_positions() - self.load_position()
        self.np_random = np.random.default_rng()
        self.steps = 0
        self.last_action = np.zeros((self.size, 3))
        self.load_target = self.load_position()
        self.pivot_targets = self.pivot_positions()

    # -- the state, as the observation reads it -------------------------------------------------
    def pivot_positions(self) -> np.ndarray:
        st = self.sim.state
        T = self.sim.params
        return np.vstack([st.lead.r[0]] + [st.r[T.start[j]] for j in range(self.size - 1)])

    def load_position(self) -> np.ndarray:
        st = self.sim.state
        return st.lead.r[-1] + st.lead.R @ np.asarray(self.scene.scene.body.rho_c, dtype=float)

    def kinematics(self) -> dict:
        """Positions, velocities and tensions of the current state (spatial frame, SI)."""
        st = self.sim.state
        T = self.sim.params
        v_lead, v_other, Omega = self.sim.velocities()
        R = st.lead.R
        rho_c = np.asarray(self.scene.scene.body.rho_c, dtype=float)
        rows = [0] + [int(T.start[j]) for j in range(self.size - 1)]
        nodes = [st.lead.r] + [st.r[T.start[j]:T.start[j + 1]] for j in range(self.size - 1)]
        strings = [self.scene.scene.string] + [s.string for s in self.scene.strings]
        tension = np.zeros((self.size, 3))
        stretched = np.zeros(self.size)
        for k, (r, string) in enumerate(zip(nodes, strings)):
            x = r[1] - r[0]
            length = np.linalg.norm(x)
            tension[k] = string.kappa * max(length - string.u, 0.0) * x / length
            stretched[k] = np.linalg.norm(np.diff(r, axis=0), axis=1).sum() / string.length
        return dict(
            pivot=np.vstack([st.lead.r[0]] + [st.r[i] for i in rows[1:]]),
            pivot_velocity=np.vstack([v_lead[0]] + [v_other[i] for i in rows[1:]]),
            load=st.lead.r[-1] + R @ rho_c, load_velocity=v_lead[-1] + R @ np.cross(Omega, rho_c),
            R=R, Omega=Omega, tension=tension, stretch=stretched)

    # -- episodes -------------------------------------------------------------------------------
    def reset(self, seed: Optional[int] = None):
        """A new episode; returns ``(observations (K, n), info)``."""
        if seed is not None:
            self.np_random = np.random.default_rng(seed)
        rng, task = self.np_random, self.task
        start = self._start.copy()
        self.sim.set_state(start)
        load = self.load_position()
        velocity = rng.uniform(-task.max_speed, task.max_speed, 3)
        rates = rng.uniform(-task.max_spin, task.max_spin, 3)
        R = start.lead.R
        rho_c = np.asarray(self.scene.scene.body.rho_c, dtype=float)
        attach_velocity = velocity - R @ np.cross(rates, rho_c)
        self.sim.set_state(self.sim.initial_state(velocity=attach_velocity, rates=rates))
        self.load_target = load + rng.uniform(-1.0, 1.0, 3) * np.asarray(task.target_box)
        self.pivot_targets = self.load_target + self._formation
        self.steps = 0
        self.last_action = np.zeros((self.size, 3))
        kin = self.kinematics()
        return self.observations(kin), {"load_target": self.load_target.copy(),
                                        "pivot_targets": self.pivot_targets.copy()}

    def observations(self, kin: dict) -> np.ndarray:
        """Every agent's observation (K, n), float32 (:func:`agent_layout`)."""
        L = self.layout
        out = np.zeros((self.size, L.size))
        R = kin["R"]
        for k in range(self.size):
            o = out[k]
            o[L["pivot_position_error"]] = kin["pivot"][k] - self.pivot_targets[k]
            o[L["pivot_velocity"]] = kin["pivot_velocity"][k]
            o[L["hook_tension"]] = kin["tension"][k]
            o[L["load_offset"]] = kin["load"] - kin["pivot"][k]
            o[L["load_position_error"]] = kin["load"] - self.load_target
            o[L["load_velocity"]] = kin["load_velocity"]
            o[L["load_attitude_6d"]] = R[:, :2].T.ravel()
            o[L["load_rates"]] = kin["Omega"]
            if self.size > 1:
                others = [(k + i) % self.size for i in range(1, self.size)]
                o[L["neighbours"]] = (kin["pivot"][others] - kin["pivot"][k]).ravel()
        return out.astype(np.float32)

    def reward_terms(self, kin: dict, action: np.ndarray) -> dict:
        """The team's reward terms, and each agent's share of the per-agent ones (module
        docstring; docs/team.md)."""
        task = self.task

        def closeness(x, scale):
            return 1.0 / (1.0 + (x / scale) ** 2)

        pivot_errors = np.linalg.norm(kin["pivot"] - self.pivot_targets, axis=1)
        tilt = float(np.arccos(np.clip(kin["R"][2, 2], -1.0, 1.0)))
        distances, pairs = self.separations(kin["pivot"])
        crowding = np.maximum(0.0, 1.0 - distances / SEPARATION) ** 2
        per_agent_crowding = np.zeros(self.size)
        for (i, j), c in zip(pairs, crowding):
            per_agent_crowding[i] += 0.5 * c
            per_agent_crowding[j] += 0.5 * c
        pivot_terms = task.w_pivot_position * closeness(pivot_errors, task.scale_position) / self.size
        control_terms = -task.w_control * np.sum(action ** 2, axis=1) / (3.0 * self.size)
        separation_terms = -task.w_separation * per_agent_crowding
        return dict(
            load_position=task.w_load_position * closeness(np.linalg.norm(kin["load"] - self.load_target),
                                                           task.scale_position),
            load_velocity=task.w_load_velocity * closeness(np.linalg.norm(kin["load_velocity"]), task.scale_velocity),
            tilt=task.w_tilt * closeness(tilt, task.scale_tilt),
            spin=task.w_spin * closeness(np.linalg.norm(kin["Omega"]), task.scale_spin),
            pivot_position=pivot_terms, control=control_terms, separation=separation_terms)

    def separations(self, pivots: np.ndarray):
        """The distances between every pair of pivots [m] and the pairs (i < j)."""
        pairs = [(i, j) for i in range(self.size) for j in range(i + 1, self.size)]
        distances = np.array([np.linalg.norm(pivots[i] - pivots[j]) for i, j in pairs])
        return distances, pairs

    def step(self, action):
        """Apply each pivot's force (K, 3) in [-1, 1] (clipped) over one control period; returns
        ``(observations, reward, terminated, truncated, info)`` with the per-agent terms in
        ``info["agents"]``."""
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (self.size, 3):
            raise ValueError(f"action must have shape ({self.size}, 3) (one pivot force per agent), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError("action must be finite")
        a = np.clip(a, -1.0, 1.0)
        forces = self.force_scale * a
        forces[:, 2] -= self.hover  # e3 points down: the hover force is -e3
        reason = ""
        try:
            self.sim.step(self.substeps, pivot_forces=forces)
        except SimulationError as error:
            reason = f"simulation_failed: {error}"
        self.steps += 1
        self.last_action = a
        kin = self.kinematics()
        terms = self.reward_terms(kin, a)
        reward = float(sum(np.sum(v) for v in terms.values()))
        distances, _ = self.separations(kin["pivot"])
        task = self.task
        if not reason:
            if distances.size and distances.min() < COLLISION:
                reason = "collision"
            elif kin["stretch"].max() > task.max_stretch:
                reason = "overstretched"
            elif (np.linalg.norm(kin["load"] - self.load_target) > task.workspace_radius or
                  np.linalg.norm(kin["pivot"] - self.pivot_targets, axis=1).max() > task.workspace_radius):
                reason = "left_workspace"
        terminated = bool(reason)
        if reason.startswith("simulation_failed"):
            reward = 0.0
        agents = [{name: float(terms[name][k]) for name in ("pivot_position", "control", "separation")}
                  for k in range(self.size)]
        info = {"reward_terms": {k: float(np.sum(v)) for k, v in terms.items()}, "agents": agents,
                "min_separation": float(distances.min()) if distances.size else np.inf,
                "tension": kin["tension"].copy()}
        if terminated:
            info["termination_reason"] = reason
        return self.observations(kin), reward, terminated, False, info


class ElasticStringTeamEnv(gym.Env):
    """``ElasticStringTeam-v0``: a team of K point pivots carrying one load, for single-agent
    learners (docs/team.md). Actions ``Box(-1, 1, (3K,))``: each pivot's force (spatial) on top of
    its hover force, ``force_limit`` of it at 1. Observations ``Box(-inf, inf, (K n,))``: the
    agents' observations (:func:`agent_layout`) one after the other. The reward is the team's;
    ``info["agents"]`` holds each agent's terms. Arguments as :class:`TeamCore`'s."""

    metadata = {"render_modes": []}

    def __init__(self, team=3, task: str = "transport", control_period: float = 0.02, force_limit: float = 0.6,
                 render_mode: Optional[str] = None):
        if render_mode is not None:
            raise ValueError(f"render_mode: a team env does not render yet, got {render_mode!r}")
        self.core = TeamCore(team, task, control_period, force_limit)
        K, n = self.core.size, self.core.layout.size
        self.action_space = gym.spaces.Box(-1.0, 1.0, (3 * K,), np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (K * n,), np.float32)
        #: name -> slice of the observation: agent k's fields are ``pivot_k/<field>``
        self.observation_structure = {f"pivot_{k}/{name}": slice(k * n + s.start, k * n + s.stop)
                                      for k in range(K) for name, s in self.core.layout.structure().items()}

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        self.core.np_random = self.np_random
        obs, info = self.core.reset()
        return obs.ravel(), info

    def step(self, action):
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        obs, reward, terminated, truncated, info = self.core.step(a.reshape(self.core.size, 3))
        return obs.ravel(), reward, terminated, truncated, info
