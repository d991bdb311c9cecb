"""The ``esp-gym`` command line.

Subcommands:

``esp-gym paper --out DIR [--t-final 5.0] [--record-every 100] [--no-progress]``
    Reproduce the paper's numerical example (scene ``paper_example``, N = 20, h = 1e-4 s,
    T = 5 s: 50,000 steps) and write into DIR:

    ===================  ==================================================================
    ``summary.json``     step cost, conservation errors, stretched-length range, Newton
                         iterations, the resolved scene and the command line
    ``trajectory.npz``   snapshots every ``record_every`` steps (t, nodes, R, omega,
                         attach_velocity, energies, pi3, orthogonality, stretched_length,
                         strain_energy) and the every-step series (t, energy, pi3,
                         orthogonality ``_every_step``)
    ``fig_ns.png``       the paper's Fig. NS (diagnostics)
    ``fig_sm.png``       the paper's Fig. SM (snapshots)
    ===================  ==================================================================

``esp-gym record --scene NAME --t-final T --out FILE.rrd [--record-every K] [--no-progress]``
    Simulate scene NAME (a name under configs/scenes or a YAML path) for T seconds without
    inputs and write a Rerun recording (esp_gym/viz/recording.py): the 3-D scene and the
    energy and momentum diagnostics every K physics steps (default: ~50 samples per simulated
    second) and at the end. Open it with ``rerun FILE.rrd``.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import platform
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

#: The paper's example: scene name, elements, time step [s], duration [s].
PAPER = dict(scene="paper_example", N=20, h=1e-4, t_final=5.0)


def summarize(traj, scene) -> dict:
    """Numbers that characterise a run (SI units). Conservation errors use the every-step series
    when ``traj`` has them (else the snapshots); the stretched length is sampled at snapshots.

    energy_drift_slope [J/s] is the least-squares slope of E - E0 against t;
    orthogonality is ||I - R^T R||_F.
    """
    t = traj.t
    E0 = float(traj.energy[0])
    pi30 = float(traj.pi3[0])
    if traj.energy_every_step is not None and len(traj.energy_every_step):
        ts = np.concatenate([t[:1], traj.t_every_step])
        E = np.concatenate([traj.energy[:1], traj.energy_every_step])
        pi3 = np.concatenate([traj.pi3[:1], traj.pi3_every_step])
        orth = np.concatenate([traj.orthogonality[:1], traj.orthogonality_every_step])
        series = "every step"
    else:
        ts, E, pi3, orth, series = t, traj.energy, traj.pi3, traj.orthogonality, "snapshots"
    dE = E - E0
    slope = float(np.polyfit(ts, dE, 1)[0]) if len(ts) > 1 else 0.0
    steps = int(traj.steps)
    return {
        "scene": scene.name,
        "N": int(scene.string.elements),
        "h": float(scene.h),
        "t_final": float(t[-1] - t[0]),
        "steps": steps,
        "conservation_series": series,
        "energy_initial": E0,
        "energy_max_abs_error": float(np.abs(dE).max()),
        "energy_max_rel_error": float(np.abs(dE).max() / abs(E0)) if E0 else None,
        "energy_drift_slope": slope,
        "pi3_initial": pi30,
        "pi3_max_abs_deviation": float(np.abs(pi3 - pi30).max()),
        "orthogonality_max": float(orth.max()),
        "stretched_length_min": float(traj.stretched_length.min()),
        "stretched_length_max": float(traj.stretched_length.max()),
        "newton_iterations_mean": traj.newton_iterations / steps if steps else 0.0,
    }


def _time_plain_steps(scene, steps: int, repeats: int = 3):
    """Median wall time [s] of ``steps`` steps in one compiled call (no recording), from the
    initial state each time, and the final node positions of the last repeat."""
    from .model import Simulator

    times = []
    for _ in range(repeats):
        sim = Simulator(scene)
        start = time.perf_counter()
        sim.step(steps)
        times.append(time.perf_counter() - start)
    return float(np.median(times)), sim.state.r


def check_paper_args(t_final: float, record_every: int, h: float = PAPER["h"]) -> None:
    """Raise ValueError unless ``t_final`` [s] is a positive whole number of ``record_every``
    steps of ``h`` [s]."""
    steps = int(round(t_final / h))
    if (record_every < 1 or steps < record_every or steps % record_every
            or abs(steps * h - t_final) > 1e-9 * max(1.0, abs(t_final))):
        raise ValueError(f"t_final = {t_final:g} s is {t_final / h:g} steps of h = {h:g} s: "
                         f"it must be a positive whole number of record_every = {record_every} steps")


def run_paper(out: Path, t_final: float = PAPER["t_final"], record_every: int = 100,
              progress: bool = True, argv: Optional[Sequence[str]] = None) -> dict:
    """Run the paper's example, write the outputs into ``out`` and return the summary."""
    from .model import Simulator
    from .params import load_scene
    from .viz.figures import plot_fig_ns, plot_fig_sm

    scene = load_scene(PAPER["scene"], N=PAPER["N"], h=PAPER["h"])
    check_paper_args(t_final, record_every, scene.h)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)

    # Load (or compile) the kernels first so that the timings below are of the simulation only.
    start = time.perf_counter()
    Simulator(scene).run(t_final=record_every * scene.h, record_every=record_every, every_step=True)
    warmup = time.perf_counter() - start

    sim = Simulator(scene)
    traj = sim.run(t_final=t_final, record_every=record_every, every_step=True, progress=progress)
    plain, r_plain = _time_plain_steps(scene, traj.steps)

    summary = summarize(traj, scene)
    steps = traj.steps
    summary.update({
        "wall_time_s": traj.wall_time_s,
        "us_per_step": plain / steps * 1e6 if steps else None,
        "us_per_step_recording": traj.wall_time_s / steps * 1e6 if steps else None,
        "wall_time_plain_s": plain,
        "kernel_load_or_compile_s": warmup,
        # the plain and the recording runs take the same steps: their end states must agree
        "plain_vs_recorded_final_nodes_max_diff": float(np.abs(r_plain - traj.nodes[-1]).max()),
        "newton_iterations_max": int(sim.newton_iterations_max),
        "record_every": int(record_every),
        "snapshots": int(len(traj.t)),
        "command": ["esp-gym", *(argv if argv is not None else sys.argv[1:])],
        "created": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
        "versions": _versions(),
        "scene_config": scene.model_dump(mode="json"),
    })
    traj.save(out / "trajectory.npz")
    with open(out / "summary.json", "w") as fh:
        json.dump(summary, fh, indent=2)
    plot_fig_ns(traj, out / "fig_ns.png", scene=scene)
    plot_fig_sm(traj, scene, out / "fig_sm.png")
    return summary


def _versions() -> dict:
    import numba

    from . import __version__

    return {"esp_gym": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba.__version__, "machine": platform.machine(), "system": platform.system()}


def _print_summary(s: dict, out: Path) -> None:
    print(f"\n{s['scene']}: N = {s['N']}, h = {s['h']:g} s, {s['steps']} steps "
          f"({s['t_final']:g} s simulated)")
    print(f"  cost          {s['us_per_step']:.3f} us/step plain, {s['us_per_step_recording']:.3f} us/step "
          f"recording ({s['wall_time_s']:.3f} s); kernels loaded in {s['kernel_load_or_compile_s']:.2f} s")
    print(f"  energy        E0 = {s['energy_initial']:.9f} J, max |E - E0| = {s['energy_max_abs_error']:.3e} J, "
          f"drift {s['energy_drift_slope']:+.3e} J/s")
    print(f"  pi3           max |pi3 - pi3(0)| = {s['pi3_max_abs_deviation']:.3e} kg m^2/s")
    print(f"  orthogonality max ||I - R^T R||_F = {s['orthogonality_max']:.3e}")
    print(f"  length        {s['stretched_length_min']:.4f} .. {s['stretched_length_max']:.4f} m")
    print(f"  Newton        {s['newton_iterations_mean']:.3f} iterations/step on average, "
          f"{s['newton_iterations_max']} at most")
    print(f"  wrote         {out}/summary.json, trajectory.npz, fig_ns.png, fig_sm.png")


def _cmd_paper(args, argv) -> int:
    from .model import SimulationError

    try:  # only argument errors are reported briefly: anything later keeps its traceback
        check_paper_args(args.t_final, args.record_every)
    except ValueError as err:
        print(f"esp-gym paper: {err}", file=sys.stderr)
        return 2
    try:
        summary = run_paper(Path(args.out), t_final=args.t_final, record_every=args.record_every,
                            progress=not args.no_progress, argv=argv)
    except SimulationError as err:
        print(f"esp-gym paper: {err}", file=sys.stderr)
        return 1
    _print_summary(summary, Path(args.out))
    return 0


def _cmd_record(args, argv) -> int:
    from .model import SimulationError, Simulator
    from .params import SceneError, load_scene
    from .viz.recording import record_simulation

    try:
        sim = Simulator(load_scene(args.scene))
        summary = record_simulation(sim, args.out, t_final=args.t_final, record_every=args.record_every,
                                    progress=not args.no_progress)
    except (SceneError, SimulationError, ValueError, FileNotFoundError) as err:
        print(f"esp-gym record: {err}", file=sys.stderr)
        return 1 if isinstance(err, SimulationError) else 2
    size = Path(args.out).stat().st_size
    print(f"{summary['scene']}: {summary['steps']} steps, {summary['samples']} samples every "
          f"{summary['record_every']} steps in {summary['wall_time_s']:.2f} s; "
          f"max |E - E0 - W| = {summary['max_abs_energy_balance_residual']:.3e} J, "
          f"max |pi3 - pi3_0 - impulse| = {summary['max_abs_pi3_balance_residual']:.3e} kg m^2/s")
    print(f"wrote {args.out} ({size / 1e6:.2f} MB); open it with: rerun {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="esp-gym", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p = sub.add_parser("paper", help="reproduce the paper's numerical example (Figs. NS and SM)",
                       description="Run the paper's example (N = 20, h = 1e-4 s, 5 s) and write "
                                   "summary.json, trajectory.npz, fig_ns.png and fig_sm.png.")
    p.add_argument("--out", default="out/paper", help="output directory (default: %(default)s)")
    p.add_argument("--t-final", type=float, default=PAPER["t_final"],
                   help="simulated time [s] (default: %(default)s, the paper's); must be a whole "
                        "number of record_every steps")
    p.add_argument("--record-every", type=int, default=100,
                   help="steps between snapshots (default: %(default)s)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=_cmd_paper)
    p = sub.add_parser("record", help="record a free simulation to a Rerun .rrd file",
                       description="Simulate a scene without inputs and write a Rerun recording: the string "
                                   "coloured by strain, the posed body, the load's trail and the energy and "
                                   "momentum diagnostics.")
    p.add_argument("--scene", default=PAPER["scene"],
                   help="scene name under configs/scenes or a YAML path (default: %(default)s)")
    p.add_argument("--t-final", type=float, default=PAPER["t_final"],
                   help="simulated time [s], a whole number of steps (default: %(default)s)")
    p.add_argument("--out", default="out/recording.rrd", help="output .rrd file (default: %(default)s)")
    p.add_argument("--record-every", type=int, default=None,
                   help="physics steps between samples (default: ~50 samples per simulated second)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=_cmd_record)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``esp-gym``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    return args.handler(args, argv)


if __name__ == "__main__":
    sys.exit(main())
