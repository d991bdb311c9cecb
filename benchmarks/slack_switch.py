"""The explicit string's slack switch, settled against plain (docs/physics.md, "The slack switch of
the explicit string"): ``drone_load`` reeled in to 0.5 m at 1 m/s and held for ``--hold`` s
(the energy balance |E - E0 - W| over time, at the environment's winch step h and at h/2); the
balance's order over the reel and 1 s of holding (h ... h/16); ``lower`` at EA = 2e5 and 2e6 N
with the hoist's reel command switching +-1 every 25 control steps (``--steps`` control steps,
``--seeds`` seeds); and the resolution rule's string (``elements: auto``) at 0.35, 0.5 and 0.8 of
its stability bound under ``stabilize``'s PD law with +-0.5 action noise, 1,000 control steps,
seed 0. The energy watchdog is off throughout, so that a gain shows in full.

Prints the tables and writes ``OUT/slack_switch.json`` and ``OUT/slack_switch.png``.
Usage: ``python -m benchmarks.slack_switch [--quick] [--hold S] [--steps K] [--seeds N] [--out DIR]``.
"""
from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
from matplotlib.ticker import NullFormatter
from tqdm.auto import tqdm

import esp_gym
from agents.baselines.pd import AntiSwayPD, Hoist
from benchmarks.common import arg_parser, figure, finish, machine
from esp_gym.physics.watchdog import energy_scale

#: The environment's winch step for drone_load (choose_h(reeling=True): 71 steps per 20 ms).
WINCH_H = 0.02 / 71
SWITCHES = ("settled", "plain")
STIFF_EA = (2e5, 2e6)
#: The plain step is run held for at most this long [s] (it has blown up well before).
PLAIN_HOLD = 100.0


def reeled_and_held(switch: str, h: float, hold: float, every: float, bar=None) -> dict:
    """|E - E0 - W| [J] at the end of the reel and then every ``every`` s of holding (until the
    step fails: ``failed``, its message), and the length reeled to [m]."""
    scene = esp_gym.load_scene("drone_load", h=h, allow_unstable_h=True, **{"initial.direction": [0.3, 0.0, 1.0]},
                               solver={"energy_watchdog": None, "slack_switch": switch})
    weight = scene.gravity * (scene.body.mass + scene.pivot.mass + scene.string.length * scene.string.mass_per_length)
    sim = esp_gym.Simulator(scene)
    sim.step(int(round(0.5 / h)) + 10, reel_speed=-1.0, pivot_force=[0.0, 0.0, -weight])
    times, residual, failed, length = [0.0], [sim.diagnostics()["energy_balance_residual"]], "", sim.winch.length
    for k in range(int(round(hold / every))):
        try:
            sim.step(int(round(every / h)), pivot_force=[0.0, 0.0, -weight])
        except esp_gym.SimulationError as error:
            failed = str(error).split(";")[0]
            break
        times.append((k + 1) * every)
        residual.append(sim.diagnostics()["energy_balance_residual"])
        if bar is not None:
            bar.update(every)
    return {"switch": switch, "h": h, "t": times, "residual": residual, "failed": failed, "length": length}


def order(switch: str, halvings: int, hold: float) -> dict:
    """The largest |E - E0 - W| over the reel and ``hold`` s of holding, sampled every 0.1 s, at
    h / 2**i, and the fitted slope of its logarithm against log h."""
    hs = [WINCH_H / 2 ** i for i in range(halvings + 1)]
    worst = [float(np.abs(reeled_and_held(switch, h, hold, 0.1)["residual"]).max()) for h in hs]
    return {"switch": switch, "h": hs, "worst": worst, "slope": float(np.polyfit(np.log(hs), np.log(worst), 1)[0])}


def stiff_winch(switch: str, EA: float, seed: int, steps: int, string: str = "explicit", substeps=None) -> dict:
    """``lower`` at EA, the hoist with its reel command switching +-1 every 25 control steps (the
    ``string`` scheme, ``substeps`` per control step; None: the environment's): the largest
    |E - E0 - W| and its value at the end [J], the largest over the energy scale, the steps taken
    and how it ended."""
    solver = {"energy_watchdog": None, "slack_switch": switch, "string": string}
    env = gym.make(esp_gym.ENV_ID, task="lower", max_episode_steps=steps, disable_env_checker=True,
                   scene_overrides={"string": {"EA": EA}, "solver": solver},
                   **({} if substeps is None else {"h": 0.02 / substeps}))
    obs, _ = env.reset(seed=seed)
    u, hoist, worst, reason, k = env.unwrapped, Hoist(), 0.0, "", 0
    for k in range(1, steps + 1):
        action = hoist.act(obs, u.setup).astype(np.float64)
        action[-1] = 1.0 if ((k - 1) // 25) % 2 else -1.0
        obs, _, terminated, truncated, info = env.step(action.astype(np.float32))
        worst = max(worst, abs(u.sim.diagnostics()["energy_balance_residual"]))
        if terminated or truncated:
            reason = info.get("termination_reason", "") if terminated else ""
            break
    omega = float(np.linalg.norm(u.sim.diagnostics()["omega"]))
    return {"switch": switch, "string": string, "EA": EA, "seed": seed, "steps": k, "worst": worst,
            "final": float(u.sim.diagnostics()["energy_balance_residual"]),
            "over_scale": worst / energy_scale(u.scene), "reason": reason, "spin": omega,
            "substeps": int(u.setup.substeps)}


#: The resolution rule's EAs and step margins (esp_gym.scene.stepsize.SLACK_SAFETY is 0.35).
MARGIN_EA = (2e5, 2e6, 1e7)
MARGINS = (0.35, 0.5, 0.8)


def margin(switch: str, EA: float, safety: float, steps: int) -> dict:
    """The rule's string at EA, ``safety`` x its bound, under the PD law with +-0.5 noise: the
    largest |E - E0 - W| [J] over ``steps`` control steps, seed 0."""
    env = gym.make(esp_gym.ENV_ID, safety=safety, max_episode_steps=10 ** 6, disable_env_checker=True,
                   scene_overrides={"string": {"EA": EA, "elements": "auto"},
                                    "solver": {"slack_switch": switch, "energy_watchdog": None}})
    obs, _ = env.reset(seed=0)
    u, pd, rng, worst = env.unwrapped, AntiSwayPD(), np.random.default_rng(0), 0.0
    for _ in range(steps):
        action = np.clip(pd.act(obs, u.setup) + 0.5 * rng.uniform(-1, 1, 6), -1, 1)
        obs, _, terminated, _, _ = env.step(action.astype(np.float32))
        worst = max(worst, abs(u.sim.diagnostics()["energy_balance_residual"]))
        if terminated:
            break
    return {"switch": switch, "EA": EA, "safety": safety, "worst": worst, "substeps": int(u.setup.substeps),
            "elements": int(u.scene.string.elements)}


def main(argv=None) -> dict:
    parser = arg_parser(__doc__, "20 s held at h, order over h..h/4 and 0.2 s, 20 control steps at 2e5 N")
    parser.add_argument("--hold", type=float, default=1000.0, help="seconds held after the reel (settled)")
    parser.add_argument("--steps", type=int, default=2000, help="control steps per stiff-winch episode")
    parser.add_argument("--seeds", type=int, default=3, help="stiff-winch episodes per EA and switch")
    args = parser.parse_args(argv)
    if args.hold <= 0 or args.steps < 1 or args.seeds < 1:
        parser.error(f"--hold must be > 0, --steps and --seeds >= 1; got {args.hold}, {args.steps}, {args.seeds}")
    start = time.perf_counter()
    hold, steps, seeds = (20.0, 20, 1) if args.quick else (args.hold, args.steps, args.seeds)
    every = 1.0 if args.quick else 10.0
    runs = [(s, h, hold if s == "settled" else min(hold, PLAIN_HOLD)) for s, h in
            (("settled", WINCH_H), ("settled", WINCH_H / 2), ("plain", WINCH_H))]
    if args.quick:
        runs = runs[:1] + runs[2:]
    with tqdm(total=sum(r[2] for r in runs), unit="s held", desc="reeled and held") as bar:
        held = [reeled_and_held(s, h, t, every, bar) for s, h, t in runs]
    print(f"\nreeled in to 0.5 m and held (h = {WINCH_H:.3e} s, the environment's winch step)")
    print(f"{'switch':>8} {'h':>10} {'held [s]':>9} {'largest |E - E0 - W| [J]':>25} {'at the end [J]':>15}  ended")
    for run in held:
        res = np.abs(run["residual"])
        print(f"{run['switch']:>8} {run['h']:10.3e} {run['t'][-1]:9.0f} {res.max():25.3e} {run['residual'][-1]:15.3e}"
              f"  {run['failed'] or '-'}")
    halvings, window = (2, 0.2) if args.quick else (4, 1.0)
    orders = [order(s, halvings, window) for s in SWITCHES]
    print(f"\norder: the largest |E - E0 - W| over the reel and {window} s held, at h / 2^i")
    for row in orders:
        print(f"{row['switch']:>8}  " + "  ".join(f"{w:.2e}" for w in row["worst"]) + f"   slope {row['slope']:.2f}")
    sweep = STIFF_EA[:1] if args.quick else STIFF_EA
    winch = [stiff_winch(s, EA, seed, steps) for EA in sweep for s in SWITCHES for seed in range(seeds)]
    print(f"\nlower, the reel switching +-1 every 25 control steps ({steps} control steps)")
    print(f"{'EA [N]':>8} {'switch':>8} {'seed':>4} {'steps':>6} {'largest |E - E0 - W| [J]':>25} {'/ scale':>8} "
          f"{'spin [rad/s]':>12}  ended")
    for row in winch:
        print(f"{row['EA']:8.0e} {row['switch']:>8} {row['seed']:4d} {row['steps']:6d} {row['worst']:25.3e} "
              f"{row['over_scale']:8.4f} {row['spin']:12.2f}  {row['reason'] or '-'}")
    margin_ea, margins, margin_steps = ((2e5,), (0.35,), 20) if args.quick else (MARGIN_EA, MARGINS, 1000)
    rule = [margin(s, EA, m, margin_steps) for EA in margin_ea for m in margins for s in SWITCHES]
    print(f"\nthe resolution rule's string, PD law + noise, {margin_steps} control steps: largest |E - E0 - W| [J]")
    print(f"{'EA [N]':>8} {'N':>3} " + " ".join(f"{f'{m} x bound (settled / plain)':>30}" for m in margins))
    for EA in margin_ea:
        rows = {(r["safety"], r["switch"]): r for r in rule if r["EA"] == EA}
        print(f"{EA:8.0e} {rows[(margins[0], 'settled')]['elements']:3d} " + " ".join(
            f"{rows[(m, 'settled')]['worst']:>14.2e} / {rows[(m, 'plain')]['worst']:<13.2e}" for m in margins))
    payload = {"held": held, "order": orders, "stiff_winch": winch, "rule_margins": rule, "winch_h": WINCH_H,
               "machine": machine("gymnasium")}
    finish(args.out, "slack_switch", payload, {"slack_switch.png": lambda path: _plot(held, orders, path)}, start)
    return payload


def _plot(held: list, orders: list, path) -> None:
    fig = figure((9, 3.6), dpi=130)
    left, right = fig.subplots(1, 2)
    for run in held:
        t = np.asarray(run["t"])
        res = np.maximum(np.abs(run["residual"]), 1e-12)
        left.plot(t, res, label=f"{run['switch']}, h = {run['h']:.2e} s" + (" (fails)" if run["failed"] else ""))
    left.set(yscale="log", xlabel="time held [s]", ylabel="|E - E0 - W| [J]", title="drone_load reeled to 0.5 m, held")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=7)
    for row in orders:
        right.loglog(row["h"], row["worst"], "o-", label=f"{row['switch']} (slope {row['slope']:.2f})")
    h = np.asarray(orders[0]["h"])
    right.loglog(h, orders[0]["worst"][0] * (h / h[0]) ** 2, "k:", lw=0.8, label="h^2")
    right.xaxis.set_minor_formatter(NullFormatter())
    right.set(xlabel="h [s]", ylabel="largest |E - E0 - W| [J]", title="reel and 1 s held")
    right.grid(True, which="both", alpha=0.3)
    right.legend(fontsize=7)
    fig.savefig(path)


if __name__ == "__main__":
    main()
