"""The Python face of the physics: the Simulator (step/run) and its diagnostics.

The state, its layout and the scene's constants are in esp_gym/physics/state.py; a run's snapshots in
esp_gym/physics/trajectory.py.
"""
from __future__ import annotations

import contextlib
from collections import namedtuple
import time as _time
from typing import Optional

import numpy as np
from tqdm.auto import tqdm

from ..kernels.step.diagnostics import diagnostics as diagnostics_kernel
from .arrays import copy_into, diag_work, state_arrays, work_arrays
from ..kernels.layout import (BALANCE, DIAG, INPUTS, LOOP_REPORT_SIZE, R_NEWTON_MAX, R_NEWTON_TOTAL, R_STATUS, R_STEPS,
                              STEP_DIAG, LGVIParams, Snapshots, StateArrays, Work)
from ..kernels.status import OK
from ..kernels.step.loops import winch_advance, winch_advance_implicit
from ..kernels.step.specialise import general_kernels, specialised_kernels
from ..kernels.step.string import state_forces
from ..errors import SimulationError, failure_advice  # noqa: F401  (re-exported)
from ..scene.params import Scene, check_rotation
from .trajectory import Trajectory  # noqa: F401  (re-exported)
from ..kernels.step.winch import winch_forces
from ..scene.stepsize import at_length
from .watchdog import WATCH_EVERY, check_balance
from .winch import Winch
from .state import (State, StepClock, build_params, check_memory, initial_state,  # noqa: F401  (re-exported)
                    legendre_momenta)

#: The live arrays of a simulator that the compiled kernels advance: ``state``
#: (:class:`~esp_gym.kernels.layout.StateArrays`), ``work`` (Work), ``params`` (LGVIParams),
#: ``diag`` (DiagWork). For kernel-level collaborators (esp_gym/pendulum/control.py, the recorder);
#: mutate them only through kernels.
Buffers = namedtuple("Buffers", "state work params diag")


class _NoBar:
    """Stands in for a tqdm bar when no progress is shown."""

    def update(self, n: int) -> None:
        pass


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


#: How far from orthogonal a state's attitude may be (``||R^T R - I||``, Frobenius). The integrator keeps
#: it near round-off (docs/physics.md, "Round-off"), so this admits any state it produced.
ROTATION_TOL = 1e-9


class Simulator(StepClock):
    """Steps a :class:`~esp_gym.scene.params.Scene` with the compiled LGVI.

    >>> sim = Simulator(load_scene("paper_example"))
    >>> sim.step(100)                 # 100 steps in one compiled call
    >>> traj = sim.run(t_final=1.0, record_every=100)
    >>> sim.diagnostics()["energy"]
    """

    def __init__(self, scene: Scene, specialise: bool = True):
        check_memory(scene.string.elements, damped=scene.string.damped)
        self.scene = scene
        self.params = build_params(scene)
        #: Run kernels compiled for this scene (fixed or free pivot, rho_c = 0 or not) and, per
        #: call, for whether any input is non-zero; ``False`` runs the general kernel (same
        #: results, every term computed: for tests and benchmarks).
        self.specialise = bool(specialise)
        #: The string's elastic force is implicit (``scene.solver.string``, kernels/step/implicit.py).
        self.implicit = scene.solver.string == "implicit"
        self.h = scene.h
        #: The winch at the pivot (esp_gym/physics/winch.py): :meth:`step`'s ``reel_speed``.
        self.winch = Winch(scene, self.params.max_len2)
        n = scene.string.elements
        st = initial_state(scene)
        self._arrays = state_arrays(n, st.r, st.p, st.R, st.Pi)
        self._step = 0
        self._work = work_arrays(n, damped=scene.string.damped)
        self._diag = diag_work(n)
        self._inputs = np.zeros(INPUTS.size)
        self._forced = False  #: any input non-zero (an unforced call then zeroes them, once)
        self._coupled = bool(np.any(self.params.rho != 0.0))  # rho_c != 0: rotation coupled
        self._kernel_cache: dict = {}
        self._stats = np.zeros(LOOP_REPORT_SIZE, dtype=np.int64)
        state_forces(self._arrays, self.params)
        self._unwatched = 0  #: steps since the energy watchdog last looked (see :meth:`_account`)
        self.newton_iterations = 0  #: total Newton iterations so far
        self.newton_iterations_max = 0  #: most iterations in any one step so far
        self.reset_balances()

    def use_scene(self, scene: Scene, params: Optional[LGVIParams] = None) -> None:
        """Run ``scene``, of the same elements, pivot kind and scheme, from here on (a randomised
        episode's: esp_gym/pendulum/randomize.py): run-time constants change, no compiled kernel.
        ``params``: its constants if built. Set a state next (:meth:`set_state`)."""
        for what in ("string.elements", "pivot.kind", "solver.string", "string.damped"):
            section, field = what.split(".")
            a, b = (getattr(getattr(x, section), field) for x in (self.scene, scene))
            if a != b:
                raise ValueError(f"use_scene: {what} must stay {a!r}, got {b!r}")
        self.scene = scene
        self.params = build_params(scene) if params is None else params
        self.h = scene.h
        self._coupled = bool(np.any(self.params.rho != 0.0))
        self.winch.use_scene(scene, self.params.max_len2)

    @property
    def buffers(self) -> Buffers:
        """The live arrays the kernels advance (:data:`Buffers`), for kernel-level collaborators
        (esp_gym/pendulum/control.py, the recorder); mutate them only through kernels and report the
        steps taken with :meth:`count_steps`."""
        return Buffers(self._arrays, self._work, self.params, self._diag)

    def use_buffers(self, state: StateArrays, work: Work) -> None:
        """Step in ``state`` and ``work`` (views of a batch's rows: esp_gym/team/batch.py) from now
        on, the current ones copied into them."""
        copy_into(self._arrays, state)
        copy_into(self._work, work)
        self._arrays, self._work = state, work

    def count_steps(self, report: np.ndarray) -> None:
        """Count the steps and Newton iterations of a :data:`~esp_gym.kernels.layout.REPORT`
        of a kernel call on :attr:`buffers` (the step counter, time and Newton totals)."""
        self._step += int(report[R_STEPS])
        self.newton_iterations += int(report[R_NEWTON_TOTAL])
        self.newton_iterations_max = max(self.newton_iterations_max, int(report[R_NEWTON_MAX]))

    # -- state ------------------------------------------------------------------------------
    @property
    def state(self) -> State:
        """A copy of the current discrete state (with its summation remainders)."""
        a = self._arrays
        return State(a.r.copy(), a.p.copy(), a.R.copy(), a.Pi.copy(), self._step,
                     (a.rc.copy(), a.pc.copy(), a.Rc.copy(), a.Pic.copy(), a.owed.copy()),
                     None if self.winch.idle else (self.winch.length, self.winch.reel_speed))

    def set_state(self, state: State, check: bool = True) -> None:
        """Replace the state (copied; resets the balances), checked like a scene (real, finite, of
        this scene's shapes, R a rotation to ``ROTATION_TOL``) unless ``check`` is False (a state
        its caller built for this scene: an environment's reset); its winch's length in range."""
        a = self._arrays
        checked = {}
        for name in ("r", "p", "R", "Pi"):
            given = np.asarray(getattr(state, name))
            if check and given.dtype.kind not in "iuf":
                raise ValueError(f"state.{name} must hold real numbers, got dtype {given.dtype}")
            new = given.astype(np.float64, copy=False)
            if check and new.shape != getattr(a, name).shape:
                raise ValueError(f"state.{name} has shape {new.shape}, expected {getattr(a, name).shape}")
            if check and not np.all(np.isfinite(new)):
                raise ValueError(f"state.{name} is not finite")
            checked[name] = new
        if check:
            check_rotation("state.R", checked["R"], ROTATION_TOL)
        winch = getattr(state, "winch", None)
        if winch is None:
            self.winch.reset()
        else:
            self.winch.set(*winch)
        for name, new in checked.items():
            getattr(a, name)[...] = new
        self._step = int(state.step)
        rem = getattr(state, "remainders", None)
        for i, c in enumerate((a.rc, a.pc, a.Rc, a.Pic, a.owed)):
            c[...] = 0.0 if rem is None or i >= len(rem) else rem[i]
        if self.winch.idle:
            state_forces(a, self.params)
        else:
            winch_forces(a, self.params, self.winch.arrays)
        self.reset_balances()

    def reset_balances(self) -> None:
        """Start the input balances (work, impulses) afresh from the current state."""
        self._arrays.acc[...] = 0.0
        self._arrays.accc[...] = 0.0
        self._update_diag()
        out = self._diag.out
        self._E0 = float(out[DIAG.scalar("energy")])
        self._pi3_0 = float(out[DIAG.scalar("pi3")])
        self._P0 = out[DIAG["linear_momentum"]].copy()

    # -- stepping ---------------------------------------------------------------------------
    def _kernels(self):
        """``(advance, record)`` for this scene (its body's coupling, its sums, its string's scheme
        and damper)."""
        damped = self.scene.string.damped
        if not self.specialise:
            return general_kernels(self.implicit, damped)
        key = (self._coupled, self.params.compensated, self.implicit, damped)
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
        self._inputs[INPUTS["pivot_force"]] = up
        self._inputs[INPUTS["pivot_force_end"]] = up  # held over the step
        self._inputs[INPUTS["body_torque"]] = tb
        self._inputs[INPUTS["spatial_torque"]] = ts
        self._forced = bool(np.any(self._inputs != 0.0))

    #: Long :meth:`step` and :meth:`run` calls are cut into compiled calls of about this many
    #: seconds [s]; Python handles signals between them, so Ctrl-C stops a long call within
    #: about this time, with the state and step counter of the calls made.
    call_seconds = 0.05
    #: Steps in one compiled call of a long :meth:`step` or :meth:`run` (a first guess; each
    #: simulator then sets its own from how long its calls take, to take ``call_seconds``).
    steps_per_call = 1 << 14

    def _account(self) -> None:
        """Count the report of the last kernel call, raise on failure, and let the watchdog look.
        Counted once: a second call (the ``finally`` after a late Ctrl-C) adds nothing."""
        steps = int(self._stats[R_STEPS])
        self.count_steps(self._stats)
        self._stats[R_STEPS] = self._stats[R_NEWTON_TOTAL] = 0
        status = int(self._stats[R_STATUS])
        if status != OK:
            raise SimulationError(status, self._step, self.time, int(self._stats[R_NEWTON_MAX]),
                                  failure_advice(self._scene_now(), status))
        self._unwatched += steps
        if self._unwatched >= WATCH_EVERY:
            self._unwatched = 0
            self._watch()

    def _watch(self) -> None:
        """The energy watchdog (esp_gym/physics/watchdog.py): SimulationError once the balance breaks."""
        if self.scene.solver.energy_watchdog is not None:
            acc = self._arrays.acc
            work = acc[BALANCE.scalar("work")] + acc[BALANCE.scalar("winch_work")]
            check_balance(self.scene, self._update_diag() - self._E0 - work, work, self._step, self.time,
                          self._scene_now().stability_bound)

    def _scene_now(self) -> Scene:
        """The scene at the winch's current length (its bound is the one a failure is measured by)."""
        return self.scene if self.winch.idle else at_length(self.scene, self.winch.length)

    def _timed(self, kernel, args: tuple, steps: int) -> None:
        """Call ``kernel(*args)``, which takes ``steps`` steps, and count them, also when an
        exception (Ctrl-C) comes as it returns; then set :attr:`steps_per_call` from its
        duration (at most 4x the steps, at least 256)."""
        start = _time.perf_counter()
        try:
            kernel(*args)
        finally:
            self._account()
        took = max(_time.perf_counter() - start, 1e-6)
        self.steps_per_call = int(min(4 * steps, max(256, steps * self.call_seconds / took)))

    def step(self, n: int = 1, pivot_force=None, body_torque=None, spatial_torque=None, reel_speed=None) -> None:
        """Advance ``n`` steps with inputs held constant: ``pivot_force`` (spatial frame, free
        pivot only) [N], ``body_torque`` (body frame) [N m], ``spatial_torque`` (spatial
        frame) [N m]; ``None`` means zero. Bad inputs raise ValueError before anything moves.
        Raises :class:`SimulationError` on failure (the simulator then holds the last good
        state). A long call is cut into compiled calls of about :attr:`call_seconds` each, so
        Ctrl-C interrupts it (KeyboardInterrupt; the simulator then holds the state after the
        calls made, and counts their steps); the results are bit for bit those of one call.
        ``reel_speed`` [m/s]: the winch reels the string out (> 0) or in at this speed, within
        ``scene.winch`` (docs/physics.md, "The winch"); ``None`` is 0."""
        n = int(n)
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        speed = 0.0 if reel_speed is None else self.winch.check_speed(reel_speed)
        reeling = speed != 0.0 or not self.winch.idle  # an idle winch runs the fixed-length kernels
        if reeling:
            self.winch.check_scene(self.scene, self.h)
        self._set_inputs(pivot_force, body_torque, spatial_torque)
        if reeling:
            return self._reel(n, speed)
        advance, _ = self._kernels()
        while n > self.steps_per_call:  # a long call: in pieces, between which Python handles signals
            k = self.steps_per_call
            n -= k
            self._timed(advance, (self._arrays, self._work, self.params, self._inputs, k, self._stats), k)
        try:
            advance(self._arrays, self._work, self.params, self._inputs, n, self._stats)
        finally:
            self._account()

    def _reel(self, n: int, speed: float) -> None:
        """:meth:`step` with the winch (kernels/step/winch.py), in calls of about :attr:`call_seconds`."""
        a, w = self._arrays, self.winch.arrays
        advance = winch_advance_implicit if self.implicit else winch_advance
        while n > 0:
            k = min(n, self.steps_per_call)
            n -= k
            self._timed(advance, (a, self._work, self.params, w, self._diag, self._inputs, speed, k,
                                        self._stats), k)

    def run(self, t_final: float, record_every: int = 100, every_step: bool = False, progress: bool = False,
            pivot_force=None, body_torque=None, spatial_torque=None, reel_speed=None) -> Trajectory:
        """Advance by ``t_final`` seconds (a whole number of steps) with constant inputs (as in
        :meth:`step`, ``reel_speed`` included), recording every ``record_every`` steps (and
        energy, pi3, orthogonality after every step if ``every_step``). Returns a
        :class:`Trajectory` whose first snapshot is the current state. While the winch reels or
        holds a moved length, Python records between compiled calls of ``record_every`` steps
        (of one step with ``every_step``): the same states as :meth:`step`'s."""
        nsteps = int(round(t_final / self.h))
        if nsteps < 0 or abs(nsteps * self.h - t_final) > 1e-9 * max(1.0, abs(t_final)):
            raise ValueError(f"t_final = {t_final} s is not a whole number of steps h = {self.h} s")
        record_every = int(record_every)
        if record_every < 1:
            raise ValueError(f"record_every must be >= 1, got {record_every}")
        if every_step and nsteps % record_every:
            raise ValueError("every_step needs t_final to be a whole number of record_every steps")
        speed = 0.0 if reel_speed is None else self.winch.check_speed(reel_speed)
        reeling = speed != 0.0 or not self.winch.idle
        if reeling:
            self.winch.check_scene(self.scene, self.h)
        self._set_inputs(pivot_force, body_torque, spatial_torque)
        n = self.scene.string.elements
        K = nsteps // record_every
        e = np.empty
        snap = Snapshots(r=e((K + 1, n + 1, 3)), R=e((K + 1, 3, 3)), omega=e((K + 1, 3)), v=e((K + 1, 3)),
                         diag=e((K + 1, DIAG.size)), strain=e((K + 1, n)), acc=e((K + 1, BALANCE.size)),
                         step_diag=e((nsteps if every_step else 0, STEP_DIAG.size)))
        length = np.full(K + 1, self.winch.length)
        self._snapshot(snap, 0)
        step0, iters0 = self._step, self.newton_iterations
        start = _time.perf_counter()
        # a disabled tqdm still costs ~50 us: build one only when asked for
        bar_cm = (tqdm(total=nsteps, unit="step", unit_scale=True, desc=f"{self.scene.name} (N={n}, h={self.h:g})")
                  if progress else contextlib.nullcontext(_NoBar()))
        with bar_cm as bar:
            if reeling:
                self._run_reeling(snap, length, record_every, speed, every_step, bar)
            else:
                self._run_compiled(snap, record_every, bar)
            rest = nsteps - K * record_every
            if rest:
                self.step(rest, pivot_force, body_torque, spatial_torque, reel_speed=speed)
                bar.update(rest)
        t = (step0 + record_every * np.arange(K + 1)) * self.h
        return Trajectory.from_snapshots(
            snap, t, length, self._E0, self._pi3_0, nsteps, self.newton_iterations - iters0,
            _time.perf_counter() - start, (step0 + 1 + np.arange(nsteps)) * self.h if every_step else None)

    def _run_compiled(self, snap: Snapshots, record_every: int, bar) -> None:
        """:meth:`run`'s snapshots 1.. by the compiled recording loop, in calls of about
        :attr:`call_seconds` (see :meth:`step`), so Ctrl-C stops a long run."""
        _, record = self._kernels()
        K = snap.r.shape[0] - 1
        j = 0
        while j < K:
            j1 = min(K, j + max(1, self.steps_per_call // record_every))
            rows = slice(j + 1, j1 + 1)
            part = Snapshots(*(x[rows] for x in snap[:-1]), step_diag=snap.step_diag[j * record_every:j1 * record_every])
            self._timed(record, (self._arrays, self._work, self.params, self._inputs, record_every, self._diag, part,
                                 self._stats), (j1 - j) * record_every)
            bar.update((j1 - j) * record_every)
            j = j1

    def _run_reeling(self, snap: Snapshots, length: np.ndarray, record_every: int, speed: float, every_step: bool,
                     bar) -> None:
        """:meth:`run`'s snapshots 1.. with the winch: :meth:`_reel` between them."""
        out = self._diag.out
        for j in range(1, snap.r.shape[0]):
            if every_step:
                for i in range((j - 1) * record_every, j * record_every):
                    self._reel(1, speed)
                    self._update_diag()
                    row = snap.step_diag[i]
                    for name in STEP_DIAG.names:
                        row[STEP_DIAG.scalar(name)] = out[DIAG.scalar(name)]
            else:
                self._reel(record_every, speed)
            self._snapshot(snap, j)
            length[j] = self.winch.length
            bar.update(record_every)

    def _snapshot(self, snap: Snapshots, j: int) -> None:
        """Row ``j`` of ``snap`` from the current state."""
        self._update_diag()
        a, d = self._arrays, self._diag
        snap.r[j], snap.R[j], snap.omega[j], snap.v[j] = a.r, a.R, d.omega, d.V[-1]
        snap.diag[j], snap.strain[j], snap.acc[j] = d.out, d.strain, a.acc

    # -- diagnostics ------------------------------------------------------------------------
    def _update_diag(self) -> float:
        """Diagnostics of the state into the scratch; returns the energy (with the winch moving,
        the Hamiltonian of docs/physics.md, "The winch")."""
        if self.winch.idle:
            diagnostics_kernel(self._arrays, self.params, self._diag)
            return float(self._diag.out[DIAG.scalar("energy")])
        return self.winch.energy(self.buffers)

    def diagnostics(self) -> dict:
        """Diagnostics of the current state from the discrete momenta (SI units).

        Scalars: time, energy, kinetic_string, kinetic_body, kinetic_pivot, potential_gravity,
        potential_elastic, pi3, orthogonality, stretched_length; the input balances since the
        last :meth:`reset_balances`: work, dissipation (the energy the string's dampers took, >= 0),
        energy_balance_residual (E - E0 - W + D),
        angular_impulse_z, pi3_balance_residual (pi3 - pi3_0 - angular impulse); the winch's
        unstretched_length [m], reel_speed [m/s] and winch_work [J], which joins the energy
        balance (E - E0 - W - W_winch; E is the Hamiltonian while the winch reels).
        Vectors (3,): attach_position, attach_velocity, pivot_position, omega (body frame),
        linear_momentum, gravity_impulse, pivot_impulse, external_impulse (wind and pushes: an
        environment's), momentum_balance_residual (P - P0 - impulses; with a fixed pivot it is
        the pivot's reaction impulse);
        strain_energy (N,) per element.
        """
        self._update_diag()
        a, d = self._arrays, self._diag
        out = {"time": self.time}
        out.update({name: float(d.out[DIAG.scalar(name)]) for name in DIAG.names if name != "linear_momentum"})
        out["work"] = float(a.acc[BALANCE.scalar("work")])
        out["unstretched_length"], out["reel_speed"] = self.winch.length, self.winch.reel_speed
        out["winch_work"] = float(a.acc[BALANCE.scalar("winch_work")])
        out["dissipation"] = float(a.acc[BALANCE.scalar("dissipation")])
        out["energy_balance_residual"] = out["energy"] - self._E0 - out["work"] - out["winch_work"] + out["dissipation"]
        out["angular_impulse_z"] = float(a.acc[BALANCE.scalar("angular_impulse_z")])
        out["pi3_balance_residual"] = out["pi3"] - self._pi3_0 - out["angular_impulse_z"]
        out["attach_position"] = a.r[-1].copy()
        out["attach_velocity"] = d.V[-1].copy()
        out["pivot_position"] = a.r[0].copy()
        out["omega"] = d.omega.copy()
        out["linear_momentum"] = d.out[DIAG["linear_momentum"]].copy()
        out["gravity_impulse"] = a.acc[BALANCE["gravity_impulse"]].copy()
        out["pivot_impulse"] = a.acc[BALANCE["pivot_impulse"]].copy()
        out["external_impulse"] = a.acc[BALANCE["external_impulse"]].copy()
        out["momentum_balance_residual"] = (out["linear_momentum"] - self._P0 - out["gravity_impulse"]
                                            - out["pivot_impulse"] - out["external_impulse"])
        out["strain_energy"] = d.strain.copy()
        return out
