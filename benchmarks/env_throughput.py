"""Environment steps per second of ElasticStringPendulum-v0 (default scene, 50 Hz control).

Prints a table and writes ``OUT/env_throughput.json`` and ``OUT/env_throughput.png``
(OUT = benchmarks/out unless ``--out``):

* single: ``gymnasium.make`` (with its wrappers: time limit, order enforcing, env checker) and
  the bare env, zero and random actions, resets included when episodes end;
* batched: ``gymnasium.make_vec`` (one parallel compiled call per step) and the SB3 VecEnv,
  for 1 to 64 environments;
* ``--ea-sweep`` (alone): the string's EA from 2e2 to 1e7 N on ``drone_load``
  (``scene_overrides``), random actions, resets included, with the resolution rule
  (``string.elements: auto``), with the scene's 8 elements at the environment's step, and with the
  implicit string asked for (``solver.string: implicit``), the runs of one repeat interleaved;
  writes ``OUT/env_throughput_ea.json`` and ``.png``; with ``--damping TAU`` every string damped
  (``string.damping_time`` TAU [s]), into ``OUT/env_throughput_ea_damped.json`` and ``.png``;
* ``--drone`` (alone): quadrotor_load's drone in each actuation against the same rig with a
  point-mass pivot, single and 8 batched, random actions of amplitude 0.2, interleaved; writes
  ``OUT/env_throughput_drone.json``;
* ``--threads`` (alone): the batched env in one thread (``threads=1``, the default) against numba's
  threads (``threads`` = the CPUs), 8 and 64 environments, on an idle machine and beside one busy
  process (a CPU-bound loop at the same priority, as a learner or a second run would be), the runs
  of one repeat interleaved; writes ``OUT/env_throughput_threads.json``;
* ``--team`` (alone): ``ElasticStringTeam-v0`` with K = 1 (the same string and physics steps as
  the single env), K = 3 and K = 3 drones (``thrust_rates``) against the single env, single (random
  actions of TEAM_AMPLITUDE, resets included) and TEAM_BATCH batched (``make_vec``), the runs of
  one repeat interleaved; the ratios to the single env's; writes ``OUT/env_throughput_team.json``;
* ``--realism`` (alone): the plain environment against the realism options (``randomize=True``,
  then with the ``hook`` observation and sensor noise too, then randomisation, the hard preset's
  wind and pushes and the ``hook`` observation (the issue's bar), then ``preset="hard"``),
  single and 8 batched, random actions, interleaved, and the median time of a reset (drawing and
  starting an episode); writes ``OUT/env_throughput_realism.json``.

Each figure is the median of ``--repeats`` timed runs after a warm-up (compilation excluded).
Usage: ``python -m benchmarks.env_throughput [--quick] [--ea-sweep | --realism | --drone | --team | --threads]
[--out DIR]``.
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time

import gymnasium as gym
import numpy as np

import esp_gym
from benchmarks.common import arg_parser, figure, finish, machine, single_env_rate, steps_rate, wall_times
from esp_gym.pendulum.sb3_vector import ElasticStringPendulumSB3VecEnv
from esp_gym.pendulum.env_setup import PRESETS
from esp_gym.workers import available_cpus


def batched(make, num_envs, steps, repeats, sb3, amplitude=1.0):
    venv = make(num_envs)
    venv.reset() if sb3 else venv.reset(seed=0)
    size = getattr(venv, "single_action_space", venv.action_space).shape  # one env's (SB3's action_space)
    acts = np.random.default_rng(0).uniform(-amplitude, amplitude, (num_envs,) + size).astype(np.float32)
    venv.step(acts)
    n = max(20, steps // num_envs)

    def run():
        for _ in range(n):
            venv.step(acts)

    return steps_rate(run, n * num_envs, repeats)


def main(argv=None) -> dict:
    ap = arg_parser(__doc__, quick="small smoke run, not a measurement")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--ea-sweep", action="store_true", help="only the sweep over the string's EA")
    ap.add_argument("--damping", type=float, default=0.0,
                    help="with --ea-sweep: every string's damping time [s] (default 0: undamped)")
    ap.add_argument("--realism", action="store_true",
                    help="only the realism options (randomize, ...) against the plain environment")
    ap.add_argument("--drone", action="store_true",
                    help="only a drone at the pivot against the same rig with a point-mass pivot")
    ap.add_argument("--team", action="store_true", help="only the team env (K = 1, 3, 3 drones) against the single env")
    ap.add_argument("--threads", action="store_true",
                    help="only the batched env in one thread against numba's threads, idle and beside a busy process")
    args = ap.parse_args(argv)
    if args.threads:
        return threads(args)
    if args.damping < 0.0 or (args.damping and not args.ea_sweep):
        ap.error(f"--damping takes a damping time >= 0 [s] with --ea-sweep, got {args.damping!r}")
    if args.ea_sweep:
        return ea_sweep(args)
    if args.realism:
        return realism(args)
    if args.drone:
        return drone(args)
    if args.team:
        return team(args)
    steps = 2_000 if args.quick else 20_000
    repeats = 1 if args.quick else args.repeats
    counts = [1, 4] if args.quick else [1, 2, 4, 8, 16, 32, 64]
    res = {"single": {}, "batched_gymnasium": {}, "batched_sb3": {}}
    env_id = esp_gym.ENV_ID
    res["single"]["gymnasium.make, zero actions"] = single_env_rate(lambda: gym.make(env_id), steps, False, repeats)
    res["single"]["gymnasium.make, random actions"] = single_env_rate(lambda: gym.make(env_id), steps, True, repeats)
    res["single"]["bare env, random actions"] = single_env_rate(lambda: gym.make(env_id).unwrapped, steps, True,
                                                                repeats)
    for b in counts:
        res["batched_gymnasium"][b] = batched(lambda n: gym.make_vec(env_id, num_envs=n), b, 4 * steps, repeats, False)
        res["batched_sb3"][b] = batched(lambda n: ElasticStringPendulumSB3VecEnv(num_envs=n), b, 4 * steps, repeats, True)
    setup = gym.make(env_id).unwrapped.setup
    print(f"ElasticStringPendulum-v0, scene {setup.scene.name} (N={setup.scene.string.elements}), "
          f"{setup.substeps} physics steps of {setup.scene.h * 1e3:.3f} ms per 20 ms control step")
    print("\nsingle environment                 steps/s")
    for k, v in res["single"].items():
        print(f"  {k:32s} {v:10,.0f}")
    print("\nbatched (one compiled call)  envs   Gymnasium VectorEnv   SB3 VecEnv   [steps/s]")
    for b in counts:
        print(f"  {'':26s} {b:4d}   {res['batched_gymnasium'][b]:19,.0f}   {res['batched_sb3'][b]:10,.0f}")
    finish(args.out, "env_throughput", {**res, "machine": machine("gymnasium", "stable_baselines3")},
           {"env_throughput.png": lambda path: _plot(res, counts, path)})
    return res


#: The sweep's string stiffnesses [N].
SWEEP_EA = (2e2, 2e3, 2e4, 2e5, 2e6, 1e7)
#: The string schemes of the sweep, as scene overrides: the resolution rule (elements: auto), the
#: scene's own 8 elements with the environment's step (0.5 of the bound), the implicit string.
SWEEP_SCHEMES = {"elements auto": {"string": {"elements": "auto"}}, "N = 8, explicit": {},
                 "N = 8, implicit": {"solver": {"string": "implicit"}}}


def ea_sweep(args) -> dict:
    """Steps/s against EA for each of SWEEP_SCHEMES (module docstring)."""
    steps = 200 if args.quick else 2_000
    repeats = 1 if args.quick else args.repeats
    sweep = SWEEP_EA[:2] if args.quick else SWEEP_EA
    makers, rates, chosen = {}, {}, {}
    for ea in sweep:
        for name, extra in SWEEP_SCHEMES.items():
            damping = {"damping_time": args.damping} if args.damping else {}
            overrides = {**extra, "string": {**extra.get("string", {}), "EA": ea, **damping}}
            env = gym.make(esp_gym.ENV_ID, scene_overrides=overrides)
            u = env.unwrapped
            chosen[(ea, name)] = (u.scene.solver.string, u.scene.string.elements, u.setup.substeps)
            makers[(ea, name)] = (lambda o=overrides: gym.make(esp_gym.ENV_ID, scene_overrides=o))
            rates[(ea, name)] = []
    for _ in range(repeats):  # interleaved: each repeat runs every configuration once
        for key, make in makers.items():
            rates[key].append(single_env_rate(make, steps, True, 1))
    print(f"{'EA [N]':9s}" + "".join(f" | {name:>15s}: N  steps   steps/s" for name in SWEEP_SCHEMES))
    table = []
    for ea in sweep:
        row = {"EA": ea}
        for name in SWEEP_SCHEMES:
            scheme, elements, substeps = chosen[(ea, name)]
            row[name] = {"scheme": scheme, "elements": elements, "substeps": substeps,
                         "steps_per_s": float(np.median(rates[(ea, name)]))}
        table.append(row)
        print(f"{ea:9.0e}" + "".join(f" | {'':15s} {row[n]['elements']:3d} {row[n]['substeps']:5d} "
                                     f"{row[n]['steps_per_s']:9,.0f}" for n in SWEEP_SCHEMES))
    base = table[0]["elements auto"]["steps_per_s"]
    for row in table:
        auto = row["elements auto"]["steps_per_s"]
        print(f"  EA {row['EA']:.0e}: elements auto / its EA = 200 N = {auto / base:.2f}; "
              f"/ N = 8 explicit at this EA = {auto / row['N = 8, explicit']['steps_per_s']:.1f}")
    name = "env_throughput_ea_damped" if args.damping else "env_throughput_ea"
    finish(args.out, name, {"sweep": table, "steps": steps, "repeats": repeats, "damping_time": args.damping,
                            "machine": machine("gymnasium")},
           {f"{name}.png": lambda path: _plot_sweep(table, path, args.damping)})
    return {"sweep": table}


def _plot_sweep(table: list, path, damping: float = 0.0) -> None:
    fig = figure((6, 3.6), dpi=130)
    ax = fig.subplots()
    for name, marker in zip(SWEEP_SCHEMES, "osd"):
        ax.plot([row["EA"] for row in table], [row[name]["steps_per_s"] for row in table], marker + "-", label=name)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("EA [N]")
    ax.set_ylabel("environment steps / s")
    ax.set_title("drone_load, random actions, one env (2 cores)"
                 + (f", τ = {damping * 1e3:g} ms" if damping else ""))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.savefig(path)


#: The options the realism comparison times against the plain environment.
REALISM = {"plain": {}, "randomize": {"randomize": True},
           "randomize, hook, noise": {"randomize": True, "observation": "hook", "sensor_noise": 1.0},
           "randomize, wind, hook": {"randomize": True, "observation": "hook", "wind": PRESETS["hard"]["wind"]},
           "preset hard": {"preset": "hard"}}
#: Batch size of the realism comparison's batched runs.
REALISM_BATCH = 8


def realism(args) -> dict:
    """Steps/s of each of REALISM, single (random actions, resets included) and batched
    (``make_vec``, REALISM_BATCH environments), the runs of one repeat interleaved."""
    steps = 500 if args.quick else 20_000
    repeats = 1 if args.quick else args.repeats
    rates = {(name, kind): [] for name in REALISM for kind in ("single", "batched")}
    for _ in range(repeats):
        for name, options in REALISM.items():
            rates[(name, "single")].append(single_env_rate(lambda o=options: gym.make(esp_gym.ENV_ID, **o), steps,
                                                           True, 1))
            rates[(name, "batched")].append(batched(
                lambda n, o=options: gym.make_vec(esp_gym.ENV_ID, num_envs=n, **o), REALISM_BATCH, 4 * steps, 1, False))
    table = {name: {kind: float(np.median(rates[(name, kind)])) for kind in ("single", "batched")} for name in REALISM}
    for name, options in REALISM.items():
        table[name]["reset_us"] = reset_time(options, 20 if args.quick else 300)
    print(f"{'options':24s} single [steps/s]  ratio   batched x{REALISM_BATCH} [steps/s]  ratio   reset [us]")
    for name, row in table.items():
        print(f"{name:24s} {row['single']:15,.0f}  {row['single'] / table['plain']['single']:5.2f}   "
              f"{row['batched']:19,.0f}  {row['batched'] / table['plain']['batched']:5.2f}   {row['reset_us']:9.0f}")
    finish(args.out, "env_throughput_realism", {"table": table, "options": {k: repr(v) for k, v in REALISM.items()},
                                                "steps": steps, "repeats": repeats,
                                                "machine": machine("gymnasium")}, {})
    return {"table": table}


#: The drone comparison: quadrotor_load's rig with its drone in each actuation, and with a point
#: mass of the drone's mass at the pivot instead (``force``), the reference of the ratios; and the
#: point-pivot environment's default (drone_load), the issue's reference (``goal_ratio``).
DRONE = {"point pivot (force)": {"scene": "quadrotor_load", "scene_overrides": {"pivot": {"kind": "free",
                                                                                         "drone": None}}},
         "drone, thrust_rates": {"scene": "quadrotor_load", "actuation": "thrust_rates"},
         "drone, thrust_torque": {"scene": "quadrotor_load", "actuation": "thrust_torque"},
         "drone, motors": {"scene": "quadrotor_load", "actuation": "motors"},
         "point env (drone_load)": {"scene": "drone_load"}}
#: Random actions' amplitude in the drone comparison (at 1, a drone flips within ten steps and
#: resets would dominate).
DRONE_AMPLITUDE = 0.2


def drone(args) -> dict:
    """Steps/s of each of DRONE, single (random actions of DRONE_AMPLITUDE, resets included) and
    batched (``make_vec``, REALISM_BATCH environments), the runs of one repeat interleaved; the
    ratios to the point pivot's."""
    steps = 500 if args.quick else 10_000
    repeats = 1 if args.quick else args.repeats
    rates = {(name, kind): [] for name in DRONE for kind in ("single", "batched")}
    for _ in range(repeats):
        for name, options in DRONE.items():
            rates[(name, "single")].append(single_env_rate(lambda o=options: gym.make(esp_gym.ENV_ID, **o).unwrapped,
                                                           steps, True, 1, DRONE_AMPLITUDE))
            rates[(name, "batched")].append(batched(lambda n, o=options: gym.make_vec(esp_gym.ENV_ID, num_envs=n, **o),
                                                    REALISM_BATCH, 4 * steps, 1, False, DRONE_AMPLITUDE))
    table = {name: {kind: float(np.median(rates[(name, kind)])) for kind in ("single", "batched")} for name in DRONE}
    base = table["point pivot (force)"]
    point = table["point env (drone_load)"]
    for row in table.values():
        row["single_ratio"] = row["single"] / base["single"]
        row["batched_ratio"] = row["batched"] / base["batched"]
        row["goal_ratio"] = row["single"] / point["single"]
    substeps = gym.make(esp_gym.ENV_ID, **DRONE["drone, thrust_rates"]).unwrapped.setup.substeps
    print(f"quadrotor_load, {substeps} physics steps per control step, random actions in +-{DRONE_AMPLITUDE}")
    print(f"{'pivot':24s} single [steps/s]  ratio  / drone_load   batched x{REALISM_BATCH} [steps/s]  ratio")
    for name, row in table.items():
        print(f"{name:24s} {row['single']:15,.0f}  {row['single_ratio']:5.2f}  {row['goal_ratio']:12.2f}   "
              f"{row['batched']:19,.0f}  {row['batched_ratio']:5.2f}")
    finish(args.out, "env_throughput_drone", {"table": table, "substeps": substeps, "steps": steps,
                                              "repeats": repeats, "amplitude": DRONE_AMPLITUDE,
                                              "machine": machine("gymnasium")}, {})
    return {"table": table}


#: ``--team``'s environments: (id, options) by name, the single env first (the ratios' base).
TEAM = {"single env": (esp_gym.ENV_ID, {}), "team K=1": (esp_gym.TEAM_ENV_ID, {"team": 1}),
        "team K=3": (esp_gym.TEAM_ENV_ID, {"team": 3}),
        "team K=3 drones": (esp_gym.TEAM_ENV_ID, {"team": 3, "actuation": "thrust_rates"})}
TEAM_AMPLITUDE = 0.3
#: ``--team``'s batch (the issue's goal: 64 teams of 3 against 64 single envs).
TEAM_BATCH = 64


def team(args) -> dict:
    """Steps/s of each of TEAM, single (random actions of TEAM_AMPLITUDE, resets included) and
    batched (``make_vec``, TEAM_BATCH environments), the runs of one repeat interleaved; the ratios
    to the single env's. A team's step counts once, whatever its K."""
    steps = 200 if args.quick else 3_000
    repeats = 1 if args.quick else args.repeats
    rates = {(name, kind): [] for name in TEAM for kind in ("single", "batched")}
    for _ in range(repeats):
        for name, (env_id, options) in TEAM.items():
            rates[(name, "single")].append(single_env_rate(lambda i=env_id, o=options: gym.make(i, **o).unwrapped,
                                                           steps, True, 1, TEAM_AMPLITUDE))
            rates[(name, "batched")].append(batched(
                lambda n, i=env_id, o=options: gym.make_vec(i, num_envs=n, vectorization_mode="vector_entry_point",
                                                            **o), TEAM_BATCH, 4 * steps, 1, False, TEAM_AMPLITUDE))
    table = {name: {kind: float(np.median(rates[(name, kind)])) for kind in ("single", "batched")} for name in TEAM}
    base = table["single env"]
    point = table["point env (drone_load)"]
    for row in table.values():
        row["single_ratio"] = row["single"] / base["single"]
        row["batched_ratio"] = row["batched"] / base["batched"]
        row["goal_ratio"] = row["single"] / point["single"]
    substeps = {name: _substeps(env_id, options) for name, (env_id, options) in TEAM.items()}
    print(f"random actions in +-{TEAM_AMPLITUDE}, medians of {repeats} interleaved repeats")
    print(f"{'environment':18s} {'physics steps':>13s}  single [steps/s]  ratio   "
          f"batched x{TEAM_BATCH} [steps/s]  ratio")
    for name, row in table.items():
        print(f"{name:18s} {substeps[name]:13d}  {row['single']:16,.0f}  {row['single_ratio']:5.3f}   "
              f"{row['batched']:20,.0f}  {row['batched_ratio']:5.3f}")
    finish(args.out, "env_throughput_team", {"table": table, "substeps": substeps, "steps": steps, "repeats": repeats,
                                             "amplitude": TEAM_AMPLITUDE, "batch": TEAM_BATCH,
                                             "machine": machine("gymnasium")}, {})
    return {"table": table, "substeps": substeps}


def _substeps(env_id: str, options: dict) -> int:
    """Physics steps per control step of ``env_id`` with ``options``."""
    env = gym.make(env_id, **options).unwrapped
    return int(env.core.substeps if hasattr(env, "core") else env.setup.substeps)


#: The batch sizes of ``--threads``.
THREAD_BATCHES = (8, 64)


@contextlib.contextmanager
def busy_process():
    """One CPU-bound process at this one's priority while the block runs, stopped by its id after."""
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.5)  # running before the timing starts
        yield
    finally:
        busy.kill()
        busy.wait()


def threads(args) -> dict:
    """Steps/s of the batched env with ``threads`` 1 and the CPUs, THREAD_BATCHES environments, idle
    and beside :func:`busy_process`, the runs of one repeat interleaved (module docstring)."""
    steps = 400 if args.quick else 10_000
    repeats = 1 if args.quick else args.repeats
    batches = THREAD_BATCHES[:1] if args.quick else THREAD_BATCHES
    counts = sorted({1, available_cpus()})
    envs = {(b, t): gym.make_vec(esp_gym.ENV_ID, num_envs=b, threads=t) for b in batches for t in counts}
    rates = {(c, b, t): [] for c in ("idle", "busy") for b in batches for t in counts}
    load = {}  # the 1-minute load average as each condition starts: "idle" is only as idle as that
    for condition in ("idle", "busy"):
        load[condition] = os.getloadavg()[0]
        with busy_process() if condition == "busy" else contextlib.nullcontext():
            for _ in range(repeats):
                for (b, t), env in envs.items():
                    rates[(condition, b, t)].append(batched(lambda n, e=env: e, b, steps, 1, False))
    table = [{"condition": c, "envs": b, "threads": t, "steps_per_s": float(np.median(r))}
             for (c, b, t), r in rates.items()]
    print(f"batched env, steps/s (median of {repeats}), {available_cpus()} CPUs")
    print(f"{'machine':26s} {'envs':>4s} " + " ".join(f"{f'threads={t}':>10s}" for t in counts))
    for c in ("idle", "busy"):
        for b in batches:
            row = " ".join(f"{float(np.median(rates[(c, b, t)])):10,.0f}" for t in counts)
            print(f"{'idle' if c == 'idle' else 'beside one busy process':26s} {b:4d} {row}")
    print(f"load average as each started: idle {load['idle']:.2f}, beside the busy process {load['busy']:.2f}")
    finish(args.out, "env_throughput_threads", {"table": table, "load_average": load, "steps": steps, "repeats": repeats,
                                                "machine": machine("gymnasium", "numba")}, {})
    return {"table": table}


def reset_time(options: dict, count: int) -> float:
    """Median wall time of drawing and starting one episode (``ControlStep.start_episode``) [us]."""
    control = gym.make(esp_gym.ENV_ID, **options).unwrapped.control
    rng = np.random.default_rng(0)
    return 1e6 * float(np.median(wall_times(lambda: control.start_episode(rng), count)))


def _plot(res: dict, counts: list, path) -> None:
    fig = figure((6, 3.6), dpi=130)
    ax = fig.subplots()
    ax.plot(counts, [res["batched_gymnasium"][b] for b in counts], "o-", label="Gymnasium VectorEnv (make_vec)")
    ax.plot(counts, [res["batched_sb3"][b] for b in counts], "s-", label="SB3 VecEnv")
    ax.axhline(res["single"]["gymnasium.make, random actions"], color="grey", ls="--", label="single env (gymnasium.make)")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("environments")
    ax.set_ylabel("environment steps / s")
    ax.set_title("ElasticStringPendulum-v0 throughput (2 cores, 50 Hz control)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(path)


if __name__ == "__main__":
    main()
