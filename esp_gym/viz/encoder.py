"""The recorder's buffered samples encoded for Rerun (esp_gym/viz/recorder.py writes what this
gives): :class:`SampleEncoder` turns rows of kernels/env/recording.py's sample layout into record
batches (arrow.py) of every entity of esp_gym/viz/entities.py, in stages: the rig's geometry
(compiled, kernels/env/recording.py ``sample_geometry``), the env's arrows, the scalar series and the
episode's return, and the targets of the episodes reset among the rows.
"""
from __future__ import annotations

import numpy as np
import pyarrow as pa
import rerun as rr

from ..kernels.env.arrays import SENSORS, TARGET
from ..kernels.env.recording import GeometryColumns, GeometryStyle, sample_geometry, trail_points
from ..kernels.step.disturbance import DISTURBANCE
from . import arrow, palette
from .entities import (BODY, BODY_TORQUE, HOOK_TENSION, LOAD_TRAIL, PIVOT, PIVOT_FORCE, PUSH, RETURN, STRING,
                       TARGET_LOAD, TARGET_PIVOT, WIND)


class SampleEncoder:
    """Rows of a recorder's sample ``layout`` (``n_elements`` elements) -> Rerun record batches.
    ``env``, ``winch``: an environment's recording (its arrows, return and targets), with the
    winch's series; ``drone``: the drone's samples (esp_gym/viz/drone_track.py) or None;
    ``scalars``: the scalar series (entities.py ``scalar_series``); the scales and offsets as
    :class:`~esp_gym.viz.recorder.Recorder`'s; ``trail``: (samples a load trail spans, samples
    between its points: its ``trail_seconds`` and ``trail_spacing`` over its sample period). It
    keeps the load trail's tail and the episode's return between calls."""

    def __init__(self, layout, n_elements: int, *, env: bool, winch: bool, drone, scalars: dict,
                 strain_scale: float, force_scale: float, torque_scale: float, wind_scale: float,
                 force_offset: np.ndarray, action_scale, trail: tuple):
        self.layout, self.n_elements = layout, n_elements
        self.env, self.winch, self.drone, self.scalars = env, winch, drone, scalars
        self.strain_scale, self.force_offset, self.action_scale = strain_scale, force_offset, action_scale
        self.force_scale, self.torque_scale, self.wind_scale = force_scale, torque_scale, wind_scale
        self.trail_len, self.trail_stride = trail
        self._columns = {path: [layout.start(f) + k for f, k in s.sources] for path, s in scalars.items()}
        self._trail_hist = np.empty((0, 3))  # the current episode's last load positions
        self._trail_episode = None
        self._return = (None, 0.0)  # (episode, return) at the last sample written

    def batches(self, buf: np.ndarray, n: int) -> list:
        """The record batches of the first ``n`` rows of ``buf``: one with every entity that has a
        value at every sample, and one with the targets of the episodes reset among them (if any)."""
        b = buf[:n]
        col = self.layout.start
        step, time, episode = b[:, col("step")], b[:, col("time")], b[:, col("episode")]
        stepped = b[:, col("stepped")] > 0
        each = np.arange(n + 1, dtype=np.int32)
        cols, pivot, load = self._geometry(buf, n, episode, each)
        if self.env:
            cols += self._disturbance_arrows(b, pivot, load, each)
        if self.drone is not None:
            cols += self.drone.columns(n, pivot, each)
        missing = ~stepped  # reset samples have no step: no Newton count, reward or action
        cols += self._scalar_columns(b, n, missing)
        if self.env:
            returns, self._return = arrow.episode_returns(b[:, col("reward")], episode, stepped, self._return)
            cols.append((RETURN, rr.Scalars.descriptor_scalars(), pa.array(returns, mask=missing)))
        out = [arrow.record_batch(step, time, cols)]
        targets = self._targets(b, step, time)
        return out if targets is None else out + [targets]

    def _geometry(self, buf: np.ndarray, n: int, episode: np.ndarray, each: np.ndarray) -> tuple:
        """The string, body, pivot, arrows and load trail columns of the first ``n`` rows, with the
        pivot's and the load's positions (n, 3) they were drawn from."""
        N = self.n_elements
        per_sample = np.arange(0, n * N + 1, N, dtype=np.int32)
        f32 = lambda *shape: np.empty(shape, dtype=np.float32)  # noqa: E731
        pts, colors, translation, mat = f32(n, N, 2, 3), np.empty(n * N, np.uint32), f32(n, 3), f32(n, 9)
        pivot, force_vec, torque_vec, load = f32(n, 3), f32(n, 3), f32(n, 3), np.empty((n, 3))
        force_limit, torque_limit = self.action_scale if self.env else (0.0, 0.0)
        style = GeometryStyle(inv_strain_scale=1.0 / self.strain_scale, lut=palette.STRAIN_RGBA,
                              inputs_from_action=self.env and self.drone is None, force_offset=self.force_offset,
                              force_limit=float(force_limit), torque_limit=float(torque_limit),
                              force_scale=self.force_scale, torque_scale=self.torque_scale)
        columns = GeometryColumns(pts=pts, colors=colors, translation=translation, mat=mat, pivot=pivot,
                                  force_vec=force_vec, torque_vec=torque_vec, load=load)
        sample_geometry(buf, n, tuple(style), tuple(columns))
        rows, vec3 = arrow.rows, arrow.vec3
        cols = [
            (STRING, rr.LineStrips3D.descriptor_strips(),
             rows(arrow.strips(pts.reshape(-1, 3), np.arange(0, 2 * n * N + 1, 2, dtype=np.int32)), per_sample)),
            (STRING, rr.LineStrips3D.descriptor_colors(),
             rows(pa.array(colors, type=arrow.arrow_type("color")), per_sample)),
            (BODY, rr.Transform3D.descriptor_translation(), rows(vec3(translation, "translation"), each)),
            (BODY, rr.Transform3D.descriptor_mat3x3(), rows(arrow.mat3x3(mat), each)),
            (PIVOT, rr.Points3D.descriptor_positions(), rows(vec3(pivot, "position"), each)),
            (PIVOT_FORCE, rr.Arrows3D.descriptor_origins(), rows(vec3(pivot, "position"), each)),
            (PIVOT_FORCE, rr.Arrows3D.descriptor_vectors(), rows(vec3(force_vec, "vector"), each)),
            (BODY_TORQUE, rr.Arrows3D.descriptor_vectors(), rows(vec3(torque_vec, "vector"), each)),
            (LOAD_TRAIL, rr.LineStrips3D.descriptor_strips(), rows(self._trail(load, episode), each)),
        ]
        return cols, pivot, load

    def _scalar_columns(self, b: np.ndarray, n: int, missing: np.ndarray) -> list:
        """The scalar series' columns of the rows ``b`` (a stepped-only series masked where
        ``missing``; the env's and the winch's only in their recordings)."""
        scalar = rr.Scalars.descriptor_scalars()
        cols = []
        for path, series in self.scalars.items():
            if (series.env_only and not self.env) or (series.winch_only and not self.winch):
                continue
            columns = self._columns[path]
            mask = missing if series.stepped_only else None
            k = len(columns)
            if k == 1:
                values = pa.array(b[:, columns[0]], mask=mask)
            else:
                values = arrow.rows(pa.array(b[:, columns].reshape(-1)), np.arange(0, n * k + 1, k, dtype=np.int32),
                                    mask)
            cols.append((path, scalar, values))
        return cols

    def _targets(self, b: np.ndarray, step: np.ndarray, time: np.ndarray):
        """The record batch of the targets of the episodes reset among the rows ``b``, or None."""
        target = self.layout.start("target")
        reset = ~np.isnan(b[:, target])
        if not reset.any():
            return None
        one = np.arange(reset.sum() + 1, dtype=np.int32)
        rows, vec3 = arrow.rows, arrow.vec3
        targets = [(path, rr.Points3D.descriptor_positions(), rows(vec3(b[reset, k:k + 3], "position"), one))
                   for path, k in ((TARGET_PIVOT, target + TARGET.start("pivot")),
                                   (TARGET_LOAD, target + TARGET.start("load")))]
        return arrow.record_batch(step[reset], time[reset], targets)

    def _disturbance_arrows(self, b: np.ndarray, pivot: np.ndarray, load: np.ndarray, each: np.ndarray) -> list:
        """The columns of the env's arrows for the rows ``b``: ``wind_scale`` x wind and
        ``force_scale`` x push from the load's centre of mass, ``force_scale`` x hook tension
        from the pivot (spatial frame; float32 of the float64 products)."""
        def part(field, layout, name):  # the rows' entries ``name`` of ``layout``, held in ``field``
            base, entries = self.layout.start(field), layout[name]
            return b[:, base + entries.start:base + entries.stop]

        rows, vec3, at = arrow.rows, arrow.vec3, rr.Arrows3D.descriptor_origins()
        load_at = rows(vec3(load, "position"), each)
        vec = rr.Arrows3D.descriptor_vectors()
        return [
            (WIND, at, load_at),
            (WIND, vec, rows(vec3(part("disturbance", DISTURBANCE, "wind") * self.wind_scale, "vector"), each)),
            (PUSH, at, load_at),
            (PUSH, vec, rows(vec3(part("disturbance", DISTURBANCE, "push") * self.force_scale, "vector"), each)),
            (HOOK_TENSION, at, rows(vec3(pivot, "position"), each)),
            (HOOK_TENSION, vec,
             rows(vec3(part("sensors", SENSORS, "hook_tension") * self.force_scale, "vector"), each)),
        ]

    def _trail(self, load: np.ndarray, episode: np.ndarray) -> pa.Array:
        """Per sample, one strip through the load's positions over the last ``trail_seconds``
        of the same episode, every ``trail_stride`` samples back from the current one (the
        tail of the previous flush is kept)."""
        L = self.trail_len
        hist = self._trail_hist if self._trail_episode == episode[0] else np.empty((0, 3))
        points = np.vstack([hist, load])
        ep = np.concatenate([np.full(len(hist), episode[0]), episode])
        offsets = np.empty(len(load) + 1, dtype=np.int32)
        m_max = (L - 1) // self.trail_stride + 1
        out = np.empty((len(load) * m_max, 3), dtype=np.float32)
        total = trail_points(points, ep, len(hist), L, self.trail_stride, offsets, out)
        keep = np.arange(max(0, len(points) - (L - 1)), len(points)) if L > 1 else np.arange(0)
        keep = keep[ep[keep] == episode[-1]]
        self._trail_hist, self._trail_episode = points[keep], episode[-1]
        return arrow.strips(out[:total], offsets)
