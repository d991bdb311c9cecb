"""The snapshots of a simulator's run (:meth:`esp_gym.physics.simulator.Simulator.run`)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from ..kernels.layout import BALANCE, DIAG, STEP_DIAG, Snapshots


@dataclass
class Trajectory:
    """Snapshots of a run every ``record_every`` steps (K of them, t = 0 included).

    Units: t [s]; nodes (K, N+1, 3) [m]; R (K, 3, 3); omega (K, 3) body frame [rad/s];
    attach_velocity (K, 3) [m/s]; energies and work [J]; pi3 and angular impulse [kg m^2/s];
    linear momentum and impulses (K, 3) [kg m/s]; strain_energy (K, N) [J]; the winch's
    unstretched_length (K,) [m] and winch_work (K,) [J]; the dissipation D (K,) [J] the string's
    dampers took. The balances (work, impulses, dissipation, residuals) count from the simulator's
    last balance reset; energy_balance_residual is E - E0 - W - W_winch + D, E the Hamiltonian while
    the winch reels (docs/physics.md, "The winch").
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
    unstretched_length: Optional[np.ndarray] = None
    winch_work: Optional[np.ndarray] = None
    dissipation: Optional[np.ndarray] = None
    t_every_step: Optional[np.ndarray] = None
    energy_every_step: Optional[np.ndarray] = None
    pi3_every_step: Optional[np.ndarray] = None
    orthogonality_every_step: Optional[np.ndarray] = None
    steps: int = 0
    newton_iterations: int = 0
    wall_time_s: float = 0.0
    extra: dict = field(default_factory=dict)

    @classmethod
    def from_snapshots(cls, snap: Snapshots, t: np.ndarray, unstretched_length: np.ndarray, energy0: float,
                       pi3_0: float, steps: int, newton_iterations: int, wall_time_s: float,
                       t_every_step: Optional[np.ndarray] = None) -> "Trajectory":
        """The trajectory of a run's :data:`~esp_gym.kernels.layout.Snapshots` (rows at times
        ``t`` [s]), its balances against the energy ``energy0`` [J] and ``pi3_0`` [kg m^2/s] at
        the last balance reset; ``t_every_step`` (when given) with ``snap.step_diag``."""
        cols = {name: snap.diag[:, DIAG.scalar(name)].copy() for name in DIAG.names if name != "linear_momentum"}
        acc = {name: snap.acc[:, BALANCE.scalar(name) if size == 1 else BALANCE[name]].copy()
               for name, size in BALANCE.fields}
        traj = cls(
            t=t, nodes=snap.r, R=snap.R, omega=snap.omega, attach_velocity=snap.v, strain_energy=snap.strain,
            linear_momentum=snap.diag[:, DIAG["linear_momentum"]].copy(), work=acc["work"],
            angular_impulse_z=acc["angular_impulse_z"],
            energy_balance_residual=cols["energy"] - energy0 - acc["work"] - acc["winch_work"] + acc["dissipation"],
            pi3_balance_residual=cols["pi3"] - pi3_0 - acc["angular_impulse_z"],
            gravity_impulse=acc["gravity_impulse"], pivot_impulse=acc["pivot_impulse"],
            unstretched_length=unstretched_length, winch_work=acc["winch_work"], dissipation=acc["dissipation"],
            steps=steps, newton_iterations=newton_iterations, wall_time_s=wall_time_s, **cols)
        if t_every_step is not None:
            traj.t_every_step = t_every_step
            traj.energy_every_step = snap.step_diag[:, STEP_DIAG.scalar("energy")].copy()
            traj.pi3_every_step = snap.step_diag[:, STEP_DIAG.scalar("pi3")].copy()
            traj.orthogonality_every_step = snap.step_diag[:, STEP_DIAG.scalar("orthogonality")].copy()
        return traj

    def arrays(self) -> dict:
        """The array fields (those that are set), e.g. for ``np.savez``."""
        return {k: v for k, v in dataclasses.asdict(self).items() if isinstance(v, np.ndarray)}

    def save(self, path: str | Path) -> None:
        np.savez_compressed(path, **self.arrays())
