"""A team's tasks (docs/team.md): reward weights and scales, and the start and target
distributions."""
from __future__ import annotations

from dataclasses import dataclass


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
    #: (esp_gym/tasks.py ``track_reference``), starting where the load starts; the velocity term is
    #: then relative to the reference's velocity
    moving: bool = False

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
}


def get_team_task(name: str) -> TeamTask:
    if name not in TEAM_TASKS:
        raise ValueError(f"task must be one of {sorted(TEAM_TASKS)}, got {name!r}")
    return TEAM_TASKS[name]
