"""A team's long-run energy balance under its own baselines with action noise, settled against plain
(docs/physics.md, "The slack switch of a team's strings"; issue 54, item 2): point teams of K = 2..6
on ``transport`` under the LQR, K = 3 on ``lift`` under the hoist, and a drone team of K = 6 on
``transport`` under the cascade, each action plus ``--noise`` x uniform(-1, 1) noise (clipped),
``--seconds`` of control steps from one reset (past the episode's 10 s: the core is stepped on),
seed ``--seed``. The largest |E - E0 - W| over the run, its value at the end and the slope of a
straight line fitted to E - E0 - W against time (a trend), all from every control step; the
watchdog is off, so that a gain shows in full. Settled and plain at the environment's default
``safety`` (h within that fraction of every string's stability bound), then settled at each
smaller ``--safety`` (its convergence in h).

Prints the table and writes ``OUT/team_energy.json`` and ``OUT/team_energy.png``.
Usage: ``python -m benchmarks.team_energy [--quick] [--seconds S] [--noise A] [--seed N]
[--safety S ...] [--out DIR]``.
"""
from __future__ import annotations

import time

import numpy as np
from tqdm.auto import tqdm

from agents.evaluate import ONE_BLAS_THREAD
from agents.team.evaluate import team_baselines
from benchmarks.common import arg_parser, figure, finish, machine
from esp_gym.team.env import ElasticStringTeamEnv
from esp_gym.team.scene import TEAM_SAFETY, team_scene
from esp_gym.physics.watchdog import team_energy_scale

SWITCHES = ("settled", "plain")
#: The settled runs' smaller safeties by default (each halves h, and doubles the physics steps).
REFINED = (0.25, 0.125)
#: The team env's default control period [s] (the progress bar's unit).
CONTROL_PERIOD = 0.02
#: The JSON keeps E - E0 - W every this many control steps (and the last); the table is of all.
SAMPLE = 25
#: (name, strings, task, drones, baseline) of each run.
RUNS = [(f"transport K={k}", k, "transport", False, "lqr") for k in range(2, 7)] + [
    ("lift K=3", 3, "lift", False, "hoist"), ("drones transport K=6", 6, "transport", True, "cascade")]


def with_solver(team, **solver):
    """``team`` (a TeamScene) with its lead scene's solver updated by ``solver``."""
    lead = team.scene
    return team.model_copy(update={"scene": lead.model_copy(update={"solver": lead.solver.model_copy(update=solver)})})


@ONE_BLAS_THREAD
def run(name: str, size: int, task: str, drones: bool, baseline: str, switch: str, seconds: float, noise: float,
        seed: int, bar=None, safety: float = TEAM_SAFETY) -> dict:
    """One run: E - E0 - W [J] after every control step, its time [s], how it ended."""
    team = with_solver(team_scene(size, drones=drones), slack_switch=switch, energy_watchdog=None)
    options = {"actuation": "thrust_rates"} if drones else {}
    env = ElasticStringTeamEnv(team, task=task, safety=safety, **options)
    obs, _ = env.reset(seed=seed)
    core = env.core
    policy = team_baselines("full", drones, task == "lift")[baseline]
    if hasattr(policy, "reset"):
        policy.reset()
    rng = np.random.default_rng(seed)
    times, residual, reason = [0.0], [0.0], ""
    for k in range(int(round(seconds / core.control_period))):
        action = np.clip(policy.act(obs, core) + noise * rng.uniform(-1.0, 1.0, env.action_space.shape), -1.0, 1.0)
        obs, _, terminated, _, info = env.step(action.astype(np.float32))
        d = core.sim.diagnostics()
        times.append((k + 1) * core.control_period)
        residual.append(d["energy_balance_residual"])
        if bar is not None:
            bar.update(1)
        if terminated:
            reason = info["termination_reason"]
            break
    res = np.asarray(residual)
    slope = float(np.polyfit(times, res, 1)[0]) if len(times) > 2 else 0.0
    kept = sorted(set(range(0, len(times), SAMPLE)) | {len(times) - 1})  # the series as written
    return {"run": name, "switch": switch, "safety": safety, "K": size, "task": task, "baseline": baseline, "h": core.sim.h,
            "scale": team_energy_scale(team), "t": [times[i] for i in kept], "residual": [residual[i] for i in kept],
            "worst": float(np.abs(res).max()),
            "end": float(res[-1]), "slope_per_min": 60.0 * slope, "reason": reason}


def main(argv=None) -> dict:
    parser = arg_parser(__doc__, "K = 2 transport only, 1 s")
    parser.add_argument("--seconds", type=float, default=60.0, help="seconds of control steps per run")
    parser.add_argument("--noise", type=float, default=0.3, help="the action noise's amplitude")
    parser.add_argument("--seed", type=int, default=200, help="the reset's and the noise's seed")
    parser.add_argument("--safety", type=float, nargs="*", default=list(REFINED), metavar="S",
                        help=f"the settled runs again at each of these safeties, below the default {TEAM_SAFETY:g} "
                             f"(default: {' '.join(map(str, REFINED))})")
    args = parser.parse_args(argv)
    if args.seconds <= 0 or not 0 <= args.noise <= 1:
        parser.error(f"--seconds must be > 0 and --noise in [0, 1]; got {args.seconds}, {args.noise}")
    if not all(0 < s < TEAM_SAFETY for s in args.safety):
        parser.error(f"--safety: each in (0, {TEAM_SAFETY:g}), got {args.safety}")
    start = time.perf_counter()
    runs, seconds, refined = (RUNS[:1], 1.0, []) if args.quick else (RUNS, args.seconds, args.safety)
    steps = int(round(seconds / CONTROL_PERIOD))
    cases = [(switch, TEAM_SAFETY) for switch in SWITCHES] + [("settled", s) for s in refined]
    with tqdm(total=len(runs) * len(cases) * steps, unit="step", desc="team energy") as bar:
        rows = [run(*spec, switch, seconds, args.noise, args.seed, bar, safety) for spec in runs
                for switch, safety in cases]
    print(f"\n{seconds:g} s under each baseline + {args.noise:g} x uniform action noise, seed {args.seed}")
    print(f"{'run':>22} {'switch':>8} {'safety':>7} {'largest |E - E0 - W| [J]':>25} {'at the end [J]':>15} "
          f"{'trend [J/min]':>14} {'/ scale':>8}  ended")
    for row in rows:
        ended = f"{row['reason']} at {row['t'][-1]:.1f} s" if row["reason"] else "-"
        print(f"{row['run']:>22} {row['switch']:>8} {row['safety']:7.3g} {row['worst']:25.3e} {row['end']:15.3e} "
              f"{row['slope_per_min']:14.2e} {row['worst'] / row['scale']:8.1e}  {ended}")
    payload = {"runs": rows, "seconds": seconds, "noise": args.noise, "seed": args.seed, "safety": TEAM_SAFETY,
               "machine": machine("gymnasium")}
    finish(args.out, "team_energy", payload, {"team_energy.png": lambda path: _plot(rows, path)}, start)
    return payload


def _plot(rows: list, path) -> None:
    """Settled and plain at the default safety over time; each run's largest residual against the
    safety (settled)."""
    fig = figure((13, 3.6), dpi=130)
    axes = fig.subplots(1, 3)
    for ax, switch in zip(axes, SWITCHES):
        for row in rows:
            if row["switch"] == switch and row["safety"] == TEAM_SAFETY:
                ax.plot(row["t"], row["residual"], lw=0.8, label=row["run"])
        ax.set(xlabel="time [s]", title=f"{switch} switch, safety {TEAM_SAFETY:g}")
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("E - E0 - W [J]")
    axes[0].legend(fontsize=6)
    ax = axes[2]
    for name in dict.fromkeys(row["run"] for row in rows):
        points = sorted((row["safety"], row["worst"]) for row in rows if row["run"] == name and row["switch"] == "settled")
        ax.loglog(*zip(*points), "o-", lw=0.8, ms=3, label=name)
    ax.set(xlabel="safety (h / stability bound)", ylabel="largest |E - E0 - W| [J]", title="settled, against h")
    ax.grid(True, which="both", alpha=0.3)
    fig.savefig(path)


if __name__ == "__main__":
    main()
