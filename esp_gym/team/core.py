"""A team's episode (docs/team.md): K point pivots (crane hooks, or drones flown as points) or K
drones carry one load on elastic tension-only strings.

:class:`TeamCore` is the episode: the team's physics (:class:`~esp_gym.team.TeamSimulator`), the
task's targets, the wind, the sensor noise and the latency; each agent's observation, the team's
reward with its per-agent terms and the episode's end are one compiled call on the state's read-out
(esp_gym/kernels/team/task.py, :meth:`TeamCore.evaluate`). Two faces share it:
:class:`~esp_gym.team.env.ElasticStringTeamEnv`, the centralised Gymnasium env ``ElasticStringTeam-v0`` (the agents' actions and observations concatenated), and
:class:`~esp_gym.team.parallel.ElasticStringTeamParallelEnv`, PettingZoo's ParallelEnv.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from typing import Optional

import numpy as np

from .. import TEAM_ENV_ID
from ..kernels.env.arrays import TARGET
from ..kernels.env.track_curve import reference_at
from ..kernels.status import TERM_NONE
from ..kernels.team.task import team_task
from ..pendulum.observe import standard_deviation
from ..pendulum.options import check_substeps, team_options
from ..pendulum.tasks import track_reference
from ..pendulum.wind import wind_options
from ..physics.arrays import copy_into
from ..physics.rig import find_rig
from .control import TeamControl
from .fleet import check_lift
from .gusts import TeamWind
from .randomize import TeamRandomizer
from .scene import TEAM_SAFETY, TeamScene, given_team, team_substeps
from .simulator import TeamSimulator
from .spaces import ACTUATIONS, TEAM_UNIT_NOISE, DroneDrive, action_size, agent_layout
from .stepping import TeamStepping
from .tasks import TEAM_PRESETS, get_team_task, hanging_rise, task_arrays

#: A point team's drone inputs to the compiled task: none.
NO_DRONES = (np.zeros((0, 3, 3)), np.zeros((0, 3)))


class TargetArray:
    """A :class:`TeamCore` target: one of its ``_targets`` arrays, which an assignment writes in
    place (the compiled task's arrays of every observation mode share them)."""

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, core, owner=None):
        return self if core is None else core._targets[self.name]

    def __set__(self, core, value):
        core._targets[self.name][...] = value


class TeamCore(TeamStepping):
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
    steps, 0-50) and ``wind`` (esp_gym/pendulum/wind.py's options: the mean wind, gusts and pushes, on the
    load), ``safety`` (h's margin under every string's stability bound, default
    :data:`~.scene.TEAM_SAFETY`). ``winch``: each point pivot's string reels on its winch, its
    reel speed (x its ``winch.max_speed``) each agent's last action and its unstretched length in
    its observation (None: as the task needs, True for ``lift``). Checked as the single env's options are
    (esp_gym/pendulum/options.py ``TeamOptions``; ``others``: its options a team lacks, refused with why)."""

    #: False: every control step in Python (TeamSimulator.step, then the compiled task), the
    #: compiled step's reference (tests/test_team_control.py)
    compiled_steps = True

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
        self.winch = self._check_winch(o.winch)
        #: the team's rig (esp_gym/physics/rig.py): its compiled entry points, or none (stepped in Python)
        self.rig = self._find_rig(scene)
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
        #: the targets, one set of arrays shared by the compiled task's arrays of every observation
        #: mode (``_tasks``, made by :meth:`evaluate`) and moved in place
        self._targets = dict(load_target=np.zeros(3), target_velocity=np.zeros(3),
                             pivot_targets=np.zeros((self.size, 3)))
        self._tasks = {}
        self._noise = np.concatenate([np.full(s.stop - s.start, self.sensor_noise * TEAM_UNIT_NOISE[name])
                                      for name, s in self.layout.structure().items()])
        self._use_scene(scene)
        self.nominal_scene = self.scene
        self.np_random = np.random.default_rng()
        self.steps, self.failure = 0, None
        self.last_action = np.zeros((self.size, self.action_size))
        self.load_target = self.load_position()
        self.pivot_targets = self.pivot_positions()
        #: for a moving task, the target's reference (a TARGET vector of
        #: esp_gym/kernels/env/arrays.py; None for a fixed target)
        self.reference = None
        self.reel_targets = None  #: a lift's target lengths (K,) [m], None for the other tasks
        self.load_force = np.zeros(3)
        #: the FrameRenderer of :meth:`frame` (made by its first call)
        self.renderer = None

    def _check_winch(self, winch: Optional[bool]) -> bool:
        """Whether the strings reel (the ``winch`` option; None: as the task needs), checked
        against the task (against the pivots by the rig table, in :meth:`__init__`)."""
        reels = self.task.needs_winch if winch is None else winch
        if self.task.needs_winch and not reels:
            raise ValueError(f"winch: task {self.task.name!r} reels the strings and needs winch=True")
        return reels

    def _find_rig(self, scene: TeamScene):
        """The rig of ``scene``'s pivots and string scheme with :attr:`winch`, from the rig table (which
        refuses any other combination)."""
        reeling_drones = "winch: a team's drones do not reel yet (docs/physics.md, \"What a team does not do yet\")"
        return find_rig("drone" if self.drones else "point", scene.scene.solver.string, self.winch, False, team=True,
                        settings=reeling_drones if self.drones and self.winch else "")

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
        #: whether the drones' actions become motor commands in Python (thrust_torque, motors)
        self.drive_held = self.drones and self.actuation != "thrust_rates"
        self._start = self.sim.state
        self._start_load = self.load_position()  # the load's centre of mass at the start [m]
        self._formation = self.pivot_positions() - self.load_position()
        #: the compiled control step (esp_gym/team/control.py); None where the team steps in Python
        #: (a rig without entry points: winches; or :attr:`compiled_steps` off)
        self.control = None
        if self.compiled_steps and self.rig.compiled:
            self.control = TeamControl(self.rig, self.sim, self._task_arrays(self.observation), self.action_size,
                                       substeps, self.force_scale, self.hover, self._formation, self.drive,
                                       self.wind is not None)

    #: The targets (spatial), arrays written in place (the compiled task reads them): the load's
    #: (3,) [m], each pivot's (K, 3) [m] and the load target's velocity (3,) [m/s].
    load_target = TargetArray()
    pivot_targets = TargetArray()
    target_velocity = TargetArray()

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
        out = self.sim.observed()
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
        load = self._start_load.copy()
        velocity = rng.uniform(-task.max_speed, task.max_speed, 3)
        rates = rng.uniform(-task.max_spin, task.max_spin, 3)
        R = self._start.lead.R
        rho_c = np.asarray(self.scene.scene.body.rho_c, dtype=float)
        self.sim.set_state(self.sim.initial_state(velocity=velocity - R @ np.cross(rates, rho_c), rates=rates),
                           check=False)
        if task.moving:
            reference = track_reference(rng, 0.0)
            reference[TARGET["centre"]] += load - reference[TARGET["load"]]
            self.reference = self._use_reference(reference)
            self._follow_reference(0.0)
        elif task.needs_winch:  # every string to the same share of its length; the pivots stay
            self.reference = self._use_reference(None)
            self.reel_targets = self.sim.winches.lengths * (1.0 + rng.uniform(*task.reel_range))
            rise = hanging_rise(self.kinematics(), self.scene.attachments(), self.reel_targets)
            self.load_target = load + np.array([0.0, 0.0, rise])
            self.pivot_targets = self.pivot_positions()
        else:
            self.reference = self._use_reference(None)
            self.load_target = load + rng.uniform(-1.0, 1.0, 3) * np.asarray(task.target_box)
            self.pivot_targets = self.load_target + self._formation
        self.steps = 0
        self.last_action = np.zeros((self.size, self.action_size))
        self._queue = deque([np.zeros((self.size, self.action_size))] * self.action_latency)
        self.load_force = np.zeros(3)
        if self.wind is not None:
            info.update(self._wind.reset(rng))
        info.update(load_target=self.load_target.copy(), pivot_targets=self.pivot_targets.copy())
        return self.observations(), info

    def _use_reference(self, reference):
        """The episode's ``reference`` (a TARGET vector; None: a fixed target) as the compiled
        control step follows it: its own copy, which the step moves."""
        return reference if self.control is None else self.control.use_reference(reference)

    def _follow_reference(self, t: float) -> None:
        """Put the targets at the reference's time ``t`` [s] (a moving task)."""
        reference_at(self.reference, t)
        self.load_target = self.reference[TARGET["load"]].copy()
        self.pivot_targets = self.load_target + self._formation
        self.target_velocity = self.reference[TARGET["velocity"]].copy()

    def observations(self, noisy: bool = True, observation: Optional[str] = None) -> np.ndarray:
        """Every agent's observation (K, n) of the current state, float32 (:func:`agent_layout`; in
        the ``observation`` mode, the env's if None), with the sensor noise drawn from
        ``np_random`` when ``noisy``."""
        return self.noisy(self.evaluate(self.last_action, observation=observation)[0].obs, noisy)

    def noisy(self, clean: np.ndarray, noisy: bool = True) -> np.ndarray:
        """``clean`` observations (K, n) with the sensor noise drawn from ``np_random`` (when
        ``noisy`` and the env has some), as float32."""
        out = clean.copy()
        if noisy and self.sensor_noise > 0.0:
            out += self._noise * self.np_random.standard_normal(out.shape)
        return out.astype(np.float32)

    def evaluate(self, action: np.ndarray, code: int = TERM_NONE, observation: Optional[str] = None):
        """The task on the current state after ``action`` (K, n_a) (kernels/team/task.py, one
        compiled call on the read-out): returns ``(its arrays, valid until the next call: every
        agent's observation without noise in the ``observation`` mode (the env's if None), the
        reward terms, each agent's shares, the pivots' distances; the reward; the smallest distance
        between two pivots [m]; the physics' ``code``, or where it is TERM_NONE the task's
        termination)``."""
        mode = observation or self.observation
        TK = self._task_arrays(mode)
        fleet = self.sim.fleet
        drone_R, rates = (fleet.attitudes(), fleet.body_rates()) if self.drones else NO_DRONES
        reward, smallest, code = team_task(self.sim.read(), drone_R, rates, np.asarray(action, dtype=float), TK, code)
        return TK, reward, smallest, code

    def use_rows(self, sim, task, env) -> None:
        """Step in a batch's rows from now on (esp_gym/team/batch.py): ``sim`` the simulator's live
        structs (:meth:`TeamSimulator.use_structs <esp_gym.team.simulator.TeamSimulator.use_structs>`),
        ``task`` the task's arrays of the env's observation and ``env`` the control step's, the
        current values copied into them; the targets move with the task's."""
        self.sim.use_structs(sim)
        copy_into(self._tasks[self.observation], task)
        self._targets = dict(load_target=task.load_target, target_velocity=task.target_velocity,
                             pivot_targets=task.pivot_targets)
        self._tasks = {mode: task if mode == self.observation else arrays._replace(**self._targets)
                       for mode, arrays in self._tasks.items()}
        self.control.use_rows(task, env)
        if self.reference is not None:
            self.reference = env.reference

    def compiled_task(self):
        """The compiled task's arrays of the env's observation (kernels/team/task.py ``TeamTaskArrays``)."""
        return self._task_arrays(self.observation)

    def _task_arrays(self, mode: str):
        """The compiled task's arrays for the observation ``mode``, made at its first use."""
        if mode not in self._tasks:
            layout = agent_layout(self.size, mode, self.drones, self.winch)
            self._tasks[mode] = task_arrays(self.task, layout, self.size)._replace(**self._targets)
        return self._tasks[mode]

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
        return self.observations(noisy=False, observation="full")
