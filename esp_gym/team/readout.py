"""What a team's state reads out (docs/physics.md, "Diagnostics of a team"): the inverse of its
Legendre transform (the nodes' and the body's velocities from the momenta), each string's nodes and
strain energy, and the energy, momenta and balances. :class:`TeamReadout` is the read-out half of
:class:`~esp_gym.team.simulator.TeamSimulator` (the stepping half is there).
"""
from __future__ import annotations

import numpy as np

from ..kernels.layout import BALANCE
from ..kernels.team.readout import TB_ENERGY_ORIGIN, TB_LOAD_WORK, TB_WINCH_JUMPS, TEAM_READ, team_read
from ..physics.state import cross3
from .assembly import string_mass
from .velocities import team_velocities


class TeamReadout:
    """The read-outs of a :class:`~esp_gym.team.simulator.TeamSimulator`'s state. The inverse
    Legendre transform is kept for the state it was taken at (the state changes only by the
    simulator's ``step`` and ``set_state``, which count ``_changes``, and the reel speeds): the
    watchdog's diagnostics and an environment's observation of one state invert it once. With the
    winches at rest at the scenes' lengths, one compiled call (kernels/team/readout.py
    ``team_read``, into ``_read``) takes the velocities with the step's own factors, the energy
    terms and what :meth:`observed` gives; a reeled team's are taken here, the flow's momenta
    removed, by LAPACK's tridiagonal solver (esp_gym/team/velocities.py)."""

    _kinematics_key = None
    _changes = 0  # the simulator's changes of state (its step and set_state)
    _compiled_read = False  # the kept kinematics came with a compiled read-out (``_read`` holds it)
    _read_changes = -1  # the count of changes at which the compiled read-out ``_read`` was taken
    #: False: every read-out in Python, the compiled one's reference (tests/test_team_switch.py).
    compiled_reads = True

    def velocities(self, reel_speeds=None):
        """The inverse of the continuous Legendre transform (docs/physics.md, "Diagnostics of a
        team"; while the winches reel, of p = M(l) v + c C^T r at each string's length and reel
        speed, ``reel_speeds`` (K,) instead of the state's if given): ``(string 0's node
        velocities (N+1, 3), the others' (rows, 3), Omega (3,))`` [m/s, rad/s]."""
        v0, vo, Omega, _, _, _ = self._kinematics(reel_speeds)
        return v0, vo, Omega

    def _kinematics(self, reel_speeds=None):
        """:meth:`velocities` with the momenta they invert: ``(v0, v_others, Omega, string 0's
        momenta less the flow's, the others' (their ends' rows 0), Pi less the ends' flow)``,
        copies of those kept for the state and speeds they were taken at (the key: the count of
        the simulator's changes of state and the speeds' bits)."""
        return tuple(a.copy() for a in self._taken(reel_speeds))

    def _taken(self, reel_speeds=None) -> tuple:
        """:meth:`_kinematics`' arrays themselves, taken if the state or the speeds changed."""
        speeds = np.asarray(self.winches.reel_speeds if reel_speeds is None else reel_speeds, dtype=float)
        key = (self._changes, speeds.tobytes(), self.compiled_reads)
        if key != self._kinematics_key:
            self._kinematics_key, self._kinematics_kept = key, self._invert(speeds)
        return self._kinematics_kept

    def _invert(self, speeds):
        """:meth:`_kinematics` taken anew at the reel ``speeds``."""
        S, A, T = self._S, self._A, self.params
        self._compiled_read = self.compiled_reads and self.winches.idle and not np.any(speeds)
        D = self._read
        if self._compiled_read:
            if self._read_changes != self._changes:  # else the control step's read is of this state
                D.length[...] = self.winches.scene_lengths
                team_read(S, self._P, T, A, D)
                self._read_changes = self._changes
            return D.V0.copy(), D.Vo.copy(), D.out[TEAM_READ["omega"]].copy(), S.p.copy(), A.p.copy(), S.Pi.copy()
        R = S.R
        p0, po, Pi = S.p.copy(), A.p.copy(), S.Pi.copy()
        if np.any(speeds != 0.0):  # the momenta of the material's flow, c C^T r, are not the nodes'
            q0, qo = self.winches.flow_momenta(S.r, A.r, speeds)
            p0 -= q0
            for j in range(len(self.team.strings)):
                e = T.start[j + 1] - 1
                p0[-1] -= qo[e]
                Pi -= cross3(T.rho[j], R.T @ qo[e])
                qo[e] = 0.0
            po -= qo
        members = []
        for k, (_, string, pivot) in enumerate(self._members()):
            diag, off, _ = string_mass(string, pivot)
            if k == 0:
                members.append((diag, off, 0 if pivot.is_free else 1, p0, np.zeros(3)))
            else:
                a, b = T.start[k - 1], T.start[k]
                members.append((diag, off, 0 if pivot.is_free else 1, po[a:b], T.rho[k - 1]))
        (v0, *rest), Omega = team_velocities(members, self._P.M, self._P.rho, self._P.J, R, p0[-1], Pi)
        vo = np.concatenate(rest) if rest else np.zeros((0, 3))
        self._fill_read(v0, vo, Omega)
        return v0, vo, Omega, p0, po, Pi

    def _fill_read(self, v0, vo, Omega) -> None:
        """The read-out's observed part (kernels/team/readout.py ``TeamReadArrays``: each pivot, its
        velocity, its string's pull and stretch, its length, R, the load's centre, its velocity and
        Omega) of the state whose velocities are ``v0``, ``vo`` and ``Omega``, taken in Python."""
        S, T, D = self._S, self.params, self._read
        self._read_changes = -1  # ``_read`` no longer holds a compiled read-out
        members = self._members()
        for k, (r, string, _) in enumerate(members):
            x = r[1] - r[0]
            length = np.linalg.norm(x)
            D.tension[k] = string.kappa * max(length - string.u, 0.0) * x / length
            D.stretch[k] = np.linalg.norm(np.diff(r, axis=0), axis=1).sum() / string.length
            D.length[k] = string.length
            row = 0 if k == 0 else int(T.start[k - 1])
            D.pivot[k] = r[0]
            D.pivot_velocity[k] = v0[0] if k == 0 else vo[row]
        R = S.R
        D.R[...] = R
        D.out[TEAM_READ["omega"]] = Omega
        D.out[TEAM_READ["load"]] = S.r[-1] + R @ self._P.rho
        D.out[TEAM_READ["load_velocity"]] = v0[-1] + R @ cross3(Omega, self._P.rho)

    def _members(self) -> list:
        """Each string's ``(nodes (N_k+1, 3) [m], its string section at its current length, its pivot
        section)``, string 0 first."""
        S, A, T = self._S, self._A, self.params
        strings = self.winches.strings_at_length()
        pivots = self.team.pivots()
        return [(S.r, strings[0], pivots[0])] + [
            (A.r[T.start[j]:T.start[j + 1]], strings[j + 1], pivots[j + 1]) for j in range(len(self.team.strings))]

    @staticmethod
    def _stretch(r: np.ndarray, string) -> np.ndarray:
        """Each element's stretch x = |r_{i+1} - r_i| - u [m] (clipped at 0 for a slack law): its
        strain energy is kappa x^2 / 2."""
        x = np.linalg.norm(np.diff(r, axis=0), axis=1) - string.u
        return np.maximum(x, 0.0) if string.law == "slack" else x

    def strings(self) -> list:
        """Each string's ``(nodes (N_k+1, 3) [m], each element's strain energy (N_k,) [J])``, string 0
        first: what a frame draws (esp_gym/viz/render.py ``render_team``)."""
        return [(r.copy(), 0.5 * string.kappa * self._stretch(r, string) ** 2) for r, string, _ in self._members()]

    def read(self):
        """The read-out of the current state (kernels/team/readout.py ``TeamReadArrays``; its energy
        terms only where it was compiled, :meth:`diagnostics` has them always): the arrays
        themselves, valid until the state changes."""
        if not (self.compiled_reads and self._read_changes == self._changes):
            self._taken()
        return self._read

    def observed(self) -> dict:
        """What an environment observes of the state (spatial, SI): each string's unstretched
        ``lengths`` (K,) [m], its pivot's ``pivot`` and ``pivot_velocity`` (K, 3), the pull of its
        first element on its pivot ``tension`` (K, 3) [N] (kappa max(|x| - u, 0) x / |x|, x = r_1 -
        r_0) and its stretched over its unstretched length ``stretch`` (K,); the load's centre of
        mass ``load`` and its ``load_velocity`` (3,); the body's ``R`` (3, 3) and ``Omega`` (3,,
        body frame) [rad/s]. Copies."""
        D = self.read()
        return dict(lengths=self.winches.lengths, R=D.R.copy(), Omega=D.out[TEAM_READ["omega"]].copy(),
                    pivot=D.pivot.copy(), pivot_velocity=D.pivot_velocity.copy(), tension=D.tension.copy(),
                    stretch=D.stretch.copy(), load=D.out[TEAM_READ["load"]].copy(),
                    load_velocity=D.out[TEAM_READ["load_velocity"]].copy())

    def _diagnostics(self, reel_speeds=None) -> dict:
        """The state's energy terms, momenta and pi3; while the winches reel, the energy is the
        Hamiltonian H = T2 - T0 + V (docs/physics.md, "The winch"), at ``reel_speeds`` if given."""
        S, A = self._S, self._A
        P = self._P
        speeds = self.winches.reel_speeds if reel_speeds is None else reel_speeds
        v0, vo, Omega, p0, po, Pi = self._kinematics(speeds)
        if self._compiled_read:
            kinetic, elastic, gravity, pi3 = self._read_energies()
            momentum = self._read.out[TEAM_READ["linear_momentum"]].copy()
        else:
            kinetic = 0.5 * (np.sum(p0 * v0) + np.sum(po * vo) + float(Pi @ Omega))
            g = P.g
            elastic = gravity = 0.0
            for r, string, pivot in self._members():
                x = self._stretch(r, string)
                elastic += 0.5 * string.kappa * float(x @ x)
                w = np.full(r.shape[0], string.m)
                w[0] = w[-1] = 0.5 * string.m
                w[0] += pivot.mass or 0.0
                gravity -= g * float(w @ r[:, 2])
            gravity -= g * P.M * float((S.r[-1] + S.R @ P.rho)[2])
            momentum = S.p.sum(0) + A.p.sum(0)
            pi3 = float(np.sum(S.r[:, 0] * S.p[:, 1] - S.r[:, 1] * S.p[:, 0]) +
                        np.sum(A.r[:, 0] * A.p[:, 1] - A.r[:, 1] * A.p[:, 0]) + (S.R @ S.Pi)[2])
        out = dict(orthogonality=float(np.linalg.norm(S.R.T @ S.R - np.eye(3))))
        if self.fleet:  # each drone's rotation
            out.update(self.fleet.diagnostics())
            kinetic += float(out["kinetic_drones"].sum())
            pi3 += float(out["pi3_drones"].sum())
        convective = self.winches.convective_energy(S.r, A.r, speeds)
        out.update(kinetic=float(kinetic), potential_elastic=elastic, potential_gravity=gravity,
                   energy=float(kinetic) - convective + elastic + gravity, linear_momentum=momentum, pi3=pi3)
        return out

    def energy_balance(self) -> tuple:
        """``(E - E0 - W - W_winch, W + W_winch)`` [J]: :meth:`diagnostics`' ``energy_balance_residual``
        and ``work`` + ``winch_work``, what the energy watchdog weighs, taken from the compiled
        read-out alone where there is one."""
        self._taken()
        if not self._compiled_read:
            d = self.diagnostics()
            return d["energy_balance_residual"], d["work"] + d["winch_work"]
        kinetic, elastic, gravity, _ = self._read_energies()
        if self.fleet:
            kinetic += float(self.fleet.kinetic_energies().sum())
        energy = kinetic + elastic + gravity
        work, winch_work = self._work()
        return energy - float(self._balance[TB_ENERGY_ORIGIN]) - work - winch_work, work + winch_work

    def _read_energies(self) -> tuple:
        """The compiled read-out's ``(kinetic (not the drones' rotations), elastic, gravity [J], pi3
        [kg m^2/s])``."""
        read = self._read.out
        return tuple(float(read[TEAM_READ.scalar(name)]) for name in ("kinetic", "potential_elastic",
                                                                      "potential_gravity", "pi3"))

    def _work(self) -> tuple:
        """The inputs' and the wind's work and the winches' since the last reset [J]."""
        acc = self._S.acc  # (the load force's work is summed here, per call of step)
        return (float(acc[BALANCE["work"]][0]) + float(self._balance[TB_LOAD_WORK]),
                float(acc[BALANCE["winch_work"]][0]) + float(self._balance[TB_WINCH_JUMPS]))

    def diagnostics(self) -> dict:
        """Energy (kinetic, elastic, gravity) [J], linear momentum [kg m/s], pi3 (about the e3
        axis through the origin) [kg m^2/s], ||R^T R - I||; with drones, the energy and pi3 with
        their rotations, and each drone's (:meth:`Fleet.diagnostics
        <esp_gym.team.fleet.Fleet.diagnostics>`), the work and angular impulse with the rotors'
        thrust and torque; and the input
        balances since the last reset with their residuals: the winches' ``unstretched_lengths``
        (K,) [m], ``reel_speeds`` (K,) [m/s] and ``winch_work`` [J]; ``energy_balance_residual`` =
        E - E0 - work - winch_work (E the Hamiltonian while the winches reel), ``pi3_balance_residual`` = pi3 - pi3_0 - the angular impulse about e3 (exact with free
        pivots only), ``momentum_balance_residual`` = P - P0 - the gravity and pivot impulses
        (with free pivots only: a fixed pivot's reaction is not an input)."""
        d = self._diagnostics()
        acc = self._S.acc
        work, winch_work = self._work()
        impulse = acc[BALANCE["gravity_impulse"]] + acc[BALANCE["pivot_impulse"]] + acc[BALANCE["external_impulse"]]
        origin = float(self._balance[TB_ENERGY_ORIGIN])
        d.update(work=work, angular_impulse_z=float(acc[BALANCE["angular_impulse_z"]][0]),
                 unstretched_lengths=self.winches.lengths, reel_speeds=self.winches.reel_speeds,
                 winch_work=winch_work, energy_balance_residual=d["energy"] - origin - work - winch_work,
                 pi3_balance_residual=d["pi3"] - self._pi3_0 - float(acc[BALANCE["angular_impulse_z"]][0]),
                 momentum_balance_residual=d["linear_momentum"] - self._P0 - impulse)
        return d
