"""What the benchmark scripts share: the command line, timing, the work-precision measures and
tables, the machine block and the ending (results JSON and plots into the output directory).

Each benchmark runs from the repository root as ``python -m benchmarks.NAME [--quick] [--out DIR]``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from importlib import import_module
from pathlib import Path
from typing import Callable, Iterable, Optional

import numpy as np

#: Where results go unless ``--out`` says otherwise.
DEFAULT_OUT = Path(__file__).resolve().parent / "out"

#: Error levels [m] at which the work-precision benchmarks rank the methods.
LEVELS = (1e-3, 1e-5, 1e-7, 1e-9)


def arg_parser(doc: str, quick: str = "fast smoke-test variant") -> argparse.ArgumentParser:
    """A parser described by the first paragraph of ``doc``, with ``--quick`` (help ``quick``)
    and ``--out`` (default :data:`DEFAULT_OUT`)."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help=quick)
    parser.add_argument("--out", default=str(DEFAULT_OUT), help="output directory (default: %(default)s)")
    return parser


# -- timing --------------------------------------------------------------------------------------
def wall_times(fn: Callable, repeats: int, setup: Optional[Callable] = None) -> list:
    """Wall times [s] of ``repeats`` calls of ``fn(setup())`` (of ``fn()`` without ``setup``);
    ``setup`` runs before each call and is not timed."""
    walls = []
    for _ in range(repeats):
        args = () if setup is None else (setup(),)
        start = time.perf_counter()
        fn(*args)
        walls.append(time.perf_counter() - start)
    return walls


def steps_rate(fn: Callable, steps: int, repeats: int) -> float:
    """Median over ``repeats`` timed calls of ``fn()`` of ``steps`` / wall time [steps/s]."""
    return float(np.median([steps / wall for wall in wall_times(fn, repeats)]))


def single_env_rate(make: Callable, steps: int, random_actions: bool, repeats: int, amplitude: float = 1.0) -> float:
    """Steps/s of the environment ``make()`` makes: ``steps`` seeded actions, uniform in
    +-``amplitude`` (zeros without ``random_actions``), resets included, one untimed step first;
    the median of ``repeats`` timed runs (:func:`steps_rate`)."""
    env = make()
    env.reset(seed=0)
    shape = (steps,) + env.action_space.shape
    actions = (np.random.default_rng(0).uniform(-amplitude, amplitude, shape).astype(np.float32) if random_actions
               else np.zeros(shape, np.float32))
    env.step(actions[0])

    def run():
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()

    return steps_rate(run, steps, repeats)


def median_wall(fn: Callable, repeats: int, setup: Optional[Callable] = None) -> float:
    """Median of :func:`wall_times` [s]."""
    return float(np.median(wall_times(fn, repeats, setup)))


def interleaved_wall_times(runs: dict, repeats: int) -> dict:
    """``{key: wall times [s]}`` of ``runs = {key: (setup, fn)}``, timed as :func:`wall_times` but
    in turn within each repeat, so that slow drifts of the machine hit every run alike."""
    walls = {key: [] for key in runs}
    for _ in range(repeats):
        for key, (setup, fn) in runs.items():
            walls[key] += wall_times(fn, 1, setup)
    return walls


def timed(fn: Callable, repeats: int, min_wall: float = 0.5):
    """Run ``fn()``; if it took under ``min_wall`` seconds, run it ``repeats`` times more and take
    the median. Returns ``(result of the first run, wall time [s])``."""
    start = time.perf_counter()
    result = fn()
    wall = time.perf_counter() - start
    if wall < min_wall and repeats > 1:
        wall = median_wall(fn, repeats)
    return result, wall


# -- work-precision measures ---------------------------------------------------------------------
def load_error(x: np.ndarray, ref: np.ndarray) -> float:
    """Max over samples of the position error [m] (rows: samples)."""
    return float(np.linalg.norm(x - ref, axis=1).max())


def pareto_time(rows, level: float):
    """Wall time [s] to reach error <= level on the method's Pareto front (log-log
    interpolation between the bracketing measured points); None if never reached."""
    pts = sorted((r["wall_s"], r["error_m"]) for r in rows if r["status"] == "ok" and r["error_m"] > 0)
    front = []
    for t, e in pts:
        if not front or e < front[-1][1]:
            front.append((t, e))
    if not front or front[-1][1] > level:
        return None
    if front[0][1] <= level:
        return front[0][0]
    for (t0, e0), (t1, e1) in zip(front, front[1:]):
        if e1 <= level < e0:
            s = (np.log(level) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(t0) + s * (np.log(t1) - np.log(t0))))
    return None  # pragma: no cover


def energy_stats(t, E, wall: float, label: str, extra: dict) -> dict:
    """Energy drift of a long run: max |E - E0|, least-squares slope and final error [J]."""
    dE = E - E[0]
    return {"label": label, "wall_s": wall, **extra, "max_abs_energy_error_J": float(np.abs(dE).max()),
            "energy_slope_J_per_s": float(np.polyfit(t, dE, 1)[0]), "final_energy_error_J": float(dE[-1])}


# -- tables --------------------------------------------------------------------------------------
def fmt(x, spec: str = ".2e") -> str:
    """``x`` formatted by ``spec``, ``-`` for None."""
    return "-" if x is None else format(x, spec)


def print_runs(results: dict, width: int, param: tuple = ("h [s]", 10), work: tuple = ("steps", 9)) -> None:
    """The work-precision runs, one line each: method (``width`` wide), h or tol, wall time,
    error, work and status; ``param`` and ``work`` are (header, width) of those columns."""
    (p_head, p_w), (w_head, w_w) = param, work
    print(f"{'method':{width}} {p_head:>{p_w}} {'wall [ms]':>10} {'error [m]':>10} {w_head:>{w_w}}  status")
    for name, rows in results.items():
        for r in rows:
            p = r["param"].get("h", r["param"].get("tol"))
            wall = None if r["wall_s"] is None else 1e3 * r["wall_s"]
            print(f"{name:{width}} {p:{p_w}.3e} {fmt(wall, '10.3f'):>10} {fmt(r['error_m']):>10} "
                  f"{fmt(r['work'], 'd'):>{w_w}}  {r['status']}")


def print_time_to_error(rank: dict, names: Iterable[str], width: int, levels=LEVELS) -> None:
    """Time [ms] each method needs for each error level (``rank[f"{level:g}"][name]`` in s)."""
    print(f"{'method':{width}} " + " ".join(f"{'<= ' + format(lv, 'g') + ' m':>12}" for lv in levels))
    for name in names:
        times = (rank[f"{lv:g}"][name] for lv in levels)
        print(f"{name:{width}} " + " ".join(f"{fmt(None if t is None else 1e3 * t, '12.3f'):>12}" for t in times))


# -- machine and output --------------------------------------------------------------------------
def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine(*modules: str) -> dict:
    """The machine block of a results file: CPU, cores and the versions of python, numpy, numba,
    esp_gym and of the named ``modules``."""
    info = {"python": platform.python_version()}
    for name in ("numpy", "numba", "esp_gym", *modules):
        info[name] = getattr(import_module(name), "__version__", "?")
    info.update(processor=_cpu_model(), cpus=os.cpu_count())
    return info


def figure(figsize, dpi: int = 150, layout: Optional[str] = "constrained"):
    """A matplotlib Figure drawn by the Agg canvas (no pyplot, no display)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def _plain(x):
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"{type(x).__name__} is not JSON serialisable")


def finish(out, name: str, payload: dict, plots: Optional[dict] = None, start: Optional[float] = None) -> list:
    """The ending of every benchmark: write ``payload`` to ``OUT/NAME.json``, draw each of
    ``plots = {file name: function(path)}`` into OUT, and print what was written (with the total
    wall time since ``start`` if given). Returns the paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / f"{name}.json"]
    with open(paths[0], "w") as fh:
        json.dump(payload, fh, indent=2, default=_plain)
    for file, draw in (plots or {}).items():
        paths.append(out / file)
        draw(paths[-1])
    took = "" if start is None else f" ({time.perf_counter() - start:.0f} s)"
    listed = ", ".join(map(str, paths[:-1])) + (" and " if len(paths) > 1 else "") + str(paths[-1])
    print(f"\nwrote {listed}{took}")
    return paths
