"""The resolution rule (``string.elements: auto``, esp_gym.choose_resolution) measured under its
protocol, at each EA of the sweep on ``drone_load``:

* accuracy: the task's baseline in closed loop (``stabilize``'s PD law, agents.baselines.pd) plus
  uniform action noise of +-0.5 (its own seed), ``--seeds`` episodes of 4 s; the load's centre of
  mass and the pivot at every control step against a converged reference (N = 32 at an eighth of
  the rule's step, and at most a quarter of N = 32's stability bound), largest distance over the
  run; median and worst over the seeds. The reference's own floor: the same reference against one
  at about twice its step (median over the seeds; an upper bound of the reference's own error);
* energy: 100 s of the protocol and 100 s of random actions (episodes restart where they end;
  each restart resets the balance), the largest |E - E0 - W| and its largest per 20 s window (a
  trend shows as windows that grow), and the physics failures.

With ``--drone`` (alone) the drone's own step error instead (esp_gym/scene/stepsize.py
``drone_step_error``): ``quadrotor_load`` at the rule's N with its rate loop at DRONE_RATE_LOOP,
the geometric cascade (agents.baselines.geometric) in ``thrust_rates`` plus +-0.5 action noise,
``--seeds`` episodes of 4 s, the drone and the load at DRONE_STEPS steps per 20 ms against
DRONE_REFERENCE (median and worst over the seeds), beside the rule's prediction; and the same
with the loop at every physics step (order 1). Writes ``OUT/resolution_drone.json``.

With ``--implicit`` (and ``--damping TAU``) the implicit string as the rule's scheme instead
(docs/physics.md, "The string's resolution"): at IMPLICIT_EA, the rule's N stepped by the
implicit string at IMPLICIT_STEPS steps per 20 ms, each against the same reference as the rule's
explicit choice, median and worst over ``--seeds``, and the env steps/s of each and of the
explicit rule (random actions, the median of 3). Writes ``OUT/resolution_implicit.json``.

With ``--damping TAU`` every string (the rule's, the reference's and its floor's) is damped,
``string.damping_time`` TAU [s] (docs/physics.md, "Material damping"), the balance is
|E - E0 - W + D|, and the files are ``OUT/resolution_damped.json`` and ``.png``.

Prints tables and writes ``OUT/resolution.json`` and ``OUT/resolution.png``.
Usage: ``python -m benchmarks.resolution [--quick] [--seeds K] [--damping TAU] [--drone | --implicit] [--out DIR]``.
"""
from __future__ import annotations

import math
import time

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import esp_gym
from agents.baselines.geometric import geometric_controller
from agents.baselines.pd import AntiSwayPD
from benchmarks.common import arg_parser, figure, finish, machine, single_env_rate
from esp_gym.scene.stepsize import dissipation_drift, drone_step_error

#: The EAs of the sweep [N] (benchmarks/env_throughput.py --ea-sweep runs the same).
SWEEP_EA = (2e2, 2e3, 2e4, 2e5, 2e6, 1e7)
CONTROL_PERIOD = 0.02
#: The protocol: action noise amplitude and horizon [s].
NOISE, HORIZON = 0.5, 4.0
REFERENCE_ELEMENTS = 32
#: ``--drone``: the rate loop's period [s] (PX4's default gyroscope rate, 800 Hz), the steps per
#: control step measured and the reference's.
DRONE_RATE_LOOP = 1.0 / 800.0
DRONE_STEPS = (16, 32, 64, 128)
DRONE_REFERENCE = 512
#: ``--implicit``: the EAs [N] and the implicit string's steps per control step.
IMPLICIT_EA = (2e5, 2e6, 1e7)
IMPLICIT_STEPS = (1, 2, 8, 32)


def make(overrides: dict, h=None, safety=None):
    return gym.make(esp_gym.ENV_ID, scene_overrides=overrides, h=h, safety=safety, max_episode_steps=10 ** 7,
                    disable_env_checker=True)


def protocol_paths(overrides: dict, h, seed: int, steps: int):
    """Load centre of mass and pivot (steps + 1, 3) under the PD law plus noise, the energy
    balance's largest |residual|, and the termination reason (None: ran through)."""
    env = make(overrides, h)
    u = env.unwrapped
    rho = np.asarray(u.scene.body.rho_c)
    obs, _ = env.reset(seed=seed)
    pd, rng = AntiSwayPD(), np.random.default_rng(10_000 + seed)
    load, pivot = np.full((steps + 1, 3), np.nan), np.full((steps + 1, 3), np.nan)
    worst = 0.0
    for k in range(steps + 1):
        state = u.sim.state
        load[k], pivot[k] = state.r[-1] + state.R @ rho, state.r[0]
        worst = max(worst, abs(u.sim.diagnostics()["energy_balance_residual"]))
        if k == steps:
            break
        action = np.clip(pd.act(obs, u.setup) + NOISE * rng.uniform(-1, 1, 6), -1, 1).astype(np.float32)
        obs, _, terminated, _, info = env.step(action)
        if terminated:
            return load, pivot, worst, info["termination_reason"]
    return load, pivot, worst, None


def drone_paths(rate_period, substeps: int, seed: int, steps: int) -> tuple:
    """The drone's and the load's centre of mass (steps + 1, 3 each) of ``quadrotor_load`` at the
    rule's N under the geometric cascade plus noise, ``substeps`` steps per control step, the rate
    loop every ``rate_period`` [s] (None: every step); NaN after an episode's end."""
    overrides = {"string": {"elements": "auto"}, "pivot": {"drone": {"rate_loop_period": rate_period}}}
    env = gym.make(esp_gym.ENV_ID, scene="quadrotor_load", actuation="thrust_rates", scene_overrides=overrides,
                   h=CONTROL_PERIOD / substeps, max_episode_steps=10 ** 7, disable_env_checker=True)
    u = env.unwrapped
    controller = geometric_controller("stabilize", "thrust_rates")
    obs, _ = env.reset(seed=seed)
    controller.reset(u)
    rng = np.random.default_rng(10_000 + seed)
    drone, load = np.full((steps + 1, 3), np.nan), np.full((steps + 1, 3), np.nan)
    for k in range(steps + 1):
        drone[k], load[k] = u.sim.state.r[0], u.load_position()
        if k == steps:
            break
        noise = NOISE * rng.uniform(-1, 1, env.action_space.shape[0])
        obs, _, terminated, _, _ = env.step(np.clip(controller.act(obs, u.setup) + noise, -1, 1).astype(np.float32))
        if terminated:
            break
    return drone, load


def drone_accuracy(seeds: int, substeps=DRONE_STEPS) -> list:
    """Rows per rate loop (sampled, every step) and steps per control step: the largest distance
    of the drone and of the load to the reference's, median and worst over ``seeds``, and the
    rule's predicted drone error."""
    steps = int(round(HORIZON / CONTROL_PERIOD))
    scene = esp_gym.load_scene("quadrotor_load", string={"elements": "auto"},
                               pivot={"drone": {"rate_loop_period": DRONE_RATE_LOOP}})
    rows = []
    for period in tqdm((DRONE_RATE_LOOP, None), desc="rate loops"):
        errors = {n: [] for n in substeps}
        for seed in range(seeds):
            ref_drone, ref_load = drone_paths(period, DRONE_REFERENCE, seed, steps)
            for n in substeps:
                drone, load = drone_paths(period, n, seed, steps)
                errors[n].append(max(distance(drone, ref_drone), distance(load, ref_load)))
        for n in substeps:
            rows.append({"rate_loop_period": period, "substeps": n, "error_median": float(np.median(errors[n])),
                         "error_worst": max(errors[n]),
                         "predicted": drone_step_error(scene, CONTROL_PERIOD / n, HORIZON) if period else None})
    return rows


def drone_main(args, start: float) -> dict:
    rows = drone_accuracy(2 if args.quick else args.seeds, DRONE_STEPS[:2] if args.quick else DRONE_STEPS)
    print(f"\nquadrotor_load, geometric cascade + +-{NOISE} noise, {HORIZON:g} s: the drone's and the load's largest "
          f"distance to {DRONE_REFERENCE} steps per 20 ms [mm]")
    print("rate loop      steps | median  worst | predicted")
    for row in rows:
        loop = f"{1 / row['rate_loop_period']:.0f} Hz" if row["rate_loop_period"] else "every step"
        predicted = f"{1e3 * row['predicted']:9.2f}" if row["predicted"] is not None else "        -"
        print(f"{loop:12s} {row['substeps']:7d} | {1e3 * row['error_median']:6.2f} {1e3 * row['error_worst']:6.2f} | "
              f"{predicted}")
    finish(args.out, "resolution_drone", {"rows": rows, "reference_substeps": DRONE_REFERENCE, "horizon": HORIZON,
                                          "noise": NOISE, "machine": machine("gymnasium")}, {}, start)
    return {"rows": rows}


def implicit_accuracy(ea: float, seeds: int, damping: float, substeps=IMPLICIT_STEPS) -> dict:
    """The rule's explicit choice and the implicit string at the rule's N and ``substeps`` steps
    per control step: the load's largest distance to the reference (median, worst over
    ``seeds``) and env steps/s."""
    damped = {"damping_time": damping} if damping else {}
    auto = {"string": {"EA": ea, "elements": "auto", **damped}}
    u = make(auto).unwrapped
    elements, rule_h = u.scene.string.elements, u.scene.h
    implicit = {"string": {"EA": ea, "elements": elements, **damped}, "solver": {"string": "implicit"}}
    reference = {"string": {"EA": ea, "elements": REFERENCE_ELEMENTS, **damped}}
    h_ref, steps = reference_h(ea, rule_h), int(round(HORIZON / CONTROL_PERIOD))
    runs = {"explicit": (auto, None), **{f"implicit {n}": (implicit, CONTROL_PERIOD / n) for n in substeps}}
    errors = {name: [] for name in runs}
    for seed in range(seeds):
        ref_load, _, _, _ = protocol_paths(reference, h_ref, seed, steps)
        for name, (overrides, h) in runs.items():
            errors[name].append(distance(protocol_paths(overrides, h, seed, steps)[0], ref_load))
    rows = {name: {"substeps": u.setup.substeps if h is None else int(round(CONTROL_PERIOD / h)),
                   "error_median": float(np.median(errors[name])), "error_worst": max(errors[name]),
                   "steps_per_s": single_env_rate(lambda o=overrides, h=h: make(o, h).unwrapped, 2000, True, 3)}
            for name, (overrides, h) in runs.items()}
    return {"EA": ea, "elements": elements, "runs": rows}


def implicit_main(args, start: float) -> dict:
    sweep = IMPLICIT_EA[:1] if args.quick else IMPLICIT_EA
    seeds = 1 if args.quick else args.seeds
    table = [implicit_accuracy(ea, seeds, args.damping, IMPLICIT_STEPS[:2] if args.quick else IMPLICIT_STEPS)
             for ea in tqdm(sweep, desc="EA", disable=args.quick)]
    print(f"\nthe implicit string at the rule's N against the explicit rule, {seeds} seeds of the protocol, "
          f"damping time {args.damping:g} s: load error median / worst [mm], env steps/s")
    for row in table:
        cells = "  ".join(f"{name} ({r['substeps']}): {1e3 * r['error_median']:.2f} / {1e3 * r['error_worst']:.2f}, "
                          f"{r['steps_per_s']:,.0f}" for name, r in row["runs"].items())
        print(f"{row['EA']:8.0e} N = {row['elements']}: {cells}")
    finish(args.out, "resolution_implicit", {"table": table, "seeds": seeds, "damping_time": args.damping,
                                             "machine": machine("gymnasium")}, {}, start)
    return {"table": table}


def reference_h(ea: float, rule_h: float) -> float:
    scene = esp_gym.load_scene("drone_load", EA=ea, N=REFERENCE_ELEMENTS, allow_unstable_h=True)
    h = min(rule_h / 8.0, 0.25 * scene.stability_bound)
    return CONTROL_PERIOD / math.ceil(CONTROL_PERIOD / h - 1e-9)


def distance(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.nanmax(np.linalg.norm(a - b, axis=1)))


def accuracy(ea: float, seeds: int, bar, damping: float = 0.0) -> dict:
    damped = {"damping_time": damping} if damping else {}
    auto = {"string": {"EA": ea, "elements": "auto", **damped}}
    u = make(auto).unwrapped
    rule_h, elements = u.scene.h, u.scene.string.elements
    ref_over = {"string": {"EA": ea, "elements": REFERENCE_ELEMENTS, **damped}}
    h_ref = reference_h(ea, rule_h)
    coarse_h = CONTROL_PERIOD / max(1, int(round(CONTROL_PERIOD / h_ref)) // 2)  # about twice h_ref
    steps = int(round(HORIZON / CONTROL_PERIOD))
    loads, pivots, floors, energies, failures = [], [], [], [], []
    for seed in range(seeds):
        load, pivot, energy, failed = protocol_paths(auto, None, seed, steps)
        ref_load, ref_pivot, _, _ = protocol_paths(ref_over, h_ref, seed, steps)
        coarse_load, _, _, _ = protocol_paths(ref_over, coarse_h, seed, steps)
        loads.append(distance(load, ref_load))
        pivots.append(distance(pivot, ref_pivot))
        floors.append(distance(ref_load, coarse_load))
        energies.append(energy)
        failures.append(failed)
        bar.update()
    return {"EA": ea, "elements": elements, "substeps": int(round(CONTROL_PERIOD / rule_h)), "h": rule_h,
            "reference_h": h_ref, "load_error_median": float(np.median(loads)), "load_error_worst": max(loads),
            "pivot_error_worst": max(pivots), "reference_floor_median": float(np.median(floors)),
            "energy_residual_worst_4s": max(energies), "failures": [f for f in failures if f]}


def long_run(ea: float, mode: str, seconds: float, damping: float = 0.0, h=None, safety=None) -> dict:
    """``seconds`` of the PD law with noise or of random actions (``mode`` "random") on drone_load
    at ``ea`` [N] with ``elements: auto``, the rule's step or ``h`` [s] or ``safety``: the largest
    |E - E0 - W + D| [J] per 20 s window (the balance restarting with each episode), the physics
    failures, the episodes, the last dissipation [J] and the rule's predicted drift over 100 s
    (esp_gym.scene.stepsize.dissipation_drift)."""
    env = make({"string": {"EA": ea, "elements": "auto", **({"damping_time": damping} if damping else {})}},
               h, safety)
    u = env.unwrapped
    obs, _ = env.reset(seed=0)
    pd, rng = AntiSwayPD(), np.random.default_rng(0)
    steps, window = int(round(seconds / CONTROL_PERIOD)), int(round(min(20.0, seconds) / CONTROL_PERIOD))
    windows, current, failures, episodes = [], 0.0, 0, 1
    for k in range(steps):
        if mode == "random":
            action = rng.uniform(-1, 1, 6)
        else:
            action = np.clip(pd.act(obs, u.setup) + NOISE * rng.uniform(-1, 1, 6), -1, 1)
        obs, _, terminated, _, info = env.step(action.astype(np.float32))
        current = max(current, abs(u.sim.diagnostics()["energy_balance_residual"]))
        if (k + 1) % window == 0 or k + 1 == steps:
            windows.append(current)
            current = 0.0
        if terminated:
            failures += info["termination_reason"].startswith("physics")
            obs, _ = env.reset()
            episodes += 1
    return {"EA": ea, "mode": mode, "seconds": seconds, "worst": max(windows), "windows": windows,
            "failures": failures, "episodes": episodes, "dissipation": u.sim.diagnostics()["dissipation"],
            "predicted_drift": dissipation_drift(u.scene, u.scene.h)}


def main(argv=None) -> dict:
    parser = arg_parser(__doc__)
    parser.add_argument("--seeds", type=int, default=10, help="episodes per EA for the accuracy (default 10)")
    parser.add_argument("--damping", type=float, default=0.0, help="every string's damping time [s] (default 0)")
    parser.add_argument("--drone", action="store_true", help="only the drone's own step error (quadrotor_load)")
    parser.add_argument("--implicit", action="store_true", help="only the implicit string as the rule's scheme")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, got {args.seeds}")
    if args.damping < 0.0:
        parser.error(f"--damping must be a damping time >= 0 [s], got {args.damping!r}")
    start = time.perf_counter()
    if args.drone:
        return drone_main(args, start)
    if args.implicit:
        return implicit_main(args, start)
    sweep = SWEEP_EA[:2] if args.quick else SWEEP_EA
    seeds = 2 if args.quick else args.seeds
    seconds = 2.0 if args.quick else 100.0
    with tqdm(total=len(sweep) * seeds, desc="accuracy (seeds)", disable=args.quick) as bar:
        table = [accuracy(ea, seeds, bar, args.damping) for ea in sweep]
    print(f"\naccuracy over {HORIZON:g} s, {seeds} seeds (PD law + +-{NOISE} action noise), lengths in mm")
    print("EA [N]     N  steps | load median  worst | pivot worst | reference floor | energy 4 s [J] | failures")
    for row in table:
        print(f"{row['EA']:8.0e} {row['elements']:3d} {row['substeps']:6d} | {1e3 * row['load_error_median']:11.2f} "
              f"{1e3 * row['load_error_worst']:6.2f} | {1e3 * row['pivot_error_worst']:11.2f} | "
              f"{1e3 * row['reference_floor_median']:15.2f} | {row['energy_residual_worst_4s']:14.2e} | "
              f"{len(row['failures'])}")
    runs = [long_run(ea, mode, seconds, args.damping) for ea in tqdm(sweep, desc="long runs", disable=args.quick)
            for mode in ("pd+noise", "random")]
    print(f"\nenergy over {seconds:g} s: largest |E - E0 - W + D| [J] (D = 0 undamped), and per 20 s window")
    for run in runs:
        windows = " ".join(f"{w:.3f}" for w in run["windows"])
        print(f"{run['EA']:8.0e} {run['mode']:9s} {run['worst']:.3f}  [{windows}]  "
              f"failures {run['failures']}, episodes {run['episodes']}")
    name = "resolution_damped" if args.damping else "resolution"
    finish(args.out, name, {"accuracy": table, "energy": runs, "seeds": seeds, "horizon": HORIZON,
                            "noise": NOISE, "damping_time": args.damping, "machine": machine("gymnasium")},
           {f"{name}.png": lambda path: _plot(table, runs, path)}, start)
    return {"accuracy": table, "energy": runs}


def _plot(table: list, runs: list, path) -> None:
    fig = figure((9, 3.4), dpi=130)
    left, right = fig.subplots(1, 2)
    ea = [row["EA"] for row in table]
    left.plot(ea, [1e3 * row["load_error_median"] for row in table], "o-", label="load, median")
    left.plot(ea, [1e3 * row["load_error_worst"] for row in table], "v--", label="load, worst")
    left.plot(ea, [1e3 * row["reference_floor_median"] for row in table], "s:", label="reference's own floor")
    left.axhline(5.0, color="grey", lw=0.8)
    left.set(xscale="log", xlabel="EA [N]", ylabel="distance to the reference [mm]", title="elements auto: accuracy")
    left.legend(fontsize=8)
    for mode, marker in (("pd+noise", "o-"), ("random", "s-")):
        chosen = [run for run in runs if run["mode"] == mode]
        right.plot([run["EA"] for run in chosen], [run["worst"] for run in chosen], marker, label=mode)
    right.axhline(0.05, color="grey", lw=0.8)
    right.set(xscale="log", yscale="log", xlabel="EA [N]", ylabel="largest |E - E0 - W| [J]",
              title="energy balance over the long runs")
    right.legend(fontsize=8)
    for ax in (left, right):
        ax.grid(True, which="both", alpha=0.3)
    fig.savefig(path)


if __name__ == "__main__":
    main()
