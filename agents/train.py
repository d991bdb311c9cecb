"""Train a Stable-Baselines3 agent (PPO or SAC) on ElasticStringPendulum-v0.

    python -m agents.train --algo ppo --task stabilize --seed 0
    python -m agents.train --algo ppo --task stabilize --set total_timesteps=200000 n_envs=8
    python -m agents.train --resume runs/RUN/checkpoints/model_100000_steps.zip

Hyper-parameters come from configs/agents/{ppo,sac}.yaml keyed by env id and task; ``--set``
overrides them (validated: unknown keys are errors). The batched SB3 VecEnv of esp_gym steps all
training environments in one compiled call; VecNormalize normalises observations (and rewards
where the config says so). A run directory ``runs/{env}__{algo}__{task}__{seed}__{time}`` receives
model.zip, vecnormalize.pkl, config.yaml (resolved), args.json, command.txt, monitor.csv,
evaluations.npz (EvalCallback), checkpoints/ and learning_curve.png.
"""
from __future__ import annotations

import dataclasses
import json
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import yaml

import esp_gym
from agents.common import (ROOT, TqdmCallback, json_default, load_run_config, parse_settings, plot_learning_curve,
                           resolve_schedules)
from agents.controllers import ZeroPolicy
from agents.evaluate import evaluate_policy
from esp_gym.tasks import TASKS


@dataclass
class Settings:
    algo: str = field(default="ppo", metadata={"help": "algorithm", "choices": ["ppo", "sac"]})
    task: str = field(default="stabilize", metadata={"help": "task", "choices": sorted(TASKS)})
    seed: int = field(default=0, metadata={"help": "seed of the agent and of the environments (seed + i)", "type": int})
    set: list = field(default_factory=list, metadata={"help": "hyper-parameter overrides KEY=VALUE (YAML values)", "nargs": "*"})
    runs: str = field(default=str(ROOT / "runs"), metadata={"help": "where run directories go"})
    run_name: Optional[str] = field(default=None, metadata={"help": "run directory name (default: generated)"})
    eval_freq: int = field(default=50_000, metadata={"help": "environment steps between evaluations", "type": int})
    eval_episodes: int = field(default=10, metadata={"help": "episodes per evaluation", "type": int})
    checkpoint_freq: int = field(default=500_000, metadata={"help": "environment steps between checkpoints", "type": int})
    resume: Optional[str] = field(default=None, metadata={"help": "checkpoint .zip to resume from (its run directory is reused)"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    threads: int = field(default=1, metadata={"help": "torch threads (the physics uses the other core)", "type": int})
    reference_episodes: int = field(default=10, metadata={"help": "episodes for the zero/baseline reference returns drawn on the learning curve", "type": int})


def _make_vec_env(n_envs: int, task: str, seed: int, env_kwargs: dict,
                  max_episode_steps: int = esp_gym.MAX_EPISODE_STEPS):
    from esp_gym.sb3_vector import ElasticStringPendulumSB3VecEnv

    venv = ElasticStringPendulumSB3VecEnv(num_envs=n_envs, task=task, max_episode_steps=max_episode_steps, **env_kwargs)
    venv.seed(seed)
    return venv


def train(s: Settings, argv: Optional[list] = None) -> Path:
    """Run one training; returns the run directory. ``argv``: the command-line arguments
    recorded in command.txt (default: this process's)."""
    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    torch.set_num_threads(max(1, s.threads))
    env_id = esp_gym.ENV_ID
    if s.resume:
        ckpt = Path(s.resume)
        if not ckpt.is_file():
            raise SystemExit(f"--resume: no checkpoint at {ckpt}")
        run_dir = ckpt.parent.parent
        saved = json.loads((run_dir / "args.json").read_text())
        # the run's own settings; extra --set overrides (e.g. a larger total_timesteps) apply on top
        s = dataclasses.replace(s, algo=saved["algo"], task=saved["task"], seed=saved["seed"], set=saved["set"] + s.set)
    cfg = load_run_config(s.algo, env_id, s.task, s.set)
    if not s.resume:
        name = s.run_name or f"{env_id}__{s.algo}__{s.task}__{s.seed}__{time.strftime('%Y%m%d-%H%M%S')}"
        run_dir = Path(s.runs) / name
        run_dir.mkdir(parents=True, exist_ok=False)
        (run_dir / "config.yaml").write_text(yaml.safe_dump(cfg.model_dump(), sort_keys=False))
        (run_dir / "args.json").write_text(json.dumps(dataclasses.asdict(s), indent=2, default=json_default))
        args = sys.argv[1:] if argv is None else list(argv)
        (run_dir / "command.txt").write_text(shlex.join([sys.executable, "-m", "agents.train", *args]) + "\n")
        n_ref = max(1, s.reference_episodes)
        refs = {"baseline_return": evaluate_policy(None, s.task, n_ref, seed=10_000, env_kwargs=cfg.env_kwargs)["mean_return"],
                "zero_return": evaluate_policy(ZeroPolicy(), s.task, n_ref, seed=10_000, env_kwargs=cfg.env_kwargs)["mean_return"]}
        (run_dir / "references.json").write_text(json.dumps(refs))

    venv = VecMonitor(_make_vec_env(cfg.n_envs, s.task, s.seed, cfg.env_kwargs), str(run_dir / "monitor.csv"))
    eval_env = VecMonitor(_make_vec_env(min(4, s.eval_episodes), s.task, s.seed + 10_000, cfg.env_kwargs))
    if cfg.normalize:
        if s.resume:
            stats = sorted(ckpt.parent.glob(f"*vecnormalize_{ckpt.stem.split('_')[-2]}_steps.pkl"))
            if not stats:
                raise SystemExit(f"--resume: no VecNormalize statistics beside {ckpt}")
            venv = VecNormalize.load(str(stats[-1]), venv)
        else:
            venv = VecNormalize(venv, gamma=cfg.algo.get("gamma", 0.99), **cfg.normalize)
        eval_env = VecNormalize(eval_env, training=False, norm_reward=False, clip_obs=cfg.normalize.get("clip_obs", 10.0))
    cls = {"ppo": PPO, "sac": SAC}[s.algo]
    if s.resume:
        model = cls.load(s.resume, env=venv, device="cpu")
    else:
        model = cls(cfg.policy, venv, seed=s.seed, device="cpu", verbose=0, **resolve_schedules(cfg.algo))
    callbacks = CallbackList([
        EvalCallback(eval_env, n_eval_episodes=s.eval_episodes, eval_freq=max(1, s.eval_freq // cfg.n_envs),
                     log_path=str(run_dir), best_model_save_path=str(run_dir / "best"), deterministic=True, verbose=0),
        CheckpointCallback(save_freq=max(1, s.checkpoint_freq // cfg.n_envs), save_path=str(run_dir / "checkpoints"),
                           name_prefix="model", save_vecnormalize=True),
        TqdmCallback(cfg.total_timesteps, disable=not s.progress),  # counts from the resumed step
    ])
    # a resumed run continues up to the configured total
    remaining = cfg.total_timesteps - (model.num_timesteps if s.resume else 0)
    start = time.perf_counter()
    if remaining > 0:
        model.learn(total_timesteps=remaining, callback=callbacks, reset_num_timesteps=not s.resume)
    wall = time.perf_counter() - start
    model.save(run_dir / "model.zip")
    if isinstance(venv, VecNormalize):
        venv.save(str(run_dir / "vecnormalize.pkl"))
    summary = {"wall_time_s": wall, "timesteps": int(model.num_timesteps),
               "steps_per_s": max(remaining, 0) / wall if wall > 0 else None}
    (run_dir / "training.json").write_text(json.dumps(summary, indent=2))
    plot_learning_curve(run_dir, f"{env_id} {s.task}: {s.algo.upper()} (seed {s.seed})")
    print(json.dumps({"run_dir": str(run_dir), **summary}))
    return run_dir


def main(argv=None) -> Path:
    return train(parse_settings(Settings, argv, description=__doc__.split("\n\n")[0]), argv)


if __name__ == "__main__":
    main()
