"""The load's shapes, centred on its centre of mass (body frame), and their inertia: a scene's
``body.shape`` (esp_gym/scene/params.py), which also draws the body and sets its drag area
(esp_gym/pendulum/wind.py). Sizes [m], masses [kg], inertia [kg m^2]."""
from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field

from .scene_input import Frozen, Real, bounded, vector


class Box(Frozen):
    """Solid box centred on the centre of mass, edges ``size`` along body x, y, z [m]."""

    kind: Literal["box"]
    size: vector("length")

    def inertia_cm(self, mass: float) -> np.ndarray:
        a, b, c = self.size
        return mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


class Cylinder(Frozen):
    """Solid circular cylinder, axis along body z, centred on the centre of mass [m]."""

    kind: Literal["cylinder"]
    radius: Real = bounded("length")
    height: Real = bounded("length")

    def inertia_cm(self, mass: float) -> np.ndarray:
        r, H = self.radius, self.height
        side = mass * (r * r / 4.0 + H * H / 12.0)
        return np.diag([side, side, mass * r * r / 2.0])


class EllipticCylinder(Frozen):
    """Solid elliptic cylinder (the paper's load): semi-axes along body x and y, height along
    body z, centred on the centre of mass [m]."""

    kind: Literal["elliptic_cylinder"]
    semi_axes: vector("length", 2)
    height: Real = bounded("length")

    def inertia_cm(self, mass: float) -> np.ndarray:
        (a, b), H = self.semi_axes, self.height
        return mass * np.diag([b * b / 4.0 + H * H / 12.0, a * a / 4.0 + H * H / 12.0, (a * a + b * b) / 4.0])


class Sphere(Frozen):
    """Solid sphere centred on the centre of mass [m]."""

    kind: Literal["sphere"]
    radius: Real = bounded("length")

    def inertia_cm(self, mass: float) -> np.ndarray:
        return 0.4 * mass * self.radius ** 2 * np.eye(3)


Shape = Annotated[Union[Box, Cylinder, EllipticCylinder, Sphere], Field(discriminator="kind")]


@lru_cache(maxsize=64)
def attachment_inertia(mass: float, rho_c: tuple, shape: "Shape") -> np.ndarray:
    """The inertia about the attachment point [kg m^2] of a body of ``mass`` and ``shape`` whose
    centre of mass is ``rho_c`` from it; cached (a randomised reset needs its episode's three
    times; callers get copies from BodyParams.J)."""
    return inertia_about_attachment(mass, shape.inertia_cm(mass), rho_c)


def check_inertia(J: np.ndarray) -> None:
    """ValueError unless ``J`` (3, 3) [kg m^2] is an inertia: symmetric, positive definite, and
    its principal moments obey the triangle inequality (some mass distribution has it)."""
    scale = np.abs(J).max()
    if scale == 0:
        raise ValueError("J must be positive definite (it is zero)")
    asym = np.abs(J - J.T).max()
    if asym > 1e-12 * scale:
        raise ValueError(f"J must be symmetric (max |J - J^T| = {asym:.3g})")
    lam = np.linalg.eigvalsh(0.5 * (J + J.T))
    if lam[0] <= 0:
        raise ValueError(f"J must be positive definite (eigenvalues {np.array2string(lam, precision=4)})")
    if lam[0] + lam[1] < lam[2] * (1 - 1e-12):
        raise ValueError("J violates the triangle inequality of principal moments "
                         f"({lam[0]:.4g} + {lam[1]:.4g} < {lam[2]:.4g}); no mass distribution has it")


def inertia_about_attachment(mass: float, inertia_cm: np.ndarray, rho_c) -> np.ndarray:
    """Parallel-axis theorem: J = J_cm + M (|rho_c|^2 I - rho_c rho_c^T) [kg m^2], the inertia
    about the attachment point, rho_c the attachment -> centre-of-mass vector (body frame)."""
    rho = np.asarray(rho_c, dtype=float)
    return inertia_cm + mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))
