"""Deterministic evaluation of a policy on seeded episodes of ElasticStringPendulum-v0.

    python -m agents.evaluate --policy {zero,baseline,PATH} --task stabilize --episodes 50 --seed 0

prints one JSON line: mean_return, std_return, success_rate, mean_final_swing_deg (the swing
measure: the load's swing angle at the episode's end, degrees), mean_swing_deg (over all steps),
episodes, task, policy. Episode i uses seed ``seed + i``. A PATH is an SB3 model (.zip) saved
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
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np

import esp_gym
from agents.artifacts import ModelFileError, load_model, stats_path_for
from agents.cli import ArgumentParser
from agents.controllers import ZeroPolicy, baseline
from agents.normalization import NormalizationFileError, NormStats
from esp_gym.tasks import TASKS

SUCCESS_DISTANCE = 0.1  #: [m]
SUCCESS_SWING_DEG = 5.0


class SB3Policy:
    """A saved SB3 model, deterministic, with the normalisation statistics that belong to it
    (agents.artifacts.stats_path_for: ``vecnormalize.npz``, or a legacy ``vecnormalize.pkl`` read
    as data, beside the model; ``model_vecnormalize_N_steps.*`` beside a checkpoint).
    Loading the model itself runs code from its archive: load only models you trust."""

    def __init__(self, path: str | Path):
        path = Path(path)
        self.model = load_model(path)
        stats = stats_path_for(path)
        #: agents.normalization.NormStats, or None when the model has no statistics beside it
        self.normalization = NormStats.load(stats) if stats else None
        expected = self.model.observation_space.shape
        if self.normalization is not None and self.normalization.obs_mean.shape != expected:
            raise NormalizationFileError(f"{stats}: statistics of observations of shape "
                                         f"{self.normalization.obs_mean.shape}, the model takes {expected}")

    def act(self, obs, setup):
        if self.normalization is not None:
            obs = self.normalization.normalize_obs(obs)
        action, _ = self.model.predict(np.asarray(obs, dtype=np.float32), deterministic=True)
        return action


#: The policies --policy names (anything else is the path of a model .zip).
POLICY_NAMES = ("zero", "baseline")


def load_policy(spec: str):
    """``zero``, ``baseline`` (None: resolved per task by :func:`evaluate_policy`) or an
    :class:`SB3Policy` from a model file; anything else raises ModelFileError naming it."""
    if spec == "zero":
        return ZeroPolicy()
    if spec == "baseline":
        return None
    if not Path(spec).exists():
        raise ModelFileError(f"{spec!r} is not one of {', '.join(POLICY_NAMES)} nor an existing model file")
    return SB3Policy(spec)


def evaluate_policy(policy, task: str = "stabilize", episodes: int = 50, seed: int = 0,
                    record: Optional[str] = None, env_kwargs: Optional[dict] = None) -> dict:
    """Run ``episodes`` seeded episodes (seed + i) and return the statistics; ``record``: a
    ``.rrd`` path for a Rerun recording of the first episode."""
    if policy is None:
        policy = baseline(task)
    returns, finals, swings, successes = [], [], [], []
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
        total, swing_sum, steps = 0.0, 0.0, 0
        terminated = truncated = False
        while not (terminated or truncated):
            obs, r, terminated, truncated, info = env.step(policy.act(obs, u.setup))
            total += r
            swing_sum += u.swing_angle()
            steps += 1
        final_swing = math.degrees(u.swing_angle())
        dist = float(np.linalg.norm(u.load_position() - u.target[3:]))
        returns.append(total)
        finals.append(final_swing)
        swings.append(math.degrees(swing_sum / steps))
        successes.append(bool(truncated and not terminated and dist < SUCCESS_DISTANCE and final_swing < SUCCESS_SWING_DEG))
        if recording:
            env.close()
    return {
        "mean_return": float(np.mean(returns)), "std_return": float(np.std(returns)),
        "success_rate": float(np.mean(successes)), "mean_final_swing_deg": float(np.mean(finals)),
        "mean_swing_deg": float(np.mean(swings)), "episodes": episodes, "task": task,
    }


def main(argv=None) -> dict:
    ap = ArgumentParser(prog="python -m agents.evaluate", description=__doc__.split("\n\n")[0])
    ap.add_argument("--policy", default="baseline", help="zero, baseline or the path of a model .zip")
    ap.add_episode_options(TASKS, episodes=50)
    ap.add_argument("--record", metavar="FILE.rrd", default=None,
                    help="write a Rerun recording of the first episode to FILE.rrd")
    args = ap.parse_args(argv)
    ap.check_parent_dir("--record", args.record)
    try:
        policy = load_policy(args.policy)
    except ValueError as err:  # ModelFileError, NormalizationFileError
        ap.error(f"argument --policy: {err}")
    stats = evaluate_policy(policy, task=args.task, episodes=args.episodes, seed=args.seed, record=args.record)
    stats["policy"] = args.policy
    print(json.dumps(stats))
    return stats


if __name__ == "__main__":
    main()
