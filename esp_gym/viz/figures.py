"""Matplotlib figures of a run, after the paper's numerical example.

* :func:`plot_fig_ns` -- Fig. NS, six diagnostics panels: energy transfer, total energy, pi3,
  orthogonality of R, second components of the body's velocities, stretched length.
* :func:`plot_fig_sm` -- Fig. SM, four 3-D panels of snapshots: the string coloured element by
  element by its strain energy, the body drawn as the paper's elliptic cylinder.

Figures are drawn on a bare :class:`~matplotlib.figure.Figure` with an Agg canvas, so importing
this module neither imports pyplot nor changes the user's backend.

Frames: gravity acts along +e3, so z grows downwards. The 3-D panels invert the z axis (the
pendulum hangs down) and also the y axis: two reflections make a rotation, so the picture is a
true view of the motion, not its mirror image. Tick labels stay the spatial coordinates [m].
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from ..extras import require

matplotlib = require("matplotlib", "esp_gym.viz.figures")  # the plot extra, then the parts used
from matplotlib import colors as mcolors
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection  # registers "3d"

#: The paper's elliptic cylinder (body frame): semi-axes along body x and y, height along body z [m];
#: the default when a scene has no cylinder shape.
CYLINDER_SEMI_AXES = (0.06, 0.04)
CYLINDER_HEIGHT = 0.1

#: Colours of the energy-transfer panel, as in the paper's caption.
ENERGY_COLOURS = {
    "kinetic_body": ("tab:red", "kinetic, body"),
    "kinetic_string": ("black", "kinetic, string"),
    "potential_gravity": ("tab:green", "gravitational potential"),
    "potential_elastic": ("tab:blue", "elastic potential"),
}

_RC = {"font.size": 10, "axes.titlesize": 10.5, "axes.labelsize": 10, "legend.fontsize": 8.5,
       "xtick.labelsize": 9, "ytick.labelsize": 9}


def new_figure(figsize) -> Figure:
    """A bare figure on an Agg canvas (no pyplot, the user's backend untouched)."""
    fig = Figure(figsize=figsize, dpi=150)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path) -> Path:
    """Write ``fig`` to ``path`` (parent directories made) at 150 dpi on white; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=150, facecolor="white")
    return path


def binned(t: np.ndarray, y: np.ndarray, bins: int = 1000):
    """Cut a long series into ``bins`` consecutive bins: (bin centre times, min, median, max).
    Series with at most ``2 * bins`` samples come back unbinned (min = median = max = y)."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if len(y) <= 2 * bins:
        return t, y, y, y
    edges = np.linspace(0, len(y), bins + 1).astype(int)
    starts = edges[:-1]
    tb = 0.5 * (t[starts] + t[edges[1:] - 1])
    lo = np.minimum.reduceat(y, starts)
    hi = np.maximum.reduceat(y, starts)
    med = np.array([np.median(y[i:j]) for i, j in zip(starts, edges[1:])])
    return tb, lo, med, hi


def _band(ax, t, y, colour="black", label=None, bins: int = 1000):
    """Draw a long, noisy series as the band between its per-bin minimum and maximum (a plain
    line when it is short), so round-off noise reads as a band rather than a black smear."""
    tb, lo, _, hi = binned(t, y, bins)
    if len(tb) == len(t):
        ax.plot(t, y, color=colour, lw=0.8, label=label)
    else:
        ax.fill_between(tb, lo, hi, color=colour, lw=0.3, alpha=0.85, label=label)


def _note(ax, text, loc="lower left"):
    """A small text box in a corner of ``ax``."""
    x, ha = (0.02, "left") if "left" in loc else (0.98, "right")
    y, va = (0.04, "bottom") if "lower" in loc else (0.96, "top")
    ax.text(x, y, text, transform=ax.transAxes, ha=ha, va=va, fontsize=8.5,
            bbox=dict(boxstyle="round,pad=0.3", fc="white", ec="0.7", alpha=0.9))


def _series(traj, name: str):
    """(t, values, is_every_step) of ``name``: the every-step series when the run kept it,
    otherwise the snapshots. The every-step series starts after step 1, so t = 0 is prepended."""
    every = getattr(traj, f"{name}_every_step", None)
    if every is not None and len(every) and traj.t_every_step is not None:
        return (np.concatenate([traj.t[:1], traj.t_every_step]),
                np.concatenate([getattr(traj, name)[:1], every]), True)
    return traj.t, getattr(traj, name), False


def _energy_transfer_panel(a, traj) -> None:
    """Fig. NS's panel (a): the kinetic energies of the body and of the string, the gravitational and
    elastic potentials [J]."""
    t = traj.t
    for name, (colour, label) in ENERGY_COLOURS.items():
        a.plot(t, getattr(traj, name), color=colour, lw=1.2, label=label)
    a.set_ylabel("energy [J]")
    a.set_title("(a) Energy transfer")
    lo, hi = a.get_ylim()
    a.set_ylim(lo, hi + 0.3 * (hi - lo))  # head room for the legend
    a.legend(loc="upper center", ncols=2, framealpha=0.9)


def _energy_panel(b, traj) -> None:
    """Fig. NS's panel (b): E - E0 [J], every step's when the trajectory has them, with its
    least-squares drift."""
    ts, E, every = _series(traj, "energy")
    E0 = E[0]
    dE = E - E0
    slope, icpt = np.polyfit(ts, dE, 1) if len(ts) > 1 else (0.0, 0.0)
    _band(b, ts, dE, label="E - E0" + (", every step (min..max per bin)" if every else ""))
    b.plot(ts[[0, -1]], icpt + slope * ts[[0, -1]], color="tab:orange", lw=1.5, ls="--",
           label=f"least-squares drift {slope:+.2e} J/s")
    b.axhline(0.0, color="grey", lw=0.6)
    b.set_ylabel("E - E0 [J]")
    b.set_title("(b) Total energy")
    b.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
    b.legend(loc="upper left", framealpha=0.9)
    _note(b, f"E0 = {E0:.6f} J\nmax |E - E0| = {np.abs(dE).max():.2e} J")


def _pi3_panel(c, traj) -> None:
    """Fig. NS's panel (c): pi3 - pi3(0) [kg m^2/s]."""
    ts, p3, every = _series(traj, "pi3")
    _band(c, ts, p3 - p3[0])
    c.axhline(0.0, color="grey", lw=0.6)
    c.set_ylabel(r"$\pi_3 - \pi_3(0)$ [kg m$^2$/s]")
    c.set_title(r"(c) Angular momentum about $e_3$: deviation from the initial value")
    c.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
    _note(c, rf"$\pi_3(0)$ = {p3[0]:.6f} kg m$^2$/s" + "\n"
          + rf"max $|\pi_3 - \pi_3(0)|$ = {np.abs(p3 - p3[0]).max():.1e}")


def _orthogonality_panel(d, traj) -> None:
    """Fig. NS's panel (d): ||I - R^T R||_F, log scale (the maximum and median per bin on a long run)."""
    ts, orth, every = _series(traj, "orthogonality")
    tb, _, med, hi = binned(ts, orth, bins=500)
    if len(tb) == len(ts):
        d.semilogy(ts, np.where(orth > 0, orth, np.nan), color="black", lw=0.8)
    else:
        d.semilogy(tb, np.where(hi > 0, hi, np.nan), color="black", lw=0.9, label="maximum per bin")
        d.semilogy(tb, np.where(med > 0, med, np.nan), color="tab:grey", lw=0.9, label="median per bin")
        d.legend(loc="lower right", framealpha=0.9)
    positive = orth[orth > 0]  # exact zeros (e.g. R(0) = I) have no logarithm
    if positive.size:  # the first steps sit far below round-off; do not let them set the scale
        typical = np.percentile(med[med > 0] if (med > 0).any() else positive, 5.0)
        d.set_ylim(10.0 ** (np.floor(np.log10(typical)) - 1), 10.0 ** np.ceil(np.log10(positive.max()) + 0.3))
    d.set_ylabel(r"$\|I - R^T R\|_F$")
    d.set_title("(d) Orthogonality error of the rotation matrices")
    _note(d, f"max = {orth.max():.1e}", loc="upper left")
    d.grid(True, which="major", alpha=0.3)


def _velocities_panel(e, traj) -> None:
    """Fig. NS's panel (e): the attachment velocity's second component [m/s] and Omega's [rad/s], on
    two axes."""
    t = traj.t
    v2 = e.plot(t, traj.attach_velocity[:, 1], color="tab:blue", lw=1.2,
                label=r"attachment velocity $v_2$ [m/s] (left)")
    e.set_ylabel(r"$v_2$ [m/s]", color="tab:blue")
    e.tick_params(axis="y", colors="tab:blue")
    e2 = e.twinx()
    w2 = e2.plot(t, traj.omega[:, 1], color="tab:red", lw=1.2,
                 label=r"angular velocity $\Omega_2$ [rad/s] (right)")
    e2.set_ylabel(r"$\Omega_2$ [rad/s]", color="tab:red")
    e2.tick_params(axis="y", colors="tab:red")
    e.legend(handles=v2 + w2, loc="lower left", framealpha=0.9)
    e.set_title("(e) Body velocity / angular velocity, second components")
    e.set_xlabel("t [s]")


def _stretch_panel(f, traj, scene) -> None:
    """Fig. NS's panel (f): the stretched length [m], with ``scene`` its unstretched length."""
    t = traj.t
    f.plot(t, traj.stretched_length, color="black", lw=1.2)
    if scene is not None:
        f.axhline(scene.string.length, color="grey", lw=0.8, ls="--",
                  label=f"unstretched length l = {scene.string.length:g} m")
        f.legend(loc="best", framealpha=0.9)
    f.set_ylabel("stretched length [m]")
    f.set_title("(f) Stretched length of the string")
    f.set_xlabel("t [s]")


def plot_fig_ns(traj, path, scene=None, title: Optional[str] = None) -> Path:
    """Fig. NS of the paper: six panels of diagnostics against time, saved as ``path`` (PNG).

    (a) energy transfer: kinetic energy of the body (red) and of the string (black),
    gravitational (green) and elastic (blue) potential [J]; (b) total energy as E - E0 [J] with
    its least-squares drift line; (c) pi3 - pi3(0) [kg m^2/s]; (d) ||I - R^T R||_F (log scale);
    (e) second components of the attachment velocity [m/s] (spatial frame) and of the body
    angular velocity Omega [rad/s] (body frame); (f) stretched length of the string [m].
    (b)-(d) use the every-step series when the trajectory has them. ``scene`` (optional) adds the
    unstretched length to (f) and the scene name to the title.
    """
    with matplotlib.rc_context(_RC):
        fig = new_figure((11, 10.5))
        axes = fig.subplots(3, 2, sharex=True)
        fig.set_layout_engine("constrained")
        t = traj.t
        (a, b), (c, d), (e, f) = axes
        _energy_transfer_panel(a, traj)
        _energy_panel(b, traj)
        _pi3_panel(c, traj)
        _orthogonality_panel(d, traj)
        _velocities_panel(e, traj)
        _stretch_panel(f, traj, scene)

        for ax in axes.ravel():
            ax.set_xlim(t[0], t[-1])
            ax.grid(True, alpha=0.3)
        if title is None:
            name = f"{scene.name}, N = {scene.string.elements}, h = {scene.h:g} s" if scene is not None else ""
            title = f"Numerical simulation of a 3D elastic string pendulum{' (' + name + ')' if name else ''}"
        fig.suptitle(title, fontsize=12)
        return save_figure(fig, path)


def cylinder_faces(R: np.ndarray, r_attach: np.ndarray, rho_c: Sequence[float],
                   semi_axes=CYLINDER_SEMI_AXES, height: float = CYLINDER_HEIGHT, n: int = 24):
    """Polygons (spatial frame) of an elliptic cylinder centred at the centre of mass: ``n`` side
    quads and the two end caps. Body point b sits at ``r_attach + R b``; the cylinder axis is
    body z, its semi-axes are along body x and y."""
    th = np.linspace(0.0, 2.0 * np.pi, n + 1)
    ring = np.column_stack([semi_axes[0] * np.cos(th), semi_axes[1] * np.sin(th), np.zeros_like(th)])
    rho = np.asarray(rho_c, dtype=float)
    lo = rho + ring - [0.0, 0.0, 0.5 * height]
    hi = rho + ring + [0.0, 0.0, 0.5 * height]
    lo = r_attach + lo @ R.T
    hi = r_attach + hi @ R.T
    sides = [np.array([lo[i], lo[i + 1], hi[i + 1], hi[i]]) for i in range(n)]
    return sides + [lo[:-1], hi[:-1]]


def _snapshot_indices(t: np.ndarray, t0: float, t1: float, count: int) -> np.ndarray:
    """Indices of the snapshots nearest to ``count`` equally spaced times in [t0, t1]."""
    want = np.linspace(t0, t1, count)
    idx = np.clip(np.searchsorted(t, want), 0, len(t) - 1)
    prev = np.clip(idx - 1, 0, len(t) - 1)
    idx = np.where(np.abs(t[prev] - want) <= np.abs(t[idx] - want), prev, idx)
    return np.unique(idx)


def _cylinder_dims(shape) -> dict:
    """The scene's own cylinder's semi-axes and height for :func:`cylinder_faces`; other shapes
    are drawn as the paper's cylinder (no dims)."""
    if getattr(shape, "kind", None) == "elliptic_cylinder":
        return dict(semi_axes=shape.semi_axes, height=shape.height)
    if getattr(shape, "kind", None) == "cylinder":
        return dict(semi_axes=(shape.radius, shape.radius), height=shape.height)
    return {}


def _snapshot_box(nodes, bodies: dict, every, pivot):
    """``(lo, hi)`` (3,) [m] of the box that holds every snapshot's string and body and the pivot,
    with room round them and no flat side for a short run."""
    pts = np.concatenate([nodes[every].reshape(-1, 3), pivot[None]] + [np.concatenate(bodies[k]) for k in every])
    mid, span = 0.5 * (pts.max(0) + pts.min(0)), pts.max(0) - pts.min(0)
    span = np.maximum(span, 0.35 * span.max()) + 0.06 * span.max()
    return mid - 0.5 * span, mid + 0.5 * span


def _snapshots(ax, traj, sel, bodies: dict, span, colour) -> None:
    """One panel's snapshots ``sel`` (indices of ``traj``) on the 3-D axes ``ax``: the attachment's
    path over the time ``span`` (a mask), each string coloured by ``colour`` (its colormap and
    norm) and each body darker than the last."""
    colormap, norm = colour
    nodes = traj.nodes
    path_k = nodes[span, -1]
    ax.plot(path_k[:, 0], path_k[:, 1], path_k[:, 2], color="0.55", lw=0.7)
    for j, k in enumerate(sel):
        seg = np.stack([nodes[k, :-1], nodes[k, 1:]], axis=1)
        lines = Line3DCollection(seg, cmap=colormap, norm=norm, linewidths=2.0)
        lines.set_array(traj.strain_energy[k])
        # autolim=False: the box is set by the caller from our own points. matplotlib 3.11 pads
        # ragged polygon lists (quads + 24-gon caps) with np.empty and autoscales over
        # the padding, so garbage there could overflow the limits (CI, stop 9).
        ax.add_collection3d(lines, autolim=False)
        grey = 0.8 - 0.55 * j / max(1, len(sel) - 1)
        body = Poly3DCollection(bodies[k], facecolor=(grey, grey, grey), edgecolor=(0.2, 0.2, 0.2),
                                linewidths=0.2, alpha=0.95)
        ax.add_collection3d(body, autolim=False)


def _snapshot_axes(ax, lo, hi, pivot, labels) -> None:
    """A snapshot panel's frame: the pivot, the first and last snapshot's times (``labels``: each
    ``(text, point)``), the box ``lo``..``hi`` with equal scales, y and z inverted, and the view."""
    for text, c in labels:
        ax.text(c[0], c[1], c[2] - 0.1 * (hi[2] - lo[2]), text, fontsize=8, ha="center",
                va="center", color="0.1", zorder=100,  # above the depth-sorted collections
                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.75))
    ax.scatter(*pivot, color="black", marker="s", s=30, depthshade=False)
    ax.text(*(pivot - [0.0, 0.0, 0.07 * (hi[2] - lo[2])]), "pivot", fontsize=8, ha="center", zorder=100)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])  # inverted: see the module docstring
    ax.set_zlim(hi[2], lo[2])  # inverted: gravity (+e3) points down
    ax.set_box_aspect(tuple(hi - lo), zoom=1.0)  # equal scale on all three axes
    ax.view_init(elev=16, azim=-72)
    ax.set_xlabel("x [m]", labelpad=4)
    ax.set_ylabel("y [m]", labelpad=4)
    ax.set_zlabel("z [m] (down)", labelpad=0)
    ax.tick_params(pad=0)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5, steps=[1, 2, 2.5, 5, 10]))


def plot_fig_sm(traj, scene, path, panels: int = 4, snapshots_per_panel: int = 11,
                cmap: str = "plasma", title: Optional[str] = None) -> Path:
    """Fig. SM of the paper: snapshots of the maneuver in ``panels`` 3-D panels that split the
    run's time span evenly (for the paper's 5 s: [0, 1.25], ..., [3.75, 5] s, and with the
    default 11 snapshots per panel one every 0.125 s).

    Each snapshot draws the string element by element, coloured by its strain energy [J] on one
    colour scale shared by all panels, and the body as the elliptic cylinder (grey, darker for
    later snapshots). The thin grey line is the path of the attachment point; the black square
    is the pivot. Axes are equal, identical across panels, z inverted (gravity points down).
    """
    t = traj.t
    nodes = traj.nodes
    rho_c = np.asarray(scene.body.rho_c, dtype=float)
    pivot = np.asarray(scene.pivot.position, dtype=float)
    edges = np.linspace(t[0], t[-1], panels + 1)
    chosen = [_snapshot_indices(t, edges[i], edges[i + 1], snapshots_per_panel) for i in range(panels)]
    every = np.unique(np.concatenate(chosen))
    dims = _cylinder_dims(scene.body.shape)
    bodies = {k: cylinder_faces(traj.R[k], nodes[k, -1], rho_c, **dims) for k in every}
    lo, hi = _snapshot_box(nodes, bodies, every, pivot)
    smax = float(traj.strain_energy[every].max()) or 1.0
    # square-root scale: most elements carry little strain energy, a few near the body a lot
    norm = mcolors.PowerNorm(gamma=0.5, vmin=0.0, vmax=smax)
    colormap = matplotlib.colormaps[cmap]

    with matplotlib.rc_context(_RC):
        ncols = 2 if panels > 1 else 1
        nrows = int(np.ceil(panels / ncols))
        fig = new_figure((11, 4.0 * nrows + 0.4))
        # 3-D axes draw in a square; the projected box is wider than tall, so the rows may overlap
        fig.subplots_adjust(left=0.0, right=0.86, bottom=-0.02, top=1.0, wspace=0.06, hspace=-0.16)
        for i in range(panels):
            ax = fig.add_subplot(nrows, ncols, i + 1, projection="3d")
            ax.patch.set_visible(False)  # the squares overlap; let no panel hide its neighbour
            sel = chosen[i]
            _snapshots(ax, traj, sel, bodies, (t >= edges[i]) & (t <= edges[i + 1]), (colormap, norm))
            # the first and the last snapshot labelled with its time
            _snapshot_axes(ax, lo, hi, pivot, [(f"{t[k]:g} s", np.asarray(bodies[k][-1]).mean(0))
                                               for k in (sel[0], sel[-1])])
            ax.set_title(f"({chr(ord('a') + i)}) $t \\in [{t[sel[0]]:g}, {t[sel[-1]]:g}]$ s, "
                         f"{len(sel)} snapshots", y=0.88)
        cax = fig.add_axes([0.9, 0.2, 0.018, 0.6])
        cb = fig.colorbar(ScalarMappable(norm=norm, cmap=colormap), cax=cax)
        cb.set_label("strain energy per element [J] (square-root scale)")
        if title is None:
            title = (f"Snapshots of a 3D elastic string pendulum maneuver ({scene.name}, "
                     f"N = {scene.string.elements}); bodies darken with time")
        fig.suptitle(title, fontsize=12, y=0.995)
        return save_figure(fig, path)
