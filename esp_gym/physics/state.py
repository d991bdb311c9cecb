"""The discrete state of the elastic string pendulum and the constants of a scene: what the
stepper needs before its first step (docs/physics.md).

Arrays follow one layout everywhere: node positions ``r`` and momenta ``p`` are ``(N+1, 3)``
(row 0 the pivot, row N the attachment node), ``R`` (3, 3) maps body to spatial frame, ``Pi`` is
the body's conjugate momentum (body frame, ``J Omega + M rho_c x R^T v_attach``) [kg m^2/s].
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..kernels.layout import LGVIParams
from ..kernels.step.string import tridiag_factor
from ..scene.params import Scene
from ..scene.stability import hat


@dataclass
class State:
    """A discrete state ``(q_k, p_k)`` at step ``step``; arrays are copies owned by the caller.

    ``remainders`` holds the compensated-summation remainders of (r, p, R, Pi) and the energy the
    explicit string's slack switches still owe per element (``owed``, kernels/step/switch.py):
    restoring them makes save/restore bit-exact; ``None`` (e.g. after editing the momenta)
    restarts them at 0.
    ``winch``: the unstretched length [m] and the reel speed the momenta were made with [m/s]
    (esp_gym/physics/winch.py); ``None`` is the scene's length at rest (a winch that never moved: such a
    state fits any scene, as before there were winches).
    """

    r: np.ndarray
    p: np.ndarray
    R: np.ndarray
    Pi: np.ndarray
    step: int = 0
    remainders: Optional[tuple] = None
    winch: Optional[tuple] = None

    def copy(self) -> "State":
        rem = None if self.remainders is None else tuple(a.copy() for a in self.remainders)
        return State(self.r.copy(), self.p.copy(), self.R.copy(), self.Pi.copy(), self.step, rem, self.winch)


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


def attachment_column(diag, off: float, cp, first: int) -> np.ndarray:
    """``w = M_tot^-1 e_{N+1}``, the attachment node's column of the inverse mass matrix (the
    Schur complement of kernels/step/lgvi.py), in O(N) from the Thomas factors ``cp`` of
    :func:`~esp_gym.kernels.step.string.tridiag_factor`. Rows before ``first`` (a fixed pivot) are 0.

    The forward sweep of e_{N+1} leaves it unchanged until the last row, so only the back
    substitution remains: ``w_N = 1/u_N``, ``w_a = -(off w_{a+1}) / u_a``, with the elimination
    pivots ``u_a = diag_a - off cp_{a-1}``. Evaluated in this order it gives the bits of the
    dense LU solve it replaces (which cost O(N^3) time and O(N^2) memory: 23 s at N = 8,000,
    74.5 GiB asked for at N = 100,000); tests/test_simulator.py checks both."""
    n = diag.shape[0] - 1
    pivots = np.zeros(n + 1)
    pivots[first] = diag[first]
    pivots[first + 1:] = diag[first + 1:] - off * cp[first:n]
    w = np.zeros(n + 1)
    w[n] = 1.0 / pivots[n]
    for a in range(n - 1, first - 1, -1):
        w[a] = -(off * w[a + 1]) / pivots[a]
    return w


#: Bytes a :class:`~esp_gym.physics.simulator.Simulator` holds per string node, an upper bound (state, remainders,
#: forces, scratch, checkpoint, diagnostics, constants: about 66 floats, and 14 more once the winch
#: has reeled; tests/test_arguments.py measures it).
BYTES_PER_NODE = 8 * 86
#: ... and a damped string's damper (its velocities, increments, directions, tensions, states and
#: eliminated blocks: esp_gym/physics/arrays.py ``work_arrays``) 20 floats more.
DAMPER_BYTES_PER_NODE = 8 * 20


def check_memory(elements: int, num_envs: Optional[int] = None, damped: bool = False) -> None:
    """Raise MemoryError, before anything is allocated, if a simulator of a string with
    ``elements`` elements (and a batch of ``num_envs`` environments of it; ``damped``: with the
    string's damper) would not fit in the memory available now."""
    per_node = BYTES_PER_NODE + (DAMPER_BYTES_PER_NODE if damped else 0)
    needed = per_node * (int(elements) + 1) * (1 + int(num_envs or 0))
    available = available_memory()
    if available is not None and needed > available:
        many = f"num_envs = {num_envs} environments with " if num_envs else ""
        raise MemoryError(f"string.elements = {elements}: {many}a string this long needs about "
                          f"{needed / 2**30:.1f} GiB, and {available / 2**30:.1f} GiB of memory is available")


def available_memory():
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``), or None where
    unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def build_params(scene: Scene) -> LGVIParams:
    """Scene -> the flat constants of the compiled stepper (see kernels/step/lgvi.py)."""
    n, m = scene.string.elements, scene.string.m
    M = scene.body.mass
    rho = np.array(scene.body.rho_c, dtype=float)
    J = scene.body.J
    J = 0.5 * (J + J.T)
    Jd = 0.5 * np.trace(J) * np.eye(3) - J
    diag, off, _ = mass_matrix(scene)
    first = 0 if scene.pivot.is_free else 1
    inv, cp = tridiag_factor(diag, off)
    w = attachment_column(diag, off, cp, first)
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
        compensated=bool(scene.solver.compensated), mdiag=diag,
        settle=scene.string.law == "slack" and scene.solver.slack_switch == "settled",
        gradient=scene.solver.implicit_form == "energy_momentum",
        damping=float(scene.string.damping),
        turn_mass=M * M * hat(rho) @ np.linalg.solve(J, hat(rho).T),
    )


def legendre_momenta(scene: Scene, r: np.ndarray, v: np.ndarray, R: np.ndarray, Omega: np.ndarray):
    """Continuous Legendre transform of the finite-element Lagrangian: velocities -> momenta.

    p = M_str v + body terms at the attachment node (+ M_p v_1 at a free pivot),
    Pi = J Omega + M rho_c x (R^T v_attach). Used to start the integrator
    (docs/physics.md, "Initialisation").
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


class StepClock:
    """A simulator's clock: the steps ``_step`` taken since its state was set, of ``h`` [s] each."""

    @property
    def step_count(self) -> int:
        return self._step

    @property
    def time(self) -> float:
        """Simulated time k*h [s]."""
        return self._step * self.h


def total_weight(scene: Scene) -> float:
    """The weight of pivot, string and load [N]: the hover force's size."""
    return scene.gravity * (scene.body.mass + (scene.pivot.mass or 0.0)
                            + scene.string.length * scene.string.mass_per_length)
