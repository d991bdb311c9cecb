"""ElasticStringPendulum-v0: a load on an elastic string under a free, actuated pivot."""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Union

import gymnasium as gym
import numpy as np

from ..errors import termination_reason
from ..kernels.env.arrays import FEATURES
from ..kernels.env.arrays import TARGET
from ..kernels.layout import INPUTS
from ..scene.params import Scene
from .control import INFO_REWARD_KEYS, ControlStep
from .env_setup import make_setup


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

    A zero action holds the whole system up. With `winch=True` the action is `Box(-1, 1, (7,))`:
    index 6 is the reel speed, x `scene.winch.max_speed` [m/s] (default 1), > 0 pays the string
    out (docs/physics.md, "The winch").

    With a drone at the pivot (`pivot.kind: drone`, e.g. `scene="quadrotor_load"`) the action is
    `Box(-1, 1, (4,))` in every `actuation`, 0 hovering: `"thrust_rates"` (the default) collective
    thrust W (1 + a_0) and body rates (4, 4, 2) rad/s x a_1..3 through the onboard rate
    controller; `"thrust_torque"` the thrust and body torques; `"motors"` each rotor's thrust
    W/4 (1 + a_i) (docs/environment.md, "A drone at the pivot").

    ## Observation Space
    `Box(-inf, inf, (22,), float32)`, spatial frame unless stated; `env.observation_structure`
    maps each name below to its slice (esp_gym/kernels/env/arrays.py OBSERVATION):

    | index | observation | unit |
    |---|---|---|
    | 0-2 | `pivot_position_error`: pivot position - pivot target | m |
    | 3-5 | `pivot_velocity` (less the target's velocity: 0 but in `track`) | m/s |
    | 6-8 | `load_position_error`: load centre of mass - load target | m |
    | 9-11 | `load_velocity`: load centre-of-mass velocity (less the target's) | m/s |
    | 12-17 | `attitude_6d`: first two columns of R (body x and y axes, spatial frame) | - |
    | 18-20 | `angular_velocity`: body angular velocity, body frame | rad/s |
    | 21 | `string_stretch`: stretched length / l - 1 | - |

    `observation="hook"`: `Box(-inf, inf, (12,), float32)`, what the hook measures, no load
    state: `pivot_position_error` (0-2) [m], `pivot_velocity` (3-5) [m/s], `hook_tension`
    (6-8): the string's pull on the pivot, the first element's force [N], `load_target_offset`
    (9-11): load target - pivot position [m]. `sensor_noise` adds Gaussian noise from
    `np_random` to either mode (esp_gym/pendulum/observe.py `UNIT_NOISE`, docs/environment.md). With
    `winch=True` either mode ends with `unstretched_length`, the string's current length [m]
    (`string_stretch` is then relative to it); with a drone, with `drone_attitude_6d` (R_q's
    first two columns) and `drone_rates` [rad/s].

    ## Rewards
    `reward = sum of info["reward_<term>"]` with, for x >= 0, `tol(x, s) = 1 / (1 + (x/s)^2)`:
    `load_position = w_lp tol(|load error|, 0.2 m)`, `load_velocity = w_lv tol(|v_load|, 0.5 m/s)`,
    `pivot_position = w_pp tol(|pivot error|, 0.2 m)`, `swing = w_sw tol(swing angle, 0.2 rad)`,
    `spin = w_sp tol(|Omega|, 1 rad/s)`, `control = -w_c |a|^2 / 6`; in `track` v_load is
    relative to the reference's velocity.
    Weights (stabilize / transport / track / lift and lower): w_lp 0.35/0.45/0.5/0.45,
    w_lv 0.2/0.1/0.15/0.1, w_pp 0.2/0.2/0.15/0.2, w_sw 0.15/0.2/0.15/0.2, w_sp 0.1/0.05/0.05/0.05,
    w_c 0.1 (the control term averages over the 7 actions with a winch); each step's reward lies
    in [-0.1, 1].

    ## Starting State
    `stabilize`: the pivot within 0.1 m of its target (the origin), the string straight and
    statically stretched at a swing angle up to 30 degrees in a random azimuth, the load hanging
    along it with random yaw (a centred load, `rho_c = 0`, with its body z axis along it); pivot and attachment velocities uniform in +-0.3 m/s per axis, body
    rates in +-0.5 rad/s. The load target is its rest position below the pivot target.
    `transport`: the system nearly at rest (swing <= 3 degrees, speeds <= 0.05 m/s) at the
    origin; the pivot target is uniform in +-(1, 1, 0.5) m, the load target below it.
    `track`: the targets move along a reference drawn per episode: a circle of radius a or a
    figure-eight (x = a sin(theta), y = a/2 sin(2 theta)), equally likely, a uniform in
    [0.3, 1] m, period uniform in [4, 10] s, either sense, random start angle and orientation
    about z, centred on the origin; the load target hangs below the pivot's at the rest depth.
    The system starts nearly at rest (as `transport`) with the pivot at the reference's start.
    `lift` and `lower` (need `winch=True`): the system nearly at rest at the origin; the load's
    target is the rest position of a string 25-45 % shorter (`lift`, the pivot target the origin)
    or 25-60 % longer (`lower`, the pivot target uniform in +-(1, 1, 0.5) m), within the winch's
    range. With `moving_target=True` (the hard preset's lift) the lift's targets move as `track`'s,
    the load target at the shorter string's rest depth, and the pivot starts at the reference's start.
    With `randomize`, the episode's tether and load are drawn first (then the state above, for
    that scene), and its physics step is its own. `reset`'s info holds the episode's physical
    parameters under `"scene_params"` (a flat dict of floats: `string_length`, `EA`, ...;
    the nominal ones without `randomize`).
    With `wind`, the episode's mean wind azimuth (unless given) and first gust are drawn next,
    and `"scene_params"` also holds `wind_speed` [m/s] and `wind_direction` [rad]; the wind of
    the current step is `env.unwrapped.control.disturbance` (kernels/step/disturbance.py DISTURBANCE).
    All randomness comes from `np_random` (seed it through `reset(seed=...)`).

    ## Episode End
    Terminated (with `info["termination_reason"]`): `physics_failure: ...` (Newton's method
    did not converge or the state became non-finite; the state is the last good one), `energy_balance`
    (|E - E0 - W| passed the energy watchdog's bound, `solver.energy_watchdog`: docs/physics.md),
    `string_overstretched` (stretched length > 1.5 l, l the current length), `left_workspace` (pivot or load more than
    4 m from its target), `drone_flipped` (a drone tilted past 90 degrees), `hit_ground` (pivot or load's centre of
    mass at the scene's `ground` plane, where it has one). Truncated: only by the time limit (`max_episode_steps`, 500 steps =
    10 s at the default 50 Hz).

    ## Arguments
    | argument | default | meaning |
    |---|---|---|
    | `scene` | `"drone_load"` | shipped scene name (esp_gym/scenes), YAML path or `Scene`; needs a free pivot |
    | `task` | `"stabilize"` | `"stabilize"`, `"transport"`, `"track"`; with `winch=True` also `"lift"`, `"lower"` |
    | `control_period` | 0.02 | seconds per `step` (a whole number of physics steps) |
    | `h` | None | physics step; None: the largest dividing the control period under `safety` x the stability bound (with `scene_overrides={"solver": {"string": "implicit"}}`, under 0.9 x the implicit string's transverse bound: docs/physics.md) |
    | `safety` | None | margin under the stability bound for the automatic h; None: 0.5 (long runs of the tension-only string under random inputs gain spurious energy above ~0.6: 0.8 J in 10 s at 0.8), or the resolution rule's with `string.elements: auto` (0.35 for the tension-only string: docs/physics.md) |
    | `force_limit` | 0.6 W | [N] per axis at action 1, at most 1000 W (options.py `MAX_FORCE_SHARE`) |
    | `torque_limit` | 0.02 | [N m] per axis at action 1 |
    | `scene_overrides` | None | dict of scene overrides, validated as in `esp_gym.load_scene` |
    | `randomize` | None | None: the preset's, else False. True: each episode draws the string's length, EA, mass per length, the load's mass, box and attachment offset, and the pivot mass from default ranges around the scene's values; a dict name -> (low, high) sets ranges (esp_gym/pendulum/randomize.py, docs/environment.md) |
    | `observation` | None | `"full"` or `"hook"` (Observation Space); None: the preset's, else `"full"` |
    | `sensor_noise` | None | None: the preset's, else 0. s: Gaussian noise of s x UNIT_NOISE per field; or a dict field -> standard deviation |
    | `action_latency` | None | control steps (0-50) between an action and its application (hover before the first); None: the preset's, else 0 |
    | `wind` | None | None: the preset's, else 0. The mean wind speed [m/s] (gusts of 0.2 x it, direction drawn per episode), or a dict of esp_gym/pendulum/wind.py `WindOptions` (speed, direction, gust_std, gust_time, drag coefficients, line_diameter, push_rate, push_speed): drag on the line and the load, pushes on the load |
    | `preset` | None | `"hard"`: randomize, wind 6 m/s with 1.5 m/s gusts and a push every 5 s on average, the hook observation with sensor noise 1 and a latency of 1 step, and for `lift` a moving target (docs/environment.md). An option given explicitly (even at its usual default) replaces the preset's: `preset="hard", observation="full"` is the hard preset with the full observation |
    | `winch` | None | True: a winch at the pivot, its reel speed the 7th action, the length the last observation; h is chosen for the shortest string it reaches (`scene.winch`). None: as the task needs (True for `lift` and `lower`) |
    | `actuation` | None | how the action moves the pivot: `"force"` (a free point mass: its only one), or for a drone `"thrust_rates"` (None's choice), `"thrust_torque"`, `"motors"` |
    | `thrust_noise` | None | a drone's: each rotor's thrust times 1 + s N(0, 1), drawn from `np_random` at every step (0-0.5); None: the preset's (hard: 0.05, a point pivot ignores it), else 0 |
    | `moving_target` | None | True: `lift`'s targets move along a `track` reference; None: the task's own (`track` moves), or the preset's (hard: `lift` moves) |
    | `render_mode` | None | `"rgb_array"`: uint8 frames, front and side views |

    ## Version History
    * v0: initial version.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, scene: Union[str, Path, Scene] = "drone_load", task: str = "stabilize",
                 control_period: float = 0.02, h: Optional[float] = None, safety: Optional[float] = None,
                 force_limit: Optional[float] = None, torque_limit: float = 0.02,
                 scene_overrides: Optional[dict] = None, render_mode: Optional[str] = None,
                 randomize: Union[bool, dict, None] = None, observation: Optional[str] = None,
                 sensor_noise: Union[float, dict, None] = None, action_latency: Optional[int] = None,
                 wind: Union[float, dict, None] = None, preset: Optional[str] = None, winch: Optional[bool] = None,
                 actuation: Optional[str] = None, thrust_noise: Optional[float] = None,
                 moving_target: Optional[bool] = None):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.setup = make_setup(scene, task=task, control_period=control_period, h=h, safety=safety,
                                force_limit=force_limit, torque_limit=torque_limit, scene_overrides=scene_overrides,
                                randomize=randomize, observation=observation, sensor_noise=sensor_noise,
                                action_latency=action_latency, wind=wind, preset=preset, winch=winch,
                                actuation=actuation, thrust_noise=thrust_noise, moving_target=moving_target)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": int(round(1.0 / self.setup.control_period))}
        self.observation_space = self.setup.observation_space
        self.action_space = self.setup.action_space
        #: The compiled control step (esp_gym/pendulum/control.py); it steps :attr:`sim` in place.
        self.control = ControlStep(self.setup)
        #: The simulator of this environment (its state and diagnostics).
        self.sim = self.control.sim
        #: Name -> slice of the observation vector of this mode (kernels/env/arrays.py OBSERVATION,
        #: HOOK_OBSERVATION).
        self.observation_structure = self.setup.observation_structure
        self._renderer = None

    # -- named accessors (dm_control style) ---------------------------------------------------
    @property
    def scene(self) -> Scene:
        """The current episode's scene (the nominal one unless ``randomize``)."""
        return self.control.scene

    @property
    def target(self) -> np.ndarray:
        """(pivot target, load target) [m], spatial frame, now (``track``'s move)."""
        t = self.control.target
        return np.concatenate((t[TARGET["pivot"]], t[TARGET["load"]]))

    def pivot_position(self) -> np.ndarray:
        return self.sim.state.r[0]

    def load_position(self) -> np.ndarray:
        """Load centre of mass [m] (spatial frame), as the last reset or step computed it
        (kernels/env/task_terms.py ``task_features``)."""
        return self.control.features[FEATURES["load_position"]].copy()

    def swing_angle(self) -> float:
        """Angle of pivot -> load centre of mass from the downward vertical [rad], as the last
        reset or step computed it for the reward (kernels/env/task_terms.py ``task_features``)."""
        return float(self.control.features[FEATURES.scalar("swing")])

    # -- gymnasium API ------------------------------------------------------------------------
    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        values = self.control.start_episode(self.np_random)
        if self._renderer is not None and self.setup.randomizer is not None:
            self._renderer = None  # the load and the string change with the episode
        return self._observe(), {"scene_params": dict(zip(self.setup.param_names, values.tolist()))}

    def _observe(self) -> np.ndarray:
        return self.setup.observer.observe(self.control.observation, self.control.sensors, self.np_random)

    def step(self, action):
        control = self.control
        control.step(action)
        terms = control.reward_terms.tolist()
        info = dict(zip(INFO_REWARD_KEYS, terms))
        reward = sum(terms)  # left to right, in REWARD_TERMS order: the documented sum, same bits
        code = control.termination
        if code:
            info["termination_reason"] = termination_reason(code)
        return self._observe(), reward, code != 0, False, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        from ..viz.render import FrameRenderer

        if self._renderer is None:
            self._renderer = FrameRenderer(self.scene.body.shape, self.scene.body.rho_c, self.scene.string.length)
        st = self.sim.state
        strain = self.sim.diagnostics()["strain_energy"]
        control = self.control
        drone = None
        if self.setup.drone:  # the drone as it is turned, its rotors where its layout puts them
            drone = (self.sim.drone.R, self.scene.pivot.drone.rotor_positions())
        return self._renderer.render(st.r, st.R, strain,
                                     pivot_force=control.inputs[INPUTS["pivot_force"]] - self.setup.hover,
                                     target_pivot=control.target[TARGET["pivot"]],
                                     target_load=control.target[TARGET["load"]], drone=drone)
