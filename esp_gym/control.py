"""The control step of ElasticStringPendulum-v0: the one Python face of the compiled step that the
single environment, the batched environments and the recording wrapper share.

A :class:`ControlStep` owns the arrays of one environment (or, with ``num_envs``, of a batch:
every array gains a leading axis) and the compiled calls on them (kernels/task.py):

* :meth:`ControlStep.start_episode` draws an episode (its physics when randomised, its state
  and targets) and :meth:`ControlStep.reset` puts it in and computes the observation;
* :meth:`ControlStep.step` takes a raw action (queued behind ``action_latency`` others),
  checks, clips and maps it to inputs, advances the episode's physics steps and fills the
  report: observation, sensors, reward terms, clipped action, inputs, and
  :data:`~esp_gym.kernels.layout.REPORT` (status, steps, Newton iterations, termination code).

Everything is readable through named, read-only views (``observation``, ``sensors``,
``reward_terms``, ``action``, ``inputs``, ``target``, ``report``, ``scene_params``) laid out in
kernels/layout.py; the observation a mode returns is esp_gym/observe.py's.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Optional, Union

import numpy as np
from gymnasium import spaces

from .kernels.layout import (ACTION, ACTION_PARAMS, ACTION_SIZE, INPUTS, OBSERVATION, R_TERMINATION, REPORT, REWARD,
                             REWARD_TERMS, SCENE_PARAMS, SENSORS, TARGET, LGVIParams)
from .kernels.string import state_forces
from .kernels.task import (actions_finite, env_reset_observe, env_step, env_step_batch, env_step_batch_implicit,
                           env_step_implicit)
from .model import Simulator
from .options import MAX_SUBSTEPS, check_count, env_options
from .observe import Observer
from .randomize import Randomizer, nominal_values
from .state import State, build_params, check_memory
from .params import Scene, load_scene, override_scene, scene_from_dict
from .stepsize import scheme_substeps
from .tasks import Task, get_task, sample_episode

#: info keys of the reward terms, in REWARD_TERMS order
INFO_REWARD_KEYS = tuple("reward_" + name for name in REWARD_TERMS)


def total_weight(scene: Scene) -> float:
    """The weight of pivot, string and load [N]: the hover force's size."""
    return scene.gravity * (scene.body.mass + (scene.pivot.mass or 0.0)
                            + scene.string.length * scene.string.mass_per_length)


def action_params(hover: np.ndarray, force_limit: float, torque_limit: float) -> np.ndarray:
    """The compiled action path's constants (:data:`~esp_gym.kernels.layout.ACTION_PARAMS`):
    box bounds [-1, 1], hover force, force and torque limits."""
    ap = np.zeros(ACTION_PARAMS.size)
    ap[ACTION_PARAMS["low"]] = -1.0
    ap[ACTION_PARAMS["high"]] = 1.0
    ap[ACTION_PARAMS["hover_force"]] = hover
    ap[ACTION_PARAMS["force_limit"]] = force_limit
    ap[ACTION_PARAMS["torque_limit"]] = torque_limit
    return ap


@dataclass(frozen=True)
class Episode:
    """The run-time physics of one episode: its scene's values (SCENE_PARAMS order), the scene
    with its step, the stepper's constants, physics steps per control step, the task's and the
    action path's constants (the hover force holds this episode's weight up)."""

    values: np.ndarray
    scene: Scene
    params: LGVIParams
    substeps: int
    task_params: np.ndarray
    action_params: np.ndarray


@dataclass(frozen=True)
class EnvSetup:
    """Everything the single and the batched environments share, resolved and validated."""

    scene: Scene  #: the nominal scene (randomised episodes draw around it)
    task: Task
    task_params: np.ndarray
    control_period: float  #: [s]
    substeps: int  #: physics steps per control step (of the nominal scene)
    hover: np.ndarray  #: feed-forward pivot force holding the nominal system up [N]
    force_limit: float  #: pivot force per axis at |action| = 1, added to the hover force [N]
    torque_limit: float  #: body torque per axis at |action| = 1 [N m]
    safety: float = 0.5  #: margin under the stability bound of each episode's automatic h
    fixed_h: Optional[float] = None  #: the user's h (every episode), or None: each episode's own
    randomizer: Optional[Randomizer] = None  #: the per-episode ranges, or None: the nominal scene
    observer: Observer = Observer()  #: the observation mode and its sensor noise
    action_latency: int = 0  #: control steps between an action and its application

    @property
    def observation_structure(self) -> dict:
        """Name -> slice of the observation vector of this setup's mode."""
        return self.observer.layout.structure()

    @property
    def observation_space(self) -> spaces.Box:
        return spaces.Box(-np.inf, np.inf, (self.observer.layout.size,), np.float32)

    @property
    def action_space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (ACTION_SIZE,), np.float32)

    @cached_property
    def action_params(self) -> np.ndarray:
        """The nominal scene's action constants (:func:`action_params`)."""
        return action_params(self.hover, self.force_limit, self.torque_limit)

    @cached_property
    def nominal_episode(self) -> Episode:
        return Episode(np.array([nominal_values(self.scene)[k] for k in SCENE_PARAMS.names]), self.scene,
                       build_params(self.scene), self.substeps, self.task_params, self.action_params)

    def draw_episode(self, rng: np.random.Generator) -> Episode:
        """The next episode's physics: the nominal one, or (``randomizer``) one drawn from
        ``rng`` with its own h (the largest dividing the control period under the scheme's bound,
        as for the nominal scene; or ``fixed_h``)."""
        if self.randomizer is None:
            return self.nominal_episode
        values = self.randomizer.draw(rng)
        drawn = self.randomizer.scene(values)
        substeps = self.substeps if self.fixed_h is not None else scheme_substeps(drawn, self.control_period,
                                                                                  self.safety)
        scene = drawn.model_copy(update={"h": self.control_period / substeps})
        hover = np.array([0.0, 0.0, -total_weight(scene)])
        return Episode(values, scene, build_params(scene), substeps, self.task.params(scene),
                       action_params(hover, self.force_limit, self.torque_limit))


def make_setup(scene: Union[str, Path, Scene] = "drone_load", task: str = "stabilize",
               control_period: float = 0.02, h: Optional[float] = None, safety: float = 0.5,
               force_limit: Optional[float] = None, torque_limit: float = 0.02,
               scene_overrides: Optional[dict] = None, randomize: Union[bool, dict] = False,
               observation: str = "full", sensor_noise: Union[float, dict] = 0.0,
               action_latency: int = 0) -> EnvSetup:
    """Resolve the environment's arguments (see :class:`~esp_gym.env.ElasticStringPendulumEnv`),
    validated by :class:`~esp_gym.options.EnvOptions` (ValueError naming each bad one)."""
    o = env_options(scene=scene, task=task, control_period=control_period, h=h, safety=safety,
                    force_limit=force_limit, torque_limit=torque_limit, scene_overrides=scene_overrides,
                    randomize=randomize, observation=observation, sensor_noise=sensor_noise,
                    action_latency=action_latency)
    control_period, h, safety = o.control_period, o.h, o.safety
    overrides = dict(o.scene_overrides or {})
    base = o.scene if isinstance(o.scene, Scene) else load_scene(o.scene)
    keep_unstable = overrides.get("allow_unstable_h", base.allow_unstable_h)
    # the scene's own h is replaced below: it must not fail the bound of a stiffer override
    overrides["allow_unstable_h"] = True
    # a Scene object takes the same overrides as a file (aliases, dotted paths, merged sections)
    resolved = override_scene(o.scene, overrides) if isinstance(o.scene, Scene) else load_scene(o.scene, **overrides)
    if not resolved.pivot.is_free:
        raise ValueError(f"ElasticStringPendulum-v0 pushes the pivot: scene {resolved.name!r} needs pivot.kind: free")
    randomizer = None if o.randomize is False else Randomizer(resolved, o.randomize)
    # the scene's scheme (explicit unless asked): choose_scheme's cost rule would pick the implicit
    # string for stiff strings, but its accuracy under random actions is not established yet
    # (docs/physics.md, "The environment's choice")
    explicit = resolved.solver.string == "explicit"
    bound_name = f"safety = {safety} x the stability bound" if explicit else "the transverse bound"
    # the stiffest episode (shortest, lightest, stiffest string) needs the most steps
    stiffest = resolved if randomizer is None else randomizer.scene(randomizer.stiffest())
    if h is None:
        wanted, what = scheme_substeps(stiffest, control_period, safety), bound_name
    else:
        wanted, what = control_period / h, f"h = {h} s"
        if randomizer is not None and explicit and not keep_unstable and h > stiffest.string.stability_bound:
            raise ValueError(f"h = {h} s is above the stability bound {stiffest.string.stability_bound:.4g} s of the "
                             "stiffest string of the randomize ranges (shortest, lightest, largest EA): leave h to "
                             "the environment or narrow the ranges")
    if wanted > MAX_SUBSTEPS:
        raise ValueError(f"ElasticStringPendulum-v0: control_period = {control_period} s with {what} needs "
                         f"{wanted:.3g} physics steps per step (at most {MAX_SUBSTEPS:,}): use a larger h or "
                         f"safety, a shorter control_period, or a softer, longer or coarser string")
    if h is None:
        substeps = scheme_substeps(resolved, control_period, safety)
    else:
        substeps = int(round(wanted))
        if substeps < 1 or abs(substeps * h - control_period) > 1e-9 * control_period:
            raise ValueError(f"h = {h} s must divide the control period {control_period} s")
    resolved = scene_from_dict({**resolved.model_dump(), "h": control_period / substeps,
                                "allow_unstable_h": keep_unstable}, source=repr(resolved.name))
    weight = total_weight(resolved)
    force_limit = o.force_limit if o.force_limit is not None else (0.6 * weight if weight > 0 else 1.0)
    t = get_task(o.task)
    return EnvSetup(scene=resolved, task=t, task_params=t.params(resolved), control_period=float(control_period),
                    substeps=substeps, hover=np.array([0.0, 0.0, -weight]), force_limit=float(force_limit),
                    torque_limit=float(o.torque_limit), safety=float(safety), fixed_h=h, randomizer=randomizer,
                    observer=Observer(o.observation, o.sensor_noise), action_latency=o.action_latency)


def raw_actions(actions, shape: tuple, name: str = "action") -> np.ndarray:
    """``actions`` as the compiled step takes them: float64, C-contiguous, writeable (copied
    only if needed, so one compiled signature serves every caller), of ``shape`` (ValueError
    otherwise) and real (TypeError for complex, bool, object and masked arrays, whose imaginary
    part or mask would otherwise be dropped). Finiteness and clipping are the kernel's
    (kernels/task.py ``take_action``)."""
    if isinstance(actions, np.ma.MaskedArray):
        raise TypeError(f"{name} must be a plain array, not a masked array (its mask would be dropped)")
    given = np.asarray(actions)
    if given.dtype.kind not in "iuf":  # bool, complex, object, strings: not an action
        raise TypeError(f"{name} must hold real numbers, got dtype {given.dtype}")
    raw = np.asarray(given, dtype=np.float64)
    if raw.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {raw.shape}")
    if not (raw.flags.c_contiguous and raw.flags.writeable):
        raw = raw.copy()
    return raw


def read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (numba types read-only arrays apart: callers that mix them with
    these views pass read-only arrays too, so one compiled signature serves both)."""
    view = a.view()
    view.flags.writeable = False
    return view


class ControlStep:
    """The compiled control step of one environment, or of ``num_envs`` stacked ones.

    One environment (``num_envs=None``) steps the :class:`~esp_gym.model.Simulator`
    :attr:`sim` in place (its step counter and Newton totals follow). A batch keeps stacked
    copies of a simulator's arrays and steps every active sub-environment in one parallel
    call; both run the same compiled :func:`~esp_gym.kernels.task.env_step_one`, so their
    numbers agree bit for bit.

    Each (sub-)environment carries its episode's run-time physics (:class:`Episode`: the
    stepper's constants, its number of physics steps, the task's and the action path's
    constants), set by :meth:`reset` with an ``episode`` or drawn by :meth:`start_episode`.

    Views (read-only; leading batch axis for a batch; layouts in kernels/layout.py):
    ``observation`` (OBSERVATION), ``reward_terms`` (REWARD), ``action`` (the clipped
    action, ACTION), ``inputs`` (INPUTS: pivot force [N], body torque [N m], spatial torque),
    ``target`` (TARGET [m]), ``report`` (REPORT, int64), ``scene_params`` (SCENE_PARAMS of the
    current episodes).
    """

    def __init__(self, setup: EnvSetup, num_envs: Optional[int] = None):
        self.setup = setup
        self.num_envs = None if num_envs is None else check_count("num_envs", num_envs)
        batch = () if self.num_envs is None else (self.num_envs,)
        check_memory(setup.scene.string.elements, copies=1 + (self.num_envs or 0))
        #: The simulator stepped in place (one environment), or the template of the batch's arrays.
        self.sim = Simulator(setup.scene)
        state, work, params, diag = self.sim.buffers
        nominal = setup.nominal_episode
        if batch:
            def stack(t):
                return type(t)(*(np.zeros(batch + a.shape) for a in t))

            state, work, diag = stack(state), stack(work), stack(diag)
            # every constant per sub-environment (scalars become (num_envs,) arrays of their type)
            params = LGVIParams(*(np.repeat(np.asarray(v)[None], self.num_envs, axis=0) for v in params))
            #: The scene of each sub-environment's episode.
            self.scenes = [setup.scene] * self.num_envs
        self._state, self._diag, self._params = state, diag, params
        self._work = work
        z = np.zeros
        self._inputs = z(batch + (INPUTS.size,))
        self._target = z(batch + (TARGET.size,))
        self._action = z(batch + (ACTION.size,))
        self._obs = z(batch + (OBSERVATION.size,))
        self._terms = z(batch + (REWARD.size,))
        self._report = z(batch + (REPORT.size,), dtype=np.int64)
        self._sensors = z(batch + (SENSORS.size,))
        # actions on their way (oldest first): each step applies the oldest and queues the new one
        self._pending = z(batch + (setup.action_latency, ACTION.size))
        # the episode's run-time physics besides the stepper's constants
        self._substeps = np.full(batch, nominal.substeps, dtype=np.int64)
        self._task_params = np.tile(nominal.task_params, batch + (1,))
        self._action_params = np.tile(nominal.action_params, batch + (1,))
        self._scene_params = np.tile(nominal.values, batch + (1,))
        self._was_reset = z(batch, dtype=bool)  # stepping a state that was never set is an error
        self._ready = False  # all of _was_reset, kept as a bool: step checks it every call
        self._make_views()

    def _make_views(self) -> None:
        # plain tuples: numba's dispatcher types them ~2x faster than namedtuples (kernels/task.py)
        self._kernel_tuples = (tuple(self._state), tuple(self._work), tuple(self._params), tuple(self._diag))
        self.observation = read_only(self._obs)
        self.reward_terms = read_only(self._terms)
        self.action = read_only(self._action)
        self.inputs = read_only(self._inputs)
        self.target = read_only(self._target)
        self.report = read_only(self._report)
        self.sensors = read_only(self._sensors)
        self.scene_params = read_only(self._scene_params)

    # a pickled view would come back as a copy: pickle the arrays, rebuild the views
    _VIEWS = ("_kernel_tuples", "observation", "reward_terms", "action", "inputs", "target", "report", "sensors",
              "scene_params")

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k not in self._VIEWS}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._make_views()

    @property
    def scene(self) -> Scene:
        """The scene of the current episode (one environment)."""
        if self.num_envs is not None:
            raise ValueError("a batch has one scene per sub-environment: see ControlStep.scenes")
        return self.sim.scene

    # -- reset ------------------------------------------------------------------------------------
    def start_episode(self, rng: np.random.Generator, index: Optional[int] = None) -> np.ndarray:
        """Draw the next episode from ``rng`` (its physics when randomised, then its state and
        targets: esp_gym/tasks.py) and :meth:`reset` to it. Returns its SCENE_PARAMS values."""
        episode = self.setup.draw_episode(rng)
        state, target = sample_episode(self.setup.task, episode.scene, rng)
        self.reset(state, target, index, episode)
        return episode.values

    def _use_episode(self, episode: Episode, index: Optional[int]) -> None:
        """Put an episode's run-time physics in (one environment, or sub-environment ``index``)."""
        if self.num_envs is None:
            if episode.scene is not self.sim.scene:
                self.sim.use_scene(episode.scene, episode.params)
                self._params = self.sim.params
                self._make_views()
            self._substeps[...] = episode.substeps
        else:
            for stacked, value in zip(self._params, episode.params):
                stacked[index] = value
            self.scenes[index] = episode.scene
            self._substeps[index] = episode.substeps
        row = () if index is None else index
        self._task_params[row] = episode.task_params
        self._action_params[row] = episode.action_params
        self._scene_params[row] = episode.values

    def reset(self, state: State, target, index: Optional[int] = None, episode: Optional[Episode] = None) -> int:
        """Put ``state`` (balances restarted) and ``target`` (TARGET [m]) in, zero the action
        and compute the observation and reward terms; ``index``: the sub-environment of a batch;
        ``episode``: its run-time physics (default: unchanged). Returns the termination code of
        the new state."""
        if (self.num_envs is None) != (index is None):
            raise ValueError("index is for batches (num_envs given), and a batch needs it")
        if episode is not None:
            self._use_episode(episode, None if index is None else int(index))
        if self.num_envs is None:
            self.sim.set_state(state)
            S, D, P = self._state, self._diag, self._params
            obs, terms, action, tgt, tp = self._obs, self._terms, self._action, self._target, self._task_params
            sensors, pending = self._sensors, self._pending
        else:
            i = int(index)
            S, D = self._row(i)
            P = LGVIParams(*(a[i] if a.ndim > 1 else a[i].item() for a in self._params))
            S.r[...], S.p[...], S.R[...], S.Pi[...] = state.r, state.p, state.R, state.Pi
            for a in (S.rc, S.pc, S.Rc, S.Pic, S.acc, S.accc):
                a[...] = 0.0
            state_forces(S, P)
            obs, terms, action, tgt, tp = self._obs[i], self._terms[i], self._action[i], self._target[i], \
                self._task_params[i]
            sensors, pending = self._sensors[i], self._pending[i]
        tgt[...] = target
        action[...] = 0.0
        pending[...] = 0.0  # a new episode starts with hover commands in flight
        if not self._ready:
            self._was_reset[() if index is None else int(index)] = True
            self._ready = bool(self._was_reset.all())
        return int(env_reset_observe(S, P, D, tgt, tp, action, obs, terms, sensors))

    # -- step -------------------------------------------------------------------------------------
    def step(self, actions, active: Optional[np.ndarray] = None) -> None:
        """One control step. ``actions``: the raw action (ACTION; a batch: (num_envs, ACTION)),
        any float array; clipped to the box in the compiled step. ValueError, with nothing
        changed, if its shape is wrong or an entry is not finite. ``active`` (batch only, bool
        (num_envs,)): the sub-environments to step (default: all); the others are untouched."""
        s, w, p, d = self._kernel_tuples
        if not self._ready:
            never = "" if self.num_envs is None else f" (sub-environments {np.flatnonzero(~self._was_reset).tolist()})"
            raise RuntimeError(f"call reset() before step(){never}")
        latency = self.setup.action_latency
        if self.num_envs is None:
            raw = raw_actions(actions, (ACTION.size,))
            if latency:
                if not actions_finite(raw[None]):
                    raise ValueError(f"action must be finite, got {raw.tolist()}")
                raw = self._delay(raw, self._pending)
            step = env_step_implicit if self.sim.implicit else env_step
            if not step(s, w, p, d, raw, self._action_params, self._inputs, int(self._substeps), self._target,
                        self._task_params, self._action, self._obs, self._terms, self._sensors, self._report):
                raise ValueError(f"action must be finite, got {raw.tolist()}")
            self.sim.count_steps(self._report)
            return
        raw = raw_actions(actions, (self.num_envs, ACTION.size), "actions")
        if not actions_finite(raw):
            raise ValueError("actions must be finite")
        if active is None:
            active = np.ones(self.num_envs, dtype=bool)
        if latency:
            raw = raw.copy()
            for i in np.flatnonzero(active):
                raw[i] = self._delay(raw[i], self._pending[i])
        batch = env_step_batch_implicit if self.sim.implicit else env_step_batch
        batch(s, w, d, p, raw, self._action_params, self._inputs, active, self._substeps, self._target,
              self._task_params, self._action, self._obs, self._terms, self._sensors, self._report)

    @staticmethod
    def _delay(raw: np.ndarray, pending: np.ndarray) -> np.ndarray:
        """Queue ``raw`` behind the ``pending`` actions (oldest first) and return the oldest."""
        applied = pending[0].copy()
        pending[:-1] = pending[1:]
        pending[-1] = raw
        return applied

    # -- the report, by name ----------------------------------------------------------------------
    def reward(self):
        """The reward: the terms summed left to right in REWARD_TERMS order (the documented sum;
        a float, or (num_envs,) for a batch)."""
        if self.num_envs is None:
            return sum(self._terms.tolist())
        out = np.zeros(self.num_envs)
        for j in range(REWARD.size):
            out += self._terms[:, j]
        return out

    @property
    def termination(self):
        """The termination code of the last step (0: none; kernels/layout.py STATUS), an int or
        (num_envs,) int64."""
        if self.num_envs is None:
            return int(self._report[R_TERMINATION])
        return self._report[:, R_TERMINATION]

    def _row(self, i: int):
        """The live StateArrays and DiagWork of sub-environment ``i`` of a batch (views)."""
        return type(self._state)(*(a[i] for a in self._state)), type(self._diag)(*(a[i] for a in self._diag))
