"""LQR on the linearisation of the environment's own control step about the hanging equilibrium.

The model is the compiled control step itself (esp_gym/pendulum/control.py: one action held over the
episode's physics steps), differentiated by central finite differences, so it is exact to
O(delta^2) for any scene, randomised or not, and includes the string's stretch, the body's
rocking about its attachment point and the discrete-time zero-order hold.

Reduced state z (REDUCED, spatial frame, relative to the targets and the reference's velocity):
pivot position error and velocity, load (centre of mass) position error and velocity, the
horizontal components of the body's hanging axis b = R rho_c/|rho_c| (R e3 for a centred load)
and of its spatial angular velocity w = R Omega. The string's internal vibrations are not in z:
a reduced state is *lifted* to a full one with the string straight from the pivot to the
attachment point, its nodes at their static stretch ratios and their velocities interpolated
(:func:`lift`), as the tasks start their episodes. The spin about the vertical is left to a
rate damper on the body torque (agents/baselines/pd.py's ``k_spin``).

Cost: the local quadratic expansion of the reward. Each term w / (1 + (x/s)^2) is
w - (w/s^2) x^2 + O(x^4), so maximising the reward near the target is minimising
sum (w/s^2) x^2 + (w_c/6) |a|^2 per control step, with x the load's position error and velocity,
the pivot's position error, the swing angle (|load - pivot|_h / depth) and the spin's
horizontal part. The gains are the discrete algebraic Riccati equation's (scipy), on the action
(not the force), so K acts on the normalised action the environment takes.
"""
from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from agents.baselines import libm
from esp_gym.pendulum.control import ControlStep
from esp_gym.layouts import ACTION, OBSERVATION, TARGET, Layout
from esp_gym.pendulum.observe import Observer
from esp_gym.physics.state import State, cross3, legendre_momenta
from esp_gym.pendulum.tasks import hanging_axis, hanging_depth, rotation_between, static_node_depths

#: The reduced state of the LQR (module docstring): 16 entries.
REDUCED = Layout(("pivot_error", 3), ("pivot_velocity", 3), ("load_error", 3), ("load_velocity", 3),
                 ("axis_h", 2), ("rate_h", 2))
HORIZONTAL = slice(0, 2)  # the x, y components of a spatial vector
#: What a ``track`` design tells a residual network of the reference (:attr:`LQRTracker.features`,
#: agents/baselines/lqg.py HookLQG.features): the preview feed-forward [action units], the
#: reference's velocity [m/s] and its displacement [m] over the next PREVIEW_TIMES [s].
PREVIEW_TIMES = (0.5, 1.0)
REFERENCE_CONTEXT = Layout(("feedforward", 3), ("reference_velocity", 3), ("reference_ahead", 3 * len(PREVIEW_TIMES)))


def reduced_state(obs: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """z (REDUCED) from full observations (OBSERVATION, (..., 22)); ``axis`` the body's hanging
    axis (:func:`hanging_axis`)."""
    obs = np.asarray(obs, dtype=np.float64)
    att = obs[..., OBSERVATION["attitude_6d"]]
    columns = att.reshape(att.shape[:-1] + (2, 3))  # R's first two columns (kernels/env/task_terms.py observe)
    first, second = columns[..., 0, :], columns[..., 1, :]
    R = np.stack((first, second, np.cross(first, second)), axis=-1)
    z = np.empty(obs.shape[:-1] + (REDUCED.size,))
    for name, source in (("pivot_error", "pivot_position_error"), ("pivot_velocity", "pivot_velocity"),
                         ("load_error", "load_position_error"), ("load_velocity", "load_velocity")):
        z[..., REDUCED[name]] = obs[..., OBSERVATION[source]]
    z[..., REDUCED["axis_h"]] = (R @ axis)[..., HORIZONTAL]
    z[..., REDUCED["rate_h"]] = (R @ obs[..., OBSERVATION["angular_velocity"], None])[..., HORIZONTAL, 0]
    return z


def lift(z: np.ndarray, scene) -> State:
    """A full state with reduced state ``z`` about the equilibrium hanging below the origin
    (module docstring): the string straight from the pivot to the attachment point, nodes at the
    static stretch ratios, velocities interpolated, no spin about the vertical, momenta by the
    Legendre transform."""
    axis = hanging_axis(scene.body.rho_c)
    rho = np.asarray(scene.body.rho_c, dtype=float)
    e3 = np.array([0.0, 0.0, 1.0])
    b = np.zeros(3)
    b[HORIZONTAL] = z[REDUCED["axis_h"]]
    b[2] = math.sqrt(max(0.0, 1.0 - b[0] ** 2 - b[1] ** 2))
    R = rotation_between(e3, b) @ rotation_between(axis, e3)
    w = np.zeros(3)
    w[HORIZONTAL] = z[REDUCED["rate_h"]]
    pivot = z[REDUCED["pivot_error"]]
    load = hanging_depth(scene) * e3 + z[REDUCED["load_error"]]
    attach = load - R @ rho
    depths = static_node_depths(scene)
    share = (depths / depths[-1])[:, None]
    r = pivot + share * (attach - pivot)
    v_attach = z[REDUCED["load_velocity"]] - cross3(w, R @ rho)
    v = z[REDUCED["pivot_velocity"]] + share * (v_attach - z[REDUCED["pivot_velocity"]])
    p, Pi = legendre_momenta(scene, r, v, R, R.T @ w)
    return State(np.ascontiguousarray(r), p, np.ascontiguousarray(R), Pi, 0)


def plain_setup(setup):
    """``setup`` without randomisation, wind, action latency and sensor noise: the control step
    the model is differentiated from."""
    return dataclasses.replace(setup, randomizer=None, wind=None, action_latency=0, observer=Observer())


def equilibrium_target(scene) -> np.ndarray:
    """TARGET of the equilibrium the model is linearised about: the pivot at the origin, the
    load hanging at rest below it."""
    target = np.zeros(TARGET.size)
    target[TARGET["load"]] = (0.0, 0.0, hanging_depth(scene))
    return target


def linearize(setup, episode=None, z_step: float = 1e-5, a_step: float = 1e-4):
    """``(A (16, 16), B (16, 3))``: central differences of one control step of ``setup`` (an
    :class:`~esp_gym.pendulum.env_setup.EnvSetup`; ``episode``: its physics, default the nominal one) in z
    and in the pivot-force part of the action, about the hanging equilibrium and action 0."""
    episode = setup.nominal_episode if episode is None else episode
    control = ControlStep(plain_setup(setup))
    axis = hanging_axis(episode.scene.body.rho_c)
    target = equilibrium_target(episode.scene)

    def step(z, force):
        control.reset(lift(z, episode.scene), target, episode=episode)
        action = np.zeros(ACTION.size)
        action[ACTION["pivot_force"]] = force
        control.step(action)
        return reduced_state(control.observation, axis)

    z0, u0 = np.zeros(REDUCED.size), np.zeros(3)
    A = np.empty((REDUCED.size, REDUCED.size))
    B = np.empty((REDUCED.size, 3))
    for j in range(REDUCED.size):
        dz = np.zeros(REDUCED.size)
        dz[j] = z_step
        A[:, j] = (step(z0 + dz, u0) - step(z0 - dz, u0)) / (2 * z_step)
    for j in range(3):
        du = np.zeros(3)
        du[j] = a_step
        B[:, j] = (step(z0, u0 + du) - step(z0, u0 - du)) / (2 * a_step)
    return A, B


def reward_weights(task, depth: float):
    """``(Q (16, 16), R (3, 3))``: the reward's local quadratic cost (module docstring) on z and
    on the pivot-force action; ``depth`` the load's hanging depth [m] (the swing's lever)."""
    Q = np.zeros((REDUCED.size, REDUCED.size))
    idx = {name: np.arange(REDUCED.size)[REDUCED[name]] for name in REDUCED.names}
    position = 1.0 / task.scale_position ** 2
    Q[idx["load_error"], idx["load_error"]] += task.w_load_position * position
    Q[idx["load_velocity"], idx["load_velocity"]] += task.w_load_velocity / task.scale_velocity ** 2
    Q[idx["pivot_error"], idx["pivot_error"]] += task.w_pivot_position * position
    # swing^2 ~ |load_h - pivot_h|^2 / depth^2
    swing = task.w_swing / (task.scale_swing * depth) ** 2
    for k in range(2):
        i, j = idx["load_error"][k], idx["pivot_error"][k]
        Q[i, i] += swing
        Q[j, j] += swing
        Q[i, j] -= swing
        Q[j, i] -= swing
    Q[idx["rate_h"], idx["rate_h"]] += task.w_spin / task.scale_spin ** 2
    R = (task.w_control / ACTION.size) * np.eye(3)
    return Q, R


def lqr_solution(A, B, Q, R) -> tuple:
    """``(K, P)`` of the discrete LQR: a = -K z minimises sum z'Qz + a'Ra under z+ = Az + Ba;
    P is the Riccati solution (the cost-to-go z'Pz)."""
    P = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A), P


@dataclass
class LQR:
    """The LQR law of one scene and task: pivot-force action -K z (clipped to the box), body
    torque -k_spin Omega (body frame, as the PD baseline). Build with :meth:`design`."""

    K: np.ndarray  #: (3, 16) gains on z, action units
    axis: np.ndarray  #: the body's hanging axis (body frame)
    A: np.ndarray  #: (16, 16) the linearised control step
    B: np.ndarray  #: (16, 3) its pivot-force action columns
    P: np.ndarray  #: (16, 16) the Riccati solution
    R: np.ndarray  #: (3, 3) the control cost (with its weight)
    k_spin: float = 0.02  #: [N m s]

    @classmethod
    def design(cls, setup, episode=None, control_weight: float = 1.0, **kw) -> "LQR":
        """Linearise ``setup``'s control step (``episode``: default nominal) and solve the LQR
        with the reward's cost, its control term times ``control_weight``."""
        episode = setup.nominal_episode if episode is None else episode
        A, B = linearize(setup, episode, **kw)
        Q, R = reward_weights(setup.task, hanging_depth(episode.scene))
        R = control_weight * R
        K, P = lqr_solution(A, B, Q, R)
        return cls(K, hanging_axis(episode.scene.body.rho_c), A, B, P, R)

    def closed_loop_radius(self) -> float:
        """Spectral radius of A - B K (< 1: the linear closed loop is stable)."""
        return float(np.max(np.abs(np.linalg.eigvals(self.A - self.B @ self.K))))

    def act(self, obs: np.ndarray, setup) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        return self.action(-(reduced_state(obs, self.axis) @ self.K.T), obs, setup)

    def action(self, force: np.ndarray, obs: np.ndarray, setup) -> np.ndarray:
        """The action of pivot-force command ``force`` (action units, before clipping) and the
        spin damper on the observation ``obs``, clipped to the box."""
        action = np.zeros(obs.shape[:-1] + (ACTION.size,))
        action[..., ACTION["pivot_force"]] = force
        if setup.torque_limit > 0:
            action[..., ACTION["body_torque"]] = -self.k_spin * obs[..., OBSERVATION["angular_velocity"]] / setup.torque_limit
        return np.clip(action, -1.0, 1.0)


def reference_states(target: np.ndarray, times: np.ndarray) -> np.ndarray:
    """z of the moving reference (``track``; TARGET ``target``) at ``times`` [s], (T, 16): the
    pivot and the load on the curve (the load's rest offset below it is the equilibrium's, so 0
    here), both at the curve's velocity, the body hanging straight."""
    from esp_gym.pendulum.tasks import track_path

    times = np.asarray(times, dtype=np.float64)
    offset, velocity = track_path(target, times)
    out = np.zeros((len(times), REDUCED.size))
    for name in ("pivot_error", "load_error"):
        out[:, REDUCED[name]] = offset
    for name in ("pivot_velocity", "load_velocity"):
        out[:, REDUCED[name]] = velocity
    return out


def preview_terms(A, B, K, P, R, preview: int) -> tuple:
    """``(-G^-1 B', [-G^-1 B' (A - BK)'^j P for j < preview])`` with G = R + B'PB: the affine
    LQR's feed-forward is sum_j (second)_j d_k+j for the known drifts d."""
    closed = (A - B @ K).T
    gain = -np.linalg.solve(R + B.T @ P @ B, B.T)
    weights = [gain @ P]
    power = P
    for _ in range(preview - 1):
        power = closed @ power
        weights.append(gain @ power)
    return gain, np.array(weights)


def preview_feedforward(terms: tuple, drifts: np.ndarray) -> np.ndarray:
    """The affine LQR's feed-forward -G^-1 B' sum_j (A - BK)'^j P d_k+j for the drifts
    ``drifts`` (one per preview step; they may give only the leading entries of the state, the
    rest being 0) and ``terms`` = :func:`preview_terms`."""
    _, weights = terms
    return np.einsum("jan,jn->a", weights[:, :, :drifts.shape[1]], drifts)


def reference_drift(target: np.ndarray, A: np.ndarray, period: float, count: int) -> np.ndarray:
    """d_k = A z_ref(t_k) - z_ref(t_k+1) for the next ``count`` control steps of the reference
    in TARGET ``target`` (its clock now), (count, 16): the error's drift e+ = A e + B a + d_k.
    The definition :class:`ReferencePreview` is checked against (tests/test_lqr.py); the laws use
    that, one matrix product a step."""
    now = float(target[TARGET.scalar("clock")])
    ref = reference_states(target, now + period * np.arange(count + 1))
    return ref[:-1] @ A.T - ref[1:]


def reference_context(target: np.ndarray, feedforward: np.ndarray) -> np.ndarray:
    """REFERENCE_CONTEXT of the reference in TARGET ``target`` (its clock now) with the preview
    feed-forward ``feedforward`` [action units]: read from the curve, the definition
    :class:`ReferencePreview` is checked against."""
    context = np.zeros(REFERENCE_CONTEXT.size)
    context[REFERENCE_CONTEXT["feedforward"]] = feedforward
    now = float(target[TARGET.scalar("clock")])
    ahead = reference_states(target, now + np.array((0.0,) + PREVIEW_TIMES))
    pivot = REDUCED["pivot_error"]
    context[REFERENCE_CONTEXT["reference_velocity"]] = ahead[0, REDUCED["pivot_velocity"]]
    context[REFERENCE_CONTEXT["reference_ahead"]] = (ahead[1:, pivot] - ahead[0, pivot]).ravel()
    return context


def reference_map(target: np.ndarray, times: np.ndarray) -> np.ndarray:
    """G (len(times), 16, 4) with z_ref(t + tau) = G(tau) b(t) for the reference in TARGET
    ``target`` (:func:`reference_states`; b = :func:`reference_basis`): the curve is a sum of
    sinusoids of theta and m theta, so a shift in time is a rotation of their phases."""
    w, m = float(target[TARGET.scalar("rate")]), float(target[TARGET.scalar("harmonic")])
    ax, ay = target[TARGET["amplitude"]]
    c, s = math.cos(target[TARGET.scalar("orientation")]), math.sin(target[TARGET.scalar("orientation")])
    times = np.asarray(times, dtype=np.float64)
    cx, sx, cy, sy = libm.cos(w * times), libm.sin(w * times), libm.cos(m * w * times), libm.sin(m * w * times)
    zero = np.zeros_like(times)
    # the curve's own frame, rows x and y, columns b = [sin u, cos u, sin v, cos v]
    offset = np.stack([np.stack([ax * cx, ax * sx, zero, zero], -1), np.stack([zero, zero, ay * cy, ay * sy], -1)], 1)
    velocity = np.stack([np.stack([-ax * w * sx, ax * w * cx, zero, zero], -1),
                         np.stack([zero, zero, -ay * m * w * sy, ay * m * w * cy], -1)], 1)
    turn = np.array([[c, -s], [s, c], [0.0, 0.0]])  # about e3, into the spatial frame
    G = np.zeros((len(times), REDUCED.size, 4))
    for name in ("pivot_error", "load_error"):
        G[:, REDUCED[name]] = turn @ offset
    for name in ("pivot_velocity", "load_velocity"):
        G[:, REDUCED[name]] = turn @ velocity
    return G


def reference_basis(target: np.ndarray) -> np.ndarray:
    """b(t) = [sin u, cos u, sin v, cos v] of the reference in TARGET at its clock, u = theta + psi_x,
    v = m theta + psi_y, theta = theta_0 + omega t (esp_gym/kernels/env/track_curve.py)."""
    theta = target[TARGET.scalar("start")] + target[TARGET.scalar("rate")] * target[TARGET.scalar("clock")]
    phase = target[TARGET["phase"]]
    u, v = theta + phase[0], target[TARGET.scalar("harmonic")] * theta + phase[1]
    return np.array([math.sin(u), math.cos(u), math.sin(v), math.cos(v)])


class ReferencePreview:
    """One episode's moving reference for a design with step ``A`` and preview ``terms``
    (:func:`preview_terms`), as linear maps of b(t) (:func:`reference_basis`): the preview
    feed-forward (:func:`preview_feedforward` of :func:`reference_drift`), the first drift d_k and
    REFERENCE_CONTEXT, each a matrix product per step instead of the 150-step sum (exact to
    round-off: z_ref(t + tau) = G(tau) b(t), :func:`reference_map`)."""

    def __init__(self, target: np.ndarray, A: np.ndarray, terms: tuple, period: float):
        _, weights = terms  # preview_terms: (gain, the preview's weights on the state)
        weights = weights[:, :, :REDUCED.size]
        G = reference_map(target, period * np.arange(len(weights) + 1))
        drifts = np.einsum("mn,jnb->jmb", A, G[:-1]) - G[1:]  # d_k+j = (A G_j - G_j+1) b
        self.drift = drifts[0]  #: (16, 4)
        self.feedforward = np.einsum("jan,jnb->ab", weights, drifts)  #: (3, 4) [action units]
        ahead = reference_map(target, np.array((0.0,) + PREVIEW_TIMES))
        pivot = REDUCED["pivot_error"]
        self.context = np.concatenate((self.feedforward, ahead[0, REDUCED["pivot_velocity"]],
                                       (ahead[1:, pivot] - ahead[0, pivot]).reshape(-1, 4)))  #: REFERENCE_CONTEXT rows
        self.target = target

    @classmethod
    def of(cls, target, A, terms, period) -> "ReferencePreview | None":
        """The preview of a moving reference in ``target``, or None for none (a fixed target)."""
        if target is None or target[TARGET.scalar("rate")] == 0.0:
            return None
        return cls(target, A, terms, period)

    def now(self) -> np.ndarray:
        """b(t) at the live TARGET's clock."""
        return reference_basis(self.target)


class LQRTracker(LQR):
    """:class:`LQR` plus the optimal feed-forward of a known reference (``track``): for the error
    e = z - z_ref, e+ = A e + B a + d_k with d_k = A z_ref(t_k) - z_ref(t_k+1), the affine LQR
    gives a = -K e - G^-1 B' sum_j (A - BK)'^j P d_k+j, G = R + B'PB (docs/agents.md); the sum is
    cut after ``preview`` control steps. The reference is read from the environment's TARGET
    (:meth:`reset`), as a tracking controller is given the curve it tracks; the observation
    already holds e. As a residual's base (agents/residual.py) it is stateful: one copy per
    environment (:meth:`clone`, :meth:`start`), telling the network the reference's
    REFERENCE_CONTEXT (:attr:`features`)."""

    def __init__(self, base: LQR, period: float, preview: int = 150):
        super().__init__(base.K, base.axis, base.A, base.B, base.P, base.R, base.k_spin)
        self._preview = preview_terms(self.A, self.B, self.K, self.P, self.R, preview)
        self.period = float(period)
        self.start(None)

    @classmethod
    def design(cls, setup, episode=None, control_weight: float = 1.0, preview: int = 150, **kw) -> "LQRTracker":
        return cls(LQR.design(setup, episode, control_weight, **kw), setup.control_period, preview)

    def reset(self, env) -> None:
        """Follow the reference of ``env``'s current episode (its live TARGET view)."""
        self.start(env.control.target)

    def start(self, target) -> None:
        """Follow the reference in the live TARGET view ``target`` (None: no reference)."""
        self._target = target
        self._reference = ReferencePreview.of(target, self.A, self._preview, self.period)
        self._context = np.zeros(REFERENCE_CONTEXT.size)

    def clone(self) -> "LQRTracker":
        """The same design following a reference of its own (one per environment of a batch)."""
        twin = copy.copy(self)  # the gains and preview terms shared, read only
        twin.start(None)
        return twin

    @property
    def features(self) -> np.ndarray:
        """The reference's REFERENCE_CONTEXT at the last observation (zeros for a fixed target)."""
        return self._context

    def applied(self, action: np.ndarray) -> None:
        """The law holds no estimate: what was applied changes nothing."""

    def act(self, obs: np.ndarray, setup) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        if obs.ndim != 1 and self._target is not None:
            raise ValueError(f"LQRTracker follows one environment's reference, got observations of shape {obs.shape}")
        force = -(reduced_state(obs, self.axis) @ self.K.T)
        if self._reference is not None:
            self._context = self._reference.context @ self._reference.now()
            force = force + self._context[REFERENCE_CONTEXT["feedforward"]]
        return self.action(force, obs, setup)


class EpisodeLQR:
    """A model-based law designed for each episode's own scene by ``design(setup, episode)``
    (e.g. :meth:`LQR.design`): with ``randomize`` and the full observation the drawn parameters
    are known to the designer (:meth:`reset` reads ``env.scene``; 15-60 ms a design). Without
    randomisation one design serves every episode."""

    def __init__(self, design):
        self.design = design
        self._scene = None
        self._law = None

    def reset(self, env) -> None:
        if env.scene != self._scene:  # equal scenes (a new env of the same task) share a design
            self._law = self.design(env.setup, env.setup.episode_for(env.scene))
            self._scene = env.scene
        if hasattr(self._law, "reset"):
            self._law.reset(env)

    def act(self, obs: np.ndarray, setup) -> np.ndarray:
        if self._law is None:
            raise RuntimeError("EpisodeLQR.act before reset(env): the design needs the episode's scene")
        return self._law.act(obs, setup)
