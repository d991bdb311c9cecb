"""Body shapes: inertia about the attachment point from geometry, against exact quadrature."""
import numpy as np
import pytest
from numpy.polynomial.legendre import leggauss

import esp_gym
from esp_gym.scene.params import BodyParams, scene_from_dict

RHO = (0.03, -0.01, 0.05)


def _gauss(n, lo, hi):
    x, w = leggauss(n)
    return 0.5 * (hi - lo) * x + 0.5 * (hi + lo), 0.5 * (hi - lo) * w


def _inertia_by_quadrature(points, weights, mass, rho):
    """J = sum m_i (|x_i|^2 I - x_i x_i^T), x_i = rho_c + rho_i: the definition, not the
    parallel-axis theorem. The quadratures below are exact for the polynomial integrands."""
    x = points + np.asarray(rho)
    m = mass * weights / weights.sum()
    return (m * np.einsum("ij,ij->i", x, x)).sum() * np.eye(3) - np.einsum("i,ij,ik->jk", m, x, x)


def _box(a, b, c):
    gx, wx = _gauss(4, -a / 2, a / 2)
    gy, wy = _gauss(4, -b / 2, b / 2)
    gz, wz = _gauss(4, -c / 2, c / 2)
    X, Y, Z = np.meshgrid(gx, gy, gz, indexing="ij")
    W = np.einsum("i,j,k->ijk", wx, wy, wz)
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1), W.ravel()


def _elliptic_cylinder(a, b, H):
    s, ws = _gauss(6, 0.0, 1.0)
    th = np.linspace(0, 2 * np.pi, 16, endpoint=False)  # trapezoid: exact for low-degree trig
    z, wz = _gauss(4, -H / 2, H / 2)
    S, T, Z = np.meshgrid(s, th, z, indexing="ij")
    W = np.einsum("i,j,k->ijk", ws * s * a * b, np.full(th.size, 2 * np.pi / th.size), wz)
    return np.stack([a * S.ravel() * np.cos(T.ravel()), b * S.ravel() * np.sin(T.ravel()), Z.ravel()], 1), W.ravel()


def _sphere(R):
    r, wr = _gauss(6, 0.0, R)
    c, wc = _gauss(6, -1.0, 1.0)  # cos(polar angle)
    ph = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    Rr, C, P = np.meshgrid(r, c, ph, indexing="ij")
    W = np.einsum("i,j,k->ijk", wr * r * r, wc, np.full(ph.size, 2 * np.pi / ph.size))
    S = np.sqrt(1 - C ** 2)
    pts = np.stack([(Rr * S * np.cos(P)).ravel(), (Rr * S * np.sin(P)).ravel(), (Rr * C).ravel()], 1)
    return pts, W.ravel()


@pytest.mark.parametrize("shape, quad", [
    ({"kind": "box", "size": [0.1, 0.08, 0.06]}, lambda: _box(0.1, 0.08, 0.06)),
    ({"kind": "cylinder", "radius": 0.03, "height": 0.3}, lambda: _elliptic_cylinder(0.03, 0.03, 0.3)),
    ({"kind": "elliptic_cylinder", "semi_axes": [0.06, 0.04], "height": 0.1}, lambda: _elliptic_cylinder(0.06, 0.04, 0.1)),
    ({"kind": "sphere", "radius": 0.05}, lambda: _sphere(0.05)),
])
def test_shape_inertia_matches_quadrature(shape, quad):
    body = BodyParams(mass=0.7, rho_c=RHO, shape=shape)
    pts, w = quad()
    np.testing.assert_allclose(body.J, _inertia_by_quadrature(pts, w, 0.7, RHO), rtol=1e-12, atol=1e-15)


def test_paper_body_inertia_is_the_printed_one_over_1000():
    """Erratum 6: the paper's elliptic cylinder about its attachment point has J = printed/1000,
    to the two printed decimals."""
    printed = np.array(esp_gym.load_scene("paper_example").body.inertia)
    derived = esp_gym.load_scene("paper_example_consistent").body.J
    np.testing.assert_array_equal(np.round(derived * 1000, 2), printed)
    # and the paper scene keeps the printed J although it carries the shape for drawing
    np.testing.assert_array_equal(esp_gym.load_scene("paper_example").body.J, printed)


@pytest.mark.parametrize("body, needle", [
    ({"mass": 0.1, "rho_c": [0, 0, 0.1]}, "needs an inertia or a shape"),
    ({"mass": 0.1, "rho_c": [0, 0, 0.1], "shape": {"kind": "box", "size": [0.1, -0.1, 0.1]}}, "body.shape.box.size"),
    ({"mass": 0.1, "rho_c": [0, 0, 0.1], "shape": {"kind": "torus", "radius": 0.1}}, "body.shape"),
    ({"mass": 0.1, "rho_c": [0, 0, 0.1], "shape": {"kind": "sphere", "radius": 0.0}}, "body.shape.sphere.radius"),
])
def test_bad_body_is_named(body, needle):
    data = esp_gym.load_scene("paper_example").model_dump()
    data["body"] = body  # replaced whole: load_scene overrides would merge into the paper's body
    with pytest.raises(esp_gym.SceneError, match=needle.replace(".", r"\.")):
        scene_from_dict(data)
