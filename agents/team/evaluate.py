"""Episodes of a team (esp_gym/team/env.py, ``ElasticStringTeam-v0``) under a centralised policy,
measured as agents/evaluate.py measures one string's: return, success, the load's final and mean
tilt (its ``swing``), settling time and the peak of the strings' pull on their pivots.

Policies act on the centralised observation: ``zero`` (hover), ``lqr`` (the team's LQR,
agents/baselines/team/lqr.py) and with the hook observation ``lqg`` (agents/baselines/team/lqg.py)
are the baselines of point pivots, ``cascade`` and with the hook observation ``cascade_lqg``
(agents/baselines/team/cascade.py) the drones' (:func:`team_baselines`).
"""
from __future__ import annotations

import math

import numpy as np

from agents.evaluate import ONE_BLAS_THREAD, SUCCESS_DISTANCE, SUCCESS_SWING_DEG, EpisodeResult
from esp_gym import MAX_EPISODE_STEPS
from esp_gym.team.env import ElasticStringTeamEnv


class TeamZero:
    """Every pivot hovers."""

    def act(self, obs, core):
        return np.zeros(core.action_size * core.size)


def nominal_core(core, **options):
    """The nominal team of ``core``'s size, task, control period, force limit and actuation (with
    ``options``), at its first episode of seed 0: where the baselines are designed."""
    from esp_gym.team.core import TeamCore

    nominal = TeamCore(core.size, core.task.name, control_period=core.control_period, force_limit=core.force_limit,
                       actuation=core.actuation, **options)
    nominal.reset(seed=0)
    return nominal


class DesignedPolicy:
    """A team baseline designed (:meth:`build`) the first time it acts, on the nominal team of the
    env's size, task, control period and actuation; reset at each episode's first step. With
    ``true_state`` it reads the true state whatever the observation
    (:meth:`~esp_gym.team.core.TeamCore.true_observations` in the ``hook`` mode: no estimator, an
    optimistic reference)."""

    true_state = False

    def __init__(self):
        self.design = None

    def build(self, core):
        raise NotImplementedError

    def act(self, obs, core):
        if self.design is None:
            self.design = self.build(core)
        if core.steps == 0:
            self.design.reset()
        if self.true_state and core.observation != "full":
            obs = core.true_observations().ravel()
        return self.design.act(obs, core)


class TeamLQRPolicy(DesignedPolicy):
    """The team's LQR (agents/baselines/team/lqr.py) with the env's action latency, reading the
    true state."""

    true_state = True

    def build(self, core):
        from agents.baselines.team.lqr import TeamLQR

        return TeamLQR.design(nominal_core(core), latency=core.action_latency)


class TeamLQGPolicy(DesignedPolicy):
    """The team's LQG (agents/baselines/team/lqg.py) for the env's observation mode, sensor noise
    and latency."""

    def build(self, core):
        from agents.baselines.team.lqg import TeamLQG

        nominal = nominal_core(core, observation=core.observation, sensor_noise=core.sensor_noise)
        return TeamLQG.design(nominal, latency=core.action_latency)


class TeamCascadePolicy(DesignedPolicy):
    """A drone team's cascade (agents/baselines/team/cascade.py) with the env's action latency,
    reading the true state."""

    true_state = True

    def build(self, core):
        from agents.baselines.team.cascade import TeamCascade

        return TeamCascade.design(nominal_core(core, action_latency=core.action_latency))


class TeamCascadeLQGPolicy(DesignedPolicy):
    """A drone team's cascade on a Kalman filter's estimate (agents/baselines/team/cascade.py
    ``TeamCascadeLQG``) for the env's observation mode, sensor noise and latency."""

    def build(self, core):
        from agents.baselines.team.cascade import TeamCascadeLQG

        return TeamCascadeLQG.design(nominal_core(core, observation=core.observation, sensor_noise=core.sensor_noise,
                                                  action_latency=core.action_latency))


class TeamHoistPolicy(DesignedPolicy):
    """A lift's baseline (agents/baselines/team/hoist.py): the team's LQR on the pivots (``lqg``:
    its LQG for the env's observation, noise and latency) and a reel law on each winch. The base
    is designed about the load hanging in formation (on the nominal ``transport`` team with
    winches, whose targets hang): the lift's target is above it, where the strings' scene lengths
    do not reach."""

    def __init__(self, base: str = "lqr", true_state: bool = False):
        super().__init__()
        self.base, self.true_state = base, true_state

    def build(self, core):
        from agents.baselines.team.hoist import TeamHoist
        from agents.baselines.team.lqg import TeamLQG
        from agents.baselines.team.lqr import TeamLQR
        from esp_gym.team.core import TeamCore

        options = dict(observation=core.observation, sensor_noise=core.sensor_noise) if self.base == "lqg" else {}
        nominal = TeamCore(core.size, "transport", control_period=core.control_period, force_limit=core.force_limit,
                           winch=True, **options)
        nominal.reset(seed=0)
        design = (TeamLQG if self.base == "lqg" else TeamLQR).design(nominal, latency=core.action_latency)
        return TeamHoist.design(design, nominal)


def team_baselines(observation: str = "full", drones: bool = False, winch: bool = False) -> dict:
    """The team's classical baselines by name for an observation mode: the LQR with the ``full``
    observation; with the ``hook`` one the LQG, and the LQR reading the true state as
    ``lqr_true_state`` (a reference, not a baseline a policy is compared with: it reads what the
    agents do not see). A drone team's (``drones``): the cascade with the ``full`` observation; with
    the ``hook`` one the cascade on its filter's estimate, and the cascade reading the true state
    as ``cascade_true_state``. With winches (``lift``): the hoist on the LQR (``full``), on the LQG
    (``hook``, with ``hoist_true_state`` its reference)."""
    if winch:
        if observation == "full":
            return {"hoist": TeamHoistPolicy()}
        return {"hoist_lqg": TeamHoistPolicy("lqg"), "hoist_true_state": TeamHoistPolicy(true_state=True)}
    if drones:
        if observation == "full":
            return {"cascade": TeamCascadePolicy()}
        return {"cascade_lqg": TeamCascadeLQGPolicy(), "cascade_true_state": TeamCascadePolicy()}
    if observation == "full":
        return {"lqr": TeamLQRPolicy()}
    return {"lqg": TeamLQGPolicy(), "lqr_true_state": TeamLQRPolicy()}


def load_tilt(core) -> float:
    """The load's tilt from its hanging attitude (R = I) [rad]."""
    R = core.sim.state.lead.R
    return math.acos(min(1.0, max(-1.0, float(R[2, 2]))))


@ONE_BLAS_THREAD
def run_team_episodes(policy, team: int = 3, task: str = "transport", episodes: int = 10, seed: int = 0,
                      env_kwargs=None) -> list:
    """``episodes`` seeded episodes (seed + i) of ``policy`` on a team of ``team`` strings:
    :class:`~agents.evaluate.EpisodeResult` each."""
    env = ElasticStringTeamEnv(team, task=task, **(env_kwargs or {}))
    core = env.core
    out = []
    for i in range(episodes):
        obs, _ = env.reset(seed=seed + i)
        total, tilt_sum, steps, settled_at, peak = 0.0, 0.0, 0, 0, 0.0
        terminated = truncated = False
        while not (terminated or truncated):
            obs, r, terminated, _, info = env.step(policy.act(obs, core))
            truncated = core.steps >= MAX_EPISODE_STEPS
            total += r
            tilt = load_tilt(core)
            tilt_sum += tilt
            steps += 1
            peak = max(peak, float(np.linalg.norm(info["tension"], axis=1).max()))
            near = (np.linalg.norm(core.load_position() - core.load_target) < SUCCESS_DISTANCE
                    and math.degrees(tilt) < SUCCESS_SWING_DEG)
            if not near:
                settled_at = steps
        final = math.degrees(load_tilt(core))
        dist = float(np.linalg.norm(core.load_position() - core.load_target))
        success = bool(not terminated and dist < SUCCESS_DISTANCE and final < SUCCESS_SWING_DEG)
        if terminated:
            settled_at = MAX_EPISODE_STEPS
        out.append(EpisodeResult(seed + i, total, success, final, math.degrees(tilt_sum / steps),
                                 settled_at * core.control_period, peak))
    return out


def main(argv=None):
    """``python -m agents.team.evaluate``: a library, not a command. One line names the command
    that evaluates a team (agents.compare --team runs these episodes for the baselines and a
    checkpoint), with exit code 2, a usage error (it printed nothing and exited 0)."""
    import sys

    print("python -m agents.team.evaluate: error: a library module, not a command: evaluate a team with "
          "python -m agents.compare --team K [--model CHECKPOINT]", file=sys.stderr)
    raise SystemExit(2)


if __name__ == "__main__":
    main()
