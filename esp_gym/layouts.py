"""The named layouts of the environments' vectors, for agents and users: what each action,
observation, target and sensor vector holds, by name and slice (the compiled step's layouts, owned
by esp_gym/kernels; docs/environment.md, "Spaces"). Code outside the package reads them here, not
from the kernels.

``Layout`` (name -> slice, size, fields); the point pivot's ``ACTION`` (``ACTION_SIZE``),
``WINCH_ACTION``, ``OBSERVATION``, ``TARGET`` and ``SENSORS``; the drone's ``ACTUATIONS``,
``DRONE_ACTION_PARAMS`` (its action path's constants) and ``DRONE_WINCH_ACTION``.
"""
from .kernels.drone.env import DRONE_ACTION_PARAMS, DRONE_WINCH_ACTION
from .kernels.drone.quadrotor import ACTUATIONS
from .kernels.env.arrays import ACTION, ACTION_SIZE, OBSERVATION, SENSORS, TARGET, WINCH_ACTION
from .kernels.layout import Layout

__all__ = ["ACTION", "ACTION_SIZE", "ACTUATIONS", "DRONE_ACTION_PARAMS", "DRONE_WINCH_ACTION", "Layout", "OBSERVATION",
           "SENSORS", "TARGET", "WINCH_ACTION"]
