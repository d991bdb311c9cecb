"""Teams: one body carried by several strings (docs/physics.md, "A team: several strings on one
body"; docs/team.md). :class:`TeamScene` describes one, :class:`TeamSimulator` steps it,
:func:`parallel_env` is its PettingZoo environment and ``ElasticStringTeam-v0`` its centralised
Gymnasium one."""
from .scene import MAX_STRINGS, TeamScene, TeamString, symmetric_team
from .simulator import TeamSimulator, TeamState
from .parallel import ElasticStringTeamParallelEnv, parallel_env

__all__ = ["MAX_STRINGS", "ElasticStringTeamParallelEnv", "TeamScene", "TeamString", "TeamSimulator", "TeamState",
           "parallel_env", "symmetric_team"]
