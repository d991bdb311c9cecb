"""Train a Stable-Baselines3 agent (PPO or SAC) on ElasticStringPendulum-v0.

    python -m agents.train --algo ppo --task stabilize --seed 0
    python -m agents.train --algo ppo --task stabilize --set total_timesteps=200000 n_envs=8 --set 'policy_kwargs.net_arch.pi=[64,64]'
    python -m agents.train --resume runs/RUN/checkpoints/model_100000_steps.zip --set total_timesteps=2000000

Hyper-parameters come from configs/agents/{ppo,sac}.yaml keyed by env id and task; ``--set
KEY=VALUE ...`` (repeatable) overrides them in order: values are YAML, dotted keys reach into
nested settings, unknown keys are errors that list the valid ones. The batched SB3 VecEnv of
esp_gym steps all training environments in one compiled call; VecNormalize normalises
observations (and rewards where the config says so). A run directory
``runs/{env}__{algo}__{task}__{seed}__{time}`` receives model.zip, vecnormalize.npz,
config.yaml (resolved), args.json, command.txt, status.json, monitor.csv, evaluations.npz
(EvalCallback), checkpoints/ and learning_curve.png; it is created only once the settings are
checked and the environments and the model are built (agents/runs.py).

``--resume`` continues a run from one of its checkpoints in its own directory, with its own
settings (``--set`` may add overrides, e.g. a larger total_timesteps); the monitor log and the
evaluations continue from the checkpoint.
"""
from __future__ import annotations

import dataclasses
import json
import math
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import yaml

import esp_gym
from agents.artifacts import ModelFileError, load_model
from agents.cli import SettingsError, one_line, option_name, parse_settings, settings_parser
from agents import ROOT
from agents.common import (CONFIG_DIR, ConfigError, CriticWarmup, RunConfig, TimeLimitCallback, TqdmCallback,
                           json_default, load_run_config, plot_learning_curve, resolve_schedules)
from agents.baselines.pd import ZeroPolicy
from agents.evaluate import evaluate_policy
from agents.normalization import NormStats
from agents.residual import base_policy, write_residual
from agents.runs import Resume, RunCheckpoint, RunMonitor, new_run_dir, write_status, write_stopped
from esp_gym.pendulum.tasks import TASKS


@dataclass
class Settings:
    algo: str = field(default="ppo", metadata={"help": "algorithm", "choices": ["ppo", "sac"], "run": True})
    task: str = field(default="stabilize", metadata={"help": "task", "choices": sorted(TASKS), "run": True})
    seed: int = field(default=0, metadata={"help": "seed of the agent and of the environments (seed + i)", "type": int,
                                           "min": 0, "run": True})
    set: list = field(default_factory=list, metadata={
        "help": "hyper-parameter overrides KEY=VALUE (YAML values, dotted keys for nested settings; repeatable)",
        "nargs": "+", "action": "extend"})
    runs: str = field(default=str(ROOT / "runs"), metadata={"help": "where run directories go", "run": True})
    run_name: Optional[str] = field(default=None, metadata={"help": "run directory name (default: generated)",
                                                            "run": True})
    eval_freq: int = field(default=50_000, metadata={"help": "environment steps between evaluations", "type": int,
                                                     "min": 1, "run": True})
    eval_episodes: int = field(default=10, metadata={"help": "episodes per evaluation", "type": int, "min": 1,
                                                     "run": True})
    checkpoint_freq: int = field(default=500_000, metadata={"help": "environment steps between checkpoints",
                                                            "type": int, "min": 1, "run": True})
    resume: Optional[str] = field(default=None, metadata={
        "help": "checkpoint RUN/checkpoints/model_N_steps.zip to resume from (in RUN, with RUN's settings)"})
    time_limit: Optional[float] = field(default=None, metadata={
        "help": "minutes of training after which the run stops and saves (default: none)", "type": float})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    threads: int = field(default=1, metadata={"help": "torch threads (the physics uses the other core)", "type": int,
                                              "min": 1})
    reference_episodes: int = field(default=10, metadata={
        "help": "episodes for the zero/baseline reference returns drawn on the learning curve", "type": int, "min": 1,
        "run": True})


#: Settings that define a run: a resumed run takes them from its args.json (giving one is an error).
RUN_SETTINGS = frozenset(f.name for f in dataclasses.fields(Settings) if f.metadata.get("run"))


def _make_vec_env(n_envs: int, task: str, seed: int, env_kwargs: dict, residual: Optional[str] = None,
                  privileged: bool = False, max_episode_steps: int = esp_gym.MAX_EPISODE_STEPS):
    from agents.privileged import PrivilegedVecEnv
    from agents.residual import ResidualVecEnv, base_policy
    from esp_gym.pendulum.sb3_vector import ElasticStringPendulumSB3VecEnv

    env = ElasticStringPendulumSB3VecEnv(num_envs=n_envs, task=task, max_episode_steps=max_episode_steps, **env_kwargs)
    env.seed(seed)
    venv = env if residual is None else ResidualVecEnv(env, base_policy(residual, task, env_kwargs), env.setup)
    return PrivilegedVecEnv(venv, env.control) if privileged else venv


def privileged_size_of(venv) -> int:
    """The privileged entries at the end of ``venv``'s observations (agents/privileged.py)."""
    from agents.privileged import PrivilegedVecEnv, privileged_size

    while not isinstance(venv, PrivilegedVecEnv):
        venv = venv.venv
    return privileged_size(venv.control)


@dataclass
class Prepared:
    """A checked run, its environments and its model, before anything is written."""

    settings: Settings
    cfg: RunConfig
    run_dir: Path
    resume: Optional[Resume]
    monitor: RunMonitor
    venv: object
    eval_env: object
    model: object


def run_config(s: Settings) -> RunConfig:
    """The run's hyper-parameters (``--set`` over the config file) and environment options,
    checked; SettingsError naming ``--set`` (or the config file) otherwise."""
    try:
        cfg = load_run_config(s.algo, esp_gym.ENV_ID, s.task, s.set)
    except ConfigError as err:
        raise SettingsError("--set" if err.override else None, str(err)) from None
    from esp_gym.pendulum.env_setup import make_setup

    try:  # env_kwargs' values, checked here rather than by the first environment
        make_setup(task=s.task, **cfg.env_kwargs)
    except (ValueError, TypeError) as err:
        touched = any(item.split("=", 1)[0].split(".")[0] == "env_kwargs" for item in s.set)
        raise SettingsError("--set" if touched else None,
                            f"env_kwargs {cfg.env_kwargs}: {one_line(err)}"
                            + ("" if touched else f" (from {CONFIG_DIR / (s.algo + '.yaml')})")) from None
    return cfg


def prepare(s: Settings, given: frozenset = frozenset()) -> Prepared:
    """Check the settings and build the environments and the model; raises SettingsError (one
    line, naming the argument) for anything wrong, having written nothing. ``given``: the
    settings the command line set (those of RUN_SETTINGS conflict with ``--resume``)."""
    if s.time_limit is not None and not (math.isfinite(s.time_limit) and s.time_limit > 0):
        raise SettingsError("--time-limit", f"must be a positive number of minutes, got {s.time_limit}")
    s, resume = _resumed_settings(s, given)
    cfg = run_config(s)
    run_dir = _run_dir(s, cfg, resume)
    _check_algorithm_needs(s, cfg)
    monitor, venv, eval_env = _environments(s, cfg, resume)
    model = _model(s, cfg, resume, monitor, venv)
    if cfg.residual and not resume:
        start_at_base(model)
    return Prepared(s, cfg, run_dir, resume, monitor, venv, eval_env, model)


def _resumed_settings(s: Settings, given: frozenset) -> tuple:
    """``(settings, Resume or None)``: with ``--resume``, the run's saved settings (``--set`` adding
    overrides after its own), none of RUN_SETTINGS given again."""
    if not s.resume:
        return s, None
    clash = sorted(given & RUN_SETTINGS)
    if clash:
        raise SettingsError(option_name(clash[0]), "not allowed with --resume (a resumed run keeps its own "
                                                   "settings; --set adds overrides)")
    try:
        resume = Resume.read(s.resume)
    except ValueError as err:
        raise SettingsError("--resume", str(err)) from None
    saved = {k: v for k, v in resume.saved.items() if k in RUN_SETTINGS}
    return dataclasses.replace(s, **saved, set=list(resume.saved["set"]) + list(s.set)), resume


def _run_dir(s: Settings, cfg: RunConfig, resume: Optional[Resume]) -> Path:
    """The run's directory: a resumed run's own (checked: steps left to take, its normalisation
    statistics there), else a new one's name (nothing made yet)."""
    if not resume:
        return new_run_dir(s.runs, s.run_name, s.algo, s.task, s.seed)
    if cfg.total_timesteps <= resume.steps:
        raise SettingsError("--resume", f"the checkpoint is at step {resume.steps}, the run's total_timesteps is "
                                        f"{cfg.total_timesteps}: raise it with --set total_timesteps=N")
    if cfg.normalize and resume.stats is None:
        raise SettingsError("--resume", f"no normalisation statistics beside {resume.checkpoint} "
                                        f"(model_vecnormalize_{resume.steps}_steps.npz or .pkl)")
    return resume.run_dir


def _check_algorithm_needs(s: Settings, cfg: RunConfig) -> None:
    """The options that need PPO (a state value), and distillation's whole recipe."""
    if cfg.privileged_critic and s.algo != "ppo":
        raise SettingsError("--set", f"privileged_critic needs an actor-critic with a state value (ppo), not {s.algo}")
    if cfg.critic_warmup and s.algo != "ppo":
        raise SettingsError("--set", f"critic_warmup needs an actor-critic with a state value (ppo), not {s.algo}")
    if cfg.distill_episodes and not (s.algo == "ppo" and cfg.residual and cfg.normalize and not cfg.privileged_critic
                                     and cfg.frame_stack == 1):
        raise SettingsError("--set", "distill_episodes fits a residual PPO actor with normalised observations: it needs "
                                     "algo ppo, residual, normalize, no privileged_critic and frame_stack 1 (got "
                                     f"{s.algo}, residual={cfg.residual}, normalize={bool(cfg.normalize)}, "
                                     f"privileged_critic={cfg.privileged_critic}, frame_stack={cfg.frame_stack})")


def _environments(s: Settings, cfg: RunConfig, resume: Optional[Resume]) -> tuple:
    """``(monitor, venv, eval_env)``: the training envs under their monitor, then normalised
    (a resumed run's statistics, or new ones) and frame-stacked as the run says, and the
    evaluation envs alike; a residual the observation cannot feed, or a batch past the memory,
    refused before anything is written."""
    from stable_baselines3.common.vec_env import VecFrameStack, VecMonitor, VecNormalize

    try:
        monitor = RunMonitor(_make_vec_env(cfg.n_envs, s.task, s.seed, cfg.env_kwargs, cfg.residual,
                                           cfg.privileged_critic, cfg.episode_steps or esp_gym.MAX_EPISODE_STEPS))
        eval_env = VecMonitor(_make_vec_env(min(4, s.eval_episodes), s.task, s.seed + 10_000, cfg.env_kwargs,
                                            cfg.residual, cfg.privileged_critic))
    except (ValueError, MemoryError) as err:
        raise SettingsError("--set", one_line(str(err))) from None
    venv = monitor
    try:
        if resume and resume.stats is not None:
            venv = resume.stats.to_vecnormalize(monitor)
        elif cfg.normalize and not resume:
            venv = VecNormalize(monitor, gamma=cfg.algo.get("gamma", 0.99), **cfg.normalize)
    except (ValueError, TypeError) as err:
        raise SettingsError("--resume" if resume else "--set", f"normalize: {one_line(err)}") from None
    if isinstance(venv, VecNormalize):
        eval_env = VecNormalize(eval_env, training=False, norm_reward=False, clip_obs=venv.clip_obs)
    if cfg.frame_stack > 1:  # stacks the normalised observations (SB3Policy does the same)
        venv, eval_env = VecFrameStack(venv, cfg.frame_stack), VecFrameStack(eval_env, cfg.frame_stack)
    return monitor, venv, eval_env


def _model(s: Settings, cfg: RunConfig, resume: Optional[Resume], monitor, venv):
    """A resumed run's model from its checkpoint, or a new PPO or SAC on ``venv`` (with the
    privileged critic, its actor reading the observation part of each stacked frame)."""
    from stable_baselines3 import PPO, SAC

    if resume:
        try:
            return load_model(resume.checkpoint, env=venv)
        except ModelFileError as err:
            raise SettingsError("--resume", str(err)) from None
    cls = {"ppo": PPO, "sac": SAC}[s.algo]
    policy, algo = cfg.policy, resolve_schedules(cfg.algo)
    if cfg.privileged_critic:
        from agents.privileged import AsymmetricPolicy

        frame = monitor.observation_space.shape[0]
        policy = AsymmetricPolicy
        algo["policy_kwargs"] = {**algo.get("policy_kwargs", {}), "frame_size": frame,
                                 "actor_size": frame - privileged_size_of(monitor)}
    try:
        return cls(policy, venv, seed=s.seed, device="cpu", verbose=0, **algo)
    except (ValueError, TypeError, KeyError, AssertionError) as err:  # SB3 checks its arguments by assert
        raise SettingsError("--set", f"{s.algo.upper()} rejects the configuration: "
                                     f"{one_line(f'{type(err).__name__}: {err}')}") from None


def start_at_base(model) -> None:
    """Zero the layer that outputs the action's mean, so that a residual policy's first
    deterministic action is its base's exactly (SB3's small initial gain still moves it, and the
    return is sensitive to that)."""
    import torch

    layer = model.policy.action_net if hasattr(model.policy, "action_net") else model.policy.actor.mu
    with torch.no_grad():
        layer.weight.zero_()
        layer.bias.zero_()


def _record_settings(p: Prepared, argv: Optional[list]) -> None:
    s, run_dir = p.settings, p.run_dir
    args = sys.argv[1:] if argv is None else list(argv)
    command = shlex.join([sys.executable, "-m", "agents.train", *args]) + "\n"
    (run_dir / "config.yaml").write_text(yaml.safe_dump(p.cfg.model_dump(), sort_keys=False))
    if p.cfg.residual:  # what SB3Policy adds back when it acts
        write_residual(run_dir, p.cfg.residual, s.task, p.cfg.env_kwargs)
    if p.resume:  # the run now includes the resume's overrides; its commands are kept in order
        (run_dir / "args.json").write_text(json.dumps({**p.resume.saved, "set": s.set}, indent=2,
                                                      default=json_default))
        with open(run_dir / "command.txt", "a") as fh:
            fh.write(command)
    else:
        (run_dir / "args.json").write_text(json.dumps(dataclasses.asdict(s), indent=2, default=json_default))
        (run_dir / "command.txt").write_text(command)


def run(p: Prepared, argv: Optional[list] = None, callbacks: Sequence = ()) -> Path:
    """Train a prepared run in its directory; returns the directory. status.json says
    ``running``, then ``finished``, ``interrupted`` (Ctrl-C, or the caller stopped it by raising
    SystemExit) or ``failed`` (the error is re-raised either way). ``callbacks``: more SB3 callbacks."""
    from stable_baselines3.common.logger import CSVOutputFormat, Logger

    cfg, run_dir, model = p.cfg, p.run_dir, p.model
    run_dir.mkdir(parents=True, exist_ok=bool(p.resume))
    try:
        write_status(run_dir, "running", timesteps=int(model.num_timesteps))
        _record_settings(p, argv)
        if not p.resume:
            _write_references(p)
        p.monitor.open_log(run_dir / "monitor.csv", p.resume.monitor if p.resume else None)
        distilled = distill(p) if cfg.distill_episodes and not p.resume else None
        taken = distilled["distill_wall_s"] if distilled else 0.0
        every, limit = _callbacks(p, taken, callbacks)
        first = model.num_timesteps
        # SB3's training statistics (losses, entropy, KL, ...) into the run, one file per segment
        # (a resume does not overwrite the first); by default SB3 makes an empty /tmp/SB3-* per run
        progress = "progress.csv" if not p.resume else f"progress_from_{first}_steps.csv"
        model.set_logger(Logger(str(run_dir), [CSVOutputFormat(str(run_dir / progress))]))
        remaining = cfg.total_timesteps - first  # a resumed run continues up to the total
        start = time.perf_counter()
        model.learn(total_timesteps=remaining, callback=every, reset_num_timesteps=not p.resume)
        summary = _save_results(p, first, time.perf_counter() - start + taken, taken, distilled, limit)
        write_status(run_dir, "finished", timesteps=int(model.num_timesteps))
    except BaseException as err:  # Ctrl-C too: the directory says why it stopped
        write_stopped(run_dir, err, timesteps=int(model.num_timesteps))
        raise
    print(json.dumps({"run_dir": str(run_dir), **summary}))
    return run_dir


def _write_references(p: Prepared) -> None:
    """references.json: the returns of the baseline, the zero action and (residual) the residual's
    base, on the reference episodes, that the run's learning curve is drawn against."""
    s, cfg = p.settings, p.cfg
    n_ref = s.reference_episodes
    refs = {"baseline_return": evaluate_policy(None, s.task, n_ref, seed=10_000,
                                               env_kwargs=cfg.env_kwargs)["mean_return"],
            "zero_return": evaluate_policy(ZeroPolicy(), s.task, n_ref, seed=10_000,
                                           env_kwargs=cfg.env_kwargs)["mean_return"]}
    if cfg.residual:  # what the residual policy starts from
        refs["residual_base_return"] = evaluate_policy(base_policy(cfg.residual, s.task, cfg.env_kwargs), s.task,
                                                       n_ref, seed=10_000, env_kwargs=cfg.env_kwargs)["mean_return"]
    (p.run_dir / "references.json").write_text(json.dumps(refs))


def _callbacks(p: Prepared, taken: float, extra: Sequence) -> tuple:
    """``(the run's SB3 callbacks, its TimeLimitCallback or None)``: the evaluations (a resumed
    run's continued), the checkpoints, the progress bar, the time limit less the ``taken``
    seconds [s], the critic's warm-up and the ``extra`` ones."""
    from stable_baselines3.common.callbacks import CallbackList, EvalCallback

    s, cfg, run_dir = p.settings, p.cfg, p.run_dir
    evaluations = EvalCallback(p.eval_env, n_eval_episodes=s.eval_episodes,
                               eval_freq=max(1, s.eval_freq // cfg.n_envs), log_path=str(run_dir),
                               best_model_save_path=str(run_dir / "best"), deterministic=True, verbose=0)
    if p.resume and p.resume.evaluations is not None:
        p.resume.evaluations.continue_in(evaluations, run_dir / "evaluations.npz")
    limit = TimeLimitCallback(max(60.0 * s.time_limit - taken, 0.0)) if s.time_limit is not None else None
    every = CallbackList([
        evaluations,
        RunCheckpoint(run_dir / "checkpoints", s.checkpoint_freq, p.monitor),
        TqdmCallback(cfg.total_timesteps, disable=not s.progress),  # counts from the resumed step
    ] + ([limit] if limit else []) + ([CriticWarmup(cfg.critic_warmup)] if cfg.critic_warmup else []) + list(extra))
    return every, limit


def _save_results(p: Prepared, first: int, wall: float, taken: float, distilled, limit) -> dict:
    """The model, its normalisation statistics, training.json (returned: the wall time [s], the
    steps and their rate from step ``first``, distillation's ``taken`` seconds and figures, the
    resume and the time limit) and the learning curve."""
    from stable_baselines3.common.vec_env import unwrap_vec_normalize

    s, model, run_dir = p.settings, p.model, p.run_dir
    model.save(run_dir / "model.zip")
    normalizer = unwrap_vec_normalize(p.venv)
    if normalizer is not None:
        NormStats.from_vecnormalize(normalizer).save(run_dir / "vecnormalize.npz")
    summary = {"wall_time_s": wall, "timesteps": int(model.num_timesteps),
               "steps_per_s": (model.num_timesteps - first) / (wall - taken) if wall > taken else None}
    if distilled:
        summary.update(distilled)
    if p.resume:
        summary["resumed_from"] = p.resume.steps
    if limit:
        summary["time_limit_min"], summary["stopped_by_time_limit"] = s.time_limit, limit.stopped
    (run_dir / "training.json").write_text(json.dumps(summary, indent=2))
    plot_learning_curve(run_dir, f"{esp_gym.ENV_ID} {s.task}: {s.algo.upper()} (seed {s.seed})")
    return summary


def distill(p: Prepared) -> dict:
    """Fit the residual actor to the teacher's episodes (agents/distill.py) and freeze the
    observation statistics at the teacher data's (the actor was fitted on them); what it took."""
    from agents.distill import DISTILL_SEED, fit_actor, teach

    from stable_baselines3.common.vec_env import unwrap_vec_normalize

    s, cfg = p.settings, p.cfg
    start = time.perf_counter()
    first = DISTILL_SEED + 1000 * s.seed
    inputs, targets, gains = teach(s.task, cfg.residual, cfg.env_kwargs,
                                   list(range(first, first + cfg.distill_episodes)), cfg.distill_knots,
                                   cfg.distill_evaluations, jobs=min(2, cfg.distill_episodes), progress=s.progress)
    normalizer = unwrap_vec_normalize(p.venv)
    loss = fit_actor(p.model, normalizer, inputs, targets, seed=s.seed)
    normalizer.training = False  # the statistics the actor was fitted on
    return {"distill_wall_s": time.perf_counter() - start, "distill_episodes": cfg.distill_episodes,
            "distill_teacher_gain_mean": float(gains.mean()), "distill_fit_loss": loss,
            "distill_target_mean_square": float((targets ** 2).mean())}


def train(s: Settings, argv: Optional[list] = None, given: frozenset = frozenset(), callbacks: Sequence = ()) -> Path:
    """Run one training; returns the run directory. ``argv``: the command-line arguments
    recorded in command.txt (default: this process's); ``callbacks``: more SB3 callbacks. Bad
    settings raise SettingsError."""
    import torch

    torch.set_num_threads(s.threads)
    return run(prepare(s, given), argv, callbacks)


def parse_args(argv=None) -> tuple:
    """``(settings, given, parser)`` from the command line (``given``: the settings it set)."""
    ap = settings_parser(Settings, prog="python -m agents.train", description=__doc__.split("\n\n")[0])
    s, given = parse_settings(ap, Settings, argv)
    return s, given, ap


def main(argv=None) -> Path:
    import torch

    s, given, ap = parse_args(argv)
    torch.set_num_threads(s.threads)
    try:
        prepared = prepare(s, given)
    except SettingsError as err:
        ap.error(str(err))
    return run(prepared, argv)


if __name__ == "__main__":
    main()
