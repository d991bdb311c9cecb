"""``ElasticStringTeam-v0``, a team's centralised Gymnasium environment (docs/team.md): the
agents' actions and observations concatenated, over the episode of :class:`~esp_gym.team.core.TeamCore`
(PettingZoo's face of the same episode is esp_gym/team/parallel.py).
"""
from __future__ import annotations

from typing import Optional

import gymnasium as gym
import numpy as np

from ..pendulum.control import raw_actions
from .core import TeamCore


class ElasticStringTeamEnv(gym.Env):
    """
    ## Description
    K point pivots (crane hooks, or drones flown as points) or K quadrotors carry one rigid load,
    each on its own extensible, tension-only elastic string, for single-agent learners: one
    policy acts for the whole team. The physics is the single environment's variational
    integrator, every string reduced to its end on the load (docs/physics.md, "A team: several
    strings on one body"). The default team (``team=K``): K free 1 kg pivots on a circle of 0.6 m
    radius, each holding a 1 m, 50 g/m, EA = 200 N string to a 1 kg box, hanging at rest. Gravity
    acts along **+z**.

    ## Action Space
    ``Box(-1, 1, (3K,), float32)``, values outside clipped: agent k's pivot force (spatial) at
    3k..3k+2, on top of its hover force (its share of the rig's weight), ``force_limit`` times
    that share at 1. With drones (``actuation``) ``Box(-1, 1, (4K,))``: each drone's four numbers
    as the single drone's environment reads them, 0 hovering (esp_gym/team/spaces.py
    ``DroneDrive``). With ``winch=True`` each agent's slice ends with its string's reel speed, times
    its ``winch.max_speed`` [m/s] (> 0 pays out).

    ## Observation Space
    ``Box(-inf, inf, (K n,), float32)``: the agents' observations one after the other,
    ``observation_structure`` naming ``pivot_k/<field>``. Agent k's n fields
    (esp_gym/team/spaces.py ``agent_layout``; spatial frame, SI units): ``pivot_position_error``,
    ``pivot_velocity``, with drones ``drone_attitude_6d`` and ``drone_rates``, ``hook_tension``
    (its string's pull on its pivot), with a winch ``string_length``; in the ``full`` mode
    ``load_offset`` (the load's centre of mass less its pivot), ``load_position_error``,
    ``load_velocity``, ``load_attitude_6d`` and ``load_rates``, in the ``hook`` mode
    ``load_target_offset`` alone; then ``neighbours``, the other pivots less its own (the next
    one first). n = 27 + 3(K - 1) in the ``full`` mode, 12 + 3(K - 1) in the ``hook`` mode, 9
    more with drones, 1 more with a winch. ``sensor_noise`` adds Gaussian noise, times
    ``TEAM_UNIT_NOISE`` per field, drawn from ``np_random``.

    ## Rewards
    The team's reward, the sum of ``info["reward_<term>"]`` over esp_gym/team/tasks.py's
    ``REWARD_TERMS``, with tol(x, s) = 1 / (1 + (x/s)^2): ``load_position`` = w_lp tol(|load
    error|, 0.2 m), ``load_velocity`` = w_lv tol(|load velocity - target velocity|, 0.5 m/s),
    ``tilt`` = w_t tol(the body z axis's angle from the vertical, 0.2 rad), ``spin`` = w_s
    tol(|Omega|, 1 rad/s), and the agents' sums of ``pivot_position`` (each w_pp tol(|pivot
    error|, 0.2 m) / K), ``control`` (each -w_c |a_k|^2 / (its action size x K)) and ``separation``
    (each pivot's half of -w_sep max(0, 1 - d/0.4 m)^2 over its pairs); ``info["agent_<term>"]``
    holds each agent's share of those three. Weights (``TEAM_TASKS``): w_lp, w_lv, w_pp, w_t, w_s
    0.45, 0.1, 0.2, 0.2, 0.05 (``transport``, ``lift``), 0.35, 0.2, 0.2, 0.15, 0.1
    (``stabilize``), 0.5, 0.15, 0.15, 0.15, 0.05 (``track``); w_c 0.1 and w_sep 0.5. A step that
    ends in a physics failure is rewarded 0.

    ## Starting State
    The team hanging at rest in its formation, then the load's velocity uniform in +-0.05 m/s
    and its body rates in +-0.1 rad/s per axis (``stabilize``: +-0.5 m/s and +-1 rad/s).
    ``stabilize``: the targets are the start. ``transport``: the load's target uniform in
    +-(1, 1, 0.5) m about its start, the pivots' the formation about it. ``track``: the load's
    target moves along a circle or figure-eight drawn as the single environment's ``track``
    draws them, from where the load starts. ``lift`` (a winch on every string): every string's
    target length is the same share, uniform in 55-75 %, of its length, the load's target the
    hanging load's rise, the pivots' where they are. With ``randomize`` the episode's team is
    drawn first; with ``wind`` its azimuth (unless given) and first gust last. ``reset``'s info
    holds ``load_target``, ``pivot_targets`` and those draws.

    ## Episode End
    Terminated, for the whole team, with ``info["termination"]`` (the single environment's codes,
    esp_gym/kernels/status.py) and ``info["termination_reason"]``: ``collision`` (two pivots
    closer than 0.15 m), ``drone_flipped`` (a drone tilted past the horizontal),
    ``string_overstretched`` (a string stretched past 1.5 times its length), ``left_workspace``
    (the load or a pivot more than 4 m from its target), ``energy_balance`` (the energy
    watchdog) and ``physics_failure: ...`` (a failed step; the state is the last good one).
    Truncated by the time limit only, ``esp_gym.MAX_EPISODE_STEPS`` (500 steps, 10 s at 50 Hz).

    ## Arguments
    ``team`` (K, 3 by default, or a ``TeamScene`` whose pivots are all free points or all drones),
    ``task`` (``"transport"``, ``"stabilize"``, ``"track"``, ``"lift"``), ``render_mode``
    (``"rgb_array"``: front and side views) and, as :class:`~esp_gym.team.core.TeamCore` takes and
    checks them, ``control_period`` (0.02 s), ``force_limit`` (0.6), ``preset`` (``"hard"``),
    ``randomize``, ``observation`` (``"full"``, ``"hook"``), ``sensor_noise``,
    ``action_latency``, ``wind``, ``actuation`` (``"force"``, or a drone's ``"thrust_rates"``,
    ``"thrust_torque"``, ``"motors"``), ``winch`` and ``safety``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, team=3, task: str = "transport", render_mode: Optional[str] = None, **options):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.core = TeamCore(team, task, **options)
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.core.control_period}  # a frame per step
        K, n = self.core.size, self.core.layout.size
        self.action_space = gym.spaces.Box(-1.0, 1.0, (self.core.action_size * K,), np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (K * n,), np.float32)
        #: name -> slice of the observation: agent k's fields are ``pivot_k/<field>``
        self.observation_structure = {f"pivot_{k}/{name}": slice(k * n + s.start, k * n + s.stop)
                                      for k in range(K) for name, s in self.core.layout.structure().items()}

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        self.core.np_random = self.np_random
        obs, info = self.core.reset()
        return obs.ravel(), info

    def step(self, action):
        a = raw_actions(action, self.action_space.shape)
        obs, reward, terminated, truncated, info = self.core.step_raw(a.reshape(self.core.size, self.core.action_size))
        return obs.ravel(), reward, terminated, truncated, info

    def render(self):
        """The frame of :meth:`TeamCore.frame` with ``render_mode="rgb_array"``, else None."""
        return self.core.frame() if self.render_mode == "rgb_array" else None
