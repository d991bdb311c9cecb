"""A team's episode (docs/team.md): K point pivots (crane hooks, or drones flown as points) or K
drones carry one load on elastic tension-only strings.

:class:`TeamCore` is the episode: the team's physics (:class:`~esp_gym.team.TeamSimulator`), the
task's targets, each agent's observation, the team's reward with its per-agent terms, and the
episode's end. Two faces share it: :class:`~esp_gym.team.env.ElasticStringTeamEnv`, the centralised
Gymnasium env ``ElasticStringTeam-v0`` (the agents' actions and observations concatenated), and
:class:`~esp_gym.team.parallel.ElasticStringTeamParallelEnv`, PettingZoo's ParallelEnv.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import Optional

import numpy as np

from .. import TEAM_ENV_ID
from ..control import raw_actions
from ..errors import SimulationError, termination_reason
from ..kernels.status import PHYSICS_FAILURES, TERM_COLLISION, TERM_DRONE_FLIPPED, TERM_NONE, TERM_OVERSTRETCH, \
    TERM_WORKSPACE
from ..kernels.env_arrays import TARGET
from ..kernels.reference import reference_at
from ..kernels.tolerance import tolerance
from ..observe import standard_deviation
from ..options import check_substeps, team_options
from ..tasks import track_reference
from ..wind import wind_options
from .fleet import check_lift
from .gusts import TeamWind
from .randomize import TeamRandomizer
from .scene import TEAM_SAFETY, TeamScene, given_team, team_substeps
from .simulator import TeamSimulator
from .spaces import ACTUATIONS, TEAM_UNIT_NOISE, DroneDrive, action_size, agent_layout
from .tasks import AGENT_TERMS, COLLISION, FLIP_COSINE, REWARD_TERMS, SEPARATION, TEAM_PRESETS, get_team_task, \
    hanging_rise


class TeamCore:
    """A team's episode (module docstring). ``team``: K or a :class:`TeamScene` whose pivots are
    all free points or all drones; ``task``: a name of :data:`~esp_gym.team.tasks.TEAM_TASKS`;
    ``actuation``: ``force`` (point pivots, the default) or a drone's (esp_gym/team/spaces.py
    :data:`ACTUATIONS`; ``team`` = K then flies :func:`~esp_gym.team.scene.quadrotor` s; a drone
    team's default ``thrust_rates``); ``force_limit``: each point pivot's force at
    action 1, as a share of its hover force (its share of the rig's weight) [-]; ``preset``:
    ``"hard"`` (:data:`~.tasks.TEAM_PRESETS`) sets the options left None: ``randomize`` (True or name ->
    (low, high), as the single env's: each episode draws its team, esp_gym/team/randomize.py;
    ``team`` a number then), ``observation`` (``"full"`` or ``"hook"``), ``sensor_noise`` (a
    level, times :data:`TEAM_UNIT_NOISE`), ``action_latency`` (control
    steps, 0-50) and ``wind`` (esp_gym/wind.py's options: the mean wind, gusts and pushes, on the
    load), ``safety`` (h's margin under every string's stability bound, default
    :data:`~.scene.TEAM_SAFETY`). ``winch``: each point pivot's string reels on its winch, its
    reel speed (x its ``winch.max_speed``) each agent's last action and its unstretched length in
    its observation (None: as the task needs, True for ``lift``). Checked as the single env's options are
    (esp_gym/options.py ``TeamOptions``; ``others``: its options a team lacks, refused with why)."""

    def __init__(self, team=3, task: str = "transport", control_period: float = 0.02, force_limit: float = 0.6,
                 preset: Optional[str] = None, randomize=None, observation: Optional[str] = None,
                 sensor_noise: Optional[float] = None, action_latency: Optional[int] = None, wind=None,
                 actuation: Optional[str] = None, winch: Optional[bool] = None, **others):
        given = {name: value for name, value in dict(randomize=randomize, observation=observation,
                                                     sensor_noise=sensor_noise, action_latency=action_latency,
                                                     wind=wind).items() if value is not None}
        o = team_options(control_period=control_period, force_limit=force_limit, preset=preset, actuation=actuation,
                         winch=winch, **given, **others)
        if o.preset is not None:  # the value given, else the preset's, else the default
            o = o.model_copy(update={name: v for name, v in TEAM_PRESETS[o.preset].items() if name not in given})
        scene = given_team(team, o.actuation not in (None, "force"), o.randomize is not False)
        #: whether the pivots are drones, and how the agents drive them
        self.drones = scene.scene.pivot.is_drone
        self.actuation = o.actuation or ("thrust_rates" if self.drones else "force")
        if self.drones == (self.actuation == "force"):
            raise ValueError(f"actuation {self.actuation!r} does not fly the team's "
                             f"{'drones' if self.drones else 'point pivots'} (point pivots take 'force', drones "
                             f"one of {ACTUATIONS[1:]})")
        self.task = get_team_task(task)
        self.winch = self.task.needs_winch if o.winch is None else o.winch
        if self.task.needs_winch and not self.winch:
            raise ValueError(f"winch: task {task!r} reels the strings and needs winch=True")
        if self.winch and self.drones:
            raise ValueError("winch: a team's drones do not reel yet (docs/physics.md, \"What a team does not do yet\")")
        self.action_size = action_size(self.actuation, self.winch)
        if isinstance(o.sensor_noise, Mapping):
            raise ValueError(f"sensor_noise: a team takes one level (times each field's TEAM_UNIT_NOISE) for now, "
                             f"got {o.sensor_noise!r}")
        self.sensor_noise = standard_deviation("sensor_noise", o.sensor_noise)
        self.observation, self.action_latency = o.observation, o.action_latency
        self.wind = wind_options(o.wind)
        self._wind = TeamWind(self.wind) if self.wind is not None else None
        #: each episode's draws (esp_gym/team/randomize.py), or None: the team given
        self.randomizer = None if o.randomize is False else TeamRandomizer(scene.size, self.drones, o.randomize)
        self.size = scene.size
        self.control_period, self.force_limit = o.control_period, o.force_limit
        #: h's margin under every string's stability bound (docs/physics.md on a team's balance)
        self.safety = TEAM_SAFETY if o.safety is None else float(o.safety)
        self._check_extremes(scene)
        self.layout = agent_layout(self.size, self.observation, self.drones, self.winch)
        self._noise = np.concatenate([np.full(s.stop - s.start, self.sensor_noise * TEAM_UNIT_NOISE[name])
                                      for name, s in self.layout.structure().items()])
        self._use_scene(scene)
        self.nominal_scene = self.scene
        self.np_random = np.random.default_rng()
        self.steps, self.failure = 0, None
        self.last_action = np.zeros((self.size, self.action_size))
        self.load_target = self.load_position()
        self.pivot_targets = self.pivot_positions()
        #: the load target's velocity [m/s] and, for a moving task, its reference (a TARGET
        #: vector of esp_gym/kernels/env_arrays.py; None for a fixed target)
        self.target_velocity = np.zeros(3)
        self.reference = None
        self.reel_targets = None  #: a lift's target lengths (K,) [m], None for the other tasks
        self.load_force = np.zeros(3)
        #: the FrameRenderer of :meth:`frame` (made by its first call)
        self.renderer = None

    def _check_extremes(self, scene: TeamScene) -> None:
        """The episodes' stiffest and heaviest teams (``scene``, or the randomize ranges' corners),
        checked before anything is built: their physics steps per control step, and each drone's lift."""
        corner = "" if self.randomizer is None else " at the randomize ranges' {} corner"
        stiffest, heaviest = (scene, scene) if self.randomizer is None else (self.randomizer.stiffest,
                                                                             self.randomizer.heaviest)
        check_substeps(TEAM_ENV_ID, self.control_period, f"h within {self.safety:g} x every string's stability "
                       "bound" + corner.format("stiffest"),
                       team_substeps(stiffest, self.control_period, self.winch, self.safety),
                       "use a shorter control_period, or softer, longer or coarser strings")
        if self.drones:
            check_lift(heaviest, corner.format("heaviest"))

    def _use_scene(self, scene: TeamScene) -> None:
        """Step ``scene`` from its initial state: h the largest within ``safety`` x every string's
        stability bound that divides the control period, the hover forces, the formation."""
        substeps = team_substeps(scene, self.control_period, self.winch, self.safety)
        scene = scene.model_copy(update={"scene": scene.scene.model_copy(update={"h": self.control_period / substeps})})
        self.scene, self.substeps = scene, substeps
        self.sim = TeamSimulator(scene)
        self.sim.watch_every = 1  # the energy watchdog at every control step, as the single env's
        pivots = [scene.scene.pivot] + [s.pivot for s in scene.strings]
        strings = [scene.scene.string] + [s.string for s in scene.strings]
        weight = scene.scene.gravity * (scene.scene.body.mass + sum(p.mass for p in pivots)
                                        + sum(s.length * s.mass_per_length for s in strings))
        #: each point pivot's hover force (its share of the weight, up: -e3) [N] and force at action 1
        #: [N]; a drone team's actions through its DroneDrive
        self.hover = weight / self.size
        self.force_scale = self.force_limit * self.hover
        self.drive = DroneDrive(self.sim.fleet, self.actuation) if self.drones else None
        self._start = self.sim.state
        self._formation = self.pivot_positions() - self.load_position()

    # -- the state, as the observation reads it -------------------------------------------------
    def pivot_positions(self) -> np.ndarray:
        st = self.sim.state
        T = self.sim.params
        return np.vstack([st.lead.r[0]] + [st.r[T.start[j]] for j in range(self.size - 1)])

    def load_position(self) -> np.ndarray:
        st = self.sim.state
        return st.lead.r[-1] + st.lead.R @ np.asarray(self.scene.scene.body.rho_c, dtype=float)

    def kinematics(self) -> dict:
        """Positions, velocities, tensions (drones: attitudes, rates, thrusts) now (spatial, SI)."""
        st = self.sim.state
        T = self.sim.params
        v_lead, v_other, Omega = self.sim.velocities()
        R = st.lead.R
        rho_c = np.asarray(self.scene.scene.body.rho_c, dtype=float)
        rows = [0] + [int(T.start[j]) for j in range(self.size - 1)]
        nodes = [st.lead.r] + [st.r[T.start[j]:T.start[j + 1]] for j in range(self.size - 1)]
        strings = self.sim.winches.strings_at_length()
        tension = np.zeros((self.size, 3))
        stretched = np.zeros(self.size)
        for k, (r, string) in enumerate(zip(nodes, strings)):
            x = r[1] - r[0]
            length = np.linalg.norm(x)
            tension[k] = string.kappa * max(length - string.u, 0.0) * x / length
            stretched[k] = np.linalg.norm(np.diff(r, axis=0), axis=1).sum() / string.length
        out = dict(lengths=st.lengths, pivot=np.vstack([st.lead.r[0]] + [st.r[i] for i in rows[1:]]),
                   pivot_velocity=np.vstack([v_lead[0]] + [v_other[i] for i in rows[1:]]),
                   load=st.lead.r[-1] + R @ rho_c, load_velocity=v_lead[-1] + R @ np.cross(Omega, rho_c),
                   R=R, Omega=Omega, tension=tension, stretch=stretched)
        if self.drones:  # R_q (K, 3, 3), Omega_q (K, 3), the collective thrusts (K,)
            out.update({k: v for k, v in self.sim.fleet.diagnostics().items()
                        if k in ("drone_attitudes", "drone_rates", "drone_thrust")})
        return out

    # -- episodes -------------------------------------------------------------------------------
    def reset(self, seed: Optional[int] = None):
        """A new episode; returns ``(observations (K, n), info)``. Draws, in order: the team
        (``randomize``), the load's velocity and rates, its target, the wind's azimuth (unless
        given) and gust."""
        if seed is not None:
            self.np_random = np.random.default_rng(seed)
        rng, task = self.np_random, self.task
        info = {}
        #: the SimulationError that ended the episode (its step, time and advice), or None
        self.failure = None
        if self.randomizer is not None:
            scene, info["team_draws"] = self.randomizer.draw(rng)
            self._use_scene(scene)
            self.renderer = None  # the team changes with the episode
        self.sim.set_state(self._start.copy())
        load = self.load_position()
        velocity = rng.uniform(-task.max_speed, task.max_speed, 3)
        rates = rng.uniform(-task.max_spin, task.max_spin, 3)
        R = self._start.lead.R
        rho_c = np.asarray(self.scene.scene.body.rho_c, dtype=float)
        self.sim.set_state(self.sim.initial_state(velocity=velocity - R @ np.cross(rates, rho_c), rates=rates))
        if task.moving:
            self.reference = track_reference(rng, 0.0)
            self.reference[TARGET["centre"]] += load - self.reference[TARGET["load"]]
            self._follow_reference(0.0)
        elif task.needs_winch:  # every string to the same share of its length; the pivots stay
            self.reference = None
            self.reel_targets = self.sim.winches.lengths * (1.0 + rng.uniform(*task.reel_range))
            rise = hanging_rise(self.kinematics(), self.scene.attachments(), self.reel_targets)
            self.load_target = load + np.array([0.0, 0.0, rise])
            self.pivot_targets = self.pivot_positions()
        else:
            self.reference = None
            self.load_target = load + rng.uniform(-1.0, 1.0, 3) * np.asarray(task.target_box)
            self.pivot_targets = self.load_target + self._formation
        self.steps = 0
        self.last_action = np.zeros((self.size, self.action_size))
        self._queue = deque([np.zeros((self.size, self.action_size))] * self.action_latency)
        self.load_force = np.zeros(3)
        if self.wind is not None:
            info.update(self._wind.reset(rng))
        kin = self.kinematics()
        info.update(load_target=self.load_target.copy(), pivot_targets=self.pivot_targets.copy())
        return self.observations(kin), info

    def _follow_reference(self, t: float) -> None:
        """Put the targets at the reference's time ``t`` [s] (a moving task)."""
        reference_at(self.reference, t)
        self.load_target = self.reference[TARGET["load"]].copy()
        self.pivot_targets = self.load_target + self._formation
        self.target_velocity = self.reference[TARGET["velocity"]].copy()

    def observations(self, kin: dict, noisy: bool = True) -> np.ndarray:
        """Every agent's observation (K, n), float32 (:func:`agent_layout`), with the sensor noise
        drawn from ``np_random`` when ``noisy``."""
        L = self.layout
        out = np.zeros((self.size, L.size))
        R = kin["R"]
        for k in range(self.size):
            o = out[k]
            o[L["pivot_position_error"]] = kin["pivot"][k] - self.pivot_targets[k]
            o[L["pivot_velocity"]] = kin["pivot_velocity"][k]
            if self.drones:
                o[L["drone_attitude_6d"]] = kin["drone_attitudes"][k][:, :2].T.ravel()
                o[L["drone_rates"]] = kin["drone_rates"][k]
            o[L["hook_tension"]] = kin["tension"][k]
            if self.winch:
                o[L["string_length"]] = kin["lengths"][k]
            if self.observation == "full":
                o[L["load_offset"]] = kin["load"] - kin["pivot"][k]
                o[L["load_position_error"]] = kin["load"] - self.load_target
                o[L["load_velocity"]] = kin["load_velocity"]
                o[L["load_attitude_6d"]] = R[:, :2].T.ravel()
                o[L["load_rates"]] = kin["Omega"]
            else:
                o[L["load_target_offset"]] = self.load_target - kin["pivot"][k]
            if self.size > 1:
                others = [(k + i) % self.size for i in range(1, self.size)]
                o[L["neighbours"]] = (kin["pivot"][others] - kin["pivot"][k]).ravel()
        if noisy and self.sensor_noise > 0.0:
            out += self._noise * self.np_random.standard_normal(out.shape)
        return out.astype(np.float32)

    def frame(self) -> np.ndarray:
        """An ``rgb_array`` frame, uint8 (480, 960, 3) (esp_gym/viz/render.py ``render_team``):
        front and side views, 3 m across, of every string coloured by its elements' strain energy,
        the load, each pivot with its force above hover (the action applied last) and its target,
        and the load's target."""
        from ..viz.render import FrameRenderer

        if self.renderer is None:
            body = self.scene.scene.body
            self.renderer = FrameRenderer(body.shape, body.rho_c, self.scene.scene.string.length, width=960,
                                           height=480, view_center=(0.0, 0.0, 0.8), view_extent=3.0)
        return self.renderer.render_team(self.sim.strings(), self.sim.state.lead.R,
                                          pivot_forces=self.shown_forces(),
                                          target_pivots=self.pivot_targets, target_load=self.load_target)

    def shown_forces(self) -> np.ndarray:
        """Each pivot's force above hover (K, 3) (spatial) [N]: a point pivot's of the action
        applied last, a drone's thrust -f R_q e3 less its hover share's -f_hover e3."""
        if not self.drones:
            return self.force_scale * self.last_action[:, :3]
        d = self.sim.fleet.diagnostics()
        up = -d["drone_attitudes"][:, :, 2] * d["drone_thrust"][:, None]
        up[:, 2] += self.drive.hover
        return up

    def true_observations(self) -> np.ndarray:
        """The ``full`` observation of the current state without noise (K, 27 + 3(K-1), + 9 with
        drones): what a centralised controller with the true state reads (agents/baselines)."""
        mode, layout = self.observation, self.layout
        self.observation, self.layout = "full", agent_layout(self.size, "full", self.drones, self.winch)
        try:
            return self.observations(self.kinematics(), noisy=False)
        finally:
            self.observation, self.layout = mode, layout

    def reward_terms(self, kin: dict, action: np.ndarray) -> dict:
        """The team's reward terms, and each agent's share of the per-agent ones (module
        docstring; docs/team.md)."""
        task = self.task

        closeness = tolerance.py_func  # the single env's shaping (its kernel's formula), on arrays here
        pivot_errors = np.linalg.norm(kin["pivot"] - self.pivot_targets, axis=1)
        tilt = math.acos(min(1.0, max(-1.0, float(kin["R"][2, 2]))))  # the C library's: NumPy's differs by processor
        distances, pairs = self.separations(kin["pivot"])
        crowding = np.maximum(0.0, 1.0 - distances / SEPARATION) ** 2
        per_agent_crowding = np.zeros(self.size)
        for (i, j), c in zip(pairs, crowding):
            per_agent_crowding[i] += 0.5 * c
            per_agent_crowding[j] += 0.5 * c
        pivot_terms = task.w_pivot_position * closeness(pivot_errors, task.scale_position) / self.size
        control_terms = -task.w_control * np.sum(action ** 2, axis=1) / (action.shape[1] * self.size)
        separation_terms = -task.w_separation * per_agent_crowding
        return dict(
            load_position=task.w_load_position * closeness(np.linalg.norm(kin["load"] - self.load_target),
                                                           task.scale_position),
            load_velocity=task.w_load_velocity * closeness(np.linalg.norm(kin["load_velocity"] - self.target_velocity),
                                                           task.scale_velocity),
            tilt=task.w_tilt * closeness(tilt, task.scale_tilt),
            spin=task.w_spin * closeness(np.linalg.norm(kin["Omega"]), task.scale_spin),
            pivot_position=pivot_terms, control=control_terms, separation=separation_terms)

    def separations(self, pivots: np.ndarray):
        """The distances between every pair of pivots [m] and the pairs (i < j)."""
        pairs = [(i, j) for i in range(self.size) for j in range(i + 1, self.size)]
        distances = np.array([np.linalg.norm(pivots[i] - pivots[j]) for i, j in pairs])
        return distances, pairs

    def step(self, action):
        """Apply each pivot's force (K, 3), or each drone's action (K, 4), in [-1, 1] (clipped;
        after ``action_latency`` steps) over one control period; returns ``(observations, reward,
        terminated, truncated, info)``: the team's reward terms ``info["reward_<term>"]``, each
        agent's own shares ``info["agent_<term>"]`` (K,), as the single env names them."""
        a = raw_actions(action, (self.size, self.action_size),
                        f"action (one {'drone action' if self.drones else 'pivot force'} per agent)")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action must be finite, got {a.tolist()}")
        a = np.clip(a, -1.0, 1.0)
        if self.action_latency:
            self._queue.append(a)
            a = self._queue.popleft()
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
        kin = self.kinematics()
        terms = self.reward_terms(kin, a)
        reward = float(sum(np.sum(v) for v in terms.values()))
        distances, _ = self.separations(kin["pivot"])
        task = self.task
        if code == TERM_NONE:
            if distances.size and distances.min() < COLLISION:
                code = TERM_COLLISION
            elif self.drones and np.any(kin["drone_attitudes"][:, 2, 2] < FLIP_COSINE):
                code = TERM_DRONE_FLIPPED
            elif kin["stretch"].max() > task.max_stretch:
                code = TERM_OVERSTRETCH
            elif (np.linalg.norm(kin["load"] - self.load_target) > task.workspace_radius or
                  np.linalg.norm(kin["pivot"] - self.pivot_targets, axis=1).max() > task.workspace_radius):
                code = TERM_WORKSPACE
        terminated = code != TERM_NONE
        if code in PHYSICS_FAILURES:
            reward = 0.0
        info = {**{f"reward_{name}": float(np.sum(terms[name])) for name in REWARD_TERMS},
                **{f"agent_{name}": np.asarray(terms[name], dtype=float).copy() for name in AGENT_TERMS},
                "min_separation": float(distances.min()) if distances.size else np.inf,
                "tension": kin["tension"].copy(), "applied_action": a.copy(), "termination": code}
        if terminated:
            info["termination_reason"] = termination_reason(code)
        return self.observations(kin), reward, terminated, False, info
