"""The string's Kelvin–Voigt damping (docs/physics.md, "Material damping"): the free decay of a
load's bounce against its analytic rate, the energy balance's order with the dissipation, and
what the damper costs a step.

* **decay**: a 1 kg point load on 1 m of light string (1 g/m, EA = 1000 N, 4 elements, h = 5e-5 s)
  released at twice its static stretch, for each damping time: the decay rate of its bounce
  (a fit of the logarithm of its peak-to-trough swings) against sigma = EA tau / (2 l M_eff),
  M_eff = M + mu l / 3;
* **order**: the paper's example with the slack law and tau = 1 ms, 0.3 s: the largest
  |E - E0 - W + D| at h = 2e-4 ... 2.5e-5 s, its fitted slope, and the dissipated energy;
* **drift**: ``drone_load`` at EA = 2e3 N, ``elements: auto``, tau = 7.7e-4 s, 100 s of the resolution
  protocol's PD law with +-0.5 action noise (benchmarks/resolution.py), at the slack law's margin
  alone (SLACK_SAFETY), its half and its quarter step, at the rule's step (set by the drift's
  prediction, esp_gym.scene.stepsize.dissipation_drift), and undamped at the rule's: the largest
  |E - E0 - W + D| per 20 s window (the splitting's error in the dissipated energy is of order
  h^2 and accumulates) against the prediction;
* **margins**: ``drone_load`` at EA = 2e5 ... 1e7 N with strong, weak and no damping, 100 s of the PD
  law with noise and of random actions at 0.35, 0.5 and 0.7 of the bound: the damped margin's
  evidence (esp_gym.scene.stepsize.FLICKER_DAMPING, DAMPED_SAFETY);
* **cost**: ElasticStringPendulum-v0's default scene (``drone_load``, stabilize) under random
  actions, undamped and with tau = 1 ms (its own rig), env steps per second (the best of
  ``--repeats`` interleaved runs of ``--steps`` steps), and their ratio.

Prints the tables and writes ``OUT/damping.json`` and ``OUT/damping.png``.
Usage: ``python -m benchmarks.damping [--quick] [--repeats R] [--steps K] [--out DIR]``.
"""
from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

import esp_gym
from benchmarks.common import arg_parser, figure, finish, machine, single_env_rate
from benchmarks.resolution import long_run
from esp_gym.scene.stepsize import SLACK_SAFETY

#: The bounce scene's constants: load [kg], string length [m], mass per length [kg/m], EA [N].
BOUNCE = {"M": 1.0, "length": 1.0, "mu": 1e-3, "EA": 1000.0}
DECAY_TAUS = (1e-3, 2e-3, 5e-3)
ORDER_HS = (2e-4, 1e-4, 5e-5, 2.5e-5)
ORDER_TAU = 1e-3
COST_TAU = 1e-3
DRIFT_EA = 2e3
DRIFT_TAU = 7.7e-4


def drift_substeps(tau: float) -> dict:
    """Steps per control step at DRIFT_EA: the resolution rule's, and at the slack law's margin alone."""
    overrides = {"string": {"EA": DRIFT_EA, "elements": "auto", **({"damping_time": tau} if tau else {})}}
    steps = {margin: gym.make(esp_gym.ENV_ID, scene_overrides=overrides, safety=safety,
                              disable_env_checker=True).unwrapped.setup.substeps
             for margin, safety in (("rule", None), ("law", SLACK_SAFETY))}
    return steps


def drift(tau: float, substeps: int, seconds: float, chosen_by: str) -> dict:
    """The largest |E - E0 - W + D| [J] per 20 s window of the PD law with noise at ``substeps``
    steps per control step, the dissipated energy [J], and the rule's prediction of the drift
    (esp_gym.scene.stepsize.dissipation_drift, over 100 s): benchmarks/resolution.py's long run."""
    run = long_run(DRIFT_EA, "pd+noise", seconds, tau, h=0.02 / substeps)
    return {"tau": tau, "substeps": substeps, "chosen_by": chosen_by, "windows": run["windows"],
            "dissipation": run["dissipation"], "predicted": run["predicted_drift"]}


def drift_rows(seconds: float) -> list:
    """The drift at the slack law's margin alone, twice and four times its steps, the rule's steps
    (the dissipation's margin), and undamped at the law's margin."""
    damped = drift_substeps(DRIFT_TAU)
    law = damped["law"]
    rows = [drift(DRIFT_TAU, law * k, seconds, "the slack law's margin" if k == 1 else f"{k} x the law's")
            for k in (1, 2, 4)]
    rows.append(drift(DRIFT_TAU, damped["rule"], seconds, "the rule (dissipation)"))
    return rows + [drift(0.0, drift_substeps(0.0)["rule"], seconds, "the rule")]


#: The margin comparison: (EA [N], tau [s]) on drone_load, each at these fractions of the bound.
MARGIN_CASES = ((2e5, 7.7e-4), (2e6, 7.7e-4), (1e7, 7.7e-4), (2e6, 1e-4), (2e5, 1e-4), (2e5, 1e-5), (2e5, 0.0))
MARGINS = (0.35, 0.5, 0.7)


def margins(seconds: float) -> list:
    """MARGIN_CASES at each of MARGINS: the fastest mode's damping ratio tau/bound and the largest
    residual under both protocols (docs/physics.md, "Material damping": the damped margin)."""
    rows = []
    for ea, tau in MARGIN_CASES:
        scene = esp_gym.load_scene("drone_load", string={"EA": ea, "elements": 1, "damping_time": tau},
                                   allow_unstable_h=True)
        rows.append({"EA": ea, "tau": tau, "ratio": tau / scene.stability_bound,
                     "residuals": {str(s): {m: long_run(ea, m, seconds, tau, safety=s)["worst"]
                                            for m in ("pd+noise", "random")} for s in MARGINS}})
    return rows


def bounce_scene(tau: float) -> esp_gym.Scene:
    """The bounce: the load released at twice its static stretch, straight below a fixed pivot."""
    b = BOUNCE
    return esp_gym.Scene(
        name="bounce", h=5e-5,
        string={"length": b["length"], "mass_per_length": b["mu"], "EA": b["EA"], "elements": 4, "law": "slack",
                "damping_time": tau},
        body={"mass": b["M"], "rho_c": [0.0, 0.0, 0.0], "shape": {"kind": "sphere", "radius": 0.02}},
        initial={"direction": [0.0, 0.0, 1.0], "stretch": 1.0 + 2.0 * b["M"] * 9.81 / b["EA"]})


def decay(tau: float, t_final: float) -> dict:
    """The bounce's measured decay rate [1/s] against the analytic one, and its trace."""
    b = BOUNCE
    tr = esp_gym.Simulator(bounce_scene(tau)).run(t_final=t_final, record_every=1)
    z = tr.nodes[:, -1, 2]
    inner = z[1:-1]
    peaks = np.flatnonzero((inner > z[:-2]) & (inner >= z[2:])) + 1
    troughs = np.flatnonzero((inner < z[:-2]) & (inner <= z[2:])) + 1
    k = min(len(peaks), len(troughs))
    swing = z[peaks[:k]] - z[troughs[:k]]
    measured = -float(np.polyfit(tr.t[peaks[:k]], np.log(swing), 1)[0])
    analytic = b["EA"] * tau / (2.0 * b["length"] * (b["M"] + b["mu"] * b["length"] / 3.0))
    omega0 = float(np.sqrt(b["EA"] / (b["length"] * (b["M"] + b["mu"] * b["length"] / 3.0))))
    every = max(1, len(z) // 2000)
    return {"tau": tau, "measured": measured, "analytic": analytic, "error": measured / analytic - 1.0,
            "zeta": analytic / omega0, "cycles": k, "t": tr.t[::every].tolist(), "z": z[::every].tolist(),
            "mean": float(np.mean(z[len(z) // 2:]))}


def order(t_final: float) -> dict:
    """The largest |E - E0 - W + D| [J] per h and its slope; the dissipated energy [J]."""
    worst, lost = [], []
    for h in ORDER_HS:
        scene = esp_gym.load_scene("paper_example", string={"damping_time": ORDER_TAU, "law": "slack"}, h=h)
        tr = esp_gym.Simulator(scene).run(t_final=t_final, record_every=max(1, round(1e-3 / h)))
        worst.append(float(np.abs(tr.energy_balance_residual).max()))
        lost.append(float(tr.dissipation[-1]))
    slope = float(np.polyfit(np.log(ORDER_HS), np.log(worst), 1)[0])
    return {"tau": ORDER_TAU, "t_final": t_final, "h": list(ORDER_HS), "worst": worst, "dissipation": lost,
            "slope": slope}


def env_rate(tau: float, steps: int) -> float:
    """Env steps per second of one run of ``steps`` random actions (the default scene; resets
    timed too, as an episode's end is part of the work)."""
    overrides = {"string": {"damping_time": tau}} if tau else {}
    return single_env_rate(lambda: gym.make(esp_gym.ENV_ID, scene_overrides=overrides, disable_env_checker=True),
                           steps, True, 1)


def cost(repeats: int, steps: int) -> dict:
    """The best of ``repeats`` interleaved runs each, undamped and damped, and their ratio."""
    rates = {"undamped": [], "damped": []}
    for _ in range(repeats):
        rates["undamped"].append(env_rate(0.0, steps))
        rates["damped"].append(env_rate(COST_TAU, steps))
    best = {k: max(v) for k, v in rates.items()}
    return {"tau": COST_TAU, "steps": steps, "runs": rates, "best": best, "ratio": best["damped"] / best["undamped"]}


def draw(result: dict):
    def plot(path):
        fig = figure((10, 3.6))
        ax1, ax2 = fig.subplots(1, 2)
        for row in result["decay"]:
            t, z = np.asarray(row["t"]), np.asarray(row["z"])
            ax1.plot(t, 1e3 * (z - row["mean"]), lw=0.6, label=f"τ = {row['tau'] * 1e3:g} ms")
        top = result["decay"][-1]
        t = np.asarray(top["t"])
        amplitude = 1e3 * (np.asarray(top["z"])[0] - top["mean"])
        ax1.plot(t, amplitude * np.exp(-top["analytic"] * t), "k--", lw=0.8, label=f"analytic envelope, τ = {top['tau'] * 1e3:g} ms")
        ax1.plot(t, -amplitude * np.exp(-top["analytic"] * t), "k--", lw=0.8)
        ax1.set(xlabel="t [s]", ylabel="load's bounce [mm]", title="free decay of the bounce mode")
        ax1.legend(fontsize=7, loc="upper right")
        o = result["order"]
        ax2.loglog(o["h"], o["worst"], "o-", label=f"max |E − E0 − W + D|, slope {o['slope']:.2f}")
        ref = np.asarray(o["h"])
        ax2.loglog(ref, o["worst"][0] * (ref / ref[0]) ** 2, "k:", lw=0.8, label="slope 2")
        ax2.set(xlabel="h [s]", ylabel="[J]", title=f"energy balance, paper example, τ = {o['tau'] * 1e3:g} ms")
        ax2.legend(fontsize=7)
        fig.savefig(path)
    return plot


def main(argv=None) -> dict:
    parser = arg_parser(__doc__, "short runs (CI smoke test)")
    parser.add_argument("--repeats", type=int, default=5, help="interleaved runs of each cost case (default 5)")
    parser.add_argument("--steps", type=int, default=3000, help="env steps per cost run (default 3000)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    quick = args.quick
    result = {"machine": machine("gymnasium"),
              "decay": [decay(tau, 0.5 if quick else 3.0) for tau in DECAY_TAUS],
              "order": order(0.02 if quick else 0.3),
              "drift": drift_rows(2.0 if quick else 100.0),
              "margins": margins(2.0 if quick else 100.0),
              "cost": cost(1 if quick else args.repeats, 200 if quick else args.steps)}
    print("free decay of the bounce: sigma measured against EA tau / (2 l M_eff)")
    print(f"{'tau [ms]':>9} {'zeta':>7} {'measured [1/s]':>15} {'analytic [1/s]':>15} {'error':>9} {'cycles':>7}")
    for row in result["decay"]:
        print(f"{row['tau'] * 1e3:9.1f} {row['zeta']:7.4f} {row['measured']:15.5f} {row['analytic']:15.5f} "
              f"{row['error']:9.2e} {row['cycles']:7d}")
    o = result["order"]
    print(f"\nenergy balance with the dissipation, paper example, tau = {o['tau'] * 1e3:g} ms, {o['t_final']:g} s")
    for h, w, d in zip(o["h"], o["worst"], o["dissipation"]):
        print(f"  h = {h:.2e} s: max |E - E0 - W + D| = {w:.3e} J  (D = {d:.3e} J)")
    print(f"  slope {o['slope']:.2f}")
    print(f"\ndrift: EA = {DRIFT_EA:g} N, PD law + noise, largest |E - E0 - W + D| per 20 s window [J]")
    for row in result["drift"]:
        print(f"  tau = {row['tau'] * 1e3:g} ms, {row['substeps']:3d} steps per 20 ms ({row['chosen_by']}): "
              + " ".join(f"{w:.4f}" for w in row["windows"])
              + f"  (D = {row['dissipation']:.3f} J, predicted over 100 s {row['predicted']:.4f} J)")
    print("\nmargins: largest |E - E0 - W + D| [J], PD law + noise / random actions, by fraction of the bound")
    for row in result["margins"]:
        cells = "  ".join(f"{s}: {r['pd+noise']:.4f} / {r['random']:.4f}" for s, r in row["residuals"].items())
        print(f"  EA {row['EA']:.0e} N, tau {row['tau'] * 1e3:g} ms (tau/bound {row['ratio']:.3f}):  {cells}")
    c = result["cost"]
    print(f"\ncost: env steps/s, default scene, best of {len(c['runs']['damped'])}: undamped {c['best']['undamped']:,.0f}, "
          f"damped (tau = {c['tau'] * 1e3:g} ms) {c['best']['damped']:,.0f}, ratio {c['ratio']:.2f}")
    finish(args.out, "damping", result, {"damping.png": draw(result)}, start)
    return result


if __name__ == "__main__":
    main()
