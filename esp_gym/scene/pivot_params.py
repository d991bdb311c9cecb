"""The pivot's scene section (``pivot``): a fixed point, a free point mass, or a drone, whose own
parameters are ``pivot.drone`` (docs/physics.md, "The pivot" and "A drone at the pivot";
docs/scenes.md). A drone's mass is ``pivot.mass``; its hook is its centre of mass or a point
``rho_q`` away from it; its rotors are an X layout (esp_gym/scene/rotors.py).
"""
from __future__ import annotations

import math

import numpy as np
from typing import Literal, Optional

from pydantic import Field, model_validator

from .rotors import X_SPINS, allocation, mixer, x_layout
from .scene_input import Frozen, Real, bounded, vector

#: Positive per-axis values (principal inertias [kg m^2], rate gains [1/s]).
Positive3 = vector()
#: A drone's reach, in arm lengths: its rotors are one arm length from its centre of mass and its
#: propellers shorter than an arm (in an X layout neighbours are sqrt(2) arm lengths apart), so all
#: of its mass, and its hook, lie within 2 arm lengths of the centre of mass. A principal moment is
#: then at most m_q (2 l)^2, and |rho_q| at most 2 l.
DRONE_REACH = 2.0
#: The largest rate gain K_Omega [1/s]: the rates' time constant 1/K_Omega is then no shorter
#: than 1 ms, the period of a 1 kHz rate loop (a flight controller's, sampling its gyroscope); a
#: loop cannot track faster than it samples.
MAX_RATE_GAIN = 1e3
#: The largest K_Omega T_r of a rate loop of period T_r: a sampled proportional loop's error falls by
#: 1 - K T_r per period, so it must stay within 1 (no overshoot from one sample to the next).
MAX_RATE_LOOP_GAIN = 1.0
Point3 = vector("coordinate")
Velocity3 = vector("speed")


class DroneParams(Frozen):
    """A quadrotor at the pivot: body, rotors, motors and the onboard rate controller, SI units.
    Rotor i pushes with k_f omega_i^2 [N] along -b3 and twists the body with k_m omega_i^2
    [N m] about b3; its motor follows the commanded speed with the first-order lag t_up
    (spinning up) or t_down (spinning down); 0 makes the speed the command."""

    inertia: Positive3 = Field(description="principal moments of inertia about the centre of mass, body axes "
                                           "b1 (forward), b2 (right), b3 (down) [kg m^2]; each at most "
                                           "pivot.mass (2 arm_length)^2, as the drone's mass lies within "
                                           "DRONE_REACH = 2 arm lengths of its centre")
    arm_length: Real = Field(gt=0.0, le=1e3, description="centre of mass -> rotor axis [m] (X layout)")
    thrust_coefficient: Real = Field(gt=0.0, le=1e3, description="k_f: rotor thrust / omega^2 [N s^2/rad^2]")
    torque_coefficient: Real = Field(gt=0.0, le=1e3, description="k_m: rotor drag torque / omega^2 [N m s^2/rad^2]")
    max_rotor_speed: Real = Field(gt=0.0, le=1e6, description="largest rotor speed [rad/s]")
    motor_time_constant_up: Real = Field(0.0, ge=0.0, le=1e3, description="motor lag spinning up [s]")
    motor_time_constant_down: Real = Field(0.0, ge=0.0, le=1e3, description="motor lag spinning down [s]")
    rho_q: Point3 = Field((0.0, 0.0, 0.0), description="the hook -> the centre of mass, body frame [m]: (0, 0, 0) "
                                                   "hangs the string from the centre of mass; (0, 0, -0.05) from "
                                                   "5 cm below it (b3 points down); |rho_q| at most 2 arm_length, the "
                                                   "hook being a point of the drone (DRONE_REACH)")
    rate_gain: Positive3 = Field((20.0, 20.0, 10.0), description="the rate controller's K_Omega per body axis "
                                                                 "[1/s] (docs/physics.md, 'Actuation and the "
                                                                 "rate controller'), at most MAX_RATE_GAIN = "
                                                                 "1e3: a time constant of 1 ms or more, a "
                                                                 "1 kHz rate loop's period")
    rate_loop_period: Optional[Real] = Field(None, gt=0.0, le=1.0, description=(
        "the rate controller's period T_r [s]: it samples the body rates and sets the motor commands every "
        "T_r, held in between (docs/physics.md, 'Actuation and the rate controller'), so the closed loop is "
        "the same whatever the physics step h, which must divide T_r; null runs it at every physics step, "
        "making the loop's sampling h's. K_Omega T_r at most MAX_RATE_LOOP_GAIN"))

    @model_validator(mode="after")
    def _a_rigid_body_with_invertible_rotors(self) -> "DroneParams":
        for name in ("inertia", "rate_gain"):
            value = getattr(self, name)
            if not all(v > 0.0 for v in value):
                raise ValueError(f"pivot.drone.{name} must be three values > 0, got {list(value)}")
        if max(self.rate_gain) > MAX_RATE_GAIN:
            raise ValueError(f"pivot.drone.rate_gain must be at most {MAX_RATE_GAIN:g} 1/s per axis, got "
                             f"{list(self.rate_gain)}: a time constant under 1 ms, faster than a 1 kHz rate loop")
        if self.rate_loop_period is not None and max(self.rate_gain) * self.rate_loop_period > MAX_RATE_LOOP_GAIN:
            raise ValueError(f"pivot.drone.rate_loop_period {self.rate_loop_period:g} s times the largest rate_gain "
                             f"{max(self.rate_gain):g} 1/s is above {MAX_RATE_LOOP_GAIN:g}: the sampled rate loop "
                             "would overshoot from one sample to the next")
        reach = DRONE_REACH * self.arm_length
        if math.hypot(*self.rho_q) > reach:
            raise ValueError(f"pivot.drone.rho_q {list(self.rho_q)} is {math.hypot(*self.rho_q):g} m from the centre "
                             f"of mass, beyond the drone ({DRONE_REACH:g} arm lengths = {reach:g} m): the hook is "
                             "a point of the drone")
        J = self.inertia
        if not (J[0] + J[1] >= J[2] and J[1] + J[2] >= J[0] and J[2] + J[0] >= J[1]):
            raise ValueError(f"pivot.drone.inertia {list(J)} breaks the triangle inequality of principal "
                             "moments: no rigid body has it")
        self.mixer()  # an invertible layout, or ValueError naming it
        return self

    def inertia_matrix(self) -> np.ndarray:
        """J_q (3, 3) about the centre of mass [kg m^2]."""
        return np.diag(np.asarray(self.inertia, dtype=np.float64))

    def hook_inertia(self, mass: float) -> np.ndarray:
        """J_q^h = J_q + m_q (|rho_q|^2 I - rho_q rho_q^T) (3, 3), about the hook [kg m^2], for the
        drone's ``mass`` m_q [kg] (docs/physics.md, "A drone at the pivot")."""
        rho = np.asarray(self.rho_q, dtype=np.float64)
        return self.inertia_matrix() + mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))

    @property
    def offset_hook(self) -> bool:
        """The string hangs from a point other than the centre of mass (rho_q != 0)."""
        return any(v != 0.0 for v in self.rho_q)

    def rotor_positions(self) -> np.ndarray:
        """The rotors' positions (4, 3) [m] in the body frame, about the centre of mass: the X
        layout's (esp_gym/scene/rotors.py), in the rotors' plane b3 = 0."""
        return np.column_stack([x_layout(self.arm_length), np.zeros(4)])

    def mixer(self) -> np.ndarray:
        """A (4, 4): (f [N], tau [N m]) = A (T_1..T_4) for the X layout (esp_gym/scene/rotors.py)."""
        return mixer(x_layout(self.arm_length), X_SPINS, self.torque_coefficient / self.thrust_coefficient)

    def allocation(self) -> np.ndarray:
        """A^-1 (4, 4): the rotor thrusts [N] of a wrench (f [N], tau [N m])."""
        return allocation(self.mixer())

    @property
    def max_thrust(self) -> float:
        """The collective thrust of all four rotors at full speed [N]."""
        return 4.0 * self.thrust_coefficient * self.max_rotor_speed ** 2

    def rotor_speed_for(self, thrust: float) -> float:
        """The common rotor speed [rad/s] whose four rotors push with ``thrust`` [N] together."""
        return math.sqrt(max(thrust, 0.0) / (4.0 * self.thrust_coefficient))

    def rate_loop_steps(self, h: float) -> int:
        """Physics steps of ``h`` [s] per rate-loop period (1 without ``rate_loop_period``: every
        step); ValueError naming both when h does not divide the period."""
        if self.rate_loop_period is None:
            return 1
        steps = int(round(self.rate_loop_period / h))
        if steps < 1 or abs(steps * h - self.rate_loop_period) > 1e-9 * self.rate_loop_period:
            raise ValueError(f"pivot.drone.rate_loop_period {self.rate_loop_period:g} s is not a whole number of "
                             f"physics steps h = {h:g} s: take an h that divides it")
        return steps

    def decays(self, h: float) -> tuple:
        """(e^(-h/t_up), e^(-h/t_down)) of the motor lag over a step ``h`` [s] (0 for t = 0)."""
        return tuple(0.0 if t == 0.0 else math.exp(-h / t)
                     for t in (self.motor_time_constant_up, self.motor_time_constant_down))


class PivotParams(Frozen):
    """Where the string is held. ``fixed``: the paper's pivot at ``position``. ``free``: node 1
    is a point mass ``mass`` [kg] free in 3-D (a crane hook, a drone), starting at ``position``
    with ``velocity`` [m/s], pushed by the pivot force input. ``drone``: node 1 is a quadrotor's
    hook (its centre of mass, or ``drone.rho_q`` from it), of mass ``mass``, flown by its rotors (``drone``:
    esp_gym/drone_params.py; docs/physics.md, "A drone at the pivot")."""

    kind: Literal["fixed", "free", "drone"] = "fixed"
    position: Point3 = (0.0, 0.0, 0.0)
    mass: Optional[Real] = bounded("mass", default=None, description="point mass of a free pivot [kg]")
    velocity: Velocity3 = (0.0, 0.0, 0.0)
    drone: Optional[DroneParams] = None

    @model_validator(mode="after")
    def _mass_iff_free(self) -> "PivotParams":
        if self.kind != "fixed" and self.mass is None:
            raise ValueError(f"a {self.kind} pivot needs its mass (pivot.mass > 0)")
        if self.kind == "fixed" and (self.mass is not None or any(self.velocity)):
            raise ValueError("pivot.mass and pivot.velocity belong to a free pivot (kind: free or drone)")
        if (self.kind == "drone") != (self.drone is not None):
            raise ValueError("pivot.drone (the quadrotor's parameters) belongs to pivot.kind: drone, and it needs "
                             f"them; got kind {self.kind!r} with{'' if self.drone is not None else 'out'} pivot.drone")
        if self.drone is not None:
            largest = self.mass * (DRONE_REACH * self.drone.arm_length) ** 2
            if max(self.drone.inertia) > largest:
                raise ValueError(f"pivot.drone.inertia {list(self.drone.inertia)} exceeds pivot.mass (2 arm_length)^2 "
                                 f"= {largest:.3g} kg m^2: no drone of {self.mass:g} kg within {DRONE_REACH:g} arm "
                                 "lengths of its centre has so large a moment")
        return self

    @property
    def is_free(self) -> bool:
        """Node 1 moves: a point mass or a drone."""
        return self.kind != "fixed"

    @property
    def is_drone(self) -> bool:
        return self.kind == "drone"
