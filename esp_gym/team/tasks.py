"""A team's tasks (docs/team.md): reward weights and scales, the start and target distributions,
the thresholds that end an episode and the presets (the time limit is the single env's,
esp_gym.MAX_EPISODE_STEPS)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..kernels.layout import Layout
from ..kernels.team.task import AGENT_REWARD, OBSERVED, TEAM_REWARD, TEAM_TASK, TeamTaskArrays
from ..pendulum.env_setup import DRONE_FLIP_TILT, PRESETS
from ..pendulum.options import TEAM_LACKS
from ..physics.arrays import team_task_arrays

#: Pivots closer than this are penalised (the reward's separation term) [m].
SEPARATION = 0.4
#: Pivots closer than this have collided: the episode ends [m].
COLLISION = 0.15
#: A drone whose body axis b3 tilts past this from the downward vertical has flipped: the episode
#: ends (the single drone's DRONE_FLIP_TILT).
FLIP_COSINE = math.cos(math.radians(DRONE_FLIP_TILT))
#: The team's reward terms, in order (``info["reward_<term>"]``), and those each agent has its own
#: share of (``info["agent_<term>"]``, one per agent): kernels/team/task.py's layouts.
REWARD_TERMS = TEAM_REWARD.names
AGENT_TERMS = AGENT_REWARD.names
#: The options each preset sets (those given to the environment win): the single env's, less what
#: a team lacks (esp_gym/pendulum/options.py TEAM_LACKS: the hard preset's thrust noise).
TEAM_PRESETS = {name: {k: v for k, v in preset.items() if k not in TEAM_LACKS} for name, preset in PRESETS.items()}


@dataclass(frozen=True)
class TeamTask:
    """Reward weights and scales, and the start and target distributions, of a team task.

    Each tracking term is ``weight / (1 + (x/scale)^2)``; the control term is
    ``-w_control mean_k |a_k|^2 / 3``; the separation term ``-w_separation sum over pairs of
    max(0, 1 - d/SEPARATION)^2``. So a step's reward is at most
    w_load_position + w_load_velocity + w_pivot_position + w_tilt + w_spin."""

    name: str
    w_load_position: float = 0.45
    w_load_velocity: float = 0.1
    w_pivot_position: float = 0.2
    w_tilt: float = 0.2
    w_spin: float = 0.05
    w_control: float = 0.1
    w_separation: float = 0.5
    scale_position: float = 0.2  #: [m]
    scale_velocity: float = 0.5  #: [m/s]
    scale_tilt: float = 0.2  #: [rad]
    scale_spin: float = 1.0  #: [rad/s]
    max_speed: float = 0.05  #: the load's initial speed, up to this per axis [m/s]
    max_spin: float = 0.1  #: the load's initial body rates, up to this per axis [rad/s]
    target_box: tuple = (0.0, 0.0, 0.0)  #: the load's target, uniform in +-box about its start [m]
    max_stretch: float = 1.5  #: the episode ends when a string is longer than this times its l
    workspace_radius: float = 4.0  #: the episode ends when the load or a pivot is this far from its target [m]
    #: the load's target moves along a reference of the single string's track family
    #: (esp_gym/pendulum/tasks.py ``track_reference``), starting where the load starts; the velocity term is
    #: then relative to the reference's velocity
    moving: bool = False
    #: lift: each string's winch must reel it to this many times its length, uniform in the range
    #: (the same for every string), the load rising with it and the pivots held where they are
    reel_range: tuple = (0.0, 0.0)

    @property
    def needs_winch(self) -> bool:
        return self.reel_range != (0.0, 0.0)

    @property
    def max_reward(self) -> float:
        return self.w_load_position + self.w_load_velocity + self.w_pivot_position + self.w_tilt + self.w_spin


TEAM_TASKS = {
    # bring a load knocked into motion (up to 0.5 m/s, 1 rad/s) to rest, the pivots held in formation
    "stabilize": TeamTask("stabilize", max_speed=0.5, max_spin=1.0, w_load_position=0.35, w_load_velocity=0.2,
                          w_tilt=0.15, w_spin=0.1),
    # carry a load hanging at rest to a random target, the pivots in formation around it
    "transport": TeamTask("transport", target_box=(1.0, 1.0, 0.5)),
    # carry a load hanging at rest along a circle or a figure-eight, the pivots in formation around it
    "track": TeamTask("track", moving=True, w_load_position=0.5, w_load_velocity=0.15, w_pivot_position=0.15,
                      w_tilt=0.15, w_spin=0.05),
    # hoist a load hanging at rest by reeling every string in to 55-75 % of its length, the pivots
    # held where they are, with little tilt and swing (winch=True)
    "lift": TeamTask("lift", reel_range=(-0.45, -0.25), w_load_position=0.45, w_load_velocity=0.1,
                     w_pivot_position=0.2, w_tilt=0.2, w_spin=0.05),
}


def get_team_task(name: str) -> TeamTask:
    if name not in TEAM_TASKS:
        raise ValueError(f"task must be one of {sorted(TEAM_TASKS)}, got {name!r}")
    return TEAM_TASKS[name]


def task_arrays(task: TeamTask, layout: Layout, size: int) -> TeamTaskArrays:
    """The compiled task's arrays (kernels/team/task.py) of ``task`` for ``size`` agents observing
    ``layout`` (esp_gym/team/spaces.py ``agent_layout``): its constants and the layout's fields;
    the targets zero."""
    constants = {"separation": SEPARATION, "collision": COLLISION, "flip_cosine": FLIP_COSINE}
    arrays = team_task_arrays(size, layout.size)
    arrays.params[...] = [constants[name] if name in constants else getattr(task, name) for name in TEAM_TASK.names]
    arrays.fields[...] = [layout.start(name) if name in layout else -1 for name in OBSERVED.names]
    return arrays


def hanging_rise(kin: dict, attachments: np.ndarray, lengths: np.ndarray) -> float:
    """The load's change of depth [m] (< 0: up) when every string of a team hanging as ``kin``
    (TeamCore.kinematics) goes to ``lengths`` (K,) [m], each keeping its stretch and its
    horizontal span: the mean over strings of the change of sqrt((s l)^2 - d^2), s its stretch, d
    its span; ``attachments`` (K, 3) body frame, from the centre of mass [m]."""
    ends = kin["load"] + (kin["R"] @ np.asarray(attachments, dtype=float).T).T
    rise = []
    for k, (pivot, end) in enumerate(zip(kin["pivot"], ends)):
        chord = end - pivot
        span2 = chord[0] ** 2 + chord[1] ** 2
        stretch = np.linalg.norm(chord) / kin["lengths"][k]
        rise.append(np.sqrt((stretch * lengths[k]) ** 2 - span2) - abs(chord[2]))
    return float(np.mean(rise))
