"""The snapshots of a simulator's run (:meth:`esp_gym.model.Simulator.run`)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np


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
