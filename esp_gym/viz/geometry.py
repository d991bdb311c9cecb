"""Geometry of the drawn body, shared by the rgb_array renderer (render.py) and the Rerun
recordings (recorder.py): the renderer's convex prism meshes (:class:`Mesh`, :func:`prism_mesh`,
:func:`body_mesh`), a triangle mesh of an elliptic prism (:func:`prism_triangles`), the box of a
body's mass and inertia (:func:`equivalent_box`) and the quaternion of a rotation matrix
(:func:`quaternion_xyzw`). NumPy only; body frame, metres.
"""
from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np

# -- the renderer's meshes ------------------------------------------------------------------------

class Mesh(NamedTuple):
    """A convex prism in the body frame, positioned at the centre of mass: vertices (2k, 3)
    (ring at z = -H/2, then ring at z = +H/2), side quads (k, 4) and the two caps (2, k) as vertex
    indices, outward unit normals (k + 2, 3) of sides then caps, edges (e, 2) as vertex indices
    with the two faces they join (e, 2) and whether they are sharp (drawn even when both faces
    show; a smooth edge is drawn only on the silhouette)."""

    vertices: np.ndarray
    sides: np.ndarray
    caps: np.ndarray
    normals: np.ndarray
    edges: np.ndarray
    edge_faces: np.ndarray
    sharp: np.ndarray


def prism_mesh(section: np.ndarray, height: float, center, smooth_sides: bool) -> Mesh:
    """Prism of counter-clockwise convex cross-section ``section`` (k, 2) in the body xy plane,
    extruded over ``height`` along body z, centred on ``center`` (3,) [m]."""
    k = len(section)
    ring = np.hstack([section, np.zeros((k, 1))])
    verts = np.vstack([ring - (0, 0, height / 2), ring + (0, 0, height / 2)]) + np.asarray(center, float)
    i = np.arange(k)
    j = (i + 1) % k
    chord = section[j] - section[i]
    side_n = np.stack([chord[:, 1], -chord[:, 0], np.zeros(k)], axis=1)
    normals = np.vstack([side_n / np.linalg.norm(side_n, axis=1, keepdims=True), [(0, 0, -1), (0, 0, 1)]])
    edges = np.vstack([np.stack([i, k + i], 1), np.stack([i, j], 1), np.stack([k + i, k + j], 1)])
    faces = np.vstack([np.stack([(i - 1) % k, i], 1), np.stack([i, np.full(k, k)], 1),
                       np.stack([i, np.full(k, k + 1)], 1)])
    sharp = np.r_[np.full(k, not smooth_sides), np.ones(2 * k, bool)]
    return Mesh(verts, np.stack([i, j, k + j, k + i], 1), np.stack([i, k + i]), normals, edges, faces, sharp)


def body_mesh(shape, rho_c, facets: int = 28) -> Optional[Mesh]:
    """The drawn mesh of a :mod:`esp_gym.scene.params` shape centred on ``rho_c`` (body frame, from
    the attachment point); a circular or elliptic section gets ``facets`` sides. None for a
    sphere or no shape."""
    kind = getattr(shape, "kind", None)
    if kind == "box":
        a, b, c = (0.5 * s for s in shape.size)
        return prism_mesh(np.array([(-a, -b), (a, -b), (a, b), (-a, b)]), 2 * c, rho_c, smooth_sides=False)
    if kind in ("cylinder", "elliptic_cylinder"):
        a, b = (shape.radius,) * 2 if kind == "cylinder" else shape.semi_axes
        phi = np.linspace(0, 2 * np.pi, facets, endpoint=False)
        return prism_mesh(np.stack([a * np.cos(phi), b * np.sin(phi)], 1), shape.height, rho_c, smooth_sides=True)
    return None


# -- recordings ----------------------------------------------------------------------------------

def quaternion_xyzw(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's method: the largest of
    w, x, y, z is taken from the diagonal, the others from the off-diagonal sums)."""
    R = np.asarray(R, dtype=float)
    tr = np.trace(R)
    d = np.array([tr, R[0, 0], R[1, 1], R[2, 2]])
    k = int(np.argmax(d))
    if k == 0:
        w = 0.5 * math.sqrt(1.0 + tr)
        q = [(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w]
    else:
        i, j, l = k - 1, k % 3, (k + 1) % 3
        s = 0.5 * math.sqrt(max(1.0 + 2.0 * R[i, i] - tr, 0.0))
        q = [0.0, 0.0, 0.0, (R[l, j] - R[j, l]) / (4 * s)]
        q[i] = s
        q[j] = (R[j, i] + R[i, j]) / (4 * s)
        q[l] = (R[l, i] + R[i, l]) / (4 * s)
    q = np.array(q)
    return q / np.linalg.norm(q)


def prism_triangles(a: float, b: float, height: float, facets: int = 32):
    """Triangle mesh of an elliptic prism (semi-axes a, b along body x, y; ``height`` along z;
    centred on the origin): vertices (V, 3), outward-wound triangles (T, 3), vertex normals
    (smooth sides, flat caps)."""
    phi = np.linspace(0.0, 2.0 * np.pi, facets, endpoint=False)
    ring = np.stack([a * np.cos(phi), b * np.sin(phi)], axis=1)
    n_side = np.stack([np.cos(phi) / a, np.sin(phi) / b, np.zeros(facets)], axis=1)
    n_side /= np.linalg.norm(n_side, axis=1, keepdims=True)
    lo, hi = -0.5 * height, 0.5 * height
    col = lambda z: np.full((facets, 1), z)  # noqa: E731
    verts = np.vstack([np.hstack([ring, col(lo)]), np.hstack([ring, col(hi)]),       # sides
                       np.hstack([ring, col(lo)]), np.hstack([ring, col(hi)]),       # caps
                       [[0.0, 0.0, lo], [0.0, 0.0, hi]]])
    normals = np.vstack([n_side, n_side, np.tile([0.0, 0.0, -1.0], (facets, 1)),
                         np.tile([0.0, 0.0, 1.0], (facets, 1)), [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]])
    i = np.arange(facets)
    j = (i + 1) % facets
    f = facets
    side = np.vstack([np.stack([i, j, f + j], 1), np.stack([i, f + j, f + i], 1)])
    bottom = np.stack([np.full(f, 4 * f), 2 * f + j, 2 * f + i], 1)
    top = np.stack([np.full(f, 4 * f + 1), 3 * f + i, 3 * f + j], 1)
    return verts, np.vstack([side, bottom, top]).astype(np.uint32), normals


def equivalent_box(mass: float, J: np.ndarray, rho_c) -> Optional[tuple]:
    """(half sizes (3,), rotation (3, 3)) of the uniform box with the body's mass and inertia
    about its centre of mass (J_cm = J - M (|rho|^2 I - rho rho^T)), or None if J_cm is not
    that of any box. For a box, I_x = M (b^2 + c^2)/3 with half sizes (a, b, c)."""
    rho = np.asarray(rho_c, dtype=float)
    Jcm = np.asarray(J, dtype=float) - mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))
    lam, Q = np.linalg.eigh(0.5 * (Jcm + Jcm.T))
    half_sq = 1.5 / mass * (lam.sum() - 2.0 * lam)
    if not np.all(half_sq > 0):
        return None
    if np.linalg.det(Q) < 0:
        Q[:, 2] = -Q[:, 2]
    return np.sqrt(half_sq), Q
