"""Stability of the LGVI: the largest stable step against theory, a 1e7-step run, and hard cases.

1. Largest stable h, by bisection, for the paper example with N in {5, 10, 20, 40} and EA in
   {10, 40, 160} N, against the theoretical bound h_max = 2/sqrt(12 kappa/m) of the explicit
   string update (kappa = EA/u, m = mu u). A step h is *stable* if a run of ``--horizon`` s
   (2 s) ends without ``SimulationError`` and its energy error stays below 5 % of the energy
   scale E_s = T(0) + (M + mu l) g l (an instability grows exponentially from round-off, so
   the verdict does not hinge on the 5 %). The bound is linear stability; the margin long
   runs need is measured by 100-s runs at 0.5 .. 0.9 h_max (max |E - E0| / E_s of each; the
   motion is the paper's, chaotic, with hard stretch events).
2. Long run: 5e7 steps of the paper example at h = 1e-4 s (5000 s; the issue asks for 1e7),
   energy, pi3 and ||I - R^T R|| after *every* step (reduced per chunk of 1e5 steps).
3. Hard cases, each at h = 1e-4 s and at 0.9 h_max (plus the largest stable h by bisection):
   slack-to-taut snaps (``string.law: slack``, the load thrown up towards the pivot, so the
   string goes slack and snaps taut again and again), a fast spin (Omega0 = 50 rad/s about a
   non-principal axis), large body torques (1 .. 1e4 N m), a large spatial torque and a large
   pivot force on the free pivot, and the stiffest strings (EA up to 1e6 N, h_max down to
   4.6e-6 s). With inputs the checks are the balances: E - E0 - W (W the discrete work) and
   pi3 - pi3(0) - angular impulse, and E_s becomes max(E_s, max |W|).
4. Tension-only law near the bound: the largest energy error against h/h_max, ``slack`` vs
   ``elastic`` law, for the snap scene above (5 s) and for the environment's scene
   ``drone_load`` driven like the environment (pivot force = hover + 0.6 W x uniform(-1, 1),
   body torque 0.02 N m x uniform(-1, 1), new random input every 20 ms, h dividing 20 ms;
   10 s, seed 0).

Prints tables and writes ``OUT/stability.json`` and ``OUT/stability.png``
(OUT = benchmarks/out unless ``--out``).

Usage: ``python -m benchmarks.stability [--quick] [--out DIR]``. ``--quick``: fewer bisection
steps, a 1e5-step long run and shorter hard cases: a smoke test (< 30 s), not a measurement.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

from benchmarks.common import DEFAULT_OUT, arg_parser, figure, finish, fmt, machine


@dataclass
class Settings:
    quick: bool = False
    """smoke test"""
    out: str = str(DEFAULT_OUT)
    """output directory"""
    elements: tuple = (5, 10, 20, 40)
    """N of the bound table"""
    stiffness: tuple = (10.0, 40.0, 160.0)
    """EA of the bound table [N]"""
    horizon: float = 2.0
    """length of a stability trial [s]"""
    bisections: int = 14
    """bisection steps (relative resolution 2^-bisections of the bracket [0.5, 1.5] h_max)"""
    margin_time: float = 100.0
    """length of the margin runs [s]"""
    margin_fracs: tuple = (0.5, 0.6, 0.7, 0.8, 0.9)
    """h/h_max of the margin runs"""
    energy_tol: float = 0.05
    """a trial fails if max|E - E0| > energy_tol * E_s"""
    long_steps: int = 50_000_000
    """steps of the long run"""
    long_chunk: int = 100_000
    """steps per chunk of the long run (every-step invariants reduced per chunk)"""
    case_time: float = 5.0
    """simulated time of each hard case [s]"""
    torque_time: float = 1.0
    """simulated time of each large-input case [s]"""
    stiff_EA: tuple = (1e3, 1e4, 1e5, 1e6)
    """EA of the stiff-string cases [N]"""
    sweep: tuple = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95)
    """h/h_max of the slack-vs-elastic sweep"""
    drone_time: float = 10.0
    """simulated time of the drone_load sweep runs [s]"""

    @classmethod
    def quick_settings(cls, out: str) -> "Settings":
        return cls(quick=True, out=out, elements=(5, 20), stiffness=(40.0,), bisections=8, margin_time=5.0,
                   margin_fracs=(0.6, 0.9),
                   long_steps=200_000, long_chunk=50_000, case_time=1.0, torque_time=0.2, stiff_EA=(1e4,),
                   sweep=(0.4, 0.8), drone_time=2.0)


def scene(name="paper_example", **overrides):
    import esp_gym

    return esp_gym.load_scene(name, allow_unstable_h=True, **overrides)


def energy_scale(sc) -> float:
    """T(0) + (M + mu l) g l [J]: what the motion can put into the string's modes."""
    import esp_gym

    d = esp_gym.Simulator(sc).diagnostics()
    kin = d["kinetic_string"] + d["kinetic_body"] + d["kinetic_pivot"]
    s = sc.string
    return kin + (sc.body.mass + s.mass_per_length * s.length) * sc.gravity * s.length


def trial(sc, T: float, energy_tol: float, inputs=None, snapshots: int = 400) -> dict:
    """Run ``sc`` for T seconds (ceil(T/h) steps) with constant ``inputs``; report stability and
    the invariants at ``snapshots`` evenly spaced steps (the balances when there are inputs)."""
    import esp_gym

    inputs = inputs or {}
    n = int(math.ceil(T / sc.h - 1e-9))
    sim = esp_gym.Simulator(sc)
    scale = energy_scale(sc)
    every = max(1, n // snapshots)
    start = time.perf_counter()
    row = {"h": sc.h, "h_max": sc.string.element_bound, "steps": n, "energy_scale_J": scale}
    try:
        traj = sim.run(n * sc.h, record_every=every, **inputs)
    except esp_gym.SimulationError as err:
        row.update(stable=False, status=str(err).split(";")[0], wall_s=time.perf_counter() - start,
                   failed_at_s=err.time)
        return row
    wall = time.perf_counter() - start
    dE = traj.energy_balance_residual
    finite = bool(np.all(np.isfinite(traj.nodes)) and np.all(np.isfinite(traj.energy)))
    max_dE = float(np.abs(dE).max())
    scale = max(scale, float(np.abs(traj.work).max()))  # with inputs: relative to the work done
    stable = finite and max_dE <= energy_tol * scale
    pi3_scale = max(np.abs(traj.pi3).max(), np.abs(traj.angular_impulse_z).max(), 1e-300)
    row.update(
        stable=stable, status="ok" if stable else ("non-finite" if not finite else f"dE>{energy_tol:.0%}E_s"),
        wall_s=wall, max_abs_energy_error_J=max_dE, rel_energy_error=max_dE / scale,
        max_abs_work_J=float(np.abs(traj.work).max()),
        max_abs_pi3_residual=float(np.abs(traj.pi3_balance_residual).max()),
        rel_pi3_residual=float(np.abs(traj.pi3_balance_residual).max() / pi3_scale),
        max_orthogonality=float(traj.orthogonality.max()),
        newton_max=int(sim.newton_iterations_max), newton_mean=sim.newton_iterations / n,
        max_omega=float(np.linalg.norm(traj.omega, axis=1).max()),
    )
    row["_traj"] = traj
    return row


def largest_stable_h(make, T: float, energy_tol: float, bisections: int, inputs=None) -> dict:
    """Bisection for the largest stable h in [0.5, 1.5] x h_max; ``make(h)`` builds the scene."""
    bound = make(1e-6).string.element_bound
    lo, hi = 0.5 * bound, 1.5 * bound
    if not trial(make(lo), T, energy_tol, inputs, snapshots=50)["stable"]:
        return {"h_max": bound, "h_stable": None, "ratio": None, "note": "unstable at 0.5 h_max"}
    if trial(make(hi), T, energy_tol, inputs, snapshots=50)["stable"]:
        return {"h_max": bound, "h_stable": hi, "ratio": 1.5, "note": "stable at 1.5 h_max (bracket end)"}
    for _ in range(bisections):
        mid = 0.5 * (lo + hi)
        if trial(make(mid), T, energy_tol, inputs, snapshots=50)["stable"]:
            lo = mid
        else:
            hi = mid
    return {"h_max": bound, "h_stable": lo, "h_unstable": hi, "ratio": lo / bound, "note": ""}


# -- 1. bounds -----------------------------------------------------------------------------------
def bound_table(cfg: Settings):
    rows = []
    for n in cfg.elements:
        for EA in cfg.stiffness:
            def make(h, n=n, EA=EA):
                return scene(N=n, EA=EA, h=h)

            res = largest_stable_h(make, cfg.horizon, cfg.energy_tol, cfg.bisections)
            margin = {}
            for frac in cfg.margin_fracs:
                r = trial(make(frac * res["h_max"]), cfg.margin_time, np.inf)
                margin[f"{frac:g}"] = r.get("rel_energy_error") if r["stable"] else None  # None: failed
            res.update(N=n, EA=EA, margin_T=cfg.margin_time, margin_rel_energy_error=margin)
            rows.append(res)
            print(f"  N = {n:3d} EA = {EA:6g}: h_max = {res['h_max']:.4e} s, measured {fmt(res['h_stable'], '.4e')} s "
                  f"(ratio {fmt(res['ratio'], '.4f')}); {cfg.margin_time:g} s runs, max|dE|/E_s: "
                  + " ".join(f"{k}: {fmt(v, '.1e')}" for k, v in margin.items()), flush=True)
    return rows


# -- 2. long run ---------------------------------------------------------------------------------
def long_run(cfg: Settings):
    import esp_gym

    sim = esp_gym.Simulator(scene(h=1e-4))
    d0 = sim.diagnostics()
    E0, pi0 = d0["energy"], d0["pi3"]
    chunks = cfg.long_steps // cfg.long_chunk
    t_end, dE_max, dE_mean, dpi_max, orth_max = [], [], [], [], []
    start = time.perf_counter()
    for c in range(chunks):
        traj = sim.run(cfg.long_chunk * sim.h, record_every=cfg.long_chunk, every_step=True)
        dE = traj.energy_every_step - E0
        t_end.append(traj.t_every_step[-1])
        dE_max.append(float(np.abs(dE).max()))
        dE_mean.append(float(dE.mean()))
        dpi_max.append(float(np.abs(traj.pi3_every_step - pi0).max()))
        orth_max.append(float(traj.orthogonality_every_step.max()))
    wall = time.perf_counter() - start
    t_end = np.array(t_end)
    half = len(dE_max) // 2
    res = {
        "steps": chunks * cfg.long_chunk, "h": sim.h, "T_s": float(t_end[-1]), "wall_s": wall,
        "us_per_step_with_every_step_diagnostics": wall / (chunks * cfg.long_chunk) * 1e6,
        "E0_J": E0, "max_abs_energy_error_J": max(dE_max),
        "max_abs_energy_error_first_half_J": max(dE_max[:half]) if half else None,
        "max_abs_energy_error_second_half_J": max(dE_max[half:]),
        "energy_slope_of_chunk_means_J_per_s": float(np.polyfit(t_end, dE_mean, 1)[0]) if len(t_end) > 1 else None,
        "max_abs_pi3_error": max(dpi_max), "max_orthogonality": max(orth_max),
        "newton_mean": sim.newton_iterations / (chunks * cfg.long_chunk), "newton_max": sim.newton_iterations_max,
        "series": {"t": t_end.tolist(), "max_abs_dE": dE_max, "mean_dE": dE_mean, "max_abs_dpi3": dpi_max,
                   "max_orth": orth_max},
    }
    return res


# -- 3. hard cases -------------------------------------------------------------------------------
#: The snap scene: the paper example with a tension-only string, the load thrown up and in.
SNAP = {"string.law": "slack", "initial": {"attach_velocity": [-3.0, 1.0, -4.0]}}


def hard_cases(cfg: Settings):
    """(name, scene factory h -> Scene, inputs, simulated time)."""
    snap = SNAP
    spin_axis = np.array([1.0, -0.6, 0.8]) / np.linalg.norm([1.0, -0.6, 0.8])
    spin = dict(initial={"Omega0": (50.0 * spin_axis).tolist()})
    axis = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])
    cases = [
        ("slack-to-taut snaps", lambda h: scene(h=h, **snap), None, cfg.case_time),
        ("fast spin |Omega0| = 50 rad/s", lambda h: scene(h=h, **spin), None, cfg.case_time),
    ]
    for tau in (1.0, 10.0, 100.0, 1e3, 1e4):
        cases.append((f"body torque {tau:g} N m", lambda h: scene(h=h), {"body_torque": tau * axis},
                      cfg.torque_time))
    cases.append(("spatial torque 100 N m (e3)", lambda h: scene(h=h), {"spatial_torque": [0.0, 0.0, 100.0]},
                  cfg.torque_time))
    cases.append(("free pivot, pivot force 100 N", lambda h: scene("paper_example_free_pivot", h=h),
                  {"pivot_force": [60.0, 0.0, -80.0]}, cfg.torque_time))
    for EA in cfg.stiff_EA:
        cases.append((f"stiff string EA = {EA:g} N", lambda h, EA=EA: scene(EA=EA, h=h), None, cfg.horizon))
    return cases


def count_snaps(traj, length: float) -> int:
    """Slack -> taut transitions of the chord |r_N - r_0| through the unstretched length."""
    chord = np.linalg.norm(traj.nodes[:, -1] - traj.nodes[:, 0], axis=1)
    taut = chord >= length
    return int(np.count_nonzero(taut[1:] & ~taut[:-1]))


def run_cases(cfg: Settings):
    rows = []
    for name, make, inputs, T in hard_cases(cfg):
        bound = make(1e-6).string.element_bound
        hs = sorted({min(1e-4, 0.9 * bound), 0.9 * bound})
        for h in hs:
            r = trial(make(h), T, cfg.energy_tol, inputs, snapshots=2000 if "snap" in name else 400)
            traj = r.pop("_traj", None)
            r.update(case=name, T_s=T, h_over_h_max=h / bound)
            if traj is not None and "snap" in name:
                r["snaps"] = count_snaps(traj, make(h).string.length)
            if "max_omega" in r:
                r["h_omega_max"] = h * r["max_omega"]
            rows.append(r)
            print(f"  {name:32} h = {h:.3e} ({h / bound:.2f} h_max): {r['status']}", flush=True)
        if inputs is None:  # with inputs the bisection would measure accuracy, not the string's bound
            bis = largest_stable_h(make, min(T, cfg.horizon), cfg.energy_tol, max(6, cfg.bisections - 4))
            rows[-1]["bisection"] = bis
            for r in rows[-len(hs):]:
                r["h_stable_ratio"] = bis["ratio"]
    return rows


# -- 4. tension-only law near the bound ----------------------------------------------------------
def drone_run(h: float, law: str, T: float, seed: int = 0) -> dict:
    """drone_load driven like the environment (see the module docstring); |E - E0 - W| per 20 ms."""
    import esp_gym

    sc = scene("drone_load", h=h, **{"string.law": law})
    weight = (sc.body.mass + sc.pivot.mass + sc.string.mass_per_length * sc.string.length) * sc.gravity
    rng = np.random.default_rng(seed)
    sub = int(round(0.02 / h))
    sim = esp_gym.Simulator(sc)
    t, res = [], []
    try:
        for k in range(int(round(T / 0.02))):
            a = rng.uniform(-1.0, 1.0, 6)
            sim.step(sub, pivot_force=np.array([0.0, 0.0, -weight]) + 0.6 * weight * a[:3],
                     body_torque=0.02 * a[3:])
            t.append(sim.time)
            res.append(sim.diagnostics()["energy_balance_residual"])
        status = "ok"
    except esp_gym.SimulationError as err:
        status = str(err).split(";")[0]
    return {"t": np.array(t), "dE": np.array(res), "status": status,
            "energy_scale_J": energy_scale(sc)}


def slack_sweep(cfg: Settings):
    rows, traces = [], {}
    for case in ("snaps", "drone_load"):
        for law in ("slack", "elastic"):
            for frac in cfg.sweep:
                if case == "snaps":
                    sc0 = scene(h=1e-4, **{**SNAP, "string.law": law})
                    h = frac * sc0.string.element_bound
                    r = trial(scene(h=h, **{**SNAP, "string.law": law}), cfg.case_time, np.inf, snapshots=1000)
                    traj = r.pop("_traj", None)
                    if traj is None:
                        t, dE, status = np.array([0.0]), np.array([np.nan]), r["status"]
                    else:
                        t, dE, status = traj.t, traj.energy_balance_residual, "ok"
                    scale = r["energy_scale_J"]
                else:
                    bound = scene("drone_load").string.element_bound
                    h = 0.02 / math.ceil(0.02 / (frac * bound) - 1e-9)
                    d = drone_run(h, law, cfg.drone_time)
                    t, dE, status, scale = d["t"], d["dE"], d["status"], d["energy_scale_J"]
                    frac = h / bound
                if law == "slack" and case == "snaps":
                    traces[f"h = {frac:.2f} h_max"] = (t, dE)
                row = {"case": case, "law": law, "h_over_h_max": frac, "h": h, "status": status,
                       "max_abs_energy_error_J": float(np.nanmax(np.abs(dE))) if dE.size else None,
                       "energy_scale_J": scale, "T_s": float(t[-1]) if t.size else 0.0}
                rows.append(row)
                print(f"  {case:10} {law:7} h = {frac:.2f} h_max: max|E - E0 - W| = "
                      f"{fmt(row['max_abs_energy_error_J'])} J ({status})", flush=True)
    return rows, traces


# -- output --------------------------------------------------------------------------------------
def print_tables(cfg, bounds, long, cases, sweep):
    print(f"\nlargest stable h ({cfg.horizon:g}-s trials, energy error < {cfg.energy_tol:g} E_s), paper_example")
    fr = [f"{f:g}" for f in cfg.margin_fracs]
    print(f"{'':46} max|E - E0|/E_s over {cfg.margin_time:g} s at h/h_max =")
    print(f"{'N':>4} {'EA [N]':>7} {'h_max theory [s]':>17} {'measured [s]':>13} {'ratio':>7} "
          + " ".join(f"{x:>8}" for x in fr))
    for r in bounds:
        m = r["margin_rel_energy_error"]
        print(f"{r['N']:4d} {r['EA']:7g} {r['h_max']:17.4e} {fmt(r['h_stable'], '13.4e'):>13} "
              f"{fmt(r['ratio'], '7.4f'):>7} " + " ".join(f"{fmt(m[x], '8.1e'):>8}" for x in fr))
    print(f"\nlong run: paper_example, {long['steps']:.3g} steps of h = {long['h']:g} s ({long['T_s']:g} s), "
          f"invariants after every step, {long['wall_s']:.1f} s wall "
          f"({long['us_per_step_with_every_step_diagnostics']:.2f} us/step with diagnostics)")
    print(f"  max|E - E0| = {long['max_abs_energy_error_J']:.3e} J (first half {fmt(long['max_abs_energy_error_first_half_J'], '.3e')}, "
          f"second half {long['max_abs_energy_error_second_half_J']:.3e}; E0 = {long['E0_J']:.5f} J); "
          f"slope of chunk means {fmt(long['energy_slope_of_chunk_means_J_per_s'], '.2e')} J/s")
    print(f"  max|pi3 - pi3(0)| = {long['max_abs_pi3_error']:.2e} kg m^2/s, max ||I - R^T R|| = "
          f"{long['max_orthogonality']:.2e}, Newton {long['newton_mean']:.2f} per step (max {long['newton_max']})")
    print("\nhard cases (with inputs: energy = |E - E0 - W|, pi3 = |pi3 - pi3(0) - angular impulse|)")
    print(f"{'case':32} {'h [s]':>9} {'h/h_max':>7} {'T [s]':>5} {'status':>10} {'max dE [J]':>10} {'/E_s':>8} "
          f"{'max dpi3':>9} {'rel':>8} {'orth':>8} {'Newton':>6} {'h|Omega|':>8} {'h_stab/h_max':>12}")
    for r in cases:
        status = "ok" if r["stable"] else ("FAILED" if "failed" in r["status"] else r["status"][:10])
        extra = f"  snaps: {r['snaps']}" if "snaps" in r else ""
        if not r["stable"] and "failed_at_s" in r:
            extra += f"  ({r['status']})"
        print(f"{r['case']:32} {r['h']:9.3e} {r['h_over_h_max']:7.2f} {r['T_s']:5g} {status:>10} "
              f"{fmt(r.get('max_abs_energy_error_J')):>10} {fmt(r.get('rel_energy_error'), '.1e'):>8} "
              f"{fmt(r.get('max_abs_pi3_residual'), '.1e'):>9} {fmt(r.get('rel_pi3_residual'), '.1e'):>8} "
              f"{fmt(r.get('max_orthogonality'), '.1e'):>8} {fmt(r.get('newton_max'), 'd'):>6} "
              f"{fmt(r.get('h_omega_max'), '.3f'):>8} {fmt(r.get('h_stable_ratio'), '.4f'):>12}{extra}")
    print("\ntension-only (slack) vs elastic law near the bound: max |E - E0 - W| [J] "
          f"(snaps: {cfg.case_time:g} s; drone_load: {cfg.drone_time:g} s of environment-like random inputs)")
    for case in ("snaps", "drone_load"):
        for law in ("slack", "elastic"):
            rows = [r for r in sweep if r["case"] == case and r["law"] == law]
            print(f"  {case:10} {law:7} " + "  ".join(
                f"{r['h_over_h_max']:.2f}: {fmt(r['max_abs_energy_error_J'], '.1e')}" for r in rows))


#: The sizes' markers of the stability figure, by EA [N].
EA_MARKERS = {10.0: "o", 40.0: "s", 160.0: "^"}


def bound_panel(a, cfg, bounds) -> None:
    """The largest stable h measured against the theoretical bound, per N (colour) and EA (marker)."""
    for r in bounds:
        if r["h_stable"] is not None:
            a.loglog(r["h_max"], r["h_stable"], EA_MARKERS.get(r["EA"], "o"), color=f"C{cfg.elements.index(r['N'])}",
                     ms=7)
    hm = np.array([r["h_max"] for r in bounds])
    span = np.array([hm.min() / 1.3, hm.max() * 1.3])
    a.loglog(span, span, "k--", lw=1, label="measured = 2/sqrt(12 kappa/m)")
    for i, n in enumerate(cfg.elements):
        a.plot([], [], "o", color=f"C{i}", label=f"N = {n}")
    for EA, mk in EA_MARKERS.items():
        if EA in cfg.stiffness:
            a.plot([], [], mk, color="grey", label=f"EA = {EA:g} N")
    from matplotlib.ticker import NullFormatter

    for axis in (a.xaxis, a.yaxis):
        axis.set_minor_formatter(NullFormatter())
    a.set_xlabel("theoretical bound h_max [s]")
    a.set_ylabel(f"largest stable h ({cfg.horizon:g}-s bisection) [s]")
    a.set_title("Stability bound: measured vs theory")
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)


def margin_panel(m, cfg, bounds) -> None:
    """The long runs' largest relative energy error against h / h_max (elastic law)."""
    for r in bounds:
        fr = [float(k) for k, v in r["margin_rel_energy_error"].items() if v is not None]
        val = [v for v in r["margin_rel_energy_error"].values() if v is not None]
        m.semilogy(fr, val, EA_MARKERS.get(r["EA"], "o"), ls="-", color=f"C{cfg.elements.index(r['N'])}", ms=5,
                   lw=0.8, label=f"N = {r['N']}, EA = {r['EA']:g}")
    m.axhline(cfg.energy_tol, color="grey", ls=":", lw=1)
    m.set_xlabel("h / h_max")
    m.set_ylabel(f"max |E - E0| / E_s over {cfg.margin_time:g} s")
    m.set_title("Margin for long runs (elastic law)")
    m.grid(True, which="both", alpha=0.3)
    m.legend(fontsize=6, ncol=2)


def long_run_panel(b, cfg, long) -> None:
    """The paper example's long run: the energy, pi3 and orthogonality errors per chunk."""
    s = long["series"]
    t = np.array(s["t"])
    b.semilogy(t, s["max_abs_dE"], color="tab:red", lw=1, label="max |E - E0| per chunk [J]")
    b.semilogy(t, np.maximum(s["max_abs_dpi3"], 1e-20), color="tab:blue", lw=1, label="max |pi3 - pi3(0)| per chunk")
    b.semilogy(t, np.maximum(s["max_orth"], 1e-20), color="tab:green", lw=1, label="max ||I - R^T R|| per chunk")
    b.set_title(f"Long run: {long['steps']:.0e} steps of h = {long['h']:g} s (paper example)")
    b.set_xlabel(f"t [s] (every step; max per {cfg.long_chunk:.0e} steps)")
    b.grid(True, which="both", alpha=0.3)
    b.legend(fontsize=8)


def snaps_panel(c, traces) -> None:
    """The energy error of slack-to-taut snaps (tension-only string), one trace each."""
    for i, (label, (t, dE)) in enumerate(traces.items()):
        c.semilogy(t[1:], np.maximum(np.abs(dE[1:]), 1e-12), lw=0.7, color=plt_color(i, len(traces)), label=label)
    c.set_xlabel("t [s]")
    c.set_ylabel("|E - E0| [J]")
    c.set_title("Slack-to-taut snaps (tension-only string): energy error")
    c.grid(True, which="both", alpha=0.3)
    c.legend(fontsize=7, ncol=2)


def near_bound_panel(d, sweep) -> None:
    """The tension-only and the elastic law's energy error against h / h_max near the bound."""
    styles = {("snaps", "slack"): ("tab:red", "-"), ("snaps", "elastic"): ("tab:red", "--"),
              ("drone_load", "slack"): ("tab:blue", "-"), ("drone_load", "elastic"): ("tab:blue", "--")}
    for (case, law), (col, ls) in styles.items():
        rows = [r for r in sweep if r["case"] == case and r["law"] == law and r["max_abs_energy_error_J"] is not None]
        d.semilogy([r["h_over_h_max"] for r in rows], [r["max_abs_energy_error_J"] for r in rows], "o",
                   ls=ls, color=col, ms=4, label=f"{case}, {law} law")
    d.axvline(0.5, color="grey", ls=":", lw=1, label="environment default (safety 0.5)")
    d.axvline(0.7, color="grey", ls="--", lw=1, label="choose_h default (safety 0.7)")
    d.set_xlabel("h / h_max")
    d.set_ylabel("max |E - E0 - W| [J]")
    d.set_title("Tension-only vs elastic law near the bound")
    d.grid(True, which="both", alpha=0.3)
    d.legend(fontsize=7)


def plot(cfg, bounds, long, traces, sweep, cases, path):
    fig = figure((17, 9))
    (a, m, b), (c, d, e) = fig.subplots(2, 3)
    bound_panel(a, cfg, bounds)
    margin_panel(m, cfg, bounds)
    long_run_panel(b, cfg, long)
    snaps_panel(c, traces)
    near_bound_panel(d, sweep)
    e.axis("off")
    e.text(0.0, 1.0, cases_text(cases), family="monospace", fontsize=6.5, va="top", transform=e.transAxes)
    fig.savefig(path)


def cases_text(cases) -> str:
    """The hard-case table, short, for the figure."""
    lines = ["hard cases (max|dE|/E_s, pi3 residual; with inputs E_s >= max|W|)", ""]
    for r in cases:
        if r["stable"] or "rel_energy_error" in r:
            lines.append(f"{r['case'][:30]:30} {r['h_over_h_max']:.2f}h_max  dE {fmt(r.get('rel_energy_error'), '.0e')}"
                         f"  pi3 {fmt(r.get('max_abs_pi3_residual'), '.0e')}")
        else:
            lines.append(f"{r['case'][:30]:30} {r['h_over_h_max']:.2f}h_max  FAILED at t = {r['failed_at_s']:.3g} s")
    return "\n".join(lines)


def plt_color(i: int, n: int):
    from matplotlib import colormaps

    return colormaps["plasma"](0.85 * i / max(n - 1, 1))


def main(argv=None) -> int:
    args = arg_parser(__doc__).parse_args(argv)
    cfg = Settings.quick_settings(args.out) if args.quick else Settings(out=args.out)
    start = time.perf_counter()

    print("largest stable h (bisection):", flush=True)
    bounds = bound_table(cfg)
    print("long run ...", flush=True)
    long = long_run(cfg)
    print("hard cases:", flush=True)
    cases = run_cases(cfg)
    print("tension-only vs elastic law near the bound:", flush=True)
    sweep, traces = slack_sweep(cfg)
    print_tables(cfg, bounds, long, cases, sweep)

    payload = {
        "settings": asdict(cfg), "bounds": bounds, "long_run": long, "cases": cases, "slack_sweep": sweep,
        "machine": machine(), "total_wall_s": time.perf_counter() - start,
    }
    finish(cfg.out, "stability", payload,
           {"stability.png": lambda path: plot(cfg, bounds, long, traces, sweep, cases, path)}, start)
    return 0


if __name__ == "__main__":
    sys.exit(main())
