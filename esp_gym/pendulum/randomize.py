"""Per-episode randomisation of the tether and the load (``randomize=`` of ElasticStringPendulum-v0).

Each episode draws the physical parameters of :data:`~esp_gym.kernels.env.arrays.SCENE_PARAMS` from
the environment's ``np_random``, in that order, one uniform draw each (so a range that is a
single value leaves the stream of the others unchanged):

=========================  =====  ===========  ==========================================
name                        unit   draw         default range (of the nominal scene's value)
=========================  =====  ===========  ==========================================
``string_length``           m      uniform      x [0.75, 1.25]
``EA``                      N      log-uniform  x [0.5, 2]
``mass_per_length``         kg/m   log-uniform  x [0.5, 2]
``load_mass``               kg     log-uniform  x [0.5, 2]
``load_size_x, _y, _z``     m      uniform      x [0.75, 1.25] each (box loads only)
``attachment_offset_x, _y`` m      uniform      +- a quarter of the box's x, y size
``pivot_mass``              kg     log-uniform  x [0.5, 2]
=========================  =====  ===========  ==========================================

With a drone at the pivot, :data:`~esp_gym.kernels.env.arrays.DRONE_SCENE_PARAMS` follow, drawn
after the others (so the draws above are the same with and without a drone), each a scale of
the scene's value (1):

===========================  ===========  ==================================================
name                          draw         default range
===========================  ===========  ==================================================
``drone_inertia_scale``       log-uniform  [0.75, 4/3]: the drone's principal inertias
``rotor_coefficient_scale``   uniform      [0.9, 1.1]: k_f and k_m together
``motor_lag_scale``           log-uniform  [0.5, 2]: both motor time constants
===========================  ===========  ==================================================

A drone's ``pivot_mass`` ranges over x [0.8, 1.25] by default (a payload or a battery's
difference, not another drone), and the environment refuses ranges whose heaviest rig the
weakest rotors cannot lift with a margin (esp_gym/pendulum/env_setup.py, ``check_lift``).

The attachment offsets are rho_c's x and y (attachment point -> centre of mass, body frame);
rho_c's z scales with the box's height, so the attachment stays on the same face. A load given
by its inertia instead of a shape keeps its geometry: its inertia scales with its mass. N, the
law, the mass model, the pivot kind and the scheme stay the scene's: an episode changes
run-time values only, never a compiled kernel's types.

User ranges (``randomize={"EA": (1e3, 1e6), ...}``) are absolute, in the units above, and
replace the defaults of the names given; a pair (v, v) fixes a value. The extreme scenes of the
ranges are validated like any scene when the environment is made, with the attachment on the
box's face at the smallest box (the environment also checks that the load can hang:
esp_gym/pendulum/env_setup.py, ``check_hanging``). A range is a tuple, list or array (a set has no order).
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Optional, Union

import numpy as np

from ..kernels.env.arrays import DRONE_SCENE_PARAMS, SCENE_PARAMS
from ..scene.params import Box, Scene, scene_from_dict

#: The names drawn on a log scale (scale parameters); the others are uniform.
LOG_UNIFORM = frozenset({"EA", "mass_per_length", "load_mass", "pivot_mass", "drone_inertia_scale",
                         "motor_lag_scale"})
#: The drone's scales' default ranges.
DRONE_RANGES = {"drone_inertia_scale": (0.75, 4.0 / 3.0), "rotor_coefficient_scale": (0.9, 1.1),
                "motor_lag_scale": (0.5, 2.0)}


def episode_param_names(scene: Scene) -> tuple:
    """The names of an episode's parameters: SCENE_PARAMS, then DRONE_SCENE_PARAMS with a drone."""
    return SCENE_PARAMS.names + (DRONE_SCENE_PARAMS.names if scene.pivot.is_drone else ())
#: Names that may take values <= 0.
SIGNED = frozenset({"attachment_offset_x", "attachment_offset_y"})
#: Names that need a box-shaped load.
BOX_ONLY = frozenset({"load_size_x", "load_size_y", "load_size_z", "attachment_offset_x", "attachment_offset_y"})


def nominal_values(scene: Scene) -> dict:
    """The scene's own values of :func:`episode_param_names` (box-only names: NaN for other loads;
    the drone's scales 1)."""
    body = scene.body
    box = isinstance(body.shape, Box) and body.inertia is None
    size = body.shape.size if box else (math.nan,) * 3
    rho = body.rho_c
    values = dict(string_length=scene.string.length, EA=scene.string.EA,
                  mass_per_length=scene.string.mass_per_length, load_mass=body.mass,
                  load_size_x=size[0], load_size_y=size[1], load_size_z=size[2],
                  attachment_offset_x=rho[0] if box else math.nan, attachment_offset_y=rho[1] if box else math.nan,
                  pivot_mass=scene.pivot.mass or 0.0, drone_inertia_scale=1.0, rotor_coefficient_scale=1.0,
                  motor_lag_scale=1.0)
    return {name: float(values[name]) for name in episode_param_names(scene)}


def default_ranges(scene: Scene) -> dict:
    """The default range of each name for ``scene`` (module docstring); box-only names are
    left out for other loads."""
    v = nominal_values(scene)
    out = {}
    for name in episode_param_names(scene):
        if math.isnan(v[name]):
            continue
        if name in DRONE_RANGES:
            out[name] = DRONE_RANGES[name]
        elif name == "pivot_mass" and scene.pivot.is_drone:  # a drone's payload and battery, not a new drone
            out[name] = (0.8 * v[name], 1.25 * v[name])
        elif name in LOG_UNIFORM:
            out[name] = (0.5 * v[name], 2.0 * v[name])
        elif name.startswith("attachment_offset"):
            half = 0.25 * v["load_size_" + name[-1]]
            out[name] = (-half, half)
        else:
            out[name] = (0.75 * v[name], 1.25 * v[name])
    return out


def check_range(name: str, given: Any) -> tuple:
    """A user's range of ``name``: two finite real numbers, low <= high (positive unless signed);
    ValueError naming it otherwise."""
    what = f"randomize: {name}"
    if not isinstance(given, (tuple, list, np.ndarray)) or len(given) != 2:  # a set has no order
        raise ValueError(f"{what} must be a pair (low, high): a tuple, list or array, got {given!r}")
    out = []
    for x in given:
        if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
            raise ValueError(f"{what} must hold two real numbers, got {given!r}")
        if not math.isfinite(float(x)):
            raise ValueError(f"{what} must be finite, got {given!r}")
        out.append(float(x))
    low, high = out
    if low > high:
        raise ValueError(f"{what}: low {low} > high {high}")
    if name not in SIGNED and low <= 0.0:
        raise ValueError(f"{what} must be > 0, got {given!r}")
    return low, high


def user_ranges(spec: Any, names: tuple, refused: Optional[Mapping[str, str]] = None) -> dict:
    """The ranges a ``randomize`` argument sets: none for True (the defaults), name -> (low, high)
    for a mapping (:func:`check_range`). ValueError naming the bad entry: neither True nor a
    mapping, a name of ``refused`` (name -> why this environment does not draw it), a name not in
    ``names``. Both environments read ``randomize`` here (the team's: esp_gym/team/randomize.py)."""
    if spec is True:
        return {}
    if not isinstance(spec, Mapping):
        raise ValueError(f"randomize must be False, True or a mapping name -> (low, high), got {spec!r}")
    out = {}
    for name, given in spec.items():
        if refused and name in refused:
            raise ValueError(f"randomize: {name} {refused[name]}")
        if name not in names:
            raise ValueError(f"randomize: unknown parameter {name!r}; choose from {list(names)}")
        out[name] = check_range(name, given)
    return out


def draw_in_ranges(rng: np.random.Generator, low: np.ndarray, high: np.ndarray, log: np.ndarray) -> np.ndarray:
    """One value in each range [low_i, high_i], one uniform draw of ``rng`` each, in order:
    log-uniform where ``log`` (a scale), uniform elsewhere; a range of one value takes no chance
    (but its draw, so that the others' stream stays the same)."""
    unit = rng.random(len(low))
    out = np.empty(len(low))
    for i in range(len(low)):
        lo, hi = low[i], high[i]
        if log[i]:
            out[i] = math.exp(math.log(lo) + unit[i] * (math.log(hi) - math.log(lo))) if hi > lo else lo
        else:
            out[i] = lo + unit[i] * (hi - lo)
    return out


class Randomizer:
    """The ranges of one environment and the draw of an episode's scene from them.

    ``spec``: True (the defaults) or a mapping name -> (low, high) overriding them.
    ValueError naming the bad entry: an unknown name, a malformed range, a box-only name on a
    load without a box shape, a corner of the ranges that is not a valid scene."""

    def __init__(self, scene: Scene, spec: Union[bool, Mapping[str, Any]] = True):
        self.nominal = scene
        #: The names of an episode's values, in their order (:func:`episode_param_names`).
        self.names = episode_param_names(scene)
        ranges = default_ranges(scene)
        boxless = {name: f"needs a box-shaped load given by its shape (scene {scene.name!r} has {scene.body.shape!r})"
                   for name in BOX_ONLY if name not in ranges}
        ranges.update(user_ranges(spec, self.names, boxless))
        #: name -> (low, high), SI; names without a range keep the nominal value
        self.ranges = ranges
        nominal = nominal_values(scene)
        self._low = np.array([ranges.get(k, (nominal[k], nominal[k]))[0] for k in self.names])
        self._high = np.array([ranges.get(k, (nominal[k], nominal[k]))[1] for k in self.names])
        self._log = np.array([k in LOG_UNIFORM and k in ranges for k in self.names])
        self._check_corners()

    def stiffest(self) -> list:
        """The values (:attr:`names` order) of the episodes that need the smallest step, the others
        nominal: the shortest, lightest, stiffest string with the lightest pivot and load, the
        smallest box and the largest offsets (the explicit string's bound: least mass at the
        chain's ends, esp_gym/scene/stability.py), and the same string under the heaviest load (the
        implicit string's transverse bound grows with the tension)."""
        names = self.names
        light = np.array([nominal_values(self.nominal)[k] for k in names])
        for i, k in enumerate(names):
            if k in ("string_length", "mass_per_length", "load_mass", "pivot_mass") or k.startswith("load_size"):
                light[i] = self._low[i]
            elif k == "EA":
                light[i] = self._high[i]
            elif k.startswith("attachment_offset"):
                light[i] = self._low[i] if abs(self._low[i]) > abs(self._high[i]) else self._high[i]
        heavy = light.copy()
        heavy[names.index("load_mass")] = self._high[names.index("load_mass")]
        return [light, heavy]

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """One episode's values (:attr:`names` order), one uniform draw per name."""
        return draw_in_ranges(rng, self._low, self._high, self._log)

    def scene(self, values: np.ndarray, h: Optional[float] = None) -> Scene:
        """The nominal scene with ``values`` (:attr:`names` order) and step ``h``: copies of its
        sections, not validated again (the ranges' corners were)."""
        v = dict(zip(self.names, values.tolist()))
        base = self.nominal
        body = base.body
        update: dict = {"mass": v["load_mass"]}
        if isinstance(body.shape, Box) and body.inertia is None:
            old = body.shape.size
            size = (v["load_size_x"], v["load_size_y"], v["load_size_z"])
            update["shape"] = body.shape.model_copy(update={"size": size})
            update["rho_c"] = (v["attachment_offset_x"], v["attachment_offset_y"], body.rho_c[2] * size[2] / old[2])
        elif body.inertia is not None:  # same geometry, scaled mass: J scales with M
            ratio = v["load_mass"] / body.mass
            update["inertia"] = tuple(tuple(ratio * x for x in row) for row in body.inertia)
        string = base.string.model_copy(update={"length": v["string_length"], "EA": v["EA"],
                                                "mass_per_length": v["mass_per_length"]})
        sections = {"string": string, "body": body.model_copy(update=update)}
        if base.pivot.is_free:
            sections["pivot"] = base.pivot.model_copy(update={"mass": v["pivot_mass"]})
        if base.pivot.is_drone:
            drone = base.pivot.drone
            rotor, lag = v["rotor_coefficient_scale"], v["motor_lag_scale"]
            sections["pivot"] = sections["pivot"].model_copy(update={"drone": drone.model_copy(update={
                "inertia": tuple(v["drone_inertia_scale"] * x for x in drone.inertia),
                "thrust_coefficient": rotor * drone.thrust_coefficient,
                "torque_coefficient": rotor * drone.torque_coefficient,
                "motor_time_constant_up": lag * drone.motor_time_constant_up,
                "motor_time_constant_down": lag * drone.motor_time_constant_down})})
        if h is not None:
            sections["h"] = float(h)
        return base.model_copy(update=sections)

    def _check_corners(self) -> None:
        """Validate the extreme scenes: all lows, all highs, the one with the smallest box and the
        largest offsets (where the body's inertia is least well conditioned), and with a drone the
        largest inertia on the lightest drone (its bound scales with the drone's mass)."""
        lows, highs = self._low.copy(), self._high.copy()
        thin = highs.copy()
        for i, name in enumerate(self.names):
            if name.startswith("load_size"):
                thin[i] = lows[i]
            elif name.startswith("attachment_offset"):
                thin[i] = lows[i] if abs(lows[i]) > abs(highs[i]) else highs[i]
        names = self.names
        for axis in "xy" if "attachment_offset_x" in self.ranges or "attachment_offset_y" in self.ranges else "":
            offset, half = abs(thin[names.index("attachment_offset_" + axis)]), thin[names.index("load_size_" + axis)] / 2
            if offset > half:
                raise ValueError(f"randomize: attachment_offset_{axis} reaches {offset:g} m, off the load's face "
                                 f"(half its {axis} size is {half:g} m at the smallest box)")
        corners = [("the lows", lows), ("the highs", highs), ("the smallest box, largest offset", thin)]
        if "drone_inertia_scale" in names:
            light = highs.copy()
            light[names.index("pivot_mass")] = lows[names.index("pivot_mass")]
            corners.append(("the largest drone inertia, lightest drone", light))
        for what, values in corners:
            data = self.scene(values).model_dump()
            data["allow_unstable_h"] = True  # the environment chooses each episode's h
            scene_from_dict(data, source=f"at {what} of the randomize ranges")  # ValueError naming the field
