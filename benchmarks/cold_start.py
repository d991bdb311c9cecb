"""Start-up time: from a fresh Python process to the first step of the simulator, the env and the
vector env, with an empty numba cache (cold) and then with the cache that run filled (warm).

    python -m benchmarks.cold_start [--quick] [--repeats K] [--out DIR]

Each case runs in a fresh process with its own new cache directory (``NUMBA_CACHE_DIR``, which
esp_gym/kernels/jit.py keys by a hash of the kernel sources): the cold run compiles every kernel
the case needs, the warm runs that follow load them. Reported per run: the process's wall time,
and inside it the seconds to ``import``, to construct, and to the end of the first step (the
clock starts when the interpreter has started, before ``import esp_gym``). ``--quick``: the
simulator only, one warm run (a smoke test).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time

from benchmarks.common import arg_parser, finish, machine

#: Python run in the child process: prints one JSON line of times [s] since its start.
CASES = {
    "simulator": (
        "import esp_gym\nt_import = time.perf_counter() - t0\n"
        "sim = esp_gym.Simulator(esp_gym.load_scene('paper_example'))\nt_made = time.perf_counter() - t0\n"
        "sim.step(1)\n"),
    "env": (
        "import gymnasium as gym, esp_gym\nt_import = time.perf_counter() - t0\n"
        "env = gym.make('ElasticStringPendulum-v0'); env.reset(seed=0)\nt_made = time.perf_counter() - t0\n"
        "env.step(env.action_space.sample())\n"),
    "vector env (8)": (
        "import gymnasium as gym, esp_gym\nt_import = time.perf_counter() - t0\n"
        "env = gym.make_vec('ElasticStringPendulum-v0', num_envs=8); env.reset(seed=0)\n"
        "t_made = time.perf_counter() - t0\n"
        "env.step(env.action_space.sample())\n"),
}
_HEAD = "import time\nt0 = time.perf_counter()\nimport json\n"
_TAIL = ("t_step = time.perf_counter() - t0\n"
         "print(json.dumps({'import_s': t_import, 'construct_s': t_made, 'first_step_s': t_step}))\n")


def run_case(code: str, cache_dir: str, timeout: float = 900.0) -> dict:
    """Run one case in a fresh interpreter with ``NUMBA_CACHE_DIR=cache_dir``; its times [s]."""
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _HEAD + code + _TAIL], env=env, capture_output=True, text=True,
                          timeout=timeout)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"the start-up case failed (exit {done.returncode}):\n{done.stderr[-2000:]}")
    times = json.loads(done.stdout.strip().splitlines()[-1])
    times["process_s"] = wall
    return times


def main(argv=None) -> dict:
    parser = arg_parser(__doc__, "the simulator only, one warm run")
    parser.add_argument("--repeats", type=int, default=3, help="warm runs per case (default: %(default)s)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    cases = {"simulator": CASES["simulator"]} if args.quick else CASES
    repeats = 1 if args.quick else max(1, args.repeats)
    rows = []
    print(f"{'case':16s} {'cache':6s} {'import [s]':>11s} {'construct [s]':>14s} {'first step [s]':>15s} "
          f"{'process [s]':>12s}")
    for name, code in cases.items():
        with tempfile.TemporaryDirectory(prefix="esp_gym-cold-") as cache:
            for k in range(1 + repeats):
                t = run_case(code, cache)
                rows.append({"case": name, "cache": "cold" if k == 0 else "warm", **t})
                print(f"{name:16s} {rows[-1]['cache']:6s} {t['import_s']:11.2f} {t['construct_s']:14.2f} "
                      f"{t['first_step_s']:15.2f} {t['process_s']:12.2f}", flush=True)
    payload = {"command": "python -m benchmarks.cold_start" + (" --quick" if args.quick else ""),
               "machine": machine("gymnasium"), "runs": rows}
    finish(args.out, "cold_start", payload, start=start)
    return payload


if __name__ == "__main__":
    main()
