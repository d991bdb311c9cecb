"""Work-precision of the LGVI against MuJoCo on the same lumped-mass model, stability limits and
long-run energy behaviour.

With ``string.mass_model: lumped`` the scene is a chain of point masses and linear springs
carrying a rigid body, which MuJoCo represents exactly (``esp_gym/verify/mujoco_chain.py``: slide-joint
point masses, tendon springs, a free-joint load; tests/test_mujoco_chain.py shows the two
models are the same ODE). Both sides integrate that one ODE, so the comparison is of the
integrators and their implementations only.

1. Work-precision on the paper example (lumped mass) over [0, T], T = 1 s. Error = max over
   samples every 0.01 s of the attachment point position error [m] against a reference: the
   LGVI's order-4 Suzuki composition at h = 1.25e-5 s, cross-checked against itself at 2h,
   against the Richardson extrapolation of the order-2 LGVI and against MuJoCo RK4 at
   h = 2.5e-5 s. Methods, each at h = 0.01 s / k: the LGVI (order 2) and its Suzuki 5-stage
   composition (order 4); MuJoCo RK4, Euler (semi-implicit) and implicitfast, stepping
   ``mj_step(m, d, nstep=k)`` between samples. Wall time = the set-up a user pays per run
   (LGVI: ``esp_gym.Simulator(scene)``; MuJoCo: ``mj_resetData`` and writing the initial
   qpos/qvel, the model compiled once beforehand) plus the run with its samples, after
   compilation: median of ``--repeats`` runs when a run takes under 0.5 s, else one run. The
   time each method needs for an error of 1e-3 .. 1e-9 m is read off its Pareto front.
2. Cost per step: each method (and MuJoCo's implicit and discrete integrators) at h = 1e-4 s
   over T, median of repeats [us/step], set-up and samples included.
3. Stability: the largest h (on a grid of 2.5 % of the LGVI's bound 1/sqrt(kappa/m) = 2/omega
   with omega = sqrt(4 kappa/m)) below which every grid h runs ``--stability-horizon`` seconds
   without blowing up (a non-finite state, an element stretched past 10 rest lengths, an energy
   gain of 10 % of (M + mu l) g l, or a MuJoCo warning: MuJoCo resets a diverged state
   silently), checked every 0.1 s, and the energy change at the end of that run.
4. Long run: 100 s, energy every 0.01 s: each MuJoCo integrator of item 1 at 0.85 of its largest
   stable h (its cheapest safe run) and the LGVI at the h whose run costs the same; and the LGVI
   alone at 0.8 of its own largest stable h.

Prints tables and writes ``OUT/mujoco_chain.json`` and ``OUT/mujoco_chain.png`` (error vs wall
time; OUT = benchmarks/out unless ``--out``). Needs the optional dependency: ``pip install
esp_gym[bench]``.

Usage: ``python -m benchmarks.mujoco_chain [--quick] [--out DIR]``. ``--quick``: a few points per
method, a loose reference, a short stability scan and long run: a smoke test, not a measurement.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np
from tqdm.auto import tqdm

from benchmarks.common import (DEFAULT_OUT, LEVELS, arg_parser, energy_stats, figure, finish, fmt, load_error,
                               machine, pareto_time, print_runs, print_time_to_error, timed)

LGVI, SUZUKI = "LGVI (esp_gym)", "LGVI o4 Suzuki 5"
#: MuJoCo integrators in the work-precision comparison (all five are in the stability scan).
MUJOCO_WP = ("RK4", "Euler", "implicitfast")
MUJOCO_ALL = ("RK4", "Euler", "implicit", "implicitfast", "discrete")
#: Force evaluations per step: RK4 4 stages, the Suzuki composition 5 LGVI substeps.
EVALUATIONS = {LGVI: 1, SUZUKI: 5, "MuJoCo RK4": 4}


@dataclass
class Settings:
    quick: bool = False
    """smoke test: few points, loose reference, short scans"""
    out: str = str(DEFAULT_OUT)
    """output directory"""
    scene: str = "paper_example"
    """scene name (esp_gym/scenes), run with string.mass_model = lumped"""
    t_final: float = 1.0
    """work-precision horizon [s]"""
    sample: float = 0.01
    """sampling interval of the attachment point [s]"""
    repeats: int = 5
    """timing repeats for runs under 0.5 s (median)"""
    lgvi_k: tuple = (9, 10, 12, 14, 16, 20, 25, 32, 40, 50, 64, 100, 160, 250, 400, 640, 1000, 1600, 2500)
    """LGVI steps per sample: h = sample / k"""
    suzuki_k: tuple = (6, 7, 8, 10, 12, 16, 20, 25, 32, 50, 64, 100)
    """Suzuki-composition steps per sample"""
    rk4_k: tuple = (7, 8, 9, 10, 12, 16, 20, 25, 32, 50, 64, 100, 160, 250)
    """MuJoCo RK4 steps per sample"""
    euler_k: tuple = (9, 10, 12, 16, 25, 50, 100, 250, 1000, 4000)
    """MuJoCo Euler and implicitfast steps per sample (first order: 1e-5 m needs h ~ 4e-6 s)"""
    reference_k: int = 800
    """Suzuki-composition steps per sample of the reference (cross-checked at half of it)"""
    richardson_k: tuple = (1000, 2000)
    """LGVI steps per sample of the reference cross-check (h, h/2)"""
    rk4_check_k: int = 400
    """MuJoCo RK4 steps per sample of the reference cross-check"""
    cost_h: float = 1e-4
    """h of the per-step cost measurement [s]"""
    stability_horizon: float = 10.0
    """length of each stability run [s]"""
    stability_ratios: tuple = tuple(round(0.8 + 0.025 * i, 3) for i in range(41))
    """h / (the LGVI's bound) scanned upwards until the first failure"""
    longrun: float = 100.0
    """long-run horizon [s]"""

    @classmethod
    def quick_settings(cls, out: str) -> "Settings":
        return cls(quick=True, out=out, repeats=1, lgvi_k=(16, 100), suzuki_k=(16,), rk4_k=(16, 100),
                   euler_k=(16,), reference_k=200, richardson_k=(100, 200), rk4_check_k=100,
                   stability_horizon=1.0, stability_ratios=(0.9, 1.2, 1.5), longrun=2.0)


def lumped_scene(cfg: Settings, h: float, suzuki: bool = False):
    import esp_gym

    solver = {"order": 4, "composition": "suzuki5"} if suzuki else {}
    return esp_gym.load_scene(cfg.scene, h=h, allow_unstable_h=True, solver=solver,
                              string={"mass_model": "lumped"})


# -- the integrators -----------------------------------------------------------------------------
def lgvi_runner(cfg: Settings, k: int, suzuki: bool = False, t_final: float | None = None):
    """LGVI (or its Suzuki composition) at h = sample/k: a function giving (attachment
    positions (K+1, 3), steps)."""
    import esp_gym

    scene = lumped_scene(cfg, cfg.sample / k, suzuki)
    T = cfg.t_final if t_final is None else t_final

    def run():
        traj = esp_gym.Simulator(scene).run(T, record_every=k)
        return traj.nodes[:, -1].copy(), traj.steps

    return run


class Unstable(Exception):
    """A MuJoCo run diverged (non-finite state, a silent MuJoCo reset, or far off)."""


def mujoco_runner(cfg: Settings, integrator: str, k: int, t_final: float | None = None):
    """MuJoCo ``integrator`` at h = sample/k, compiled once: a function giving (attachment
    positions, steps) that resets the data and runs."""
    from esp_gym.verify.mujoco_chain import MujocoChain

    chain = MujocoChain(lumped_scene(cfg, cfg.sample), integrator, h=cfg.sample / k)
    T = cfg.t_final if t_final is None else t_final

    def run():
        chain.reset()
        x = chain.samples(T, k)
        if chain.warnings() or not np.all(np.isfinite(x)) or np.abs(x).max() > 10.0:
            raise Unstable(f"diverged ({chain.warnings()} MuJoCo warnings)")
        return x, int(round(T / chain.h))

    return run


def compile_all(cfg: Settings) -> None:
    """Compile the LGVI kernels (lumped, both solvers) before timing anything."""
    for suzuki in (False, True):
        lgvi_runner(cfg, 100, suzuki, t_final=2 * cfg.sample)()


# -- work-precision ----------------------------------------------------------------------------
def reference(cfg: Settings):
    """The Suzuki composition at h = sample/reference_k, and its cross-checks."""
    start = time.perf_counter()
    ref, _ = lgvi_runner(cfg, cfg.reference_k, suzuki=True)()
    wall = time.perf_counter() - start
    half, _ = lgvi_runner(cfg, cfg.reference_k // 2, suzuki=True)()
    k1, k2 = cfg.richardson_k
    x1, _ = lgvi_runner(cfg, k1)()
    x2, _ = lgvi_runner(cfg, k2)()
    rich = x2 + (x2 - x1) * (k1 ** 2 / (k2 ** 2 - k1 ** 2))
    rk4, _ = mujoco_runner(cfg, "RK4", cfg.rk4_check_k)()
    info = {"method": SUZUKI, "h": cfg.sample / cfg.reference_k, "wall_s": wall,
            "vs_half_steps_m": load_error(half, ref),
            "richardson_h": [cfg.sample / k1, cfg.sample / k2], "vs_lgvi_richardson_m": load_error(rich, ref),
            "mujoco_rk4_h": cfg.sample / cfg.rk4_check_k, "vs_mujoco_rk4_m": load_error(rk4, ref)}
    return ref, info


def method_grid(cfg: Settings):
    """(name, k, runner factory) of every work-precision run."""
    grid = [(LGVI, k, lambda k=k: lgvi_runner(cfg, k)) for k in cfg.lgvi_k]
    grid += [(SUZUKI, k, lambda k=k: lgvi_runner(cfg, k, suzuki=True)) for k in cfg.suzuki_k]
    for integrator in MUJOCO_WP:
        ks = cfg.rk4_k if integrator == "RK4" else cfg.euler_k
        grid += [(f"MuJoCo {integrator}", k, lambda k=k, i=integrator: mujoco_runner(cfg, i, k)) for k in ks]
    return grid


def work_precision(cfg: Settings, ref):
    import esp_gym

    results = {}
    grid = method_grid(cfg)
    for name, k, factory in tqdm(grid, desc="work-precision", unit="run"):
        row = {"param": {"h": cfg.sample / k}}
        try:
            (x, steps), wall = timed(factory(), cfg.repeats)
            row.update(wall_s=wall, error_m=load_error(x, ref), work=int(steps), status="ok")
        except (esp_gym.SimulationError, Unstable) as err:
            row.update(wall_s=None, error_m=None, work=None, status=f"failed: {err}")
        results.setdefault(name, []).append(row)
    return results


def ranking(results):
    """Time [s] to each error level for every method (Pareto front)."""
    return {f"{level:g}": {name: pareto_time(rows, level) for name, rows in results.items()} for level in LEVELS}


# -- cost per step -------------------------------------------------------------------------------
def step_costs(cfg: Settings):
    """us per step of each method at h = cfg.cost_h over cfg.t_final (set-up included)."""
    k = int(round(cfg.sample / cfg.cost_h))
    runners = {LGVI: lgvi_runner(cfg, k), SUZUKI: lgvi_runner(cfg, k, suzuki=True)}
    runners.update({f"MuJoCo {i}": mujoco_runner(cfg, i, k) for i in MUJOCO_ALL})
    costs = {}
    for name, run in tqdm(runners.items(), desc="step cost", unit="method"):
        (_, steps), wall = timed(run, max(cfg.repeats, 3))
        us = 1e6 * wall / steps
        costs[name] = {"h": cfg.sample / k, "steps": steps, "us_per_step": us,
                       "evaluations_per_step": EVALUATIONS.get(name, 1),
                       "us_per_evaluation": us / EVALUATIONS.get(name, 1)}
    return costs


def setup_costs(cfg: Settings):
    """Per-run and one-off set-up [s]: Simulator(scene); MuJoCo compile; reset + initial state."""
    import timeit

    import esp_gym
    from esp_gym.verify.mujoco_chain import MujocoChain

    scene = lumped_scene(cfg, cfg.cost_h)
    chain = MujocoChain(scene, "RK4")
    best = lambda fn, n: min(timeit.repeat(fn, number=n, repeat=5)) / n  # noqa: E731
    return {"lgvi_simulator_s": best(lambda: esp_gym.Simulator(scene), 20),
            "mujoco_compile_s": best(lambda: MujocoChain(scene, "RK4"), 3),
            "mujoco_reset_s": best(chain.reset, 200)}


# -- stability -----------------------------------------------------------------------------------
def blowup_energy(scene) -> float:
    """Energy gain [J] taken as a blow-up: 10 % of (M + mu l) g l, the energy of dropping the
    whole system by the string's length. Near their bounds, runs here gain energy slowly for
    seconds before they diverge: this catches that within the horizon."""
    st = scene.string
    return 0.1 * (scene.body.mass + st.mass_per_length * st.length) * scene.gravity * st.length


def survives(cfg: Settings, scene, h: float, advance, state):
    """``(ok, energy change [J] at the end, why it failed)`` of a run of ``advance(nsteps)``
    over the stability horizon, checked every 0.1 s through ``state() -> (node positions,
    energy, failed)``: it fails on a failure flag (an LGVI error, a MuJoCo warning: MuJoCo
    resets a diverged state silently), a non-finite state, an element beyond 10 rest lengths
    (the LGVI's own guard) or an energy gain above :func:`blowup_energy`."""
    nsteps = int(round(cfg.stability_horizon / h))
    chunk = max(1, int(round(0.1 / h)))
    limit = 10.0 * scene.string.u
    _, E0, _ = state()
    with np.errstate(all="ignore"):
        for done in range(0, nsteps, chunk):
            t = min(done + chunk, nsteps) * h
            if not advance(min(chunk, nsteps - done)):
                return False, None, f"solver error by t = {t:.1f} s"
            r, E, failed = state()
            if failed or not np.all(np.isfinite(r)) or not math.isfinite(E):
                return False, None, f"diverged by t = {t:.1f} s"
            if np.linalg.norm(np.diff(r, axis=0), axis=1).max() > limit:
                return False, None, f"stretch > 10 by t = {t:.1f} s"
            if E - E0 > blowup_energy(scene):
                return False, None, f"energy gain by t = {t:.1f} s"
    return True, E - E0, ""


def lgvi_stable(cfg: Settings, h: float, suzuki: bool):
    """:func:`survives` for the LGVI (or its Suzuki composition) at h."""
    import esp_gym

    scene = lumped_scene(cfg, h, suzuki)
    sim = esp_gym.Simulator(scene)

    def advance(n):
        try:
            sim.step(n)
        except esp_gym.SimulationError:
            return False
        return True

    return survives(cfg, scene, h, advance, lambda: (sim.state.r, sim.diagnostics()["energy"], False))


def mujoco_stable(cfg: Settings, h: float, integrator: str):
    """:func:`survives` for MuJoCo ``integrator`` at h."""
    from esp_gym.verify.mujoco_chain import MujocoChain

    scene = lumped_scene(cfg, h)
    chain = MujocoChain(scene, integrator, h=h)

    def advance(n):
        chain.step(n)
        return True

    return survives(cfg, scene, h, advance,
                    lambda: (chain.node_positions(), chain.total_energy(), chain.warnings() > 0))


def stability(cfg: Settings):
    """Largest stable h of each integrator on the ratio grid (scanned up to the first failure)."""
    bound = lumped_scene(cfg, cfg.cost_h).string.element_bound
    checks = {LGVI: lambda h: lgvi_stable(cfg, h, False), SUZUKI: lambda h: lgvi_stable(cfg, h, True)}
    checks.update({f"MuJoCo {i}": (lambda h, i=i: mujoco_stable(cfg, h, i)) for i in MUJOCO_ALL})
    rows = []
    for name, check in tqdm(checks.items(), desc="stability", unit="integrator"):
        best, first_fail, why = None, None, ""
        for ratio in cfg.stability_ratios:
            ok, dE, why = check(ratio * bound)
            if not ok:
                first_fail = ratio
                break
            best = (ratio, dE)
        rows.append({"integrator": name, "lgvi_bound_s": bound,
                     "largest_stable_ratio": None if best is None else best[0],
                     "largest_stable_h_s": None if best is None else best[0] * bound,
                     "energy_change_J": None if best is None else best[1],
                     "first_failing_ratio": first_fail, "horizon_s": cfg.stability_horizon,
                     "failure": why if first_fail is not None else "none on the grid (it ends there)"})
    return rows


# -- long run ------------------------------------------------------------------------------------
def lgvi_longrun(cfg: Settings, k: int):
    import esp_gym

    scene = lumped_scene(cfg, cfg.sample / k)
    start = time.perf_counter()
    traj = esp_gym.Simulator(scene).run(cfg.longrun, record_every=k)
    wall = time.perf_counter() - start
    return energy_stats(traj.t, traj.energy, wall, f"LGVI h = {scene.h:.3g} s", {"h": scene.h, "steps": traj.steps})


def mujoco_longrun(cfg: Settings, integrator: str, k: int):
    from esp_gym.verify.mujoco_chain import MujocoChain

    chain = MujocoChain(lumped_scene(cfg, cfg.sample), integrator, h=cfg.sample / k)
    K = int(round(cfg.longrun / cfg.sample))
    E = np.empty(K + 1)
    start = time.perf_counter()
    chain.reset()
    E[0] = chain.total_energy()
    for j in range(1, K + 1):
        chain.step(k)
        E[j] = chain.total_energy()
    wall = time.perf_counter() - start
    status = "ok" if chain.warnings() == 0 and np.all(np.isfinite(E)) else "diverged"
    return energy_stats(np.arange(K + 1) * cfg.sample, E, wall, f"MuJoCo {integrator} h = {chain.h:.3g} s",
                        {"h": chain.h, "steps": K * k, "status": status})


def long_run(cfg: Settings, stab, costs):
    """Each MuJoCo integrator of the work-precision set at 0.85 of its largest stable h, the
    LGVI at the h of equal cost, and the LGVI at 0.8 of its bound."""
    stable_h = {s["integrator"]: s["largest_stable_h_s"] for s in stab}
    lgvi_us = costs[LGVI]["us_per_step"]
    k_lgvi_min = math.ceil(cfg.sample / (0.8 * stable_h[LGVI]))
    stats = [lgvi_longrun(cfg, k_lgvi_min)]
    for integrator in tqdm(MUJOCO_WP, desc="long run", unit="pair"):
        k = math.ceil(cfg.sample / (0.85 * stable_h[f"MuJoCo {integrator}"]))
        mj = mujoco_longrun(cfg, integrator, k)
        steps = mj["wall_s"] / (1e-6 * lgvi_us)  # LGVI steps that cost as much
        k_eq = max(k_lgvi_min, int(round(steps * cfg.sample / cfg.longrun)))
        lg = lgvi_longrun(cfg, k_eq)
        lg["equal_cost_with"] = mj["label"]
        lg["label"] += " (same cost)"
        stats += [mj, lg]
    return stats


# -- output --------------------------------------------------------------------------------------
def print_tables(cfg, ref_info, setup, results, rank, costs, stab, stats):
    print(f"\nreference: {ref_info['method']} at h = {ref_info['h']:.3g} s ({ref_info['wall_s']:.2f} s); its "
          f"distance to itself at 2h {ref_info['vs_half_steps_m']:.1e} m, to the Richardson extrapolation of the "
          f"LGVI at h = {ref_info['richardson_h'][0]:.1e}, {ref_info['richardson_h'][1]:.1e} s "
          f"{ref_info['vs_lgvi_richardson_m']:.1e} m, to MuJoCo RK4 at h = {ref_info['mujoco_rk4_h']:.1e} s "
          f"{ref_info['vs_mujoco_rk4_m']:.1e} m")
    print(f"set-up per run: esp_gym.Simulator(scene) {1e3 * setup['lgvi_simulator_s']:.3f} ms; MuJoCo mj_resetData "
          f"+ initial state {1e3 * setup['mujoco_reset_s']:.3f} ms (+ compiling the MJCF once, "
          f"{1e3 * setup['mujoco_compile_s']:.2f} ms, not timed)")
    print(f"\nwork-precision, {cfg.scene} with lumped mass, [0, {cfg.t_final:g}] s; error = max attachment point "
          f"error over samples every {cfg.sample:g} s")
    print_runs(results, 22)
    print("\ntime to reach an attachment point error [ms] (Pareto front, log-log interpolation)")
    print_time_to_error(rank, results, 22)
    for lv in LEVELS:
        times = {n: t for n, t in rank[f"{lv:g}"].items() if t is not None}
        mj = {n: t for n, t in times.items() if n.startswith("MuJoCo")}
        lg = {n: t for n, t in times.items() if n.startswith("LGVI")}
        if mj and lg:
            a, b = min(lg, key=lg.get), min(mj, key=mj.get)
            print(f"  {lv:g} m: fastest LGVI {a} {1e3 * lg[a]:.2f} ms, fastest MuJoCo {b} {1e3 * mj[b]:.2f} ms: "
                  f"{mj[b] / lg[a]:.1f}x")
        else:
            print(f"  {lv:g} m: reached by {sorted(times) or 'none'}")
    print(f"\ncost per step at h = {cfg.cost_h:g} s over {cfg.t_final:g} s (set-up and samples included)")
    print(f"{'method':22} {'us/step':>9} {'evals/step':>11} {'us/eval':>9}")
    for name, c in costs.items():
        print(f"{name:22} {c['us_per_step']:9.2f} {c['evaluations_per_step']:11d} {c['us_per_evaluation']:9.2f}")
    bound = stab[0]["lgvi_bound_s"]
    print(f"\nstability: largest h stable for {stab[0]['horizon_s']:g} s, grid in units of the LGVI's bound "
          f"{bound:.4g} s = 2/sqrt(4 kappa/m)")
    print(f"{'integrator':22} {'h [s]':>10} {'/ bound':>8} {'dE there [J]':>13} {'first fail':>11}  how")
    for s in stab:
        print(f"{s['integrator']:22} {fmt(s['largest_stable_h_s'], '10.3e'):>10} "
              f"{fmt(s['largest_stable_ratio'], '8.3f'):>8} {fmt(s['energy_change_J'], '13.2e'):>13} "
              f"{fmt(s['first_failing_ratio'], '11.3f'):>11}  {s['failure']}")
    print(f"\nlong run: {cfg.longrun:g} s, energy every {cfg.sample:g} s (MuJoCo at 0.85 of its largest stable h, "
          "the LGVI at the same cost)")
    print(f"{'':38} {'steps':>9} {'wall [s]':>9} {'max|dE| [J]':>12} {'dE slope [J/s]':>15} {'final dE [J]':>13}")
    for s in stats:
        print(f"{s['label']:38} {s['steps']:9d} {s['wall_s']:9.2f} {s['max_abs_energy_error_J']:12.2e} "
              f"{s['energy_slope_J_per_s']:15.2e} {s['final_energy_error_J']:13.2e}")


COLORS = {LGVI: "tab:red", SUZUKI: "darkred", "MuJoCo RK4": "tab:blue", "MuJoCo Euler": "tab:green",
          "MuJoCo implicitfast": "tab:olive"}


def plot(cfg, results, ref_info, path):
    fig = figure((8.5, 6))
    ax = fig.subplots()
    for name, rows in results.items():
        ok = [r for r in rows if r["status"] == "ok"]
        ax.loglog([r["wall_s"] for r in ok], [r["error_m"] for r in ok], marker="o", ms=4,
                  ls="--" if name == "MuJoCo implicitfast" else "-", color=COLORS.get(name), label=name)
    for lv in LEVELS:
        ax.axhline(lv, color="grey", ls=":", lw=0.8)
    ax.set_xlabel("wall time per run [s] (set-up + run, after compilation; median of repeats for fast runs)")
    ax.set_ylabel(f"max attachment point error over [0, {cfg.t_final:g}] s [m]")
    ax.set_title(f"{cfg.scene}, lumped mass: esp_gym LGVI vs MuJoCo on the same point-mass chain\n"
                 f"(reference: {ref_info['method']} at h = {ref_info['h']:.3g} s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path)


def main(argv=None) -> int:
    parser = arg_parser(__doc__)
    parser.add_argument("--repeats", type=int, default=None, help="timing repeats (default 5, quick 1)")
    parser.add_argument("--stability-horizon", type=float, default=None, help="seconds per stability run (default 10)")
    args = parser.parse_args(argv)
    cfg = Settings.quick_settings(args.out) if args.quick else Settings(out=args.out)
    if args.repeats is not None:
        cfg.repeats = args.repeats
    if args.stability_horizon is not None:
        cfg.stability_horizon = args.stability_horizon
    start = time.perf_counter()
    import mujoco

    # the stability scan diverges on purpose: runs read MuJoCo's warning counters, so silence its
    # printed warnings (and its MUJOCO_LOG.TXT in the working directory)
    mujoco.set_mju_user_warning(lambda message: None)

    compile_all(cfg)
    ref, ref_info = reference(cfg)
    setup = setup_costs(cfg)
    results = work_precision(cfg, ref)
    rank = ranking(results)
    costs = step_costs(cfg)
    stab = stability(cfg)
    stats = long_run(cfg, stab, costs)
    print_tables(cfg, ref_info, setup, results, rank, costs, stab, stats)

    payload = {
        "settings": asdict(cfg), "reference": ref_info, "setup_s": setup, "work_precision": results,
        "time_to_error_s": rank, "step_cost": costs, "stability": stab, "long_run": stats,
        "machine": machine("mujoco"), "total_wall_s": time.perf_counter() - start,
    }
    finish(cfg.out, "mujoco_chain", payload, {"mujoco_chain.png": lambda path: plot(cfg, results, ref_info, path)},
           start)
    return 0


if __name__ == "__main__":
    sys.exit(main())
