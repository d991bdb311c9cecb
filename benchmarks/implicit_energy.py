"""The implicit string's energy balance under a controller, against its step: ``drone_load`` at
each EA with ``solver.string: implicit``, ``stabilize``'s PD law plus uniform action noise of
+-0.5, ``--seeds`` episodes of ``--steps`` control steps (the energy watchdog off, so that a gain
shows in full); the largest |E - E0 - W| of each episode and how it ended, at 1, 2, 3 and 4 times
the substeps the environment chooses (docs/physics.md, "The implicit string", "What does not work
yet").

Prints a table and writes ``OUT/implicit_energy.json`` and ``OUT/implicit_energy.png``.
Usage: ``python -m benchmarks.implicit_energy [--quick] [--seeds K] [--steps S] [--out DIR]``.
"""
from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

import esp_gym
from agents.controllers import AntiSwayPD
from benchmarks.common import arg_parser, figure, finish, machine

SWEEP_EA = (2e5, 2e6, 1e7)
MULTIPLES = (1, 2, 3, 4)
NOISE = 0.5


def overrides(EA: float) -> dict:
    return {"string": {"EA": EA}, "solver": {"string": "implicit", "energy_watchdog": None}}


def episode(EA: float, substeps: int, seed: int, steps: int) -> dict:
    """The largest |E - E0 - W| [J] (every 10th control step), the steps taken and the
    termination reason ("" for none)."""
    env = gym.make(esp_gym.ENV_ID, h=0.02 / substeps, scene_overrides=overrides(EA), max_episode_steps=steps,
                   disable_env_checker=True)
    obs, _ = env.reset(seed=seed)
    u, pd, rng = env.unwrapped, AntiSwayPD(), np.random.default_rng(seed)
    worst, reason, k = 0.0, "", 0
    for k in range(1, steps + 1):
        action = np.clip(pd.act(obs, u.setup) + NOISE * rng.uniform(-1, 1, 6), -1, 1)
        obs, _, terminated, truncated, info = env.step(action.astype(np.float32))
        if k % 10 == 0 or terminated or truncated:
            worst = max(worst, abs(u.sim.diagnostics()["energy_balance_residual"]))
        if terminated or truncated:
            reason = info.get("termination_reason", "") if terminated else ""
            break
    return {"worst": worst, "steps": k, "reason": reason}


def main(argv=None) -> dict:
    parser = arg_parser(__doc__, "EA = 2e5 N, 1x and 2x the substeps, one seed of 20 control steps")
    parser.add_argument("--seeds", type=int, default=3, help="episodes per EA and step")
    parser.add_argument("--steps", type=int, default=1000, help="control steps per episode")
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.steps < 1:
        parser.error(f"--seeds and --steps must be >= 1, got {args.seeds} and {args.steps}")
    start = time.perf_counter()
    sweep, multiples = (SWEEP_EA[:1], MULTIPLES[:2]) if args.quick else (SWEEP_EA, MULTIPLES)
    seeds, steps = (1, 20) if args.quick else (args.seeds, args.steps)
    table = []
    print(f"{'EA [N]':>8} {'substeps':>8}  largest |E - E0 - W| per seed [J] (how it ended)")
    for EA in sweep:
        chosen = gym.make(esp_gym.ENV_ID, scene_overrides=overrides(EA), disable_env_checker=True).unwrapped
        for multiple in multiples:
            substeps = chosen.setup.substeps * multiple
            runs = [episode(EA, substeps, seed, steps) for seed in range(seeds)]
            table.append({"EA": EA, "multiple": multiple, "substeps": substeps, "runs": runs})
            shown = ", ".join(f"{r['worst']:.3g}" + (f" ({r['reason']} at {r['steps']})" if r["reason"] else "")
                              for r in runs)
            print(f"{EA:8.0e} {substeps:8d}  {shown}")
    finish(args.out, "implicit_energy", {"table": table, "seeds": seeds, "steps": steps, "noise": NOISE,
                                         "machine": machine("gymnasium")},
           {"implicit_energy.png": lambda path: _plot(table, path)}, start)
    return {"table": table}


def _plot(table: list, path) -> None:
    fig = figure((6, 3.6), dpi=130)
    ax = fig.subplots()
    for EA in sorted({row["EA"] for row in table}):
        rows = [row for row in table if row["EA"] == EA]
        ax.plot([row["multiple"] for row in rows], [max(r["worst"] for r in row["runs"]) for row in rows], "o-",
                label=f"EA = {EA:.0e} N")
    ax.axhline(0.05, color="grey", lw=0.8)
    ax.set(yscale="log", xlabel="substeps / the environment's choice", ylabel="largest |E - E0 - W| [J]",
           title="implicit string, PD law + noise")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path)


if __name__ == "__main__":
    main()
