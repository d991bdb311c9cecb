"""ElasticStringPendulum-v0: a load on an elastic string under a free, actuated pivot."""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, Optional, Union

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .kernels.task import (ACTION_PARAM_SIZE, OBS_SIZE, REWARD_TERMS, TERM_OVERSTRETCH, TERM_WORKSPACE,
                           env_reset_observe, env_step)
from .model import STATUS_MESSAGES, Simulator
from .params import Scene, load_scene, scene_from_dict
from .tasks import Task, get_task, sample_episode

ACTION_SIZE = 6
#: info keys of the reward terms, in REWARD_TERMS order
INFO_REWARD_KEYS = tuple("reward_" + name for name in REWARD_TERMS)

TERMINATION_REASONS = {
    1: "physics_failure: " + STATUS_MESSAGES[1],
    2: "physics_failure: " + STATUS_MESSAGES[2],
    5: "physics_failure: " + STATUS_MESSAGES[5],
    TERM_OVERSTRETCH: "string_overstretched",
    TERM_WORKSPACE: "left_workspace",
}


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
        return spaces.Box(-np.inf, np.inf, (OBS_SIZE,), np.float32)

    @property
    def action_space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (ACTION_SIZE,), np.float32)

    @cached_property
    def action_params(self) -> np.ndarray:
        """The compiled action path's constants (kernels/task.py ``ap``): box bounds, hover
        force, force and torque limits."""
        space = self.action_space
        ap = np.concatenate([space.low, space.high, self.hover, [self.force_limit, self.torque_limit]])
        assert ap.shape == (ACTION_PARAM_SIZE,)
        return ap.astype(np.float64)


def raw_actions(actions, shape: tuple, name: str = "action") -> np.ndarray:
    """``actions`` as the compiled step takes them: float64, C-contiguous, writeable (copied
    only if needed, so one compiled signature serves every caller), of ``shape`` (ValueError
    otherwise). Finiteness and clipping are the kernel's (kernels/task.py ``take_action``)."""
    raw = np.asarray(actions, dtype=np.float64)
    if raw.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {raw.shape}")
    if not (raw.flags.c_contiguous and raw.flags.writeable):
        raw = raw.copy()
    return raw


def make_setup(scene: Union[str, Path, Scene] = "drone_load", task: str = "stabilize",
               control_period: float = 0.02, h: Optional[float] = None, safety: float = 0.5,
               force_limit: Optional[float] = None, torque_limit: float = 0.02,
               scene_overrides: Optional[dict] = None) -> EnvSetup:
    """Resolve the environment's arguments (see :class:`ElasticStringPendulumEnv`)."""
    if not (control_period > 0 and math.isfinite(control_period)):
        raise ValueError(f"control_period must be a positive time [s], got {control_period}")
    if not 0 < safety <= 1:
        raise ValueError(f"safety must be in (0, 1], got {safety}")
    overrides = dict(scene_overrides or {})
    if isinstance(scene, Scene):
        base = scene.model_dump()
        for k, v in overrides.items():
            base[k] = v
        resolved = scene_from_dict(base, source=repr(scene.name))
    else:
        resolved = load_scene(scene, **overrides)
    if not resolved.pivot.is_free:
        raise ValueError(f"ElasticStringPendulum-v0 pushes the pivot: scene {resolved.name!r} needs pivot.kind: free")
    bound = resolved.stability_bound
    if h is None:
        substeps = math.ceil(control_period / (safety * bound) - 1e-9)
    else:
        substeps = int(round(control_period / h))
        if substeps < 1 or abs(substeps * h - control_period) > 1e-9 * control_period:
            raise ValueError(f"h = {h} s must divide the control period {control_period} s")
    h_used = control_period / substeps
    resolved = scene_from_dict({**resolved.model_dump(), "h": h_used}, source=repr(resolved.name))
    weight = resolved.gravity * (resolved.body.mass + resolved.pivot.mass
                                 + resolved.string.length * resolved.string.mass_per_length)
    if force_limit is None:
        force_limit = 0.6 * weight if weight > 0 else 1.0
    if not (force_limit > 0 and torque_limit >= 0):
        raise ValueError("force_limit must be > 0 and torque_limit >= 0")
    t = get_task(task)
    return EnvSetup(scene=resolved, task=t, task_params=t.params(resolved), control_period=float(control_period),
                    substeps=substeps, hover=np.array([0.0, 0.0, -weight]), force_limit=float(force_limit),
                    torque_limit=float(torque_limit))


class ElasticStringPendulumEnv(gym.Env):
    """
    ## Description
    A rigid load hangs from an extensible elastic string whose upper end, the pivot, is a free
    point mass pushed by a 3-D force, like a drone or a crane hook; a torque can also act on the
    load. The physics is the Lie group variational integrator of Lee, Leok & McClamroch's 3D
    elastic string pendulum (finite-element string with consistent mass, rigid body on SO(3)),
    with the inputs entering through the discrete Lagrange-d'Alembert principle. Gravity acts
    along **+z**: "below" means larger z.

    ## Action Space
    `Box(-1, 1, (6,), float32)`; values outside are clipped.

    | index | action | unit at 1.0 |
    |---|---|---|
    | 0-2 | pivot force x, y, z, added to the hover force `(0, 0, -W)` (W the total weight) | `force_limit` [N] (default 0.6 W) |
    | 3-5 | body torque, body frame | `torque_limit` [N m] (default 0.02) |

    A zero action holds the whole system up.

    ## Observation Space
    `Box(-inf, inf, (22,), float32)`, spatial frame unless stated:

    | index | observation | unit |
    |---|---|---|
    | 0-2 | pivot position - pivot target | m |
    | 3-5 | pivot velocity | m/s |
    | 6-8 | load centre of mass - load target | m |
    | 9-11 | load centre-of-mass velocity | m/s |
    | 12-17 | attitude: first two columns of R (body x and y axes, spatial frame) | - |
    | 18-20 | body angular velocity, body frame | rad/s |
    | 21 | string stretch: stretched length / l - 1 | - |

    ## Rewards
    `reward = sum of info["reward_<term>"]` with, for x >= 0, `tol(x, s) = 1 / (1 + (x/s)^2)`:
    `load_position = w_lp tol(|load error|, 0.2 m)`, `load_velocity = w_lv tol(|v_load|, 0.5 m/s)`,
    `pivot_position = w_pp tol(|pivot error|, 0.2 m)`, `swing = w_sw tol(swing angle, 0.2 rad)`,
    `spin = w_sp tol(|Omega|, 1 rad/s)`, `control = -w_c |a|^2 / 6`.
    Weights (stabilize / transport): w_lp 0.35/0.45, w_lv 0.2/0.1, w_pp 0.2/0.2, w_sw 0.15/0.2,
    w_sp 0.1/0.05, w_c 0.1/0.1; each step's reward lies in [-0.1, 1].

    ## Starting State
    `stabilize`: the pivot within 0.1 m of its target (the origin), the string straight and
    statically stretched at a swing angle up to 30 degrees in a random azimuth, the load hanging
    along it with random yaw; pivot and attachment velocities uniform in +-0.3 m/s per axis, body
    rates in +-0.5 rad/s. The load target is its rest position below the pivot target.
    `transport`: the system nearly at rest (swing <= 3 degrees, speeds <= 0.05 m/s) at the
    origin; the pivot target is uniform in +-(1, 1, 0.5) m, the load target below it.
    All randomness comes from `np_random` (seed it through `reset(seed=...)`).

    ## Episode End
    Terminated (with `info["termination_reason"]`): `physics_failure: ...` (Newton's method
    did not converge or the state became non-finite; the state is the last good one),
    `string_overstretched` (stretched length > 1.5 l), `left_workspace` (pivot or load more than
    4 m from its target). Truncated: only by the time limit (`max_episode_steps`, 500 steps =
    10 s at the default 50 Hz).

    ## Arguments
    | argument | default | meaning |
    |---|---|---|
    | `scene` | `"drone_load"` | scene name under configs/scenes, YAML path or `Scene`; needs a free pivot |
    | `task` | `"stabilize"` | `"stabilize"` or `"transport"` |
    | `control_period` | 0.02 | seconds per `step` (a whole number of physics steps) |
    | `h` | None | physics step; None: the largest dividing the control period under `safety` x the stability bound |
    | `safety` | 0.5 | margin under the stability bound for the automatic h (long runs of the tension-only string under random inputs gain spurious energy above ~0.6: 0.8 J in 10 s at 0.8) |
    | `force_limit` | 0.6 W | [N] per axis at action 1 |
    | `torque_limit` | 0.02 | [N m] per axis at action 1 |
    | `scene_overrides` | None | dict of scene overrides, validated as in `esp_gym.load_scene` |
    | `render_mode` | None | `"rgb_array"`: uint8 frames, front and side views |

    ## Version History
    * v0: initial version.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, scene: Union[str, Path, Scene] = "drone_load", task: str = "stabilize",
                 control_period: float = 0.02, h: Optional[float] = None, safety: float = 0.5,
                 force_limit: Optional[float] = None, torque_limit: float = 0.02,
                 scene_overrides: Optional[dict] = None, render_mode: Optional[str] = None):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.setup = make_setup(scene, task, control_period, h, safety, force_limit, torque_limit, scene_overrides)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": int(round(1.0 / self.setup.control_period))}
        self.observation_space = self.setup.observation_space
        self.action_space = self.setup.action_space
        self.sim = Simulator(self.setup.scene)
        self._target = np.zeros(6)
        self._inputs = np.zeros(9)
        self._action = np.zeros(ACTION_SIZE)
        self._obs = np.zeros(OBS_SIZE)
        self._terms = np.zeros(len(REWARD_TERMS))
        self._result = np.zeros(5, dtype=np.int64)
        self._renderer = None

    # -- named accessors (dm_control style) ---------------------------------------------------
    @property
    def scene(self) -> Scene:
        return self.setup.scene

    @property
    def target(self) -> np.ndarray:
        """(pivot target, load target) [m], spatial frame."""
        return self._target.copy()

    def pivot_position(self) -> np.ndarray:
        return self.sim.state.r[0]

    def load_position(self) -> np.ndarray:
        """Load centre of mass [m]."""
        st = self.sim.state
        return st.r[-1] + st.R @ np.asarray(self.scene.body.rho_c)

    def swing_angle(self) -> float:
        """Angle of pivot -> load centre of mass from the downward vertical [rad]."""
        d = self.load_position() - self.pivot_position()
        return float(math.atan2(math.hypot(d[0], d[1]), d[2]))

    # -- gymnasium API ------------------------------------------------------------------------
    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        state, target = sample_episode(self.setup.task, self.scene, self.np_random)
        self.sim.set_state(state)
        self._target[:] = target
        self._action[:] = 0.0
        S, _, P, D = self.sim.kernel_args
        env_reset_observe(S, P, D, self._target, self.setup.task_params, self._action, self._obs, self._terms)
        return self._obs.astype(np.float32), {}

    def step(self, action):
        raw = raw_actions(action, self.action_space.shape)
        S, W, P, D = self.sim.kernel_args
        if not env_step(tuple(S), tuple(W), tuple(P), tuple(D), raw, self.setup.action_params, self._inputs,
                        self.setup.substeps, self._target, self.setup.task_params, self._action, self._obs,
                        self._terms, self._result):
            raise ValueError(f"action must be finite, got {raw.tolist()}")
        self.sim.advance_counter(self._result[1], self._result[2], self._result[3])
        terms = self._terms.tolist()
        info = dict(zip(INFO_REWARD_KEYS, terms))
        reward = sum(terms)  # left to right, in REWARD_TERMS order: the documented sum, same bits
        code = int(self._result[4])
        if code:
            info["termination_reason"] = TERMINATION_REASONS[code]
        return self._obs.astype(np.float32), reward, code != 0, False, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        from .viz.render import FrameRenderer

        if self._renderer is None:
            self._renderer = FrameRenderer(self.scene.body.shape, self.scene.body.rho_c, self.scene.string.length)
        st = self.sim.state
        strain = self.sim.diagnostics()["strain_energy"]
        return self._renderer.render(st.r, st.R, strain, pivot_force=self._inputs[0:3] - self.setup.hover,
                                     target_pivot=self._target[:3], target_load=self._target[3:])
