"""Robustness of the baselines and the shipped policy in the hard preset: the mean return
against the mean wind speed, the string's EA and the load's mass, each swept through and beyond
the training ranges while everything else is drawn as in training.

    python -m agents.robustness --task stabilize --episodes 20 --out docs/img

For each value the preset's options are kept but one: ``wind.speed`` is replaced, or the
``randomize`` range of ``EA`` / ``load_mass`` is pinned to the value (a factor of the nominal
scene's; the training ranges are x[0.5, 2] and 6 m/s). Writes robustness_{task}.png (three
panels, the training range shaded, mean +- standard error) and robustness_{task}.json.
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np

from agents.cli import ArgumentParser
from agents.compare import HELD_OUT_SEED, shipped_model
from agents.baselines.registry import baselines
from agents.evaluate import SB3Policy, run_episodes
from esp_gym.pendulum.env_setup import PRESETS, make_setup
from esp_gym.pendulum.tasks import TASKS

#: The swept quantity -> (values, training range, axis label); EA and load mass as factors.
SWEEPS = {
    "wind_speed": ((0.0, 3.0, 6.0, 9.0, 12.0), (6.0, 6.0), "mean wind speed [m/s]"),
    "EA": ((0.25, 0.5, 1.0, 2.0, 4.0), (0.5, 2.0), "EA / nominal"),
    "load_mass": ((0.25, 0.5, 1.0, 2.0, 4.0), (0.5, 2.0), "load mass / nominal"),
}


def sweep_options(name: str, value: float) -> dict:
    """The hard preset's environment options with ``name`` set to ``value`` (the default scene's
    point pivot: without the drone's thrust noise, which it would refuse)."""
    options = {key: given for key, given in copy.deepcopy(PRESETS["hard"]).items() if key != "thrust_noise"}
    if name == "wind_speed":
        options["wind"]["speed"] = float(value)
        return options
    scene = make_setup().scene  # the environment's default scene, which the preset keeps
    nominal = {"EA": scene.string.EA, "load_mass": scene.body.mass}[name]
    options["randomize"] = {name: (value * nominal, value * nominal)}
    return options


def robustness(task: str, episodes: int, seed: int = HELD_OUT_SEED, model=None, progress: bool = True) -> dict:
    """name -> {"values": [...], policy -> [(mean, standard error) per value]}."""
    from tqdm import tqdm

    path = Path(model) if model else shipped_model(task, "hard")
    trained = SB3Policy(path) if path.is_file() else None  # reset per episode by run_episodes
    out = {}
    total = sum(len(values) for values, _, _ in SWEEPS.values())
    bar = tqdm(total=total, desc=f"robustness {task}", disable=not progress)
    for name, (values, _, _) in SWEEPS.items():
        rows = {"values": list(values)}
        for value in values:
            options = sweep_options(name, value)
            policies = dict(baselines(task, options))
            if trained is not None:
                policies["policy"] = trained
            for label, policy in policies.items():
                returns = [r.ret for r in run_episodes(policy, task, episodes, seed, env_kwargs=options)]
                rows.setdefault(label, []).append((float(np.mean(returns)),
                                                   float(np.std(returns) / np.sqrt(len(returns)))))
            bar.update()
        out[name] = rows
    bar.close()
    return out


def plot(task: str, result: dict, path: Path) -> None:
    from esp_gym.viz.figures import new_figure, save_figure

    fig = new_figure((4.2 * len(SWEEPS), 3.6))
    axes = fig.subplots(1, len(SWEEPS))
    for ax, (name, (values, trained, label)) in zip(axes, SWEEPS.items()):
        rows = result[name]
        for policy in (k for k in rows if k != "values"):
            mean, err = np.array(rows[policy]).T
            ax.errorbar(values, mean, yerr=err, marker="o", capsize=3, label=policy)
        ax.axvspan(trained[0] * 0.97, trained[1] * 1.03, color="0.85", zorder=0, label="training range")
        if name != "wind_speed":
            ax.set_xscale("log", base=2)
        ax.set_xlabel(label)
        ax.set_ylabel("mean return")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{task}, hard preset: robustness (mean +- standard error)")
    fig.tight_layout()
    save_figure(fig, path)


def main(argv=None) -> dict:
    ap = ArgumentParser(prog="python -m agents.robustness", description=__doc__.split("\n\n")[0])
    ap.add_episode_options(TASKS, episodes=20, default_seed=HELD_OUT_SEED)
    ap.add_argument("--model", default=None, help="model .zip (default: the shipped hard-preset one)")
    ap.add_argument("--out", default="docs/img", help="directory for robustness_TASK.png and .json")
    ap.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    a = ap.parse_args(argv)
    ap.check_file("--model", a.model)
    ap.check_out_dir("--out", a.out)
    out = Path(a.out)
    result = robustness(a.task, a.episodes, a.seed, a.model, a.progress)
    out.mkdir(exist_ok=True)
    (out / f"robustness_{a.task}.json").write_text(json.dumps(result, indent=2) + "\n")
    plot(a.task, result, out / f"robustness_{a.task}.png")
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
