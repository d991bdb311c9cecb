"""The wind on a team's load over an episode (docs/team.md, "Tasks"; the single string's law,
esp_gym/pendulum/wind.py): a mean wind of a drawn azimuth, gusts of an Ornstein-Uhlenbeck process and
pushes."""
from __future__ import annotations

import math

import numpy as np

from ..pendulum.wind import drag_areas


class TeamWind:
    """The wind of one episode (``options``: esp_gym/pendulum/wind.py's ``wind_options``)."""

    def __init__(self, options):
        self.options = options
        self.mean = np.zeros(3)
        self.gust = np.zeros(3)

    def reset(self, rng: np.random.Generator) -> dict:
        """Draw the azimuth (unless given) and the first gust from ``rng``; returns the episode's
        ``wind_speed`` [m/s] and ``wind_direction`` [rad] for its info."""
        o = self.options
        azimuth = o.direction if o.direction is not None else 2.0 * math.pi * rng.random()
        self.mean = o.speed * np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
        self.gust = o.gusts * rng.standard_normal(3)
        return dict(wind_speed=float(o.speed), wind_direction=float(azimuth))

    def force(self, rng: np.random.Generator, kin: dict, scene, period: float) -> np.ndarray:
        """The force on the load over the next control step of ``period`` [s] [N], and the gusts
        and pushes drawn for it from ``rng``: drag 1/2 rho C_d A(n) |v| v of the air's velocity v
        relative to the load (A the load's projected area across n = v/|v|, esp_gym/pendulum/wind.py's
        law), plus a push (Poisson, a horizontal force changing the load's velocity by 0.5-1.5 x
        push_speed over the step, in a random azimuth). ``scene``: the team's lead scene."""
        o = self.options
        decay = math.exp(-period / o.gust_time)
        self.gust = decay * self.gust + o.gusts * math.sqrt(1.0 - decay * decay) * rng.standard_normal(3)
        relative = self.mean + self.gust - kin["load_velocity"]
        speed = float(np.linalg.norm(relative))
        force = np.zeros(3)
        if speed > 0.0:
            n = kin["R"].T @ (relative / speed)
            faces, side, (a, b), round_ = drag_areas(scene)
            area = faces @ np.abs(n) + side * math.hypot(a * n[1], b * n[0]) + round_
            force = 0.5 * o.air_density * o.load_drag_coefficient * area * speed * relative
        chance, azimuth, size = rng.random(3)
        if chance < -math.expm1(-o.push_rate * period):
            push = scene.body.mass * o.push_speed * (0.5 + size) / period
            force = force + push * np.array([math.cos(2 * math.pi * azimuth), math.sin(2 * math.pi * azimuth), 0.0])
        return force
