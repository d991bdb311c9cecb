"""Software renderer of ``rgb_array`` frames: NumPy only, no matplotlib, no fonts.

:class:`FrameRenderer` draws one frame (uint8, ``(height, width, 3)``) per call: two
orthographic panels side by side, both with z growing *downwards* on screen (gravity is +e3):

* left, **front**: x right, z down, seen from +y (looking along -e2);
* right, **side**: y right, z down, seen from -x (looking along +e1).

Right, down and towards-the-viewer form a right-handed frame in both, so neither panel is a
mirror image. Each panel shows the string coloured element by element by its strain energy, the
body as a flat-shaded convex solid with its silhouette and sharp edges outlined, the pivot (a
dark square with arms, a drone or crane hook), the pivot target (crimson ring), the load target
(crimson cross in a ring: where the body's centre of mass should be), and the pivot force as a
magenta arrow. Pivot and targets outside a panel appear as small dots on its border, towards
where they are. A light grid (every ``grid_step`` m, darker every metre and on x, y, z = 0), a
label, an axes icon and a strain colour bar are drawn once into a cached background.

The rasterising primitives (:func:`draw_lines`, :func:`draw_discs`,
:func:`fill_convex_polygons`) are pure functions on a uint8 canvas, vectorised over pixels and
shapes, with no per-pixel Python loop. Pixel ``(row, col)`` has its centre at the float point
``(x=col, y=row)``; geometry is clipped to the canvas (segments by Liang-Barsky before they are
sampled, so a segment reaching 1e300 m costs nothing), non-finite geometry is skipped, and no
negative index ever reaches the canvas (so nothing wraps around).
"""
from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple, Optional

import numpy as np

# -- colours (RGB, uint8) ------------------------------------------------------------------------

#: Anchors of the strain colour ramp, low to high: purple, blue, teal, green, yellow (a
#: perceptually ordered, viridis-like ramp, defined here and interpolated to :data:`STRAIN_LUT`).
_RAMP_ANCHORS = np.array([(68, 1, 84), (65, 68, 135), (42, 120, 142), (34, 168, 132),
                          (122, 209, 81), (253, 231, 37)], dtype=float)
#: 256-entry lookup table of the strain ramp, (256, 3) uint8.
STRAIN_LUT = np.stack([np.interp(np.linspace(0, 1, 256), np.linspace(0, 1, len(_RAMP_ANCHORS)),
                                 _RAMP_ANCHORS[:, c]) for c in range(3)], axis=1).round().astype(np.uint8)

BACKGROUND = (250, 250, 247)
GRID_MINOR = (232, 232, 228)
GRID_MAJOR = (212, 212, 208)
GRID_AXIS = (182, 182, 190)
INK = (70, 70, 78)          #: labels, axes icon, panel divider
BODY = (226, 150, 84)       #: body base colour, scaled by the shade in [SHADE_AMBIENT, 1]
PIVOT = (38, 38, 46)
TARGET = (214, 30, 50)
FORCE = (190, 40, 170)
OUTLINE_SHADE = 0.42        #: body edges are drawn in OUTLINE_SHADE * BODY
SHADE_AMBIENT = 0.5         #: shade of a face turned away from the light (1 when facing it)

#: Light direction in screen coordinates (right, down, towards the viewer): upper left, in front.
_LIGHT_SCREEN = np.array([-0.45, -0.6, 0.66]) / np.linalg.norm([-0.45, -0.6, 0.66])


# -- primitives ----------------------------------------------------------------------------------

@lru_cache(maxsize=64)
def _kernel(r_out: float, r_in: float = -1.0) -> np.ndarray:
    """Integer offsets (m, 2) as (dx, dy) with r_in <= |(dx, dy)| <= r_out [px] (a disc, or a
    ring when r_in >= 0); always holds at least the centre unless r_in > 0."""
    n = int(np.ceil(r_out))
    dy, dx = np.mgrid[-n:n + 1, -n:n + 1]
    d = np.hypot(dx, dy)
    keep = (d <= r_out + 1e-9) & (d >= r_in - 1e-9)
    if r_in <= 0:
        keep |= (dx == 0) & (dy == 0)
    out = np.stack([dx[keep], dy[keep]], axis=1).astype(np.intp)
    out.setflags(write=False)
    return out


def _stamp(canvas: np.ndarray, points: np.ndarray, offsets: np.ndarray, colors: np.ndarray) -> None:
    """Write ``colors`` (n, 3) at every rounded point (n, 2) of bounded magnitude plus every
    offset (m, 2); pixels off the canvas are dropped before indexing."""
    h, w = canvas.shape[:2]
    c = np.rint(points).astype(np.intp)
    xs = (c[:, 0, None] + offsets[None, :, 0]).ravel()
    ys = (c[:, 1, None] + offsets[None, :, 1]).ravel()
    ok = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
    canvas[ys[ok], xs[ok]] = np.repeat(colors, len(offsets), axis=0)[ok]


def _as_colors(colors, n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(colors, dtype=np.uint8).reshape(-1, 3), (n, 3))


def clip_segments(p0: np.ndarray, p1: np.ndarray, lo, hi):
    """Liang-Barsky clipping of segments ``p0 -> p1`` (n, 2) to the box ``lo <= p <= hi``.

    A point of the segment is ``p0 + t (p1 - p0)``, t in [0, 1]; each box side bounds t from
    below (entering) or above (leaving). Returns ``(q0, q1, keep)``: the clipped end points of the
    kept segments and the boolean mask (n,) of segments that are finite and meet the box.
    """
    p0 = np.asarray(p0, dtype=float).reshape(-1, 2)
    p1 = np.asarray(p1, dtype=float).reshape(-1, 2)
    with np.errstate(all="ignore"):
        d = p1 - p0
        keep = np.isfinite(p0).all(1) & np.isfinite(p1).all(1) & np.isfinite(d).all(1)
        # t-bounds of the sides x >= lo_x, x <= hi_x, y >= lo_y, y <= hi_y: p t <= q
        p = np.stack([-d[:, 0], d[:, 0], -d[:, 1], d[:, 1]], axis=1)
        q = np.stack([p0[:, 0] - lo[0], hi[0] - p0[:, 0], p0[:, 1] - lo[1], hi[1] - p0[:, 1]], axis=1)
        r = q / p
        enter, leave = np.where(p < 0, r, -np.inf), np.where(p > 0, r, np.inf)
        t0 = np.maximum(enter.max(axis=1), 0.0)
        t1 = np.minimum(leave.min(axis=1), 1.0)
        keep &= ~((p == 0) & (q < 0)).any(axis=1) & (t0 <= t1)
        ends = []
        for t, side in ((t0, enter.argmax(axis=1)), (t1, leave.argmin(axis=1))):
            e = p0 + t[:, None] * d
            # an end on a side lies exactly on it (far end points lose every digit to round-off)
            cut = (t > 0) & (t < 1)
            bound = np.array([lo[0], hi[0], lo[1], hi[1]], dtype=float)[side]
            e[cut, side[cut] // 2] = bound[cut]
            ends.append(np.clip(e[keep], lo, hi))
        return ends[0], ends[1], keep


def draw_lines(canvas: np.ndarray, p0, p1, colors, thickness: float = 1.0) -> np.ndarray:
    """Draw segments ``p0[i] -> p1[i]`` (n, 2) pixel coordinates (x = column, y = row) in
    ``colors`` ((3,) or (n, 3) uint8), ``thickness`` px wide, in place; returns ``canvas``.

    Each segment is clipped to the canvas grown by half the thickness, sampled every <= 0.7 px,
    and a disc of diameter ``thickness`` is stamped at every sample. Later segments overwrite
    earlier ones.
    """
    h, w = canvas.shape[:2]
    r = 0.5 * thickness
    q0, q1, keep = clip_segments(p0, p1, (-r, -r), (w - 1 + r, h - 1 + r))
    if not len(q0):
        return canvas
    colors = _as_colors(colors, len(keep))[keep]
    d = q1 - q0
    n = np.ceil(np.hypot(d[:, 0], d[:, 1]) / 0.7).astype(np.intp) + 1
    seg = np.repeat(np.arange(len(n)), n)
    t = (np.arange(n.sum()) - (np.cumsum(n) - n)[seg]) / np.maximum(n - 1, 1)[seg]
    _stamp(canvas, q0[seg] + t[:, None] * d[seg], _kernel(r), colors[seg])
    return canvas


def draw_discs(canvas: np.ndarray, centers, radius: float, colors, inner: float = -1.0) -> np.ndarray:
    """Draw discs of ``radius`` px at ``centers`` (n, 2) (x, y), rounded to whole pixels, in
    ``colors`` ((3,) or (n, 3)), in place; with ``inner >= 0`` only the ring
    ``inner <= distance <= radius``. Returns ``canvas``."""
    h, w = canvas.shape[:2]
    centers = np.asarray(centers, dtype=float).reshape(-1, 2)
    with np.errstate(invalid="ignore"):
        keep = ((centers[:, 0] > -radius - 1) & (centers[:, 0] < w + radius)
                & (centers[:, 1] > -radius - 1) & (centers[:, 1] < h + radius))
    if keep.any():
        _stamp(canvas, centers[keep], _kernel(float(radius), float(inner)),
               _as_colors(colors, len(centers))[keep])
    return canvas


def fill_convex_polygons(canvas: np.ndarray, polygons, colors) -> np.ndarray:
    """Fill convex polygons ``polygons`` ((k, 2) or (p, k, 2) vertices x, y, either winding;
    repeat a vertex to pad a shorter one) in ``colors`` ((3,) or (p, 3)), in place.

    A pixel centre c is inside when it is on the inner side of every edge a -> b:
    ``s * cross(b - a, c - a) >= 0``, s the sign of the polygon's area. All polygons are tested
    over the canvas part of their common bounding box at once (one (p, k, rows, cols) array, so
    pass polygons that lie close together); where they overlap, the later one wins. Non-finite
    polygons are skipped. Returns ``canvas``.
    """
    h, w = canvas.shape[:2]
    poly = np.asarray(polygons, dtype=float)
    if poly.ndim == 2:
        poly = poly[None]
    colors = _as_colors(colors, len(poly))
    keep = np.isfinite(poly).all(axis=(1, 2))
    poly, colors = poly[keep], colors[keep]
    if not len(poly):
        return canvas
    lo = np.floor(np.maximum(poly.min(axis=(0, 1)), 0.0))
    hi = np.ceil(np.minimum(poly.max(axis=(0, 1)), (w - 1, h - 1)))
    if np.any(hi < lo):
        return canvas
    x0, y0, x1, y1 = int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1])
    xs = np.arange(x0, x1 + 1, dtype=float)
    ys = np.arange(y0, y1 + 1, dtype=float)
    with np.errstate(all="ignore"):
        a = poly
        e = np.roll(poly, -1, axis=1) - a
        s = np.sign(np.sum(a[..., 0] * e[..., 1] - a[..., 1] * e[..., 0], axis=1))
        s[s == 0] = 1.0
        # s cross(e, c - a) = A x + B y + C for a pixel centre c = (x, y)
        A = (-e[..., 1] * s[:, None])[..., None, None]
        B = (e[..., 0] * s[:, None])[..., None, None]
        C = ((e[..., 1] * a[..., 0] - e[..., 0] * a[..., 1]) * s[:, None])[..., None, None]
        inside = (A * xs + B * ys[:, None] + C >= -1e-9).all(axis=1)   # (p, rows, cols)
    hit = inside.any(axis=0)
    last = len(poly) - 1 - inside[::-1].argmax(axis=0)
    region = canvas[y0:y1 + 1, x0:x1 + 1]
    region[hit] = colors[last[hit]]
    return canvas


# -- text (a 3x5 pixel font with the few letters the labels use) --------------------------------

_GLYPHS = {
    "A": (".#.", "#.#", "###", "#.#", "#.#"), "D": ("##.", "#.#", "#.#", "#.#", "##."),
    "E": ("###", "#..", "##.", "#..", "###"), "F": ("###", "#..", "##.", "#..", "#.."),
    "I": ("###", ".#.", ".#.", ".#.", "###"), "N": ("#..#", "##.#", "#.##", "#..#", "#..#"),
    "O": ("###", "#.#", "#.#", "#.#", "###"), "R": ("##.", "#.#", "##.", "#.#", "#.#"),
    "S": (".##", "#..", ".#.", "..#", "##."), "T": ("###", ".#.", ".#.", ".#.", ".#."),
    "X": ("#.#", "#.#", ".#.", "#.#", "#.#"), "Y": ("#.#", "#.#", ".#.", ".#.", ".#."),
    "Z": ("###", "..#", ".#.", "#..", "###"), " ": ("..", "..", "..", "..", ".."),
}


def _text_mask(text: str, scale: int) -> np.ndarray:
    cols = []
    for ch in text.upper():
        g = np.array([[c == "#" for c in row] for row in _GLYPHS[ch]])
        cols += [g, np.zeros((5, 1), bool)]
    return np.kron(np.hstack(cols[:-1]), np.ones((scale, scale), bool))


def draw_text(canvas: np.ndarray, x: int, y: int, text: str, color, scale: int = 1) -> np.ndarray:
    """Write ``text`` (letters of :data:`_GLYPHS`) with its top-left corner at column ``x``, row
    ``y``, ``5 * scale`` px tall, clipped to the canvas; returns ``canvas``."""
    m = _text_mask(text, scale)
    ys, xs = np.nonzero(m)
    _stamp(canvas, np.stack([xs + x, ys + y], axis=1), np.zeros((1, 2), np.intp),
           _as_colors(color, len(xs)))
    return canvas


# -- bodies --------------------------------------------------------------------------------------

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
    """The drawn mesh of a :mod:`esp_gym.params` shape centred on ``rho_c`` (body frame, from
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


# -- the renderer --------------------------------------------------------------------------------

class _Panel(NamedTuple):
    x0: int                 #: first frame column of the panel
    x1: int                 #: one past its last column
    proj: np.ndarray        #: (3, 2): pixel (x, y) = P @ proj + offset, P a spatial point [m]
    offset: np.ndarray      #: (2,)
    toward: np.ndarray      #: unit vector towards the viewer, spatial frame
    light: np.ndarray       #: unit vector towards the light, spatial frame


class FrameRenderer:
    """Renders uint8 RGB frames (front and side orthographic panels) of the string and its load.

    Arguments (lengths [m], spatial frame, gravity along +e3 so z grows downwards on screen):

    | argument | default | meaning |
    |---|---|---|
    | `shape` | - | a :mod:`esp_gym.params` shape (Box, Cylinder, EllipticCylinder, Sphere) centred on the centre of mass, or None (a disc of radius 0.04 `string_length`) |
    | `rho_c` | - | attachment point -> centre of mass, body frame [m] |
    | `string_length` | - | unstretched string length [m] (sizes the body of a None shape) |
    | `width`, `height` | 480, 480 | frame size [px]; each panel is `width // 2` wide |
    | `view_center` | (0, 0, 0.6) | spatial point at the centre of both panels (front uses x, z; side y, z) [m] |
    | `view_extent` | 2.5 | world span of a panel's height [m]; its width spans `view_extent * panel_width / height` (1.25 m at 480 x 480) |
    | `strain_scale` | 0.05 | fixed strain-energy scale [J]: an element's colour is `STRAIN_LUT` at `sqrt(E / strain_scale)` clipped to [0, 1] (the square root makes it linear in the tension); the drone_load scene's elements hold T^2 / (2 EA/u) = 8 mJ at rest (T = 5 N), 40 % up the ramp; its top is 2.5x the static tension |
    | `force_scale` | 0.05 | pivot-force arrow length per newton [m/N] (a 9 N force draws 0.45 m) |
    | `grid_step` | 0.25 | grid spacing [m]; every metre and the x, y, z = 0 lines are darker |
    """

    def __init__(self, shape, rho_c, string_length, width=480, height=480, view_center=(0.0, 0.0, 0.6),
                 view_extent=2.5, strain_scale=0.05, force_scale=0.05, grid_step=0.25):
        if width < 16 or height < 16:
            raise ValueError(f"frame must be at least 16 x 16 px, got {width} x {height}")
        if not (view_extent > 0 and strain_scale > 0 and force_scale >= 0 and grid_step > 0 and string_length > 0):
            raise ValueError("view_extent, strain_scale, grid_step and string_length must be > 0, force_scale >= 0")
        self.width, self.height = int(width), int(height)
        self.strain_scale = float(strain_scale)
        self.force_scale = float(force_scale)
        self.rho_c = np.asarray(rho_c, dtype=float)
        self.scale = self.height / float(view_extent)      #: [px/m], both panels
        self._unit = self.height / 480.0                   # marker and line sizes: 1 at 480 px high
        self.body_rgb = np.array(BODY, dtype=float)

        self.mesh = body_mesh(shape, self.rho_c)
        kind = getattr(shape, "kind", None)
        if shape is not None and kind not in ("box", "cylinder", "elliptic_cylinder", "sphere"):
            raise ValueError(f"cannot draw a body of shape {shape!r}")
        self._rod = shape is None           # no shape: a disc at the centre of mass on a rod
        self._disc_radius = shape.radius if kind == "sphere" else 0.04 * float(string_length)

        c = np.asarray(view_center, dtype=float)
        e = np.eye(3)
        half = self.width // 2
        self.panels = []
        for x0, x1, right, toward in ((0, half, e[0], e[1]), (half, self.width, e[1], -e[0])):
            down = e[2]
            proj = np.stack([right, down], axis=1) * self.scale
            mid = np.array([(x1 - x0 - 1) / 2.0, (self.height - 1) / 2.0])
            light = _LIGHT_SCREEN @ np.stack([right, down, toward])
            self.panels.append(_Panel(x0, x1, proj, mid - c @ proj, toward, light))
        self._background = self._draw_background(float(grid_step))
        self._background.setflags(write=False)

    def _px(self, base: float) -> float:
        """A size of ``base`` px at 480 px high, scaled to this frame, whole and >= 1 [px]."""
        return max(1.0, round(base * self._unit))

    @property
    def background(self) -> np.ndarray:
        """The cached frame without any state drawn (grid, labels, colour bar), read-only."""
        return self._background

    def project(self, points, panel: int) -> np.ndarray:
        """Frame pixel coordinates (..., 2) as (x = column, y = row) of spatial ``points``
        (..., 3) [m] in panel 0 (front) or 1 (side)."""
        p = self.panels[panel]
        return np.asarray(points, dtype=float) @ p.proj + p.offset + (p.x0, 0)

    def strain_colors(self, strain_energy) -> np.ndarray:
        """Colours (n, 3) uint8 of elements with strain energies (n,) [J] (see `strain_scale`)."""
        e = np.nan_to_num(np.asarray(strain_energy, dtype=float), nan=0.0, posinf=1e300, neginf=0.0)
        x = np.sqrt(np.clip(e / self.strain_scale, 0.0, 1.0))
        return STRAIN_LUT[np.rint(x * 255).astype(np.intp)]

    # -- drawing ---------------------------------------------------------------------------
    def _draw_background(self, step: float) -> np.ndarray:
        frame = np.empty((self.height, self.width, 3), np.uint8)
        frame[:] = BACKGROUND
        for k, (panel, name, axis) in enumerate(zip(self.panels, ("FRONT", "SIDE"), "XY")):
            view = frame[:, panel.x0:panel.x1]
            h, w = view.shape[:2]
            for dim, n in ((0, w), (1, h)):                  # vertical lines, then horizontal
                vec = panel.proj[:, dim]
                j = int(np.nonzero(vec)[0][0])
                s, off = vec[j], panel.offset[dim]
                g = np.arange(np.ceil(-off / s / step), np.floor((n - 1 - off) / s / step) + 1) * step
                for value in g:                               # a few dozen lines, once
                    pix = int(round(value * s + off))
                    major = abs(value - round(value)) < 1e-9
                    color = GRID_AXIS if abs(value) < 1e-9 else GRID_MAJOR if major else GRID_MINOR
                    if dim == 0:
                        view[:, pix] = color
                    else:
                        view[pix, :] = color
            ts = int(self._px(2))
            draw_text(view, 2 * ts + 2, 2 * ts + 2, name, INK, ts)
            # axes icon, bottom left: the panel's right axis and z (down)
            L, o = self._px(22), np.array([self._px(10), h - 1 - self._px(34)])
            tips = np.array([o + (L, 0), o + (0, L)])
            self._arrows(view, np.array([o, o]), tips, INK, 1.0, self._px(5))
            draw_text(view, int(tips[0, 0] + self._px(4)), int(o[1] - 2.5 * ts), axis, INK, ts)
            draw_text(view, int(o[0] + self._px(5)), int(tips[1, 1] - 4 * ts), "Z", INK, ts)
            if k == 1:                                        # strain colour bar, bottom right
                bw, bh = int(self._px(72)), int(self._px(6))
                bx, by = w - bw - int(self._px(10)), h - bh - int(self._px(10))
                view[by:by + bh, bx:bx + bw] = STRAIN_LUT[np.linspace(0, 255, bw).astype(int)]
                draw_text(view, bx, by - 7 * ts, "STRAIN", INK, ts)
        return frame

    def _arrows(self, view, tails, tips, color, thickness, head):
        """Arrows tails -> tips (n, 2) px with a triangular head ``head`` px long."""
        d = tips - tails
        n = np.hypot(d[:, 0], d[:, 1])
        ok = n > 1.0
        if not ok.any():
            return
        tails, tips, d = tails[ok], tips[ok], d[ok] / n[ok, None]
        hl = np.minimum(head, n[ok])[:, None]
        base = tips - d * hl
        perp = np.stack([-d[:, 1], d[:, 0]], 1) * 0.5 * hl
        draw_lines(view, tails, base, color, thickness)
        for tip, b, p in zip(tips, base, perp):
            fill_convex_polygons(view, np.array([tip, b + p, b - p]), color)

    def _marker(self, view, p, kind):
        """Draw marker ``kind`` ("drone", "ring" or "cross") at pixel point p of the view; when p
        is outside the view, a small dot of its colour on the nearest border point instead."""
        if not np.isfinite(p).all():
            return
        h, w = view.shape[:2]
        px = self._px
        color = PIVOT if kind == "drone" else TARGET
        if not (0 <= p[0] <= w - 1 and 0 <= p[1] <= h - 1):
            m = px(4)
            draw_discs(view, np.clip(p, m, (w - 1 - m, h - 1 - m)), m, color)
        elif kind == "ring":
            draw_discs(view, p, px(9), color, inner=px(7))
        elif kind == "cross":
            a = px(6)
            draw_lines(view, [p - a, p + (a, -a)], [p + a, p + (-a, a)], color, px(2))
            draw_discs(view, p, px(10), color, inner=px(8))
        else:                       # drone: arm, two posts, two rotors, a square hull
            arm, rotor, up = px(13), px(6), px(5)
            x, y = p
            tails = [(x - arm, y), (x - arm, y), (x + arm, y), (x - arm - rotor, y - up),
                     (x + arm - rotor, y - up)]
            heads = [(x + arm, y), (x - arm, y - up), (x + arm, y - up), (x - arm + rotor, y - up),
                     (x + arm + rotor, y - up)]
            draw_lines(view, tails, heads, color, px(2))      # arm, posts, rotors
            fill_convex_polygons(view, p + np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)]) * px(4), color)

    def _draw_body(self, view, panel, verts, normals, center):
        """Flat-shaded visible faces of the mesh (spatial ``verts``, ``normals``), then its
        silhouette and sharp edges; a shaded disc for a sphere (or no shape)."""
        outline = (self.body_rgb * OUTLINE_SHADE).astype(np.uint8)
        if self.mesh is None:
            c = center @ panel.proj + panel.offset
            r = self._disc_radius * self.scale
            h, w = view.shape[:2]
            if not (np.isfinite(c).all() and -r < c[0] < w + r and -r < c[1] < h + r):
                return
            x0, x1 = int(max(np.floor(c[0] - r), 0)), int(min(np.ceil(c[0] + r), w - 1))
            y0, y1 = int(max(np.floor(c[1] - r), 0)), int(min(np.ceil(c[1] + r), h - 1))
            dx = (np.arange(x0, x1 + 1) - c[0]) / r
            dy = (np.arange(y0, y1 + 1) - c[1])[:, None] / r
            rr = dx * dx + dy * dy
            inside = rr <= 1.0
            nz = np.sqrt(np.maximum(1.0 - rr, 0.0))         # screen normal (dx, dy, nz) of the sphere
            lit = np.maximum(dx * _LIGHT_SCREEN[0] + dy * _LIGHT_SCREEN[1] + nz * _LIGHT_SCREEN[2], 0.0)
            rgb = (SHADE_AMBIENT + (1 - SHADE_AMBIENT) * lit)[..., None] * self.body_rgb
            view[y0:y1 + 1, x0:x1 + 1][inside] = rgb[inside].astype(np.uint8)
            draw_discs(view, c, r, outline, inner=r - 1.0)
            return
        m = self.mesh
        pix = verts @ panel.proj + panel.offset
        visible = normals @ panel.toward > 1e-9
        shade = SHADE_AMBIENT + (1 - SHADE_AMBIENT) * np.maximum(normals @ panel.light, 0.0)
        rgb = (shade[:, None] * self.body_rgb).astype(np.uint8)
        k = len(m.sides)
        vs, vc = visible[:k], visible[k:]
        if vs.any():
            fill_convex_polygons(view, pix[m.sides[vs]], rgb[:k][vs])
        if vc.any():
            fill_convex_polygons(view, pix[m.caps[vc]], rgb[k:][vc])
        f0, f1 = visible[m.edge_faces[:, 0]], visible[m.edge_faces[:, 1]]
        drawn = (f0 != f1) | (m.sharp & f0 & f1)
        e = m.edges[drawn]
        draw_lines(view, pix[e[:, 0]], pix[e[:, 1]], outline, 1.0)

    def render(self, nodes, R, strain_energy, pivot_force=None, target_pivot=None, target_load=None) -> np.ndarray:
        """One frame, uint8 (height, width, 3).

        nodes: (N+1, 3) node positions, spatial frame [m]; row 0 the pivot, row N the attachment
        point. R: (3, 3) body -> spatial rotation (a body point b is at ``nodes[-1] + R @ b``).
        strain_energy: (N,) per element [J]. pivot_force: (3,) [N], drawn from the pivot as an
        arrow ``force_scale`` m/N long. target_pivot, target_load: (3,) [m], where the pivot and
        the load's centre of mass should be. Any of the last three may be None (not drawn).
        """
        nodes = np.asarray(nodes, dtype=float).reshape(-1, 3)
        R = np.asarray(R, dtype=float).reshape(3, 3)
        seg_rgb = self.strain_colors(strain_energy).reshape(-1, 3)
        if len(seg_rgb) != len(nodes) - 1:
            raise ValueError(f"strain_energy needs one value per element ({len(nodes) - 1}), got {len(seg_rgb)}")
        frame = self._background.copy()
        px = self._px
        with np.errstate(all="ignore"):
            attach = nodes[-1]
            center = attach + R @ self.rho_c
            if self.mesh is not None:
                verts = attach + self.mesh.vertices @ R.T
                normals = self.mesh.normals @ R.T
            else:
                verts = normals = None
            for panel in self.panels:
                view = frame[:, panel.x0:panel.x1]
                pix = nodes @ panel.proj + panel.offset
                self._draw_body(view, panel, verts, normals, center)
                c = center @ panel.proj + panel.offset
                if self._rod:
                    draw_lines(view, pix[-1], c, PIVOT, 1.0)      # no shape: a rod to the centre of mass
                draw_discs(view, c, px(1.5), PIVOT)
                draw_lines(view, pix[:-1], pix[1:], seg_rgb, px(3))
                draw_discs(view, pix[-1], px(2.5), PIVOT)
                if target_pivot is not None:
                    self._marker(view, np.asarray(target_pivot, float) @ panel.proj + panel.offset, "ring")
                if target_load is not None:
                    self._marker(view, np.asarray(target_load, float) @ panel.proj + panel.offset, "cross")
                self._marker(view, pix[0], "drone")
                if pivot_force is not None and np.isfinite(pix[0]).all():
                    tip = pix[0] + self.force_scale * (np.asarray(pivot_force, float) @ panel.proj)
                    self._arrows(view, pix[:1], tip[None], FORCE, px(2), px(9))
            frame[:, self.panels[1].x0] = INK                # divider
        return frame
