"""Work-precision of the LGVI against general-purpose integrators of the same finite-element
model (``esp_gym/verify/ode.py``), and their long-run energy behaviour.

1. Work-precision on the paper example over [0, T] (T = 1 s: the motion is chaotic after
   ~2 s, so pointwise errors are only meaningful early). Error = max over samples every 0.01 s
   of the load (attachment node) position error [m] against a reference: DOP853 at
   rtol = atol = 1e-13, cross-checked against the Richardson extrapolation of two LGVI runs
   with tiny h (the LGVI is symmetric, so its error expands in h^2, h^4). Methods:

   * the LGVI (``esp_gym.Simulator``) at h = 0.01 s / k from near the stability bound
     (7.2e-4 s) down to 1e-6 s;
   * the same LGVI variants with ``solver.compensated = false`` ("plain sums": no Kahan
     compensation of the state updates, which only matters over 1e6+ steps; RK4 has none
     either), whose Pareto front is reported separately as "LGVI frontier, plain sums";
   * a compiled classical RK4 with fixed h (``ElasticStringODE.rk4``, numba);
   * SciPy ``solve_ivp`` RK45 and DOP853 (numba right-hand side called from Python) at
     rtol = atol = tol;
   * SciPy Radau and BDF (implicit; Jacobian by finite differences over the vectorised numba
     right-hand side); a tolerance whose solve passes ``--time-limit`` seconds is abandoned,
     and so are the tighter ones.

   Wall time = building the integrator's objects from a validated scene (``Simulator`` or
   ``ElasticStringODE``) plus the integration with its samples, after compilation: median of
   ``--repeats`` runs when a run takes under 0.5 s, else one run.
   For each error level 1e-3, 1e-5, 1e-7 m the time each method needs is read off its Pareto
   front (log-log interpolation between measured points).

2. Long run: 100 s of the paper example, energy, pi3 and ||I - R^T R|| every 0.01 s, for the
   LGVI at h = 1e-4 s, RK4 at the h whose cost matches the LGVI's, and DOP853 at its cheapest
   tolerance (the tightest whose 1-s cost is within 1.25x of its cheapest: below that it is
   stability-bound and cannot be made cheaper) and at tol = 1e-10.

Prints tables and writes ``OUT/work_precision.json``, ``OUT/work_precision.png`` (error vs wall
time) and ``OUT/energy_longrun.png`` (OUT = benchmarks/out unless ``--out``).

Usage: ``python -m benchmarks.work_precision [--quick] [--out DIR]``. ``--quick``: a few
points per method, a looser reference, a 5-s long run: a smoke test (< 30 s), not a measurement.
"""
from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

from esp_gym.kernels.layout import STEP_DIAG

from benchmarks.common import (DEFAULT_OUT, LEVELS, arg_parser, energy_stats, figure, finish, fmt, load_error,
                               machine, pareto_time, print_runs, print_time_to_error, timed)


@dataclass
class Settings:
    quick: bool = False
    """smoke test: few points, loose reference, short long run"""
    out: str = str(DEFAULT_OUT)
    """output directory"""
    scene: str = "paper_example"
    """scene name (esp_gym/scenes)"""
    t_final: float = 1.0
    """work-precision horizon [s]"""
    sample: float = 0.01
    """sampling interval of the load position [s]"""
    repeats: int = 5
    """timing repeats for runs under 0.5 s (median)"""
    time_limit: float = 60.0
    """abandon an implicit solve after this many seconds [s]"""
    longrun: float = 100.0
    """long-run horizon [s]"""
    lgvi_k: tuple = (14, 16, 20, 25, 32, 40, 50, 64, 100, 160, 250, 400, 640, 1000, 1600, 2500, 4000,
                     6400, 10000)
    """LGVI steps per sample: h = sample / k"""
    composition_k: tuple = (("triple_jump", (18, 20, 25, 32, 40, 64, 100, 160, 250, 400)),
                            ("suzuki5", (11, 12, 14, 16, 20, 25, 32, 50, 80, 130, 200)),
                            ("wide5", (9, 10, 11, 12, 14, 16, 20, 25, 32, 50)),
                            ("kahan_li9", (12, 13, 14, 16, 18, 20, 25, 32, 40, 50, 64, 100)),
                            ("kahan_li17", (7, 8, 9, 10, 11, 12, 14, 16, 20, 25, 32, 50)))
    """steps per sample of each composition of the LGVI (esp_gym/scene/compositions.py)"""
    plain_k: tuple = (("lgvi", (14, 16, 20, 25, 32, 40, 50, 64, 100, 160, 250)),
                      ("suzuki5", (11, 12, 14, 16, 20, 25, 32, 50, 80)),
                      ("wide5", (9, 10, 11, 12, 14, 16, 20)),
                      ("kahan_li17", (7, 8, 9, 10, 12, 16, 25, 50)))
    """steps per sample of the variants run with solver.compensated = false (plain sums)"""
    rk4_k: tuple = (10, 11, 12, 14, 16, 20, 25, 32, 40, 50, 64, 100, 160, 250, 400)
    """RK4 steps per sample: h = sample / k"""
    explicit_tols: tuple = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
    """rtol = atol for RK45 and DOP853"""
    implicit_tols: tuple = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
    """rtol = atol for Radau and BDF"""
    reference_tol: float = 1e-13
    """DOP853 tolerance of the reference"""
    richardson_k: tuple = (5000, 10000)
    """LGVI steps per sample of the reference cross-check (h, h/2)"""

    @classmethod
    def quick_settings(cls, out: str) -> "Settings":
        return cls(quick=True, out=out, repeats=1, longrun=5.0, lgvi_k=(16, 100, 400),
                   composition_k=(("suzuki5", (14, 50)), ("kahan_li9", (16, 50))),
                   plain_k=(("wide5", (10, 50)),), rk4_k=(12, 50),
                   explicit_tols=(1e-4, 1e-7), implicit_tols=(1e-4,), reference_tol=1e-10,
                   richardson_k=(500, 1000), time_limit=10.0)


class TooSlow(Exception):
    """Raised from inside a solve that passed its time limit."""


# -- the integrators -----------------------------------------------------------------------------
def lgvi_samples(scene_name: str, k: int, t_final: float, sample: float, composition: str = "lgvi",
                 compensated: bool = True):
    """LGVI (or one of its compositions) with h = sample/k: returns a function giving
    (load positions (K+1, 3), steps)."""
    import esp_gym
    from esp_gym.scene.compositions import COMPOSITIONS

    h = sample / k
    solver = {"order": COMPOSITIONS[composition].order, "composition": composition,
              "compensated": compensated}
    scene = esp_gym.load_scene(scene_name, h=h, allow_unstable_h=True, solver=solver)

    def run():
        sim = esp_gym.Simulator(scene)
        traj = sim.run(t_final, record_every=k)
        return traj.nodes[:, -1].copy(), traj.steps

    return run, h


def rk4_samples(scene, k: int, t_final: float, sample: float):
    """Compiled RK4 with h = sample/k: function giving (load positions, steps)."""
    from esp_gym.verify.ode import ElasticStringODE

    h = sample / k
    nsteps = int(round(t_final / h))

    def run():
        ode = ElasticStringODE(scene)
        Y = ode.rk4(ode.y0(), h, nsteps, k)
        return ode.attach_position(Y), nsteps

    return run, h


def ivp_samples(scene, method: str, tol: float, t_eval: np.ndarray, deadline_s: float | None = None):
    """SciPy solve_ivp: function giving (load positions, nfev). Implicit methods get the
    vectorised right-hand side (their finite-difference Jacobian then costs one call)."""
    from scipy.integrate import solve_ivp

    from esp_gym.verify.ode import ElasticStringODE

    implicit = method in ("Radau", "BDF")

    def run():
        ode = ElasticStringODE(scene)
        fun = ode.rhs_columns if implicit else ode.rhs
        if deadline_s is not None:
            limit = time.perf_counter() + deadline_s
            inner = fun

            def fun(t, y):
                if time.perf_counter() > limit:
                    raise TooSlow
                return inner(t, y)
        sol = solve_ivp(fun, (t_eval[0], t_eval[-1]), ode.y0(), method=method, rtol=tol, atol=tol,
                        t_eval=t_eval, vectorized=implicit)
        if sol.status != 0:
            raise FloatingPointError(sol.message)
        return ode.attach_position(sol.y.T), ode.nfev  # right-hand sides, Jacobian columns included

    return run


# -- work-precision ----------------------------------------------------------------------------
def reference(cfg: Settings, scene, t_eval):
    """DOP853 at cfg.reference_tol, and its cross-checks."""
    runner = ivp_samples(scene, "DOP853", cfg.reference_tol, t_eval)
    start = time.perf_counter()
    ref, nfev = runner()
    wall = time.perf_counter() - start
    looser, _ = ivp_samples(scene, "DOP853", cfg.reference_tol * 10, t_eval)()
    k1, k2 = cfg.richardson_k
    x1, _ = lgvi_samples(cfg.scene, k1, cfg.t_final, cfg.sample)[0]()
    x2, _ = lgvi_samples(cfg.scene, k2, cfg.t_final, cfg.sample)[0]()
    rich = x2 + (x2 - x1) * (k1 ** 2 / (k2 ** 2 - k1 ** 2))
    info = {
        "method": "DOP853", "tol": cfg.reference_tol, "nfev": int(nfev), "wall_s": wall,
        "vs_DOP853_tol_x10_m": load_error(looser, ref),
        "lgvi_h": [cfg.sample / k1, cfg.sample / k2],
        "vs_lgvi_fine_m": load_error(x2, ref),
        "vs_lgvi_richardson_m": load_error(rich, ref),
    }
    return ref, info


def compile_all(cfg: Settings, scene, t_eval) -> None:
    """Every method's kernels compiled (and SciPy's solvers warmed) on short runs, before anything is
    timed."""
    lgvi_samples(cfg.scene, 20, 2 * cfg.sample, cfg.sample)[0]()
    for name, ks in cfg.composition_k:
        lgvi_samples(cfg.scene, 100, 2 * cfg.sample, cfg.sample, composition=name)[0]()
    for name, ks in cfg.plain_k:
        lgvi_samples(cfg.scene, 100, 2 * cfg.sample, cfg.sample, composition=name, compensated=False)[0]()
    rk4_samples(scene, 10, 2 * cfg.sample, cfg.sample)[0]()
    for method in ("RK45", "Radau"):
        ivp_samples(scene, method, 1e-3, t_eval[:3])()


def record_run(cfg: Settings, ref, results: dict, name: str, param: dict, runner) -> dict:
    """Time ``runner`` (its ``cfg.repeats``' best) and measure its load error against ``ref`` into
    ``results[name]``; a run past the time limit is abandoned, a failed one says why. Returns its row."""
    import esp_gym

    try:
        (x, work), wall = timed(runner, cfg.repeats)
        row = {"param": param, "wall_s": wall, "error_m": load_error(x, ref), "work": int(work), "status": "ok"}
    except TooSlow:
        row = {"param": param, "wall_s": None, "error_m": None, "work": None,
               "status": f"abandoned after {cfg.time_limit:g} s"}
    except (esp_gym.SimulationError, FloatingPointError) as err:
        row = {"param": param, "wall_s": None, "error_m": None, "work": None, "status": f"failed: {err}"}
    results.setdefault(name, []).append(row)
    return row


def run_lgvi_variants(cfg: Settings, record) -> None:
    """The LGVI, its compositions and their plain-sum variants at each of their step counts."""
    for k in cfg.lgvi_k:
        runner, h = lgvi_samples(cfg.scene, k, cfg.t_final, cfg.sample)
        record("LGVI (esp_gym)", {"h": h}, runner)
    for name, ks in cfg.composition_k:
        for k in ks:
            runner, h = lgvi_samples(cfg.scene, k, cfg.t_final, cfg.sample, composition=name)
            record(LABELS[name], {"h": h}, runner)
    for name, ks in cfg.plain_k:
        for k in ks:
            runner, h = lgvi_samples(cfg.scene, k, cfg.t_final, cfg.sample, composition=name, compensated=False)
            record(LABELS[name] + PLAIN, {"h": h}, runner)


def run_general_methods(cfg: Settings, scene, t_eval, record) -> None:
    """RK4 at fixed steps and SciPy's solvers at each tolerance (an implicit one stops at its first
    run past the time limit)."""
    for k in cfg.rk4_k:
        runner, h = rk4_samples(scene, k, cfg.t_final, cfg.sample)
        record("RK4 (numba, fixed h)", {"h": h}, runner)
    for method in ("RK45", "DOP853"):
        for tol in cfg.explicit_tols:
            record(f"{method} (SciPy)", {"tol": tol}, ivp_samples(scene, method, tol, t_eval))
    for method in ("Radau", "BDF"):
        for tol in cfg.implicit_tols:
            row = record(f"{method} (SciPy, implicit)", {"tol": tol},
                         ivp_samples(scene, method, tol, t_eval, deadline_s=cfg.time_limit))
            if row["status"].startswith("abandoned"):
                break


def work_precision(cfg: Settings):
    """Every method's runs against the reference: ``(results by method, the reference's info)``."""
    import esp_gym

    scene = esp_gym.load_scene(cfg.scene)
    ns = int(round(cfg.t_final / cfg.sample))
    t_eval = np.arange(ns + 1) * cfg.sample
    compile_all(cfg, scene, t_eval)
    ref, ref_info = reference(cfg, scene, t_eval)
    print(f"reference: DOP853 rtol = atol = {cfg.reference_tol:g} ({ref_info['nfev']} evaluations, "
          f"{ref_info['wall_s']:.2f} s); its distance to DOP853 at 10x the tolerance "
          f"{ref_info['vs_DOP853_tol_x10_m']:.1e} m, to the LGVI at h = {ref_info['lgvi_h'][1]:.1e} s "
          f"{ref_info['vs_lgvi_fine_m']:.1e} m, to the Richardson extrapolation of the LGVI at "
          f"h = {ref_info['lgvi_h'][0]:.1e}, {ref_info['lgvi_h'][1]:.1e} s {ref_info['vs_lgvi_richardson_m']:.1e} m")
    results = {}

    def record(name, param, runner):
        return record_run(cfg, ref, results, name, param, runner)

    run_lgvi_variants(cfg, record)
    run_general_methods(cfg, scene, t_eval, record)
    return results, ref_info


#: Labels of the LGVI variants. "LGVI frontier" is the Pareto front over the default
#: (compensated) variants, "LGVI frontier, plain sums" over those run with
#: solver.compensated = false.
LABELS = {"lgvi": "LGVI (esp_gym)", "triple_jump": "LGVI o4 triple jump", "suzuki5": "LGVI o4 Suzuki 5",
          "wide5": "LGVI o4 wide5", "kahan_li9": "LGVI o6 Kahan-Li 9", "kahan_li17": "LGVI o8 Kahan-Li 17"}
PLAIN = ", plain sums"
FRONTIER = "LGVI frontier"
FRONTIER_PLAIN = "LGVI frontier" + PLAIN
FRONTIERS = (FRONTIER, FRONTIER_PLAIN)


def is_lgvi(name: str) -> bool:
    return name.startswith("LGVI")


def ranking(results):
    """Time to each error level for every method, plus the LGVI frontiers (best LGVI variant,
    compensated and plain)."""
    table = {}
    for level in LEVELS:
        times = {name: pareto_time(rows, level) for name, rows in results.items()}
        for frontier, plain in ((FRONTIER, False), (FRONTIER_PLAIN, True)):
            lgvi = [t for name, t in times.items()
                    if is_lgvi(name) and name.endswith(PLAIN) == plain and t is not None]
            times[frontier] = min(lgvi) if lgvi else None
        table[f"{level:g}"] = times
    return table


# -- long run ------------------------------------------------------------------------------------
def invariant_columns(inv: np.ndarray) -> tuple:
    """(energy, pi3, orthogonality) columns of ``ElasticStringODE.invariants`` rows (STEP_DIAG)."""
    return tuple(inv[:, STEP_DIAG.scalar(name)] for name in ("energy", "pi3", "orthogonality"))


def drift_stats(t, E, pi3, orth, wall, label, extra):
    """:func:`~benchmarks.common.energy_stats` plus the drift of pi3 and of R's orthogonality."""
    dpi = pi3 - pi3[0]
    return {
        **energy_stats(t, E, wall, label, extra),
        "max_abs_pi3_error": float(np.abs(dpi).max()),
        "pi3_slope_per_s": float(np.polyfit(t, dpi, 1)[0]),
        "max_orthogonality": float(orth.max()),
        "final_orthogonality": float(orth[-1]),
    }


def long_run(cfg: Settings, wp):
    """LGVI h = 1e-4 vs RK4 and DOP853 at a comparable cost over cfg.longrun seconds."""
    from scipy.integrate import solve_ivp

    import esp_gym
    from esp_gym.verify.ode import ElasticStringODE

    T = cfg.longrun
    every_lgvi = int(round(cfg.sample / 1e-4))
    scene = esp_gym.load_scene(cfg.scene, h=1e-4)
    start = time.perf_counter()
    sim = esp_gym.Simulator(scene)
    traj = sim.run(T, record_every=every_lgvi)
    wall = time.perf_counter() - start
    series = {"LGVI h = 1e-4 s": (traj.t, traj.energy, traj.pi3, traj.orthogonality)}
    stats = [drift_stats(traj.t, traj.energy, traj.pi3, traj.orthogonality, wall, "LGVI h = 1e-4 s",
                         {"h": 1e-4, "steps": traj.steps})]
    lgvi_wall = wall

    # RK4: the h (from the work-precision steps) whose cost over T matches the LGVI's
    rk4_rows = [r for r in wp["RK4 (numba, fixed h)"] if r["status"] == "ok"]
    us_per_step = np.median([r["wall_s"] / r["work"] for r in rk4_rows])
    ks = [k for k in (10, 12, 14, 16, 20, 25, 32, 40, 50, 64, 100) if cfg.sample / k < 1e-3]
    k = min(ks, key=lambda k: abs(np.log(T / (cfg.sample / k) * us_per_step / lgvi_wall)))
    h = cfg.sample / k
    ode = ElasticStringODE(esp_gym.load_scene(cfg.scene))
    start = time.perf_counter()
    Y = ode.rk4(ode.y0(), h, int(round(T / h)), k)
    wall = time.perf_counter() - start
    inv = ode.invariants(Y)
    t = np.arange(len(Y)) * cfg.sample
    label = f"RK4 h = {h:.3g} s"
    series[label] = (t, *invariant_columns(inv))
    stats.append(drift_stats(t, *invariant_columns(inv), wall, label,
                             {"h": h, "steps": int(round(T / h))}))

    # DOP853: its cheapest tolerance, and a tight one
    dop = [r for r in wp["DOP853 (SciPy)"] if r["status"] == "ok"]
    cheapest = min(r["wall_s"] for r in dop)
    tol_cheap = min(r["param"]["tol"] for r in dop if r["wall_s"] <= 1.25 * cheapest)
    t_eval = np.arange(int(round(T / cfg.sample)) + 1) * cfg.sample
    for tol in sorted({tol_cheap, 1e-10}, reverse=True):
        ode = ElasticStringODE(esp_gym.load_scene(cfg.scene))
        start = time.perf_counter()
        sol = solve_ivp(ode.rhs, (0.0, T), ode.y0(), method="DOP853", rtol=tol, atol=tol, t_eval=t_eval)
        wall = time.perf_counter() - start
        inv = ode.invariants(sol.y.T)
        label = f"DOP853 tol = {tol:g}"
        series[label] = (sol.t, *invariant_columns(inv))
        stats.append(drift_stats(sol.t, *invariant_columns(inv), wall, label,
                                 {"tol": tol, "nfev": int(sol.nfev), "status": int(sol.status)}))
    return stats, series


# -- output --------------------------------------------------------------------------------------
def print_tables(cfg, results, rank, stats):
    print(f"\nwork-precision, {cfg.scene}, [0, {cfg.t_final:g}] s; error = max load position error over "
          f"samples every {cfg.sample:g} s")
    print_runs(results, 30, param=("h [s] / tol", 12), work=("steps/nfev", 11))
    print("\ntime to reach a load position error [ms] (Pareto front, log-log interpolation)")
    print_time_to_error(rank, list(results) + list(FRONTIERS), 30)
    for lv in LEVELS:
        times = {n: t for n, t in rank[f"{lv:g}"].items() if t is not None}
        others = {n: t for n, t in times.items() if not is_lgvi(n)}
        best = min(others, key=others.get) if others else None
        for frontier in FRONTIERS:
            lg = times.get(frontier)
            if lg is None or best is None:
                print(f"  {lv:g} m: {frontier} {fmt(lg)} s, best general-purpose {best}")
                continue
            plain = frontier == FRONTIER_PLAIN
            lead = min((n for n in times if is_lgvi(n) and n not in FRONTIERS and n.endswith(PLAIN) == plain),
                       key=times.get)
            print(f"  {lv:g} m: {frontier} {1e3 * lg:.2f} ms ({lead}); best general-purpose {best} "
                  f"{1e3 * others[best]:.2f} ms: the LGVI is {others[best] / lg:.2f}x as fast")
    print(f"\nlong run: {cfg.scene}, {cfg.longrun:g} s, invariants every {cfg.sample:g} s")
    print(f"{'':24} {'wall [s]':>9} {'max|dE| [J]':>12} {'dE slope [J/s]':>15} {'max|dpi3|':>10} "
          f"{'pi3 slope [/s]':>15} {'max orth':>9}")
    for s in stats:
        print(f"{s['label']:24} {s['wall_s']:9.2f} {s['max_abs_energy_error_J']:12.2e} "
              f"{s['energy_slope_J_per_s']:15.2e} {s['max_abs_pi3_error']:10.2e} {s['pi3_slope_per_s']:15.2e} "
              f"{s['max_orthogonality']:9.1e}")


COLORS = {"LGVI (esp_gym)": "tab:red", "LGVI o4 triple jump": "salmon", "LGVI o4 Suzuki 5": "darkred",
          "LGVI o4 wide5": "goldenrod",
          "LGVI o6 Kahan-Li 9": "magenta", "LGVI o8 Kahan-Li 17": "indigo", "RK4 (numba, fixed h)": "tab:blue",
          "RK45 (SciPy)": "tab:orange", "DOP853 (SciPy)": "tab:green", "Radau (SciPy, implicit)": "tab:purple",
          "BDF (SciPy, implicit)": "tab:brown"}


def plot_wp(cfg, results, path):
    fig = figure((8.5, 6))
    ax = fig.subplots()
    for name, rows in results.items():
        ok = [r for r in rows if r["status"] == "ok"]
        t = np.array([r["wall_s"] for r in ok])
        e = np.array([r["error_m"] for r in ok])
        plain = name.endswith(PLAIN)
        ax.loglog(t, e, "x--" if plain else "o-", ms=4, lw=1.6 if name.startswith("LGVI") else 1.1,
                  color=COLORS.get(name.removesuffix(PLAIN)), label=name)
        if ok and "h" in ok[0]["param"] and not plain:  # label the largest and smallest h
            below = name.startswith("LGVI")
            for i, xy in ((0, (-10, -14) if below else (-10, 8)), (len(ok) - 1, (6, -3))):
                ax.annotate(f"h={ok[i]['param']['h']:.1e}", (t[i], e[i]), textcoords="offset points",
                            xytext=xy, fontsize=7, color=COLORS.get(name))
    for lv in LEVELS:
        ax.axhline(lv, color="grey", ls=":", lw=0.8)
    ax.set_xlabel("wall time [s] (after compilation; median of repeats for fast runs)")
    ax.set_ylabel(f"max load position error over [0, {cfg.t_final:g}] s [m]")
    ax.set_title(f"Work-precision, {cfg.scene} (N = 20), reference DOP853 tol {cfg.reference_tol:g}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path)


def plot_energy(cfg, series, path):
    fig = figure((10, 10))
    a, b, c, d = fig.subplots(4, 1, sharex=True)
    colors = ["tab:red", "tab:blue", "tab:green", "tab:olive"]
    window = max(1, int(round(1.0 / cfg.sample)))  # 1-s windows

    def window_max(t, x):
        k = len(x) // window
        if k == 0:
            return t[-1:], np.abs(x[-1:])
        return t[window:k * window + 1:window], np.abs(x[1:k * window + 1]).reshape(k, window).max(axis=1)

    for (label, (t, E, pi3, orth)), col in zip(series.items(), colors):
        a.plot(t, E - E[0], lw=0.8, color=col, label=label)
        for ax, x in ((b, E - E[0]), (c, pi3 - pi3[0]), (d, orth)):
            tw, xw = window_max(t, x)
            ax.semilogy(tw, np.maximum(xw, 1e-20), lw=1.0, color=col, label=label)
    a.set_ylabel("E - E0 [J]")
    a.set_title(f"Long run, {cfg.scene}: LGVI vs RK4 and DOP853 (E0 = {series[next(iter(series))][1][0]:.5f} J; "
                "lower panels: max per 1-s window)")
    b.set_ylabel("max |E - E0| [J]")
    c.set_ylabel("max |pi3 - pi3(0)| [kg m^2/s]")
    d.set_ylabel("max ||I - R^T R||_F")
    d.set_xlabel("t [s]")
    for ax in (a, b, c, d):
        ax.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8, loc="lower left")
    fig.savefig(path)


def main(argv=None) -> int:
    parser = arg_parser(__doc__)
    parser.add_argument("--repeats", type=int, default=None, help="timing repeats (default 5, quick 1)")
    parser.add_argument("--time-limit", type=float, default=None, help="seconds per implicit solve (default 60)")
    args = parser.parse_args(argv)
    cfg = Settings.quick_settings(args.out) if args.quick else Settings(out=args.out)
    if args.repeats is not None:
        cfg.repeats = args.repeats
    if args.time_limit is not None:
        cfg.time_limit = args.time_limit
    start = time.perf_counter()

    results, ref_info = work_precision(cfg)
    rank = ranking(results)
    stats, series = long_run(cfg, results)
    print_tables(cfg, results, rank, stats)

    payload = {
        "settings": asdict(cfg), "reference": ref_info, "work_precision": results,
        "time_to_error_s": rank, "long_run": stats, "machine": machine("scipy"),
        "total_wall_s": time.perf_counter() - start,
    }
    finish(cfg.out, "work_precision", payload,
           {"work_precision.png": lambda path: plot_wp(cfg, results, path),
            "energy_longrun.png": lambda path: plot_energy(cfg, series, path)}, start)
    return 0


if __name__ == "__main__":
    sys.exit(main())
