"""The control step of ElasticStringPendulum-v0: the one Python face of the compiled step that the
single environment, the batched environments and the recording wrapper share.

A :class:`ControlStep` owns the arrays of one environment (or, with ``num_envs``, of a batch:
every array gains a leading axis) and the compiled calls on them (kernels/env/step.py):

* :meth:`ControlStep.start_episode` draws an episode (its physics when randomised, its state
  and targets) and :meth:`ControlStep.reset` puts it in and computes the observation;
* :meth:`ControlStep.step` takes a raw action (queued behind ``action_latency`` others),
  checks, clips and maps it to inputs, advances the episode's physics steps and fills the
  report: observation, sensors, reward terms, clipped action, inputs, and
  :data:`~esp_gym.kernels.layout.REPORT` (status, steps, Newton iterations, termination code).

Everything is readable through named, read-only views (``observation``, ``sensors``,
``reward_terms``, ``action``, ``inputs``, ``target``, ``report``, ``scene_params``,
``disturbance``) laid out in kernels/env/arrays.py (INPUTS and REPORT in kernels/layout.py,
DISTURBANCE in kernels/step/disturbance.py); the observation a mode returns is
esp_gym/pendulum/observe.py's; the environments' shared, resolved arguments are esp_gym/pendulum/env_setup.py's.
"""
from __future__ import annotations

from typing import Optional

import numba
import numpy as np

from ..kernels.drone.env import DRONE_SENSORS
from ..kernels.env.arrays import OBSERVATION, REWARD, REWARD_TERMS, SCHEME_DISTURBED, SENSORS, TARGET, WINCH_OBSERVATION
from ..kernels.env.arrays import FEATURES, EnvArrays
from ..kernels.env.step import actions_finite
from ..kernels.layout import INPUTS, R_TERMINATION, REPORT
from ..kernels.step.disturbance import DISTURBANCE, DISTURBANCE_PARAMS, DRAWS
from ..kernels.step.string import state_forces
from ..physics.arrays import params_row, row
from ..physics.drone import hover_at_rest, use_drone_scene, use_hook_scene
from ..physics.rig_arrays import make_arrays
from ..physics.state import State, check_memory
from ..physics.winch import winch_state
from ..scene.params import Scene
from ..workers import check_within_cpus
from .env_setup import Episode, EnvSetup
from .options import check_count
from .tasks import sample_episode
from .wind import BLOCK, Wind

#: info keys of the reward terms, in REWARD_TERMS order
INFO_REWARD_KEYS = tuple("reward_" + name for name in REWARD_TERMS)


def raw_actions(actions, shape: tuple, name: str = "action") -> np.ndarray:
    """``actions`` as the compiled step takes them: float64, C-contiguous, writeable (copied
    only if needed, so one compiled signature serves every caller), of ``shape`` (ValueError
    otherwise) and real (TypeError for complex, bool, object and masked arrays, whose imaginary
    part or mask would otherwise be dropped). Finiteness and clipping are the kernel's
    (kernels/env/step.py ``take_action``)."""
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


def check_threads(threads, num_envs: Optional[int]) -> int:
    """``threads``, the numba threads a batch of ``num_envs`` steps on: a whole number from 1 to
    the CPUs this process may use (and numba's NUMBA_NUM_THREADS); a single environment takes 1.
    ValueError naming ``threads`` otherwise."""
    threads = check_count("threads", threads)
    if num_envs is None and threads != 1:
        raise ValueError(f"threads is for batches (num_envs given), got {threads}")
    check_within_cpus("threads", threads)
    if threads > numba.config.NUMBA_NUM_THREADS:
        raise ValueError(f"threads must be at most numba's {numba.config.NUMBA_NUM_THREADS} (NUMBA_NUM_THREADS), "
                         f"got {threads}")
    return threads


class ControlStep:
    """The compiled control step of one environment, or of ``num_envs`` stacked ones.

    One environment (``num_envs=None``) steps the :class:`~esp_gym.physics.simulator.Simulator`
    :attr:`sim` in place (its step counter and Newton totals follow). A batch keeps stacked
    copies of a simulator's arrays and steps every active sub-environment in one compiled call, in
    one thread or on ``threads`` of numba's (docs/performance.md, "Threads"); both run the same
    compiled control step (esp_gym/kernels/env/step.py), so their numbers agree bit for bit.

    Each (sub-)environment carries its episode's run-time physics (:class:`Episode`: the
    stepper's constants, its number of physics steps, the task's and the action path's
    constants), set by :meth:`reset` with an ``episode`` or drawn by :meth:`start_episode`.

    Views (read-only; leading batch axis for a batch; layouts in kernels/env/arrays.py):
    ``observation`` (OBSERVATION), ``reward_terms`` (REWARD), ``action`` (the clipped
    action, ACTION), ``inputs`` (INPUTS: pivot force [N], body torque [N m], spatial torque),
    ``target`` (TARGET [m]), ``report`` (REPORT, int64), ``scene_params`` (SCENE_PARAMS of the
    current episodes, then the wind's WIND_INFO), ``disturbance`` (DISTURBANCE: the wind and the
    external forces of the last step; zeros in still air).
    """

    def __init__(self, setup: EnvSetup, num_envs: Optional[int] = None, threads: int = 1):
        self.setup = setup
        self.num_envs = None if num_envs is None else check_count("num_envs", num_envs)
        #: numba threads a batch steps on (1: its own thread, no pool)
        self.threads = check_threads(threads, self.num_envs)
        batch = () if self.num_envs is None else (self.num_envs,)
        check_memory(setup.scene.string.elements, self.num_envs, damped=setup.scene.string.damped)
        self._physics_structs(batch)
        self._env_buffers(batch)
        #: the rig (esp_gym/physics/rig.py): its compiled step and batched step, the structs they take
        self.rig = setup.rig
        entries = self.rig.entries
        self._step_kernel = entries.step
        self._batch_kernel = entries.batch if self.threads == 1 else entries.threaded_batch
        self._scheme = SCHEME_DISTURBED if self._windy else 0
        self._was_reset = np.zeros(batch, dtype=bool)  # stepping a state that was never set is an error
        self._ready = False  # all of _was_reset, kept as a bool: step checks it every call
        self._make_views()

    def _physics_structs(self, batch: tuple) -> None:
        """The simulator and the physics' structs (esp_gym/physics/rig_arrays.py :func:`make_arrays`): its
        state, work, constants and diagnostics, the winch's, the drone's and its hook's; for a
        batch, each stacked (``batch`` its leading axis), the constants per sub-environment."""
        arrays = make_arrays(self.setup.scene, self.num_envs)
        #: The simulator stepped in place (one environment), or the template of the batch's arrays;
        #: a :class:`~esp_gym.physics.drone.DroneSimulator` with a drone at the pivot.
        self.sim = arrays.sim
        self._arrays = arrays
        self._state, self._work, self._params, self._diag = arrays.state, arrays.work, arrays.params, arrays.diag
        #: the winch's arrays (read only with winch=True); the drone's (kernels/drone/quadrotor.py) or None
        #: without a drone; the drone's hook constants (kernels/drone/hook.py) when it is off the
        #: centre of mass, else None
        self._winch, self._drone, self._hook = arrays.winch, arrays.drone, arrays.hook
        if batch:
            #: The scene of each sub-environment's episode.
            self.scenes = [self.setup.scene] * self.num_envs

    def _env_buffers(self, batch: tuple) -> None:
        """The environment's arrays (kernels/env/arrays.py EnvArrays: inputs, target, action,
        observation, reward terms, report, sensors, features, the episode's run-time physics and
        the wind's), the actions in flight and the generators, with the leading axis ``batch``."""
        setup = self.setup
        nominal = setup.nominal_episode
        z = np.zeros
        self._inputs = z(batch + (INPUTS.size,))
        self._target = z(batch + (TARGET.size,))
        self._action = z(batch + (setup.action_size,))
        self._obs = z(batch + ((WINCH_OBSERVATION if setup.winch else OBSERVATION).size,))
        self._terms = z(batch + (REWARD.size,))
        self._report = z(batch + (REPORT.size,), dtype=np.int64)
        self._sensors = z(batch + ((DRONE_SENSORS if setup.drone else SENSORS).size,))
        self._features = z(batch + (FEATURES.size,))
        # actions on their way (oldest first): each step applies the oldest and queues the new one
        self._pending = z(batch + (setup.action_latency, setup.action_size))
        # the episode's run-time physics besides the stepper's constants
        self._substeps = np.full(batch + (1,), nominal.substeps, dtype=np.int64)
        self._task_params = np.tile(nominal.task_params, batch + (1,))
        self._action_params = np.tile(nominal.action_params, batch + (1,))
        self._scene_params = np.zeros(batch + (len(setup.param_names),))
        self._scene_params[..., :nominal.values.size] = nominal.values
        # the wind's episode constants, its state, the random draws ahead and the next one's row
        # (kernels/step/disturbance.py); stand-ins of the same types in still air
        self._wind_params = z(batch + (DISTURBANCE_PARAMS.size,))
        self._disturbance = z(batch + (DISTURBANCE.size,))
        self._draws = z(batch + (BLOCK if setup.wind is not None else 1, DRAWS.size))
        self._drawn = z(batch + (1,), dtype=np.int64)
        self._rngs = [None] * (self.num_envs or 1)  # each (sub-)environment's generator, for more draws
        self._windy = setup.wind is not None
        #: a drone's rotors draw their thrust noise before every control step (setup.thrust_noise)
        self._noisy_thrust = setup.drone and setup.thrust_noise > 0.0

    def _env_arrays(self) -> EnvArrays:
        """The environment's arrays as the compiled step takes them (kernels/env/arrays.py)."""
        return EnvArrays(ap=self._action_params, inputs=self._inputs, nsub=self._substeps, target=self._target,
                         tp=self._task_params, action=self._action, obs=self._obs, terms=self._terms,
                         sensors=self._sensors, features=self._features, result=self._report, dp=self._wind_params,
                         ds=self._disturbance, draws=self._draws, drawn=self._drawn)

    def _make_views(self) -> None:
        self._pack_structs()
        self.observation = read_only(self._obs)
        self.reward_terms = read_only(self._terms)
        self.action = read_only(self._action)
        self.inputs = read_only(self._inputs)
        self.target = read_only(self._target)
        self.report = read_only(self._report)
        self.sensors = read_only(self._sensors)
        self.features = read_only(self._features)
        self.scene_params = read_only(self._scene_params)
        self.disturbance = read_only(self._disturbance)

    def _pack_structs(self) -> None:
        """The structs the rig's entry points take, in its order (esp_gym/physics/rig.py STRUCTS), each
        as a plain tuple: numba's dispatcher types them ~2x faster than namedtuples
        (kernels/env/step.py)."""
        arrays = self._arrays._replace(params=self._params)  # a single env's episode may bring new constants
        self._structs = arrays.structs(self.rig.structs, env=self._env_arrays())

    # a pickled view would come back as a copy: pickle the arrays, rebuild the views
    _VIEWS = ("_structs", "observation", "reward_terms", "action", "inputs",
              "target", "report", "sensors", "features", "scene_params", "disturbance")

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
        targets: esp_gym/pendulum/tasks.py) and :meth:`reset` to it. Returns its SCENE_PARAMS values."""
        episode = self.setup.draw_episode(rng)
        state, target = sample_episode(self.setup.task, episode.scene, rng)
        wind = self.setup.wind
        self._rngs[0 if index is None else int(index)] = rng  # the wind's and the thrust noise's draws
        if wind is None:
            self.reset(state, target, index, episode)
            return episode.values
        row = () if index is None else int(index)
        params, start, draws, info = wind.episode(episode.scene, rng)
        self._wind_params[row], self._disturbance[row], self._draws[row] = params, start, draws
        self._drawn[row] = 0
        self.reset(state, target, index, episode)
        values = np.concatenate((episode.values, [info[name] for name in self.setup.param_names[episode.values.size:]]))
        self._scene_params[row] = values
        return values

    def _use_episode(self, episode: Episode, index: Optional[int]) -> None:
        """Put an episode's run-time physics in (one environment, or sub-environment ``index``)."""
        if self.num_envs is None:
            if episode.scene is not self.sim.scene:
                self.sim.use_scene(episode.scene, episode.params)
                self._params = self.sim.params
                self._pack_structs()
            self._substeps[...] = episode.substeps
        else:
            for field, value in zip(self._params, episode.params):
                field[index] = value
            if self._drone is not None:
                use_drone_scene(row(self._drone, index), episode.scene)
            if self._hook is not None:
                use_hook_scene(row(self._hook, index), episode.scene)
            self.scenes[index] = episode.scene
            self._substeps[index] = episode.substeps
        at = () if index is None else index
        self._task_params[at] = episode.task_params
        self._action_params[at] = episode.action_params
        self._scene_params[at][:episode.values.size] = episode.values

    def reset(self, state: State, target, index: Optional[int] = None, episode: Optional[Episode] = None) -> int:
        """Put ``state`` (balances restarted) and ``target`` (TARGET [m]) in, zero the action
        and compute the observation and reward terms; ``index``: the sub-environment of a batch;
        ``episode``: its run-time physics (default: unchanged). Returns the termination code of
        the new state."""
        if (self.num_envs is None) != (index is None):
            raise ValueError("index is for batches (num_envs given), and a batch needs it")
        if episode is not None:
            self._use_episode(episode, None if index is None else int(index))
        DR = None
        if self._drone is not None:  # before the state: the simulator's balances start with it
            DR = self._drone if index is None else row(self._drone, int(index))
            hover_at_rest(DR, self.sim.scene if index is None else self.scenes[int(index)])
        if self.num_envs is None:
            self.sim.set_state(state, check=False)  # built for this scene, as the batch's rows below
            S, D, P, E = self._state, self._diag, self._params, self._env_arrays()
            pending = self._pending
        else:
            i = int(index)
            S, D = self._row(i)
            P = params_row(self._params, i)
            S.r[...], S.p[...], S.R[...], S.Pi[...] = state.r, state.p, state.R, state.Pi
            for a in (S.rc, S.pc, S.Rc, S.Pic, S.acc, S.accc, S.owed):
                a[...] = 0.0
            state_forces(S, P)
            self._winch.state[i] = winch_state(self.scenes[i], P.max_len2)
            E = row(self._env_arrays(), i)
            pending = self._pending[i]
        E.target[...] = target
        E.action[...] = 0.0
        pending[...] = 0.0  # a new episode starts with hover commands in flight
        if not self._ready:
            self._was_reset[() if index is None else int(index)] = True
            self._ready = bool(self._was_reset.all())
        WA = self.sim.winch.arrays if index is None else row(self._winch, int(index))
        HK = self._hook if self._hook is None or index is None else row(self._hook, int(index))
        return self.rig.reset_observe(S, P, D, WA, E, DR, HK)

    # -- step -------------------------------------------------------------------------------------
    def step(self, actions, active: Optional[np.ndarray] = None) -> None:
        """One control step. ``actions``: the raw action (ACTION; a batch: (num_envs, ACTION)),
        any float array; clipped to the box in the compiled step. ValueError, with nothing
        changed, if its shape is wrong or an entry is not finite. ``active`` (batch only, bool
        (num_envs,)): the sub-environments to step (default: all); the others are untouched."""
        if not self._ready:
            never = "" if self.num_envs is None else f" (sub-environments {np.flatnonzero(~self._was_reset).tolist()})"
            raise RuntimeError(f"call reset() before step(){never}")
        latency = self.setup.action_latency
        if self.num_envs is None:
            raw = raw_actions(actions, (self.setup.action_size,))
            if latency:
                if not actions_finite(raw[None]):
                    raise ValueError(f"action must be finite, got {raw.tolist()}")
                raw = self._delay(raw, self._pending)
            if self._windy and self._drawn[0] == BLOCK:
                self._draws[...] = Wind.draws(self._rngs[0])
                self._drawn[0] = 0
            if self._noisy_thrust:  # a bad action must leave the generator alone: checked first
                if not actions_finite(raw[None]):
                    raise ValueError(f"action must be finite, got {raw.tolist()}")
                self._drone.thrust_scale[...] = 1.0 + self.setup.thrust_noise * self._rngs[0].standard_normal(4)
            if not self._step_kernel(*self._structs, raw, self._scheme):
                raise ValueError(f"action must be finite, got {raw.tolist()}")
            self.sim.count_steps(self._report)
            return
        raw = raw_actions(actions, (self.num_envs, self.setup.action_size), "actions")
        if not actions_finite(raw):
            raise ValueError("actions must be finite")
        if active is None:
            active = np.ones(self.num_envs, dtype=bool)
        if latency:
            raw = raw.copy()
            for i in np.flatnonzero(active):
                raw[i] = self._delay(raw[i], self._pending[i])
        if self._windy:
            for i in np.flatnonzero(self._drawn[:, 0] == BLOCK):
                self._draws[i] = Wind.draws(self._rngs[i])
                self._drawn[i] = 0
        if self._noisy_thrust:  # each sub-environment's own draws, in the single environment's order
            for i in np.flatnonzero(active):
                self._drone.thrust_scale[i] = 1.0 + self.setup.thrust_noise * self._rngs[i].standard_normal(4)
        if self.threads > 1:  # numba's thread count is per calling thread: set where the call is made
            numba.set_num_threads(self.threads)
        self._batch_kernel(*self._structs, raw, active, self._scheme)

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
        """The termination code of the last step (0: none; kernels/status.py STATUS), an int or
        (num_envs,) int64."""
        if self.num_envs is None:
            return int(self._report[R_TERMINATION])
        return self._report[:, R_TERMINATION]

    def _row(self, i: int):
        """The live StateArrays and DiagWork of sub-environment ``i`` of a batch (views)."""
        return row(self._state, i), row(self._diag, i)
