"""Train PPO with RLlib (new API stack) on ElasticStringPendulum-v0, on this machine or a Ray cluster.

    python -m agents.distributed.train --task stabilize --iterations 100
    python -m agents.distributed.train --task transport --iterations 50 --address 10.0.0.1:6379 --set num_env_runners=8
    python -m agents.distributed.train --task stabilize --iterations 20 --set 'env_kwargs={preset: hard}' lr=1e-4

Hyper-parameters come from configs/agents/rllib_ppo.yaml keyed by env id and task; ``--set
KEY=VALUE ...`` overrides them as in agents.train (YAML values, dotted keys, unknown keys are
errors listing the valid ones). ``num_env_runners`` env runners (Ray actors of one CPU each, placed
by Ray anywhere on the cluster) sample ``num_envs_per_env_runner`` environments each, in one
compiled call per runner (agents/distributed/rllib.py); the learner runs in this process.

Without ``--address`` Ray starts on this machine (``ray.init()``); ``--address HOST:PORT`` joins the
cluster whose head was started with ``ray start --head --port PORT``. A run directory
``runs/{env}__rllib_ppo__{task}__{seed}__{time}`` receives config.yaml (resolved), args.json,
command.txt, status.json, progress.csv (one row per iteration), references.json,
checkpoints/iteration_K/ (every ``--checkpoint-every`` iterations), checkpoint/ (the last),
training.json (wall time, steps, the cluster's nodes and the steps each env runner sampled),
evaluation.json (agents/evaluate.py's metrics of the final policy) and learning_curve.png.
"""
from __future__ import annotations

import csv
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
from agents.cli import SettingsError, one_line, parse_settings, settings_parser
from agents import ROOT
from agents.common import ConfigError, json_default, save_learning_curve
from agents.baselines.pd import ZeroPolicy
from agents.evaluate import evaluate_policy
from agents.distributed.cluster import AddressError, check_address, cluster_nodes, connect, shutdown, token_auth
from agents.distributed.rllib import CONFIG_FILE, RLlibPolicy, RLlibRunConfig, load_rllib_config, ppo_config, runner_steps
from agents.runs import new_run_dir, write_status, write_stopped
from esp_gym.pendulum.tasks import TASKS
from esp_gym.workers import check_within_cpus

ALGO = "rllib_ppo"
#: Seeds of the final evaluation and of the reference returns (episode i: seed + i), as agents.train's.
EVAL_SEED = 10_000
PROGRESS_FIELDS = ("iteration", "env_steps", "episode_return_mean", "episode_len_mean", "episodes", "time_s",
                   "env_steps_per_s")


@dataclass
class Settings:
    task: str = field(default="stabilize", metadata={"help": "task", "choices": sorted(TASKS)})
    iterations: int = field(default=100, metadata={
        "help": "training iterations (each samples train_batch_size_per_learner steps)", "type": int, "min": 1})
    seed: int = field(default=0, metadata={"help": "seed of the algorithm and of the environments", "type": int,
                                           "min": 0})
    set: list = field(default_factory=list, metadata={
        "help": "hyper-parameter overrides KEY=VALUE (YAML values, dotted keys for nested settings; repeatable)",
        "nargs": "+", "action": "extend"})
    address: Optional[str] = field(default=None, metadata={
        "help": "a Ray cluster's head HOST:PORT (`ray start --head --port PORT`) or 'auto' (default: start Ray "
                "on this machine)"})
    runs: str = field(default=str(ROOT / "runs"), metadata={"help": "where run directories go"})
    run_name: Optional[str] = field(default=None, metadata={"help": "run directory name (default: generated)"})
    checkpoint_every: int = field(default=10, metadata={"help": "iterations between checkpoints", "type": int,
                                                        "min": 1})
    eval_episodes: int = field(default=10, metadata={
        "help": f"episodes of the final evaluation (seeds {EVAL_SEED}+)", "type": int, "min": 1})
    reference_episodes: int = field(default=10, metadata={
        "help": "episodes for the zero/baseline reference returns drawn on the learning curve", "type": int, "min": 1})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    threads: int = field(default=1, metadata={"help": "torch threads of the learner (this process)", "type": int,
                                              "min": 1})


def check_settings(s: Settings) -> tuple:
    """``(config, run_dir)`` of checked settings; SettingsError (one line, naming the argument) for
    anything wrong, before anything is written or started."""
    try:
        cfg = load_rllib_config(s.task, s.set)
    except ConfigError as err:
        raise SettingsError("--set" if err.override else None, str(err)) from None
    from esp_gym.pendulum.env_setup import make_setup

    try:
        make_setup(task=s.task, **cfg.env_kwargs)
    except (ValueError, TypeError) as err:
        raise SettingsError("--set", f"env_kwargs {cfg.env_kwargs}: {one_line(err)} (from --set or {CONFIG_FILE})") \
            from None
    check_local_runners(s.address, cfg)
    run_dir = new_run_dir(s.runs, s.run_name, ALGO, s.task, s.seed)
    try:
        check_address(s.address)
    except AddressError as err:
        raise SettingsError("--address", str(err)) from None
    return cfg, run_dir


def check_local_runners(address: Optional[str], cfg: RLlibRunConfig) -> None:
    """SettingsError naming ``--set`` when Ray, started on this machine (no ``address``), would be
    asked for more env runners (one CPU each) than the CPUs: they would wait for a CPU forever. A
    cluster's runners (``address`` given) are placed on its nodes, whose CPUs cannot be counted
    from here, so Ray is left to place them."""
    if address is None:
        try:
            check_within_cpus("num_env_runners", cfg.num_env_runners)
        except ValueError as err:
            raise SettingsError("--set", f"{err} (Ray on this machine, one CPU per env runner; or join a "
                                         f"cluster with --address)") from None


def build(s, cfg: RLlibRunConfig, make_config=None):
    """Join Ray and build the algorithm of ``make_config(cfg, s)`` (default :func:`ppo_config`'s);
    a configuration RLlib rejects is a SettingsError."""
    connect(s.address)
    try:
        config = ppo_config(cfg, s.task, s.seed) if make_config is None else make_config(cfg, s)
        return config.build_algo()
    except (ValueError, TypeError, KeyError) as err:
        raise SettingsError("--set", f"RLlib rejects the configuration: {one_line(f'{type(err).__name__}: {err}')}") \
            from None


def progress_row(result: dict, iteration: int) -> dict:
    """One progress.csv row from ``Algorithm.train()``'s result."""
    runners = result.get("env_runners", {})
    steps = result.get("num_env_steps_sampled_lifetime", runners.get("num_env_steps_sampled_lifetime", 0))
    this_iter = runners.get("num_env_steps_sampled", 0)
    wall = result.get("time_this_iter_s") or float("nan")
    return {"iteration": iteration, "env_steps": int(steps),
            "episode_return_mean": runners.get("episode_return_mean", float("nan")),
            "episode_len_mean": runners.get("episode_len_mean", float("nan")),
            "episodes": runners.get("num_episodes", 0), "time_s": result.get("time_total_s", float("nan")),
            "env_steps_per_s": this_iter / wall}


def plot_curve(run_dir: Path, title: str) -> Path:
    """learning_curve.png: the training episodes' mean return per iteration against environment
    steps, the references and the final evaluation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read_progress(run_dir / "progress.csv")
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    ax.plot([r["env_steps"] for r in rows], [r["episode_return_mean"] for r in rows], "o-", ms=3,
            color="tab:blue", label="training episodes (mean per iteration)")
    refs = json.loads((run_dir / "references.json").read_text()) if (run_dir / "references.json").is_file() else {}
    for name, style in (("baseline_return", "--"), ("zero_return", ":")):
        if name in refs:
            ax.axhline(refs[name], color="k", ls=style, lw=1, label=name.replace("_", " "))
    ev = run_dir / "evaluation.json"
    if ev.is_file() and rows:
        e = json.loads(ev.read_text())
        ax.errorbar([rows[-1]["env_steps"]], [e["mean_return"]], yerr=[e["std_return"]], fmt="s", color="tab:red",
                    label="final deterministic evaluation")
    return save_learning_curve(fig, ax, run_dir, title)


def read_progress(path: Path) -> list:
    with open(path) as fh:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(fh)]


def _record_settings(s: Settings, cfg: RLlibRunConfig, run_dir: Path, argv: Optional[list]) -> None:
    args = sys.argv[1:] if argv is None else list(argv)
    (run_dir / "config.yaml").write_text(yaml.safe_dump(cfg.model_dump(), sort_keys=False))
    (run_dir / "args.json").write_text(json.dumps(dataclasses.asdict(s), indent=2, default=json_default))
    (run_dir / "command.txt").write_text(shlex.join([sys.executable, "-m", "agents.distributed.train", *args]) + "\n")
    refs = {"baseline_return": evaluate_policy(None, s.task, s.reference_episodes, seed=EVAL_SEED,
                                               env_kwargs=cfg.env_kwargs)["mean_return"],
            "zero_return": evaluate_policy(ZeroPolicy(), s.task, s.reference_episodes, seed=EVAL_SEED,
                                           env_kwargs=cfg.env_kwargs)["mean_return"]}
    (run_dir / "references.json").write_text(json.dumps(refs))


def run(s: Settings, cfg: RLlibRunConfig, run_dir: Path, algo, argv: Optional[list] = None) -> Path:
    """Train a built algorithm for ``s.iterations`` in ``run_dir``; status.json says ``running``,
    then ``finished``, ``interrupted`` or ``failed`` (the error is re-raised)."""
    from tqdm.auto import tqdm

    run_dir.mkdir(parents=True)
    steps = 0
    try:
        write_status(run_dir, "running", iterations=0, timesteps=0)
        _record_settings(s, cfg, run_dir, argv)
        start = time.perf_counter()
        with open(run_dir / "progress.csv", "w", newline="") as fh, \
                tqdm(total=s.iterations, unit="it", desc="training", disable=not s.progress) as bar:
            log = csv.DictWriter(fh, fieldnames=PROGRESS_FIELDS)
            log.writeheader()
            for k in range(1, s.iterations + 1):
                row = progress_row(algo.train(), k)
                log.writerow(row)
                fh.flush()
                steps = row["env_steps"]
                bar.set_postfix(steps=steps, ret=f"{row['episode_return_mean']:.1f}",
                                sps=f"{row['env_steps_per_s']:.0f}")
                bar.update()
                if k % s.checkpoint_every == 0 and k < s.iterations:
                    algo.save_to_path(str((run_dir / "checkpoints" / f"iteration_{k}").resolve()))
        wall = time.perf_counter() - start
        algo.save_to_path(str((run_dir / "checkpoint").resolve()))
        runners = algo.env_runner_group.foreach_env_runner(runner_steps, local_env_runner=False)
        summary = {"wall_time_s": wall, "iterations": s.iterations, "timesteps": steps,
                   "steps_per_s": steps / wall if wall > 0 else None, "address": s.address,
                   "nodes": cluster_nodes(), "env_runners": runners}
        (run_dir / "training.json").write_text(json.dumps(summary, indent=2))
        stats = evaluate_policy(RLlibPolicy(run_dir / "checkpoint", cfg, s.task), s.task, s.eval_episodes,
                                seed=EVAL_SEED, env_kwargs=cfg.env_kwargs)
        (run_dir / "evaluation.json").write_text(json.dumps({**stats, "seed": EVAL_SEED}, indent=2))
        plot_curve(run_dir, f"{esp_gym.ENV_ID} {s.task}: RLlib PPO (seed {s.seed})")
        write_status(run_dir, "finished", iterations=s.iterations, timesteps=steps)
    except BaseException as err:  # Ctrl-C too: the directory says why it stopped
        write_stopped(run_dir, err, timesteps=steps)
        raise
    print(json.dumps({"run_dir": str(run_dir), "timesteps": steps, "wall_time_s": wall,
                      "mean_return": stats["mean_return"]}))
    return run_dir


def rllib_main(ap, settings_class, argv, check, build_algo, train) -> Path:
    """An RLlib training command's life (this module's and agents.team.train's): the settings from
    ``ap``, Ray's token and the learner's threads; ``check(s) -> (config, run_dir)`` and
    ``build_algo(s, config)``, whose SettingsError is one line naming the argument;
    ``train(s, config, run_dir, algo, argv)``; the algorithm and Ray stopped whatever happens."""
    import torch

    s, _ = parse_settings(ap, settings_class, argv)
    token_auth(s.address)  # before anything imports ray
    torch.set_num_threads(s.threads)
    algo = None
    try:
        try:
            cfg, run_dir = check(s)
            algo = build_algo(s, cfg)
        except SettingsError as err:
            shutdown()
            ap.error(str(err))
        return train(s, cfg, run_dir, algo, argv)
    finally:
        if algo is not None:
            algo.stop()
        shutdown()


def main(argv=None) -> Path:
    ap = settings_parser(Settings, prog="python -m agents.distributed.train", description=__doc__.split("\n\n")[0])
    return rllib_main(ap, Settings, argv, check_settings, build, run)


if __name__ == "__main__":
    main()
