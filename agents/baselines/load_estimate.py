"""The load's position and velocity from what a drone's hook measures (``observation="hook"``),
for the load-led cascade of agents/baselines/geometric.py (docs/agents.md, "Flying the drone").

The hook measures the string's pull T on the drone [N] (spatial; it points from the drone
towards the load). The string is light next to the load, so the load feels -T:

* its acceleration is a = g e3 - T / m (m the load's mass; e3 points down, as everywhere in the
  project), known from the load cell;
* it hangs at the distance l from the drone along q = T / |T|, so its place relative to the
  drone's target is p = e_drone + l q.

Per axis, a steady-state Kalman filter on x = [p, v, b] (the place, the velocity and an
acceleration the model leaves out: the wind's drag, the reference's acceleration) with
x+ = F x + G a, F = [[1, h, h^2/2], [0, 1, h], [0, 0, 1]], G = [h^2/2, h, 0], fuses the two:
the load cell's acceleration carries the velocity between the position fixes, whose error the
string's direction noise sets (|noise of T| / |T| rad times l).

What the hook does not say the first observation does: the load's weight m g is the first
reading's downward pull, then a low-pass of it (time constant ``weighing_time``; over a swing its
mean is the weight). A first reading that pulls up or not at all (a load lighter than the load
cell's noise: crazyflie_load's pulls 0.049 N, the hard preset's noise is 0.1 N) weighs nothing;
the estimate then starts from the nominal load's mass (``nominal_mass``, the nominal scene's), and
the low-pass, a convex mean while ``weighing_time`` exceeds the period, keeps it positive. And l
is the depth of the load's target below the drone's ((load_target_offset + pivot_position_error) . e3, the episode's hanging depth). With a winch l
follows the reel instead (the caller gives it each step: the observed unstretched length plus the
nominal excess of the hanging depth over it), and the load's target stays at the first depth.
Nothing of the episode's true parameters is read.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Optional

import numpy as np
import scipy.linalg

from esp_gym.layouts import Layout

E3 = np.array([0.0, 0.0, 1.0])

#: What :attr:`LoadEstimator.features` holds: the estimate a residual network sees beside the
#: observation.
ESTIMATE = Layout(("load_position_error", 3), ("load_velocity", 3), ("unmodelled_acceleration", 3),
                  ("load_mass", 1))


def nominal_load_mass(scene) -> float:
    """What the hook weighs of ``scene``'s rig at rest [kg]: the load and its string."""
    return scene.body.mass + scene.string.mass_per_length * scene.string.length


def axis_model(period: float) -> tuple:
    """``(F, G)`` of one axis over a step of ``period`` [s]: x+ = F x + G a (module docstring)."""
    h = period
    return np.array([[1.0, h, 0.5 * h * h], [0.0, 1.0, h], [0.0, 0.0, 1.0]]), np.array([0.5 * h * h, h, 0.0])


def steady_gain(period: float, position_std: float, acceleration_std: float, drift_std: float) -> np.ndarray:
    """The steady-state Kalman gain (3,) of one axis of x = [p, v, b] (module docstring) with a
    position fix of standard deviation ``position_std`` [m], white acceleration noise
    ``acceleration_std`` [m/s^2] over each step and the left-out acceleration's random walk
    ``drift_std`` [m/s^2 per sqrt(s)]."""
    F, G = axis_model(period)
    Q = acceleration_std ** 2 * np.outer(G, G) + np.diag([0.0, 0.0, drift_std ** 2 * period])
    C = np.array([[1.0, 0.0, 0.0]])
    R = np.array([[position_std ** 2]])
    P = scipy.linalg.solve_discrete_are(F.T, C.T, Q, R)  # the predicted covariance
    return (P @ C.T / (C @ P @ C.T + R)).ravel()


@dataclass
class LoadEstimator:
    """The filter of the module docstring for a control period ``period`` [s], gravity
    ``gravity`` [m/s^2] and the nominal load's mass ``nominal_mass`` [kg] (the string's included;
    the start of the weight when the first reading weighs nothing). Noise: ``position_std`` [m] of
    the position fix, ``acceleration_std`` [m/s^2] of the load cell's acceleration, ``drift_std``
    of the left-out acceleration; ``weighing_time`` [s] the weight's low-pass (longer than the
    period); below ``taut_fraction`` of the weight the pull
    is too slack to fix the load's place (the filter predicts only)."""

    period: float
    gravity: float
    nominal_mass: float
    position_std: float = 0.05
    acceleration_std: float = 1.0
    drift_std: float = 1.0
    weighing_time: float = 2.0
    taut_fraction: float = 0.3
    _gain: np.ndarray = field(init=False, repr=False)
    _state: Optional[np.ndarray] = field(default=None, init=False, repr=False)  # (3 axes, [p, v, b])
    _input: np.ndarray = field(default_factory=lambda: np.zeros(3), init=False, repr=False)
    _mass: float = field(default=0.0, init=False, repr=False)
    _length: float = field(default=0.0, init=False, repr=False)
    _depth: float = field(default=0.0, init=False, repr=False)

    def __post_init__(self):
        for name in ("period", "gravity", "nominal_mass", "position_std", "acceleration_std", "drift_std",
                     "weighing_time"):
            if not getattr(self, name) > 0:
                raise ValueError(f"LoadEstimator {name} must be > 0, got {getattr(self, name)!r}")
        if not self.weighing_time > self.period:  # the weight's low-pass stays a mean of the readings
            raise ValueError(f"LoadEstimator weighing_time must exceed the period {self.period!r}, "
                             f"got {self.weighing_time!r}")
        self._gain = steady_gain(self.period, self.position_std, self.acceleration_std, self.drift_std)  # [p, v, b]
        self._F, self._G = axis_model(self.period)

    def clone(self) -> "LoadEstimator":
        """The same filter with no estimate yet."""
        twin = copy.copy(self)
        twin.start()
        return twin

    def start(self) -> None:
        """Forget the episode: the next :meth:`update` starts a new estimate."""
        self._state = None

    @property
    def load_mass(self) -> float:
        """The load's weighed mass [kg] (the string's below the hook included)."""
        return self._mass

    @property
    def length(self) -> float:
        """The drone-load distance l [m]."""
        return self._length

    @property
    def depth(self) -> float:
        """The depth of the load's target below the drone's [m] (the first observation's; without a
        winch also l)."""
        return self._depth

    @property
    def position_error(self) -> np.ndarray:
        """The load's place relative to its own target, :attr:`depth` below the drone's [m]."""
        return self._state[:, 0] - self._depth * E3

    @property
    def velocity(self) -> np.ndarray:
        """The load's velocity (less the target's) [m/s]."""
        return self._state[:, 1].copy()

    @property
    def disturbance(self) -> np.ndarray:
        """The load's acceleration the model leaves out [m/s^2] (the wind's drag)."""
        return self._state[:, 2].copy()

    @property
    def features(self) -> np.ndarray:
        """:data:`ESTIMATE`: the load's position error relative to its own target, velocity,
        left-out acceleration and mass (zeros before the first :meth:`update`)."""
        out = np.zeros(ESTIMATE.size)
        if self._state is not None:
            out[ESTIMATE["load_position_error"]] = self.position_error
            out[ESTIMATE["load_velocity"]] = self._state[:, 1]
            out[ESTIMATE["unmodelled_acceleration"]] = self._state[:, 2]
            out[ESTIMATE["load_mass"]] = self._mass
        return out

    def update(self, drone_error: np.ndarray, tension: np.ndarray, load_target_offset: np.ndarray,
               length: Optional[float] = None) -> None:
        """Take one observation: the drone's position error [m], the hook's pull [N] and the load
        target relative to the drone [m]; ``length``, the drone-load distance now [m] when a winch
        changes it (None: the depth of the load's target below the drone's, from the first)."""
        pull = float(np.linalg.norm(tension))
        q = tension / pull if pull > 0 else E3
        if length is not None:
            self._length = max(float(length), 0.0)
        if self._state is None:
            self._mass = max(float(tension[2]), 0.0) / self.gravity
            if not self._mass > 0:  # a load lighter than the cell's noise (module docstring)
                self._mass = float(self.nominal_mass)
            self._depth = max(float(load_target_offset[2] + drone_error[2]), 0.0)
            if length is None:
                self._length = self._depth
            self._state = np.zeros((3, 3))
            self._state[:, 0] = drone_error + self._length * q
        else:
            self._mass += self.period / self.weighing_time * (max(float(tension[2]), 0.0) / self.gravity - self._mass)
            predicted = self._state @ self._F.T + np.outer(self._input, self._G)
            self._state = predicted
            if pull > self.taut_fraction * self.gravity * self._mass:  # a slack string does not point at the load
                innovation = drone_error + self._length * q - predicted[:, 0]
                self._state = predicted + np.outer(innovation, self._gain)
        mass = max(self._mass, 1e-6)
        self._input = self.gravity * E3 - tension / mass
