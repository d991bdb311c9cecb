"""RLlib on a local Ray cluster against Stable-Baselines3 in one process, on ElasticStringPendulum-v0.

Prints two tables and writes ``OUT/ray_throughput.json`` and ``OUT/ray_learning.png``
(OUT = benchmarks/out unless ``--out``):

* sampling: environment steps per second sampled with the policy in the loop (a PPO network of
  2 x 128, stochastic actions), medians of ``--repeats`` timed rounds after a warm-up:
  - RLlib on local clusters of 1 and 2 nodes (one CPU each, one env runner per node, all runners
    sampling at once), each runner with 16 environments in one compiled call (``batched``), 16
    environments of one compiled call each (Gymnasium's SyncVectorEnv, ``sync``) or 1 environment;
  - the SB3 VecEnv of 16 environments in this process (SB3's PPO policy and its step loop);
* learning: ``agents.train`` (SB3 PPO, configs/agents/ppo.yaml) and ``agents.distributed.train`` (RLlib
  PPO, configs/agents/rllib_ppo.yaml: 2 env runners on this machine) on the same task for the
  same number of environment steps, one after the other; their training curves and the final
  policies' agents/evaluate.py metrics on the same 10 episodes (seeds 10000+).

Usage: ``python -m benchmarks.ray_throughput [--quick] [--steps N] [--task T] [--out DIR]``.
"""
from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np

from benchmarks.common import arg_parser, figure, finish, machine

ROOT = Path(__file__).resolve().parent.parent
N_ENVS = 16
MODES = {"batched": (N_ENVS, True), "sync": (N_ENVS, False), "1 env": (1, True)}
SAMPLE_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def rllib_sampling(nodes: int, steps: int, repeats: int) -> dict:
    """Steps/s of each of MODES on a local cluster of ``nodes`` one-CPU nodes (a driver joins it)."""
    import ray

    from agents.distributed.cluster import LocalCluster, connect
    from agents.distributed.rllib import load_rllib_config, ppo_config

    rates = {}
    with LocalCluster(nodes=nodes, cpus=1, token=os.environ["RAY_AUTH_TOKEN"]) as cluster:
        connect(cluster.address)
        try:
            for mode, (n, batched) in MODES.items():
                cfg = load_rllib_config("stabilize", [f"num_env_runners={nodes}", f"num_envs_per_env_runner={n}",
                                                      f"batched={str(batched).lower()}"])
                algo = ppo_config(cfg, "stabilize", seed=0).build_algo()
                group = algo.env_runner_group

                def sample(runner, k=steps):
                    return sum(len(e) for e in runner.sample(num_timesteps=k, explore=True))

                group.foreach_env_runner(sample, local_env_runner=False)  # warm-up: compilation, first episodes
                walls, counts = [], []
                for _ in range(repeats):
                    start = time.perf_counter()
                    counts.append(sum(group.foreach_env_runner(sample, local_env_runner=False)))
                    walls.append(time.perf_counter() - start)
                rates[mode] = float(np.median(np.array(counts) / np.array(walls)))
                algo.stop()
                print(f"  RLlib, {nodes} node{'s' * (nodes > 1)}, {mode}: {rates[mode]:,.0f} steps/s")
        finally:
            ray.shutdown()
    return rates


def sb3_sampling(steps: int, repeats: int) -> float:
    """Steps/s of SB3's PPO policy stepping the batched SB3 VecEnv (as PPO.collect_rollouts does)."""
    import torch
    from stable_baselines3 import PPO

    from esp_gym.pendulum.sb3_vector import ElasticStringPendulumSB3VecEnv

    torch.set_num_threads(1)
    venv = ElasticStringPendulumSB3VecEnv(num_envs=N_ENVS, task="stabilize")
    venv.seed(0)
    model = PPO("MlpPolicy", venv, policy_kwargs={"net_arch": {"pi": [128, 128], "vf": [128, 128]}}, device="cpu")
    low, high = venv.action_space.low, venv.action_space.high
    obs = venv.reset()

    def run(count):
        nonlocal obs
        for _ in range(count // N_ENVS):
            with torch.no_grad():
                actions, _, _ = model.policy(torch.as_tensor(obs))
            obs, _, _, _ = venv.step(np.clip(actions.numpy(), low, high))

    run(10 * N_ENVS)
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        run(steps)
        rates.append(steps / (time.perf_counter() - start))
    return float(np.median(rates))


def _cli(module: str, *args) -> None:
    env = {**os.environ, **SAMPLE_ENV}
    done = subprocess.run([sys.executable, "-m", module, *map(str, args)], cwd=ROOT, env=env, capture_output=True,
                          text=True)
    if done.returncode:
        raise RuntimeError(f"{module} failed: {done.stderr[-3000:]}")


def learning(task: str, steps: int, runs: Path, quick: bool) -> dict:
    """Train SB3 PPO then RLlib PPO for ``steps`` environment steps each; their curves and metrics."""
    from agents.evaluate import SB3Policy, evaluate_policy

    batch = 4096  # both configs: 16 environments x 256 steps per update
    small = ["--reference-episodes", "1", "--eval-episodes", "1"] if quick else []
    episodes = 1 if quick else 10
    start = time.perf_counter()
    _cli("agents.train", "--algo", "ppo", "--task", task, "--runs", runs, "--run-name", "sb3", "--no-progress",
         "--set", f"total_timesteps={steps}", *small)
    sb3_wall = time.perf_counter() - start
    iterations = max(1, round(steps / batch))
    start = time.perf_counter()
    _cli("agents.distributed.train", "--task", task, "--iterations", iterations, "--runs", runs, "--run-name", "rllib",
         "--no-progress", "--eval-episodes", episodes, *small)
    rllib_wall = time.perf_counter() - start
    sb3_eval = evaluate_policy(SB3Policy(runs / "sb3" / "model.zip"), task, episodes, seed=10_000)
    rows = np.genfromtxt(runs / "sb3" / "monitor.csv", delimiter=",", skip_header=2, ndmin=2)
    with open(runs / "rllib" / "progress.csv") as fh:
        progress = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    return {
        "task": task, "steps": steps,
        "sb3": {"wall_s": sb3_wall, "train_wall_s": json.loads((runs / "sb3" / "training.json").read_text())[
            "wall_time_s"], "evaluation": sb3_eval, "episode_steps": np.cumsum(rows[:, 1]).tolist(),
                "episode_returns": rows[:, 0].tolist()},
        "rllib": {"wall_s": rllib_wall, "train_wall_s": json.loads((runs / "rllib" / "training.json").read_text())[
            "wall_time_s"], "iterations": iterations,
                  "evaluation": json.loads((runs / "rllib" / "evaluation.json").read_text()),
                  "steps": [r["env_steps"] for r in progress], "returns": [r["episode_return_mean"] for r in progress]},
        "references": json.loads((runs / "sb3" / "references.json").read_text()),
    }


def _plot(res: dict, path) -> None:
    lr = res["learning"]
    fig = figure((7, 4), dpi=130)
    ax = fig.subplots()
    steps, rets = np.array(lr["sb3"]["episode_steps"]), np.array(lr["sb3"]["episode_returns"])
    k = max(1, len(rets) // 50)
    ax.plot(steps[k - 1:], np.convolve(rets, np.ones(k) / k, mode="valid"), color="tab:blue",
            label=f"SB3 PPO, one process (training episodes, mean of {k})")
    ax.plot(lr["rllib"]["steps"], lr["rllib"]["returns"], "o-", ms=3, color="tab:orange",
            label="RLlib PPO, 2 env runners (training episodes, mean per iteration)")
    for name, style in (("baseline_return", "--"), ("zero_return", ":")):
        ax.axhline(lr["references"][name], color="k", ls=style, lw=1, label=name.replace("_", " "))
    ax.set(xlabel="environment steps", ylabel="episode return",
           title=f"{lr['task']}: the same budget ({lr['steps']:,} steps), 2 cores")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.savefig(path)


def main(argv=None) -> dict:
    ap = arg_parser(__doc__)
    ap.add_argument("--steps", type=int, default=300_000, help="environment steps of each training run")
    ap.add_argument("--task", default="stabilize")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    # one token for both clusters: Ray reads it once, when this process first joins one
    os.environ.update({**SAMPLE_ENV, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": uuid.uuid4().hex})
    begin = time.perf_counter()
    steps, repeats = (512, 1) if args.quick else (4096, args.repeats)  # per env runner per round
    sampling = {f"RLlib, {n} node{'s' * (n > 1)}": rllib_sampling(n, steps, repeats) for n in (1, 2)}
    sampling["SB3 VecEnv, one process"] = {"batched": sb3_sampling(4 * steps, repeats)}
    print(f"\n{'sampled steps/s':28s}" + "".join(f"{m:>12s}" for m in MODES))
    for name, row in sampling.items():
        print(f"{name:28s}" + "".join(f"{row[m]:12,.0f}" if m in row else f"{'-':>12s}" for m in MODES))
    with tempfile.TemporaryDirectory(prefix="ray_bench") as tmp:
        lr = learning(args.task, 8192 if args.quick else args.steps, Path(tmp), args.quick)
    print(f"\n{'learning (' + lr['task'] + ')':28s}{'wall [s]':>10s}{'train [s]':>11s}{'return':>16s}{'success':>9s}")
    for name in ("sb3", "rllib"):
        e = lr[name]["evaluation"]
        print(f"{name:28s}{lr[name]['wall_s']:10.0f}{lr[name]['train_wall_s']:11.0f}"
              f"{e['mean_return']:9.1f} ± {e['std_return']:5.1f}{e['success_rate']:9.2f}")
    res = {"sampling": sampling, "n_envs": N_ENVS, "steps_per_round": steps, "repeats": repeats, "learning": lr,
           "machine": machine("ray", "stable_baselines3", "torch")}
    finish(args.out, "ray_throughput", res, {"ray_learning.png": lambda p: _plot(res, p)}, start=begin)
    return res


if __name__ == "__main__":
    main()
