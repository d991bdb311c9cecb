"""The Python face of the physics: initial state, the Simulator (step/run) and diagnostics.

Arrays follow one layout everywhere: node positions ``r`` and momenta ``p`` are ``(N+1, 3)``
(row 0 the pivot, row N the attachment node), ``R`` (3, 3) maps body to spatial frame, ``Pi`` is
the body's conjugate momentum (body frame, ``J Omega + M rho_c x R^T v_attach``) [kg m^2/s].
"""
from __future__ import annotations

import contextlib
import dataclasses
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
from tqdm.auto import tqdm

from .kernels.diagnostics import DIAG_NAMES, DiagWork, diagnostics as diagnostics_kernel
from .kernels.lgvi import (LGVIParams, Snapshots, StateArrays, Work, lgvi_advance, lgvi_record, specialised_kernels,
                           state_size)
from .kernels.string import tridiag_factor
from .params import Scene

STATUS_MESSAGES = {
    1: "Newton's method on the Cayley vector did not converge",
    2: "the state became non-finite (inf or NaN)",
    5: "an element stretched beyond solver.max_stretch times its rest length (the step is blowing up)",
}


class _NoBar:
    """Stands in for a tqdm bar when no progress is shown."""

    def update(self, n: int) -> None:
        pass


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


def cross3(a, b) -> np.ndarray:
    """``np.cross`` of two 3-vectors, same formula and bits, without its ~80 us of overhead."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def mass_matrix(scene: Scene):
    """``(diagonal (N+1,), off-diagonal, end share)`` of the string's mass matrix on the unknown
    nodes, with the body mass M at the attachment node and a free pivot's M_p at node 1 (a fixed
    pivot's diagonal entry is 0: not an unknown). Consistent mass: element matrix
    m/6 [[2, 1], [1, 2]] (end share 2m/6, off m/6); lumped: m/2 on each end node, no coupling.
    """
    n, m = scene.string.elements, scene.string.m
    if scene.string.mass_model == "consistent":
        off, end = m / 6.0, 2.0 * m / 6.0  # written as in the paper, so results stay bit-stable
    else:
        off, end = 0.0, 0.5 * m
    diag = np.full(n + 1, 2.0 * end)
    diag[0] = end + scene.pivot.mass if scene.pivot.is_free else 0.0
    diag[n] = end + scene.body.mass
    return diag, off, end


def build_params(scene: Scene) -> LGVIParams:
    """Scene -> the flat constants of the compiled stepper (see kernels/lgvi.py)."""
    n, m = scene.string.elements, scene.string.m
    M = scene.body.mass
    rho = np.array(scene.body.rho_c, dtype=float)
    J = scene.body.J
    J = 0.5 * (J + J.T)
    Jd = 0.5 * np.trace(J) * np.eye(3) - J
    diag, off, _ = mass_matrix(scene)
    first = 0 if scene.pivot.is_free else 1
    inv, cp = tridiag_factor(diag, off)
    # w = M_tot^-1 e_{N+1}: the attachment column of the inverse (Schur complement)
    k = n + 1 - first
    dense = np.diag(diag[first:]) + off * (np.eye(k, k=1) + np.eye(k, k=-1))
    e = np.zeros(k)
    e[-1] = 1.0
    w = np.zeros(n + 1)
    w[first:] = np.linalg.solve(dense, e)
    s = inv[n]  # (M_tot^-1)_{N+1,N+1} equals the last Thomas pivot inverse
    Jeff = J + M * M * s * hat(rho) @ hat(rho)
    return LGVIParams(
        h=float(scene.h), m=float(m), kappa=float(scene.string.kappa), u=float(scene.string.u),
        g=float(scene.gravity), M=float(M), Mp=float(scene.pivot.mass or 0.0), rho=rho, J=J, Jd=Jd,
        Jeff=Jeff, inv=inv, cp=cp, off=float(off), w=w, first=first,
        slack=scene.string.law == "slack",
        tol=float(scene.solver.newton_tol), max_iter=int(scene.solver.newton_max_iter),
        gammas=scene.solver.scheme.weights(),
        max_len2=float((scene.solver.max_stretch * scene.string.u) ** 2),
        compensated=bool(scene.solver.compensated),
    )


def legendre_momenta(scene: Scene, r: np.ndarray, v: np.ndarray, R: np.ndarray, Omega: np.ndarray):
    """Continuous Legendre transform of the finite-element Lagrangian: velocities -> momenta.

    p = M_str v + body terms at the attachment node (+ M_p v_1 at a free pivot),
    Pi = J Omega + M rho_c x (R^T v_attach). Used to start the integrator
    (physics_notes.md, "Initialisation").
    """
    M = scene.body.mass
    rho = np.array(scene.body.rho_c, dtype=float)
    J = scene.body.J
    _, off, end = mass_matrix(scene)
    p = np.zeros_like(v)
    p[:-1] += end * v[:-1] + off * v[1:]
    p[1:] += off * v[:-1] + end * v[1:]
    p[-1] += M * (v[-1] + R @ cross3(Omega, rho))
    if scene.pivot.is_free:
        p[0] += scene.pivot.mass * v[0]
    else:
        p[0] = 0.0  # the fixed pivot carries no momentum of its own
    Pi = J @ Omega + M * cross3(rho, R.T @ v[-1])
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
    attach_velocity (K, 3) [m/s]; energies and work [J]; pi3 and angular impulse [kg m^2/s];
    linear momentum and impulses (K, 3) [kg m/s]; strain_energy (K, N) [J]. The balances
    (work, impulses, residuals) count from the simulator's last balance reset.
    ``*_every_step`` hold (energy, pi3, orthogonality) after every step when requested.
    """

    t: np.ndarray
    nodes: np.ndarray
    R: np.ndarray
    omega: np.ndarray
    attach_velocity: np.ndarray
    kinetic_string: np.ndarray
    kinetic_body: np.ndarray
    kinetic_pivot: np.ndarray
    potential_gravity: np.ndarray
    potential_elastic: np.ndarray
    energy: np.ndarray
    pi3: np.ndarray
    orthogonality: np.ndarray
    stretched_length: np.ndarray
    strain_energy: np.ndarray
    linear_momentum: np.ndarray
    work: np.ndarray
    angular_impulse_z: np.ndarray
    energy_balance_residual: np.ndarray
    pi3_balance_residual: np.ndarray
    gravity_impulse: np.ndarray
    pivot_impulse: np.ndarray
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


def _vector_input(name: str, value) -> np.ndarray:
    """An input 3-vector [SI], checked: shape (3,), finite."""
    if value is None:
        return np.zeros(3)
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr


class Simulator:
    """Steps a :class:`~esp_gym.params.Scene` with the compiled LGVI.

    >>> sim = Simulator(load_scene("paper_example"))
    >>> sim.step(100)                 # 100 steps in one compiled call
    >>> traj = sim.run(t_final=1.0, record_every=100)
    >>> sim.diagnostics()["energy"]
    """

    def __init__(self, scene: Scene, specialise: bool = True):
        self.scene = scene
        self.params = build_params(scene)
        #: Run kernels compiled for this scene (fixed or free pivot, rho_c = 0 or not) and, per
        #: call, for whether any input is non-zero; ``False`` runs the general kernel (same
        #: results, every term computed: for tests and benchmarks).
        self.specialise = bool(specialise)
        self.h = scene.h
        n = scene.string.elements
        st = initial_state(scene)
        z = np.zeros
        self._arrays = StateArrays(
            r=st.r, p=st.p, R=st.R, Pi=st.Pi, rc=z((n + 1, 3)), pc=z((n + 1, 3)), Rc=z((3, 3)),
            Pic=z(3), f=z((n + 1, 3)), acc=z(8), accc=z(8))
        self._step = 0
        self._work = Work(fn=z((n + 1, 3)), X=z((n + 1, 3)), Y=z((n + 1, 3)),
                          FmI=z((3, 3)), RF=z((3, 3)), Rn=z((3, 3)), jac=z((3, 3)),
                          backup=z(state_size(self._arrays)))
        self._diag = DiagWork(V=z((n + 1, 3)), strain=z(n), omega=z(3), out=z(len(DIAG_NAMES)))
        self._inputs = z(9)
        self._forced = False  #: any input non-zero (picks the forced or the unforced kernels)
        self._coupled = bool(np.any(self.params.rho != 0.0))  # rho_c != 0: rotation coupled
        self._kernel_cache: dict = {}
        self._stats = np.zeros(4, dtype=np.int64)
        self.newton_iterations = 0  #: total Newton iterations so far
        self.newton_iterations_max = 0  #: most iterations in any one step so far
        self.reset_balances()

    @property
    def kernel_args(self):
        """``(StateArrays, Work, LGVIParams, DiagWork)``: the live arrays the kernels advance
        (for the environment's compiled step; mutate only through kernels)."""
        return self._arrays, self._work, self.params, self._diag

    def advance_counter(self, steps: int, newton_iterations: int = 0, newton_iterations_max: int = 0) -> None:
        """Count ``steps`` (and their Newton iterations) taken by an external kernel call on
        :attr:`kernel_args`."""
        self._step += int(steps)
        self.newton_iterations += int(newton_iterations)
        self.newton_iterations_max = max(self.newton_iterations_max, int(newton_iterations_max))

    # -- state ------------------------------------------------------------------------------
    @property
    def state(self) -> State:
        """A copy of the current discrete state (with its summation remainders)."""
        a = self._arrays
        return State(a.r.copy(), a.p.copy(), a.R.copy(), a.Pi.copy(), self._step,
                     (a.rc.copy(), a.pc.copy(), a.Rc.copy(), a.Pic.copy()))

    def set_state(self, state: State) -> None:
        """Replace the state (copied, shape- and finiteness-checked); resets the balances."""
        a = self._arrays
        for name in ("r", "p", "R", "Pi"):
            new = np.asarray(getattr(state, name), dtype=np.float64)
            if new.shape != getattr(a, name).shape:
                raise ValueError(f"state.{name} has shape {new.shape}, expected {getattr(a, name).shape}")
            if not np.all(np.isfinite(new)):
                raise ValueError(f"state.{name} is not finite")
        for name in ("r", "p", "R", "Pi"):
            getattr(a, name)[...] = getattr(state, name)
        self._step = int(state.step)
        rem = getattr(state, "remainders", None)
        for i, c in enumerate((a.rc, a.pc, a.Rc, a.Pic)):
            c[...] = 0.0 if rem is None else rem[i]
        self.reset_balances()

    def reset_balances(self) -> None:
        """Start the input balances (work, impulses) afresh from the current state."""
        self._arrays.acc[...] = 0.0
        self._arrays.accc[...] = 0.0
        self._update_diag()
        out = self._diag.out
        self._E0 = float(out[4])
        self._pi3_0 = float(out[5])
        self._P0 = out[9:12].copy()

    @property
    def step_count(self) -> int:
        return self._step

    @property
    def time(self) -> float:
        """Simulated time k*h [s]."""
        return self._step * self.h

    # -- stepping ---------------------------------------------------------------------------
    def _kernels(self):
        """``(advance, record)`` for this scene and the current inputs."""
        if not self.specialise:
            return lgvi_advance, lgvi_record
        key = (self.params.first == 0, self._forced, self._coupled, self.params.compensated)
        kernels = self._kernel_cache.get(key)
        if kernels is None:
            kernels = self._kernel_cache[key] = specialised_kernels(*key)
        return kernels

    def _set_inputs(self, pivot_force, body_torque, spatial_torque) -> None:
        """Validate and hold the inputs; ``self._forced`` says whether any is non-zero."""
        if pivot_force is None and body_torque is None and spatial_torque is None:
            # the common unforced call: no validation to do (~4 us of NumPy saved per call)
            if self._forced:
                self._inputs.fill(0.0)
                self._forced = False
            return
        up = _vector_input("pivot_force", pivot_force)
        tb = _vector_input("body_torque", body_torque)
        ts = _vector_input("spatial_torque", spatial_torque)
        if not self.scene.pivot.is_free and np.any(up != 0):
            raise ValueError("pivot_force needs a free pivot (this scene's pivot.kind is 'fixed')")
        self._inputs[0:3], self._inputs[3:6], self._inputs[6:9] = up, tb, ts
        self._forced = bool(np.any(self._inputs != 0.0))

    def _account(self) -> None:
        status, steps, total, most = (int(x) for x in self._stats)
        self._step += steps
        self.newton_iterations += total
        self.newton_iterations_max = max(self.newton_iterations_max, most)
        if status != 0:
            raise SimulationError(status, self._step, self.time, most)

    def step(self, n: int = 1, pivot_force=None, body_torque=None, spatial_torque=None) -> None:
        """Advance ``n`` steps in one compiled call with inputs held constant: ``pivot_force``
        (spatial frame, free pivot only) [N], ``body_torque`` (body frame) [N m],
        ``spatial_torque`` (spatial frame) [N m]; ``None`` means zero. Bad inputs raise
        ValueError before anything moves. Raises :class:`SimulationError` on failure (the
        simulator then holds the last good state)."""
        n = int(n)
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        self._set_inputs(pivot_force, body_torque, spatial_torque)
        advance, _ = self._kernels()
        advance(self._arrays, self._work, self.params, self._inputs, n, self._stats)
        self._account()

    def run(self, t_final: float, record_every: int = 100, every_step: bool = False,
            progress: bool = False, pivot_force=None, body_torque=None, spatial_torque=None) -> Trajectory:
        """Advance by ``t_final`` seconds (a whole number of steps) with constant inputs (as in
        :meth:`step`), recording every ``record_every`` steps (and energy, pi3, orthogonality
        after every step if ``every_step``). Returns a :class:`Trajectory` whose first snapshot
        is the current state."""
        nsteps = int(round(t_final / self.h))
        if nsteps < 0 or abs(nsteps * self.h - t_final) > 1e-9 * max(1.0, abs(t_final)):
            raise ValueError(f"t_final = {t_final} s is not a whole number of steps h = {self.h} s")
        record_every = int(record_every)
        if record_every < 1:
            raise ValueError(f"record_every must be >= 1, got {record_every}")
        if every_step and nsteps % record_every:
            raise ValueError("every_step needs t_final to be a whole number of record_every steps")
        self._set_inputs(pivot_force, body_torque, spatial_torque)
        advance, record = self._kernels()
        n = self.scene.string.elements
        K = nsteps // record_every
        e = np.empty
        snap = Snapshots(r=e((K + 1, n + 1, 3)), R=e((K + 1, 3, 3)), omega=e((K + 1, 3)), v=e((K + 1, 3)),
                         diag=e((K + 1, len(DIAG_NAMES))), strain=e((K + 1, n)), acc=e((K + 1, 8)),
                         step_diag=e((nsteps if every_step else 0, 3)))
        a, d = self._arrays, self._diag
        self._update_diag()
        snap.r[0], snap.R[0], snap.omega[0], snap.v[0] = a.r, a.R, d.omega, d.V[-1]
        snap.diag[0], snap.strain[0], snap.acc[0] = d.out, d.strain, a.acc
        step0 = self._step
        iters0 = self.newton_iterations
        start = _time.perf_counter()
        chunk = max(1, min(K, 2_000_000 // (record_every * max(n, 1)) or 1))
        # a disabled tqdm still costs ~50 us: build one only when asked for
        bar_cm = (tqdm(total=nsteps, unit="step", unit_scale=True, desc=f"{self.scene.name} (N={n}, h={self.h:g})")
                  if progress else contextlib.nullcontext(_NoBar()))
        with bar_cm as bar:
            j = 0
            while j < K:
                j1 = min(K, j + chunk)
                rows = slice(j + 1, j1 + 1)
                part = Snapshots(*(x[rows] for x in snap[:-1]),
                                 step_diag=snap.step_diag[j * record_every:j1 * record_every])
                record(a, self._work, self.params, self._inputs, record_every, d, part, self._stats)
                self._account()
                bar.update((j1 - j) * record_every)
                j = j1
            rest = nsteps - K * record_every
            if rest:
                advance(a, self._work, self.params, self._inputs, rest, self._stats)
                self._account()
                bar.update(rest)
        wall = _time.perf_counter() - start
        t = (step0 + record_every * np.arange(K + 1)) * self.h
        cols = {name: snap.diag[:, i].copy() for i, name in enumerate(DIAG_NAMES) if "momentum" not in name}
        traj = Trajectory(
            t=t, nodes=snap.r, R=snap.R, omega=snap.omega, attach_velocity=snap.v,
            strain_energy=snap.strain, linear_momentum=snap.diag[:, 9:12].copy(),
            work=snap.acc[:, 0].copy(), angular_impulse_z=snap.acc[:, 1].copy(),
            energy_balance_residual=cols["energy"] - self._E0 - snap.acc[:, 0],
            pi3_balance_residual=cols["pi3"] - self._pi3_0 - snap.acc[:, 1],
            gravity_impulse=snap.acc[:, 2:5].copy(), pivot_impulse=snap.acc[:, 5:8].copy(),
            steps=nsteps, newton_iterations=self.newton_iterations - iters0, wall_time_s=wall, **cols,
        )
        if every_step:
            traj.t_every_step = (step0 + 1 + np.arange(nsteps)) * self.h
            traj.energy_every_step = snap.step_diag[:, 0].copy()
            traj.pi3_every_step = snap.step_diag[:, 1].copy()
            traj.orthogonality_every_step = snap.step_diag[:, 2].copy()
        return traj

    # -- diagnostics ------------------------------------------------------------------------
    def _update_diag(self) -> None:
        diagnostics_kernel(self._arrays, self.params, self._diag)

    def diagnostics(self) -> dict:
        """Diagnostics of the current state from the discrete momenta (SI units).

        Scalars: time, energy, kinetic_string, kinetic_body, kinetic_pivot, potential_gravity,
        potential_elastic, pi3, orthogonality, stretched_length; the input balances since the
        last :meth:`reset_balances`: work, energy_balance_residual (E - E0 - W),
        angular_impulse_z, pi3_balance_residual (pi3 - pi3_0 - angular impulse).
        Vectors (3,): attach_position, attach_velocity, pivot_position, omega (body frame),
        linear_momentum, gravity_impulse, pivot_impulse, momentum_balance_residual
        (P - P0 - impulses; with a fixed pivot it is the pivot's reaction impulse);
        strain_energy (N,) per element.
        """
        self._update_diag()
        a, d = self._arrays, self._diag
        out = {"time": self.time}
        out.update({name: float(d.out[i]) for i, name in enumerate(DIAG_NAMES) if "momentum" not in name})
        out["work"] = float(a.acc[0])
        out["energy_balance_residual"] = out["energy"] - self._E0 - out["work"]
        out["angular_impulse_z"] = float(a.acc[1])
        out["pi3_balance_residual"] = out["pi3"] - self._pi3_0 - out["angular_impulse_z"]
        out["attach_position"] = a.r[-1].copy()
        out["attach_velocity"] = d.V[-1].copy()
        out["pivot_position"] = a.r[0].copy()
        out["omega"] = d.omega.copy()
        out["linear_momentum"] = d.out[9:12].copy()
        out["gravity_impulse"] = a.acc[2:5].copy()
        out["pivot_impulse"] = a.acc[5:8].copy()
        out["momentum_balance_residual"] = out["linear_momentum"] - self._P0 - a.acc[2:5] - a.acc[5:8]
        out["strain_energy"] = d.strain.copy()
        return out
