"""The implicit string's energy balance under a controller, by form and step: ``drone_load`` at
each EA with ``solver.string: implicit``, ``stabilize``'s PD law plus uniform action noise of
+-0.5, ``--seeds`` episodes of ``--steps`` control steps (the energy watchdog off, so that a gain
shows in full); the largest |E - E0 - W| of each episode and how it ended, for the energy-momentum
form (the default) at 1/4, 1/2 and 1 times the substeps the environment chooses and the
variational form at 1, 2 and 4 times (docs/physics.md, "The energy-momentum form", "The
transverse step"). Then the winch: ``lower`` at EA = 2e3 and 2e5 N, the hoist with its reel
command switching +-1 every 25 control steps, no noise, 2,000 control steps, the energy-momentum
form at 1, 2 and 4 times the environment's substeps, against the explicit string's settled switch
at its own step: the balance at the end (docs/physics.md, "The implicit string too").

Prints a table and writes ``OUT/implicit_energy.json`` and ``OUT/implicit_energy.png``.
Usage: ``python -m benchmarks.implicit_energy [--quick] [--seeds K] [--steps S] [--out DIR]``.
"""
from __future__ import annotations

import time

import gymnasium as gym
import matplotlib.ticker
import numpy as np

import esp_gym
from agents.baselines.pd import AntiSwayPD
from benchmarks.common import arg_parser, figure, finish, machine
from benchmarks.slack_switch import stiff_winch

SWEEP_EA = (2e5, 2e6, 1e7)
#: The substeps of each form, in multiples of the environment's choice.
MULTIPLES = {"energy_momentum": (0.25, 0.5, 1), "variational": (1, 2, 4)}
NOISE = 0.5


def overrides(EA: float, form: str = "energy_momentum") -> dict:
    return {"string": {"EA": EA}, "solver": {"string": "implicit", "implicit_form": form, "energy_watchdog": None}}


def episode(EA: float, substeps: int, seed: int, steps: int, form: str = "energy_momentum") -> dict:
    """The largest |E - E0 - W| [J] (every 10th control step), the steps taken and the
    termination reason ("" for none)."""
    env = gym.make(esp_gym.ENV_ID, h=0.02 / substeps, scene_overrides=overrides(EA, form), max_episode_steps=steps,
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


WINCH_EA = (2e3, 2e5)
WINCH_MULTIPLES = (1, 2, 4)


def reversing_reel(EA: float, substeps, steps: int, string: str = "implicit") -> dict:
    """``lower`` at EA with the reel reversing every 25 control steps, seed 0
    (:func:`benchmarks.slack_switch.stiff_winch`; ``substeps`` per control step, None: the
    environment's): the balance E - E0 - W [J] at the end (``residual``), the steps and substeps."""
    run = stiff_winch("settled", EA, 0, steps, string, substeps)
    return {"EA": EA, "string": string, "substeps": run["substeps"], "steps": run["steps"], "residual": run["final"]}


def main(argv=None) -> dict:
    parser = arg_parser(__doc__, "EA = 2e5 N, 1x and 2x the substeps, one seed of 20 control steps")
    parser.add_argument("--seeds", type=int, default=3, help="episodes per EA and step")
    parser.add_argument("--steps", type=int, default=1000, help="control steps per episode")
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.steps < 1:
        parser.error(f"--seeds and --steps must be >= 1, got {args.seeds} and {args.steps}")
    start = time.perf_counter()
    sweep = SWEEP_EA[:1] if args.quick else SWEEP_EA
    multiples = {form: m[-2:] for form, m in MULTIPLES.items()} if args.quick else MULTIPLES
    seeds, steps = (1, 20) if args.quick else (args.seeds, args.steps)
    table = []
    print(f"{'EA [N]':>8} {'form':>16} {'substeps':>8}  largest |E - E0 - W| per seed [J] (how it ended)")
    for EA in sweep:
        chosen = gym.make(esp_gym.ENV_ID, scene_overrides=overrides(EA), disable_env_checker=True).unwrapped
        for form, form_multiples in multiples.items():
            for multiple in form_multiples:
                substeps = max(1, round(chosen.setup.substeps * multiple))
                runs = [episode(EA, substeps, seed, steps, form) for seed in range(seeds)]
                table.append({"EA": EA, "form": form, "multiple": multiple, "substeps": substeps, "runs": runs})
                shown = ", ".join(f"{r['worst']:.3g}" + (f" ({r['reason']} at {r['steps']})" if r["reason"] else "")
                                  for r in runs)
                print(f"{EA:8.0e} {form:>16} {substeps:8d}  {shown}")
    winch_sweep, winch_multiples, winch_steps = ((2e5,), (1,), 20) if args.quick else (WINCH_EA, WINCH_MULTIPLES, 2000)
    winch = []
    print(f"{'EA [N]':>8} {'string':>9} {'substeps':>8}  E - E0 - W after {winch_steps} steps, the reel reversing [J]")
    for EA in winch_sweep:
        chosen = reversing_reel(EA, None, 1)["substeps"]
        rows = [reversing_reel(EA, chosen * m, winch_steps) for m in winch_multiples]
        rows.append(reversing_reel(EA, None, winch_steps, "explicit"))
        winch += rows
        for row in rows:
            print(f"{EA:8.0e} {row['string']:>9} {row['substeps']:8d}  {row['residual']:.3g}")
    finish(args.out, "implicit_energy", {"table": table, "winch": winch, "seeds": seeds, "steps": steps,
                                         "noise": NOISE, "machine": machine("gymnasium")},
           {"implicit_energy.png": lambda path: _plot(table, path)}, start)
    return {"table": table, "winch": winch}


def _plot(table: list, path) -> None:
    fig = figure((6, 3.6), dpi=130)
    ax = fig.subplots()
    for form, style in (("energy_momentum", "o-"), ("variational", "s--")):
        for EA in sorted({row["EA"] for row in table}):
            rows = [row for row in table if row["EA"] == EA and row["form"] == form]
            ax.plot([row["multiple"] for row in rows], [max(r["worst"] for r in row["runs"]) for row in rows], style,
                    label=f"{form}, EA = {EA:.0e} N")
    ax.axhline(0.05, color="grey", lw=0.8)
    ticks = sorted({row["multiple"] for row in table})
    ax.set(xscale="log", yscale="log", xlabel="substeps / the environment's choice",
           ylabel="largest |E - E0 - W| [J]", title="implicit string, PD law + noise")
    ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
    ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path)


if __name__ == "__main__":
    main()
