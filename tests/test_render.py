"""The NumPy software renderer (esp_gym.viz.render): primitives, frame content, clipping, speed."""
import time

import numpy as np
import pytest

from esp_gym.scene.params import Box, Cylinder, EllipticCylinder, Sphere
from esp_gym.viz.render import (BODY, FORCE, OUTLINE_SHADE, FrameRenderer, clip_segments, draw_discs,
                                draw_lines, fill_convex_polygons)

SHAPES = {
    "box": Box(kind="box", size=(0.2, 0.15, 0.1)),
    "cylinder": Cylinder(kind="cylinder", radius=0.06, height=0.12),
    "elliptic_cylinder": EllipticCylinder(kind="elliptic_cylinder", semi_axes=(0.08, 0.05), height=0.1),
    "sphere": Sphere(kind="sphere", radius=0.07),
    "none": None,
}
N = 8


def rotation(axis, angle):
    """Rodrigues: rotation by ``angle`` [rad] about ``axis``."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def hanging_nodes(top=(0.0, 0.0, 0.0), length=1.0):
    """N+1 nodes straight down (+z) from ``top`` [m]."""
    return np.asarray(top, float) + np.outer(np.linspace(0, length, N + 1), (0, 0, 1))


def blank(h=40, w=60):
    return np.zeros((h, w, 3), np.uint8)


# -- primitives ----------------------------------------------------------------------------------

def test_line_covers_its_pixels_and_nothing_else():
    c = draw_lines(blank(), [(5, 10)], [(50, 10)], (255, 0, 0), thickness=1)
    lit = np.argwhere(c[..., 0] == 255)
    assert set(lit[:, 0]) == {10} and lit[:, 1].min() == 5 and lit[:, 1].max() == 50 and len(lit) == 46


def test_thick_line_is_three_pixels_wide():
    c = draw_lines(blank(), [(10, 5)], [(10, 30)], (0, 255, 0), thickness=3)
    assert set(np.nonzero(c[20, :, 1])[0]) == {9, 10, 11}


def test_segments_are_clipped_without_wrap_around():
    # one segment far to the left, one crossing the canvas from -1e300 to +1e300: neither may
    # write a pixel through a negative index (the right-hand columns stay black except row 20)
    c = draw_lines(blank(), [(-1e6, 5), (-1e300, 20)], [(-10, 5), (1e300, 20)], (9, 9, 9), thickness=3)
    assert not c[:5].any() and not c[:18].any() and c[20].all() and not c[23:].any()
    q0, q1, keep = clip_segments([(-10.0, 5.0), (np.nan, 0), (-5, -5)], [(100.0, 5.0), (1, 1), (-1, -1)],
                                 (0, 0), (59, 39))
    assert keep.tolist() == [True, False, False]
    np.testing.assert_allclose(np.r_[q0[0], q1[0]], [0, 5, 59, 5])


@pytest.mark.parametrize("winding", [1, -1])
def test_convex_polygon_fills_its_interior_either_winding(winding):
    square = np.array([(10, 10), (20, 10), (20, 30), (10, 30)], float)[::winding]
    c = fill_convex_polygons(blank(), square, (1, 2, 3))
    lit = c[..., 2] == 3
    assert lit.sum() == 11 * 21 and lit[10:31, 10:21].all()


def test_polygons_partly_or_far_off_canvas_are_clipped():
    big = np.array([(-1e9, -1e9), (1e9, -1e9), (1e9, 1e9), (-1e9, 1e9)])
    assert (fill_convex_polygons(blank(), big, (7, 7, 7)) == 7).all()
    away = big * 1e-6 - 5e3     # a 2000 px square entirely left of and above the canvas
    assert not fill_convex_polygons(blank(), away, (7, 7, 7)).any()


def test_disc_and_ring():
    c = draw_discs(blank(), [(30, 20)], 5, (255, 255, 255))
    assert c[20, 25:36, 0].all() and not c[20, 24, 0] and not c[20, 36, 0]
    r = draw_discs(blank(), [(30, 20), (-1e300, 0)], 5, (255, 255, 255), inner=4)
    assert r[20, 25, 0] and not r[20, 30, 0]


# -- frames --------------------------------------------------------------------------------------

@pytest.mark.parametrize("size", [(480, 480), (320, 200)])
@pytest.mark.parametrize("name", SHAPES)
def test_frame_shape_and_dtype(name, size):
    r = FrameRenderer(SHAPES[name], (0.0, 0.0, 0.05), 1.0, width=size[0], height=size[1])
    f = r.render(hanging_nodes(), rotation((1, 2, 3), 0.4), np.full(N, 0.01), pivot_force=(1.0, 2.0, -3.0),
                 target_pivot=(0.1, 0.2, 0.0), target_load=(0.1, 0.2, 1.1))
    assert f.shape == (size[1], size[0], 3) and f.dtype == np.uint8


def test_projection_has_z_down_front_x_and_side_y():
    r = FrameRenderer(None, (0, 0, 0), 1.0)
    o, dz, dx, dy = r.project([(0, 0, 0), (0, 0, 0.5), (0.3, 0, 0), (0, 0.3, 0)], panel=0)
    assert dz[1] > o[1] and dz[0] == o[0] and dx[0] > o[0] and dy[0] == o[0]
    o, dz, dx, dy = r.project([(0, 0, 0), (0, 0, 0.5), (0.3, 0, 0), (0, 0.3, 0)], panel=1)
    assert dz[1] > o[1] and dy[0] > o[0] and dx[0] == o[0]
    assert o[0] >= r.width // 2       # the side view is the right-hand panel


def test_string_segments_carry_their_strain_colour():
    r = FrameRenderer(SHAPES["box"], (0.0, 0.0, 0.05), 1.0)
    nodes = hanging_nodes()
    energy = np.linspace(0.0, 0.06, N)
    f = r.render(nodes, np.eye(3), energy)
    expected = r.strain_colors(energy)
    for panel in (0, 1):
        mid = np.rint(r.project(0.5 * (nodes[:-1] + nodes[1:]), panel)).astype(int)
        np.testing.assert_array_equal(f[mid[:, 1], mid[:, 0]], expected)


def test_different_strain_energies_give_different_colours():
    r = FrameRenderer(SHAPES["box"], (0.0, 0.0, 0.05), 1.0)
    colours = r.strain_colors([0.0, 0.005, 0.02, 0.05])
    assert len({tuple(c) for c in colours}) == 4
    nodes = hanging_nodes()
    low, high = (r.render(nodes, np.eye(3), np.full(N, e)) for e in (0.001, 0.04))
    x, y = np.rint(r.project(0.5 * (nodes[3] + nodes[4]), 0)).astype(int)
    assert not np.array_equal(low[y, x], high[y, x])


def is_body_colour(pixel):
    """A body pixel is ``floor(shade * BODY)``, shade in [OUTLINE_SHADE, 1] (faces, or an edge
    that may cross the centre): the channel ratios to BODY agree to the flooring error,
    1/min(BODY) < 0.012 (0.03 allowed)."""
    s = np.asarray(pixel, float) / np.asarray(BODY, float)
    return s.max() - s.min() < 0.03 and OUTLINE_SHADE - 0.03 <= s.mean() <= 1.0


@pytest.mark.parametrize("tilt", [0.0, 0.7])
@pytest.mark.parametrize("name", SHAPES)
def test_body_colour_around_its_projected_centre(name, tilt):
    rho_c = np.array([0.0, 0.0, 0.05])
    R = rotation((1.0, -0.5, 0.3), tilt)
    r = FrameRenderer(SHAPES[name], rho_c, 1.0)
    nodes = hanging_nodes()
    f = r.render(nodes, R, np.full(N, 0.01))
    for panel in (0, 1):
        x, y = np.rint(r.project(nodes[-1] + R @ rho_c, panel)).astype(int)
        # beside the 1.5 px centre-of-mass dot, and below it, away from the string
        around = [f[y + dy, x + dx] for dx, dy in ((-4, 2), (4, 2), (0, 4))]
        assert all(is_body_colour(p) for p in around), (name, panel, around)


def test_pivot_force_draws_an_arrow():
    r = FrameRenderer(SHAPES["box"], (0.0, 0.0, 0.05), 1.0)
    args = hanging_nodes(), np.eye(3), np.full(N, 0.01)
    without, with_force = r.render(*args), r.render(*args, pivot_force=(6.0, 0.0, -4.0))
    assert not (without == FORCE).all(-1).any()
    assert (with_force == FORCE).all(-1).sum() > 50


@pytest.mark.parametrize("offset", [1e3, -1e6, 1e12, -1e300])
def test_far_out_of_view_geometry_does_not_raise(offset):
    r = FrameRenderer(SHAPES["box"], (0.0, 0.0, 0.05), 1.0)
    far = np.full(3, offset)
    for nodes in (hanging_nodes(far), np.vstack([hanging_nodes()[:-1], far])):   # all out; straddling
        f = r.render(nodes, rotation((0, 1, 0), 1.0), np.full(N, 0.01), pivot_force=(offset, 0, 0),
                     target_pivot=far, target_load=-far)
        assert f.shape == (480, 480, 3)
    with np.errstate(all="raise"):   # the renderer silences its own float warnings
        r.render(np.full((N + 1, 3), np.nan), np.full((3, 3), np.inf), np.full(N, np.nan),
                 pivot_force=(np.nan,) * 3, target_pivot=(np.inf,) * 3)


def test_geometry_left_of_the_view_does_not_wrap_to_the_right():
    r = FrameRenderer(SHAPES["box"], (0.0, 0.0, 0.05), 1.0)
    f = r.render(hanging_nodes((-100.0, -100.0, 0.0)), np.eye(3), np.full(N, 0.05), pivot_force=(-9.0, -9.0, 0),
                 target_pivot=(-100.0, -100.0, 0.0), target_load=(-100.0, -100.0, 1.0))
    for panel in r.panels:
        right = slice((panel.x0 + panel.x1) // 2, panel.x1)
        np.testing.assert_array_equal(f[:, right], r.background[:, right])


def test_render_is_fast():
    r = FrameRenderer(SHAPES["elliptic_cylinder"], (0.03, -0.02, 0.05), 1.0)
    nodes = hanging_nodes() + np.outer(np.sin(np.linspace(0, np.pi, N + 1)), (0.05, 0.03, 0))
    R = rotation((0.3, 1.0, 0.2), 0.5)
    energy = np.linspace(0.0, 0.05, N)
    kwargs = dict(pivot_force=(3.0, 1.0, -2.0), target_pivot=(0.2, 0.1, 0.0), target_load=(0.2, 0.1, 1.1))
    r.render(nodes, R, energy, **kwargs)
    t0 = time.perf_counter()
    for _ in range(50):
        r.render(nodes, R, energy, **kwargs)
    ms = (time.perf_counter() - t0) / 50 * 1e3
    # target < 5 ms per 480 x 480 frame; 20 ms leaves room for a loaded CI machine
    assert ms < 20.0, f"mean {ms:.2f} ms per frame"
