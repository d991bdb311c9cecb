"""The Python face of the physics: initial state, the Simulator (step/run) and diagnostics.

Arrays follow one layout everywhere: node positions ``r`` and momenta ``p`` are ``(N+1, 3)``
(row 0 the pivot, row N the attachment node), ``R`` (3, 3) maps body to spatial frame, ``Pi`` is
the body's conjugate momentum (body frame, ``J Omega + M rho_c x R^T v_attach``) [kg m^2/s].
"""
from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
from tqdm.auto import tqdm

from .kernels.diagnostics import DIAG_NAMES, diagnostics as _diagnostics
from .kernels.lgvi import LGVIParams, Work, lgvi_advance, lgvi_record
from .kernels.string import tridiag_factor
from .params import Scene

STATUS_MESSAGES = {
    1: "Newton's method on the Cayley vector did not converge",
    2: "the state became non-finite (inf or NaN)",
}


class SimulationError(RuntimeError):
    """The stepper could not take a step. The simulator keeps the last good state."""

    def __init__(self, status: int, step: int, time: float, newton_iterations: int):
        self.status = status
        self.step = step
        self.time = time
        super().__init__(
            f"step {step} (t = {time:.6g} s) failed: {STATUS_MESSAGES.get(status, status)} "
            f"(Newton iterations in the failing step: {newton_iterations}); "
            "the simulator holds the last good state. A smaller h usually helps.")


@dataclass
class State:
    """A discrete state ``(q_k, p_k)`` at step ``step``; arrays are copies owned by the caller.

    ``remainders`` holds the compensated-summation remainders of (r, p, R, Pi): restoring them
    makes save/restore bit-exact; ``None`` (e.g. after editing the momenta) restarts them at 0.
    """

    r: np.ndarray
    p: np.ndarray
    R: np.ndarray
    Pi: np.ndarray
    step: int = 0
    remainders: Optional[tuple] = None

    def copy(self) -> "State":
        rem = None if self.remainders is None else tuple(a.copy() for a in self.remainders)
        return State(self.r.copy(), self.p.copy(), self.R.copy(), self.Pi.copy(), self.step, rem)


def hat(v) -> np.ndarray:
    """The hat map: ``hat(v) @ y == np.cross(v, y)``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def consistent_mass_diagonal(scene: Scene) -> np.ndarray:
    """Diagonal (N+1,) of the consistent mass matrix of the unknown nodes; 0 for the fixed pivot.

    Off-diagonal entries are all ``m/6``; the attachment node carries the body mass M.
    """
    n, m = scene.string.elements, scene.string.m
    diag = np.full(n + 1, 4.0 * m / 6.0)
    diag[0] = 0.0  # fixed pivot: not an unknown
    diag[n] = 2.0 * m / 6.0 + scene.body.mass
    return diag


def build_params(scene: Scene) -> LGVIParams:
    """Scene -> the flat constants of the compiled stepper (see kernels/lgvi.py)."""
    n, m = scene.string.elements, scene.string.m
    M = scene.body.mass
    rho = np.array(scene.body.rho_c, dtype=float)
    J = np.array(scene.body.inertia, dtype=float)
    J = 0.5 * (J + J.T)
    Jd = 0.5 * np.trace(J) * np.eye(3) - J
    off = m / 6.0
    inv, cp = tridiag_factor(consistent_mass_diagonal(scene), off)
    # w = M_tot^-1 e_{N+1}: the attachment row of the inverse (Schur complement column)
    w = np.zeros(n + 1)
    dense = np.diag(consistent_mass_diagonal(scene)[1:]) + off * (np.eye(n, k=1) + np.eye(n, k=-1))
    e = np.zeros(n)
    e[-1] = 1.0
    w[1:] = np.linalg.solve(dense, e)
    s = inv[n]  # (M_tot^-1)_{N+1,N+1} equals the last Thomas pivot inverse
    Jeff = J + M * M * s * hat(rho) @ hat(rho)
    return LGVIParams(
        h=float(scene.h), m=float(m), kappa=float(scene.string.kappa), u=float(scene.string.u),
        g=float(scene.gravity), M=float(M), rho=rho, J=J, Jd=Jd, Jeff=Jeff,
        inv=inv, cp=cp, off=float(off), w=w, first=1,
        tol=float(scene.solver.newton_tol), max_iter=int(scene.solver.newton_max_iter),
    )


def legendre_momenta(scene: Scene, r: np.ndarray, v: np.ndarray, R: np.ndarray, Omega: np.ndarray):
    """Continuous Legendre transform of the finite-element Lagrangian: velocities -> momenta.

    p = M_str v + body terms at the attachment node, Pi = J Omega + M rho_c x (R^T v_attach).
    Used to start the integrator (physics_notes.md, "Initialisation").
    """
    m, M = scene.string.m, scene.body.mass
    rho = np.array(scene.body.rho_c, dtype=float)
    J = np.array(scene.body.inertia, dtype=float)
    p = np.zeros_like(v)
    p[:-1] += (m / 6.0) * (2.0 * v[:-1] + v[1:])
    p[1:] += (m / 6.0) * (v[:-1] + 2.0 * v[1:])
    p[-1] += M * (v[-1] + R @ np.cross(Omega, rho))
    p[0] = 0.0  # the fixed pivot carries no momentum of its own
    Pi = J @ Omega + M * np.cross(rho, R.T @ v[-1])
    return p, Pi


def initial_state(scene: Scene) -> State:
    """The state at t = 0: configuration from the scene, momenta by the Legendre transform."""
    r = scene.initial_nodes()
    v = scene.initial_velocities()
    R = np.array(scene.initial.R0, dtype=float)
    Omega = np.array(scene.initial.Omega0, dtype=float)
    p, Pi = legendre_momenta(scene, r, v, R, Omega)
    return State(np.ascontiguousarray(r), np.ascontiguousarray(p), np.ascontiguousarray(R), Pi, 0)


@dataclass
class Trajectory:
    """Snapshots of a run every ``record_every`` steps (K of them, t = 0 included).

    Units: t [s]; nodes (K, N+1, 3) [m]; R (K, 3, 3); omega (K, 3) body frame [rad/s];
    attach_velocity (K, 3) [m/s]; energies [J]; pi3 [kg m^2/s]; strain_energy (K, N) [J].
    ``*_every_step`` hold (energy, pi3, orthogonality) after every step when requested.
    """

    t: np.ndarray
    nodes: np.ndarray
    R: np.ndarray
    omega: np.ndarray
    attach_velocity: np.ndarray
    kinetic_string: np.ndarray
    kinetic_body: np.ndarray
    potential_gravity: np.ndarray
    potential_elastic: np.ndarray
    energy: np.ndarray
    pi3: np.ndarray
    orthogonality: np.ndarray
    stretched_length: np.ndarray
    strain_energy: np.ndarray
    t_every_step: Optional[np.ndarray] = None
    energy_every_step: Optional[np.ndarray] = None
    pi3_every_step: Optional[np.ndarray] = None
    orthogonality_every_step: Optional[np.ndarray] = None
    steps: int = 0
    newton_iterations: int = 0
    wall_time_s: float = 0.0
    extra: dict = field(default_factory=dict)

    def arrays(self) -> dict:
        """The array fields (those that are set), e.g. for ``np.savez``."""
        return {k: v for k, v in dataclasses.asdict(self).items() if isinstance(v, np.ndarray)}

    def save(self, path: str | Path) -> None:
        np.savez_compressed(path, **self.arrays())


class Simulator:
    """Steps a :class:`~esp_gym.params.Scene` with the compiled LGVI.

    >>> sim = Simulator(load_scene("paper_example"))
    >>> sim.step(100)                 # 100 steps in one compiled call
    >>> traj = sim.run(t_final=1.0, record_every=100)
    >>> sim.diagnostics()["energy"]
    """

    def __init__(self, scene: Scene):
        self.scene = scene
        self.params = build_params(scene)
        self.h = scene.h
        n = scene.string.elements
        self._state = initial_state(scene)
        self._forces = np.zeros((n + 1, 3))
        # compensated-summation remainders of r, p, R, Pi (part of the state, reset by set_state)
        self._comp = (np.zeros((n + 1, 3)), np.zeros((n + 1, 3)), np.zeros((3, 3)), np.zeros(3))
        self._work = Work(
            fn=np.zeros((n + 1, 3)), B=np.zeros((n + 1, 3)), X=np.zeros((n + 1, 3)),
            Y=np.zeros((n + 1, 3)), FmI=np.zeros((3, 3)), RF=np.zeros((3, 3)), Rn=np.zeros((3, 3)),
            jac=np.zeros((3, 3)),
        )
        self._diag_work = dict(V=np.zeros((n + 1, 3)), strain=np.zeros(n), omega=np.zeros(3), out=np.zeros(8))
        self._stats = np.zeros(4, dtype=np.int64)
        self.newton_iterations = 0  #: total Newton iterations so far
        self.newton_iterations_max = 0  #: most iterations in any one step so far

    # -- state ------------------------------------------------------------------------------
    @property
    def state(self) -> State:
        """A copy of the current discrete state (with its summation remainders)."""
        st = self._state.copy()
        st.remainders = tuple(a.copy() for a in self._comp)
        return st

    def set_state(self, state: State) -> None:
        """Replace the state (copied, shape- and finiteness-checked)."""
        s = self._state
        for name in ("r", "p", "R", "Pi"):
            new = np.asarray(getattr(state, name), dtype=np.float64)
            if new.shape != getattr(s, name).shape:
                raise ValueError(f"state.{name} has shape {new.shape}, expected {getattr(s, name).shape}")
            if not np.all(np.isfinite(new)):
                raise ValueError(f"state.{name} is not finite")
            getattr(s, name)[...] = new
        s.step = int(state.step)
        rem = getattr(state, "remainders", None)
        for i, c in enumerate(self._comp):
            c[...] = 0.0 if rem is None else rem[i]

    @property
    def step_count(self) -> int:
        return self._state.step

    @property
    def time(self) -> float:
        """Simulated time k*h [s]."""
        return self._state.step * self.h

    # -- stepping ---------------------------------------------------------------------------
    def _args(self):
        s = self._state
        return (s.r, s.p, s.R, s.Pi, *self._comp, self._forces, self._work, self.params)

    def _account(self) -> None:
        status, steps, total, most = (int(x) for x in self._stats)
        self._state.step += steps
        self.newton_iterations += total
        self.newton_iterations_max = max(self.newton_iterations_max, most)
        if status != 0:
            raise SimulationError(status, self._state.step, self.time, most)

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps in one compiled call. Raises :class:`SimulationError` on failure
        (the simulator then holds the last good state)."""
        n = int(n)
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        lgvi_advance(*self._args(), n, self._stats)
        self._account()

    def run(self, t_final: float, record_every: int = 100, every_step: bool = False,
            progress: bool = False) -> Trajectory:
        """Advance by ``t_final`` seconds (a whole number of steps), recording every
        ``record_every`` steps (and energy, pi3, orthogonality after every step if
        ``every_step``). Returns a :class:`Trajectory` whose first snapshot is the current state."""
        nsteps = int(round(t_final / self.h))
        if nsteps < 0 or abs(nsteps * self.h - t_final) > 1e-9 * max(1.0, abs(t_final)):
            raise ValueError(f"t_final = {t_final} s is not a whole number of steps h = {self.h} s")
        record_every = int(record_every)
        if record_every < 1:
            raise ValueError(f"record_every must be >= 1, got {record_every}")
        if every_step and nsteps % record_every:
            raise ValueError("every_step needs t_final to be a whole number of record_every steps")
        n = self.scene.string.elements
        K = nsteps // record_every
        snap = dict(
            r=np.empty((K + 1, n + 1, 3)), R=np.empty((K + 1, 3, 3)), omega=np.empty((K + 1, 3)),
            v=np.empty((K + 1, 3)), diag=np.empty((K + 1, 8)), strain=np.empty((K + 1, n)),
        )
        per_step = np.empty((nsteps if every_step else 0, 3))
        d = self._diag_work
        s = self._state
        _diagnostics(s.r, s.p, s.R, s.Pi, self.params, d["V"], d["strain"], d["omega"], d["out"])
        snap["r"][0], snap["R"][0], snap["omega"][0] = s.r, s.R, d["omega"]
        snap["v"][0], snap["diag"][0], snap["strain"][0] = d["V"][-1], d["out"], d["strain"]
        step0 = s.step
        iters0 = self.newton_iterations
        start = _time.perf_counter()
        chunk = max(1, min(K, 2_000_000 // (record_every * max(n, 1)) or 1))
        with tqdm(total=nsteps, disable=not progress, unit="step", unit_scale=True,
                  desc=f"{self.scene.name} (N={n}, h={self.h:g})") as bar:
            j = 0
            while j < K:
                j1 = min(K, j + chunk)
                k0 = (j) * record_every
                lgvi_record(*self._args(), record_every, d["V"], d["strain"], d["omega"], d["out"],
                            snap["r"][j + 1:j1 + 1], snap["R"][j + 1:j1 + 1], snap["omega"][j + 1:j1 + 1],
                            snap["v"][j + 1:j1 + 1], snap["diag"][j + 1:j1 + 1], snap["strain"][j + 1:j1 + 1],
                            per_step[k0:j1 * record_every] if every_step else per_step, self._stats)
                self._account()
                bar.update((j1 - j) * record_every)
                j = j1
            rest = nsteps - K * record_every
            if rest:
                self.step(rest)
                bar.update(rest)
        wall = _time.perf_counter() - start
        t = (step0 + record_every * np.arange(K + 1)) * self.h
        diag = {name: snap["diag"][:, i].copy() for i, name in enumerate(DIAG_NAMES)}
        traj = Trajectory(
            t=t, nodes=snap["r"], R=snap["R"], omega=snap["omega"], attach_velocity=snap["v"],
            strain_energy=snap["strain"], steps=nsteps, newton_iterations=self.newton_iterations - iters0,
            wall_time_s=wall, **diag,
        )
        if every_step:
            traj.t_every_step = (step0 + 1 + np.arange(nsteps)) * self.h
            traj.energy_every_step = per_step[:, 0].copy()
            traj.pi3_every_step = per_step[:, 1].copy()
            traj.orthogonality_every_step = per_step[:, 2].copy()
        return traj

    # -- diagnostics ------------------------------------------------------------------------
    def diagnostics(self) -> dict:
        """Diagnostics of the current state from the discrete momenta (SI units).

        Keys: time, energy, kinetic_string, kinetic_body, potential_gravity, potential_elastic,
        pi3, orthogonality, stretched_length (scalars); attach_position (3,), omega (3,, body
        frame), attach_velocity (3,), strain_energy (N,) per element.
        """
        d = self._diag_work
        s = self._state
        _diagnostics(s.r, s.p, s.R, s.Pi, self.params, d["V"], d["strain"], d["omega"], d["out"])
        out = {"time": self.time}
        out.update({name: float(d["out"][i]) for i, name in enumerate(DIAG_NAMES)})
        out["attach_position"] = s.r[-1].copy()
        out["attach_velocity"] = d["V"][-1].copy()
        out["omega"] = d["omega"].copy()
        out["strain_energy"] = d["strain"].copy()
        return out
