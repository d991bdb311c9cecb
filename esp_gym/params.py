"""Validated, immutable scene parameters (pydantic) and YAML loading.

A scene is a string, a body, a pivot, gravity, the time step and the initial state. Every
quantity is SI: lengths [m], masses [kg], EA [N], inertia about the attachment point in the body
frame [kg m^2], time [s]. Gravity acts along +e3 (the paper's convention).
"""
from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, PositiveFloat, ValidationError, field_validator, model_validator

from .compositions import COMPOSITIONS, DEFAULT_FOR_ORDER, Composition

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]
PosVec3 = tuple[PositiveFloat, PositiveFloat, PositiveFloat]

SCENES_DIR = Path(__file__).resolve().parent.parent / "configs" / "scenes"

#: Short names accepted by :func:`load_scene` overrides.
ALIASES = {
    "N": "string.elements",
    "EA": "string.EA",
    "length": "string.length",
    "M": "body.mass",
    "J": "body.inertia",
    "rho_c": "body.rho_c",
    "g": "gravity",
}


class SceneError(ValueError):
    """A scene failed validation; the message names each bad field and the rule it breaks."""


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class StringParams(_Frozen):
    """Extensible string: unstretched length, mass per unstretched length, axial stiffness."""

    length: float = Field(gt=0, description="unstretched length l [m]")
    mass_per_length: float = Field(gt=0, description="mass per unstretched length mu [kg/m]")
    EA: float = Field(gt=0, description="axial stiffness E*A [N]")
    elements: int = Field(ge=1, description="number of finite elements N")
    law: Literal["elastic", "slack"] = Field(
        "elastic", description="elastic: the paper's law, resists compression; slack: tension only, "
                               "energy EA/2 max(|r'| - 1, 0)^2 (a real string goes slack)")
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
    def stability_bound(self) -> float:
        """Largest stable h of the explicit string update [s]: 2/omega_max, where the axial mode
        of one free element bounds the chain's: omega_max = sqrt(12 kappa/m) with consistent
        mass, sqrt(4 kappa/m) lumped."""
        return 2.0 / math.sqrt((12.0 if self.mass_model == "consistent" else 4.0) * self.kappa / self.m)


class Box(_Frozen):
    """Solid box centred on the centre of mass, edges ``size`` along body x, y, z [m]."""

    kind: Literal["box"]
    size: PosVec3

    def inertia_cm(self, mass: float) -> np.ndarray:
        a, b, c = self.size
        return mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


class Cylinder(_Frozen):
    """Solid circular cylinder, axis along body z, centred on the centre of mass [m]."""

    kind: Literal["cylinder"]
    radius: PositiveFloat
    height: PositiveFloat

    def inertia_cm(self, mass: float) -> np.ndarray:
        r, H = self.radius, self.height
        side = mass * (r * r / 4.0 + H * H / 12.0)
        return np.diag([side, side, mass * r * r / 2.0])


class EllipticCylinder(_Frozen):
    """Solid elliptic cylinder (the paper's load): semi-axes along body x and y, height along
    body z, centred on the centre of mass [m]."""

    kind: Literal["elliptic_cylinder"]
    semi_axes: tuple[PositiveFloat, PositiveFloat]
    height: PositiveFloat

    def inertia_cm(self, mass: float) -> np.ndarray:
        (a, b), H = self.semi_axes, self.height
        return mass * np.diag([b * b / 4.0 + H * H / 12.0, a * a / 4.0 + H * H / 12.0, (a * a + b * b) / 4.0])


class Sphere(_Frozen):
    """Solid sphere centred on the centre of mass [m]."""

    kind: Literal["sphere"]
    radius: PositiveFloat

    def inertia_cm(self, mass: float) -> np.ndarray:
        return 0.4 * mass * self.radius ** 2 * np.eye(3)


Shape = Annotated[Union[Box, Cylinder, EllipticCylinder, Sphere], Field(discriminator="kind")]


def inertia_about_attachment(mass: float, inertia_cm: np.ndarray, rho_c) -> np.ndarray:
    """Parallel-axis theorem: J = J_cm + M (|rho_c|^2 I - rho_c rho_c^T) [kg m^2], the inertia
    about the attachment point, rho_c the attachment -> centre-of-mass vector (body frame)."""
    rho = np.asarray(rho_c, dtype=float)
    return inertia_cm + mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))


class BodyParams(_Frozen):
    """Rigid load: mass, centre-of-mass offset, and its inertia about the attachment point
    (body frame) given either directly (``inertia``) or by its ``shape`` (then computed by the
    parallel-axis theorem). With both, ``inertia`` is used and ``shape`` only draws the body."""

    mass: float = Field(gt=0, description="body mass M [kg]")
    inertia: Optional[Mat3] = Field(None, description="inertia J about the attachment point, body frame [kg m^2]")
    rho_c: Vec3 = Field(description="attachment point -> centre of mass, body frame [m]")
    shape: Optional[Shape] = Field(None, description="geometry centred on the centre of mass")

    @field_validator("inertia")
    @classmethod
    def _inertia_is_physical(cls, J: Optional[Mat3]) -> Optional[Mat3]:
        if J is None:
            return J
        A = np.array(J, dtype=float)
        scale = np.abs(A).max()
        if scale == 0:
            raise ValueError("J must be positive definite (it is zero)")
        asym = np.abs(A - A.T).max()
        if asym > 1e-12 * scale:
            raise ValueError(f"J must be symmetric (max |J - J^T| = {asym:.3g})")
        lam = np.linalg.eigvalsh(0.5 * (A + A.T))
        if lam[0] <= 0:
            raise ValueError(f"J must be positive definite (eigenvalues {np.array2string(lam, precision=4)})")
        if lam[0] + lam[1] < lam[2] * (1 - 1e-12):
            raise ValueError(
                "J violates the triangle inequality of principal moments "
                f"({lam[0]:.4g} + {lam[1]:.4g} < {lam[2]:.4g}); no mass distribution has it")
        return J

    @model_validator(mode="after")
    def _inertia_or_shape(self) -> "BodyParams":
        if self.inertia is None and self.shape is None:
            raise ValueError("body needs an inertia or a shape to compute it from")
        if self.inertia is not None:
            # J about the attachment point = J_cm + M (|rho|^2 I - rho rho^T): J_cm must itself be
            # an inertia, else no body of this mass and offset has J (and J_eff turns indefinite)
            rho = np.asarray(self.rho_c, dtype=float)
            shift = self.mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))
            lam = np.linalg.eigvalsh(0.5 * (self.J + self.J.T) - shift)
            tol = 1e-12 * max(1.0, float(np.abs(self.J).max()))
            if lam[0] <= -tol or lam[0] + lam[1] < lam[2] - tol:
                raise ValueError(
                    "body.inertia: J - M (|rho_c|^2 I - rho_c rho_c^T), the inertia about the centre of "
                    f"mass, is not an inertia (eigenvalues {np.array2string(lam, precision=4)}): no body of "
                    "this mass and offset has this J")
        return self

    @property
    def J(self) -> np.ndarray:
        """Inertia about the attachment point, body frame [kg m^2] (given, or from the shape)."""
        if self.inertia is not None:
            return np.array(self.inertia, dtype=float)
        return inertia_about_attachment(self.mass, self.shape.inertia_cm(self.mass), self.rho_c)


class PivotParams(_Frozen):
    """Where the string is held. ``fixed``: the paper's pivot at ``position``. ``free``: node 1
    is a point mass ``mass`` [kg] free in 3-D (a crane hook, a drone), starting at ``position``
    with ``velocity`` [m/s], pushed by the pivot force input."""

    kind: Literal["fixed", "free"] = "fixed"
    position: Vec3 = (0.0, 0.0, 0.0)
    mass: Optional[float] = Field(None, gt=0, description="point mass of a free pivot [kg]")
    velocity: Vec3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _mass_iff_free(self) -> "PivotParams":
        if self.kind == "free" and self.mass is None:
            raise ValueError("a free pivot needs its point mass (pivot.mass > 0)")
        if self.kind == "fixed" and (self.mass is not None or any(self.velocity)):
            raise ValueError("pivot.mass and pivot.velocity belong to a free pivot (kind: free)")
        return self

    @property
    def is_free(self) -> bool:
        return self.kind == "free"


class SolverParams(_Frozen):
    """Newton on the Cayley vector (relative stopping tolerance, iteration cap) and the time
    stepper: ``order`` 2 is the paper's LGVI; 4, 6 and 8 compose LGVI substeps symmetrically
    (esp_gym/compositions.py), by default Suzuki's 5-stage (order 4) and Kahan-Li's 9- and
    17-stage (orders 6, 8) schemes; ``composition`` names another scheme of that order (``triple_jump``)."""

    newton_tol: float = Field(1e-14, gt=0, le=1e-10)
    newton_max_iter: int = Field(25, ge=2, le=200)
    order: Literal[2, 4, 6, 8] = 2
    max_stretch: float = Field(
        10.0, gt=1.0, description="blow-up guard: a step that stretches an element beyond this many rest "
                                  "lengths stops with an error (an unstable step grows geometrically; this "
                                  "catches it while the state is still finite)")
    composition: Optional[Literal[tuple(COMPOSITIONS)]] = Field(
        None, description="composition scheme (default: the order's, see esp_gym/compositions.py)")
    compensated: bool = Field(
        True, description="add the state increments with Kahan's compensation: keeps energy and pi3 "
                          "round-off bounded over 1e7+ steps; false is ~13 % faster per step and "
                          "loses nothing over short horizons (docs/performance.md)")

    @model_validator(mode="after")
    def _composition_has_the_order(self) -> "SolverParams":
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
        composition's exact stability interval otherwise, see esp_gym/compositions.py)."""
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
    stretch: float = Field(1.0, gt=0)
    nodes: Optional[list[Vec3]] = None
    attach_velocity: Vec3 = (0.0, 0.0, 0.0)
    node_velocities: Optional[list[Vec3]] = None
    R0: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    Omega0: Vec3 = (0.0, 0.0, 0.0)

    @field_validator("direction")
    @classmethod
    def _direction_nonzero(cls, d: Vec3) -> Vec3:
        if np.linalg.norm(d) == 0:
            raise ValueError("direction must be a non-zero vector")
        return d

    @field_validator("R0")
    @classmethod
    def _rotation(cls, R: Mat3) -> Mat3:
        A = np.array(R, dtype=float)
        err = np.linalg.norm(A.T @ A - np.eye(3))
        if err > 1e-12 or np.linalg.det(A) <= 0:
            raise ValueError(f"R0 must be a rotation (||R^T R - I|| = {err:.2g}, det = {np.linalg.det(A):.6g})")
        return R


class Scene(_Frozen):
    """A complete, validated scene. Build it with :func:`load_scene` or ``Scene(**dict)``."""

    name: str = "custom"
    string: StringParams
    body: BodyParams
    pivot: PivotParams = PivotParams()
    gravity: float = Field(9.81, ge=0, description="gravitational acceleration along +e3 [m/s^2]")
    h: float = Field(gt=0, description="time step [s]")
    allow_unstable_h: bool = Field(False, description="accept h above the stability bound")
    solver: SolverParams = SolverParams()
    initial: InitialState = InitialState()

    @property
    def stability_bound(self) -> float:
        """Largest stable h [s]: the string's bound, times the composition's bound factor
        when one is used."""
        return self.string.stability_bound * self.solver.bound_factor

    @model_validator(mode="after")
    def _consistent(self) -> "Scene":
        bound = self.stability_bound
        if self.h > bound and not self.allow_unstable_h:
            scheme = self.solver.scheme
            composed = "" if scheme.stages == 1 else f", times {scheme.bound_factor:.4f} for {scheme.name}"
            raise ValueError(
                f"h = {self.h:.6g} s exceeds the stability bound h_max = {bound:.6g} s "
                f"(2/omega_max, omega_max = sqrt(12 EA/(mu u^2)) for N = {self.string.elements}{composed}); "
                "use a smaller h or set allow_unstable_h: true")
        n1 = self.string.elements + 1
        init = self.initial
        if init.nodes is not None:
            if len(init.nodes) != n1:
                raise ValueError(f"initial.nodes needs N+1 = {n1} rows, got {len(init.nodes)}")
            if not np.allclose(init.nodes[0], self.pivot.position, rtol=0, atol=1e-12):
                raise ValueError("initial.nodes[0] must be at pivot.position")
            x = np.diff(np.array(init.nodes, dtype=float), axis=0)
            if np.any(np.linalg.norm(x, axis=1) == 0):
                raise ValueError("initial.nodes has an element of zero length")
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
        d = np.array(self.initial.direction, dtype=float)
        d /= np.linalg.norm(d)
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


def _format_errors(err: ValidationError, source: str) -> str:
    lines = [f"invalid scene {source}:"]
    for e in err.errors():
        loc = ".".join(str(x) for x in e["loc"])
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] == "extra_forbidden":
            msg = "unknown key"
        # scene-level rules (h vs the bound, row counts) name their field in the message
        lines.append(f"  {loc}: {msg}" if loc else f"  {msg}")
    return "\n".join(lines)


def scene_from_dict(data: dict, source: str = "<dict>") -> Scene:
    """Validate a plain dict into a :class:`Scene`, raising :class:`SceneError` on bad input."""
    try:
        return Scene.model_validate(data)
    except ValidationError as err:
        raise SceneError(_format_errors(err, source)) from None


def available_scenes() -> list[str]:
    """Names of the scenes under ``configs/scenes``."""
    return sorted(p.stem for p in SCENES_DIR.glob("*.yaml"))


def _set_dotted(data: dict, dotted: str, value: Any) -> None:
    keys = dotted.split(".")
    node = data
    for key in keys[:-1]:
        child = node.get(key)
        if child is None:
            child = node[key] = {}
        if not isinstance(child, dict):
            raise SceneError(f"override {dotted!r}: {key!r} is not a section")
        node = child
    if isinstance(value, dict) and isinstance(node.get(keys[-1]), dict):
        merged = dict(node[keys[-1]])
        for k, v in value.items():
            _set_dotted(merged, k, v)
        node[keys[-1]] = merged
    else:
        node[keys[-1]] = value


def load_scene(name_or_path: str | Path, **overrides: Any) -> Scene:
    """Load a scene by name (``configs/scenes/NAME.yaml``) or YAML path, with overrides.

    Overrides are validated like the file: top-level fields (``h=2.5e-5``), sections merged
    key by key (``string={"EA": 80}``), dotted paths (``**{"body.mass": 0.2}``) and the aliases
    N, EA, length, M, J, rho_c, g.
    """
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = SCENES_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        raise SceneError(f"no scene {str(name_or_path)!r}: not a YAML file and not one of {available_scenes()}")
    with open(path) as fh:
        data = yaml.safe_load(fh) or {}
    if not isinstance(data, dict):
        raise SceneError(f"invalid scene {path}: the file must hold a mapping")
    data = copy.deepcopy(data)
    data.setdefault("name", path.stem)
    for key, value in overrides.items():
        dotted = ALIASES.get(key, key)
        if dotted.split(".")[0] not in Scene.model_fields:
            raise SceneError(f"unknown override {key!r}: use a scene field "
                             f"{sorted(Scene.model_fields)}, a dotted path or one of {sorted(ALIASES)}")
        _set_dotted(data, dotted, value)
    return scene_from_dict(data, source=repr(data.get("name")))
