"""Start-up time: from a fresh Python process to the first step of the simulator, the env and the
vector env, the env and the vector env with a drone at the pivot, and a team of three, with an empty numba cache
(cold) and then with the cache that run filled (warm).

    python -m benchmarks.cold_start [--quick] [--repeats K] [--out DIR]

Each case runs in a fresh process with its own new cache directory (``NUMBA_CACHE_DIR``, which
esp_gym/kernels/jit.py keys by a hash of the kernel sources): the cold run compiles every kernel
the case needs, the warm runs that follow load them. Reported per run: the process's wall time,
and inside it the seconds to ``import``, to construct, and to the end of the first step (the
clock starts when the interpreter has started, before ``import esp_gym``); per cold run, the
longest kernel compiles, each kernel's own seconds (numba's ``numba:compile`` events, less the
kernels compiled within it: ``compile_s_by_kernel``). ``--quick``: the
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

#: How many of the longest kernel compiles a cold run reports.
TOP_KERNELS = 12

#: Each case: (imports, construction, first step), Python run in a fresh child process.
CASES = {
    "simulator": ("import esp_gym",
                  "sim = esp_gym.Simulator(esp_gym.load_scene('paper_example'))",
                  "sim.step(1)"),
    "env": ("import gymnasium as gym, esp_gym",
            "env = gym.make('ElasticStringPendulum-v0'); env.reset(seed=0)",
            "env.step(env.action_space.sample())"),
    "damped env": ("import gymnasium as gym, esp_gym",
                   "env = gym.make('ElasticStringPendulum-v0', scene_overrides={'string': {'damping_time': 1e-3}}); "
                   "env.reset(seed=0)",
                   "env.step(env.action_space.sample())"),
    "vector env (8)": ("import gymnasium as gym, esp_gym",
                       "env = gym.make_vec('ElasticStringPendulum-v0', num_envs=8); env.reset(seed=0)",
                       "env.step(env.action_space.sample())"),
    "drone env": ("import gymnasium as gym, esp_gym",
                  "env = gym.make('ElasticStringPendulum-v0', scene='quadrotor_load'); env.reset(seed=0)",
                  "env.step(env.action_space.sample())"),
    "drone vector env (8)": ("import gymnasium as gym, esp_gym",
                             "env = gym.make_vec('ElasticStringPendulum-v0', num_envs=8, scene='quadrotor_load'); "
                             "env.reset(seed=0)",
                             "env.step(env.action_space.sample())"),
    "team env (3)": ("import gymnasium as gym, esp_gym",
                     "env = gym.make('ElasticStringTeam-v0', team=3); env.reset(seed=0)",
                     "env.step(env.action_space.sample())"),
}

_CHILD = """import time
t0 = time.perf_counter()
import json
from numba.core import event as _event


class _OwnCompileTime(_event.Listener):
    # seconds each kernel's compile took, less the kernels it compiled meanwhile (numba's
    # numba:compile events nest: a caller's compile compiles its callees)
    def __init__(self):
        self.stack, self.own = [], {{}}

    def on_start(self, ev):
        now = time.perf_counter()
        if self.stack:
            self.own[self.stack[-1][0]] = self.own.get(self.stack[-1][0], 0.0) + now - self.stack[-1][1]
        dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        self.stack.append([getattr(getattr(dispatcher, "py_func", None), "__qualname__", "?"), now])

    def on_end(self, ev):
        now = time.perf_counter()
        name, since = self.stack.pop()
        self.own[name] = self.own.get(name, 0.0) + now - since
        if self.stack:
            self.stack[-1][1] = now


_compiles = _OwnCompileTime()
_event.register("numba:compile", _compiles)
{imports}
times = {{'import_s': time.perf_counter() - t0}}
{construct}
times['construct_s'] = time.perf_counter() - t0
{step}
times['first_step_s'] = time.perf_counter() - t0
{after}
times['after_s'] = time.perf_counter() - t0 if {has_after} else None
times['compile_s_by_kernel'] = dict(sorted(_compiles.own.items(), key=lambda item: -item[1]))
print(json.dumps(times))
"""


def run_case(case: tuple, cache_dir: str, after: str = "", timeout: float = 900.0) -> dict:
    """Run ``case`` (imports, construction, first step) in a fresh interpreter with
    ``NUMBA_CACHE_DIR=cache_dir``, then ``after`` (more code, optional). Returns the seconds from
    the interpreter's start to the end of each part (``after_s`` None without ``after``) and
    the process's wall time ``process_s`` as seen by the parent."""
    imports, construct, step = case
    code = _CHILD.format(imports=imports, construct=construct, step=step, after=after or "pass",
                         has_after=bool(after))
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=timeout)
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
                del t["after_s"]
                by_kernel = t.pop("compile_s_by_kernel")
                rows.append({"case": name, "cache": "cold" if k == 0 else "warm", **t})
                if k == 0:  # the longest compiles of the cold start, rounded for reading
                    rows[-1]["compile_s_by_kernel"] = {kernel: round(seconds, 2) for kernel, seconds
                                                       in list(by_kernel.items())[:TOP_KERNELS]}
                print(f"{name:16s} {rows[-1]['cache']:6s} {t['import_s']:11.2f} {t['construct_s']:14.2f} "
                      f"{t['first_step_s']:15.2f} {t['process_s']:12.2f}", flush=True)
    print("\nthe longest compiles of the cold starts (each kernel's own seconds):")
    for row in rows:
        if row["cache"] == "cold":
            print(f"{row['case']:16s} " + ", ".join(f"{k} {v:.2f}" for k, v in row["compile_s_by_kernel"].items()))
    payload = {"command": "python -m benchmarks.cold_start" + (" --quick" if args.quick else ""),
               "machine": machine("gymnasium"), "runs": rows}
    finish(args.out, "cold_start", payload, start=start)
    return payload


if __name__ == "__main__":
    main()
