"""Validated, immutable scene parameters (pydantic), and loading a scene by name, path or overrides.

A scene is a string, a body, a pivot, gravity, the time step and the initial state. Every
quantity is SI: lengths [m], masses [kg], EA [N], inertia about the attachment point in the body
frame [kg m^2], time [s]. Gravity acts along +e3 (the paper's convention).

Numbers are strict (a bool or a string is not a number) and bounded, so that the energy at
t = 0 and every constant the stepper derives are finite: esp_gym/scene/scene_input.py, docs/scenes.md.
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any, Literal, Optional

import numpy as np
from pydantic import Field, field_validator, model_validator

from .pivot_params import DroneParams, PivotParams  # noqa: F401  (re-exported)
from .compositions import COMPOSITIONS, DEFAULT_FOR_ORDER, Composition
from .scene_input import (ALIASES, BOUNDS, Count, Flag, Frozen as _Frozen, Real, SceneError, bounded,  # noqa: F401
                          is_yaml_path, matrix, merge_overrides, read_scene_file, validated, vector)
from .shapes import (Box, Cylinder, EllipticCylinder, Shape, Sphere, attachment_inertia,  # noqa: F401
                     check_inertia, inertia_about_attachment)

Vec3 = vector()
Mat3 = matrix()
Point3 = vector("coordinate")
Velocity3 = vector("speed")

#: Smallest principal inertia about the centre of mass, relative to J's largest (J about the
#: attachment point): keeps six digits of J_eff = J - (the string's share) in float64.
MIN_INERTIA_SHARE = 1e-10

#: Sections that an override of another ``kind`` replaces instead of merging into (their kinds
#: have different fields).
KINDS = ("body.shape",)

#: The shipped scenes, package data of esp_gym (esp_gym/scenes/NAME.yaml): a Traversable, read
#: through importlib.resources.
SCENES_DIR = resources.files("esp_gym") / "scenes"


class StringParams(_Frozen):
    """Extensible string: unstretched length, mass per unstretched length, axial stiffness."""

    length: Real = bounded("length", description="unstretched length l [m]")
    mass_per_length: Real = bounded("mass_per_length", description="mass per unstretched length mu [kg/m]")
    EA: Real = bounded("EA", description="axial stiffness E*A [N]")
    elements: Count = Field(ge=BOUNDS["elements"][0], le=BOUNDS["elements"][1],
                            description="number of finite elements N")
    law: Literal["elastic", "slack"] = Field(
        "elastic", description="elastic: the paper's law, resists compression; slack: tension only, "
                               "energy EA/2 max(|r'| - 1, 0)^2 (a real string goes slack)")
    auto: Flag = Field(False, description="N and the scene's h were chosen by esp_gym.choose_resolution "
                                           "(the scene file said elements: auto); the environment chooses again for "
                                           "its control period and for each randomised episode")
    damping_time: Real = bounded("time", default=0.0,
                                 description="Kelvin-Voigt retardation time tau [s]: a taut element's tension is "
                                             "EA (strain + tau strain rate), held >= 0 with the slack law (0: no "
                                             "damping, the paper's conservative string)")
    mass_model: Literal["consistent", "lumped"] = Field(
        "consistent", description="consistent: the paper's finite-element mass (tridiagonal); lumped: "
                                  "m/2 at each end of an element (diagonal; sqrt(3) larger stable steps)")

    @property
    def u(self) -> float:
        """Unstretched element length l/N [m]."""
        return self.length / self.elements

    @property
    def m(self) -> float:
        """Element mass mu*u [kg]."""
        return self.mass_per_length * self.u

    @property
    def kappa(self) -> float:
        """Element stiffness EA/u [N/m]."""
        return self.EA / self.u

    @property
    def damping(self) -> float:
        """An element's damper coefficient c = EA tau / u [N s/m] (kernels/step/damper.py)."""
        return self.kappa * self.damping_time

    @property
    def damped(self) -> bool:
        """Whether the string has a damper (``damping_time`` > 0): a rig of its own."""
        return self.damping_time > 0.0

    @property
    def element_bound(self) -> float:
        """One free element's bound [s]: 2/omega_e with omega_e = sqrt(12 kappa/m) (consistent mass)
        or sqrt(4 kappa/m) (lumped). A lower bound of the assembled string's
        (:attr:`Scene.stability_bound`, esp_gym/scene/stability.py), which it approaches as N grows."""
        # within the bounds of docs/scenes.md no factor here is 0 or overflows
        return 2.0 / math.sqrt((12.0 if self.mass_model == "consistent" else 4.0) * self.kappa / self.m)


class BodyParams(_Frozen):
    """Rigid load: mass, centre-of-mass offset, and its inertia about the attachment point
    (body frame) given either directly (``inertia``) or by its ``shape`` (then computed by the
    parallel-axis theorem). With both, ``inertia`` is used and ``shape`` only draws the body."""

    mass: Real = bounded("mass", description="body mass M [kg]")
    inertia: Optional[matrix("inertia")] = Field(
        None, description="inertia J about the attachment point, body frame [kg m^2]")
    rho_c: Point3 = Field(description="attachment point -> centre of mass, body frame [m]")
    shape: Optional[Shape] = Field(None, description="geometry centred on the centre of mass")

    @field_validator("inertia")
    @classmethod
    def _inertia_is_physical(cls, J: Optional[Mat3]) -> Optional[Mat3]:
        if J is not None:
            check_inertia(np.array(J, dtype=float))
        return J

    @model_validator(mode="after")
    def _inertia_or_shape(self) -> "BodyParams":
        if self.inertia is None and self.shape is None:
            raise ValueError("body needs an inertia or a shape to compute it from")
        # J about the attachment point = J_cm + M (|rho|^2 I - rho rho^T): J_cm must itself be
        # an inertia, else no body of this mass and offset has J (and J_eff turns indefinite)
        rho, J = np.asarray(self.rho_c, dtype=float), self.J
        shift = self.mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))
        J_cm = 0.5 * (J + J.T) - shift if self.inertia is not None else self.shape.inertia_cm(self.mass)
        lam = np.linalg.eigvalsh(J_cm)
        tol = 1e-12 * max(1.0, float(np.abs(J).max()))
        if self.inertia is not None and (lam[0] <= -tol or lam[0] + lam[1] < lam[2] - tol):
            raise ValueError(
                "body.inertia: J - M (|rho_c|^2 I - rho_c rho_c^T), the inertia about the centre of "
                f"mass, is not an inertia (eigenvalues {np.array2string(lam, precision=4)}): no body of "
                "this mass and offset has this J")
        # the stepper subtracts the string's share from J (J_eff, docs/physics.md): a J_cm below
        # round-off of J would leave J_eff to the rounding errors
        top = np.linalg.eigvalsh(J)[2]
        if lam[0] < MIN_INERTIA_SHARE * top:
            source = "body.inertia" if self.inertia is not None else "body.shape"
            raise ValueError(
                f"{source}: the smallest principal inertia about the centre of mass, {lam[0]:.4g} kg m^2, is "
                f"below {MIN_INERTIA_SHARE:g} of J's largest, {top:.4g} kg m^2 (with body.mass and body.rho_c): a "
                "body this thin or this far from its attachment point leaves J_eff to round-off")
        return self

    @property
    def J(self) -> np.ndarray:
        """Inertia about the attachment point, body frame [kg m^2] (given, or from the shape)."""
        if self.inertia is not None:
            return np.array(self.inertia, dtype=float)
        return attachment_inertia(float(self.mass), tuple(map(float, self.rho_c)), self.shape).copy()


class WinchParams(_Frozen):
    """A winch at the pivot that reels the string out and in (``Simulator.step``'s ``reel_speed``;
    docs/physics.md, "The winch"): the unstretched length stays within [min_length, max_length]
    (unset: half and twice ``string.length``) and the reel speed within ``max_speed``."""

    min_length: Optional[Real] = bounded("length", default=None, description="shortest unstretched length [m]")
    max_length: Optional[Real] = bounded("length", default=None, description="longest unstretched length [m]")
    max_speed: Real = Field(1.0, gt=0.0, le=BOUNDS["speed"][1], description="largest reel speed |dl/dt| [m/s]")


class SolverParams(_Frozen):
    """Newton on the Cayley vector (relative stopping tolerance, iteration cap) and the time
    stepper: ``order`` 2 is the paper's LGVI; 4, 6 and 8 compose LGVI substeps symmetrically
    (esp_gym/scene/compositions.py), by default Suzuki's 5-stage (order 4) and Kahan-Li's 9- and
    17-stage (orders 6, 8) schemes; ``composition`` names another scheme of that order (``triple_jump``)."""

    newton_tol: Real = Field(1e-14, gt=0, le=1e-10)
    newton_max_iter: Count = Field(25, ge=2, le=200)
    order: Literal[2, 4, 6, 8] = 2
    max_stretch: Real = Field(
        10.0, gt=1.0, le=BOUNDS["stretch"][1],
        description="blow-up guard: a step that stretches an element beyond this many rest lengths stops with "
                    "an error (an unstable step grows geometrically; this catches it while the state is finite)")
    composition: Optional[Literal[tuple(COMPOSITIONS)]] = Field(
        None, description="composition scheme (default: the order's, see esp_gym/scene/compositions.py)")
    compensated: Flag = Field(
        True, description="add the state increments with Kahan's compensation (energy and pi3 round-off bounded "
                          "over 1e7+ steps); false is ~13 % faster, as good over short runs (docs/performance.md)")
    string: Literal["explicit", "implicit"] = Field(
        "explicit", description="the string's elastic forces: explicit (the paper's) or implicit (docs/physics.md)")
    slack_switch: Literal["settled", "plain"] = Field("settled", description=(
        "the explicit string's step where an element of the slack law turns slack or taut: settled (an "
        "impulse along the element settles the energy the step's trapezoid rule misses there) or plain (the "
        "variational step as it is, whose errors there add up: docs/physics.md)"))
    implicit_form: Literal["energy_momentum", "variational"] = Field("energy_momentum", description=(
        "the implicit string's forces over a step: energy_momentum (each element's tension along the discrete "
        "gradient's direction: the string's energy is conserved exactly, at any step) or variational (along the "
        "element at both ends of the step, the discrete Euler-Lagrange equations of its Lagrangian, with an "
        "explicit transverse bound: docs/physics.md)"))
    energy_watchdog: Optional[Real] = Field(1.0, gt=0, le=1e6, description=(
        "f: a run whose |E - E0 - W| passes f (energy scale + |W|) raises SimulationError, an episode ends "
        "(esp_gym/physics/watchdog.py, docs/physics.md); null: no watchdog"))

    @model_validator(mode="after")
    def _composition_has_the_order(self) -> "SolverParams":
        if self.string == "implicit" and self.order != 2:  # a second-order scheme
            raise ValueError(f"string: implicit takes order: 2 (got {self.order})")
        if self.composition is not None and COMPOSITIONS[self.composition].order != self.order:
            c = COMPOSITIONS[self.composition]
            raise ValueError(f"composition {c.name!r} has order {c.order}, but order is {self.order}; "
                             f"set order: {c.order} or drop composition")
        return self

    @property
    def scheme(self) -> Composition:
        """The composition this solver runs (``lgvi`` for order 2)."""
        return COMPOSITIONS[self.composition or DEFAULT_FOR_ORDER[self.order]]

    @property
    def bound_factor(self) -> float:
        """The scheme's stable h relative to one LGVI step's (1 for the LGVI; from the
        composition's exact stability interval otherwise, see esp_gym/scene/compositions.py)."""
        return self.scheme.bound_factor


class InitialState(_Frozen):
    """Initial configuration and velocities.

    The string is straight from the pivot along ``direction`` with element length
    ``stretch * u``, unless ``nodes`` (N+1 rows, the first at the pivot) is given. Node velocities
    are zero except the attachment node's (``attach_velocity``) and a free pivot's
    (``pivot.velocity``), unless ``node_velocities`` (N+1 rows, the first zero for a fixed
    pivot) is given. ``R0`` maps body to spatial frame;
    ``Omega0`` is the body-frame angular velocity [rad/s].
    """

    direction: Vec3 = (1.0, 0.0, 0.0)
    stretch: Real = bounded("stretch", default=1.0)
    nodes: Optional[list[Point3]] = None
    attach_velocity: Velocity3 = (0.0, 0.0, 0.0)
    node_velocities: Optional[list[Velocity3]] = None
    R0: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    Omega0: vector("angular_speed") = (0.0, 0.0, 0.0)

    @field_validator("direction")
    @classmethod
    def _direction_nonzero(cls, d: Vec3) -> Vec3:
        if not any(d):
            raise ValueError("direction must be a non-zero vector")
        return d

    def unit_direction(self) -> np.ndarray:
        """``direction`` normalised; scaled first only where a square would overflow or
        underflow, so that ordinary directions keep the bits they always had."""
        d = np.array(self.direction, dtype=float)
        norm = np.linalg.norm(d)
        if not 1e-150 < norm < 1e150:
            d /= np.abs(d).max()
            norm = np.linalg.norm(d)
        return d / norm

    @field_validator("R0")
    @classmethod
    def _rotation(cls, R: Mat3) -> Mat3:
        check_rotation("R0", R, 1e-12)
        return R


def check_rotation(name: str, R, tol: float) -> None:
    """ValueError naming ``name`` unless the 3x3 ``R`` is a rotation: entries in [-1, 1],
    ``||R^T R - I|| <= tol`` (Frobenius) and det R > 0 (for scenes and for states set later)."""
    A = np.array(R, dtype=float)
    if np.abs(A).max() > 1.0 + 1e-9:
        raise ValueError(f"{name} must be a rotation (its entries lie in [-1, 1], got {np.abs(A).max():.6g})")
    err = np.linalg.norm(A.T @ A - np.eye(3))
    if not (err <= tol and np.linalg.det(A) > 0):
        raise ValueError(f"{name} must be a rotation (||R^T R - I|| = {err:.2g}, at most {tol:g}; "
                         f"det = {np.linalg.det(A):.6g})")


class Scene(_Frozen):
    """A complete, validated scene. Build it with :func:`load_scene` or ``Scene(**dict)``."""

    name: str = "custom"
    string: StringParams
    body: BodyParams
    pivot: PivotParams = PivotParams()
    gravity: Real = bounded("gravity", default=9.81, description="gravitational acceleration along +e3 [m/s^2]")
    h: Real = Field(gt=0, description="time step [s]")
    allow_unstable_h: Flag = Field(False, description="accept h above the stability bound")
    solver: SolverParams = SolverParams()
    initial: InitialState = InitialState()
    winch: WinchParams = WinchParams()
    ground: Optional[Real] = Field(None, gt=0, allow_inf_nan=False,
                                   description="the ground plane's depth z below the origin [m] (e3 down): an "
                                               "environment's episode ends when the pivot or the load reaches it")

    @model_validator(mode="after")
    def _a_damper_the_step_has(self) -> "Scene":
        if self.string.damped and self.pivot.is_drone and self.pivot.drone.offset_hook:
            raise ValueError("string.damping_time: a drone's offset hook has no damper yet (docs/physics.md, \"Material "
                             "damping\"); hang the string from the drone's centre of mass (pivot.drone.rho_q 0), "
                             "or take damping_time 0")
        return self

    @model_validator(mode="before")
    @classmethod
    def _resolve_auto_elements(cls, data: Any) -> Any:
        """``string.elements: auto``: N and h by :func:`esp_gym.choose_resolution` (5 mm over 4 s;
        docs/physics.md, "The string's resolution"), the scene's own h replaced."""
        if not (isinstance(data, Mapping) and isinstance(data.get("string"), Mapping)
                and isinstance(data["string"].get("elements"), str) and data["string"]["elements"] == "auto"):
            return data
        initial = data.get("initial")
        if isinstance(initial, Mapping) and (initial.get("nodes") is not None
                                             or initial.get("node_velocities") is not None):
            raise ValueError("string.elements: auto chooses N, so initial.nodes and initial.node_velocities "
                             "(one row per node) cannot be given with it")
        solver = data.get("solver")
        if isinstance(solver, Mapping) and solver.get("string") == "implicit":
            raise ValueError("string.elements: auto chooses the explicit string (docs/physics.md, \"The string's "
                             "resolution\"); drop solver.string: implicit or give string.elements")
        from .stepsize import choose_resolution  # the rule reads a scene: resolve a provisional one
        provisional = cls.model_validate({**data, "string": {**data["string"], "elements": 1},
                                          "h": data.get("h", 1.0), "allow_unstable_h": True})
        choice = choose_resolution(provisional)
        if not choice.met:
            warnings.warn(f"string.elements: auto: {choice.reason}", stacklevel=2)
        return {**data, "string": {**data["string"], "elements": choice.elements, "auto": True},
                "solver": {**(data.get("solver") or {}), "string": choice.string}, "h": choice.h}

    @property
    def stability_bound(self) -> float:
        """Largest stable h [s]: 2/omega_max of the assembled chain (the string's elements, the
        pivot's and the load's masses: :func:`esp_gym.scene.stability.explicit_bound`), times the
        composition's bound factor when one is used; ``inf`` for the implicit string
        (docs/physics.md, "The stability bound")."""
        if self.solver.string == "implicit":
            return math.inf
        from .stability import explicit_bound  # stability reads the scene's sections only
        return explicit_bound(self)

    @property
    def winch_range(self) -> tuple:
        """``(shortest, longest)`` unstretched length the winch reaches [m]."""
        w, length = self.winch, self.string.length
        return (0.5 * length if w.min_length is None else w.min_length,
                2.0 * length if w.max_length is None else w.max_length)

    @model_validator(mode="after")
    def _consistent(self) -> "Scene":
        bound = self.stability_bound
        if self.h > bound and not self.allow_unstable_h:
            scheme = self.solver.scheme
            composed = "" if scheme.stages == 1 else f", times {scheme.bound_factor:.4f} for {scheme.name}"
            raise ValueError(
                f"h = {self.h:.6g} s exceeds the stability bound h_max = {bound:.6g} s "
                f"(2/omega_max of the assembled string, N = {self.string.elements}{composed}); "
                "use a smaller h or set allow_unstable_h: true")
        shortest, longest = self.winch_range
        if not shortest <= self.string.length <= longest:
            raise ValueError(f"string.length = {self.string.length:g} m must lie in the winch's range "
                             f"[winch.min_length, winch.max_length] = [{shortest:g}, {longest:g}] m")
        n1 = self.string.elements + 1
        init, limit = self.initial, self.solver.max_stretch
        if init.nodes is None and init.stretch >= limit:
            raise ValueError(f"initial.stretch = {init.stretch:g} must be below solver.max_stretch = {limit:g} "
                             "(the blow-up guard would stop the first step)")
        if init.nodes is not None:
            if len(init.nodes) != n1:
                raise ValueError(f"initial.nodes needs N+1 = {n1} rows, got {len(init.nodes)}")
            if not np.allclose(init.nodes[0], self.pivot.position, rtol=0, atol=1e-12):
                raise ValueError("initial.nodes[0] must be at pivot.position")
            lengths = np.linalg.norm(np.diff(np.array(init.nodes, dtype=float), axis=0), axis=1)
            if np.any(lengths == 0):
                raise ValueError("initial.nodes has an element of zero length")
            if lengths.max() >= limit * self.string.u:
                raise ValueError(f"initial.nodes has an element {lengths.max() / self.string.u:.4g} rest lengths "
                                 f"long, not below solver.max_stretch = {limit:g} (the blow-up guard would "
                                 "stop the first step)")
        if init.node_velocities is not None:
            if len(init.node_velocities) != n1:
                raise ValueError(f"initial.node_velocities needs N+1 = {n1} rows, got {len(init.node_velocities)}")
            if not self.pivot.is_free and np.any(np.array(init.node_velocities[0]) != 0):
                raise ValueError("initial.node_velocities[0] must be zero (the pivot is fixed)")
        return self

    # -- derived arrays -------------------------------------------------------------------
    def initial_nodes(self) -> np.ndarray:
        """Initial node positions (N+1, 3) [m]."""
        if self.initial.nodes is not None:
            return np.array(self.initial.nodes, dtype=float)
        d = self.initial.unit_direction()
        s = np.arange(self.string.elements + 1) * (self.string.u * self.initial.stretch)
        return np.asarray(self.pivot.position, dtype=float) + s[:, None] * d

    def initial_velocities(self) -> np.ndarray:
        """Initial node velocities (N+1, 3) [m/s]."""
        if self.initial.node_velocities is not None:
            return np.array(self.initial.node_velocities, dtype=float)
        v = np.zeros((self.string.elements + 1, 3))
        v[0] = self.pivot.velocity
        v[-1] = self.initial.attach_velocity
        return v


def scene_from_dict(data: Any, source: str = "<dict>") -> Scene:
    """Validate a plain dict into a :class:`Scene`, raising :class:`SceneError` on bad input."""
    return validated(Scene, data, source)


def available_scenes() -> list[str]:
    """Names of the shipped scenes (esp_gym/scenes)."""
    return sorted(p.name.removesuffix(".yaml") for p in SCENES_DIR.iterdir() if p.name.endswith(".yaml"))


def override_scene(scene: Scene, overrides: Optional[Mapping[str, Any]] = None) -> Scene:
    """A new scene: ``scene`` with ``overrides`` applied and validated as :func:`load_scene`
    applies them to a file (the same merge, aliases and dotted paths:
    :func:`~esp_gym.scene.scene_input.merge_overrides`)."""
    if not overrides:
        return scene
    data = merge_overrides(scene.model_dump(), overrides, Scene.model_fields, KINDS)
    return scene_from_dict(data, source=repr(scene.name))


def load_scene(name_or_path: str | Path | Scene, **overrides: Any) -> Scene:
    """Load a scene by name (a shipped one, esp_gym/scenes/NAME.yaml) or YAML path (.yaml or .yml, in any
    case), with overrides; a :class:`Scene` is taken as it is (then see :func:`override_scene`).

    Overrides are validated like the file: top-level fields (``h=2.5e-5``), sections merged
    key by key (``string={"EA": 80}``), dotted paths (``**{"body.mass": 0.2}``) and the aliases
    N, EA, length, M, J, rho_c, g. Every failure is a :class:`SceneError`: a bad field (named
    with its rule), or a file that cannot be read or is not a scene (named with the problem).
    """
    if isinstance(name_or_path, Scene):
        return override_scene(name_or_path, overrides)
    path = Path(name_or_path)
    if not is_yaml_path(path):
        path = SCENES_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        known = available_scenes()
        if not is_yaml_path(name_or_path):
            raise SceneError(f"no scene {str(name_or_path)!r}: not a YAML file and not one of {known}")
        what = "a directory" if path.is_dir() else "no such file"
        raise SceneError(f"no scene file {str(name_or_path)!r}: {what} (the scenes by name: {known})")
    with resources.as_file(path) as file:  # a shipped scene as a file (it is one, but for a zipped install)
        data = read_scene_file(file)
    data.setdefault("name", Path(path.name).stem)
    data = merge_overrides(data, overrides, Scene.model_fields, KINDS)
    return scene_from_dict(data, source=f"{data.get('name')!r} ({path})")
