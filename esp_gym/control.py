"""The control step of ElasticStringPendulum-v0: the one Python face of the compiled step that the
single environment, the batched environments and the recording wrapper share.

A :class:`ControlStep` owns the arrays of one environment (or, with ``num_envs``, of a batch:
every array gains a leading axis) and the compiled calls on them (kernels/task.py):

* :meth:`ControlStep.reset` puts a state and its targets in and computes the observation;
* :meth:`ControlStep.step` takes a raw action, checks, clips and maps it to inputs, advances
  ``setup.substeps`` physics steps and fills the report: observation, reward terms, clipped
  action, inputs, and :data:`~esp_gym.kernels.layout.REPORT` (status, steps, Newton
  iterations, termination code).

Everything is readable through named, read-only views (``observation``, ``reward_terms``,
``action``, ``inputs``, ``target``, ``report``) laid out in kernels/layout.py.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Optional, Union

import numpy as np
from gymnasium import spaces

from .kernels.layout import (ACTION, ACTION_PARAMS, ACTION_SIZE, INPUTS, OBSERVATION, R_TERMINATION, REPORT, REWARD,
                             REWARD_TERMS, TARGET)
from .kernels.string import state_forces
from .kernels.task import (actions_finite, env_reset_observe, env_step, env_step_batch, env_step_batch_implicit,
                           env_step_implicit)
from .model import Simulator
from .options import MAX_SUBSTEPS, check_count, env_options
from .state import State, check_memory
from .params import Scene, load_scene, override_scene, scene_from_dict
from .stepsize import choose_scheme
from .tasks import Task, get_task

#: info keys of the reward terms, in REWARD_TERMS order
INFO_REWARD_KEYS = tuple("reward_" + name for name in REWARD_TERMS)


@dataclass(frozen=True)
class EnvSetup:
    """Everything the single and the batched environments share, resolved and validated."""

    scene: Scene
    task: Task
    task_params: np.ndarray
    control_period: float  #: [s]
    substeps: int  #: physics steps per control step
    hover: np.ndarray  #: feed-forward pivot force holding the whole system up [N]
    force_limit: float  #: pivot force per axis at |action| = 1, added to the hover force [N]
    torque_limit: float  #: body torque per axis at |action| = 1 [N m]

    @property
    def observation_space(self) -> spaces.Box:
        return spaces.Box(-np.inf, np.inf, (OBSERVATION.size,), np.float32)

    @property
    def action_space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (ACTION_SIZE,), np.float32)

    @cached_property
    def action_params(self) -> np.ndarray:
        """The compiled action path's constants (:data:`~esp_gym.kernels.layout.ACTION_PARAMS`):
        box bounds, hover force, force and torque limits."""
        space = self.action_space
        ap = np.zeros(ACTION_PARAMS.size)
        ap[ACTION_PARAMS["low"]] = space.low
        ap[ACTION_PARAMS["high"]] = space.high
        ap[ACTION_PARAMS["hover_force"]] = self.hover
        ap[ACTION_PARAMS["force_limit"]] = self.force_limit
        ap[ACTION_PARAMS["torque_limit"]] = self.torque_limit
        return ap


def make_setup(scene: Union[str, Path, Scene] = "drone_load", task: str = "stabilize",
               control_period: float = 0.02, h: Optional[float] = None, safety: float = 0.5,
               force_limit: Optional[float] = None, torque_limit: float = 0.02,
               scene_overrides: Optional[dict] = None) -> EnvSetup:
    """Resolve the environment's arguments (see :class:`~esp_gym.env.ElasticStringPendulumEnv`),
    validated by :class:`~esp_gym.options.EnvOptions` (ValueError naming each bad one)."""
    o = env_options(scene=scene, task=task, control_period=control_period, h=h, safety=safety,
                    force_limit=force_limit, torque_limit=torque_limit, scene_overrides=scene_overrides)
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
    scheme = resolved.solver.string
    if h is None:
        # the scene's scheme (explicit unless asked): choose_scheme's cost rule would pick the
        # implicit string for stiff strings, but its accuracy under random actions is not
        # established yet (docs/physics.md, "The environment's choice")
        choice = choose_scheme(resolved, control_period, safety)
        wanted = choice.explicit_substeps if scheme == "explicit" else choice.implicit_substeps
        what = f"safety = {safety} x the stability bound" if scheme == "explicit" else "the transverse bound"
    else:
        wanted = control_period / h
        what = f"h = {h} s"
    if wanted > MAX_SUBSTEPS:
        raise ValueError(f"ElasticStringPendulum-v0: control_period = {control_period} s with {what} needs "
                         f"{wanted:.3g} physics steps per step (at most {MAX_SUBSTEPS:,}): use a larger h or "
                         f"safety, a shorter control_period, or a softer, longer or coarser string")
    if h is None:
        substeps = int(wanted)
    else:
        substeps = int(round(wanted))
        if substeps < 1 or abs(substeps * h - control_period) > 1e-9 * control_period:
            raise ValueError(f"h = {h} s must divide the control period {control_period} s")
    h_used = control_period / substeps
    resolved = scene_from_dict({**resolved.model_dump(), "h": h_used, "allow_unstable_h": keep_unstable,
                                "solver": {**resolved.solver.model_dump(), "string": scheme}},
                               source=repr(resolved.name))
    weight = resolved.gravity * (resolved.body.mass + resolved.pivot.mass
                                 + resolved.string.length * resolved.string.mass_per_length)
    force_limit = o.force_limit if o.force_limit is not None else (0.6 * weight if weight > 0 else 1.0)
    torque_limit = o.torque_limit
    t = get_task(o.task)
    return EnvSetup(scene=resolved, task=t, task_params=t.params(resolved), control_period=float(control_period),
                    substeps=substeps, hover=np.array([0.0, 0.0, -weight]), force_limit=float(force_limit),
                    torque_limit=float(torque_limit))


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

    Views (read-only; leading batch axis for a batch; layouts in kernels/layout.py):
    ``observation`` (OBSERVATION), ``reward_terms`` (REWARD), ``action`` (the clipped
    action, ACTION), ``inputs`` (INPUTS: pivot force [N], body torque [N m], spatial torque),
    ``target`` (TARGET [m]), ``report`` (REPORT, int64).
    """

    def __init__(self, setup: EnvSetup, num_envs: Optional[int] = None):
        self.setup = setup
        self.num_envs = None if num_envs is None else check_count("num_envs", num_envs)
        batch = () if self.num_envs is None else (self.num_envs,)
        check_memory(setup.scene.string.elements, copies=1 + (self.num_envs or 0))
        #: The simulator stepped in place (one environment), or the template of the batch's arrays.
        self.sim = Simulator(setup.scene)
        state, work, params, diag = self.sim.buffers
        if batch:
            def stack(t):
                return type(t)(*(np.zeros(batch + a.shape) for a in t))

            state, work, diag = stack(state), stack(work), stack(diag)
        self._state, self._diag, self._params = state, diag, params
        self._work = work
        z = np.zeros
        self._inputs = z(batch + (INPUTS.size,))
        self._target = z(batch + (TARGET.size,))
        self._action = z(batch + (ACTION.size,))
        self._obs = z(batch + (OBSERVATION.size,))
        self._terms = z(batch + (REWARD.size,))
        self._report = z(batch + (REPORT.size,), dtype=np.int64)
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

    # a pickled view would come back as a copy: pickle the arrays, rebuild the views
    _VIEWS = ("_kernel_tuples", "observation", "reward_terms", "action", "inputs", "target", "report")

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k not in self._VIEWS}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._make_views()

    # -- reset ------------------------------------------------------------------------------------
    def reset(self, state: State, target, index: Optional[int] = None) -> int:
        """Put ``state`` (balances restarted) and ``target`` (TARGET [m]) in, zero the action
        and compute the observation and reward terms; ``index``: the sub-environment of a batch.
        Returns the termination code of the new state."""
        if self.num_envs is None:
            if index is not None:
                raise ValueError("index is for batches (num_envs given)")
            self.sim.set_state(state)
            S, D, obs, terms, action, tgt = self._state, self._diag, self._obs, self._terms, self._action, self._target
        else:
            i = int(index)
            S, D = self._row(i)
            S.r[...], S.p[...], S.R[...], S.Pi[...] = state.r, state.p, state.R, state.Pi
            for a in (S.rc, S.pc, S.Rc, S.Pic, S.acc, S.accc):
                a[...] = 0.0
            state_forces(S, self._params)
            obs, terms, action, tgt = self._obs[i], self._terms[i], self._action[i], self._target[i]
        tgt[...] = target
        action[...] = 0.0
        if not self._ready:
            self._was_reset[() if index is None else int(index)] = True
            self._ready = bool(self._was_reset.all())
        return int(env_reset_observe(S, self._params, D, tgt, self.setup.task_params, action, obs, terms))

    # -- step -------------------------------------------------------------------------------------
    def step(self, actions, active: Optional[np.ndarray] = None) -> None:
        """One control step. ``actions``: the raw action (ACTION; a batch: (num_envs, ACTION)),
        any float array; clipped to the box in the compiled step. ValueError, with nothing
        changed, if its shape is wrong or an entry is not finite. ``active`` (batch only, bool
        (num_envs,)): the sub-environments to step (default: all); the others are untouched."""
        s, w, p, d = self._kernel_tuples
        setup = self.setup
        if not self._ready:
            never = "" if self.num_envs is None else f" (sub-environments {np.flatnonzero(~self._was_reset).tolist()})"
            raise RuntimeError(f"call reset() before step(){never}")
        if self.num_envs is None:
            raw = raw_actions(actions, (ACTION.size,))
            step = env_step_implicit if self.sim.implicit else env_step
            if not step(s, w, p, d, raw, setup.action_params, self._inputs, setup.substeps, self._target,
                            setup.task_params, self._action, self._obs, self._terms, self._report):
                raise ValueError(f"action must be finite, got {raw.tolist()}")
            self.sim.count_steps(self._report)
            return
        raw = raw_actions(actions, (self.num_envs, ACTION.size), "actions")
        if not actions_finite(raw):
            raise ValueError("actions must be finite")
        if active is None:
            active = np.ones(self.num_envs, dtype=bool)
        batch = env_step_batch_implicit if self.sim.implicit else env_step_batch
        batch(s, w, d, p, raw, setup.action_params, self._inputs, active, setup.substeps, self._target,
              setup.task_params, self._action, self._obs, self._terms, self._report)

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
