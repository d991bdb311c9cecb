"""Rasterising primitives of the ``rgb_array`` renderer (viz/render.py): pure functions on a uint8
canvas ``(height, width, 3)``, vectorised over pixels and shapes, with no per-pixel Python loop.

Pixel ``(row, col)`` has its centre at the float point ``(x=col, y=row)``; geometry is clipped to
the canvas (segments by Liang-Barsky before they are sampled, so a segment reaching 1e300 m
costs nothing), non-finite geometry is skipped, and no negative index ever reaches the canvas
(so nothing wraps around).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

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
