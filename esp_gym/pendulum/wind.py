"""Wind and pushes of ElasticStringPendulum-v0 (``wind=``): the options, each episode's
DISTURBANCE_PARAMS, and the random numbers the compiled step reads (kernels/step/disturbance.py;
docs/environment.md, "Wind and pushes"; docs/physics.md for how the forces enter).

``wind`` is 0.0 (still air, no pushes: the plain kernels), a mean wind speed [m/s] (gusts of
0.2 x that, no pushes), or a mapping of :class:`WindOptions` fields. The mean wind is
horizontal, from the azimuth ``direction`` or from one drawn per episode; gusts are an
Ornstein-Uhlenbeck process per axis (the Dryden model's first-order form), started from its
stationary law; pushes are Poisson events, each a horizontal force on the load held for one
control step, of a random azimuth and a size that changes the load's velocity by 0.5-1.5 x
``push_speed``.

Every random number comes from the environment's ``np_random``, after the episode's state: the
mean wind's azimuth (if drawn), the initial gust, then :data:`BLOCK` control steps of DRAWS at a
time (another block when those are used up), so seeded episodes repeat bit for bit.
"""
from __future__ import annotations

import math
from typing import Any, Mapping, NamedTuple, Optional, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..kernels.step.disturbance import DISTURBANCE, DISTURBANCE_PARAMS, DRAWS
from ..scene.params import Box, Cylinder, EllipticCylinder, Scene, Sphere
from ..scene.scene_input import Real
from .options import validation_message

# the fields a reset writes, resolved once (a reset is on the hot path of short episodes)
_DP_MEAN_WIND, _DP_LINE_DRAG, _DP_LOAD_FACES, _DP_LOAD_SIDE, _DP_LOAD_SEMI_AXES, _DP_LOAD_ROUND, _DP_PUSH_FORCE = (
    DISTURBANCE_PARAMS[name] for name in ("mean_wind", "line_drag", "load_faces", "load_side", "load_semi_axes",
                                          "load_round", "push_force"))
_DS_GUST, _DS_WIND = DISTURBANCE["gust"], DISTURBANCE["wind"]

#: Control steps of random draws taken from np_random at a time.
BLOCK = 256
#: The reset info's wind entries (besides SCENE_PARAMS): the mean wind's speed [m/s] and azimuth
#: [rad] from +x towards +y.
WIND_INFO = ("wind_speed", "wind_direction")
#: Density of the line's material when its diameter is derived from its mass per length [kg/m^3]
#: (nylon, polyester and rubber are 1100-1400).
LINE_DENSITY = 1150.0
#: Gusts' standard deviation per axis as a share of the mean speed when only a speed is given
#: (a turbulence intensity; 0.1-0.2 near the ground).
TURBULENCE_INTENSITY = 0.2
#: Upper bounds of the options (SI): a wind, gust or push speed past 100 m/s (above any
#: hurricane's), a fluid denser than water, a drag coefficient past 10, a line thicker than 1 m or
#: a gust memory past 1e4 s describes no flight, and 1e4 pushes per second is a statistics test's;
#: they also keep every force finite.
MAX_SPEED, MAX_DENSITY, MAX_DRAG, MAX_DIAMETER, MAX_RATE, MAX_TIME = 100.0, 1000.0, 10.0, 1.0, 1e4, 1e4


class WindOptions(BaseModel):
    """The fields of a ``wind`` mapping (SI units)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    speed: Real = Field(0.0, ge=0, le=MAX_SPEED, allow_inf_nan=False, description="mean horizontal wind [m/s]")
    direction: Optional[Real] = Field(None, allow_inf_nan=False,
                                      description="azimuth the wind blows towards [rad]; None: drawn per episode")
    gust_std: Optional[Real] = Field(None, ge=0, le=MAX_SPEED, allow_inf_nan=False,
                                     description="gusts' standard deviation per axis [m/s]; None: 0.2 x speed")
    gust_time: Real = Field(1.0, gt=0, le=MAX_TIME, allow_inf_nan=False, description="gusts' correlation time [s]")
    air_density: Real = Field(1.225, gt=0, le=MAX_DENSITY, allow_inf_nan=False, description="[kg/m^3]")
    load_drag_coefficient: Real = Field(1.05, ge=0, le=MAX_DRAG, allow_inf_nan=False, description="C_d of the load")
    line_drag_coefficient: Real = Field(1.2, ge=0, le=MAX_DRAG, allow_inf_nan=False,
                                        description="C_d of the line in cross-flow")
    line_diameter: Optional[Real] = Field(None, gt=0, le=MAX_DIAMETER, allow_inf_nan=False,
                                          description="[m]; None: from the mass per length at 1150 kg/m^3")
    push_rate: Real = Field(0.0, ge=0, le=MAX_RATE, allow_inf_nan=False, description="pushes per second (Poisson)")
    push_speed: Real = Field(0.5, ge=0, le=MAX_SPEED, allow_inf_nan=False,
                             description="a push's mean velocity change [m/s]")

    @property
    def gusts(self) -> float:
        return TURBULENCE_INTENSITY * self.speed if self.gust_std is None else self.gust_std

    @property
    def active(self) -> bool:
        return self.speed > 0 or self.gusts > 0 or (self.push_rate > 0 and self.push_speed > 0)


def wind_options(value: Union[float, Mapping[str, Any], None]) -> Optional[WindOptions]:
    """The options of ``wind=`` (None: no wind and no pushes); ValueError naming a bad one."""
    if value is None:
        return None
    try:
        if isinstance(value, Mapping):
            options = WindOptions(**value)
        elif isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise ValueError(f"wind must be a speed [m/s] or a mapping of {list(WindOptions.model_fields)}, "
                             f"got {value!r}")
        else:
            options = WindOptions(speed=value)
    except ValidationError as e:
        raise ValueError(validation_message(e, "wind")) from None
    return options if options.active else None


class DragAreas(NamedTuple):
    """The load's projected-area law (:func:`drag_areas`)."""

    faces: np.ndarray  # (3,) [m^2]
    side: float  # [m]
    semi_axes: tuple  # (a, b) [m]
    round: float  # [m^2]


def drag_areas(scene: Scene) -> DragAreas:
    """The load's projected-area law across a unit direction n (body frame) [m^2, m]:
    ``faces . |n| + side sqrt(a^2 n_y^2 + b^2 n_x^2) + round`` (DISTURBANCE_PARAMS), exact for
    each shape (a convex body's projected area is half its surface's integral of |n . dA|).
    """
    shape = scene.body.shape
    faces, side, axes, round_ = np.zeros(3), 0.0, (0.0, 0.0), 0.0
    if isinstance(shape, Box):
        x, y, z = shape.size
        faces[:] = (y * z, x * z, x * y)
    elif isinstance(shape, (Cylinder, EllipticCylinder)):
        a, b = (shape.radius, shape.radius) if isinstance(shape, Cylinder) else shape.semi_axes
        faces[2], side, axes = math.pi * a * b, 2.0 * shape.height, (a, b)
    elif isinstance(shape, Sphere):
        round_ = math.pi * shape.radius ** 2
    else:
        raise ValueError(f"wind needs the load's shape for its drag area; scene {scene.name!r} gives only its "
                         f"inertia (set body.shape)")
    return DragAreas(faces, side, axes, round_)


class Wind:
    """The wind and pushes of an environment: ``options`` (:class:`WindOptions`) and the control
    period [s]."""

    def __init__(self, options: WindOptions, control_period: float):
        self.options = options
        self.control_period = float(control_period)
        # the episode's constants that depend on the options alone (a reset fills in the rest)
        o = options
        template = np.zeros(DISTURBANCE_PARAMS.size)
        decay = math.exp(-self.control_period / o.gust_time)
        template[DISTURBANCE_PARAMS["gust_decay"]] = decay
        template[DISTURBANCE_PARAMS["gust_innovation"]] = o.gusts * math.sqrt(1.0 - decay * decay)
        template[DISTURBANCE_PARAMS["push_chance"]] = -math.expm1(-o.push_rate * self.control_period)
        self._template = template
        self._half_rho = 0.5 * o.air_density

    def episode(self, scene: Scene, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
        """One episode's (DISTURBANCE_PARAMS, initial DISTURBANCE state, the first block of
        DRAWS, the reset info's wind entries) for ``scene``, drawn from ``rng``."""
        o = self.options
        azimuth = o.direction if o.direction is not None else 2.0 * math.pi * rng.random()
        dp = self._template.copy()
        mean = (o.speed * math.cos(azimuth), o.speed * math.sin(azimuth), 0.0)
        dp[_DP_MEAN_WIND] = mean
        diameter = o.line_diameter or math.sqrt(4.0 * scene.string.mass_per_length / (math.pi * LINE_DENSITY))
        dp[_DP_LINE_DRAG] = self._half_rho * o.line_drag_coefficient * diameter
        faces, side, semi_axes, round_ = drag_areas(scene)
        k = self._half_rho * o.load_drag_coefficient
        dp[_DP_LOAD_FACES] = k * faces
        dp[_DP_LOAD_SIDE] = k * side
        dp[_DP_LOAD_SEMI_AXES] = semi_axes
        dp[_DP_LOAD_ROUND] = k * round_
        dp[_DP_PUSH_FORCE] = scene.body.mass * o.push_speed / self.control_period
        ds = np.zeros(DISTURBANCE.size)
        gust = o.gusts * rng.standard_normal(3)  # the stationary law
        ds[_DS_GUST] = gust
        ds[_DS_WIND] = dp[_DP_MEAN_WIND] + gust
        return dp, ds, self.draws(rng), {"wind_speed": float(o.speed), "wind_direction": float(azimuth)}

    @staticmethod
    def draws(rng: np.random.Generator) -> np.ndarray:
        """:data:`BLOCK` control steps of DRAWS from ``rng``: gust normals, then the uniforms."""
        out = np.empty((BLOCK, DRAWS.size))
        out[:, DRAWS["gust"]] = rng.standard_normal((BLOCK, 3))
        out[:, DRAWS.scalar("push_chance"):] = rng.random((BLOCK, 3))
        return out
