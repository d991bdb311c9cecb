"""A drone's part of a Rerun recording (esp_gym/viz/recording.py): its attitude, body rates and
rotor speeds per sample, buffered beside the recorder's rows (recorder.py) and written as the
drone's frame at the pivot (turned by R_q, its arms and rotors drawn in it) and two series.
"""
from __future__ import annotations

import numpy as np
import pyarrow as pa
import rerun as rr

from ..kernels.layout import Layout
from . import arrow, palette
from .entities import DRONE, DRONE_FRAME, DRONE_RATES, DRONE_ROTORS, drone_frame

#: One sample of the drone: R_q column-major (Rerun's layout), its body rates [rad/s] and its
#: rotor speeds [rad/s].
DRONE_SAMPLE = Layout(("attitude", 9), ("rates", 3), ("rotor_speeds", 4))


class DroneTrack:
    """The drone's samples of one recorder: ``rotors`` (4, 3) its rotor positions in its body
    frame [m], ``capacity`` the recorder's rows."""

    def __init__(self, rotors, capacity: int):
        self.rotors = np.asarray(rotors, dtype=float)
        self._buf = np.zeros((capacity, DRONE_SAMPLE.size))

    def set(self, row: int, R, rates, rotor_speeds) -> None:
        """The drone's values of the recorder's row ``row`` (written before the row is counted)."""
        sample = self._buf[row]
        sample[DRONE_SAMPLE["attitude"]] = np.asarray(R, dtype=float).ravel(order="F")
        sample[DRONE_SAMPLE["rates"]] = rates
        sample[DRONE_SAMPLE["rotor_speeds"]] = rotor_speeds

    def log_static(self, log) -> None:
        log(DRONE_FRAME, drone_frame(self.rotors), static=True)
        log(DRONE_RATES, rr.SeriesLines(names=["rate_x", "rate_y", "rate_z"], colors=palette.TAB10[:3]), static=True)
        log(DRONE_ROTORS, rr.SeriesLines(names=[f"rotor_{i}" for i in range(1, 5)], colors=palette.TAB10[:4]),
            static=True)

    def columns(self, n: int, pivot: np.ndarray, each: np.ndarray) -> list:
        """The columns of the first ``n`` samples: the drone's frame at the ``pivot`` (n, 3)
        float32, and its series."""
        b = self._buf[:n]
        rows, vec3, scalar = arrow.rows, arrow.vec3, rr.Scalars.descriptor_scalars()
        attitude = b[:, DRONE_SAMPLE["attitude"]].astype(np.float32)
        out = [(DRONE, rr.Transform3D.descriptor_translation(), rows(vec3(pivot, "translation"), each)),
               (DRONE, rr.Transform3D.descriptor_mat3x3(), rows(arrow.mat3x3(attitude), each))]
        for path, name in ((DRONE_RATES, "rates"), (DRONE_ROTORS, "rotor_speeds")):
            values = b[:, DRONE_SAMPLE[name]]
            k = values.shape[1]
            out.append((path, scalar, rows(pa.array(values.reshape(-1)), np.arange(0, n * k + 1, k, dtype=np.int32))))
        return out
