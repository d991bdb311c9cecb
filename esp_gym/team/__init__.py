"""Teams: one body carried by several strings (docs/physics.md, "A team: several strings on one
body"). :class:`TeamScene` describes one, :class:`TeamSimulator` steps it."""
from .scene import MAX_STRINGS, TeamScene, TeamString, symmetric_team
from .simulator import TeamSimulator, TeamState

__all__ = ["MAX_STRINGS", "TeamScene", "TeamString", "TeamSimulator", "TeamState", "symmetric_team"]
