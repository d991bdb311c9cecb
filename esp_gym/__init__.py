"""esp_gym: the 3D elastic string pendulum (Lee, Leok & McClamroch) as a fast, exact simulator.

``import esp_gym`` stays light: the compiled physics is imported on first use.
"""
from .params import Scene, SceneError, available_scenes, load_scene

__all__ = ["Scene", "SceneError", "Simulator", "SimulationError", "Trajectory", "available_scenes", "load_scene"]
__version__ = "0.1.0"


def __getattr__(name):
    if name in ("Simulator", "SimulationError", "Trajectory", "State"):
        from . import model

        return getattr(model, name)
    raise AttributeError(f"module 'esp_gym' has no attribute {name!r}")
