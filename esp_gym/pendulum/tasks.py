"""Tasks of ElasticStringPendulum-v0: targets, initial-state distributions and reward weights.

The reward itself is compiled (esp_gym/kernels/env/task_terms.py) so the single and the batched
environments share it; this module holds what varies per task, as small pure functions.
Every distance is in metres, spatial frame, gravity along +e3 (so "below" is +z).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..kernels.env.arrays import TARGET, TASK_PARAM_NAMES
from ..kernels.env.track_curve import reference_at, reference_path
from ..physics.state import State, cross3, legendre_momenta
from ..physics.watchdog import task_constants
from ..scene.params import Scene
from ..scene.stability import hat


@dataclass(frozen=True)
class Task:
    """Reward weights and scales, and the start/target distribution of one task.

    Each reward term is ``weight * 1/(1 + (x/scale)^2)`` (1 at x = 0, 1/2 at x = scale), the
    control term is ``-w_control * |a|^2 / 6``; so a step's reward lies in
    [-w_control, w_load_position + w_load_velocity + w_pivot_position + w_swing + w_spin].
    """

    name: str
    w_load_position: float = 0.35
    w_load_velocity: float = 0.2
    w_pivot_position: float = 0.2
    w_swing: float = 0.15
    w_spin: float = 0.1
    w_control: float = 0.1
    scale_position: float = 0.2  #: [m]
    scale_velocity: float = 0.5  #: [m/s]
    scale_swing: float = 0.2  #: [rad]
    scale_spin: float = 1.0  #: [rad/s]
    max_swing_deg: float = 30.0  #: stabilize: initial swing up to this angle [deg]
    max_speed: float = 0.3  #: initial speeds up to this, per axis [m/s]
    max_spin: float = 0.5  #: initial body rates up to this, per axis [rad/s]
    target_box: tuple = (0.0, 0.0, 0.0)  #: transport: pivot target uniform in +-box [m]
    max_stretch: float = 1.5  #: terminate when the stretched length exceeds this times l
    workspace_radius: float = 4.0  #: terminate when pivot or load is this far from its target [m]
    #: lift, lower: the load's target hangs from a string this many times l longer, uniform in the
    #: range (negative: shorter); the winch (``winch=True``) must reel it there
    reel_range: tuple = (0.0, 0.0)
    #: the targets move along a reference of the track family (:func:`track_reference`), the pivot
    #: starting at its start: ``track``, and ``lift`` with ``moving_target=True`` (the hard preset)
    moving: bool = False

    @property
    def needs_winch(self) -> bool:
        return self.reel_range != (0.0, 0.0)

    def params(self, scene: Scene) -> np.ndarray:
        """The compiled kernel's task parameter vector (TASK_PARAM_NAMES)."""
        values = dict(
            w_load_position=self.w_load_position, w_load_velocity=self.w_load_velocity,
            w_pivot_position=self.w_pivot_position, w_swing=self.w_swing, w_spin=self.w_spin,
            w_control=self.w_control, scale_position=self.scale_position,
            scale_velocity=self.scale_velocity, scale_swing=self.scale_swing, scale_spin=self.scale_spin,
            max_stretched_length=self.max_stretch * scene.string.length,
            workspace_radius=self.workspace_radius, string_length=scene.string.length,
            ground_depth=np.inf if scene.ground is None else scene.ground, energy_origin=0.0)
        values["energy_watchdog"], values["energy_bound"] = task_constants(scene)
        return np.array([values[k] for k in TASK_PARAM_NAMES], dtype=np.float64)

    @property
    def max_reward(self) -> float:
        return self.w_load_position + self.w_load_velocity + self.w_pivot_position + self.w_swing + self.w_spin


TASKS = {
    # bring a swinging load to rest below the pivot, pivot held at the origin
    "stabilize": Task("stabilize"),
    # carry a load hanging at rest to a random target with little swing
    "transport": Task("transport", max_swing_deg=3.0, max_speed=0.05, max_spin=0.1, target_box=(1.0, 1.0, 0.5),
                      w_load_position=0.45, w_load_velocity=0.1, w_swing=0.2, w_spin=0.05),
    # the load follows a moving reference (a circle or a figure-eight) from rest
    "track": Task("track", max_swing_deg=3.0, max_speed=0.05, max_spin=0.1, w_load_position=0.5,
                  w_load_velocity=0.15, w_pivot_position=0.15, w_swing=0.15, w_spin=0.05, moving=True),
    # hoist a load hanging at rest to a target 25-45 % of the string's length higher, the pivot
    # held where it is, with little swing (winch=True)
    "lift": Task("lift", max_swing_deg=3.0, max_speed=0.05, max_spin=0.1, w_load_position=0.45,
                 w_load_velocity=0.1, w_swing=0.2, w_spin=0.05, reel_range=(-0.45, -0.25)),
    # lower a load to a point 25-60 % of the string's length deeper, below a pivot that moves to
    # a random target (winch=True)
    "lower": Task("lower", max_swing_deg=3.0, max_speed=0.05, max_spin=0.1, target_box=(1.0, 1.0, 0.5),
                  w_load_position=0.45, w_load_velocity=0.1, w_swing=0.2, w_spin=0.05, reel_range=(0.25, 0.6)),
}

#: The ``track`` task's reference family (kernels/env/track_curve.py): each episode draws a circle or a
#: figure-eight (equally likely) of size ``a`` [m] and period [s] uniform in these ranges, either
#: sense, a uniform start angle and a uniform orientation about e3, centred on the origin.
TRACK_SIZE = (0.3, 1.0)
TRACK_PERIOD = (4.0, 10.0)


def track_reference(rng: np.random.Generator, depth: float) -> np.ndarray:
    """A ``track`` episode's TARGET at t = 0 (the load ``depth`` [m] below the pivot's target)."""
    t = np.zeros(TARGET.size)
    a = rng.uniform(*TRACK_SIZE)
    eight = rng.random() < 0.5
    t[TARGET["amplitude"]] = (a, 0.5 * a) if eight else (a, a)
    t[TARGET["harmonic"]] = 2.0 if eight else 1.0
    t[TARGET["phase"]] = (0.0, 0.0) if eight else (0.5 * math.pi, 0.0)
    t[TARGET["rate"]] = 2.0 * math.pi / rng.uniform(*TRACK_PERIOD) * (1.0 if rng.random() < 0.5 else -1.0)
    t[TARGET["start"]] = rng.uniform(0.0, 2.0 * math.pi)
    t[TARGET["orientation"]] = rng.uniform(0.0, 2.0 * math.pi)
    t[TARGET["depth"]] = depth
    reference_at(t, 0.0)
    return t


def track_path(target: np.ndarray, times) -> tuple:
    """The track reference of the TARGET vector ``target`` at each of ``times`` [s]: the pivot
    target's offset from the centre [m] and its velocity [m/s], (len(times), 3) each, spatial."""
    times = np.asarray(times, dtype=np.float64)
    offset, velocity = np.empty((len(times), 3)), np.empty((len(times), 3))
    reference_path(np.array(target, dtype=np.float64), times, offset, velocity)
    return offset, velocity


def reference_acceleration(target: np.ndarray, t: float) -> np.ndarray:
    """The acceleration [m/s^2] (spatial frame) of the reference TARGET ``target`` at time ``t``
    [s]: the second derivative of kernels/env/track_curve.py's curve, zero for a fixed target."""
    w, m = target[TARGET["rate"]][0], target[TARGET["harmonic"]][0]
    theta = target[TARGET["start"]][0] + w * t
    (ax, ay), (px, py) = target[TARGET["amplitude"]], target[TARGET["phase"]]
    x = -ax * w * w * math.sin(theta + px)
    y = -ay * m * m * w * w * math.sin(m * theta + py)
    alpha = target[TARGET["orientation"]][0]
    c, s = math.cos(alpha), math.sin(alpha)
    return np.array([c * x - s * y, s * x + c * y, 0.0])


#: The tasks whose targets may move (``moving_target=True``): track always does.
MOVABLE_TASKS = ("track", "lift")


def get_task(name: str, moving_target: bool = None) -> Task:
    """The task ``name``; ``moving_target`` True moves a movable task's targets (None: the task's own)."""
    if name not in TASKS:
        raise ValueError(f"unknown task {name!r}; choose one of {sorted(TASKS)}")
    task = TASKS[name]
    if moving_target is None or moving_target == task.moving:
        return task
    if name not in MOVABLE_TASKS or not moving_target:
        raise ValueError(f"moving_target={moving_target!r}: task {name!r} "
                         + ("always moves its targets" if task.moving else
                            f"has fixed targets; the targets of {MOVABLE_TASKS} move"))
    return dataclasses.replace(task, moving=True)


def static_node_depths(scene: Scene, length=None) -> np.ndarray:
    """Depth below the pivot [m] of each node of the string hanging at rest (N+1,), of the
    scene's unstretched length or ``length`` [m] (a winch's).

    Tension at unstretched arclength s is g (M + mu (l - s)); integrating the strain T/EA gives
    z(s) = s + g (M s + mu (l s - s^2/2)) / EA, exact at the nodes of linear elements.
    """
    st = scene.string
    l = st.length if length is None else float(length)
    s = np.linspace(0.0, l, st.elements + 1)
    M, mu, g = scene.body.mass, st.mass_per_length, scene.gravity
    return s + g * (M * s + mu * (l * s - 0.5 * s * s)) / st.EA


def hanging_depth(scene: Scene, length=None) -> float:
    """Depth of the load's centre of mass below the pivot at rest [m] (``length``: as
    :func:`static_node_depths`)."""
    return float(static_node_depths(scene, length)[-1] + np.linalg.norm(scene.body.rho_c))


def hanging_axis(rho_c) -> np.ndarray:
    """The body-frame unit vector that hangs straight down at rest: rho_c/|rho_c|, or the body
    z axis for a centred load (rho_c = 0)."""
    rho = np.asarray(rho_c, dtype=float)
    norm = float(np.linalg.norm(rho))
    return rho / norm if norm > 0 else np.array([0.0, 0.0, 1.0])


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector a to unit vector b (Rodrigues)."""
    v = cross3(a, b)
    c = float(a @ b)
    if c < -1.0 + 1e-12:  # opposite: rotate by pi about any axis perpendicular to a
        axis = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    vx = hat(v)
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the unit vector ``axis`` (Rodrigues)."""
    k = hat(axis)
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def sample_episode(task: Task, scene: Scene, rng: np.random.Generator):
    """Initial state and targets of one episode: ``(State, target (TARGET))``.

    The string starts straight, statically stretched, at a swing angle up to max_swing_deg in a
    random azimuth from the pivot; the body hangs with its centre of mass along the string
    (a centred load, rho_c = 0: its body z axis; random yaw about it); pivot and attachment velocities are uniform in +-max_speed per axis
    (the string's velocity interpolates between them), body rates uniform in +-max_spin.
    stabilize: targets are the origin for the pivot and the rest position below it for the load;
    the pivot starts within 0.1 m of the origin. transport: the pivot starts at the origin and
    its target is uniform in +-target_box. lift, lower: as transport (lift's pivot target is the
    origin), the load's target at the rest position of a string of a length drawn from
    ``reel_range`` (within the winch's range). track, and a moving lift: the reference is drawn
    first (:func:`track_reference`; a lift's load target at its reeled length's depth) and the
    pivot starts at its start, the system nearly at rest.
    """
    origin = np.zeros(3)
    box = np.asarray(task.target_box, dtype=float)
    pivot_target = rng.uniform(-box, box) if np.any(box) else origin.copy()
    start = rng.uniform(-0.1, 0.1, 3) if task.name == "stabilize" else origin.copy()
    target = np.zeros(TARGET.size)
    length = scene.string.length
    if task.needs_winch:  # within the winch's range
        shortest, longest = scene.winch_range
        length = min(max(length * (1.0 + rng.uniform(*task.reel_range)), shortest), longest)
    if task.moving:  # the pivot starts where the reference does
        target = track_reference(rng, hanging_depth(scene, length))
        start = target[TARGET["pivot"]].copy()
    else:
        target[TARGET["pivot"]] = pivot_target
        target[TARGET["load"]] = pivot_target + hanging_depth(scene, length) * np.array([0.0, 0.0, 1.0])
    theta = math.radians(task.max_swing_deg) * rng.uniform(0.0, 1.0)
    phi = rng.uniform(0.0, 2.0 * math.pi)
    d = np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])
    r = start + static_node_depths(scene)[:, None] * d
    # the centre of mass along the string; a centred load (rho_c = 0) has its body z axis there
    R = rotation_between(hanging_axis(scene.body.rho_c), d)
    R = _axis_rotation(d, rng.uniform(-math.pi, math.pi)) @ R
    v_pivot = rng.uniform(-task.max_speed, task.max_speed, 3)
    v_attach = rng.uniform(-task.max_speed, task.max_speed, 3)
    frac = np.linspace(0.0, 1.0, scene.string.elements + 1)[:, None]
    v = v_pivot + frac * (v_attach - v_pivot)
    Omega = rng.uniform(-task.max_spin, task.max_spin, 3)
    p, Pi = legendre_momenta(scene, r, v, R, Omega)
    return State(np.ascontiguousarray(r), p, np.ascontiguousarray(R), Pi, 0), target
