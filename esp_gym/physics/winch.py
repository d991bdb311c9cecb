"""The winch's Python face: its arrays, its checks and its share of a Simulator's diagnostics
(the step is kernels/step/winch.py; the model docs/physics.md, "The winch").

A :class:`~esp_gym.physics.simulator.Simulator` holds one :class:`Winch`. While the length is the scene's and
the reel speed is 0 the winch is idle and the simulator runs the fixed-length kernels, bit for bit
as without a winch; once it has moved, every step is the winch's (with v = 0 it is the
fixed-length step at the new length).
"""
from __future__ import annotations

import math

import numpy as np

from ..kernels.layout import WINCH, WinchArrays
from ..kernels.step.winch import convective_weights, winch_energy
from ..scene.params import Scene
from ..scene.scene_input import real_number
from ..scene.stepsize import shortest
from .arrays import winch_arrays


def winch_state(scene: Scene, max_len2: float) -> np.ndarray:
    """The :data:`~esp_gym.kernels.layout.WINCH` vector of ``scene`` (``max_len2``: its blow-up
    guard, LGVIParams.max_len2): its length, the reel at rest, its string's constants and the
    winch's range."""
    s, st = scene.string, np.zeros(WINCH.size)
    consistent = s.mass_model == "consistent"
    st[WINCH["length"]] = s.length
    st[WINCH["mass_per_length"]] = s.mass_per_length
    st[WINCH["EA"]] = s.EA
    st[WINCH["max_stretch"]] = math.sqrt(max_len2) / s.u
    st[WINCH["end_share"]] = 1.0 / 3.0 if consistent else 0.5
    st[WINCH["off_share"]] = 1.0 / 6.0 if consistent else 0.0
    st[WINCH["min_length"]], st[WINCH["max_length"]] = scene.winch_range
    return st


class Winch:
    """The winch of a simulator of ``scene``: the unstretched length [m], the reel speed of the
    state [m/s] and the compiled step's arrays (:class:`~esp_gym.kernels.layout.WinchArrays`)."""

    def __init__(self, scene: Scene, max_len2: float):
        self._state = np.zeros(WINCH.size)
        self._arrays = None
        self.use_scene(scene, max_len2)

    @property
    def arrays(self) -> WinchArrays:
        """The compiled step's arrays, made on first use (about 14 floats per node; a simulator
        that never reels does not hold them)."""
        if self._arrays is None:
            self._arrays = winch_arrays(self._state, convective_weights(self.elements, self.consistent))
        return self._arrays

    def use_scene(self, scene: Scene, max_len2: float) -> None:
        """Take ``scene``'s string and winch (a new episode's); the length goes back to the
        scene's and the reel stops."""
        s = scene.string
        self.elements, self.consistent = s.elements, s.mass_model == "consistent"
        self._state[...] = winch_state(scene, max_len2)
        if self._arrays is not None:  # in place: the environment's compiled step holds them
            self._arrays.coef[...] = convective_weights(self.elements, self.consistent)
        self.scene_length = float(s.length)
        self.max_speed = float(scene.winch.max_speed)
        self.min_length, self.max_length = scene.winch_range
        self._shortest_bound = None  # the stability bound at min_length, found when first needed
        self.reset()

    def reset(self) -> None:
        """The scene's length, the reel at rest."""
        self.set(self.scene_length, 0.0)

    def set(self, length: float, reel_speed: float) -> None:
        """Set the length [m] and the state's reel speed [m/s] (checked)."""
        length, speed = real_number("length", length), self.check_speed(reel_speed)  # both, before any change
        if not self.min_length <= length <= self.max_length:
            raise ValueError(f"length = {length:g} m lies outside the winch's range "
                             f"[{self.min_length:g}, {self.max_length:g}] m")
        st = self._state
        st[WINCH.scalar("length")] = length
        st[WINCH.scalar("reel_speed")] = speed

    def check_speed(self, reel_speed) -> float:
        """``reel_speed`` [m/s] as a float: ValueError naming it unless it is a finite real of
        magnitude at most ``winch.max_speed``."""
        v = real_number("reel_speed", reel_speed)
        if abs(v) > self.max_speed:
            raise ValueError(f"reel_speed = {v:g} m/s exceeds winch.max_speed = {self.max_speed:g} m/s")
        return v

    def check_scene(self, scene: Scene, h: float) -> None:
        """ValueError unless ``scene`` can reel at step ``h``: the explicit string's h stable at the
        winch's shortest length (the assembled string's bound there); the implicit string
        has no such bound (its steps cut themselves back where the transverse one breaks). A damped
        string does not reel yet (docs/physics.md, "Material damping")."""
        if scene.string.damped:
            raise ValueError(f"reel_speed: the winch does not reel a damped string yet (string.damping_time = "
                             f"{scene.string.damping_time:g} s; docs/physics.md, \"Material damping\")")
        if scene.solver.string == "implicit":
            return
        if self._shortest_bound is None:  # the assembled string's, at its shortest elements
            self._shortest_bound = shortest(scene).stability_bound
        bound = self._shortest_bound
        if h > bound and not scene.allow_unstable_h:
            raise ValueError(f"reel_speed: h = {h:g} s exceeds the stability bound {bound:.4g} s at the winch's "
                             f"shortest length winch.min_length = {self.min_length:g} m; raise winch.min_length "
                             "or take a smaller h")

    @property
    def vector(self) -> np.ndarray:
        """The live WINCH vector (length, reel speed, the string's constants, the range), read
        only (recordings read it: esp_gym/viz/recorder.py)."""
        view = self._state.view()
        view.flags.writeable = False
        return view

    @property
    def length(self) -> float:
        """The unstretched length [m]."""
        return float(self._state[WINCH.scalar("length")])

    @property
    def reel_speed(self) -> float:
        """The reel speed of the state [m/s] (its momenta were made with it)."""
        return float(self._state[WINCH.scalar("reel_speed")])

    @property
    def idle(self) -> bool:
        """At the scene's length and at rest: the fixed-length kernels run."""
        return self.length == self.scene_length and self.reel_speed == 0.0

    def energy(self, buffers) -> float:
        """Fill the simulator's diagnostics scratch for its state; returns the energy, the
        Hamiltonian H = T2 - T0 + V of the reeling string (docs/physics.md, "The winch")."""
        H, _ = winch_energy(buffers.state, buffers.params, self.arrays, buffers.diag, self.length, self.reel_speed)
        return float(H)
