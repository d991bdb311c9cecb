"""LQG: the LQR of agents/baselines/lqr.py acting on a steady-state Kalman filter's estimate, for
observations that do not hold the load's state (``observation="hook"``: the hook's position
error and velocity, the string's pull on it, the load target relative to it), with the action
latency and the sensor noise of the environment.

Model (docs/agents.md, "LQG for the hook observation"), all from the simulator about the hanging
equilibrium of the *nominal* scene (the hook observation does not reveal a randomised episode's
parameters, so the design is fixed):

* z+ = A z + B a_applied + E f, with (A, B) the LQR's central differences of the control step;
* a_applied is the action given ``action_latency`` steps earlier: the pending actions q join the
  state (x = [z; q], oldest first), so the LQR is designed for the delayed system;
* f is a force on the load [N], constant but for a random walk (the mean wind, a load heavier or
  lighter than nominal): E is its impulse over one control step, T/M on the load's velocity and
  T^2/(2M) on its position (M the nominal load mass);
* y = y0 + C z + v, with C the central differences of the observation (Observer.measure: the
  hook tension from the top element's stretch and direction) and v the sensor noise (its
  standard deviations are the environment's ``noise_std``).

Control: a = -K x - K_f f + feed-forward, where K is the delayed system's LQR gain and
K_f = G^-1 B' (I - A_cl')^-1 P E the affine LQR's answer to a constant f (the same sum as
LQRTracker's reference preview, for a constant drift). For ``track`` the reference's preview is
added too. The body torque is 0 (the hook observation has no gyro).
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np
import scipy.linalg

from agents.baselines.lqr import (LQR, REDUCED, REFERENCE_CONTEXT, ReferencePreview, equilibrium_target, lift, lqr_solution,
                                  plain_setup, preview_terms, reward_weights)
from esp_gym.pendulum.control import ControlStep
from esp_gym.layouts import ACTION
from esp_gym.pendulum.observe import UNIT_NOISE
from esp_gym.scene.params import override_scene
from esp_gym.pendulum.tasks import hanging_depth

#: Entries of z that the process noise drives (velocities: forces act on them).
DRIVEN = ("pivot_velocity", "load_velocity", "rate_h")


def measurement_model(setup, episode=None, z_step: float = 1e-5) -> tuple:
    """``(C (m, 16), y0 (m,))``: central differences in z of ``setup``'s observation (its
    mode's fields, noiseless) about the equilibrium of ``episode`` (default: the nominal one),
    and its value there."""
    plain = plain_setup(setup)
    episode = plain.nominal_episode if episode is None else episode
    control = ControlStep(plain)
    target = equilibrium_target(episode.scene)

    def measure(z):
        control.reset(lift(z, episode.scene), target, episode=episode)
        return setup.observer.measure(control.observation, control.sensors)

    y0 = measure(np.zeros(REDUCED.size))
    C = np.empty((y0.size, REDUCED.size))
    for j in range(REDUCED.size):
        dz = np.zeros(REDUCED.size)
        dz[j] = z_step
        C[:, j] = (measure(dz) - measure(-dz)) / (2 * z_step)
    return C, y0


def delayed_system(A, B, latency: int) -> tuple:
    """``(A_x, B_x)`` of x = [z; q] when the action acts ``latency`` control steps after it is
    given (q: the pending actions, oldest first; the oldest is applied, the new one queued)."""
    n, m = B.shape
    size = n + m * latency
    Ax = np.zeros((size, size))
    Ax[:n, :n] = A
    Bx = np.zeros((size, m))
    if latency == 0:
        Bx[:n] = B
        return Ax, Bx
    Ax[:n, n:n + m] = B
    for i in range(latency - 1):
        Ax[n + m * i:n + m * (i + 1), n + m * (i + 1):n + m * (i + 2)] = np.eye(m)
    Bx[size - m:] = np.eye(m)
    return Ax, Bx


def load_force_input(scene, period: float) -> np.ndarray:
    """E (16, 3): the change of z over one control step of ``period`` [s] under a force of 1 N
    on the load (its impulse, the load's mass alone)."""
    E = np.zeros((REDUCED.size, 3))
    mass = scene.body.mass
    E[REDUCED["load_velocity"]] = np.eye(3) * period / mass
    E[REDUCED["load_error"]] = np.eye(3) * period ** 2 / (2 * mass)
    return E


@dataclasses.dataclass
class HookLQG:
    """The LQG law of a setup (build with :meth:`design`); stateful: :meth:`reset` starts an
    episode's estimate (agents.evaluate.evaluate_policy calls it), :meth:`act` takes one
    observation at a time."""

    K: np.ndarray  #: (3, nx) LQR gain on x = [z; q]
    K_force: np.ndarray  #: (3, 3) gain on the estimated load force
    L: np.ndarray  #: (nx + 3, m) Kalman gain (measurement update)
    A_est: np.ndarray  #: (nx + 3, nx + 3) the estimator's model of [x; f]
    B_est: np.ndarray  #: (nx + 3, 3)
    C_est: np.ndarray  #: (m, nx + 3)
    y0: np.ndarray  #: (m,) the observation at the equilibrium
    A: np.ndarray  #: (16, 16) the linearised control step (for the reference's drift)
    period: float  #: [s]
    preview: tuple = ()  #: preview_terms of the delayed system, for ``track``

    @classmethod
    def design(cls, setup, control_weight: float = 100.0, state_noise: float = 1e-4, force_noise: float = 1e-3,
               model_error: float = 1.0, preview: int = 150, episode=None) -> "HookLQG":
        """The LQR of the delayed nominal system with the reward's cost (control term times
        ``control_weight``), and the steady-state Kalman filter with process noise
        ``state_noise`` [(m/s)^2 per step] on the velocities and ``force_noise`` [N^2 per step]
        on the load force, and the environment's sensor noise plus ``model_error`` times each
        field's UNIT_NOISE (what the model leaves out: the string's own vibrations pull on the
        hook; without it a noiseless observation makes the filter follow them). ``episode``:
        the physics designed for (default: the nominal scene's)."""
        episode = setup.nominal_episode if episode is None else episode
        base = LQR.design(plain_setup(setup), episode, control_weight=control_weight)
        latency = setup.action_latency
        Ax, Bx = delayed_system(base.A, base.B, latency)
        nx = Ax.shape[0]
        Q = np.zeros((nx, nx))
        Q[:REDUCED.size, :REDUCED.size] = reward_weights(setup.task, hanging_depth(episode.scene))[0]
        K, P = lqr_solution(Ax, Bx, Q, base.R)
        gain, _ = preview_terms(Ax, Bx, K, P, base.R, 1)
        Ex = np.zeros((nx, 3))
        Ex[:REDUCED.size] = load_force_input(episode.scene, setup.control_period)
        closed = (Ax - Bx @ K).T
        K_force = -gain @ np.linalg.solve(np.eye(nx) - closed, P @ Ex)
        C, y0 = measurement_model(setup, episode)
        ne = nx + 3
        A_est = np.zeros((ne, ne))
        A_est[:nx, :nx] = Ax
        A_est[:nx, nx:] = Ex
        A_est[nx:, nx:] = np.eye(3)
        B_est = np.vstack((Bx, np.zeros((3, 3))))
        C_est = np.zeros((C.shape[0], ne))
        C_est[:, :REDUCED.size] = C
        W = np.zeros((ne, ne))
        for name in DRIVEN:
            idx = np.arange(REDUCED.size)[REDUCED[name]]
            W[idx, idx] = state_noise
        W[nx:, nx:] = force_noise * np.eye(3)
        W += 1e-12 * np.eye(ne)  # the pending actions are known: a token noise keeps the DARE regular
        unmodelled = np.empty(setup.observer.layout.size)
        for name in setup.observer.layout.names:
            unmodelled[setup.observer.layout[name]] = model_error * UNIT_NOISE[name]
        V = np.diag(setup.observer.noise_std ** 2 + unmodelled ** 2)
        S = scipy.linalg.solve_discrete_are(A_est.T, C_est.T, W, V)
        L = S @ C_est.T @ np.linalg.inv(C_est @ S @ C_est.T + V)
        terms = preview_terms(Ax, Bx, K, P, base.R, preview) if setup.task.name == "track" else ()
        return cls(K, K_force, L, A_est, B_est, C_est, y0, base.A, setup.control_period, terms)

    def __post_init__(self):
        self.start(None)

    def reset(self, env) -> None:
        """Start an episode of ``env`` (the estimate at the equilibrium; ``track``: follow its
        reference through its live TARGET view)."""
        self.start(env.control.target)

    def start(self, target) -> None:
        """Start an episode whose TARGET is the live view ``target`` (one environment's row)."""
        self._target = target
        self._reference = ReferencePreview.of(target, self.A, self.preview, self.period) if self.preview else None
        self._predicted = np.zeros(self.A_est.shape[0])
        self._estimate = self._predicted
        self._drift0 = None
        self._context = np.zeros(REFERENCE_CONTEXT.size)

    @property
    def estimate(self) -> np.ndarray:
        """The filtered [z; q; f] after the last observation (z: REDUCED, q: the pending actions,
        f: the load force [N])."""
        return self._estimate

    @property
    def features(self) -> np.ndarray:
        """What a residual network sees of this law: the estimate, and for a ``track`` design the
        reference's REFERENCE_CONTEXT after the last observation (zeros for a fixed target)."""
        return np.concatenate((self._estimate, self._context)) if self.preview else self._estimate

    def act(self, obs: np.ndarray, setup) -> np.ndarray:
        y = np.asarray(obs, dtype=np.float64) - self.y0
        if y.ndim != 1:
            raise ValueError(f"HookLQG filters one environment's observation at a time, got shape {y.shape}")
        predicted = self._predicted
        estimate = predicted + self.L @ (y - self.C_est @ predicted)
        nx = self.K.shape[1]
        force = -self.K @ estimate[:nx] - self.K_force @ estimate[nx:]
        drift0 = None
        if self._reference is not None:  # the reference moves z only: the pending actions' drift is 0
            phases = self._reference.now()
            self._context = self._reference.context @ phases
            force = force + self._context[REFERENCE_CONTEXT["feedforward"]]
            drift0 = self._reference.drift @ phases
        force = np.clip(force, -1.0, 1.0)
        self._estimate, self._drift0 = estimate, drift0
        self._predict(force)
        action = np.zeros(ACTION.size)
        action[ACTION["pivot_force"]] = force
        return action

    def applied(self, action: np.ndarray) -> None:
        """The action that was applied instead of the last one :meth:`act` gave (a residual
        policy adds to it): the filter's prediction takes its pivot force."""
        self._predict(np.asarray(action, dtype=np.float64)[ACTION["pivot_force"]])

    def _predict(self, force: np.ndarray) -> None:
        self._predicted = self.A_est @ self._estimate + self.B_est @ force
        if self._drift0 is not None:
            self._predicted[:REDUCED.size] += self._drift0


class ScheduledLQG:
    """:class:`HookLQG` designs for load masses ``mass_factors`` times the nominal one (the other
    parameters nominal); each episode uses the design whose resting hook tension is nearest the
    first one measured (the load cell weighs the load: its mass is the randomised parameter that
    costs a fixed design the most, docs/agents.md)."""

    def __init__(self, setup, mass_factors=(0.5, 0.71, 1.0, 1.41, 2.0), **design):
        self.laws = []
        self.rest_tension = []
        field = setup.observer.layout["hook_tension"]
        for factor in mass_factors:
            scene = override_scene(setup.scene, {"body.mass": factor * setup.scene.body.mass})  # validated
            law = HookLQG.design(setup, episode=setup.episode_for(scene), **design)
            self.laws.append(law)
            self.rest_tension.append(float(np.linalg.norm(law.y0[field])))
        self._field = field
        self.start(None)

    @property
    def current(self):
        """The design in use this episode (None before its first observation)."""
        return self._law

    def clone(self) -> "ScheduledLQG":
        """The same designs with an estimate of their own (one per environment of a batch)."""
        twin = copy.copy(self)
        twin.laws = [copy.copy(law) for law in self.laws]
        twin.start(None)
        return twin

    def reset(self, env) -> None:
        self.start(env.control.target)

    def start(self, target) -> None:
        """Start an episode whose TARGET is the live view ``target`` (None: no reference)."""
        self._law, self._target = None, target

    @property
    def estimate(self) -> np.ndarray:
        """The current design's filtered [z; q; f] (zeros before the episode's first observation)."""
        if self._law is None:
            return np.zeros(self.laws[0].A_est.shape[0])
        return self._law.estimate

    @property
    def features(self) -> np.ndarray:
        """The current design's :attr:`HookLQG.features` (zeros before the first observation)."""
        if self._law is None:
            return np.zeros(self.laws[0].features.shape)
        return self._law.features

    def act(self, obs: np.ndarray, setup) -> np.ndarray:
        if self._law is None:  # weigh the load with the first observation
            tension = float(np.linalg.norm(np.asarray(obs, dtype=np.float64)[..., self._field]))
            self._law = self.laws[int(np.argmin(np.abs(np.array(self.rest_tension) - tension)))]
            self._law.start(self._target)
        return self._law.act(obs, setup)

    def applied(self, action: np.ndarray) -> None:
        """See :meth:`HookLQG.applied`."""
        self._law.applied(action)
