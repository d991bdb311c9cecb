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
    Simulate scene NAME (a shipped scene, esp_gym/scenes, or a YAML path) for T seconds without
    inputs and write a Rerun recording (esp_gym/viz/recording.py): the 3-D scene and the
    energy and momentum diagnostics every K physics steps (default: ~50 samples per simulated
    second) and at the end. Open it with ``rerun FILE.rrd``.

``esp-gym compile [--jobs 2] [--no-progress]``
    Compile every configuration of the environment's step into the kernel cache ahead of use, in
    worker processes, at most the CPUs (esp_gym/precompile.py), and print their seconds as one JSON line.

Every argument is checked before anything is created on disk or allocated: times must be
positive and finite, ``--out`` must name a directory (``paper``) or a file (``record``) that can
be written, and a run may take at most :data:`MAX_STEPS` physics steps and hold or write at most
:data:`MAX_BYTES` (an estimate from the arguments). A refusal is one line on stderr naming the
argument, and the exit status says what went wrong (docs/cli.md):

====  ==========================================================================================
0     done
1     the simulation failed: a step did not converge, became non-finite or blew up (the physics)
2     bad arguments: an unknown option, a bad value, an output that cannot be written, or a run
      larger than the limits
3     the scene is invalid or its file cannot be read
4     the outputs could not be written (an OS error while writing, e.g. a full disk)
====  ==========================================================================================
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from .paths import cannot_write
from .workers import jobs_argument

#: The paper's example: scene name, elements, time step [s], duration [s].
PAPER = dict(scene="paper_example", N=20, h=1e-4, t_final=5.0)

#: Exit statuses (the module docstring and docs/cli.md explain them).
EXIT_OK, EXIT_SIMULATION_FAILED, EXIT_USAGE, EXIT_SCENE, EXIT_OUTPUT = 0, 1, 2, 3, 4
#: Physics steps one command may take (~10 min at the paper example's 0.5 us per step).
MAX_STEPS = 10**9
#: Memory a command may hold for its results, and size of what it writes [bytes] (estimates).
MAX_BYTES = 2 * 2**30
#: Bytes ``paper`` holds per physics step (every-step series: the kernel's buffer, the
#: trajectory's copies, the summary's concatenation) and per float of a snapshot (two copies).
PAPER_BYTES_PER_STEP, PAPER_BYTES_PER_SNAPSHOT_FLOAT = 128, 16
#: Samples ``record`` buffers before writing them (the Recorder's ``flush_every``).
RECORD_FLUSH_EVERY = 2000


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
    from .physics.simulator import Simulator

    times = []
    for _ in range(repeats):
        sim = Simulator(scene)
        start = time.perf_counter()
        sim.step(steps)
        times.append(time.perf_counter() - start)
    return float(np.median(times)), sim.state.r


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


def check_paper_args(t_final: float, record_every: int, h: float = PAPER["h"]) -> None:
    """Raise ValueError, naming the argument, unless ``t_final`` [s] is a positive whole number
    of ``record_every`` steps of ``h`` [s] and the run fits :data:`MAX_STEPS` and :data:`MAX_BYTES`."""
    if not (isinstance(t_final, (int, float)) and math.isfinite(t_final) and t_final > 0):
        raise ValueError(f"--t-final must be a positive, finite time [s], got {t_final!r}")
    if isinstance(record_every, bool) or not isinstance(record_every, int) or record_every < 1:
        raise ValueError(f"--record-every must be a whole number of steps >= 1, got {record_every!r}")
    wanted = t_final / h
    if wanted > MAX_STEPS:
        raise ValueError(f"--t-final {t_final:g} s is {wanted:.3g} steps of h = {h:g} s, more than one command "
                         f"takes ({MAX_STEPS:,})")
    steps = int(round(wanted))
    if steps < record_every or steps % record_every or abs(steps * h - t_final) > 1e-9 * max(1.0, t_final):
        raise ValueError(f"--t-final {t_final:g} s is {wanted:g} steps of h = {h:g} s: "
                         f"it must be a positive whole number of --record-every {record_every} steps")
    snapshot_floats = 4 * (PAPER["N"] + 1) + 48  # nodes, strain, R, omega, velocity, diagnostics, balances
    need = steps * PAPER_BYTES_PER_STEP + (steps // record_every + 1) * snapshot_floats * PAPER_BYTES_PER_SNAPSHOT_FLOAT
    if need > MAX_BYTES:
        raise ValueError(f"--t-final {t_final:g} s with --record-every {record_every} keeps about {_gib(need)} of "
                         f"series and snapshots (at most {_gib(MAX_BYTES)}): use a shorter --t-final or a "
                         "larger --record-every")


def check_output(out: str, directory: bool) -> Path:
    """``out`` as a Path, or ValueError naming ``--out``: it must name a directory (``directory``)
    or a file that can be created or overwritten; whatever of its parents is missing will be
    created, under an existing, writable directory. Nothing is created here."""
    if not isinstance(out, str) or not out.strip():
        raise ValueError(f"--out is empty: name the output {'directory' if directory else 'file'}")
    path = Path(out)
    try:  # what is there now; a path the system cannot look at (permissions, a NUL) is refused
        exists, is_dir = path.exists(), path.is_dir()
        base = path if directory else path.parent  # the nearest existing directory it goes under
        while not base.exists():
            base = base.parent
    except (OSError, ValueError) as err:
        raise ValueError(f"--out {out}: cannot look at it ({err})") from None
    if directory and exists and not is_dir:
        raise ValueError(f"--out {out}: is a file, not a directory")
    if not directory and (out.endswith(("/", os.sep)) or is_dir):
        raise ValueError(f"--out {out}: is a directory; name the file to write")
    if not directory and exists and not os.access(path, os.W_OK):
        raise ValueError(f"--out {out}: the file exists and is not writable")
    problem = cannot_write(base)  # not a directory, or the file system refuses a file in it
    if problem:
        raise ValueError(f"--out {out}: {problem}")
    return path


def run_paper(out: Path, t_final: float = PAPER["t_final"], record_every: int = 100,
              progress: bool = True, argv: Optional[Sequence[str]] = None) -> dict:
    """Run the paper's example, write the outputs into ``out`` and return the summary."""
    from .physics.simulator import Simulator
    from .scene.params import load_scene
    from .viz.figures import plot_fig_ns, plot_fig_sm

    scene = load_scene(PAPER["scene"], N=PAPER["N"], h=PAPER["h"])
    check_paper_args(t_final, record_every, scene.h)
    out = check_output(str(out), directory=True)
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


def one_line(message) -> str:
    """A (multi-line) error message as one line: ``head: item; item``."""
    lines = [line.strip() for line in str(message).splitlines() if line.strip()]
    if len(lines) > 1 and lines[0].endswith(":"):
        return f"{lines[0]} {'; '.join(lines[1:])}"
    return "; ".join(lines)


def _fail(command: str, message, status: int) -> int:
    print(f"esp-gym {command}: {one_line(message)}", file=sys.stderr)
    return status


def _cmd_paper(args, argv) -> int:
    from .physics.simulator import SimulationError
    from .scene.params import SceneError

    try:
        check_paper_args(args.t_final, args.record_every)
        check_output(args.out, directory=True)
    except ValueError as err:
        return _fail("paper", err, EXIT_USAGE)
    try:
        summary = run_paper(Path(args.out), t_final=args.t_final, record_every=args.record_every,
                            progress=not args.no_progress, argv=argv)
    except SceneError as err:
        return _fail("paper", err, EXIT_SCENE)
    except SimulationError as err:
        return _fail("paper", err, EXIT_SIMULATION_FAILED)
    except OSError as err:
        return _fail("paper", f"could not write the outputs into {args.out}: {err}", EXIT_OUTPUT)
    _print_summary(summary, Path(args.out))
    return EXIT_OK


def check_record_args(scene, t_final: float, record_every: Optional[int]) -> tuple:
    """``(steps, record_every)`` of a recording of ``scene`` for ``t_final`` [s], or ValueError
    naming the argument: a whole number of steps, at most :data:`MAX_STEPS`, and the samples'
    buffer and file within :data:`MAX_BYTES`."""
    from .kernels.env.recording import sample_layout
    from .viz.recording import default_record_every

    h, n = scene.h, scene.string.elements
    wanted = t_final / h
    if wanted > MAX_STEPS:
        raise ValueError(f"--t-final {t_final:g} s is {wanted:.3g} steps of h = {h:g} s (scene {scene.name}), more "
                         f"than one command takes ({MAX_STEPS:,})")
    steps = int(round(wanted))
    if abs(steps * h - t_final) > 1e-9 * max(1.0, t_final):
        raise ValueError(f"--t-final {t_final:g} s is not a whole number of steps of h = {h:g} s (scene {scene.name})")
    every = default_record_every(h) if record_every is None else record_every
    row = 8 * sample_layout(n).size  # one sample [bytes], as buffered; a conservative size on disk
    buffered, written = RECORD_FLUSH_EVERY * row, (steps // every + 2) * row
    if buffered > MAX_BYTES:
        raise ValueError(f"--scene {scene.name}: string.elements = {n} makes a sample {row:,} bytes, and the "
                         f"recorder's buffer of {RECORD_FLUSH_EVERY} samples {_gib(buffered)} "
                         f"(at most {_gib(MAX_BYTES)})")
    if written > MAX_BYTES:
        raise ValueError(f"--t-final {t_final:g} s with a sample every {every} steps writes about {_gib(written)} "
                         f"(at most {_gib(MAX_BYTES)}): use a shorter --t-final or a larger --record-every")
    return steps, every


def _cmd_compile(args, argv) -> int:
    from .precompile import precompile

    seconds = precompile(args.jobs, progress=not args.no_progress)
    print(json.dumps({"seconds": {name: round(t, 1) for name, t in sorted(seconds.items())}}))
    return EXIT_OK


def _cmd_record(args, argv) -> int:
    from .physics.simulator import SimulationError, Simulator
    from .scene.params import SceneError, load_scene
    from .viz import recording

    try:
        out = check_output(args.out, directory=False)
    except ValueError as err:
        return _fail("record", err, EXIT_USAGE)
    try:
        scene = load_scene(args.scene)
    except SceneError as err:
        return _fail("record", err, EXIT_SCENE)
    try:
        _, every = check_record_args(scene, args.t_final, args.record_every)
        sim = Simulator(scene)
    except (ValueError, MemoryError) as err:  # MemoryError: the string does not fit this machine
        return _fail("record", err, EXIT_USAGE)
    try:
        summary = recording.record_simulation(sim, out, t_final=args.t_final, record_every=every,
                                              progress=not args.no_progress, flush_every=RECORD_FLUSH_EVERY)
    except SimulationError as err:
        return _fail("record", err, EXIT_SIMULATION_FAILED)
    except OSError as err:
        return _fail("record", f"could not write {out}: {err}", EXIT_OUTPUT)
    size = out.stat().st_size if out.is_file() else 0
    print(f"{summary['scene']}: {summary['steps']} steps, {summary['samples']} samples every "
          f"{summary['record_every']} steps in {summary['wall_time_s']:.2f} s; "
          f"max |E - E0 - W| = {summary['max_abs_energy_balance_residual']:.3e} J, "
          f"max |pi3 - pi3_0 - impulse| = {summary['max_abs_pi3_balance_residual']:.3e} kg m^2/s")
    print(f"wrote {out} ({size / 1e6:.2f} MB); open it with: rerun {out}")
    return EXIT_OK


class UsageError(Exception):
    """A command line argparse could not parse (raised instead of argparse's exit)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(f"{self.prog}: {message} (see {self.prog} --help)")


def _seconds(text: str) -> float:
    """An argparse type: a positive, finite time [s]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive, finite time [s], got {text!r}")
    return value


def _steps(text: str) -> int:
    """An argparse type: a whole number of steps >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text!r}")
    return value


EPILOG = """exit status: 0 done; 1 the simulation failed (the physics); 2 bad arguments (unknown option,
bad value, an output that cannot be written, a run past the limits); 3 invalid or unreadable scene;
4 the outputs could not be written. Limits: %s physics steps and %s of results per command."""


def build_parser() -> argparse.ArgumentParser:
    epilog = EPILOG % (f"{MAX_STEPS:,}", _gib(MAX_BYTES))
    parser = _Parser(prog="esp-gym", description=__doc__.split("\n\n")[0], epilog=epilog)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p = sub.add_parser("paper", help="reproduce the paper's numerical example (Figs. NS and SM)", epilog=epilog,
                       description="Run the paper's example (N = 20, h = 1e-4 s, 5 s) and write "
                                   "summary.json, trajectory.npz, fig_ns.png and fig_sm.png.")
    p.add_argument("--out", default="out/paper", help="output directory (default: %(default)s)")
    p.add_argument("--t-final", type=_seconds, default=PAPER["t_final"],
                   help="simulated time [s] (default: %(default)s, the paper's); must be a whole "
                        "number of record_every steps")
    p.add_argument("--record-every", type=_steps, default=100,
                   help="steps between snapshots (default: %(default)s)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=_cmd_paper)
    p = sub.add_parser("record", help="record a free simulation to a Rerun .rrd file", epilog=epilog,
                       description="Simulate a scene without inputs and write a Rerun recording: the string "
                                   "coloured by strain, the posed body, the load's trail and the energy and "
                                   "momentum diagnostics.")
    p.add_argument("--scene", default=PAPER["scene"],
                   help="a shipped scene's name (esp_gym/scenes) or a YAML path (default: %(default)s)")
    p.add_argument("--t-final", type=_seconds, default=PAPER["t_final"],
                   help="simulated time [s], a whole number of steps (default: %(default)s)")
    p.add_argument("--out", default="out/recording.rrd", help="output .rrd file (default: %(default)s)")
    p.add_argument("--record-every", type=_steps, default=None,
                   help="physics steps between samples (default: ~50 samples per simulated second)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=_cmd_record)
    p = sub.add_parser("compile", help="compile every configuration of the environment's step ahead of use",
                       epilog=epilog, description="Compile every configuration of the environment's step (esp_gym/"
                       "precompile.py) into the kernel cache, in worker processes; prints their seconds as one JSON line.")
    p.add_argument("--jobs", type=jobs_argument, default=None, help="worker processes, at most the CPUs (default: 2)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=_cmd_compile)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``esp-gym``; returns the exit status (the module docstring lists them)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser().parse_args(argv)
    except UsageError as err:
        print(one_line(err), file=sys.stderr)
        return EXIT_USAGE
    except SystemExit as done:  # --help
        return done.code if isinstance(done.code, int) else EXIT_OK
    return args.handler(args, argv)


if __name__ == "__main__":
    sys.exit(main())
