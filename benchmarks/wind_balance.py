"""The balances of ElasticStringPendulum-v0 with wind and pushes, at halved physics steps.

One seeded, gusty episode (6 m/s mean wind, 1.5 m/s gusts, five pushes a second, actions
uniform in +-0.3) is run with h = 20 ms / 36, / 72, ... ; for each h it prints the worst
|E - E0 - W| over the episode, the observed order log2 of consecutive ratios, the total work W
and the worst momentum and pi3 balance residuals at the end. Writes
``OUT/wind_balance.json`` and ``OUT/wind_balance.png`` (OUT = benchmarks/out unless ``--out``).
Usage: ``python -m benchmarks.wind_balance [--quick] [--steps K] [--halvings H] [--out DIR]``.
"""
from __future__ import annotations

import math
import time

import gymnasium as gym
import numpy as np

import esp_gym  # noqa: F401  (registers the env)
from benchmarks.common import arg_parser, figure, finish, machine

WIND = {"speed": 6.0, "gust_std": 1.5, "push_rate": 5.0}


def balances(substeps: int, steps: int, seed: int = 3) -> dict:
    """The balances of one episode with ``substeps`` physics steps per 20 ms control step: the
    worst |E - E0 - W| over it [J], and at its end W [J], the largest momentum balance residual
    [kg m/s], |pi3 balance residual| [kg m^2/s] and the external impulse [kg m/s]
    (tests/test_wind.py asserts on them)."""
    env = gym.make("ElasticStringPendulum-v0", h=0.02 / substeps, wind=WIND).unwrapped
    env.reset(seed=seed)
    actions = 0.3 * np.random.default_rng(0).uniform(-1, 1, (steps, 6))
    worst = 0.0
    for a in actions:
        env.step(a)
        d = env.sim.diagnostics()
        worst = max(worst, abs(d["energy_balance_residual"]))
    return {"h_s": 0.02 / substeps, "energy_residual_J": worst, "work_J": d["work"],
            "momentum_residual": float(np.abs(d["momentum_balance_residual"]).max()),
            "pi3_residual": abs(d["pi3_balance_residual"]),
            "external_impulse": d["external_impulse"].tolist()}


def main(argv=None) -> int:
    parser = arg_parser(__doc__)
    parser.add_argument("--steps", type=int, default=100, help="control steps (default: %(default)s)")
    parser.add_argument("--halvings", type=int, default=3, help="halvings of h (default: %(default)s)")
    args = parser.parse_args(argv)
    steps, halvings = (10, 1) if args.quick else (args.steps, args.halvings)
    start = time.perf_counter()
    rows = [balances(36 * 2 ** i, steps) for i in range(halvings + 1)]
    print(f"{'h [us]':>8} {'max|E-E0-W| [J]':>16} {'order':>6} {'W [J]':>9} {'momentum':>9} {'pi3':>9}")
    for i, row in enumerate(rows):
        order = "" if i == 0 else f"{math.log2(rows[i - 1]['energy_residual_J'] / row['energy_residual_J']):.2f}"
        row["order"] = None if i == 0 else float(order)
        print(f"{1e6 * row['h_s']:8.1f} {row['energy_residual_J']:16.3e} {order:>6} {row['work_J']:9.4f} "
              f"{row['momentum_residual']:9.1e} {row['pi3_residual']:9.1e}")
    payload = {"settings": {"steps": steps, "halvings": halvings, "wind": WIND, "quick": args.quick},
               "rows": rows, "machine": machine(), "total_wall_s": time.perf_counter() - start}
    finish(args.out, "wind_balance", payload, {"wind_balance.png": lambda path: plot(rows, path)}, start)
    return 0


def plot(rows: list, path) -> None:
    fig = figure((5.5, 4.0), dpi=130)
    ax = fig.subplots()
    h = np.array([r["h_s"] for r in rows])
    e = np.array([r["energy_residual_J"] for r in rows])
    ax.loglog(h, e, "o-", label="max |E - E0 - W|")
    ax.loglog(h, e[0] * (h / h[0]) ** 2, "k--", lw=0.8, label="slope 2")
    ax.set_xlabel("h [s]")
    ax.set_ylabel("energy balance residual [J]")
    ax.set_title("wind and pushes: energy balance")
    ax.legend()
    fig.savefig(path)


if __name__ == "__main__":
    raise SystemExit(main())
