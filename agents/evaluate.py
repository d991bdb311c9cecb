"""Deterministic evaluation of a policy on seeded episodes of ElasticStringPendulum-v0.

    python -m agents.evaluate --policy {zero,baseline,pd,lqr,lqr_zv,lqg,PATH} --task stabilize [--preset hard] --episodes 50 --seed 0

prints one JSON line: mean_return, std_return, success_rate, mean_final_swing_deg (the swing
measure: the load's swing angle at the episode's end, degrees), mean_swing_deg (over all steps),
mean_settling_time_s, mean_peak_tension_N (see EpisodeResult), episodes, task, preset, policy.
Episode i uses seed ``seed + i``. A PATH is an SB3 model (.zip) saved
by ``python -m agents.train``; the normalisation statistics beside it (vecnormalize.npz, or a
legacy vecnormalize.pkl read as data) are applied. Loading a model runs code from its archive:
evaluate only models you trust (docs/agents.md).

Success: the episode runs to the time limit and ends with the load within 0.1 m of its target
and swinging less than 5 degrees.

``--record FILE.rrd`` also writes a Rerun recording of the first episode (esp_gym.viz.recording:
the 3-D scene, energy and momentum diagnostics, reward terms and actions); the statistics are
the same with or without it.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np
from threadpoolctl import threadpool_limits

import esp_gym
from agents.artifacts import (ConfigurationError, ModelFileError, check_configuration, load_model, model_configuration,
                              stats_path_for)
from agents.cli import ArgumentParser
from agents.mlp import UnsupportedNetwork, actor_of_sb3
from agents.baselines.pd import ZeroPolicy
from agents.baselines.registry import baseline
from agents.normalization import NormalizationFileError, NormStats
from agents.residual import base_features, residual_for
from esp_gym.layouts import SENSORS
from esp_gym.pendulum.env_setup import make_setup
from esp_gym.pendulum.tasks import TASKS

SUCCESS_DISTANCE = 0.1  #: [m]
SUCCESS_SWING_DEG = 5.0
#: Episodes run with BLAS on one thread: a matrix product's sums (the LQR's and LQG's) then come in
#: the same order on any number of cores. OpenBLAS splits a product among its threads by size and
#: count, and a chaotic closed-loop episode grows a last-bit difference into another return, so the
#: documented comparisons (docs/compare) hold on any machine only so.
ONE_BLAS_THREAD = threadpool_limits.wrap(limits=1, user_api="blas")


#: What loading a model or checking it against a configuration raises (each a ValueError): the
#: model's faults, where an error inside an episode is not.
MODEL_ERRORS = (ModelFileError, NormalizationFileError, ConfigurationError, UnsupportedNetwork)


class SB3Policy:
    """A saved SB3 model, deterministic, with the normalisation statistics that belong to it
    (agents.artifacts.stats_path_for: ``vecnormalize.npz``, or a legacy ``vecnormalize.pkl`` read
    as data, beside the model; ``model_vecnormalize_N_steps.*`` beside a checkpoint).
    Loading the model itself runs code from its archive: load only models you trust."""

    def __init__(self, path: str | Path):
        path = Path(path)
        self.model = load_model(path)
        #: the network's deterministic action in float64, the same on every processor (agents/mlp.py)
        self.actor = actor_of_sb3(self.model)
        stats = stats_path_for(path)
        #: agents.normalization.NormStats, or None when the model has no statistics beside it
        self.normalization = NormStats.load(stats) if stats else None
        expected = self.model.observation_space.shape
        self.input_size = expected[-1]
        if self.normalization is not None:
            size = self.normalization.obs_mean.shape
            if len(size) != 1 or len(expected) != 1 or expected[0] % size[0]:
                raise NormalizationFileError(f"{stats}: statistics of observations of shape {size}, the model "
                                             f"takes {expected} (a stack of whole observations)")
        self._stack = None
        #: the baseline the network's action is added to (agents/residual.py), or None
        self.residual = residual_for(path)
        self.path = path
        #: the task and environment options it was trained with (agents.artifacts.model_configuration), or None
        self.configuration = model_configuration(path)
        self._checked = set()

    def check(self, task: str, env_kwargs: Optional[dict] = None) -> None:
        """Before running on ``task`` with ``env_kwargs``: ConfigurationError where the model's
        observations or actions do not fit them, a warning where only its configuration differs
        (agents.artifacts.check_configuration)."""
        key = (task, repr(sorted((env_kwargs or {}).items())))
        if key not in self._checked:  # once per configuration (compare checks before its episodes)
            check_configuration(self.path, self.configuration, task, env_kwargs)
            self._checked.add(key)

    def reset(self, env=None) -> None:
        """Start an episode: a frame-stacked model's earlier observations are zeros again, a
        stateful base (agents/residual.py) starts a new estimate."""
        self._stack = None
        if self.residual is not None and hasattr(self.residual, "reset"):
            self.residual.reset(env)

    def act(self, obs, setup):
        raw = obs
        if self.residual is not None:  # a stateful base filters the observation; the network sees its estimate
            base = self.residual.act(raw, setup)
            obs = np.concatenate([np.asarray(obs, dtype=np.float64), base_features(self.residual, np.shape(obs)[:-1])],
                                 axis=-1)
        hidden = getattr(self.model.policy, "frame_size", 0) - getattr(self.model.policy, "actor_size", 0)
        if hidden:  # the critic's privileged entries (agents/privileged.py): the actor never reads them
            obs = np.concatenate([np.asarray(obs, dtype=np.float64), np.zeros(np.shape(obs)[:-1] + (hidden,))], axis=-1)
        if self.normalization is not None:
            obs = self.normalization.normalize_obs(obs)
        obs = np.asarray(obs, dtype=np.float32)
        n = obs.shape[-1]
        if n != self.input_size:  # trained on the last k observations (RunConfig.frame_stack)
            if self.input_size % n:
                raise ValueError(f"the model takes {self.input_size} inputs, not a stack of observations of size {n}")
            if self._stack is None or self._stack.shape[:-1] != obs.shape[:-1]:
                self._stack = np.zeros(obs.shape[:-1] + (self.input_size,), dtype=np.float32)
            self._stack[..., :-n] = self._stack[..., n:]  # as SB3 VecFrameStack: oldest first, zeros at the start
            self._stack[..., -n:] = obs
            obs = self._stack
        space = self.model.action_space
        action = np.clip(self.actor(obs), space.low, space.high)
        if self.residual is not None:
            action = np.clip(action + base, -1.0, 1.0)
            if hasattr(self.residual, "applied"):
                self.residual.applied(action)
        return action


#: The policies --policy names besides the baselines of agents.baselines.registry.baselines (anything
#: else is the path of a model .zip).
POLICY_NAMES = ("zero", "baseline")


def load_policy(spec: str, task: str = "stabilize", env_kwargs: Optional[dict] = None):
    """``zero``, ``baseline`` (None: the task's PD law, resolved by :func:`evaluate_policy`), a
    baseline's name for ``task`` and the options ``env_kwargs`` (``pd``, ``lqr``, ``lqr_zv``,
    ``lqg``: agents.baselines.registry.baselines) or an :class:`SB3Policy` from a model file; anything
    else raises ModelFileError naming the choices."""
    if spec == "zero":
        return ZeroPolicy()
    if spec == "baseline":
        return None
    if not Path(spec).exists():
        from agents.baselines.registry import baseline_factories

        known = baseline_factories(task, env_kwargs)
        if spec in known:
            return known[spec]()
        raise ModelFileError(f"{spec!r} is not one of {', '.join(POLICY_NAMES + tuple(known))} (for task {task!r}) "
                             f"nor an existing model file")
    return SB3Policy(spec)


@dataclass(frozen=True)
class EpisodeResult:
    """One evaluated episode: return, success, final and mean swing [deg], settling time [s]
    (from when the load stays within SUCCESS_DISTANCE of its target swinging less than
    SUCCESS_SWING_DEG to the end; the episode's length if it never does, the time limit if it
    ends early) and the peak of the
    string's pull on the pivot [N] (the true hook tension, noiseless)."""

    seed: int
    ret: float
    success: bool
    final_swing_deg: float
    mean_swing_deg: float
    settling_time_s: float
    peak_tension_N: float


@ONE_BLAS_THREAD
def run_episodes(policy, task: str = "stabilize", episodes: int = 50, seed: int = 0,
                 record: Optional[str] = None, env_kwargs: Optional[dict] = None) -> list:
    """Run ``episodes`` seeded episodes (seed + i) of ``policy`` (None: the task's PD baseline)
    and return their :class:`EpisodeResult`; ``record``: a ``.rrd`` path for a Rerun recording
    of the first episode. A policy with ``reset(env)`` is reset after each env reset."""
    if policy is None:
        setup = make_setup(task=task, **(env_kwargs or {}))
        policy = baseline(task, setup.winch, setup.drone)
    if isinstance(policy, SB3Policy):
        policy.check(task, env_kwargs)
    out = []
    for i in range(episodes):
        env = gym.make(esp_gym.ENV_ID, task=task, **(env_kwargs or {}))
        recording = bool(record) and i == 0
        if recording:
            from esp_gym.viz.recording import RecordRerun

            env = RecordRerun(env, record)
        u = env.unwrapped
        obs, _ = env.reset(seed=seed + i)
        if hasattr(policy, "reset"):  # a controller that reads the episode (e.g. its reference)
            policy.reset(u)
        total, swing_sum, steps, settled_at, peak = 0.0, 0.0, 0, 0, 0.0
        terminated = truncated = False
        while not (terminated or truncated):
            obs, r, terminated, truncated, info = env.step(policy.act(obs, u.setup))
            total += r
            swing = u.swing_angle()
            swing_sum += swing
            steps += 1
            peak = max(peak, float(np.linalg.norm(u.control.sensors[SENSORS["hook_tension"]])))
            near = (np.linalg.norm(u.load_position() - u.target[3:]) < SUCCESS_DISTANCE
                    and math.degrees(swing) < SUCCESS_SWING_DEG)
            if not near:
                settled_at = steps
        final_swing = math.degrees(u.swing_angle())
        dist = float(np.linalg.norm(u.load_position() - u.target[3:]))
        success = bool(truncated and not terminated and dist < SUCCESS_DISTANCE and final_swing < SUCCESS_SWING_DEG)
        if terminated:  # ended early (workspace, overstretch): it never settled
            settled_at = max(steps, env.spec.max_episode_steps or steps)
        out.append(EpisodeResult(seed + i, total, success, final_swing, math.degrees(swing_sum / steps),
                                 settled_at * u.setup.control_period, peak))
        if recording:
            env.close()
    return out


def summarize(results: list, task: str) -> dict:
    """Means (and the return's standard deviation) over episodes of :func:`run_episodes`."""
    def mean(name):
        return float(np.mean([getattr(r, name) for r in results]))

    return {
        "mean_return": mean("ret"), "std_return": float(np.std([r.ret for r in results])),
        "success_rate": mean("success"), "mean_final_swing_deg": mean("final_swing_deg"),
        "mean_swing_deg": mean("mean_swing_deg"), "mean_settling_time_s": mean("settling_time_s"),
        "mean_peak_tension_N": mean("peak_tension_N"), "episodes": len(results), "task": task,
    }


def evaluate_policy(policy, task: str = "stabilize", episodes: int = 50, seed: int = 0,
                    record: Optional[str] = None, env_kwargs: Optional[dict] = None) -> dict:
    """:func:`run_episodes`, summarised (:func:`summarize`)."""
    return summarize(run_episodes(policy, task, episodes, seed, record, env_kwargs), task)


def main(argv=None) -> dict:
    ap = ArgumentParser(prog="python -m agents.evaluate", description=__doc__.split("\n\n")[0])
    ap.add_argument("--policy", default="baseline",
                    help="zero, baseline (the PD law), a baseline's name (pd, lqr, lqr_zv, lqg: as the observation "
                         "allows) or the path of a model .zip")
    ap.add_episode_options(TASKS, episodes=50, preset=True)
    ap.add_argument("--record", metavar="FILE.rrd", default=None,
                    help="write a Rerun recording of the first episode to FILE.rrd")
    ap.add_scene_options()
    args = ap.parse_args(argv)
    ap.check_new_file("--record", args.record)
    env_kwargs = ap.environment_options(args)
    try:
        policy = load_policy(args.policy, args.task, env_kwargs)
    except ValueError as err:  # ModelFileError, NormalizationFileError
        ap.error(f"argument --policy: {err}")
    try:
        stats = evaluate_policy(policy, task=args.task, episodes=args.episodes, seed=args.seed, record=args.record,
                                env_kwargs=env_kwargs)
    except ConfigurationError as err:  # raised before the first episode
        ap.error(f"argument --policy: {err}")
    stats["preset"] = args.preset
    stats["policy"] = args.policy
    stats.update({name: env_kwargs[name] for name in ("scene", "actuation") if name in env_kwargs})
    print(json.dumps(stats))
    return stats


if __name__ == "__main__":
    main()
