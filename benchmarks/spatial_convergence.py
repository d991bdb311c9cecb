"""Spatial discretisation error: how far the N-element string is from the continuum string.

The work-precision benchmarks measure the *time*-integration error of one finite-element model
(N fixed). This one measures the model's own error, which sets how much time accuracy is worth
having: the attachment point of the paper example over [0, T] (T = 1 s, sampled every 0.01 s)
for N = 10 .. 160 elements, consistent and lumped mass, against the consistent string with
``--ref-N`` (640) elements. Every run uses the Suzuki 5-stage composition (order 4) at
h <= ``--h-fraction`` (0.3) of the scene's stability bound, so its time error (printed: the
reference rerun at h/2) is far below the spatial errors measured.

Two starts of the same scene:

* ``paper``: the paper's initial condition: string straight and at rest, the attachment node
  (and the body) moving at v0 = (0, 0.2, -0.5) m/s. In the continuum limit this is a velocity
  jump at the attachment point, a kink that travels along the string and reflects, so the
  finite-element solution converges slowly (the observed order is printed);
* ``linear``: the same attachment velocity with the string's velocity growing linearly from the
  pivot, v(s) = (s/l) v0: no velocity jump. It is still not smooth data: the string starts
  unstretched (zero tension, so zero transverse wave speed) and the body's weight acts at once
  on its end, a jump in tension at the attachment point;
* ``hanging``: smooth data: the string hangs straight down (+e3) stretched as in the
  continuum's static equilibrium, eps(s) = g (M + mu (l - s)) / EA, with the transverse
  velocity v(s) = (s/l) (v0_1, v0_2, 0). Here the finite elements show their order on
  smooth solutions.

Observed orders come from successive differences max|x_N - x_2N| (no reference needed).
Prints a table and writes ``OUT/spatial_convergence.json`` and ``OUT/spatial_convergence.png``
(OUT = benchmarks/out unless ``--out``).

Usage: ``python -m benchmarks.spatial_convergence [--quick] [--out DIR]``. ``--quick``:
N = 5, 10, 20 against 40 (a smoke test, not a measurement).
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from benchmarks.common import arg_parser, figure, finish, machine

STARTS = ("paper", "linear", "hanging")
MASS_MODELS = ("consistent", "lumped")


def scene_for(N: int, start: str, mass_model: str, h: float | None = None, scene_name: str = "paper_example"):
    """The scene with ``N`` elements, one of :data:`STARTS` and a mass model; ``h`` [s] if given."""
    import esp_gym

    base = esp_gym.load_scene(scene_name, N=N, allow_unstable_h=True)
    initial = {}
    if start == "linear":
        s = np.linspace(0.0, 1.0, N + 1)[:, None]
        v = s * np.asarray(base.initial.attach_velocity, dtype=float)
        v[0] = base.pivot.velocity
        initial = {"node_velocities": v.tolist()}
    elif start == "hanging":
        st, M, g = base.string, base.body.mass, base.gravity
        length, mu, EA = st.length, st.mass_per_length, st.EA
        s = np.linspace(0.0, length, N + 1)
        # z(s) = integral of 1 + eps over [0, s], eps linear in s: exact at the nodes
        z = s + g * (M * s + mu * (length * s - 0.5 * s * s)) / EA
        r = np.asarray(base.pivot.position, dtype=float) + np.outer(z, (0.0, 0.0, 1.0))
        v0 = np.asarray(base.initial.attach_velocity, dtype=float) * (1.0, 1.0, 0.0)
        v = np.outer(s / length, v0)
        initial = {"nodes": r.tolist(), "node_velocities": v.tolist()}
    elif start != "paper":
        raise ValueError(f"start must be one of {STARTS}, got {start!r}")
    kwargs = dict(N=N, string={"mass_model": mass_model}, solver={"order": 4, "composition": "suzuki5"})
    if initial:
        kwargs["initial"] = initial
    if h is not None:
        kwargs["h"] = h
    else:  # the scene's default h may exceed a fine string's bound: only the bound is read then
        kwargs["allow_unstable_h"] = True
    return esp_gym.load_scene(scene_name, **kwargs)


def attachment_path(N: int, start: str, mass_model: str, t_final: float, sample: float,
                    h_fraction: float, refine: int = 1) -> tuple[np.ndarray, float]:
    """Attachment point every ``sample`` s over [0, t_final] (rows) and the h used [s]."""
    import esp_gym

    bound = scene_for(N, start, mass_model).string.element_bound
    k = refine * math.ceil(sample / (h_fraction * bound))
    h = sample / k
    sim = esp_gym.Simulator(scene_for(N, start, mass_model, h=h))
    traj = sim.run(t_final, record_every=k)
    return traj.nodes[:, -1].copy(), h


def observed_orders(Ns, paths) -> list:
    """log2 of successive ratios of d_N = max|x_N - x_2N| (None where 2N was not run)."""
    d = {N: float(np.abs(paths[N] - paths[2 * N]).max()) for N in Ns if 2 * N in paths}
    return [math.log2(d[N] / d[2 * N]) if N in d and 2 * N in d and d[2 * N] > 0 else None for N in Ns]


def run_paths(Ns: tuple, ref_N: int, t_final: float, sample: float, h_fraction: float) -> tuple:
    """``(paths, hs)``: every run's attachment path (by (N, start, mass model)) and its h, the
    reference's (``ref_N``, consistent mass) and its own time error, a rerun at h/2, under
    ``(ref_N, start, "time_error")``."""
    from tqdm import tqdm

    runs = [(N, s, m) for s in STARTS for m in MASS_MODELS for N in Ns + (2 * max(Ns),)]
    paths, hs = {}, {}
    with tqdm(total=len(runs) + 2 * len(STARTS), desc="runs", unit="run") as bar:
        for start in STARTS:
            paths[(ref_N, start, "consistent")], hs[(ref_N, start)] = attachment_path(
                ref_N, start, "consistent", t_final, sample, h_fraction)
            bar.update()
            # the reference's own time error: the same run at h/2
            finer, _ = attachment_path(ref_N, start, "consistent", t_final, sample, h_fraction, refine=2)
            hs[(ref_N, start, "time_error")] = float(np.abs(finer - paths[(ref_N, start, "consistent")]).max())
            bar.update()
        for N, start, mass in runs:
            paths[(N, start, mass)], hs[(N, start, mass)] = attachment_path(N, start, mass, t_final, sample, h_fraction)
            bar.update()
    return paths, hs


def error_table(paths: dict, Ns: tuple, ref_N: int) -> dict:
    """Per start and mass model: each N's largest distance from the reference's path [m] and the
    observed orders."""
    table = {}
    for start in STARTS:
        ref = paths[(ref_N, start, "consistent")]
        for mass in MASS_MODELS:
            series = {N: paths[(N, start, mass)] for N in Ns + (2 * max(Ns),)}
            errors = [float(np.abs(series[N] - ref).max()) for N in Ns]
            table[f"{start}/{mass}"] = {"N": list(Ns), "error_m": errors, "order": observed_orders(Ns, series)}
    return table


def print_table(table: dict, hs: dict, Ns: tuple, ref_N: int, t_final: float, sample: float) -> None:
    """The error table with its observed orders, and the reference's time error."""
    print(f"\nspatial error: max |attachment point - that of N = {ref_N} (consistent)| over [0, {t_final:g}] s "
          f"every {sample:g} s [m]")
    print("time error of the reference (rerun at h/2): "
          + ", ".join(f"{s} {hs[(ref_N, s, 'time_error')]:.1e} m" for s in STARTS))
    head = f"{'N':>5}" + "".join(f"{key:>22}" for key in table)
    print(head)
    for i, N in enumerate(Ns):
        print(f"{N:>5}" + "".join(f"{row['error_m'][i]:>13.3e}" + (f" ({row['order'][i]:.2f})" if row['order'][i]
                                                                     is not None else " " * 7) + "  "
                                   for row in table.values()))
    print("(in brackets: the observed order log2(d_N / d_2N), d_N = max|x_N - x_2N|)")


def main(argv=None) -> int:
    parser = arg_parser(__doc__)
    parser.add_argument("--t-final", type=float, default=1.0, help="simulated time [s] (default: %(default)s)")
    parser.add_argument("--ref-N", type=int, default=640, help="elements of the reference (default: %(default)s)")
    parser.add_argument("--h-fraction", type=float, default=0.3,
                        help="h as a fraction of each scene's stability bound (default: %(default)s)")
    args = parser.parse_args(argv)
    if args.quick:
        Ns, ref_N, t_final = (5, 10, 20), 40, 0.2
    else:
        Ns, ref_N, t_final = (10, 20, 40, 80, 160), args.ref_N, args.t_final
    if ref_N <= max(Ns) or ref_N % max(Ns):
        parser.error(f"--ref-N must be a multiple of {max(Ns)} above it, got {ref_N}")
    sample = 0.01
    start_time = time.perf_counter()
    paths, hs = run_paths(Ns, ref_N, t_final, sample, args.h_fraction)
    table = error_table(paths, Ns, ref_N)
    print_table(table, hs, Ns, ref_N, t_final, sample)
    payload = {
        "settings": {"Ns": list(Ns), "ref_N": ref_N, "t_final": t_final, "sample": sample,
                     "h_fraction": args.h_fraction, "quick": args.quick},
        "reference_time_error_m": {s: hs[(ref_N, s, "time_error")] for s in STARTS},
        "h_s": {f"{k[1]}/{k[2]}/N={k[0]}": v for k, v in hs.items() if len(k) == 3 and k[2] in MASS_MODELS},
        "table": table,
        "machine": machine(), "total_wall_s": time.perf_counter() - start_time,
    }
    finish(args.out, "spatial_convergence", payload,
           {"spatial_convergence.png": lambda path: plot(table, ref_N, t_final, path)}, start_time)
    return 0


def plot(table: dict, ref_N: int, t_final: float, path) -> None:
    fig = figure((7.5, 5.0), dpi=130)
    ax = fig.subplots()
    colours = {"paper": "tab:red", "linear": "tab:blue", "hanging": "tab:green"}
    styles = {"consistent": "-", "lumped": "--"}
    for key, row in table.items():
        start, mass = key.split("/")
        ax.loglog(row["N"], row["error_m"], styles[mass], marker="o", color=colours[start],
                  label=f"{start} start, {mass} mass")
    N = np.array(next(iter(table.values()))["N"], dtype=float)
    for order, anchor in ((1, "paper/consistent"), (2, "hanging/consistent")):
        e0 = table[anchor]["error_m"][0]
        ax.loglog(N, 0.5 * e0 * (N / N[0]) ** -order, ":", color="0.5", lw=1)
        ax.annotate(f"order {order}", (N[-1], 0.5 * e0 * (N[-1] / N[0]) ** -order), fontsize=8, color="0.4",
                    ha="left", va="center", xytext=(4, 0), textcoords="offset points")
    ax.set_xlabel("elements N")
    ax.set_ylabel(f"max attachment-point error over [0, {t_final:g}] s [m]")
    ax.set_title(f"Spatial discretisation error (paper example; reference N = {ref_N}, consistent mass)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path)


if __name__ == "__main__":
    sys.exit(main())
