"""Work-precision on a stiff tether: ``drone_load`` at EA = 2e5 N hanging from a fixed hook,
released from a swing (string 17 degrees off the vertical, at rest), tension-only string, 1 s.
The error is the largest distance of the load's attachment point from a converged reference over
samples every 10 ms; every method is measured against the same reference, so a coarse string's
own error counts. Methods:

* the LGVI with the resolution rule's choice (``esp_gym.choose_resolution`` at accuracies 1e-2 to
  1e-5 m over the 1-s horizon: N, then h dividing the 10-ms sample);
* the explicit LGVI at the scene's N = 8, h from 0.9 of its bound down;
* the implicit LGVI at N = 8, h = 10 ms / k;
* SciPy's Radau and BDF on the same N = 8 finite-element ODE (``esp_gym/verify/ode.py``), rtol =
  atol = tol; a tolerance that runs past ``--time-limit`` s is abandoned with the tighter ones;
* MuJoCo's ``implicitfast`` and ``discrete`` integrators on the lumped N = 8 chain
  (``esp_gym/verify/mujoco_chain.py``), h = 10 ms / k up to where they stay stable.

The reference is the explicit LGVI at N = 64 and a quarter of its bound; its distance to N = 32 at
the same fraction is reported as its own floor. Wall time: building the integrator from a
validated scene plus the run, after compilation (median of ``--repeats`` when under 0.5 s).

Prints the runs and the time each method needs per error level, writes
``OUT/stiff_work_precision.json`` and ``.png``.
Usage: ``python -m benchmarks.stiff_work_precision [--quick] [--out DIR]``.
"""
from __future__ import annotations

import math
import time

import numpy as np
from tqdm import tqdm

import esp_gym
from benchmarks.common import (arg_parser, figure, finish, load_error, machine, pareto_time, print_runs,
                               print_time_to_error, timed)
from benchmarks.work_precision import TooSlow, ivp_samples

EA, SAMPLE, T_FINAL = 2e5, 0.01, 1.0
LEVELS = (1e-2, 1e-3, 1e-4, 1e-5)
RULE = "LGVI, elements auto"
METHODS = (RULE, "LGVI, N = 8 explicit", "LGVI, N = 8 implicit", "SciPy Radau, N = 8", "SciPy BDF, N = 8",
           "MuJoCo implicitfast, N = 8 lumped", "MuJoCo discrete, N = 8 lumped")


def scene(elements, h: float = 1e-3, **overrides):
    return esp_gym.load_scene("drone_load", EA=EA, N=elements, h=h, allow_unstable_h=True,
                              pivot={"kind": "fixed", "position": [0.0, 0.0, 0.0], "mass": None},
                              initial={"direction": [0.3, 0.0, 1.0]}, **overrides)


def lgvi(sc):
    k = int(round(SAMPLE / sc.h))

    def run():
        traj = esp_gym.Simulator(sc).run(T_FINAL, record_every=k)
        return traj.nodes[:, -1].copy()

    return run


def mujoco(integrator: str, k: int):
    from esp_gym.verify.mujoco_chain import MujocoChain
    chain = MujocoChain(scene(8, string={"mass_model": "lumped"}), integrator, h=SAMPLE / k)

    def run():
        chain.reset()
        x = chain.samples(T_FINAL, k)
        if chain.warnings() or not np.all(np.isfinite(x)) or np.abs(x).max() > 10.0:
            raise FloatingPointError(f"diverged ({chain.warnings()} MuJoCo warnings)")
        return x

    return run


def divided(h: float) -> float:
    """The largest step dividing the sample that is at most ``h``."""
    return SAMPLE / math.ceil(SAMPLE / h - 1e-9)


def grid(quick: bool, time_limit: float):
    """(method, parameter, runner factory) of every run; SciPy's give up after ``time_limit`` s."""
    template = scene(8)
    runs = []
    for accuracy in ((1e-2, 1e-3) if quick else (1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5)):
        choice = esp_gym.choose_resolution(template, accuracy=accuracy, horizon=T_FINAL, divides=SAMPLE)
        runs.append((RULE, {"accuracy": accuracy, "N": choice.elements, "h": choice.h},
                     lambda c=choice: lgvi(c.scene(template))))
    bound = template.stability_bound
    for fraction in ((0.9,) if quick else (0.9, 0.45, 0.2, 0.1)):
        h = divided(fraction * bound)
        runs.append(("LGVI, N = 8 explicit", {"h": h}, lambda h=h: lgvi(scene(8, h))))
    for k in ((4,) if quick else (1, 2, 4, 8, 16, 32, 64)):
        runs.append(("LGVI, N = 8 implicit", {"h": SAMPLE / k},
                     lambda k=k: lgvi(scene(8, SAMPLE / k, solver={"string": "implicit"}))))
    t_eval = np.linspace(0.0, T_FINAL, int(round(T_FINAL / SAMPLE)) + 1)
    for method in ("Radau", "BDF"):
        for tol in ((1e-3,) if quick else (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)):
            runs.append((f"SciPy {method}, N = 8", {"tol": tol},
                         lambda m=method, t=tol: ivp_samples(scene(8), m, t, t_eval, deadline_s=time_limit)))
    for integrator in ("implicitfast", "discrete"):
        for k in ((100,) if quick else (10, 20, 50, 100, 200, 500, 1000)):
            runs.append((f"MuJoCo {integrator}, N = 8 lumped", {"h": SAMPLE / k},
                         lambda i=integrator, k=k: mujoco(i, k)))
    return runs


def reference(quick: bool):
    """The finer of two explicit LGVI runs (N = 32 and 64; 8 and 16 with ``quick``) at a quarter of
    their bounds, and their distance (the reference's floor)."""
    coarse, fine = (8, 16) if quick else (32, 64)
    runs = {n: lgvi(scene(n, divided(0.25 * scene(n).stability_bound)))() for n in (coarse, fine)}
    return runs[fine], load_error(runs[coarse], runs[fine])


def main(argv=None) -> dict:
    parser = arg_parser(__doc__)
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of a fast point (default 3)")
    parser.add_argument("--time-limit", type=float, default=60.0, help="SciPy's limit per run [s] (default 60)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    # compile the explicit, implicit and N = 1 kernels before timing
    lgvi(scene(8, divided(0.5 * scene(8).stability_bound)))()
    lgvi(scene(8, solver={"string": "implicit"}))()
    lgvi(scene(1, 1e-4))()
    ref, floor = reference(args.quick)
    results, abandoned = {}, set()
    for name, param, factory in tqdm(grid(args.quick, 2.0 if args.quick else args.time_limit), desc="stiff work-precision", unit="run"):
        row = {"param": param}
        if name in abandoned:
            row.update(wall_s=None, error_m=None, work=None, status="skipped: a looser tolerance was too slow")
        else:
            try:
                x, wall = timed(factory(), args.repeats)
                if isinstance(x, tuple):  # SciPy's runner gives (positions, evaluations)
                    x = x[0]
                row.update(wall_s=wall, error_m=load_error(x, ref), work=None, status="ok")
            except TooSlow:
                abandoned.add(name)
                row.update(wall_s=None, error_m=None, work=None, status="abandoned: over the time limit")
            except (esp_gym.SimulationError, FloatingPointError) as err:
                row.update(wall_s=None, error_m=None, work=None, status=f"failed: {str(err)[:60]}")
        results.setdefault(name, []).append(row)
    rank = {f"{level:g}": {name: pareto_time(rows, level) for name, rows in results.items()} for level in LEVELS}
    print(f"\nreference: the explicit LGVI at N = {8 if args.quick else 32} and {16 if args.quick else 64}: "
          f"{floor:.2e} m apart\n")
    print_runs(results, 34, param=("h or tol", 10), work=("", 1))
    print()
    print_time_to_error(rank, results, 34, LEVELS)
    finish(args.out, "stiff_work_precision", {"results": results, "time_to_error": rank, "reference_floor_m": floor,
                                              "EA": EA, "t_final": T_FINAL, "machine": machine("scipy", "mujoco")},
           {"stiff_work_precision.png": lambda path: _plot(results, floor, path)}, start)
    return {"results": results, "time_to_error": rank}


def _plot(results: dict, floor: float, path) -> None:
    fig = figure((6.4, 4.2), dpi=130)
    ax = fig.subplots()
    for (name, rows), marker in zip(results.items(), "o^sDvP*"):
        ok = [r for r in rows if r["status"] == "ok"]
        if ok:
            ax.plot([r["wall_s"] for r in ok], [r["error_m"] for r in ok], marker + "-", label=name)
    ax.axhline(floor, color="grey", ls=":", lw=0.8, label="reference's floor (N = 32 vs 64)")
    ax.set(xscale="log", yscale="log", xlabel="wall time [s]", ylabel="load error [m]",
           title=f"drone_load at EA = {EA:g} N, fixed hook, 1 s")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.savefig(path)


if __name__ == "__main__":
    main()
