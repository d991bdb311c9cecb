"""The stability bound of the assembled string: the explicit step's largest stable h, from the
highest frequency of the linearised chain with its real masses (docs/physics.md, "The stability
bound").

The string's elastic forces are explicit in the LGVI, so, like the Stormer-Verlet scheme, a step
is linearly stable while h omega_max < 2, omega_max^2 the largest eigenvalue of K x = lambda M x:

* M, the chain's mass matrix on the nodes that move: the string's consistent (or lumped) element
  masses, a free pivot's mass on node 1, and on the attachment node the load's smallest
  *effective* translational mass (:func:`attachment_mass`: the body turns under a push at its
  attachment point, so it resists it with less than its mass M);
* K, the path Laplacian of the elements times one stiffness per element: EA/u for the explicit
  string (an element's tangent stiffness is EA/u along it and T/l < EA/u across it, at any
  stretch), T/u for the implicit string's transverse directions at tension T.

Both replacements (the smallest effective mass in every direction, the axial stiffness in every
direction) only raise the Rayleigh quotient, so omega_max is an upper bound for every
configuration and orientation, and it is reached by a straight string whose axis lies along the
load's softest direction. Gravity's own stiffness (the load's pendulum, about 10 rad/s) is left
out: it is orders of magnitude below the elastic frequencies the bound is about.

The eigenproblem is tridiagonal and solved by Sturm bisection in O(N) (a compiled kernel,
esp_gym/kernels/stability.py) up to N = 4,096; beyond, one free element's frequency bounds it
(2.2e-7 apart at N = 4,096). One free element's frequency sqrt(12 kappa/m) (consistent mass;
sqrt(4 kappa/m) lumped) bounds it from above (the assembled chain's largest eigenvalue is at most
the largest of its elements'; the end masses only add mass); the two agree to 6e-5 at N = 256.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

def hat(v) -> np.ndarray:
    """The hat map: ``hat(v) @ y == np.cross(v, y)``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def attachment_mass(body) -> float:
    """The smallest translational mass [kg] the load presents at its attachment point:
    the least eigenvalue of ``M I + M^2 hat(rho_c) J^-1 hat(rho_c)``, the body's mass matrix in
    (attachment velocity, Omega) with Omega eliminated (J about the attachment point). It equals M
    for rho_c = 0 and falls towards 0 as the body's inertia about its centre of mass does
    (closed form, compiled: esp_gym/kernels/stability.py)."""
    from ..kernels.stability import least_effective_mass  # compiled on first use
    return float(least_effective_mass(float(body.mass), np.asarray(body.rho_c, dtype=np.float64),
                                      np.ascontiguousarray(body.J, dtype=np.float64)))


#: Largest N whose chain is solved (Sturm bisection, O(N) per count); beyond it one free element's
#: eigenvalue, which bounds the chain's from above and is within 2.2e-7 of it at N = 4,096.
MAX_SOLVED_ELEMENTS = 4096


def chain_omega2(elements: int, element_mass: float, stiffness: float, consistent: bool,
                 pivot_mass: Optional[float], end_mass: float) -> float:
    """omega_max^2 [1/s^2] of a chain of ``elements`` elements of mass ``element_mass`` [kg] and
    ``stiffness`` [N/m] each: a free pivot's ``pivot_mass`` [kg] on node 1 (None: the pivot is
    fixed, node 1 does not move) and ``end_mass`` [kg] on the attachment node, on top of the
    element masses (consistent m/6 [[2, 1], [1, 2]] or lumped m/2 per end). Sturm bisection in
    O(N) (esp_gym/kernels/stability.py), exact to a few ulp, up to MAX_SOLVED_ELEMENTS elements."""
    if elements > MAX_SOLVED_ELEMENTS:
        return (12.0 if consistent else 4.0) * float(stiffness) / float(element_mass)
    from ..kernels.stability import largest_eigenvalue  # compiled on first use
    fixed = pivot_mass is None
    return float(stiffness) * largest_eigenvalue(int(elements), float(element_mass), bool(consistent),
                                                 0.0 if fixed else float(pivot_mass), fixed, float(end_mass))


def chain_bound(scene, stiffness: float) -> float:
    """2/omega_max [s] of the scene's string with ``stiffness`` [N/m] per element, its pivot and
    its load (one LGVI step; see the module docstring)."""
    s = scene.string
    omega2 = chain_omega2(int(s.elements), float(s.m), float(stiffness), s.mass_model == "consistent",
                          float(scene.pivot.mass) if scene.pivot.is_free else None, attachment_mass(scene.body))
    return 2.0 / math.sqrt(omega2)


def explicit_bound(scene) -> float:
    """The explicit string's largest stable h [s]: 2/omega_max of the assembled chain at the axial
    stiffness EA/u, times the scene's composition factor (esp_gym/scene/compositions.py)."""
    return chain_bound(scene, scene.string.kappa) * scene.solver.bound_factor


def element_bound(scene) -> float:
    """The one-element bound [s], 2/sqrt(12 kappa/m) (consistent) or 2/sqrt(4 kappa/m) (lumped),
    times the composition factor: a lower bound of :func:`explicit_bound` (docs/physics.md)."""
    return scene.string.element_bound * scene.solver.bound_factor


def transverse_bound(scene, tension: float) -> float:
    """The implicit string's largest stable h [s] at ``tension`` [N]: its directions are explicit
    (docs/physics.md, "The implicit string"), so 2/omega_max of the assembled chain at the
    transverse stiffness T/u per element."""
    return chain_bound(scene, tension / scene.string.u)
