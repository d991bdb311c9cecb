"""esp_gym: the 3D elastic string pendulum (Lee, Leok & McClamroch) as a fast, exact simulator
and the Gymnasium environment ``ElasticStringPendulum-v0``.

``import esp_gym`` registers the environment and stays light: the compiled physics is imported
on first use.
"""
from gymnasium.envs.registration import register, registry

from .scene.params import Scene, SceneError, available_scenes, load_scene

__all__ = ["Scene", "SceneError", "Simulator", "SimulationError", "StepChoice", "Trajectory", "available_scenes", "choose_h",
           "choose_resolution", "ResolutionChoice", "load_scene", "rigs"]
__version__ = "0.1.0"

ENV_ID = "ElasticStringPendulum-v0"
#: Time limit of an episode of ENV_ID [control steps]: 10 s at the default 20-ms control period.
MAX_EPISODE_STEPS = 500

if ENV_ID not in registry:
    register(
        id=ENV_ID,
        entry_point="esp_gym.pendulum.env:ElasticStringPendulumEnv",
        vector_entry_point="esp_gym.pendulum.vector:ElasticStringPendulumVectorEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
    )

TEAM_ENV_ID = "ElasticStringTeam-v0"
if TEAM_ENV_ID not in registry:
    register(id=TEAM_ENV_ID, entry_point="esp_gym.team.env:ElasticStringTeamEnv",
             vector_entry_point="esp_gym.team.vector:ElasticStringTeamVectorEnv", max_episode_steps=MAX_EPISODE_STEPS)


def __getattr__(name):
    if name in ("Simulator", "SimulationError", "Trajectory", "State"):
        from .physics import simulator

        return getattr(simulator, name)
    if name in ("choose_h", "StepChoice"):
        from .physics import pilot

        return getattr(pilot, name)
    if name in ("choose_resolution", "ResolutionChoice"):
        from .scene import stepsize

        return getattr(stepsize, name)
    if name == "rigs":
        from .physics.rig import rigs

        return rigs
    raise AttributeError(f"module 'esp_gym' has no attribute {name!r}")
