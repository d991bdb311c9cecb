"""Teams: one body carried by several strings (docs/physics.md, "A team: several strings on one
body"; docs/team.md). :class:`TeamScene` describes one, :class:`TeamSimulator` steps it,
:func:`parallel_env` is its PettingZoo environment and ``ElasticStringTeam-v0`` its centralised
Gymnasium one. The PettingZoo env needs the ``team`` extra and is imported on first use;
``ElasticStringTeam-v0`` does not."""
from .scene import MAX_STRINGS, TeamScene, TeamString, symmetric_team
from .simulator import TeamSimulator, TeamState

__all__ = ["MAX_STRINGS", "ElasticStringTeamParallelEnv", "TeamScene", "TeamString", "TeamSimulator", "TeamState",
           "parallel_env", "symmetric_team"]


def __getattr__(name):
    if name in ("ElasticStringTeamParallelEnv", "parallel_env"):
        from . import parallel

        return getattr(parallel, name)
    raise AttributeError(f"module 'esp_gym.team' has no attribute {name!r}")
