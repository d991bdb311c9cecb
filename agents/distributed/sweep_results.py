"""A sweep's results in one table and one plot (agents/distributed/sweep.py, agents/team/sweep.py):
``results.csv`` (one row per trial: its grid point, agents/evaluate.py's metrics of its final
model, steps, wall time, node, run directory), ``results.md`` (the configurations, seeds pooled:
mean ± standard deviation over seeds of each trial's mean return, best first; then every trial)
and ``results.png`` (each trial's returns during training, coloured by configuration, and the
final returns)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

COLUMNS = ("mean_return", "std_return", "success_rate", "mean_final_swing_deg", "timesteps", "wall_time_s",
           "node_id", "run_dir")


def trial_rows(results, space: dict) -> list:
    """One dict per trial of Tune's ResultGrid: the grid point, then :data:`COLUMNS` (``error``
    for a trial that failed or did not finish). Only a trial's final report (its evaluation, which
    names its run directory) fills the columns: a progress report of a stopped trial gives its
    steps alone."""
    rows = []
    for r in results:
        metrics = r.metrics or {}
        final = "run_dir" in metrics
        row = {k: (r.config or {}).get(k) for k in space}
        row.update({k: metrics.get(k) if final or k == "timesteps" else None for k in COLUMNS})
        error = r.error if r.error is not None or final else "did not finish (the sweep was stopped)"
        row["error"] = None if error is None else " ".join(str(error).split())[:300]
        rows.append(row)
    return rows


def configuration(row: dict, space: dict) -> str:
    """A trial's configuration: its grid point without the seed."""
    return ", ".join(f"{k}={json.dumps(row[k])}" for k in space if k != "seed") or "(one configuration)"


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.1f}" if abs(v) >= 10 else f"{v:.3g}"
    return "" if v is None else str(v)


def markdown(rows: list, space: dict) -> str:
    groups: dict = {}
    for row in rows:
        if row["mean_return"] is not None:
            groups.setdefault(configuration(row, space), []).append(row)
    lines = ["| configuration | trials | mean return (mean ± sd over seeds) | success rate |", "|---|---|---|---|"]
    for name, members in sorted(groups.items(), key=lambda kv: -np.mean([m["mean_return"] for m in kv[1]])):
        ret = [m["mean_return"] for m in members]
        lines.append(f"| {name} | {len(members)} | {np.mean(ret):.1f} ± {np.std(ret):.1f} | "
                     f"{np.mean([m['success_rate'] for m in members]):.2f} |")
    keys = list(space) + ["mean_return", "success_rate", "timesteps", "wall_time_s", "error"]
    lines += ["", "| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for row in sorted(rows, key=lambda r: -(r["mean_return"] if r["mean_return"] is not None else -np.inf)):
        lines.append("| " + " | ".join(_fmt(row[k]) for k in keys) + " |")
    return "\n".join(lines) + "\n"


def run_curve(run_dir: Path):
    """``(steps, returns, label)`` of a trial's run directory: agents.train's evaluations during
    training (evaluations.npz), or an RLlib run's training episodes per iteration (progress.csv,
    agents.team.train); None if it has neither."""
    ev, progress = run_dir / "evaluations.npz", run_dir / "progress.csv"
    if ev.is_file():
        with np.load(ev) as d:
            return d["timesteps"], d["results"].mean(axis=1), "evaluation return (mean)"
    if progress.is_file():
        with open(progress, newline="") as fh:
            rows = list(csv.DictReader(fh))
        return ([int(r["env_steps"]) for r in rows], [float(r["episode_return_mean"]) for r in rows],
                "training episodes' return (mean)")
    return None


def plot(rows: list, space: dict, title: str, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = sorted({configuration(r, space) for r in rows})
    colours = {n: plt.cm.tab10(i % 10) for i, n in enumerate(names)}
    fig, (curves, finals) = plt.subplots(1, 2, figsize=(12, 4.5), layout="constrained")
    label = "evaluation return (mean)"
    for row in rows:
        curve = run_curve(Path(row["run_dir"])) if row["run_dir"] else None
        if curve is not None:
            steps, returns, label = curve
            curves.plot(steps, returns, "o-", ms=2, lw=1, color=colours[configuration(row, space)])
    refs = next((Path(r["run_dir"]) / "references.json" for r in rows
                 if r["run_dir"] and (Path(r["run_dir"]) / "references.json").is_file()), None)
    if refs is not None:  # the trials share their task: one trial's baseline and zero-action returns
        references = json.loads(refs.read_text())
        for key, style in (("baseline_return", "--"), ("zero_return", ":")):
            if key in references:
                for ax in (curves, finals):
                    ax.axhline(references[key], color="0.4", ls=style, lw=1,
                               label=f"{key.removesuffix('_return').replace('_', ' ')} ({references[key]:.1f})")
        curves.legend(loc="best", fontsize=8)
    curves.set(xlabel="environment steps", ylabel=label, title="during training")
    for i, name in enumerate(names):
        ret = [r["mean_return"] for r in rows if configuration(r, space) == name and r["mean_return"] is not None]
        finals.scatter([i] * len(ret), ret, color=colours[name], zorder=3)
        if ret:
            finals.errorbar([i + 0.15], [np.mean(ret)], yerr=[np.std(ret)], fmt="s", color="k", ms=4)
    finals.set_xticks(range(len(names)), names, rotation=20, ha="right", fontsize=7)
    finals.set(ylabel="final evaluation return", title="final models (dots: seeds; square: mean ± sd)")
    for ax in (curves, finals):
        ax.grid(True, alpha=0.3)
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def gather(results, spec) -> list:
    """Write OUT/results.csv, results.md and results.png for Tune's ResultGrid of the sweep ``spec``."""
    out, space = Path(spec.out), spec.space
    rows = trial_rows(results, space)
    with open(out / "results.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(space) + list(COLUMNS) + ["error"])
        writer.writeheader()
        writer.writerows({k: (json.dumps(v) if isinstance(v, (list, dict)) else v) for k, v in r.items()}
                         for r in rows)
    (out / "results.md").write_text(markdown(rows, space))
    s = spec.settings
    what = f"a team of {s['team']}, RLlib PPO" if "team" in s else s["algo"].upper()
    plot(rows, space, f"sweep: {what} on {s['task']} ({len(rows)} trials)", out / "results.png")
    return rows
