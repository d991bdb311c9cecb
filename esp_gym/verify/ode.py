"""The finite-element model of the elastic string pendulum as a first-order ODE ``y' = f(t, y)``.

This is the *same* spatial model the LGVI discretises in time (consistent mass, the elastic law
of ``kernels/step/string.py``, the body of the paper's Sec. 3), written as ordinary differential
equations so that general-purpose integrators (SciPy's RK45, DOP853, Radau, BDF, a compiled RK4)
can solve it and be compared with the LGVI (``benchmarks/work_precision.py``). Its exact flow
is what the LGVI converges to as h -> 0.

State (``size = 6 n_free + 12``, SI units)::

    y = [ r (n_free, 3) | v (n_free, 3) | R (3, 3) row-major | Omega (3,) ]

``r, v``: positions [m] and velocities [m/s] of the nodes that move (rows 1..N for a fixed
pivot, 0..N for a free one; row N the attachment node), ``R`` body -> spatial, ``Omega`` the
body-frame angular velocity [rad/s]. ``R`` is integrated as 9 numbers (R' = R Omega^), so a
general-purpose method lets it drift off SO(3); :meth:`ElasticStringODE.orthogonality`
measures that.

Derivation. The finite-element Lagrangian (paper Sec. 3 with the tent functions of Sec. 4.1)::

    L = 1/2 v^T M_str v + 1/2 M |v_N|^2 + 1/2 Omega.J Omega + M v_N . R (Omega x rho_c)
        + 1/2 M_p |v_0|^2 - V(r) + M g e3 . R rho_c,

``M_str`` the consistent mass (m/6)[1 4 1] (per element (m/6)[[2, 1], [1, 2]]), ``V`` the
potential of ``nodal_forces``: elastic energy and the gravity of the string's element masses,
of the body mass at node N and of a free pivot's M_p (its force is ``f = -dV/dr``); the
last term is the rest of the body's gravity potential. With p = dL/dv and
Pi = dL/dOmega = J Omega + M rho_c x (R^T v_N) (the Legendre transform of
``esp_gym.physics.simulator.legendre_momenta``), the Euler-Lagrange equations in r and the Euler-Poincare
equation on SO(3) (variations delta R = R eta^) are::

    M_tot a - M e_N R (rho_c x Omega')  = f(r) - M e_N R (Omega x (Omega x rho_c)) + e_0 u_p  (T)
    J Omega' + M rho_c x (R^T a_N)      = -Omega x J Omega + M g rho_c x (R^T e3)
                                          + tau + R^T T                                  (Rot)

``M_tot`` = M_str with M added at the attachment node (and M_p at a free pivot), ``a = v'``.
(Rot) is the paper's rotational equation with erratum 4 (``M``, not ``m``): the terms
``M (Omega x rho_c) x R^T v`` of dL/dR and ``M rho_c x (Omega x R^T v)`` of d/dt Pi cancel with
``Pi x Omega`` by the Jacobi identity. Inputs (constant): ``u_p`` spatial force on a free pivot
[N], ``tau`` body torque [N m], ``T`` spatial torque [N m], as in ``Simulator.step``.

The coupled linear system for (a, Omega') is solved like the LGVI's step and the diagnostics'
Legendre transform (kernels/step/diagnostics.py): with ``w = M_tot^-1 e_N`` and
``s = (M_tot^-1)_{N,N}``,

    Y = M_tot^-1 (rhs of (T) with Omega' = 0)                 (one Thomas solve, 3 columns)
    J_eff Omega' = rhs of (Rot) - M rho_c x (R^T Y_N),   J_eff = J + M^2 s rho_c^ rho_c^
    a = Y + M w R (rho_c x Omega').

``J_eff`` is ``LGVIParams.Jeff``: the body's inertia less what the string carries.

Energy E = T + V and pi3 = e3 . (sum_a r_a x p_a + R Pi) are conserved by the exact flow
(without inputs; pi3 needs the pivot on the e3 axis through the origin, as for the LGVI).
"""
from __future__ import annotations

import numpy as np

from ..kernels.layout import DIAG, INPUTS, STEP_DIAG, DiagWork
from ..kernels.step.diagnostics import diagnostics as diagnostics_kernel
from ..physics.arrays import diag_work, state_arrays
from ..physics.state import State, build_params, legendre_momenta
from ..scene.params import Scene
from .ode_kernels import ODEWork, ode_rhs, ode_rhs_columns, rk4_run

class ElasticStringODE:
    """The finite-element model of a :class:`~esp_gym.scene.params.Scene` as ``y' = f(t, y)``.

    >>> ode = ElasticStringODE(load_scene("paper_example"))
    >>> sol = scipy.integrate.solve_ivp(ode.rhs, (0, 1), ode.y0(), method="DOP853",
    ...                                 rtol=1e-10, atol=1e-10)
    >>> ode.energy(sol.y.T)  # (K,) [J]

    ``pivot_force`` (spatial, free pivot only) [N], ``body_torque`` (body frame) [N m] and
    ``spatial_torque`` [N m] are constant inputs, as in :meth:`esp_gym.Simulator.step`.
    Everything the scene's time step governs (h, Newton settings) is ignored.
    """

    def __init__(self, scene: Scene, pivot_force=None, body_torque=None, spatial_torque=None):
        self.scene = scene
        self.params = build_params(scene)
        n = scene.string.elements
        self.first = self.params.first
        self.n_free = n + 1 - self.first
        self.size = 6 * self.n_free + 12
        self.r0 = np.array(scene.pivot.position, dtype=np.float64)
        inputs = np.zeros(INPUTS.size)
        for name, value in (("pivot_force", pivot_force), ("body_torque", body_torque),
                            ("spatial_torque", spatial_torque)):
            if value is not None:
                arr = np.asarray(value, dtype=np.float64)
                if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                    raise ValueError(f"{name} must be a finite 3-vector, got {value!r}")
                inputs[INPUTS[name]] = arr
        if not scene.pivot.is_free and np.any(inputs[INPUTS["pivot_force"]] != 0):
            raise ValueError("pivot_force needs a free pivot (this scene's pivot.kind is 'fixed')")
        self.inputs = inputs
        z = np.zeros
        self.work = ODEWork(r=z((n + 1, 3)), f=z((n + 1, 3)), X=z((n + 1, 3)))
        # the simulator's state and diagnostics arrays, for _diagnose
        self._diag = (state_arrays(n), diag_work(n))
        self.nfev = 0  #: right-hand side evaluations through :meth:`rhs` / :meth:`rhs_columns`

    # -- right-hand side --------------------------------------------------------------------
    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``f(t, y)`` (autonomous: t is ignored) for ``scipy.integrate.solve_ivp``."""
        dy = np.empty(self.size)
        ode_rhs(np.ascontiguousarray(y, dtype=np.float64), self.params, self.r0, self.inputs, self.work, dy)
        self.nfev += 1
        return dy

    def rhs_columns(self, t: float, Y: np.ndarray) -> np.ndarray:
        """``f`` of each column of ``Y`` (size, k): pass with ``vectorized=True`` to solve_ivp."""
        Y = np.asarray(Y, dtype=np.float64)
        if Y.ndim == 1:
            return self.rhs(t, Y)
        dY = np.empty(Y.shape)
        ode_rhs_columns(np.ascontiguousarray(Y), self.params, self.r0, self.inputs, self.work,
                        np.empty(self.size), np.empty(self.size), dY)
        self.nfev += Y.shape[1]
        return dY

    def rk4(self, y0: np.ndarray, h: float, nsteps: int, every: int = 1) -> np.ndarray:
        """Classical RK4 (compiled), ``nsteps`` steps of ``h`` [s]; returns the states after
        every ``every`` steps, (nsteps // every + 1, size), row 0 = y0. Raises
        ``FloatingPointError`` if the state becomes non-finite."""
        every = int(every)
        out = np.empty((int(nsteps) // every + 1, self.size))
        y = np.array(y0, dtype=np.float64)  # advanced in place by the kernel
        done = rk4_run(y, float(h), int(nsteps), every, self.params, self.r0, self.inputs, self.work,
                       np.empty((5, self.size)), out)
        if done < nsteps:
            raise FloatingPointError(f"RK4 with h = {h:g} s became non-finite at step {done + 1}")
        return out

    # -- states -----------------------------------------------------------------------------
    def pack(self, r: np.ndarray, v: np.ndarray, R: np.ndarray, Omega: np.ndarray) -> np.ndarray:
        """(r, v) (N+1, 3), R (3, 3), Omega (3,) -> y (the pivot row is dropped if fixed)."""
        f = self.first
        return np.concatenate([np.asarray(r, float)[f:].ravel(), np.asarray(v, float)[f:].ravel(),
                               np.asarray(R, float).ravel(), np.asarray(Omega, float).ravel()])

    def unpack(self, y: np.ndarray) -> dict:
        """y (or Y with states along the last axis) -> ``r``, ``v`` (..., N+1, 3), ``R``
        (..., 3, 3), ``Omega`` (..., 3) (copies; a fixed pivot's row is its position, at rest)."""
        y = np.asarray(y, dtype=np.float64)
        lead = y.shape[:-1]
        k = 3 * self.n_free
        n1 = self.scene.string.elements + 1
        r = np.empty(lead + (n1, 3))
        v = np.zeros(lead + (n1, 3))
        r[..., self.first:, :] = y[..., :k].reshape(lead + (self.n_free, 3))
        v[..., self.first:, :] = y[..., k:2 * k].reshape(lead + (self.n_free, 3))
        if self.first:
            r[..., 0, :] = self.r0
        return {"r": r, "v": v, "R": y[..., 2 * k:2 * k + 9].reshape(lead + (3, 3)).copy(),
                "Omega": y[..., 2 * k + 9:].copy()}

    def y0(self) -> np.ndarray:
        """The scene's initial state (the same configuration and velocities the LGVI starts from)."""
        s = self.scene
        return self.pack(s.initial_nodes(), s.initial_velocities(), np.array(s.initial.R0, dtype=float),
                         np.array(s.initial.Omega0, dtype=float))

    def _diagnose(self, state: State) -> DiagWork:
        """The simulator's diagnostics kernel on ``state`` (velocities, energies, pi3, ...);
        the returned arrays are reused by the next call."""
        S, D = self._diag
        for name in ("r", "p", "R", "Pi"):
            getattr(S, name)[...] = getattr(state, name)
        diagnostics_kernel(S, self.params, D)
        return D

    def from_state(self, state: State) -> np.ndarray:
        """A discrete LGVI state (r, p, R, Pi) -> y, with velocities from the continuous
        Legendre transform inverted as in the diagnostics (kernels/step/diagnostics.py)."""
        D = self._diagnose(state)
        return self.pack(state.r, D.V, state.R, D.omega)

    def to_state(self, y: np.ndarray, step: int = 0) -> State:
        """y -> a :class:`~esp_gym.physics.simulator.State` with momenta from ``legendre_momenta``."""
        u = self.unpack(y)
        p, Pi = legendre_momenta(self.scene, u["r"], u["v"], u["R"], u["Omega"])
        return State(np.ascontiguousarray(u["r"]), np.ascontiguousarray(p), np.ascontiguousarray(u["R"]),
                     np.ascontiguousarray(Pi), int(step))

    # -- invariants -------------------------------------------------------------------------
    def invariants(self, Y: np.ndarray) -> np.ndarray:
        """(energy [J], pi3 [kg m^2/s], ||I - R^T R||_F) of y (size,) or of each row of Y
        (K, size), laid out as :data:`~esp_gym.kernels.layout.STEP_DIAG`; shape (3,) or (K, 3). Computed like the simulator's: momenta by
        ``legendre_momenta``, then the diagnostics kernel (which inverts that transform again
        assuming R^T R = I: off SO(3) the energy is off by ~ its size x ||I - R^T R||)."""
        Y = np.asarray(Y, dtype=np.float64)
        rows = Y.reshape(-1, self.size)
        out = np.empty((rows.shape[0], 3))
        cols = [DIAG.scalar(name) for name in STEP_DIAG.names]
        for k, y in enumerate(rows):
            out[k] = self._diagnose(self.to_state(y)).out[cols]
        return out[0] if Y.ndim == 1 else out

    def energy(self, Y: np.ndarray):
        """Total energy E = T + V [J] of y or of each row of Y."""
        return self.invariants(Y)[..., STEP_DIAG.scalar("energy")]

    def pi3(self, Y: np.ndarray):
        """Angular momentum about e3 through the origin [kg m^2/s] of y or of each row of Y."""
        return self.invariants(Y)[..., STEP_DIAG.scalar("pi3")]

    def orthogonality(self, Y: np.ndarray):
        """||I - R^T R||_F of y or of each row of Y."""
        return self.invariants(Y)[..., STEP_DIAG.scalar("orthogonality")]

    def attach_position(self, Y: np.ndarray) -> np.ndarray:
        """Position of the attachment node (the load) [m], (3,) or (K, 3)."""
        Y = np.asarray(Y, dtype=np.float64)
        k = 3 * self.n_free
        return Y[..., k - 3:k].copy()
