"""What a Rerun recording holds: the entity paths, the scalar series and where each takes its
values in a sample row (kernels/env/recording.py ``sample_layout``), the default blueprint, the string's
colour scale and the body's shape archetype. The writing is recorder.py's; the entities, their
units and frames are listed in esp_gym/viz/recording.py.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..kernels.env.arrays import ACTION, REWARD_TERMS, SENSORS
from ..kernels.layout import DIAG
from ..kernels.step.disturbance import DISTURBANCE
from ..kernels.env.recording import (SB_ENERGY_RESIDUAL, SB_PI3_RESIDUAL, SB_WORK, SW_REEL_SPEED, SW_UNSTRETCHED_LENGTH,
                                     SW_WINCH_WORK)
from . import palette
from .geometry import equivalent_box, prism_triangles, quaternion_xyzw

# -- entity paths ---------------------------------------------------------------------------------

WORLD = "/world"
STRING = "/world/string"
BODY = "/world/body"
BODY_SHAPE = "/world/body/shape"
BODY_COM = "/world/body/center_of_mass"
BODY_TORQUE = "/world/body/torque"
PIVOT = "/world/pivot"
PIVOT_FORCE = "/world/pivot_force"
LOAD_TRAIL = "/world/load_trail"
TARGET_PIVOT = "/world/targets/pivot"
TARGET_LOAD = "/world/targets/load"
#: Env rollouts: arrows of the wind (at the load), the push (at the load) and the hook tension
#: (at the pivot).
WIND = "/world/wind"
PUSH = "/world/push"
HOOK_TENSION = "/world/hook_tension"
NEWTON = "/diag/newton_iterations"
RETURN = "/rl/return"
#: Env rollouts: the series of the wind [m/s], the hook tension, the push and the drag [N].
ENV_WIND = "/env/wind"
ENV_HOOK_TENSION = "/env/hook_tension"
ENV_PUSH = "/env/push"
ENV_DRAG = "/env/drag"
#: With a winch: the unstretched length [m], the reel speed [m/s] and the winch's work [J].
WINCH_LENGTH = "/winch/unstretched_length"
WINCH_SPEED = "/winch/reel_speed"
WINCH_WORK = "/winch/work"
#: With a drone at the pivot: its frame (a transform at the pivot, turned by R_q), its arms and
#: rotors drawn in it, and the series of its body rates [rad/s] and rotor speeds [rad/s].
DRONE = "/world/drone"
DRONE_FRAME = "/world/drone/frame"
DRONE_RATES = "/drone/rates"
DRONE_ROTORS = "/drone/rotor_speeds"

ENERGY_PARTS = ("kinetic_string", "kinetic_body", "kinetic_pivot", "potential_gravity", "potential_elastic")
ACTION_NAMES = ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z")


class Series(NamedTuple):
    """Named scalar series sharing one entity: the names, their sources (a field of
    :func:`~esp_gym.kernels.env.recording.sample_layout` and an offset in it), colours, whether only
    samples after a step have values (not resets), whether only env rollouts have them, whether
    only recordings with a winch have them."""

    names: tuple
    sources: tuple
    colors: list
    stepped_only: bool = False
    env_only: bool = False
    winch_only: bool = False


def _diag(*names) -> tuple:
    return tuple(("diag", DIAG.scalar(name)) for name in names)


def _field(field: str, offsets=(0,)) -> tuple:
    return tuple((field, k) for k in offsets)


def _axes(field: str, layout, name: str, axes: str = "xyz") -> tuple:
    """(names, sources) of the components ``axes`` of the 3-vector ``name`` of ``layout``, held
    in the sample's ``field``: the series ``name_x``, ..."""
    start = layout.start(name)
    return tuple(f"{name}_{a}" for a in axes), _field(field, [start + "xyz".index(a) for a in axes])


TAB10, BLACK = palette.TAB10, palette.BLACK
_LOAD_DRAG = _axes("disturbance", DISTURBANCE, "load_drag")
_LINE_DRAG = _axes("disturbance", DISTURBANCE, "line_drag")
#: The scalar series by entity. Related series share an entity (one Scalars batch per sample,
#: a named line each): every entity costs a row id and two time values per sample; grouping
#: the energy parts, reward terms and actions (27 -> 11 scalar entities) cut an env recording
#: from 1.1 to 0.8 kB per step, and Rerun's encoding work with it.
SCALARS = {
    "/diag/energy/total": Series(("total",), _diag("energy"), [BLACK]),
    "/diag/energy/parts": Series(ENERGY_PARTS + ("work",), _diag(*ENERGY_PARTS) + _field("balances", [SB_WORK]),
                                 TAB10[:6]),
    "/diag/energy_residual": Series(("E - E0 - W",), _field("balances", [SB_ENERGY_RESIDUAL]), [TAB10[3]]),
    "/diag/pi3": Series(("pi3",), _diag("pi3"), [TAB10[0]]),
    "/diag/pi3_residual": Series(("pi3 - pi3_0 - angular impulse",), _field("balances", [SB_PI3_RESIDUAL]),
                                 [TAB10[3]]),
    "/diag/orthogonality": Series(("||I - R^T R||_F",), _diag("orthogonality"), [TAB10[7]]),
    "/diag/stretched_length": Series(("stretched length",), _diag("stretched_length"), [TAB10[2]]),
    NEWTON: Series(("Newton iterations / step",), _field("newton"), [TAB10[7]], True),
    "/rl/reward/total": Series(("reward",), _field("reward"), [BLACK], True, True),
    "/rl/reward/terms": Series(REWARD_TERMS, _field("terms", range(len(REWARD_TERMS))), TAB10[:6], True, True),
    "/rl/action": Series(ACTION_NAMES, _field("action", range(ACTION.size)), TAB10[:6], True, True),
    # the wind and forces of the last step (at a reset: the episode's start), spatial frame
    ENV_WIND: Series(*_axes("disturbance", DISTURBANCE, "wind"), TAB10[:3], env_only=True),
    ENV_HOOK_TENSION: Series(*_axes("sensors", SENSORS, "hook_tension"), TAB10[:3], env_only=True),
    ENV_PUSH: Series(*_axes("disturbance", DISTURBANCE, "push", "xy"), TAB10[:2], env_only=True),  # horizontal
    ENV_DRAG: Series(_LOAD_DRAG[0] + _LINE_DRAG[0], _LOAD_DRAG[1] + _LINE_DRAG[1], TAB10[:6], env_only=True),
    WINCH_LENGTH: Series(("unstretched length",), _field("winch", [SW_UNSTRETCHED_LENGTH]), [TAB10[2]],
                         winch_only=True),
    WINCH_SPEED: Series(("reel speed",), _field("winch", [SW_REEL_SPEED]), [TAB10[0]], winch_only=True),
    WINCH_WORK: Series(("winch work",), _field("winch", [SW_WINCH_WORK]), [TAB10[1]], winch_only=True),
}


#: A drone's action by actuation: the names of its four entries (the action series' names).
DRONE_ACTION_NAMES = {"thrust_rates": ("thrust", "rate_x", "rate_y", "rate_z"),
                      "thrust_torque": ("thrust", "torque_x", "torque_y", "torque_z"),
                      "motors": ("motor_1", "motor_2", "motor_3", "motor_4")}


def scalar_series(actuation: str = "force") -> dict:
    """:data:`SCALARS`, with a drone's four action entries named for its ``actuation`` in place
    of the pivot force's and body torque's six."""
    if actuation == "force":
        return SCALARS
    names = DRONE_ACTION_NAMES[actuation]
    return {**SCALARS, "/rl/action": Series(names, _field("action", range(len(names))), TAB10[:len(names)], True,
                                            True)}


def drone_frame(rotors: np.ndarray) -> rr.LineStrips3D:
    """The drone in its body frame: an arm from the centre to each rotor at ``rotors`` (4, 3) [m],
    and a ring around each, a third of the arm across."""
    rotors = np.asarray(rotors, dtype=float)
    arm = float(np.linalg.norm(rotors[0]))
    angle = np.linspace(0.0, 2.0 * np.pi, 17)
    ring = 0.35 * arm * np.column_stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)])
    strips = [np.array([np.zeros(3), r]) for r in rotors] + [r + ring for r in rotors]
    return rr.LineStrips3D(strips, radii=0.004, colors=[palette.PIVOT])


#: The 3-D view's eye: this many rig lengths from the rig's middle, looking at it from the front,
#: the right and above (z down), so the pivot, a drone on it, and the load are all in view.
EYE_DISTANCE = 2.5
EYE_DIRECTION = np.array([1.0, -1.0, -0.6]) / np.linalg.norm([1.0, -1.0, -0.6])


def rig_eye(scene):
    """``(position, look_target)`` [m] of the 3-D view's eye for ``scene``: it looks at the middle
    of the hanging rig, from the pivot down to the load's centre of mass at rest, from
    :data:`EYE_DISTANCE` times the rig's length (at least 1 m) along :data:`EYE_DIRECTION`."""
    from ..pendulum.tasks import hanging_depth

    depth = hanging_depth(scene)
    target = np.asarray(scene.pivot.position, dtype=float) + np.array([0.0, 0.0, 0.5 * depth])
    return target + EYE_DISTANCE * max(depth, 1.0) * EYE_DIRECTION, target


def default_blueprint(env: bool, winch: bool = False, drone: bool = False, eye=None) -> rrb.Blueprint:
    """The 3-D view beside the diagnostics (and, for env rollouts, reward and action, and wind
    and forces; with a winch, its length, speed and work; with a drone, its rates and rotor
    speeds) panels; ``eye``: the 3-D view's ``(position, look_target)`` (:func:`rig_eye`; None:
    Rerun's own choice, which can leave the pivot out of the web viewer's first frame)."""
    ts = rrb.TimeSeriesView
    panels = [
        ts(origin="/diag/energy", name="energy [J]"),
        rrb.Tabs(ts(origin="/diag/energy_residual", name="E - E0 - W [J]"),
                 ts(origin="/diag/pi3_residual", name="pi3 - pi3_0 - impulse [kg m2/s]"),
                 ts(origin="/diag/pi3", name="pi3 [kg m2/s]")),
        rrb.Tabs(ts(origin="/diag/stretched_length", name="stretched length [m]"),
                 ts(origin="/diag/orthogonality", name="||I - R^T R||"),
                 ts(origin=NEWTON, name="Newton iterations / step")),
    ]
    if env:
        panels.append(rrb.Tabs(ts(origin="/rl/reward", name="reward"), ts(origin="/rl/action", name="action"),
                               ts(origin=RETURN, name="return")))
        panels.append(rrb.Tabs(ts(origin=ENV_WIND, name="wind [m/s]"),
                               ts(origin=ENV_HOOK_TENSION, name="hook tension [N]"),
                               ts(origin=ENV_PUSH, name="push [N]"), ts(origin=ENV_DRAG, name="drag [N]")))
    if drone:
        panels.append(rrb.Tabs(ts(origin=DRONE_RATES, name="drone rates [rad/s]"),
                               ts(origin=DRONE_ROTORS, name="rotor speeds [rad/s]")))
    if winch:
        panels.append(rrb.Tabs(ts(origin=WINCH_LENGTH, name="unstretched length [m]"),
                               ts(origin=WINCH_SPEED, name="reel speed [m/s]"),
                               ts(origin=WINCH_WORK, name="winch work [J]")))
    controls = None if eye is None else rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=eye[0],
                                                          look_target=eye[1], eye_up=[0.0, 0.0, -1.0])
    view = rrb.Spatial3DView(origin=WORLD, name="3-D", eye_controls=controls)
    return rrb.Blueprint(rrb.Horizontal(view, rrb.Vertical(*panels), column_shares=[3, 2]), collapse_panels=True)


def default_strain_scale(scene) -> float:
    """Strain-energy scale [J] of the string colours: 2.5x the static tension at the top,
    T0 = g (M + mu l), in one element: (2.5 T0)^2 u / (2 EA); the hanging string sits at 40 %
    of the colour ramp (as the rgb_array renderer's default for drone_load)."""
    st = scene.string
    T0 = scene.gravity * (scene.body.mass + st.mass_per_length * st.length)
    e = (2.5 * T0) ** 2 * st.u / (2.0 * st.EA)
    return float(e) if e > 0 else 1.0


def body_shape(body, rho: np.ndarray):
    """The Rerun archetype of the body's shape centred on ``rho`` (body frame [m]): box, sphere,
    a mesh for the cylinders; without a shape the box of the same mass and inertia about the
    centre of mass (a small sphere if there is none)."""
    shape, color = body.shape, [palette.BODY]
    kind = getattr(shape, "kind", None)
    if kind == "box":
        return rr.Boxes3D(centers=[rho], half_sizes=[0.5 * np.asarray(shape.size)], colors=color, fill_mode="solid")
    if kind == "sphere":
        return rr.Ellipsoids3D(centers=[rho], half_sizes=[[shape.radius] * 3], colors=color, fill_mode="solid")
    if kind in ("cylinder", "elliptic_cylinder"):
        a, b = (shape.radius, shape.radius) if kind == "cylinder" else shape.semi_axes
        v, t, nrm = prism_triangles(a, b, shape.height)
        return rr.Mesh3D(vertex_positions=v + rho, triangle_indices=t, vertex_normals=nrm, albedo_factor=palette.BODY)
    eq = equivalent_box(body.mass, body.J, rho)
    if eq is None:
        return rr.Ellipsoids3D(centers=[rho], half_sizes=[[0.03] * 3], colors=color, fill_mode="solid")
    half, Q = eq
    return rr.Boxes3D(centers=[rho], half_sizes=[half], colors=color, fill_mode="solid",
                      quaternions=[rr.Quaternion(xyzw=quaternion_xyzw(Q))], labels=["inertia-equivalent box"])
