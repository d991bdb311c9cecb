"""The energy balance |E - E0 - W - W_winch| of the shipped configurations' episodes against the
energy watchdog's bound (docs/physics.md, "The energy watchdog"): every task, nominal and with
``preset="hard"``, under the task's baseline plus uniform action noise of +-0.5 (the PD law;
the hoist for the winch's tasks) and under random actions, ``--seeds`` episodes each; the largest
residual of each episode [J], relative to the scene's energy scale, and the episodes the
watchdog ended.

Prints a table and writes ``OUT/energy_balance.json`` and ``OUT/energy_balance.png``.
Usage: ``python -m benchmarks.energy_balance [--quick] [--seeds K] [--out DIR]``.
"""
from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import esp_gym
from esp_gym.physics.watchdog import energy_scale
from agents.baselines.pd import AntiSwayPD, Hoist
from benchmarks.common import arg_parser, figure, finish, machine

TASKS = ("stabilize", "transport", "track", "lift", "lower")
PRESETS = (None, "hard")
POLICIES = ("baseline+noise", "random")
NOISE = 0.5


def episode(task: str, preset, policy: str, seed: int, max_steps=None) -> dict:
    """One episode: the largest |E - E0 - W - W_winch| [J], it over the scene's energy scale,
    the steps taken and the termination reason ("" for none)."""
    options = {} if preset is None else {"preset": preset}
    env = gym.make(esp_gym.ENV_ID, task=task, disable_env_checker=True, max_episode_steps=max_steps, **options)
    obs, _ = env.reset(seed=seed)
    u = env.unwrapped
    baseline = Hoist() if u.setup.winch else AntiSwayPD()
    rng = np.random.default_rng(20_000 + seed)
    shape = env.action_space.shape
    worst, steps, reason = 0.0, 0, ""
    while True:
        noise = rng.uniform(-1, 1, shape)
        action = noise if policy == "random" else baseline.act(obs, u.setup) + NOISE * noise
        obs, _, terminated, truncated, info = env.step(np.clip(action, -1, 1).astype(np.float32))
        steps += 1
        worst = max(worst, abs(u.sim.diagnostics()["energy_balance_residual"]))
        if terminated or truncated:
            reason = info.get("termination_reason", "") if terminated else ""
            break
    return {"task": task, "preset": preset or "nominal", "policy": policy, "seed": seed, "worst": worst,
            "relative": worst / energy_scale(u.scene), "steps": steps, "reason": reason}


def main(argv=None) -> dict:
    parser = arg_parser(__doc__, "one seed, 40 control steps per episode")
    parser.add_argument("--seeds", type=int, default=4, help="episodes per configuration and policy")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    start = time.perf_counter()
    seeds = 1 if args.quick else args.seeds
    jobs = [(task, preset, policy, seed) for task in TASKS for preset in PRESETS for policy in POLICIES
            for seed in range(seeds)]
    rows = [episode(*job, max_steps=40 if args.quick else None) for job in tqdm(jobs, desc="episodes")]
    print(f"{'task':10s} {'preset':8s} {'policy':15s} worst |E - E0 - W| [J]  / scale   episodes ended by it")
    table = []
    for task in TASKS:
        for preset in PRESETS:
            for policy in POLICIES:
                mine = [r for r in rows if r["task"] == task and r["preset"] == (preset or "nominal")
                        and r["policy"] == policy]
                worst = max(mine, key=lambda r: r["worst"])
                fired = sum(r["reason"] == "energy_balance" for r in mine)
                table.append({"task": task, "preset": preset or "nominal", "policy": policy, "worst": worst["worst"],
                              "relative": worst["relative"], "fired": fired, "episodes": len(mine)})
                print(f"{task:10s} {preset or 'nominal':8s} {policy:15s} {worst['worst']:22.2e}  "
                      f"{worst['relative']:7.1e}   {fired} of {len(mine)}")
    finish(args.out, "energy_balance", {"table": table, "episodes": rows, "seeds": seeds, "noise": NOISE,
                                        "machine": machine("gymnasium")},
           {"energy_balance.png": lambda path: _plot(table, path)}, start)
    return {"table": table, "episodes": rows}


def _plot(table: list, path) -> None:
    fig = figure((7, 3.4), dpi=130)
    ax = fig.subplots()
    labels = [f"{row['task']}\n{row['preset']}" for row in table if row["policy"] == POLICIES[0]]
    x = np.arange(len(labels))
    for offset, policy, marker in ((-0.15, POLICIES[0], "o"), (0.15, POLICIES[1], "s")):
        ax.plot(x + offset, [row["relative"] for row in table if row["policy"] == policy], marker, ls="", label=policy)
    ax.axhline(1.0, color="crimson", lw=1.0, label="the watchdog's bound (1 x the scale)")
    ax.set_xticks(x, labels, fontsize=7)
    ax.set(yscale="log", ylabel="largest |E - E0 - W| / energy scale",
           title="the shipped configurations' energy balance")
    ax.grid(True, which="both", axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path)


if __name__ == "__main__":
    main()
