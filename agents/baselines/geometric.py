"""The classical controllers of a drone at the pivot (docs/agents.md, "Flying the drone"): a cascade
from a desired thrust vector through the drone's attitude to its rates, torques or motors, under
two outer laws.

* :class:`DronePD`: the point pivot's PD law (agents/baselines/pd.py: the pivot's position and
  velocity, the anti-sway term) asks for a force on the pivot; the drone makes it its thrust
  vector. The load enters only through that law's anti-sway term.
* :class:`GeometricLoadController`: the load leads (the geometric controllers of a quadrotor with
  a suspended load: Sreenath, Lee and Kumar 2013; Lee, Sreenath and Kumar 2013). The load's
  position error asks for a load acceleration, that for the string's force on the load, whose
  direction q_d and size T_d place the drone at x_L - d q_d (d the drone-load distance now); a
  PD law on that place, plus the load's asked acceleration along the string q (along it drone
  and load move as one: without that term only the load's mass stiffens the height, and a hover
  thrust 2 % off settles 17 cm off), with the string's pull -T_d q taken off, is the thrust vector.
* :class:`HookGeometricController`: that law on the hook observation, on the load's place and
  velocity as agents/baselines/load_estimate.py's filter tells them from the hook's pull; the
  load's mass is weighed, the drone's is the nominal one. With a winch (under the hoist) the
  estimate's string length follows the observed reel.

The inner loops (:func:`drone_action`), shared: the thrust vector u_d (spatial, pushing the
drone; hover -W e3) gives the collective thrust f = -u_d . b3 along the body's -b3 now and the
desired body axis b3_d = -u_d / |u_d|, with the heading b1_d nearest e1; the attitude error
e_R = 1/2 (R_d^T R - R^T R_d)^vee (Lee, Leok and McClamroch 2010) asks for the body rates
Omega_d = -k_R e_R (``thrust_rates``), the torque J (k_Omega (Omega_d - Omega)) + Omega x J Omega
(``thrust_torque``), or that wrench's rotor thrusts (``motors``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from agents.baselines.load_estimate import LoadEstimator, nominal_load_mass
from esp_gym.layouts import DRONE_ACTION_PARAMS
from esp_gym.physics.state import total_weight
from esp_gym.pendulum.tasks import hanging_depth

E1 = np.array([1.0, 0.0, 0.0])
E3 = np.array([0.0, 0.0, 1.0])


def drone_attitude(obs: np.ndarray, layout) -> np.ndarray:
    """R_q (3, 3) from the observation's ``drone_attitude_6d`` (its first two columns)."""
    six = obs[layout["drone_attitude_6d"]]
    b1, b2 = six[:3], six[3:]
    return np.column_stack([b1, b2, np.cross(b1, b2)])


def attitude_error(R_d: np.ndarray, R: np.ndarray) -> np.ndarray:
    """e_R = 1/2 (R_d^T R - R^T R_d)^vee (body frame)."""
    E = 0.5 * (R_d.T @ R - R.T @ R_d)
    return np.array([E[2, 1], E[0, 2], E[1, 0]])


def desired_attitude(b3_d: np.ndarray) -> np.ndarray:
    """R_d with third column ``b3_d`` and first column the unit vector nearest e1 normal to it."""
    b2 = np.cross(b3_d, E1)
    norm = np.linalg.norm(b2)
    b2 = b2 / norm if norm > 1e-9 else np.array([0.0, 1.0, 0.0])
    return np.column_stack([np.cross(b2, b3_d), b2, b3_d])


@dataclass(frozen=True)
class InnerLoops:
    """The attitude gain k_R [1/s] (rates = -k_R e_R) and, for ``thrust_torque`` and ``motors``, the
    rate gain k_Omega [1/s] of the torque."""

    k_attitude: float = 8.0
    k_rate: float = 20.0


def drone_action(u_d: np.ndarray, obs: np.ndarray, setup, inner: InnerLoops = InnerLoops(),
                 hover: Optional[float] = None) -> np.ndarray:
    """The action in [-1, 1]^4 of ``setup.actuation`` that pushes the drone with the thrust vector
    ``u_d`` [N] (spatial; module docstring). The action's thrust is relative to the episode's hover
    thrust (the rig's weight: esp_gym/pendulum/env_setup.py drone_action_params), ``hover`` [N] the
    controller's value of it (default: the nominal scene's)."""
    layout = setup.observer.layout
    qa = setup.action_params
    if hover is None:
        hover = qa[DRONE_ACTION_PARAMS.scalar("hover_thrust")]
    limits = (qa[DRONE_ACTION_PARAMS["rate_limit"]], qa[DRONE_ACTION_PARAMS["torque_limit"]])
    return inner_action(u_d, drone_attitude(obs, layout), obs[layout["drone_rates"]], setup.actuation,
                        setup.scene.pivot.drone, hover, limits, inner)


def inner_action(u_d: np.ndarray, R: np.ndarray, rates: np.ndarray, actuation: str, drone, hover: float, limits,
                 inner: InnerLoops = InnerLoops()) -> np.ndarray:
    """The inner loops (module docstring) of a drone (``drone``: its DroneParams) at attitude ``R``
    turning at body ``rates`` [rad/s]: its action in [-1, 1]^4 of ``actuation`` for the thrust
    vector ``u_d`` [N], the thrust relative to ``hover`` [N], the rates and torques over
    ``limits`` = (rates at action 1 (3) [rad/s], torques at action 1 (3) [N m])."""
    rate_limit, torque_limit = limits
    size = np.linalg.norm(u_d)
    b3_d = -u_d / size if size > 1e-9 else E3
    f = max(-float(u_d @ R[:, 2]), 0.0)
    rates_d = -inner.k_attitude * attitude_error(desired_attitude(b3_d), R)
    action = np.empty(4)
    action[0] = f / hover - 1.0
    if actuation == "thrust_rates":
        action[1:] = rates_d / rate_limit
        return np.clip(action, -1.0, 1.0)
    J = drone.inertia_matrix()
    torque = J @ (inner.k_rate * (rates_d - rates)) + np.cross(rates, J @ rates)
    if actuation == "thrust_torque":
        action[1:] = torque / torque_limit
        return np.clip(action, -1.0, 1.0)
    thrusts = drone.allocation() @ np.concatenate([[f], torque])
    return np.clip(thrusts / (0.25 * hover) - 1.0, -1.0, 1.0)


@dataclass(frozen=True)
class DronePD:
    """The point pivot's PD law (gains in 1/s^2 and 1/s, as agents/baselines/pd.py's AntiSwayPD)
    as the drone's thrust vector u_d = -W e3 + (W/g) a, then :func:`drone_action`."""

    kp: float = 4.0
    kd: float = 2.0
    kp_z: float = 16.0
    kd_z: float = 6.0
    k_sway: float = 0.0
    inner: InnerLoops = InnerLoops()

    def act(self, obs, setup) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        if obs.ndim > 1:
            return np.stack([self.act(o, setup) for o in obs])
        layout = setup.observer.layout
        e_p = obs[layout["pivot_position_error"]]
        v_p = obs[layout["pivot_velocity"]]
        horizontal, vertical = slice(0, 2), 2  # x, y and z of a spatial vector
        acc = np.empty(3)
        acc[horizontal] = -self.kp * e_p[horizontal] - self.kd * v_p[horizontal]
        if "load_velocity" in layout:
            acc[horizontal] += self.k_sway * (obs[layout["load_velocity"]] - v_p)[horizontal]
        acc[vertical] = -self.kp_z * e_p[vertical] - self.kd_z * v_p[vertical]
        weight = -setup.hover[2]
        return drone_action(-weight * E3 + weight / setup.scene.gravity * acc, obs, setup, self.inner)


@dataclass
class GeometricLoadController:
    """The load-led cascade (module docstring), for the full observation. Gains: the load's
    k_load [1/s^2] and k_load_d [1/s], its acceleration command's largest size
    max_load_acceleration [m/s^2], the drone's place k_drone [1/s^2] and velocity k_drone_d [1/s],
    the share of the load's asked acceleration along the string the drone takes too
    (``feedforward``, 1; 0 leaves it out). :meth:`reset` reads the episode's masses, the depth of
    the load's target below the pivot's (its hanging depth; with a winch, at the task's target
    length) and the hover thrust the action is relative to (randomised episodes have their own).
    Under :class:`~agents.baselines.pd.Hoist` it flies a winch's task, the hoist reeling."""

    k_load: float = 6.0
    k_load_d: float = 3.0
    k_drone: float = 16.0
    k_drone_d: float = 4.0
    max_load_acceleration: float = np.inf
    feedforward: float = 1.0
    inner: InnerLoops = InnerLoops()
    _episode: Optional[tuple] = None
    _hover: Optional[float] = None

    def reset(self, env) -> None:
        pivot_target, load_target = np.split(np.asarray(env.target), 2)  # a winch's task: at its target length
        self._use(env.scene, float((load_target - pivot_target) @ E3))

    def _use(self, scene, depth: float) -> None:
        """Fly ``scene``'s rig with the load ``depth`` [m] below the drone at its target."""
        half_string = 0.5 * scene.string.mass_per_length * scene.string.length
        self._episode = (scene.body.mass + half_string, scene.pivot.mass + half_string, depth)
        self._hover = total_weight(scene)

    def act(self, obs, setup) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        if obs.ndim > 1:
            return np.stack([self.act(o, setup) for o in obs])
        layout = setup.observer.layout
        if "load_position_error" not in layout:
            raise ValueError("GeometricLoadController needs the full observation (the load's state); "
                             "HookGeometricController flies on the hook's")
        if self._episode is None:  # not reset: the nominal scene's rig, the load hanging at rest below the pivot
            self._use(setup.scene, hanging_depth(setup.scene))
        e_load, v_load = obs[layout["load_position_error"]], obs[layout["load_velocity"]]
        e_drone, v_drone = obs[layout["pivot_position_error"]], obs[layout["pivot_velocity"]]
        m_load, m_drone, depth = self._episode
        if setup.winch:
            e_load, v_load, depth = hoisted(e_load, v_load, e_drone, v_drone, depth)
        u_d = self.thrust_vector(e_load, v_load, e_drone, v_drone, m_load, m_drone, depth, setup.scene.gravity)
        return drone_action(u_d, obs, setup, self.inner, self._hover)

    def thrust_vector(self, e_load, v_load, e_drone, v_drone, m_load: float, m_drone: float, depth: float,
                      g: float, disturbance=None) -> np.ndarray:
        """The drone's thrust vector u_d [N] (module docstring) from the load's and the drone's
        position errors [m] and velocities [m/s], their masses [kg], the load's depth below the
        drone at rest [m], gravity [m/s^2] and ``disturbance``, what else accelerates the load
        [m/s^2] (the wind's drag; the string's force cancels it)."""
        # 1. the load's acceleration -> the string's force on it: its tension and direction
        wanted = -self.k_load * e_load - self.k_load_d * v_load
        size = np.linalg.norm(wanted)
        if size > self.max_load_acceleration:
            wanted *= self.max_load_acceleration / size
        force = m_load * (wanted - g * E3 - (0.0 if disturbance is None else disturbance))
        tension = np.linalg.norm(force)
        q_d = -force / tension if tension > 0 else E3  # no force wanted: the string hangs
        # 2. the drone's place on that direction, at the distance it has now
        r = e_load - e_drone + depth * E3  # drone -> load
        place = r - np.linalg.norm(r) * q_d  # x_d - x
        q = r / max(np.linalg.norm(r), 1e-9)
        acc = self.feedforward * (wanted @ q) * q + self.k_drone * place + self.k_drone_d * (v_load - v_drone)
        # 3. its thrust vector: the PD's force less the string's pull on it, tension T_d along q
        return m_drone * (acc - g * E3) - tension * q


def hoisted(e_load, v_load, e_drone, v_drone, depth: float) -> tuple:
    """The load's errors and depth as the cascade takes them while a hoist reels (Hoist): the reel
    sets the load's height, so the load asks for the drone's; the drone -> load vector is kept.
    Returns (e_load [m], v_load [m/s], depth [m])."""
    below = (e_load - e_drone) @ E3  # the load's depth error beyond the drone's
    return e_load - below * E3, v_load - ((v_load - v_drone) @ E3) * E3, depth + below


@dataclass
class HookGeometricController:
    """The load-led cascade on the hook observation: ``law``'s gains acting on the load's state
    as agents/baselines/load_estimate.py's filter estimates it from the hook's pull. Stateful
    (one estimate per episode): ``reset``/``start`` begin an episode, ``clone`` makes a copy with an
    estimate of its own, ``features`` is the estimate (a residual network sees it)."""

    law: GeometricLoadController
    estimator: LoadEstimator

    @classmethod
    def for_setup(cls, setup, law: GeometricLoadController, **noise) -> "HookGeometricController":
        """``law`` with a filter at ``setup``'s control period and its nominal load (``noise``:
        LoadEstimator's)."""
        scene = setup.scene
        return cls(law, LoadEstimator(setup.control_period, scene.gravity, nominal_load_mass(scene), **noise))

    def clone(self) -> "HookGeometricController":
        return HookGeometricController(self.law, self.estimator.clone())

    def reset(self, env=None) -> None:
        self.estimator.start()

    def start(self, target=None) -> None:
        self.estimator.start()

    def applied(self, action) -> None:
        """The filter takes the load cell's pull, not the action: nothing to do."""

    @property
    def features(self) -> np.ndarray:
        return self.estimator.features

    def act(self, obs, setup) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        if obs.ndim > 1:
            raise ValueError("HookGeometricController acts on one observation (clone one per environment)")
        layout = setup.observer.layout
        if "hook_tension" not in layout:
            raise ValueError("HookGeometricController needs the hook observation (observation='hook' or preset='hard')")
        e_drone, v_drone = obs[layout["pivot_position_error"]], obs[layout["pivot_velocity"]]
        estimate = self.estimator
        scene = setup.scene  # the nominal one: the drone's mass is not measured
        length = None
        if setup.winch:  # the load hangs the reeled length and the nominal excess of its depth over it
            length = obs[layout["unstretched_length"]][0] + hanging_depth(scene) - scene.string.length
        estimate.update(e_drone, obs[layout["hook_tension"]], obs[layout["load_target_offset"]], length)
        e_load, v_load, depth = estimate.position_error, estimate.velocity, estimate.depth
        if setup.winch:
            e_load, v_load, depth = hoisted(e_load, v_load, e_drone, v_drone, depth)
        u_d = self.law.thrust_vector(e_load, v_load, e_drone, v_drone, estimate.load_mass, scene.pivot.mass, depth,
                                     scene.gravity, estimate.disturbance)
        hover = scene.gravity * (scene.pivot.mass + estimate.load_mass)  # the weighed load's rig
        return drone_action(u_d, obs, setup, self.law.inner, hover)


#: The load-led cascade's gains per task (k_load, k_load_d, k_drone, k_drone_d,
#: max_load_acceleration), tuned by the project's tuner on quadrotor_load in ``thrust_rates``, 20
#: episodes (seeds 1000+) per grid point: ``python -m agents.baselines.gain_search --controller
#: geometric --scene quadrotor_load --task TASK --episodes 20 --grid GRID`` with GRID
#: {"k_load": [4, 6, 8], "k_load_d": [3, 4, 6], "k_drone": [12, 16, 24], "k_drone_d": [4, 6]} for
#: stabilize (462.9), {"k_load": [4, 6], "k_load_d": [4, 6], "k_drone": [12, 16], "k_drone_d": [4, 6],
#: "max_load_acceleration": [2, 100]} for transport (455.0) and {"k_load": [4, 6, 8], "k_load_d":
#: [3, 4, 6], "k_drone": [16, 24], "k_drone_d": [4, 6]} for track (390.6). The PD law on the same
#: seeds: 441.6, 424.9, 270.8.
GEOMETRIC_GAINS = {"stabilize": (4.0, 4.0, 16.0, 6.0, np.inf), "transport": (4.0, 4.0, 16.0, 6.0, np.inf),
                   "track": (8.0, 4.0, 24.0, 6.0, np.inf)}
#: Where ``motors`` keeps other gains: its torque loop closes at the control rate (50 Hz), not at
#: the onboard rate controller's. With track's stiff gains some episodes
#: flip (the PD law won on held-out seeds 0-49, -29.9 +- 34.2, where these win); transport's
#: uncapped ones flipped one episode of 50 (+11.8 +- 18.1), capped at 2 m/s^2 (the tuner's best in
#: ``motors``, 451.9) none. ``lower`` moves its pivot as transport does and takes the same (uncapped:
#: +29.3 +- 28.2, one flip; capped: +69.3 +- 10.2).
MOTORS_GAINS = {"transport": (4.0, 4.0, 16.0, 6.0, 2.0), "lower": (4.0, 4.0, 16.0, 6.0, 2.0),
                "track": (6.0, 3.0, 16.0, 4.0, np.inf)}


#: The hoist's reel gain k_length [1/s] under the cascade (agents/baselines/pd.py Hoist; the winch's
#: tasks, full observation, stabilize's cascade gains): ``python -m agents.baselines.gain_search
#: --controller geometric --scene quadrotor_load --task lift --episodes 10 --grid GRID`` with GRID
#: {"k_load": [2, 4, 6], "k_load_d": [2, 4], "k_drone": [8, 16], "k_drone_d": [4, 6], "k_length": [1, 2, 4]}:
#: 453.1 at 1 with stabilize's gains (453.4 the grid's best), 186.7 at 4. On the hook observation
#: (``--preset hard``, 20 episodes, GRID {"k_length": [0.5, 1, 2, 4], "k_load": [2, 4, 6]}) (1, 4) is
#: within 1.8 % of the best on both tasks: lift 222.2 (best 226.3), lower 275.0 (best 275.8).
GEOMETRIC_HOIST_GAIN = 1.0


#: The cascade's gains on the hook observation (:class:`HookGeometricController`, the hard preset), as
#: :data:`GEOMETRIC_GAINS`, tuned on quadrotor_load in ``thrust_rates``, 20 episodes (seeds 1000+) per
#: grid point: ``python -m agents.baselines.gain_search --controller geometric --scene quadrotor_load
#: --preset hard --task TASK --episodes 20 --grid GRID`` with GRID {"k_load": [2, 3, 4], "k_load_d":
#: [4, 6, 8], "k_drone": [4, 6, 8], "k_drone_d": [4, 6, 8]} for stabilize (327.1), {"k_load": [3, 4, 6],
#: "k_load_d": [4, 6], "k_drone": [8, 12], "k_drone_d": [4, 6], "max_load_acceleration": [2, 100]} for
#: transport (326.6) and {"k_load": [3, 4, 6, 8], "k_load_d": [4, 6], "k_drone": [8, 12, 16],
#: "k_drone_d": [4, 6]} for track (253.3); the PD law on the same seeds: 317.3, 210.9, 203.6. The
#: shipped hard drone policies (models/*_quadrotor_load_hard_ppo) are residuals on this controller:
#: a change here changes what they do.
HOOK_GEOMETRIC_GAINS = {"stabilize": (4.0, 6.0, 8.0, 4.0, np.inf), "transport": (6.0, 6.0, 12.0, 6.0, np.inf),
                        "track": (4.0, 6.0, 12.0, 6.0, np.inf)}
#: The hook's load estimate (agents/baselines/load_estimate.py LoadEstimator's noise and slack pull).
HOOK_ESTIMATOR = {"position_std": 0.05, "acceleration_std": 1.0, "drift_std": 1.0, "taut_fraction": 0.3}


def hook_geometric_controller(task: str, actuation: str = "thrust_rates") -> GeometricLoadController:
    """The load-led cascade's law with ``task``'s gains on the hook observation
    (:data:`HOOK_GEOMETRIC_GAINS`; stabilize's for other tasks)."""
    return GeometricLoadController(*HOOK_GEOMETRIC_GAINS.get(task, HOOK_GEOMETRIC_GAINS["stabilize"]))


def geometric_controller(task: str, actuation: str = "thrust_rates") -> GeometricLoadController:
    """The load-led cascade with ``task``'s gains in ``actuation`` (:data:`GEOMETRIC_GAINS`, with
    :data:`MOTORS_GAINS` for ``motors``; stabilize's for other tasks)."""
    table = {**GEOMETRIC_GAINS, **MOTORS_GAINS} if actuation == "motors" else GEOMETRIC_GAINS
    return GeometricLoadController(*table.get(task, GEOMETRIC_GAINS["stabilize"]))

