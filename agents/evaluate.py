"""Deterministic evaluation of a policy on seeded episodes of ElasticStringPendulum-v0.

    python -m agents.evaluate --policy {zero,baseline,PATH} --task stabilize --episodes 50 --seed 0

prints one JSON line: mean_return, std_return, success_rate, mean_final_swing_deg (the swing
measure: the load's swing angle at the episode's end, degrees), mean_swing_deg (over all steps),
episodes, task, policy. Episode i uses seed ``seed + i``. A PATH is an SB3 model (.zip) saved
by ``python -m agents.train``; its VecNormalize statistics (vecnormalize.pkl beside it) are applied.

Success: the episode runs to the time limit and ends with the load within 0.1 m of its target
and swinging less than 5 degrees.

``--record FILE.rrd`` also writes a Rerun recording of the first episode (esp_gym.viz.recording:
the 3-D scene, energy and momentum diagnostics, reward terms and actions); the statistics are
the same with or without it.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np

import esp_gym
from agents.controllers import ZeroPolicy, baseline
from esp_gym.tasks import TASKS

SUCCESS_DISTANCE = 0.1  #: [m]
SUCCESS_SWING_DEG = 5.0


class SB3Policy:
    """A saved SB3 model (+ optional VecNormalize observation statistics), deterministic."""

    def __init__(self, path: str | Path):
        from stable_baselines3 import PPO, SAC

        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no model at {path}")
        args = path.parent / "args.json"  # written by train.py beside the model
        algo = json.loads(args.read_text()).get("algo") if args.is_file() else None
        candidates = [{"ppo": PPO, "sac": SAC}[algo]] if algo in ("ppo", "sac") else [PPO, SAC]
        self.model = None
        for cls in candidates:
            try:
                self.model = cls.load(path, device="cpu")
                break
            except (ValueError, KeyError, RuntimeError, TypeError):  # not this algorithm's file
                continue
        if self.model is None:
            raise ValueError(f"{path} is not a PPO or SAC model")
        self.obs_rms = None
        stats = path.parent / "vecnormalize.pkl"
        if stats.is_file():
            import pickle

            with open(stats, "rb") as fh:
                vn = pickle.load(fh)
            self.obs_rms, self.clip_obs, self.epsilon = vn.obs_rms, vn.clip_obs, vn.epsilon

    def act(self, obs, setup):
        obs = np.asarray(obs, dtype=np.float32)
        if self.obs_rms is not None:
            obs = np.clip((obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon),
                          -self.clip_obs, self.clip_obs).astype(np.float32)
        action, _ = self.model.predict(obs, deterministic=True)
        return action


def load_policy(spec: str):
    if spec == "zero":
        return ZeroPolicy()
    if spec.startswith("baseline"):
        return None  # resolved per task
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
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--policy", default="baseline", help="zero, baseline or the path of a model .zip")
    ap.add_argument("--task", default="stabilize", choices=sorted(TASKS))
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0, help="episode i uses seed + i")
    ap.add_argument("--record", metavar="FILE.rrd", default=None,
                    help="write a Rerun recording of the first episode to FILE.rrd")
    args = ap.parse_args(argv)
    if args.episodes < 1:
        ap.error("--episodes must be >= 1")
    stats = evaluate_policy(load_policy(args.policy), task=args.task, episodes=args.episodes, seed=args.seed,
                            record=args.record)
    stats["policy"] = args.policy
    print(json.dumps(stats))
    return stats


if __name__ == "__main__":
    main()
