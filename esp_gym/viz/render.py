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
:func:`fill_convex_polygons`, :func:`draw_text`) are in viz/raster.py.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .geometry import Mesh, body_mesh, prism_mesh  # noqa: F401  (Mesh, prism_mesh: still importable here)
from .palette import BACKGROUND, BODY, FORCE, GRID_AXIS, GRID_MAJOR, GRID_MINOR, INK, PIVOT, STRAIN_LUT, TARGET
from .raster import clip_segments, draw_discs, draw_lines, draw_text, fill_convex_polygons  # noqa: F401

# -- shading -------------------------------------------------------------------------------------

OUTLINE_SHADE = 0.42        #: body edges are drawn in OUTLINE_SHADE * BODY
SHADE_AMBIENT = 0.5         #: shade of a face turned away from the light (1 when facing it)

#: Light direction in screen coordinates (right, down, towards the viewer): upper left, in front.
_LIGHT_SCREEN = np.array([-0.45, -0.6, 0.66]) / np.linalg.norm([-0.45, -0.6, 0.66])

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
    | `shape` | - | a :mod:`esp_gym.scene.params` shape (Box, Cylinder, EllipticCylinder, Sphere) centred on the centre of mass, or None (a disc of radius 0.04 `string_length`) |
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

    def render(self, nodes, R, strain_energy, pivot_force=None, target_pivot=None, target_load=None,
               drone=None) -> np.ndarray:
        """One frame, uint8 (height, width, 3).

        nodes: (N+1, 3) node positions, spatial frame [m]; row 0 the pivot, row N the attachment
        point. R: (3, 3) body -> spatial rotation (a body point b is at ``nodes[-1] + R @ b``).
        strain_energy: (N,) per element [J]. pivot_force: (3,) [N], drawn from the pivot as an
        arrow ``force_scale`` m/N long. target_pivot, target_load: (3,) [m], where the pivot and
        the load's centre of mass should be. Any of the last three may be None (not drawn).
        drone: None (the pivot's icon) or (R_q (3, 3), rotor positions (4, 3) in its body frame
        [m]): the drone drawn at the pivot, its arms to its rotors' rings, as it is turned.
        """
        return self._draw([(nodes, strain_energy)], R, [pivot_force], [target_pivot], target_load, [drone])

    def render_team(self, strings, R, pivot_forces=None, target_pivots=None, target_load=None) -> np.ndarray:
        """One frame of a team (esp_gym/team), uint8 (height, width, 3): :meth:`render`'s picture
        with K strings, pivots, pivot forces and pivot targets.

        strings: K pairs ``(nodes (N_k+1, 3) [m], strain energy (N_k,) [J])``, row 0 the pivot,
        the last row the attachment point; string 0's is the one ``rho_c`` is measured from (a
        body point b is at ``strings[0][0][-1] + R @ b``). pivot_forces, target_pivots: (K, 3) or
        None; target_load: (3,) or None.
        """
        K = len(strings)
        forces = [None] * K if pivot_forces is None else list(np.asarray(pivot_forces, float).reshape(K, 3))
        targets = [None] * K if target_pivots is None else list(np.asarray(target_pivots, float).reshape(K, 3))
        return self._draw(strings, R, forces, targets, target_load, [None] * K)

    def _draw(self, strings, R, pivot_forces, target_pivots, target_load, drones) -> np.ndarray:
        """The frame of strings ``[(nodes, strain energy)]`` and the body (string 0's attachment
        the reference of ``rho_c``), each string's pivot force, pivot target and drone (or None)."""
        drawn = []
        for nodes, strain_energy in strings:
            nodes = np.asarray(nodes, dtype=float).reshape(-1, 3)
            seg_rgb = self.strain_colors(strain_energy).reshape(-1, 3)
            if len(seg_rgb) != len(nodes) - 1:
                raise ValueError(f"strain_energy needs one value per element ({len(nodes) - 1}), got {len(seg_rgb)}")
            drawn.append((nodes, seg_rgb))
        R = np.asarray(R, dtype=float).reshape(3, 3)
        frame = self._background.copy()
        px = self._px
        with np.errstate(all="ignore"):
            attach = drawn[0][0][-1]
            center = attach + R @ self.rho_c
            if self.mesh is not None:
                verts = attach + self.mesh.vertices @ R.T
                normals = self.mesh.normals @ R.T
            else:
                verts = normals = None
            for panel in self.panels:
                view = frame[:, panel.x0:panel.x1]
                pixels = [nodes @ panel.proj + panel.offset for nodes, _ in drawn]
                self._draw_body(view, panel, verts, normals, center)
                c = center @ panel.proj + panel.offset
                if self._rod:
                    draw_lines(view, pixels[0][-1], c, PIVOT, 1.0)      # no shape: a rod to the centre of mass
                draw_discs(view, c, px(1.5), PIVOT)
                for pix, (_, seg_rgb) in zip(pixels, drawn):
                    draw_lines(view, pix[:-1], pix[1:], seg_rgb, px(3))
                    draw_discs(view, pix[-1], px(2.5), PIVOT)
                for target in target_pivots:
                    if target is not None:
                        self._marker(view, np.asarray(target, float) @ panel.proj + panel.offset, "ring")
                if target_load is not None:
                    self._marker(view, np.asarray(target_load, float) @ panel.proj + panel.offset, "cross")
                for pix, (nodes, _), drone in zip(pixels, drawn, drones):
                    if drone is None:
                        self._marker(view, pix[0], "drone")
                        continue
                    rotors = (nodes[0] + np.asarray(drone[1], float) @ np.asarray(drone[0], float).T) @ panel.proj \
                        + panel.offset
                    draw_lines(view, np.repeat(pix[:1], len(rotors), axis=0), rotors, PIVOT, px(2))
                    draw_discs(view, rotors, px(5), PIVOT, inner=px(3.5))
                    fill_convex_polygons(view, pix[0] + np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)]) * px(3),
                                         PIVOT)
                for pix, force in zip(pixels, pivot_forces):
                    if force is not None and np.isfinite(pix[0]).all():
                        tip = pix[0] + self.force_scale * (np.asarray(force, float) @ panel.proj)
                        self._arrows(view, pix[:1], tip[None], FORCE, px(2), px(9))
            frame[:, self.panels[1].x0] = INK                # divider
        return frame
