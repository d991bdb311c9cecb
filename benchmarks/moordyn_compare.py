"""Our damped tether against MoorDyn (a maintained lumped-mass mooring-line code with
Kelvin-Voigt axial damping; the ``moordyn`` package, v2 Python API) on the same line at equal
resolution: ``dyneema_tether``'s 3 m of 4 mm Dyneema (9.1 g/m, EA = 614,600 N, 473 N s per unit
strain rate, tau = 7.7e-4 s) carrying a 0.3 kg load from a fixed pivot, 8 elements, the lumped
mass on both sides (``string.mass_model: lumped``), no water, drag or bending. Two cases, each
from rest from MoorDyn's own initial node positions (ours start from the same nodes):

* ``swing``: released 30 degrees from the vertical, unstretched: the line stays taut, rings at
  its bounce mode (about 130 Hz) and swings (a period of about 3.5 s);
* ``drop``: released from 0.1 m above its unstretched hanging length on the vertical: the line
  is slack (MoorDyn lays it as a catenary of its own), the load falls and the line snaps taut.

The load's path and the tension at its end over ``--seconds`` (default 2 s): MoorDyn with its
RK2 at ``MOORDYN_DT`` (its explicit damper's stability limit is about 1.35e-6 s here), ours at
0.35 of the stability bound (the slack law's margin) and at half that (our own convergence). Our
end tension is EA (eps + tau d(eps)/dt) held >= 0 while taut and 0 while slack
(:func:`end_tension`); MoorDyn's is its last segment's |T + T_d|, its damper acting
whatever the strain (it damps a slack segment that shortens: docs/benchmarks.md).

Prints a table and writes ``OUT/moordyn_compare.json`` and ``OUT/moordyn_compare.png``.
Usage: ``python -m benchmarks.moordyn_compare [--quick] [--seconds S] [--out DIR]``.
"""
from __future__ import annotations

import os
import tempfile
import time

import numpy as np

from benchmarks.common import arg_parser, figure, finish, machine
from esp_gym import Simulator
from esp_gym.extras import require
from esp_gym.scene.params import scene_from_dict

#: The tether (dyneema_tether.yaml's; Fechner et al. 2015) and the load [SI].
LENGTH, MASS_PER_LENGTH, EA, DAMPING_TIME = 3.0, 0.0091, 614600.0, 7.7e-4
LOAD, ELEMENTS, GRAVITY = 0.3, 8, 9.81
#: MoorDyn's step [s] (RK2; 1.5e-6 s blows up) and the output interval of both [s].
MOORDYN_DT, SAMPLE = 1e-6, 1e-3
#: The cases: the load's start, MoorDyn's frame (z up), from the fixed pivot at the origin [m].
CASES = {"swing": (LENGTH * float(np.sin(np.pi / 6)), 0.0, -LENGTH * float(np.cos(np.pi / 6))),
         "drop": (0.0, 0.0, -(LENGTH - 0.1))}

MOORDYN_INPUT = """MoorDyn input: an elastic string pendulum in vacuum (benchmarks/moordyn_compare.py)
----------------------- LINE TYPES ------------------------------------------
TypeName Diam Mass/m EA BA/-zeta EI Cd Ca CdAx CaAx
(name) (m) (kg/m) (N) (N-s/-) (N-m^2) (-) (-) (-) (-)
tether 0.004 {mu!r} {EA!r} {BA!r} 0 0 0 0 0
---------------------- POINT PROPERTIES --------------------------------
ID Type X Y Z Mass Volume CdA Ca
(#) (-) (m) (m) (m) (kg) (m^3) (m^2) (-)
1 Fixed 0 0 0 0 0 0 0
2 Free {x!r} {y!r} {z!r} {M!r} 0 0 0
---------------------- LINES ----------------------------------------
ID LineType AttachA AttachB UnstrLen NumSegs LineOutputs
(#) (name) (#) (#) (m) (-) (-)
1 tether 1 2 {L!r} {N} -
---------------------- OPTIONS -----------------------------------------
0 writeLog
{dt!r} dtM
RK2 tScheme
{g!r} g
0.0 WtrDnsty
1000.0 WtrDpth
0 TmaxIC
1 disableOutput
1 disableOutTime
------------------------- need this line --------------------------------------
"""


def to_ours(points: np.ndarray) -> np.ndarray:
    """MoorDyn's frame (z up) -> ours (e3 down, gravity +e3)."""
    return np.asarray(points, dtype=np.float64) * np.array([1.0, 1.0, -1.0])


def moordyn_run(start, seconds: float) -> dict:
    """MoorDyn from rest with the load at ``start``: its initial nodes (ours' frame), the load's
    path (n + 1, 3) and the end tension (n + 1) every SAMPLE [s], and its wall time [s]."""
    moordyn = require("moordyn", "the MoorDyn comparison (benchmarks.moordyn_compare)")
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "line.txt")
        with open(path, "w") as fh:
            fh.write(MOORDYN_INPUT.format(mu=MASS_PER_LENGTH, EA=EA, BA=EA * DAMPING_TIME, x=start[0], y=start[1],
                                          z=start[2], M=LOAD, L=LENGTH, N=ELEMENTS, dt=MOORDYN_DT, g=GRAVITY))
        here = os.getcwd()
        os.chdir(folder)  # MoorDyn writes an (empty) output file beside its input
        try:
            system = moordyn.Create(path)
            moordyn.SetVerbosity(system, moordyn.LEVEL_ERR)
            if moordyn.Init_NoIC(system, [], []) != moordyn.ERRCODE_SUCCESS:  # from rest, where the file says
                raise RuntimeError("MoorDyn's initialisation failed")
            load, line = moordyn.GetPoint(system, 2), moordyn.GetLine(system, 1)
            nodes = np.array([moordyn.GetLineNodePos(line, i) for i in range(ELEMENTS + 1)])
            samples = int(round(seconds / SAMPLE))
            path_, tension = np.empty((samples + 1, 3)), np.full(samples + 1, np.nan)
            path_[0] = moordyn.GetPointPos(load)
            began = time.perf_counter()
            for k in range(samples):
                moordyn.Step(system, [], [], k * SAMPLE, SAMPLE)
                path_[k + 1] = moordyn.GetPointPos(load)
                tension[k + 1] = moordyn.GetLineFairTen(line)
            wall = time.perf_counter() - began
        finally:
            moordyn.Close(system)
            os.chdir(here)
    return {"nodes": to_ours(nodes), "path": to_ours(path_), "tension": tension, "wall": wall}


def our_scene(nodes: np.ndarray, h: float):
    """The same line and load as ours: a fixed pivot, the load's centre of mass at the line's end
    (no moment on it), starting at rest from ``nodes`` (N + 1, 3) [m], stepped at ``h`` [s]."""
    return scene_from_dict({
        "name": "moordyn_compare",
        "string": {"length": LENGTH, "mass_per_length": MASS_PER_LENGTH, "EA": EA, "elements": ELEMENTS,
                   "law": "slack", "damping_time": DAMPING_TIME, "mass_model": "lumped"},
        "body": {"mass": LOAD, "rho_c": [0.0, 0.0, 0.0], "shape": {"kind": "box", "size": [0.12, 0.1, 0.08]}},
        "pivot": {"kind": "fixed", "position": [0.0, 0.0, 0.0]},
        "gravity": GRAVITY, "h": h, "initial": {"nodes": nodes.tolist()}})


def end_tension(sim) -> tuple:
    """The end element's strain and tension [N]: EA (eps + tau d(eps)/dt) held >= 0 while taut,
    0 while slack; d(eps)/dt = n . (v_end - v_N)/u from the load's attachment velocity and node
    N's, p_N/(mu u) (the lumped mass; the step's momenta are its velocities to order 2)."""
    r, u = sim.state.r, LENGTH / ELEMENTS
    chord = r[-1] - r[-2]
    length = float(np.linalg.norm(chord))
    strain = length / u - 1.0
    if strain <= 0.0:
        return strain, 0.0
    relative = sim.diagnostics()["attach_velocity"] - sim.state.p[-2] / (MASS_PER_LENGTH * u)
    rate = float(chord @ relative) / (length * u)
    return strain, max(EA * (strain + DAMPING_TIME * rate), 0.0)


def our_run(nodes: np.ndarray, h: float, seconds: float) -> dict:
    """Ours from ``nodes`` at ``h`` (dividing SAMPLE): the load's path and end tension every SAMPLE."""
    sim = Simulator(our_scene(nodes, h))
    per = int(round(SAMPLE / h))
    samples = int(round(seconds / SAMPLE))
    path, tension = np.empty((samples + 1, 3)), np.full(samples + 1, np.nan)
    path[0] = sim.state.r[-1]
    began = time.perf_counter()
    for k in range(1, samples + 1):
        sim.step(per)
        path[k], tension[k] = sim.state.r[-1], end_tension(sim)[1]
    return {"path": path, "tension": tension, "wall": time.perf_counter() - began,
            "dissipation": sim.diagnostics()["dissipation"],
            "energy_balance_residual": sim.diagnostics()["energy_balance_residual"]}


#: The series the JSON keeps: every this many samples (5 ms; the plot draws every sample).
SERIES_EVERY = 5
#: Our steps: the slack law's margin under the stability bound (0.35; docs/physics.md, "The
#: string's resolution"), halved twice (our own convergence).
STEP_DIVISIONS = (1, 2, 4)


def compare(name: str, seconds: float) -> dict:
    """One case: MoorDyn, and ours at each of STEP_DIVISIONS; per step the largest distance
    between the load's paths [m] and between the end tensions [N] (overall, and where both
    strings are taut), and the series of MoorDyn and of ours at the finest step."""
    theirs = moordyn_run(CASES[name], seconds)
    bound = our_scene(theirs["nodes"], 1e-5).stability_bound
    h0 = SAMPLE / int(np.ceil(SAMPLE / (0.35 * bound) - 1e-9))  # dividing SAMPLE
    steps, ours = [], None
    for division in STEP_DIVISIONS:
        ours = our_run(theirs["nodes"], h0 / division, seconds)
        gap = np.abs(ours["tension"] - theirs["tension"])
        taut = (ours["tension"] > 0.0) & (theirs["tension"] > 0.0)
        steps.append({"h": h0 / division, "path": float(np.max(np.linalg.norm(ours["path"] - theirs["path"], axis=1))),
                      "tension": float(np.nanmax(gap)), "tension_taut": float(np.max(gap[taut])) if taut.any() else None,
                      "wall": ours["wall"], "energy_balance_residual": ours["energy_balance_residual"],
                      "dissipation": ours["dissipation"]})
    return {"case": name, "seconds": seconds, "moordyn_dt": MOORDYN_DT, "moordyn_wall": theirs["wall"], "steps": steps,
            "peak_tension": {"ours": float(np.nanmax(ours["tension"])), "moordyn": float(np.nanmax(theirs["tension"]))},
            "slack_samples": {"ours": int(np.sum(ours["tension"] == 0.0)),
                              "moordyn": int(np.sum(theirs["tension"] < 1e-9))},
            "series": {"t": np.arange(len(ours["tension"])) * SAMPLE,
                       **{f"{who}_{what}": run[what] for who, run in (("ours", ours), ("moordyn", theirs))
                          for what in ("path", "tension")}}}


def main(argv=None) -> dict:
    parser = arg_parser(__doc__)
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated time per case [s] (default 2)")
    args = parser.parse_args(argv)
    if not args.seconds > 0.0:
        parser.error(f"--seconds must be > 0, got {args.seconds!r}")
    seconds = min(args.seconds, 0.05) if args.quick else args.seconds
    start = time.perf_counter()
    rows = [compare(name, seconds) for name in CASES]
    print(f"\nour string (8 lumped elements, damped) against MoorDyn (RK2 at {MOORDYN_DT:g} s), {seconds:g} s")
    print("case   our h [s] | load path vs MoorDyn [m] | end tension vs MoorDyn: all, taut [N] | wall ours [s] "
          "| wall MoorDyn [s] | peak tension ours/MoorDyn [N]")
    for r in rows:
        for k, step in enumerate(r["steps"]):
            taut = "-" if step["tension_taut"] is None else f"{step['tension_taut']:.2e}"
            tail = (f"| {r['moordyn_wall']:16.2f} | {r['peak_tension']['ours']:.2f}/{r['peak_tension']['moordyn']:.2f}"
                    if k == 0 else "|")
            print(f"{r['case'] if k == 0 else '':6s} {step['h']:.3e} | {step['path']:24.2e} | {step['tension']:.2e}, "
                  f"{taut:>9s} | {step['wall']:13.2f} {tail}")
    kept = [{**r, "series": {k: v[::SERIES_EVERY].tolist() for k, v in r["series"].items()}} for r in rows]
    finish(args.out, "moordyn_compare", {"cases": kept, "machine": machine("moordyn")},
           {"moordyn_compare.png": lambda path: _plot(rows, path)}, start)
    return {"cases": rows}


def _plot(rows: list, path) -> None:
    fig = figure((10, 3.2 * len(rows)), dpi=110)
    axes = fig.subplots(len(rows), 2, squeeze=False)
    for (left, right), r in zip(axes, rows):
        s = r["series"]
        t = np.asarray(s["t"])
        moving = [i for i, name in enumerate("xyz") if np.ptp(np.asarray(s["moordyn_path"])[:, i]) > 1e-3
                  or np.ptp(np.asarray(s["ours_path"])[:, i]) > 1e-3]
        for key, style, label in (("moordyn", "-", "MoorDyn"), ("ours", "--", "esp_gym")):
            p = np.asarray(s[f"{key}_path"])
            for i in moving:
                left.plot(t, p[:, i], style, label=f"{label}, {'xyz'[i]}" + (" (down)" if i == 2 else ""))
            right.plot(t, s[f"{key}_tension"], style, lw=0.8, label=label)
        left.set(xlabel="t [s]", ylabel="load [m]", title=f"{r['case']}: the load's path")
        right.set(xlabel="t [s]", ylabel="end tension [N]", title=f"{r['case']}: tension at the load",
                  yscale="symlog" if r["case"] == "drop" else "linear")
        for ax in (left, right):
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7)
    fig.savefig(path)


if __name__ == "__main__":
    main()
