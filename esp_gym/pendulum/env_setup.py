"""What ElasticStringPendulum-v0's single and batched environments share, resolved from their
arguments (:func:`make_setup`): the nominal scene and task, the control period and physics steps,
the action path, and each episode's run-time physics (:class:`Episode`, drawn by
:meth:`EnvSetup.draw_episode` when randomised), the observation mode and the wind.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Optional, Union

import math

import numpy as np
from gymnasium import spaces

from ..kernels.drone.env import DRONE_ACTION_PARAMS, DRONE_ACTION_SIZE, DRONE_WINCH_ACTION_SIZE
from ..kernels.drone.quadrotor import ACTUATIONS
from ..kernels.env.arrays import ACTION_PARAMS, ACTION_SIZE, WINCH_ACTION
from ..kernels.layout import LGVIParams
from ..physics.rig import Rig, scene_rig
from ..physics.state import build_params, total_weight
from ..scene.params import Scene, load_scene, override_scene, scene_from_dict
from ..scene.stepsize import auto_elements, longest, rate_loop_substeps, resolution_safety, scheme_substeps, shortest
from .observe import Observer
from .options import MAX_FORCE_SHARE, check_substeps, env_options
from .randomize import Randomizer, episode_param_names, nominal_values
from .tasks import Task, get_task, hanging_depth
from .wind import WIND_INFO, Wind, drag_areas, wind_options

#: The arguments each preset sets (docs/environment.md, "The hard preset"): ``hard`` is every
#: realism option on, for benchmarks that cite one string.
PRESETS = {"hard": {"randomize": True, "observation": "hook", "sensor_noise": 1.0, "action_latency": 1,
                    "wind": {"speed": 6.0, "gust_std": 1.5, "push_rate": 0.2, "push_speed": 0.5},
                    "thrust_noise": 0.05}}
#: The arguments a preset sets for one task only (after :data:`PRESETS`' own): the hard preset's
#: lift follows a moving target, since hoisting to a fixed one is solved by the hoist baseline.
PRESET_TASK_OPTIONS = {"hard": {"lift": {"moving_target": True}}}


def check_hanging(scene: Scene, task: Task, randomizer: Optional[Randomizer]) -> None:
    """ValueError unless the load can hang in every episode: under the weight it carries, the
    string's top stretches by g (M + mu l) / EA, at most half the stretch at which the task ends
    an episode (at the ranges' worst corner with ``randomizer``: the softest string, the heaviest
    and longest load and string), or every episode would end at its first steps; and the load's
    deepest target lies above the scene's ground plane."""
    nominal = nominal_values(scene)
    ranges = {} if randomizer is None else randomizer.ranges
    low = {k: ranges.get(k, (v, v))[0] for k, v in nominal.items()}
    high = {k: ranges.get(k, (v, v))[1] for k, v in nominal.items()}
    weight = scene.gravity * (high["load_mass"] + high["mass_per_length"] * high["string_length"])
    stretch, allowed = weight / low["EA"], 0.5 * (task.max_stretch - 1.0)
    if stretch > allowed:
        where = " at the randomize ranges' softest, heaviest corner" if randomizer is not None else ""
        raise ValueError(f"ElasticStringPendulum-v0: the load cannot hang: its weight {weight:.4g} N stretches the "
                         f"string (EA = {low['EA']:.4g} N) by {stretch:.3g} of its length{where}, past {allowed:g} "
                         f"(half of the {task.max_stretch - 1.0:g} at which task {task.name!r} ends an episode); "
                         f"raise EA or lighten the load or the string")
    if scene.ground is not None:  # the load's deepest target, hanging from the pivot's deepest one
        longest = high["string_length"] / nominal["string_length"] * (1.0 + stretch) * (1.0 + max(task.reel_range))
        deepest = task.target_box[2] + hanging_depth(scene) * longest
        if scene.ground <= deepest:
            raise ValueError(f"ElasticStringPendulum-v0: scene {scene.name!r}: ground {scene.ground:g} m is not below "
                             f"the load's deepest target, {deepest:.4g} m (its longest string under task "
                             f"{task.name!r}); lower the ground")


#: The least thrust-to-weight a drone needs at the randomize ranges' worst corner: below it a
#: controller has no authority left to steer (at 1 it could only hover).
MIN_THRUST_TO_WEIGHT = 1.2


def check_lift(scene: Scene, randomizer: Optional[Randomizer]) -> None:
    """ValueError unless the drone's rotors lift the rig with :data:`MIN_THRUST_TO_WEIGHT` to spare:
    at the ranges' heaviest drone, load and string under the weakest rotors with ``randomizer``."""
    nominal = nominal_values(scene)
    ranges = {} if randomizer is None else randomizer.ranges
    high = {k: ranges.get(k, (v, v))[1] for k, v in nominal.items()}
    weakest = ranges.get("rotor_coefficient_scale", (1.0, 1.0))[0]
    weight = scene.gravity * (high["pivot_mass"] + high["load_mass"] + high["mass_per_length"] * high["string_length"])
    where = " at the randomize ranges' heaviest, weakest corner" if randomizer is not None else ""
    check_thrust("ElasticStringPendulum-v0: the drone", weakest * scene.pivot.drone.max_thrust, weight, where)


def check_thrust(drone: str, thrust: float, weight: float, where: str = "") -> None:
    """ValueError unless a drone's rotors, ``thrust`` at most [N], lift the ``weight`` it carries
    [N] with :data:`MIN_THRUST_TO_WEIGHT` to spare (the single env's drone, each drone of a team:
    esp_gym/team/randomize.py); ``drone`` and ``where`` name them in the message."""
    if thrust < MIN_THRUST_TO_WEIGHT * weight:
        raise ValueError(f"{drone} cannot carry the rig: its rotors push {thrust:.4g} N against a weight of "
                         f"{weight:.4g} N{where}, under the {MIN_THRUST_TO_WEIGHT:g} times the weight a controller "
                         f"needs; lighten the rig or narrow the ranges")


def action_params(hover: np.ndarray, force_limit: float, torque_limit: float, max_reel_speed: float) -> np.ndarray:
    """The compiled action path's constants (:data:`~esp_gym.kernels.env.arrays.ACTION_PARAMS`):
    box bounds [-1, 1], hover force, force and torque limits, the winch's largest reel speed."""
    ap = np.zeros(ACTION_PARAMS.size)
    ap[ACTION_PARAMS["low"]] = -1.0
    ap[ACTION_PARAMS["high"]] = 1.0
    ap[ACTION_PARAMS["hover_force"]] = hover
    ap[ACTION_PARAMS["force_limit"]] = force_limit
    ap[ACTION_PARAMS["torque_limit"]] = torque_limit
    ap[ACTION_PARAMS["max_reel_speed"]] = max_reel_speed
    return ap


#: The body rates at |action| = 1 of ``thrust_rates`` (roll, pitch, yaw) [rad/s].
DRONE_RATE_LIMIT = (4.0, 4.0, 2.0)
#: The drone has flipped when its body axis b3 tilts this far from the downward vertical [deg]:
#: past the horizontal, its thrust no longer holds anything up (``info["termination_reason"]``
#: "drone_flipped").
DRONE_FLIP_TILT = 90.0


def drone_action_params(scene: Scene, actuation: str) -> np.ndarray:
    """The drone's action path (:data:`~esp_gym.kernels.drone.env.DRONE_ACTION_PARAMS`) for
    ``scene``: the actuation's code, the hover thrust (the rig's weight, :func:`total_weight`) and
    the rotors' largest [N], the torque limit per axis [N m] (a quarter of the hover thrust across
    the arm for roll and pitch, times k_m/k_f for yaw), :data:`DRONE_RATE_LIMIT`, the flip's
    cosine and the winch's largest reel speed [m/s]."""
    drone = scene.pivot.drone
    hover = total_weight(scene)
    qa = np.zeros(DRONE_ACTION_PARAMS.size)
    qa[DRONE_ACTION_PARAMS.scalar("actuation")] = ACTUATIONS.index(actuation)
    qa[DRONE_ACTION_PARAMS.scalar("hover_thrust")] = hover
    qa[DRONE_ACTION_PARAMS.scalar("max_thrust")] = drone.max_thrust
    arm = 0.25 * hover * drone.arm_length
    qa[DRONE_ACTION_PARAMS["torque_limit"]] = (arm, arm, 0.25 * hover * drone.torque_coefficient
                                               / drone.thrust_coefficient)
    qa[DRONE_ACTION_PARAMS["rate_limit"]] = DRONE_RATE_LIMIT
    qa[DRONE_ACTION_PARAMS.scalar("flip_cosine")] = math.cos(math.radians(DRONE_FLIP_TILT))
    qa[DRONE_ACTION_PARAMS.scalar("max_reel_speed")] = scene.winch.max_speed
    return qa


@dataclass(frozen=True)
class Episode:
    """The run-time physics of one episode: its scene's values (episode_param_names order), the scene
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
    wind: Optional[Wind] = None  #: the wind and pushes (esp_gym/pendulum/wind.py), or None: still air
    winch: bool = False  #: the winch's reel speed is the 7th action (kernels/step/winch.py)
    #: how the action moves the pivot: "force" (a point mass), or a drone's (kernels/drone/quadrotor.py ACTUATIONS)
    actuation: str = "force"
    #: a drone's thrust noise: each rotor's thrust times 1 + this x N(0, 1), drawn per control step
    thrust_noise: float = 0.0

    @property
    def drone(self) -> bool:
        """The pivot is a drone, flown in :attr:`actuation`."""
        return self.actuation != "force"

    @property
    def rig(self) -> Rig:
        """The rig this setup runs (esp_gym/physics/rig.py): its pivot, string scheme, winch and hook."""
        return scene_rig(self.scene, self.winch)

    @property
    def param_names(self) -> tuple:
        """The names of the reset info's ``"scene_params"``: SCENE_PARAMS (DRONE_SCENE_PARAMS after
        them with a drone: esp_gym/pendulum/randomize.py), then WIND_INFO with wind."""
        return episode_param_names(self.scene) + (WIND_INFO if self.wind is not None else ())

    @property
    def observation_structure(self) -> dict:
        """Name -> slice of the observation vector of this setup's mode."""
        return self.observer.layout.structure()

    @property
    def observation_space(self) -> spaces.Box:
        return spaces.Box(-np.inf, np.inf, (self.observer.layout.size,), np.float32)

    @property
    def action_size(self) -> int:
        """ACTION's size, WINCH_ACTION's with the winch, or a drone's 4 (5 with the winch)."""
        if self.drone:
            return DRONE_WINCH_ACTION_SIZE if self.winch else DRONE_ACTION_SIZE
        return WINCH_ACTION.size if self.winch else ACTION_SIZE

    @property
    def action_space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (self.action_size,), np.float32)

    @cached_property
    def action_params(self) -> np.ndarray:
        """The nominal scene's action constants (:func:`action_params`, :func:`drone_action_params`)."""
        if self.drone:
            return drone_action_params(self.scene, self.actuation)
        return action_params(self.hover, self.force_limit, self.torque_limit, self.scene.winch.max_speed)

    @cached_property
    def nominal_episode(self) -> Episode:
        return Episode(np.array([nominal_values(self.scene)[k] for k in episode_param_names(self.scene)]), self.scene,
                       build_params(self.scene), self.substeps, self.task_params, self.action_params)

    def episode_for(self, scene: Scene) -> Episode:
        """The run-time physics of an episode of ``scene`` (its own h, which divides the control
        period; the hover force holds its weight up): e.g. the current one, ``env.scene``."""
        substeps = int(round(self.control_period / scene.h))
        if substeps < 1 or abs(substeps * scene.h - self.control_period) > 1e-9 * self.control_period:
            raise ValueError(f"scene {scene.name!r}: h = {scene.h} s does not divide the control period "
                             f"{self.control_period} s")
        nominal = nominal_values(scene)
        values = np.array([nominal[k] for k in episode_param_names(scene)])
        hover = np.array([0.0, 0.0, -total_weight(scene)])
        ap = (drone_action_params(scene, self.actuation) if self.drone
              else action_params(hover, self.force_limit, self.torque_limit, scene.winch.max_speed))
        return Episode(values, scene, build_params(scene), substeps, self.task.params(scene), ap)

    def draw_episode(self, rng: np.random.Generator) -> Episode:
        """The next episode's physics: the nominal one, or (``randomizer``) one drawn from
        ``rng`` with its own h (the largest dividing the control period under the scheme's bound,
        as for the nominal scene; or ``fixed_h``)."""
        if self.randomizer is None:
            return self.nominal_episode
        values = self.randomizer.draw(rng)
        drawn = self.randomizer.scene(values)
        steps_for = shortest(drawn) if self.winch else drawn
        substeps = self.substeps if self.fixed_h is not None else scheme_substeps(steps_for, self.control_period,
                                                                                  self.safety)
        episode = self.episode_for(drawn.model_copy(update={"h": self.control_period / substeps}))
        return dataclasses.replace(episode, values=values)


def make_setup(scene: Union[str, Path, Scene] = "drone_load", *, task: str = "stabilize",
               control_period: float = 0.02, h: Optional[float] = None, safety: Optional[float] = None,
               force_limit: Optional[float] = None, torque_limit: float = 0.02,
               scene_overrides: Optional[dict] = None, randomize: Union[bool, dict, None] = None,
               observation: Optional[str] = None, sensor_noise: Union[float, dict, None] = None,
               action_latency: Optional[int] = None, wind: Union[float, dict, None] = None,
               preset: Optional[str] = None, winch: Optional[bool] = None,
               actuation: Optional[str] = None, thrust_noise: Optional[float] = None,
               moving_target: Optional[bool] = None) -> EnvSetup:
    """Resolve the environment's arguments (see :class:`~esp_gym.pendulum.env.ElasticStringPendulumEnv`),
    validated by :class:`~esp_gym.pendulum.options.EnvOptions` (ValueError naming each bad one), in stages:
    the options with the preset's (:func:`preset_options`), the scene with its overrides
    (:func:`resolve_scene`), the rig's checks (:func:`check_rig`), the physics steps
    (:func:`physics_steps`), then the action's scale."""
    o, given = preset_options(scene=scene, task=task, control_period=control_period, h=h, safety=safety,
                              force_limit=force_limit, torque_limit=torque_limit, scene_overrides=scene_overrides,
                              randomize=randomize, observation=observation, sensor_noise=sensor_noise,
                              action_latency=action_latency, wind=wind, preset=preset, winch=winch,
                              actuation=actuation, thrust_noise=thrust_noise, moving_target=moving_target)
    resolved, keep_unstable = resolve_scene(o)
    t = get_task(o.task, o.moving_target)
    winch = t.needs_winch if o.winch is None else o.winch
    actuation = o.actuation or ("thrust_rates" if resolved.pivot.is_drone else "force")
    check_rig(resolved, o, t, winch, actuation, given)
    randomizer = None if o.randomize is False else Randomizer(resolved, o.randomize)
    check_hanging(resolved, t, randomizer)
    if resolved.pivot.is_drone:
        check_lift(resolved, randomizer)
    resolved, randomizer, safety, substeps = physics_steps(resolved, o, randomizer, winch, keep_unstable)
    weight = total_weight(resolved)
    force_limit = o.force_limit if o.force_limit is not None else (0.6 * weight if weight > 0 else 1.0)
    if weight > 0 and force_limit > MAX_FORCE_SHARE * weight:
        raise ValueError(f"ElasticStringPendulum-v0: force_limit = {force_limit:g} N is {force_limit / weight:.3g} "
                         f"times the rig's weight {weight:.4g} N, above the {MAX_FORCE_SHARE:g} times a pivot can push")
    wind_given = wind_options(o.wind)
    if wind_given is not None:
        drag_areas(resolved)  # the load needs a shape (a randomised episode keeps its kind)
    return EnvSetup(scene=resolved, task=t, task_params=t.params(resolved), control_period=float(o.control_period),
                    substeps=substeps, hover=np.array([0.0, 0.0, -weight]), force_limit=float(force_limit),
                    torque_limit=float(o.torque_limit), safety=float(safety), fixed_h=o.h, randomizer=randomizer,
                    observer=Observer(o.observation, o.sensor_noise, winch, actuation != "force"),
                    action_latency=o.action_latency,
                    wind=None if wind_given is None else Wind(wind_given, o.control_period),
                    winch=winch, actuation=actuation,
                    thrust_noise=float(o.thrust_noise) if resolved.pivot.is_drone else 0.0)


#: make_setup's arguments that a preset may set: the value given wins over the preset's.
PRESET_SETS = ("randomize", "observation", "sensor_noise", "action_latency", "wind", "thrust_noise", "moving_target")


def preset_options(**arguments) -> tuple:
    """``(EnvOptions, the arguments of PRESET_SETS given)``: the options a preset sets take, in
    this order, the value given (None: not given), the preset's (with its task's), EnvOptions'
    default."""
    given = {name: value for name in PRESET_SETS if (value := arguments.pop(name, None)) is not None}
    o = env_options(**arguments, **given)
    if o.preset is not None:
        preset = {**PRESETS[o.preset], **PRESET_TASK_OPTIONS[o.preset].get(o.task, {})}
        o = o.model_copy(update={name: value for name, value in preset.items() if name not in given})
    return o, given


def resolve_scene(o) -> tuple:
    """``(the scene with its overrides, whether it allows an unstable h)``; its own h is replaced
    later (:func:`physics_steps`), so it must not fail the bound of a stiffer override."""
    overrides = dict(o.scene_overrides or {})
    base = o.scene if isinstance(o.scene, Scene) else load_scene(o.scene)
    keep_unstable = overrides.get("allow_unstable_h", base.allow_unstable_h)
    overrides["allow_unstable_h"] = True
    # a Scene object takes the same overrides as a file (aliases, dotted paths, merged sections)
    resolved = override_scene(o.scene, overrides) if isinstance(o.scene, Scene) else load_scene(o.scene, **overrides)
    return resolved, keep_unstable


def check_rig(resolved: Scene, o, t: Task, winch: bool, actuation: str, given: dict) -> None:
    """ValueError, naming what asked for it, unless the scene's pivot moves, the actuation flies
    it, the rig exists (esp_gym/physics/rig.py) and the task gets the winch it needs."""
    if not resolved.pivot.is_free:
        raise ValueError(f"ElasticStringPendulum-v0 moves the pivot: scene {resolved.name!r} needs pivot.kind: free "
                         "or drone")
    if resolved.pivot.is_drone != (actuation != "force"):
        wanted = "one of " + ", ".join(map(repr, ACTUATIONS)) if resolved.pivot.is_drone else "'force'"
        raise ValueError(f"ElasticStringPendulum-v0: actuation={actuation!r} does not fly scene {resolved.name!r}'s "
                         f"{resolved.pivot.kind} pivot: it takes {wanted}")
    if "thrust_noise" in given and given["thrust_noise"] != 0 and not resolved.pivot.is_drone:
        raise ValueError(f"ElasticStringPendulum-v0: thrust_noise={given['thrust_noise']!r} is a drone's rotors' noise: "
                         f"scene {resolved.name!r}'s pivot is {resolved.pivot.kind!r}")
    scene_rig(resolved, winch)
    if resolved.pivot.is_drone and resolved.solver.order != 2:
        raise ValueError(f"ElasticStringPendulum-v0: a drone at the pivot flies the explicit string of order 2 "
                         f"(scene {resolved.name!r}: solver.order {resolved.solver.order})")
    if t.needs_winch and not winch:
        raise ValueError(f"ElasticStringPendulum-v0: task={o.task!r} reels the string: it needs winch=True")


def physics_steps(resolved: Scene, o, randomizer, winch: bool, keep_unstable: bool) -> tuple:
    """``(the scene at its h, the randomizer, safety, physics steps per control step)``: with
    ``elements: auto`` the resolution rule's N (docs/physics.md, "The string's resolution"), then
    the steps that keep the stiffest episode (and the winch's shortest string) within ``safety`` x
    its stability bound, or the user's ``h`` (which must divide the control period)."""
    control_period, h, safety = o.control_period, o.h, o.safety
    if resolved.string.auto and resolved.solver.string == "explicit":
        # N for the nominal scene (every episode keeps the arrays' shape) at the longest string a
        # winch pays out, each episode's step for its own draw (EnvSetup.draw_episode, scheme_substeps)
        elements = auto_elements(longest(resolved) if winch else resolved)
        if elements != resolved.string.elements:
            resolved = resolved.model_copy(update={"string": resolved.string.model_copy(update={"elements": elements})})
            randomizer = None if randomizer is None else Randomizer(resolved, o.randomize)
        safety = resolution_safety(resolved, control_period) if safety is None else safety
    safety = 0.5 if safety is None else safety
    # the scene's scheme (explicit unless asked): choose_scheme's cost rule would pick the implicit
    # string for stiff strings, but its accuracy under random actions is not established yet
    # (docs/physics.md, "The environment's choice")
    explicit = resolved.solver.string == "explicit"
    bound_name = f"safety = {safety} x the stability bound" if explicit else "the transverse bound"
    # the stiffest episodes (shortest, lightest, stiffest string; light or heavy ends) need the most steps
    stiffest = [resolved] if randomizer is None else [randomizer.scene(v) for v in randomizer.stiffest()]
    if winch:  # and the shortest string the winch reaches
        stiffest = [shortest(scene) for scene in stiffest]
    if h is None:
        wanted, what = max(scheme_substeps(scene, control_period, safety) for scene in stiffest), bound_name
    else:
        wanted, what = control_period / h, f"h = {h} s"
        bound = min(scene.stability_bound for scene in stiffest)
        if (randomizer is not None or winch) and explicit and not keep_unstable and h > bound:
            raise ValueError(f"h = {h} s is above the stability bound {bound:.4g} s of the stiffest string of the "
                             "randomize ranges (shortest, lightest, largest EA, lightest ends) and the winch's "
                             "shortest: leave h to the environment, narrow the ranges or raise winch.min_length")
    check_substeps("ElasticStringPendulum-v0", control_period, what, wanted,
                   "use a larger h or safety, a shorter control_period, or a softer, longer or coarser string")
    if h is None:
        substeps = scheme_substeps(shortest(resolved) if winch else resolved, control_period, safety)
    else:
        substeps = int(round(wanted))
        if substeps < 1 or abs(substeps * h - control_period) > 1e-9 * control_period:
            raise ValueError(f"h = {h} s must divide the control period {control_period} s")
        if rate_loop_substeps(resolved, control_period, substeps) != substeps:
            raise ValueError(f"h = {h} s must divide the drone's rate-loop period "
                             f"(pivot.drone.rate_loop_period {resolved.pivot.drone.rate_loop_period:g} s)")
    resolved = scene_from_dict({**resolved.model_dump(), "h": control_period / substeps,
                                "allow_unstable_h": keep_unstable}, source=repr(resolved.name))
    return resolved, randomizer, safety, substeps
