"""Cost of recording rollouts to Rerun (esp_gym.viz.recording) against unrecorded rollouts.

For each policy (zero action: the cheapest rollout, so the largest relative overhead; the
classical baseline controller) the same seeded episodes of ElasticStringPendulum-v0
(``gymnasium.make``, 50 Hz control, 500-step episodes, resets included) run plain and wrapped in
``RecordRerun`` (default settings), in interleaved pairs. Timed: the rollout loop (wall), the
whole job including creating the wrapper (Rerun stream, file, static geometry, blueprint) and
closing it (writing the rest and the footer), the CPU time of the rollout's thread and of the
whole process (which adds Rerun's writer thread). Overheads are medians of the per-pair ratios
over ``--repeats`` pairs, after a warm-up pair (compilation excluded). A free simulation of the
paper example (``record_simulation`` at 50 samples/s vs ``Simulator.step``) is timed too.

Prints a table and writes ``OUT/recording_overhead.json`` and ``OUT/recording_overhead.png``
(OUT = benchmarks/out unless ``--out``). Usage:
``python -m benchmarks.recording_overhead [--episodes 8] [--repeats 9] [--quick] [--out DIR]``.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import esp_gym
from agents.baselines.pd import ZeroPolicy
from agents.baselines.registry import baseline
from benchmarks.common import arg_parser, figure, finish, machine
from esp_gym.viz.recording import RecordRerun, record_simulation


def rollout(policy, episodes: int, path=None, seed: int = 0):
    """One job: make the env (wrapped in RecordRerun if ``path``), run ``episodes`` seeded
    episodes, close. Returns steps and the times [s]: ``loop`` (the episodes, wall),
    ``total`` (make + wrap + loop + close, wall), ``cpu`` (the whole process, all threads, over
    the loop: includes Rerun's writer thread), ``thread`` (CPU of the rollout's own thread)."""
    t0 = time.perf_counter()
    env = gym.make(esp_gym.ENV_ID, task="stabilize")
    if path is not None:
        env = RecordRerun(env, path)
    setup = env.unwrapped.setup
    loop_start, cpu_start, thread_start = time.perf_counter(), time.process_time(), time.thread_time()
    steps = 0
    for i in range(episodes):
        obs, _ = env.reset(seed=seed + i)
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(policy.act(obs, setup))
            done = terminated or truncated
            steps += 1
    loop, cpu = time.perf_counter() - loop_start, time.process_time() - cpu_start
    thread = time.thread_time() - thread_start
    env.close()
    total = time.perf_counter() - t0
    size = Path(path).stat().st_size if path is not None else 0
    return {"steps": steps, "loop": loop, "total": total, "cpu": cpu, "thread": thread, "bytes": size}


def measure(name, policy, episodes, repeats, tmp):
    rollout(policy, 1)
    rollout(policy, 1, tmp / "warmup.rrd")
    pairs = []
    for k in range(repeats):  # interleaved pairs, so slow drifts of the machine hit both
        pairs.append((rollout(policy, episodes), rollout(policy, episodes, tmp / f"{name}_{k}.rrd")))
    steps = pairs[0][0]["steps"]
    assert all(p["steps"] == r["steps"] == steps for p, r in pairs), "recording changed the rollouts"
    med = lambda f: float(np.median([f(p, r) for p, r in pairs]))  # noqa: E731
    return {
        "policy": name, "episodes": episodes, "steps": steps, "repeats": repeats,
        "plain_us_per_step": med(lambda p, r: p["loop"]) / steps * 1e6,
        "recorded_us_per_step": med(lambda p, r: r["loop"]) / steps * 1e6,
        # medians of the per-pair ratios
        "overhead_loop_pct": 100 * (med(lambda p, r: r["loop"] / p["loop"]) - 1),
        "overhead_total_pct": 100 * (med(lambda p, r: r["total"] / p["total"]) - 1),
        "overhead_cpu_pct": 100 * (med(lambda p, r: r["cpu"] / p["cpu"]) - 1),
        "overhead_thread_pct": 100 * (med(lambda p, r: r["thread"] / p["thread"]) - 1),
        "file_bytes": int(pairs[0][1]["bytes"]),
    }


def free_simulation(repeats, tmp, t_final=5.0):
    scene = esp_gym.load_scene("paper_example")
    plain, rec = [], []
    record_simulation(esp_gym.Simulator(scene), tmp / "warm.rrd", t_final=0.1)
    for k in range(repeats):
        sim = esp_gym.Simulator(scene)
        start = time.perf_counter()
        sim.step(int(round(t_final / sim.h)))
        plain.append(time.perf_counter() - start)
        start = time.perf_counter()
        summary = record_simulation(esp_gym.Simulator(scene), tmp / f"free_{k}.rrd", t_final=t_final)
        rec.append(time.perf_counter() - start)
    return {"scene": "paper_example", "t_final": t_final, "samples": summary["samples"],
            "plain_s": float(np.median(plain)), "recorded_s": float(np.median(rec)),
            "file_bytes": (tmp / "free_0.rrd").stat().st_size}


def main(argv=None) -> dict:
    ap = arg_parser(__doc__, quick="2 episodes, 1 repeat: a smoke run, not a measurement")
    ap.add_argument("--episodes", type=int, default=8,
                    help=f"episodes per timed run ({esp_gym.MAX_EPISODE_STEPS} steps each)")
    ap.add_argument("--repeats", type=int, default=9, help="interleaved plain/recorded pairs")
    args = ap.parse_args(argv)
    episodes, repeats = (2, 1) if args.quick else (args.episodes, args.repeats)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rows = [measure("zero", ZeroPolicy(), episodes, repeats, tmp),
                measure("baseline", baseline("stabilize"), episodes, repeats, tmp)]
        free = free_simulation(repeats, tmp)
    print(f"\nRecording overhead, ElasticStringPendulum-v0 (stabilize, 50 Hz), {episodes} episodes "
          f"({rows[0]['steps']} steps) per run, medians of {repeats} pairs:\n")
    print("| policy | plain [us/step] | recorded [us/step] | overhead: loop (wall) | + setup and close | "
          "rollout thread CPU | process CPU | file [kB/step] |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['policy']} | {r['plain_us_per_step']:.1f} | {r['recorded_us_per_step']:.1f} | "
              f"{r['overhead_loop_pct']:+.1f} % | {r['overhead_total_pct']:+.1f} % | {r['overhead_thread_pct']:+.1f} % | "
              f"{r['overhead_cpu_pct']:+.1f} % | {r['file_bytes'] / r['steps'] / 1e3:.2f} |")
    print(f"\nfree simulation ({free['scene']}, {free['t_final']:g} s, {free['samples']} samples): "
          f"{free['plain_s'] * 1e3:.0f} ms plain, {free['recorded_s'] * 1e3:.0f} ms recorded "
          f"(incl. creating and closing the recording), {free['file_bytes'] / 1e6:.2f} MB")
    results = {"rollouts": rows, "free_simulation": free, "quick": args.quick, "machine": machine("rerun")}
    finish(args.out, "recording_overhead", results, {"recording_overhead.png": lambda path: _plot(rows, path)})
    return results


def _plot(rows, path):
    fig = figure((5, 3.2), dpi=120, layout="tight")
    ax = fig.subplots()
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [r["plain_us_per_step"] for r in rows], 0.4, label="plain")
    ax.bar(x + 0.2, [r["recorded_us_per_step"] for r in rows], 0.4, label="recorded (RecordRerun)")
    for i, r in enumerate(rows):
        ax.text(i + 0.2, r["recorded_us_per_step"], f"{r['overhead_loop_pct']:+.1f} %", ha="center", va="bottom")
    ax.set_xticks(x, [r["policy"] for r in rows])
    ax.set_ylabel("wall time per env step [us]")
    ax.set_title("Rerun recording overhead (50 Hz control)")
    ax.legend(loc="upper left", fontsize=8)
    fig.savefig(path)


if __name__ == "__main__":
    main()
