"""Rerun recordings of a team's episodes (docs/team.md): :class:`RecordTeamRerun` wraps
``ElasticStringTeam-v0``, or the PettingZoo env (esp_gym.team.parallel_env), and logs, after every
reset and step, every string's nodes, every pivot, the load (its box turned by R at its centre of
mass), the targets, and as series each string's pull on its pivot, the closest two pivots, the
reward and the energy balance. The file carries its layout (:func:`team_blueprint`: the 3-D
view in front, the whole team in view). Read it with ``rerun FILE`` or ``rerun.chunk.RrdReader``.

Entities: ``/world/strings/{k}`` (LineStrips3D), ``/world/pivots`` (Points3D), a drone team's
``/world/drones/{k}`` (Transform3D: at its pivot, turned by R_q; its arms and rotors
``/world/drones/{k}/frame`` static), ``/world/load``
(Transform3D; its box ``/world/load/box`` static), ``/world/targets`` (Points3D: the pivots' and
the load's), ``/team/tension/pivot_{k}`` [N], ``/team/separation`` [m], ``/team/reward``,
``/team/energy/balance`` (E - E0 - W [J]) and ``/team/energy/total`` (E [J]) (Scalars). Times:
``step`` (control steps since the recording began) and ``time`` [s].
"""
from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

from ..extras import require

rr = require("rerun", "esp_gym.team.recording")  # first: the viz modules below import rerun too

from ..scene.params import Box  # noqa: E402
from ..viz.entities import EYE_DIRECTION, EYE_DISTANCE, drone_frame  # noqa: E402
try:  # the PettingZoo env's face (without PettingZoo there is no such env to record)
    from pettingzoo.utils.wrappers import BaseParallelWrapper
except ImportError:
    BaseParallelWrapper = object


def team_eye(core) -> tuple:
    """``(position, look_target)`` [m] of the 3-D view's eye: it looks at the middle of the team
    (its pivots' and load's centre) from :data:`~esp_gym.viz.entities.EYE_DISTANCE` times the
    rig's extent (at least 1 m) along the single env's direction, so every pivot, string and the
    load are in view."""
    points = np.vstack([core.pivot_positions(), core.load_position()[None]])
    target = points.mean(axis=0)
    extent = max(float(np.linalg.norm(points - target, axis=1).max()) * 2.0, 1.0)
    return target + EYE_DISTANCE * extent * EYE_DIRECTION, target


def team_blueprint(core):
    """The recording's layout: the 3-D view in front (:func:`team_eye`), beside the energy and
    its balance, each string's pull, the closest two pivots and the reward."""
    import rerun.blueprint as rrb

    ts = rrb.TimeSeriesView
    position, target = team_eye(core)
    eye = rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=position, look_target=target,
                            eye_up=[0.0, 0.0, -1.0])
    panels = rrb.Vertical(rrb.Tabs(ts(origin="/team/energy/balance", name="E - E0 - W [J]"),
                                   ts(origin="/team/energy/total", name="energy [J]")),
                          ts(origin="/team/tension", name="string pulls [N]"),
                          rrb.Tabs(ts(origin="/team/reward", name="reward"),
                                   ts(origin="/team/separation", name="closest pivots [m]")))
    view = rrb.Spatial3DView(origin="/world", name="3-D", eye_controls=eye)
    return rrb.Blueprint(rrb.Horizontal(view, panels, column_shares=[3, 2]), collapse_panels=True)


class TeamRecorder:
    """The recording of one team (``core``: a :class:`~esp_gym.team.core.TeamCore`) to the ``.rrd``
    file ``path`` (Rerun's file sink), whichever face steps it."""

    def __init__(self, core, path):
        self.path = Path(path)
        if not self.path.parent.is_dir():
            raise ValueError(f"path: the directory {self.path.parent} does not exist")
        self.core = core
        self.rec = rr.RecordingStream("esp_gym_team")
        self.rec.save(str(self.path), default_blueprint=team_blueprint(core))
        self.samples = 0
        self.rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)
        shape = core.scene.scene.body.shape
        if isinstance(shape, Box):
            self.rec.log("/world/load/box", rr.Boxes3D(half_sizes=[0.5 * np.asarray(shape.size)], fill_mode="solid"),
                         static=True)
        if core.drones:  # each drone drawn as the single env draws its own, in its body frame
            for k, pivot in enumerate(core.scene.pivots()):
                self.rec.log(f"/world/drones/{k}/frame", drone_frame(pivot.drone.rotor_positions()), static=True)

    def log(self, reward: float | None = None, pulls=None, min_separation: float | None = None) -> None:
        """The state now; after a step, its ``reward``, each pivot's string's pull [N] (K, 3) and
        the closest two pivots' distance [m] too."""
        core, rec = self.core, self.rec
        rec.set_time("step", sequence=self.samples)
        rec.set_time("time", duration=self.samples * core.control_period)
        st, T = core.sim.state, core.sim.params
        nodes = [st.lead.r] + [st.r[T.start[j]:T.start[j + 1]] for j in range(core.size - 1)]
        for k, r in enumerate(nodes):
            rec.log(f"/world/strings/{k}", rr.LineStrips3D([r]))
        rec.log("/world/pivots", rr.Points3D(core.pivot_positions(), radii=0.03,
                                             labels=[f"pivot_{k}" for k in range(core.size)]))
        rec.log("/world/load", rr.Transform3D(translation=core.load_position(), mat3x3=st.lead.R))
        if core.drones:
            attitudes = core.sim.fleet.diagnostics()["drone_attitudes"]
            for k, (position, R_q) in enumerate(zip(core.pivot_positions(), attitudes)):
                rec.log(f"/world/drones/{k}", rr.Transform3D(translation=position, mat3x3=R_q))
        rec.log("/world/targets", rr.Points3D(np.vstack([core.pivot_targets, core.load_target]), radii=0.02))
        d = core.sim.diagnostics()
        rec.log("/team/energy/total", rr.Scalars(float(d["energy"])))
        rec.log("/team/energy/balance", rr.Scalars(float(d["energy_balance_residual"])))
        if reward is not None:
            for k, pull in enumerate(np.linalg.norm(pulls, axis=1)):
                rec.log(f"/team/tension/pivot_{k}", rr.Scalars(float(pull)))
            rec.log("/team/separation", rr.Scalars(float(min_separation)))
            rec.log("/team/reward", rr.Scalars(float(reward)))
        self.samples += 1

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()


class RecordTeamRerun(gym.Wrapper):
    """Record the wrapped team env's episodes to the ``.rrd`` file ``path`` (:meth:`close`
    flushes it). Given the PettingZoo env, this is a :class:`RecordTeamParallelRerun`."""

    def __new__(cls, env, path):
        if hasattr(env, "possible_agents"):  # a PettingZoo env
            return RecordTeamParallelRerun(env, path)
        return super().__new__(cls)

    def __init__(self, env: gym.Env, path):
        super().__init__(env)
        self.recorder = TeamRecorder(env.unwrapped.core, path)

    @property
    def path(self) -> Path:
        return self.recorder.path

    def reset(self, **kwargs):
        out = self.env.reset(**kwargs)
        self.recorder.log()
        return out

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.recorder.log(reward, info["tension"], info["min_separation"])
        return obs, reward, terminated, truncated, info

    def close(self):
        self.recorder.close()
        super().close()


class RecordTeamParallelRerun(BaseParallelWrapper):
    """:class:`RecordTeamRerun` of the PettingZoo env ``env``: a ParallelEnv whose agents, spaces,
    state and frames are ``env``'s, its episodes recorded to ``path``."""

    def __init__(self, env, path):
        super().__init__(env)
        self.recorder = TeamRecorder(env.unwrapped.core, path)

    @property
    def path(self) -> Path:
        return self.recorder.path

    def reset(self, seed=None, options=None):
        out = self.env.reset(seed=seed, options=options)
        self.recorder.log()
        return out

    def step(self, actions: dict):
        obs, rewards, terminations, truncations, infos = self.env.step(actions)
        if infos:
            first = next(iter(infos.values()))
            self.recorder.log(next(iter(rewards.values())), np.stack([infos[a]["tension"] for a in infos]),
                              first["min_separation"])
        return obs, rewards, terminations, truncations, infos

    def close(self):
        self.recorder.close()
        self.env.close()
