"""The Python face of a team's physics: :class:`TeamSimulator` steps a :class:`TeamScene` with the
compiled team step (esp_gym/kernels/team/step.py) and reports its diagnostics and balances
(docs/physics.md, "A team: several strings on one body").
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..kernels.layout import INPUTS, LOOP_REPORT_SIZE, R_NEWTON_TOTAL, R_STATUS, R_STEPS
from ..kernels.status import ENERGY_BALANCE, OK
from ..kernels.team.env import TeamStructs
from ..kernels.team.loops import team_advance, team_drone_advance, team_winch_advance
from ..kernels.team.readout import TB_ENERGY_ORIGIN, TB_LOAD_WORK, TB_WINCH_JUMPS, TEAM_BALANCE
from ..kernels.team.step import team_forces
from ..kernels.team.winch import team_winch_forces
from ..physics.arrays import copy_into, plain_structs, team_arrays, team_read_arrays
from ..physics.drone import DroneState
from ..physics.simulator import SimulationError, Simulator
from ..physics.state import State, StepClock, cross3, legendre_momenta
from ..physics.watchdog import WATCH_EVERY, check_team_balance, team_energy_scale
from .assembly import build_team
from .fleet import Fleet
from .readout import TeamReadout
from .scene import TeamScene
from .winches import TeamWinches


@dataclass
class TeamState:
    """A team's discrete state: ``lead`` string 0 and the body (a single string's
    :class:`~esp_gym.physics.state.State`, whose last row of p and whose Pi hold the body's momenta with
    every string end's share), and the other strings' positions ``r`` and momenta ``p``, stacked by
    rows (each string's end last, its momentum row 0); ``drones``: each drone's
    :data:`~esp_gym.physics.drone.DroneState` in the order of :attr:`TeamSimulator.drone_pivots` (empty
    without drones); ``lengths`` (K,) each string's unstretched length [m] and ``reel_speeds`` (K,)
    the reel speeds its momenta were made with [m/s] (None: the scenes' lengths, at rest)."""

    lead: State
    r: np.ndarray
    p: np.ndarray
    drones: tuple = field(default_factory=tuple)
    lengths: Optional[np.ndarray] = None
    reel_speeds: Optional[np.ndarray] = None

    def copy(self) -> "TeamState":
        return TeamState(self.lead.copy(), self.r.copy(), self.p.copy(),
                         tuple(DroneState(*(a.copy() for a in d)) for d in self.drones),
                         None if self.lengths is None else self.lengths.copy(),
                         None if self.reel_speeds is None else self.reel_speeds.copy())


class TeamSimulator(TeamReadout, StepClock):
    """Steps a :class:`TeamScene` with the compiled team step.

    >>> sim = TeamSimulator(team)
    >>> sim.step(100, pivot_forces=np.zeros((team.size, 3)))
    >>> sim.diagnostics()["energy"]
    """

    def __init__(self, team: TeamScene):
        self.team = team
        self.h = team.scene.h
        #: string 0 and the body: a single string's arrays (its Simulator is not stepped itself)
        self._lead = Simulator(team.scene, specialise=False)
        buffers = self._lead.buffers
        self._S, self._W, self._P = buffers.state, buffers.work, buffers.params
        self.params, self._strings = build_team(team, self._P)
        rows = int(self.params.start[-1])
        self._A = team_arrays(rows, len(team.strings))
        self._inputs = np.zeros(INPUTS.size)
        self._stats = np.zeros(LOOP_REPORT_SIZE, dtype=np.int64)
        self._step = 0
        #: The team's drones (esp_gym/team/fleet.py), None without drones.
        self.fleet = Fleet(team, self.h) if any(p.is_drone for p in team.pivots()) else None
        #: The pivots that are drones (0: string 0's), in the order of the drones' arrays.
        self.drone_pivots = self.fleet.pivots if self.fleet else []
        #: Each string's winch (esp_gym/team/winches.py): :meth:`step`'s ``reel_speeds``.
        self.winches = TeamWinches(team, np.concatenate([[self._P.max_len2], self.params.max_len2]),
                                   self.params.start)
        self._read = team_read_arrays(team.scene.string.elements, rows, self.winches.scene_lengths)
        #: E0, the load force's work and the winches' jumps of H (kernels/team/readout.py TEAM_BALANCE)
        self._balance = np.zeros(TEAM_BALANCE.size)
        self._energy_scale = team_energy_scale(team)  # the watchdog's [J]
        self._unwatched = 0  # steps since the energy watchdog last looked
        #: The energy watchdog looks at the end of the call in which this many steps have passed
        #: since it last did (esp_gym/physics/watchdog.py; an environment's: 1, every control step).
        self.watch_every = WATCH_EVERY
        self.set_state(self.initial_state())

    # -- state ------------------------------------------------------------------------------
    def initial_state(self, velocity=None, rates=None) -> TeamState:
        """The scene's initial state: string 0 and the body as the lead scene's, every other
        string straight from its pivot to its attachment point, its nodes at rest but its pivot
        (``pivot.velocity``) and its end (moving with the body); momenta by the continuous
        Legendre transform, each end's row added to the body's. ``velocity``: string 0's
        attachment point's (spatial) [m/s], ``rates``: the body's Omega (body frame) [rad/s],
        instead of the scene's ``initial.attach_velocity`` and ``initial.Omega0``."""
        scene = self.team.scene
        x0 = scene.initial_nodes()
        v0 = scene.initial_velocities()
        if velocity is not None:
            v0[-1] = np.asarray(velocity, dtype=float)
        R = np.array(scene.initial.R0, dtype=float)
        Omega = np.array(scene.initial.Omega0 if rates is None else rates, dtype=float)
        p0, Pi = legendre_momenta(scene, x0, v0, R, Omega)
        lead = State(np.ascontiguousarray(x0), np.ascontiguousarray(p0), R, Pi, 0)
        pivots = np.array([s.pivot.position for s in self.team.strings], dtype=float).reshape(-1, 3)
        velocities = np.array([s.pivot.velocity for s in self.team.strings], dtype=float).reshape(-1, 3)
        state = self._with_others(lead, v0[-1], Omega, pivots, velocities, interpolate=False)
        state.drones = self.fleet.hovering() if self.fleet else ()
        return state

    def lifted_state(self, pivots, pivot_velocities, load, load_velocity, R, Omega) -> TeamState:
        """The state with every string straight from its pivot (K, 3) to its attachment point,
        its nodes evenly spaced and their velocities interpolated between the pivot's (K, 3) and
        the end's, the load's centre of mass at ``load`` moving at ``load_velocity`` (spatial)
        [m, m/s], turned by ``R`` at ``Omega`` (body frame) [rad/s]; momenta by the continuous
        Legendre transform (a reduced state lifted to a full one: agents/baselines/team/lqr.py)."""
        pivots = np.asarray(pivots, dtype=float)
        pivot_velocities = np.asarray(pivot_velocities, dtype=float)
        R = np.asarray(R, dtype=float)
        Omega = np.asarray(Omega, dtype=float)
        rho_c = np.asarray(self.team.scene.body.rho_c, dtype=float)
        x = np.asarray(load, dtype=float) - R @ rho_c
        v_x = np.asarray(load_velocity, dtype=float) - R @ cross3(Omega, rho_c)
        scene = self.team.scene
        t = np.linspace(0.0, 1.0, scene.string.elements + 1)[:, None]
        r0 = (1.0 - t) * pivots[0] + t * x
        v0 = (1.0 - t) * pivot_velocities[0] + t * v_x
        p0, Pi = legendre_momenta(scene, r0, v0, R, Omega)
        lead = State(np.ascontiguousarray(r0), np.ascontiguousarray(p0), R.copy(), Pi, 0)
        return self._with_others(lead, v_x, Omega, pivots[1:], pivot_velocities[1:], interpolate=True)

    def _with_others(self, lead: State, v_x, Omega, pivots, pivot_velocities, interpolate: bool) -> TeamState:
        """``lead`` with the other strings straight from ``pivots`` to their attachment points;
        their velocities the pivots' and the ends' (with the body), the nodes between at rest or
        (``interpolate``) interpolated; their ends' momenta added to the body's."""
        x, R = lead.r[-1], lead.R
        rows = int(self.params.start[-1])
        r, p = np.zeros((rows, 3)), np.zeros((rows, 3))
        for j, s in enumerate(self.team.strings):
            a, b = self.params.start[j], self.params.start[j + 1]
            rho = self.params.rho[j]
            t = np.linspace(0.0, 1.0, b - a)[:, None]
            r[a:b] = (1.0 - t) * pivots[j] + t * (x + R @ rho)
            end_velocity = v_x + R @ cross3(Omega, rho)
            if interpolate:
                v = (1.0 - t) * pivot_velocities[j] + t * end_velocity
            else:
                v = np.zeros((b - a, 3))
                v[0] = pivot_velocities[j]
                v[-1] = end_velocity
            diag, off, end_share, first = self._strings[j]
            q = np.zeros_like(v)
            q[:-1] += end_share * v[:-1] + off * v[1:]
            q[1:] += off * v[:-1] + end_share * v[1:]
            if first == 0:
                q[0] += s.pivot.mass * v[0]
            else:
                q[0] = 0.0
            p[a:b - 1] = q[:-1]
            lead.p[-1] += q[-1]
            lead.Pi += cross3(rho, R.T @ q[-1])
        return TeamState(lead, r, p)

    @property
    def state(self) -> TeamState:
        """A copy of the current state (without the summation remainders)."""
        S = self._S
        return TeamState(State(S.r.copy(), S.p.copy(), S.R.copy(), S.Pi.copy(), self._step), self._A.r.copy(),
                         self._A.p.copy(), self.fleet.states() if self.fleet else (), self.winches.lengths,
                         self.winches.reel_speeds)

    def set_state(self, state: TeamState, check: bool = True) -> None:
        """Replace the state (copied; remainders and balances restart at 0). The other strings'
        ends are placed on the body. Without ``state.drones`` the drones keep theirs; with them,
        each R_q a rotation to ROTATION_TOL, Pi_q (3,) [kg m^2/s] and its rotor speeds (4,) in
        [0, max_rotor_speed] [rad/s], its motor commands then those speeds. ``check`` False: a
        state its caller built for this team (:meth:`initial_state`: an environment's reset), its
        strings' shapes, finiteness and rotation taken as given."""
        if state.drones:
            if not self.fleet:
                raise ValueError(f"state.drones has {len(state.drones)} drones, the team none")
            self.fleet.set_states(state.drones)
        A = self._A
        for name in ("r", "p") if check else ():
            given = np.asarray(getattr(state, name), dtype=float)
            if given.shape != getattr(A, name).shape:
                raise ValueError(f"state.{name} has shape {given.shape}, expected {getattr(A, name).shape}")
            if not np.all(np.isfinite(given)):
                raise ValueError(f"state.{name} is not finite")
        self._changes += 1
        self.winches.set(state.lengths, state.reel_speeds)
        self._lead.set_state(state.lead, check=check)
        A.r[...] = state.r
        A.p[...] = state.p
        x, R = self._S.r[-1], self._S.R
        for j in range(len(self.team.strings)):
            e = self.params.start[j + 1] - 1
            A.r[e] = x + R @ self.params.rho[j]
            A.p[e] = 0.0
        A.rc[...] = 0.0
        A.pc[...] = 0.0
        A.owed[...] = 0.0  # as the lead's remainders (its owed energies among them)
        self._step = int(state.lead.step)
        if self.winches.idle:
            team_forces(self._S, self._P, self.params, A)
        else:
            team_winch_forces(self._S, self._P, self.params, A, self.winches.arrays)
        self.reset_balances()

    def load_position(self) -> np.ndarray:
        """The load's centre of mass (spatial) [m]."""
        return self._S.r[-1] + self._S.R @ self._P.rho

    def reset_balances(self) -> None:
        """Start the input balances (work, impulses) afresh from the current state."""
        self._balance[...] = 0.0
        self._S.acc[...] = 0.0
        self._S.accc[...] = 0.0
        d = self._diagnostics()
        self._balance[TB_ENERGY_ORIGIN] = d["energy"]
        self._pi3_0, self._P0 = d["pi3"], d["linear_momentum"].copy()

    # -- stepping ---------------------------------------------------------------------------
    def _set_forces(self, pivot_forces) -> None:
        K = self.team.size
        u = np.zeros((K, 3)) if pivot_forces is None else np.asarray(pivot_forces, dtype=float)
        if u.shape != (K, 3):
            raise ValueError(f"pivot_forces must have shape ({K}, 3), one spatial force per string's pivot [N]; "
                             f"got {u.shape}")
        if not np.all(np.isfinite(u)):
            raise ValueError("pivot_forces must be finite")
        for k, pivot in enumerate(self.team.pivots()):
            if not pivot.is_free and np.any(u[k] != 0.0):
                raise ValueError(f"pivot_forces[{k}]: string {k}'s pivot is fixed and cannot be pushed")
            if pivot.is_drone and np.any(u[k] != 0.0):
                raise ValueError(f"pivot_forces[{k}]: string {k}'s pivot is a drone, flown by its rotors "
                                 "(step's rotor_commands, or thrust with torque or rates)")
        self._inputs[INPUTS["pivot_force"]] = u[0]
        self._inputs[INPUTS["pivot_force_end"]] = u[0]
        self._A.force[:, 0] = u[1:]
        self._A.force[:, 1] = u[1:]

    def step(self, n: int = 1, pivot_forces=None, load_force=None, rotor_commands=None, thrust=None, torque=None,
             rates=None, reel_speeds=None) -> None:
        """Advance ``n`` steps with each pivot's force (K, 3) held (spatial) [N]; fixed pivots'
        and drones' rows must be 0; ``load_force`` (3,) a force on the load's centre of mass
        (spatial) [N] held too (wind, a push: its impulse joins the balances' ``external_impulse``).
        The drones (in :attr:`drone_pivots`' order): ``rotor_commands`` (n_drones, 4) [rad/s]
        held; or ``thrust`` (n_drones,) [N] with ``torque`` (n_drones, 3) (body frame) [N m],
        made into held commands through A^-1 (clipped to each rotor's range); or ``thrust`` with
        ``rates`` (n_drones, 3) [rad/s], the rate controller setting the commands before every
        step (kernels/drone/quadrotor.py ``actuate``). None of them keeps the last call's (at first
        hover: :meth:`Fleet.shares <esp_gym.team.fleet.Fleet.shares>`). ``reel_speeds`` (K,)
        [m/s]: each string's winch reels it out (> 0) or in, held, within its ``winch`` section
        (None: at rest; docs/physics.md, "Winches on a team's strings"). Raises
        :class:`~esp_gym.errors.SimulationError` on failure (the state is then the last good one)."""
        n = int(n)
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        speeds = np.zeros(self.team.size) if reel_speeds is None else self.winches.check_speeds(reel_speeds)
        reeling = bool(np.any(speeds != 0.0)) or not self.winches.idle
        if reeling:
            if self.fleet:
                raise ValueError("reel_speeds: a team's drones do not reel yet (docs/physics.md, \"What a team does "
                                 "not do yet\")")
            self.winches.check_scene(self.h)
        self._set_forces(pivot_forces)
        drive = dict(rotor_commands=rotor_commands, thrust=thrust, torque=torque, rates=rates)
        if self.fleet:
            self.fleet.command(**drive)
        elif any(v is not None for v in drive.values()):
            given = next(k for k, v in drive.items() if v is not None)
            raise ValueError(f"{given}: the team has no drone (its pivots are points: use pivot_forces)")
        disturbed = load_force is not None
        if disturbed:
            F = np.asarray(load_force, dtype=float)
            if F.shape != (3,) or not np.all(np.isfinite(F)):
                raise ValueError(f"load_force must be 3 finite numbers [N], got {load_force!r}")
            self._W.ext[...] = 0.0
            self._W.ext[-1] = F
            before = self.load_position()
        if reeling:
            self._reel(n, speeds, disturbed)
        elif self.fleet is None:
            team_advance(self._S, self._W, self._P, self.params, self._A, self._inputs, n, self._stats, disturbed)
        else:
            team_drone_advance(self._S, self._W, self._P, self.params, self._A, self.fleet.arrays, self._inputs,
                               n, self._stats, disturbed, self.fleet.rates)
        self._changes += 1  # the read-outs kept are of the state before
        self._step += int(self._stats[R_STEPS])
        self._unwatched += int(self._stats[R_STEPS])
        if disturbed:  # a held force's work: F . the displacement of its point
            self._balance[TB_LOAD_WORK] += float(F @ (self.load_position() - before))
        status = int(self._stats[R_STATUS])
        if status != OK:
            raise SimulationError(status, self._step, self.time, int(self._stats[R_NEWTON_TOTAL]))
        if self._unwatched >= self.watch_every:  # the energy watchdog, as the single simulator's
            self._unwatched = 0
            check_team_balance(self.team, self.energy_balance, self._step, self.time, self.winches.lengths,
                               self._energy_scale)

    # -- the environment's compiled control step --------------------------------------------
    def structs(self) -> TeamStructs:
        """The structs a compiled control step (kernels/team/env.py) advances and reads
        (kernels/team/env.py ``TeamStructs``; the drones None without drones). Only a team whose
        strings keep their scenes' lengths steps there (ValueError for one with winches that have
        reeled, or with :attr:`compiled_reads` off); after each call, :meth:`count_control_step`."""
        if not (self.winches.idle and self.compiled_reads):
            raise ValueError("a compiled control step needs the winches at rest at the scenes' lengths and "
                             "compiled_reads on")
        self._read.length[...] = self.winches.scene_lengths
        drones = None if self.fleet is None else self.fleet.arrays
        return TeamStructs(self._S, self._W, self._P, self.params, self._A, drones, self._read, self._inputs,
                           self._stats, self._balance)

    def compiled(self) -> TeamStructs:
        """:meth:`structs` as the entry points take them: each struct a plain tuple."""
        return plain_structs(self.structs())

    def use_structs(self, rows: TeamStructs) -> None:
        """Keep the live arrays in ``rows`` (a batch's row views, esp_gym/team/batch.py: the state,
        work, the other strings', the drones', the read-out, the inputs, the loop's report and the
        balance) from now on, the current values copied into them. The constants (``rows.params``,
        ``rows.team``) stay the simulator's: the batch copies them."""
        self._lead.use_buffers(rows.state, rows.work)
        self._S, self._W = rows.state, rows.work
        copy_into(self._A, rows.arrays)
        copy_into(self._read, rows.read)
        self._A, self._read = rows.arrays, rows.read
        if self.fleet is not None:
            self.fleet.use_arrays(rows.drones)
        for name in ("inputs", "stats", "balance"):
            getattr(rows, name)[...] = getattr(self, "_" + name)
        self._inputs, self._stats, self._balance = rows.inputs, rows.stats, rows.balance

    def count_control_step(self) -> None:
        """Count a compiled control step's physics steps (its ``stats``) and keep its read-out as
        the new state's (the watchdog looked at it)."""
        steps = int(self._stats[R_STEPS])
        self._step += steps
        self._changes += 1
        self._read_changes = self._changes
        self._unwatched = 0

    def failure(self, code: int, residual: float, work: float) -> SimulationError:
        """The :class:`~esp_gym.errors.SimulationError` :meth:`step` would have raised for a
        compiled control step's termination ``code`` (a physics failure, or ENERGY_BALANCE with its
        balance's ``residual`` and ``work`` [J])."""
        if code != ENERGY_BALANCE:
            return SimulationError(code, self._step, self.time, int(self._stats[R_NEWTON_TOTAL]))
        try:
            check_team_balance(self.team, lambda: (residual, work), self._step, self.time, self.winches.lengths,
                               self._energy_scale)
        except SimulationError as error:
            return error
        raise AssertionError(f"the compiled watchdog broke a balance ({residual!r} J, work {work!r} J) that "
                             "check_team_balance accepts")

    def watchdog_constants(self) -> tuple:
        """The energy watchdog's ``(fraction f, or -1 without it; energy scale [J])``."""
        fraction = self.team.scene.solver.energy_watchdog
        return (-1.0 if fraction is None else float(fraction)), self._energy_scale

    # -- diagnostics ------------------------------------------------------------------------
    def _reel(self, n: int, speeds: np.ndarray, disturbed: bool) -> None:
        """:meth:`step`'s ``n`` steps while the winches reel at ``speeds`` (kernels/team/loops.py
        ``team_winch_advance``); a step that would pass an end of a winch's range is cut to end on
        it at its own speed, that string then stops, each change of the reel speeds with H's jump
        at fixed (q, p). On return ``_stats`` counts every step taken (``_step`` not yet moved)."""
        winches = self.winches
        taken = 0
        self._change_speeds(winches.held(speeds))
        while taken < n:
            cut = winches.cut_speeds(self.h)
            steps = n - taken
            if not np.array_equal(cut, winches.reel_speeds):  # the next step ends on a range's end
                self._change_speeds(cut)
                steps = 1
            team_winch_advance(self._S, self._W, self._P, self.params, self._A, winches.arrays, self._inputs, steps,
                               self._stats, disturbed)
            taken += int(self._stats[R_STEPS])
            if int(self._stats[R_STATUS]) != OK:
                break
            self._change_speeds(winches.held(speeds))
        self._stats[R_STEPS] = taken

    def _change_speeds(self, speeds: np.ndarray) -> None:
        """Set the state's reel speeds, adding H's jump at fixed (q, p) to the winch work."""
        if np.array_equal(speeds, self.winches.reel_speeds):
            return
        self._changes += 1  # a step may have moved the state since the last read-out
        before = self._diagnostics()["energy"]
        self.winches.use_speeds(speeds)
        self._balance[TB_WINCH_JUMPS] += self._diagnostics()["energy"] - before
