"""Rerun recordings of a team's episodes (docs/team.md): :class:`RecordTeamRerun` wraps
``ElasticStringTeam-v0`` and logs, after every reset and step, every string's nodes, every pivot,
the load (its box turned by R at its centre of mass), the targets, and as series each string's pull
on its pivot, the closest two pivots and the reward. Read it with ``rerun FILE`` or
``rerun.chunk.RrdReader``.

Entities: ``/world/strings/{k}`` (LineStrips3D), ``/world/pivots`` (Points3D), ``/world/load``
(Transform3D; its box ``/world/load/box`` static), ``/world/targets`` (Points3D: the pivots' and
the load's), ``/team/tension/pivot_{k}`` [N], ``/team/separation`` [m], ``/team/reward``
(Scalars). Times: ``step`` (control steps since the recording began) and ``time`` [s].
"""
from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

from ..extras import require
from ..params import Box

rr = require("rerun", "esp_gym.team.recording")


class RecordTeamRerun(gym.Wrapper):
    """Record the wrapped team env's episodes to the ``.rrd`` file ``path`` (written by Rerun's
    file sink; :meth:`close` flushes it)."""

    def __init__(self, env: gym.Env, path):
        super().__init__(env)
        self.path = Path(path)
        if not self.path.parent.is_dir():
            raise ValueError(f"path: the directory {self.path.parent} does not exist")
        self.rec = rr.RecordingStream("esp_gym_team")
        self.rec.save(str(self.path))
        self.samples = 0
        core = env.unwrapped.core
        self.rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)
        shape = core.scene.scene.body.shape
        if isinstance(shape, Box):
            self.rec.log("/world/load/box", rr.Boxes3D(half_sizes=[0.5 * np.asarray(shape.size)], fill_mode="solid"),
                         static=True)

    def _log(self, reward: float | None = None, info: dict | None = None) -> None:
        core = self.env.unwrapped.core
        rec = self.rec
        rec.set_time("step", sequence=self.samples)
        rec.set_time("time", duration=self.samples * core.control_period)
        st, T = core.sim.state, core.sim.params
        nodes = [st.lead.r] + [st.r[T.start[j]:T.start[j + 1]] for j in range(core.size - 1)]
        for k, r in enumerate(nodes):
            rec.log(f"/world/strings/{k}", rr.LineStrips3D([r]))
        rec.log("/world/pivots", rr.Points3D(core.pivot_positions(), radii=0.03,
                                             labels=[f"pivot_{k}" for k in range(core.size)]))
        rec.log("/world/load", rr.Transform3D(translation=core.load_position(), mat3x3=st.lead.R))
        rec.log("/world/targets", rr.Points3D(np.vstack([core.pivot_targets, core.load_target]), radii=0.02))
        if info is not None:
            for k, pull in enumerate(np.linalg.norm(info["tension"], axis=1)):
                rec.log(f"/team/tension/pivot_{k}", rr.Scalars(float(pull)))
            rec.log("/team/separation", rr.Scalars(float(info["min_separation"])))
            rec.log("/team/reward", rr.Scalars(float(reward)))
        self.samples += 1

    def reset(self, **kwargs):
        out = self.env.reset(**kwargs)
        self._log()
        return out

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._log(reward, info)
        return obs, reward, terminated, truncated, info

    def close(self):
        self.rec.flush()
        self.rec.disconnect()
        super().close()
