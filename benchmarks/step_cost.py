"""Cost of one LGVI step against the number of elements N, and the cost of starting up.

Prints three tables and writes ``OUT/step_cost.json`` and ``OUT/step_cost.png``
(OUT = benchmarks/out unless ``--out`` says otherwise):

1. microseconds per step (median over repeats, no recording) for the scene ``paper_example``
   with N in {5, 10, 20, 40, 80}; h = min(1e-4, 0.8 h_max(N)) stays under each N's stability
   bound and is reported;
2. start-up (a child process run by benchmarks.cold_start): seconds from interpreter start to
   the first completed step (``sim.step(1)``) and to the first recorded run (``sim.run(...,
   every_step=True)``, which needs the recording and diagnostics kernels too), in a fresh
   process whose NUMBA_CACHE_DIR is an empty temporary directory (cold: everything compiles)
   and then again with the same directory (cached);
3. the paper's example, 50,000 steps after compilation: plain stepping and a recorded run
   (snapshots every 100 steps plus energy, pi3 and orthogonality after every step);
4. plain against Kahan-compensated state updates (``solver.compensated``);
5. the kernels specialised for a scene (fixed/free pivot, inputs or none, rho_c = 0, a
   composition) against the general kernel, and the cost of diagnostics.

Usage: ``python -m benchmarks.step_cost [--quick] [--no-startup] [--out DIR]``. ``--quick`` runs N
in {5, 20}, fewer steps and repeats, a 5,000-step paper run and start-up to the first step only: a
smoke test, not a measurement. ``--no-startup`` leaves out 2 (its cold child compiles everything:
about 12 s; ``benchmarks.cold_start`` measures start-up on its own).
"""
from __future__ import annotations

import sys
import tempfile

import numpy as np

from benchmarks.cold_start import CASES, run_case
from benchmarks.common import arg_parser, figure, finish, interleaved_wall_times, machine, median_wall, wall_times


def scene_for(n: int, h_max: float = 1e-4, safety: float = 0.8):
    """paper_example with N = n and h = min(h_max, safety * stability bound)."""
    import esp_gym

    bound = esp_gym.load_scene("paper_example", N=n, allow_unstable_h=True).string.element_bound
    h = min(h_max, safety * bound)
    return esp_gym.load_scene("paper_example", N=n, h=h), bound


def time_steps(scene, steps: int, repeats: int) -> dict:
    """Median, min and max microseconds per step of ``sim.step(steps)`` from the initial state."""
    import esp_gym

    esp_gym.Simulator(scene).step(2)  # make sure everything is loaded
    sims = []

    def fresh():
        sims.append(esp_gym.Simulator(scene))
        return sims[-1]

    per_step = [wall / steps * 1e6 for wall in wall_times(lambda sim: sim.step(steps), repeats, setup=fresh)]
    iters = sims[-1].newton_iterations
    return {"us_per_step": float(np.median(per_step)), "us_per_step_min": float(min(per_step)),
            "us_per_step_max": float(max(per_step)), "steps": steps, "repeats": repeats,
            "newton_iterations_mean": iters / steps}


def startup(cache_dir: str, first_run: bool = True) -> dict:
    """Seconds from a fresh Python process's start to its first step of the paper's example
    and (if ``first_run``) to the end of its first recorded run, with NUMBA_CACHE_DIR =
    ``cache_dir`` (benchmarks.cold_start runs the process)."""
    after = "sim.run(t_final=100 * sim.h, record_every=10, every_step=True)" if first_run else ""
    t = run_case(CASES["simulator"], cache_dir, after=after)
    return {"import_s": t["import_s"], "first_step_s": t["first_step_s"], "first_run_s": t["after_s"]}


def paper_timing(steps: int, repeats: int) -> dict:
    """The paper's example after compilation: plain stepping and a recorded run."""
    import esp_gym

    scene = esp_gym.load_scene("paper_example")
    plain = time_steps(scene, steps, repeats)
    esp_gym.Simulator(scene).run(t_final=100 * scene.h, record_every=100, every_step=True)
    walls = []
    for _ in range(repeats):
        traj = esp_gym.Simulator(scene).run(t_final=steps * scene.h, record_every=100, every_step=True)
        walls.append(traj.wall_time_s)
    wall = float(np.median(walls))
    return {"steps": steps, "h": scene.h, "N": scene.string.elements,
            "plain_s": plain["us_per_step"] * steps * 1e-6, "plain_us_per_step": plain["us_per_step"],
            "recorded_s": wall, "recorded_us_per_step": wall / steps * 1e6}


def _alternating(make_sims: dict, steps: int, repeats: int, inputs: dict) -> dict:
    """``{key: median us/step}`` of ``make_sims[key]().step(steps, **inputs)``, compiled first,
    timed in turn within each repeat (so every variant sees the same machine state)."""
    for make in make_sims.values():
        make().step(2, **inputs)  # compile
    walls = interleaved_wall_times({key: (make, lambda sim: sim.step(steps, **inputs))
                                    for key, make in make_sims.items()}, repeats)
    return {key: float(np.median(w)) / steps * 1e6 for key, w in walls.items()}


#: Scenes of the specialisation table: (label, paper_example overrides, step inputs).
SPECIALISED_CASES = (
    ("fixed pivot, no inputs", {}, {}),
    ("fixed pivot, torques", {}, {"body_torque": [0.0, 0.01, 0.0], "spatial_torque": [0.0, 0.0, 0.01]}),
    ("free pivot, no inputs", {"pivot": {"kind": "free", "mass": 0.3}}, {}),
    ("free pivot, pushed", {"pivot": {"kind": "free", "mass": 0.3}}, {"pivot_force": [0.1, 0.0, -3.0]}),
    ("rho_c = 0, no inputs", {"rho_c": [0.0, 0.0, 0.0]}, {}),
    ("order 4 (Suzuki), no inputs", {"solver": {"order": 4}}, {}),
)


def specialisation_timing(steps: int, repeats: int, cases=SPECIALISED_CASES) -> list:
    """us/step of the general kernel and of the kernel specialised for each case (medians of
    ``repeats`` alternating runs, so both see the same machine state)."""
    import esp_gym

    rows = []
    for label, overrides, inputs in cases:
        scene = esp_gym.load_scene("paper_example", **overrides)
        makers = {spec: lambda spec=spec: esp_gym.Simulator(scene, specialise=spec) for spec in (True, False)}
        runs = _alternating(makers, steps, repeats, inputs)
        general, special = runs[False], runs[True]
        rows.append({"case": label, "general_us": general, "specialised_us": special, "speedup": general / special})
    return rows


COMPENSATION_CASES = (
    ("LGVI, no inputs", {}, {}),
    ("free pivot, pushed", {"pivot": {"kind": "free", "mass": 0.3}}, {"pivot_force": [0.2, -0.1, -3.0]}),
    ("order 4 (Suzuki), no inputs", {"solver": {"order": 4}}, {}),
)


def compensation_timing(steps: int, repeats: int, cases=COMPENSATION_CASES) -> list:
    """us/step with Kahan-compensated state updates (the default) and with plain sums
    (``solver.compensated: false``), both on the specialised kernels, alternating runs."""
    import esp_gym

    rows = []
    for label, overrides, inputs in cases:
        scenes = {c: esp_gym.load_scene("paper_example", **overrides, **{"solver.compensated": c})
                  for c in (True, False)}
        runs = _alternating({c: lambda sc=sc: esp_gym.Simulator(sc) for c, sc in scenes.items()}, steps, repeats,
                            inputs)
        kahan, plain = runs[True], runs[False]
        rows.append({"case": label, "compensated_us": kahan, "plain_us": plain, "speedup": kahan / plain})
    return rows


def diagnostics_timing(steps: int, repeats: int) -> dict:
    """us/step of the paper example with diagnostics off (plain stepping), with snapshots every
    100 steps, and with energy, pi3 and orthogonality after every step as well."""
    import esp_gym

    scene = esp_gym.load_scene("paper_example")
    modes = {"off (step)": lambda sim: sim.step(steps),
             "snapshots every 100 steps": lambda sim: sim.run(steps * scene.h, record_every=100),
             "every step": lambda sim: sim.run(steps * scene.h, record_every=100, every_step=True)}
    for fn in modes.values():
        fn(esp_gym.Simulator(scene))  # compile
    return {name: median_wall(fn, repeats, setup=lambda: esp_gym.Simulator(scene)) / steps * 1e6
            for name, fn in modes.items()}


def plot(results: dict, path) -> None:
    from matplotlib.ticker import NullFormatter

    rows = results["step_cost"]
    n = np.array([r["N"] for r in rows], dtype=float)
    us = np.array([r["us_per_step"] for r in rows])
    lo = np.array([r["us_per_step_min"] for r in rows])
    hi = np.array([r["us_per_step_max"] for r in rows])
    fig = figure((10, 4.2))
    a, b = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.3, 1]})
    a.errorbar(n, us, yerr=[us - lo, hi - us], fmt="o-", color="tab:blue", capsize=3,
               label="median over repeats (bars: min..max)")
    ref = us[-1] * n / n[-1]
    a.plot(n, ref, ls="--", color="grey", label="proportional to N")
    hs = sorted({r["h"] for r in rows})
    if len(hs) > 1:  # label h where it differs between N
        for x, y, r in zip(n, us, rows):
            a.annotate(f"h={r['h']:.2g}", (x, y), textcoords="offset points", xytext=(4, -12), fontsize=7.5)
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xticks(n, [f"{int(x)}" for x in n])
    a.xaxis.set_minor_formatter(NullFormatter())
    yt = [v for v in (0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100) if ref.min() / 1.5 <= v <= hi.max() * 1.5]
    a.set_yticks(yt, [f"{v:g}" for v in yt])
    a.yaxis.set_minor_formatter(NullFormatter())
    a.set_xlabel("elements N")
    a.set_ylabel("time per step [us]")
    a.set_title("LGVI step cost, paper_example (no recording)"
                + (f", h = {hs[0]:g} s" if len(hs) == 1 else ""))
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)

    su = results["startup"]
    if su is None:
        b.set_axis_off()
        b.text(0.5, 0.5, "start-up not measured (--no-startup)", ha="center", va="center")
        fig.savefig(path)
        return
    keys = [k for k in ("first_step_s", "first_run_s") if su["cold"][k] is not None]
    labels = [{"first_step_s": "first step", "first_run_s": "first recorded run"}[k] for k in keys]
    x = np.arange(len(labels))
    cold = [su["cold"][k] for k in keys]
    warm = [su["cached"][k] for k in keys]
    b.bar(x - 0.2, cold, 0.4, color="tab:red", label="cold (empty numba cache)")
    b.bar(x + 0.2, warm, 0.4, color="tab:green", label="cached")
    for xs, vals in ((x - 0.2, cold), (x + 0.2, warm)):
        for xi, v in zip(xs, vals):
            b.annotate(f"{v:.2f} s", (xi, v), ha="center", va="bottom", fontsize=8)
    b.set_xticks(x, labels)
    b.set_ylabel("seconds from process start")
    b.set_title("Start-up (N = 20)")
    b.legend(fontsize=8)
    b.grid(True, axis="y", alpha=0.3)
    fig.savefig(path)


def measure_startup(quick: bool) -> dict:
    """Table 2: ``{"cold": ..., "cached": ...}`` of :func:`startup`, printed."""
    with tempfile.TemporaryDirectory(prefix="esp_gym_numba_cache_") as cache:
        starts = {"cold": startup(cache, first_run=not quick), "cached": startup(cache, first_run=not quick)}
    print("start-up: seconds from process start (fresh NUMBA_CACHE_DIR, then the same one)")
    print(f"{'':8} {'imports':>8} {'first step':>11} {'first recorded run':>19}")
    for name, s in starts.items():
        run = "(skipped)" if s["first_run_s"] is None else f"{s['first_run_s']:.2f}"
        print(f"{name:8} {s['import_s']:8.2f} {s['first_step_s']:11.2f} {run:>19}")
    return starts


def main(argv=None) -> int:
    parser = arg_parser(__doc__)
    parser.add_argument("--no-startup", action="store_true", help="leave out the start-up measurement (table 2)")
    args = parser.parse_args(argv)

    elements = (5, 20) if args.quick else (5, 10, 20, 40, 80)
    steps, repeats = (2_000, 3) if args.quick else (20_000, 7)
    paper_steps = 5_000 if args.quick else 50_000

    # start-up first, while the parent has compiled nothing (the children do not share its state)
    starts = None if args.no_startup else measure_startup(args.quick)

    rows = []
    for n in elements:
        scene, bound = scene_for(n)
        r = time_steps(scene, steps, repeats)
        rows.append({"N": n, "h": scene.h, "h_bound": bound, **r})
    print(f"\nstep cost, paper_example, median of {repeats} x {steps} steps (no recording)")
    print(f"{'N':>4} {'h [s]':>9} {'h_max [s]':>10} {'us/step':>8} {'min':>7} {'max':>7} {'ns/step/elem':>13} {'Newton/step':>12}")
    for r in rows:
        print(f"{r['N']:4d} {r['h']:9.2e} {r['h_bound']:10.2e} {r['us_per_step']:8.3f} {r['us_per_step_min']:7.3f} "
              f"{r['us_per_step_max']:7.3f} {1e3 * r['us_per_step'] / r['N']:13.1f} {r['newton_iterations_mean']:12.2f}")

    paper = paper_timing(paper_steps, 3 if args.quick else 5)
    print(f"\npaper example after compilation (N = {paper['N']}, h = {paper['h']:g} s, {paper['steps']} steps)")
    print(f"  plain stepping: {paper['plain_s'] * 1e3:8.2f} ms ({paper['plain_us_per_step']:.3f} us/step)")
    print(f"  recorded run:   {paper['recorded_s'] * 1e3:8.2f} ms ({paper['recorded_us_per_step']:.3f} us/step; "
          "snapshots every 100 steps + per-step energy, pi3, orthogonality)")

    spec = specialisation_timing(steps, repeats, SPECIALISED_CASES[:2] if args.quick else SPECIALISED_CASES)
    print(f"\nspecialised kernels, paper_example (N = 20, h = 1e-4 s), median of {repeats} x {steps} steps")
    print(f"{'scene':30} {'general [us]':>13} {'specialised [us]':>17} {'speed-up':>9}")
    for r in spec:
        print(f"{r['case']:30} {r['general_us']:13.3f} {r['specialised_us']:17.3f} {r['speedup']:9.2f}")
    comp = compensation_timing(steps, repeats, COMPENSATION_CASES[:1] if args.quick else COMPENSATION_CASES)
    print(f"\nstate updates, paper_example: Kahan-compensated (default) vs plain sums, median of "
          f"{repeats} x {steps} steps")
    print(f"{'scene':30} {'compensated [us]':>17} {'plain [us]':>11} {'speed-up':>9}")
    for r in comp:
        print(f"{r['case']:30} {r['compensated_us']:17.3f} {r['plain_us']:11.3f} {r['speedup']:9.2f}")
    diag = diagnostics_timing(steps, repeats)
    print("\ndiagnostics, paper_example: us/step")
    for name, us in diag.items():
        print(f"  {name:28} {us:7.3f}  ({us / diag['off (step)']:.2f}x)")

    results = {
        "specialised": spec,
        "compensation": comp,
        "diagnostics_us_per_step": diag,
        "quick": args.quick,
        "step_cost": rows,
        "startup": starts,
        "paper_example": paper,
        "machine": machine(),
    }
    finish(args.out, "step_cost", results, {"step_cost.png": lambda path: plot(results, path)})
    return 0


if __name__ == "__main__":
    sys.exit(main())
