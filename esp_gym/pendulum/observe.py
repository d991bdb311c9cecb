"""Observation modes of ElasticStringPendulum-v0 (``observation=``) and their sensor noise.

* ``full``: the compiled step's OBSERVATION (kernels/env/arrays.py), the load's state included;
* ``hook``: HOOK_OBSERVATION, what a drone or a crane hook measures: its own position error and
  velocity, the string's pull on it (a load cell; SENSORS ``hook_tension``) and the load target
  relative to it, no load state.

Both are gathered by name from the step's OBSERVATION and SENSORS vectors; with a winch
(``winch=True``) each ends with the unstretched length (WINCH_OBSERVATION), and with a drone at the
pivot with the drone's attitude and body rates (DRONE_SENSORS: kernels/drone/env.py). ``sensor_noise`` adds
Gaussian noise drawn from the environment's ``np_random`` after every reset and step: a float s
gives each field s times its :data:`UNIT_NOISE` standard deviation, a mapping field -> standard
deviation (in the field's unit) sets fields of its own (the others noiseless).
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Union

import numpy as np

from ..kernels.drone.env import DRONE_SENSORS
from ..kernels.env.arrays import HOOK_OBSERVATION, OBSERVATION, SENSORS, WINCH_OBSERVATION
from ..kernels.layout import Layout

#: The observation layout of each mode.
MODES = {"full": OBSERVATION, "hook": HOOK_OBSERVATION}

#: Standard deviation of each field's noise at ``sensor_noise=1`` (its unit): a metre-class
#: position fix, a velocity estimate, an attitude estimate, a gyro, a load cell.
UNIT_NOISE = {
    "pivot_position_error": 0.01, "pivot_velocity": 0.05, "load_position_error": 0.01, "load_velocity": 0.05,
    "attitude_6d": 0.01, "angular_velocity": 0.05, "string_stretch": 1e-3, "hook_tension": 0.1,
    "load_target_offset": 0.01, "unstretched_length": 0.005, "drone_attitude_6d": 0.01, "drone_rates": 0.05,
}

#: The largest sensor_noise, a level or a standard deviation (every field's unit noise is at most
#: 0.1): noise far past any sensor, and float32 observations stay finite.
MAX_NOISE = 1e6

#: The step's measured vector by (winch, drone): OBSERVATION (WINCH_OBSERVATION with a winch), then
#: SENSORS (DRONE_SENSORS with a drone).
MEASURED = {(winch, drone): Layout(*(WINCH_OBSERVATION if winch else OBSERVATION).fields,
                                   *(DRONE_SENSORS if drone else SENSORS).fields)
            for winch in (False, True) for drone in (False, True)}
#: The winch's field of an observation (esp_gym/physics/winch.py).
WINCH_FIELD = ("unstretched_length", 1)
#: A drone's fields, at the end of either mode's observation (kernels/drone/env.py).
DRONE_FIELDS = DRONE_SENSORS.fields[len(SENSORS.fields):]


class Observer:
    """Turns the step's OBSERVATION and SENSORS into the mode's float32 observation."""

    def __init__(self, mode: str = "full", sensor_noise: Union[float, Mapping[str, Any]] = 0.0, winch: bool = False,
                 drone: bool = False):
        if mode not in MODES:
            raise ValueError(f"observation must be one of {sorted(MODES)}, got {mode!r}")
        self.mode = mode
        self.winch = bool(winch)
        self.drone = bool(drone)
        self.layout = Layout(*MODES[mode].fields, *((WINCH_FIELD,) if winch else ()), *(DRONE_FIELDS if drone else ()))
        measured = MEASURED[(self.winch, self.drone)]
        self._index = np.concatenate([np.arange(measured.size)[measured[name]] for name in self.layout.names])
        std = np.zeros(self.layout.size)
        if isinstance(sensor_noise, Mapping):
            for name, value in sensor_noise.items():
                if name not in self.layout:
                    raise ValueError(f"sensor_noise: {name!r} is not a field of the {mode!r} observation "
                                     f"({list(self.layout.names)})")
                std[self.layout[name]] = standard_deviation(f"sensor_noise[{name!r}]", value)
        else:
            level = standard_deviation("sensor_noise", sensor_noise)
            for name in self.layout.names:
                std[self.layout[name]] = level * UNIT_NOISE[name]
        #: Standard deviation of each entry's noise (its unit).
        self.noise_std = std
        self.noisy = bool(np.any(std > 0.0))
        self.plain = mode == "full" and not self.noisy and not self.drone

    def measure(self, obs: np.ndarray, sensors: np.ndarray) -> np.ndarray:
        """The mode's fields of the step's OBSERVATION and SENSORS (..., size), noiseless, float64:
        what a model-based controller differentiates (agents/baselines/lqg.py)."""
        return np.concatenate((obs, sensors), axis=-1)[..., self._index]

    def observe(self, obs: np.ndarray, sensors: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """One environment's observation (float32), noise drawn from ``rng``."""
        if self.plain:
            return obs.astype(np.float32)
        out = self.measure(obs, sensors)
        if self.noisy:
            out = out + self.noise_std * rng.standard_normal(self.layout.size)
        return out.astype(np.float32)

    def observe_batch(self, obs: np.ndarray, sensors: np.ndarray, rngs: list, rows=None) -> np.ndarray:
        """A batch's observations (B, size); noise for the sub-environments ``rows`` (default
        all) from their own generators, in row order."""
        if self.plain:
            return obs.astype(np.float32)
        out = self.measure(obs, sensors)
        if self.noisy:
            for i in (range(out.shape[0]) if rows is None else rows):
                out[i] += self.noise_std * rngs[i].standard_normal(self.layout.size)
        return out.astype(np.float32)


def standard_deviation(name: str, value: Any) -> float:
    """``value`` as a noise's standard deviation, or a noise level (a factor of each field's unit
    noise): a real number in [0, MAX_NOISE] (NumPy's too); ValueError naming ``name`` otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number >= 0, got {value!r}")
    if not (math.isfinite(float(value)) and 0.0 <= float(value) <= MAX_NOISE):
        raise ValueError(f"{name} must be finite and >= 0, at most {MAX_NOISE:g} (so that a float32 observation stays "
                         f"finite), got {value!r}")
    return float(value)
