"""Zero action, every classical baseline and the shipped policy of a task on the same held-out
seeded episodes, with the paired difference policy - best baseline and its bootstrap CI.

    python -m agents.compare --task transport --preset hard --episodes 100 --json
    python -m agents.compare --scene quadrotor_load --actuation thrust_rates --task stabilize --preset hard

Policies: ``zero``, the baselines of agents/baselines/registry.py ``baselines`` for the task, the
scene, its actuation and the preset's observation, and the shipped policy
``models/{task}[_{scene}][_{actuation}][_{preset}]_ppo/model.zip`` (:func:`configuration_name`; or
``--model``). Each runs episodes seed + i (default seed 100000: none of them is a training or
an evaluation-during-training seed). Per policy: mean and standard deviation of the return,
success rate, final and mean swing, settling time and peak hook tension (agents/evaluate.py
EpisodeResult), and the return of every episode (``returns``). The best baseline is the one of highest mean return; the paired differences
(policy - best baseline, episode by episode) get a 95 % bootstrap confidence interval (BCa,
scipy.stats.bootstrap). Prints a Markdown table, or with ``--json`` one JSON object;
``--out DIR`` writes both (compare_{configuration}.md/.json).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import numpy as np

from agents.cli import ArgumentParser
from agents import MODELS
from agents.artifacts import ConfigurationError
from agents.baselines.pd import ZeroPolicy
from agents.baselines.registry import baselines
from agents.evaluate import MODEL_ERRORS, SB3Policy, run_episodes, summarize
from esp_gym.pendulum.options import EnvOptions
from esp_gym.pendulum.tasks import TASKS

HELD_OUT_SEED = 100_000
DEFAULT_SCENE = EnvOptions.model_fields["scene"].default
NOT_BASELINES = ("zero", "policy", "lqr_true_state", "cascade_true_state", "hoist_true_state")


def configuration_name(task: str, preset: Optional[str] = None, scene: Optional[str] = None,
                       actuation: Optional[str] = None) -> str:
    """``task[_scene][_actuation][_preset]``: the scene when it is not the default one, the actuation
    when it is not the scene's default (``thrust_rates`` for a drone, ``force`` for a point pivot)."""
    parts = [task]
    if scene is not None and scene != DEFAULT_SCENE:
        parts.append(scene)
    if actuation is not None:
        from esp_gym.pendulum.env_setup import make_setup

        if actuation != make_setup(task=task, scene=scene or DEFAULT_SCENE).actuation:
            parts.append(actuation)
    if preset:
        parts.append(preset)
    return "_".join(parts)


def shipped_model(task: str, preset: Optional[str] = None, scene: Optional[str] = None,
                  actuation: Optional[str] = None) -> Path:
    """Where the policy shipped for the configuration (:func:`configuration_name`) lives."""
    return MODELS / f"{configuration_name(task, preset, scene, actuation)}_ppo" / "model.zip"


def shipped_team_model(team: int, task: str, preset: Optional[str] = None, actuation: Optional[str] = None) -> Path:
    """Where the team checkpoint shipped for the configuration lives:
    ``models/team{K}[_drones[_{actuation}]]_{task}[_{preset}]_rllib/checkpoint`` (the drones'
    actuation named when it is not ``thrust_rates``)."""
    drones = "" if actuation in (None, "force") else "drones_" if actuation == "thrust_rates" else f"drones_{actuation}_"
    return MODELS / f"team{team}_{drones}{task}{'_' + preset if preset else ''}_rllib" / "checkpoint"


def paired_ci(differences, confidence: float = 0.95, resamples: int = 10_000, seed: int = 0) -> tuple:
    """``(low, high)``: the BCa bootstrap confidence interval of the mean of paired differences."""
    from scipy.stats import bootstrap

    d = np.asarray(differences, dtype=float)
    if d.size < 2:
        raise ValueError(f"a bootstrap interval needs at least 2 paired differences, got {d.size}")
    if np.ptp(d) == 0.0:  # every resample has the same mean
        return float(d[0]), float(d[0])
    res = bootstrap((d,), np.mean, confidence_level=confidence, n_resamples=resamples, method="BCa",
                    random_state=np.random.default_rng(seed))
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def compare(task: str, preset: Optional[str] = None, episodes: int = 100, seed: int = HELD_OUT_SEED,
            model: Optional[str] = None, progress: bool = True, scene: Optional[str] = None,
            actuation: Optional[str] = None) -> dict:
    """Evaluate zero, the baselines and the policy (``model``, default :func:`shipped_model`;
    left out when there is none) on ``scene`` (default: drone_load) in ``actuation`` (default:
    the scene's pivot's) and return the comparison (module docstring)."""
    from tqdm import tqdm

    env_kwargs = {"preset": preset} if preset else {}
    env_kwargs.update({name: value for name, value in (("scene", scene), ("actuation", actuation)) if value is not None})
    policies = {"zero": ZeroPolicy(), **baselines(task, env_kwargs)}
    path = Path(model) if model else shipped_model(task, preset, scene, actuation)
    if model or path.is_file():
        policies["policy"] = SB3Policy(path)
        policies["policy"].check(task, env_kwargs)  # before any episode: a model that does not fit says so
    results = {}
    for name, policy in tqdm(policies.items(), desc=f"compare {task} {preset or 'nominal'}", disable=not progress):
        results[name] = run_episodes(policy, task, episodes, seed, env_kwargs=env_kwargs)
    table = {}
    for name, rows in results.items():
        table[name] = {k: v for k, v in summarize(rows, task).items() if k not in ("task", "episodes")}
        table[name]["returns"] = [r.ret for r in rows]  # episode by episode, seed + i
    best = max((n for n in table if n not in NOT_BASELINES), key=lambda n: table[n]["mean_return"])
    out = {"task": task, "preset": preset, "scene": scene, "actuation": actuation, "episodes": episodes, "seed": seed,
           "model": str(path) if "policy" in policies else None, "policies": table, "best_baseline": best,
           "paired_diff_mean": None, "paired_ci95": None}
    if "policy" in results:
        diff = np.array([p.ret - b.ret for p, b in zip(results["policy"], results[best])])
        out["paired_diff_mean"] = float(diff.mean())
        out["paired_ci95"] = list(paired_ci(diff))
    return out


def compare_team(team: int, task: str, preset: Optional[str] = None, episodes: int = 100, seed: int = HELD_OUT_SEED,
                 progress: bool = True, model: Optional[str] = None, actuation: Optional[str] = None) -> dict:
    """:func:`compare` for a team of ``team`` strings (esp_gym/team/env.py): zero, the team's
    baselines (agents/team/evaluate.py), ``preset`` the team's (esp_gym/team/tasks.py TEAM_PRESETS),
    ``actuation`` a drone team's (None: point pivots), and ``model``, an agents.team.train
    checkpoint directory (default :func:`shipped_team_model`; left out when there is none),
    checked against the configuration before any episode (ConfigurationError where its sizes do
    not fit, a warning where only the configuration differs); the same keys, with ``team``."""
    from tqdm import tqdm

    from agents.team.evaluate import TeamZero, run_team_episodes, team_baselines

    env_kwargs = {"preset": preset} if preset else {}
    if actuation:
        env_kwargs["actuation"] = actuation
    from esp_gym.team.tasks import TEAM_PRESETS
    from esp_gym.team.tasks import get_team_task

    drones = actuation not in (None, "force")
    observation = TEAM_PRESETS.get(preset, {}).get("observation", "full")
    policies = {"zero": TeamZero(), **team_baselines(observation, drones, get_team_task(task).needs_winch)}
    if model is None and shipped_team_model(team, task, preset, actuation).is_dir():
        model = str(shipped_team_model(team, task, preset, actuation))
    if model is not None:
        from agents.team.train import TeamRLlibPolicy, check_team_checkpoint

        check_team_checkpoint(model, team, task, env_kwargs)  # before any episode
        policies["policy"] = TeamRLlibPolicy(model)
    results = {name: run_team_episodes(policy, team, task, episodes, seed, env_kwargs)
               for name, policy in tqdm(policies.items(), desc=f"compare team {team} {task}", disable=not progress)}
    table = {}
    for name, rows in results.items():
        table[name] = {k: v for k, v in summarize(rows, task).items() if k not in ("task", "episodes")}
        table[name]["returns"] = [r.ret for r in rows]
    best = max((n for n in table if n not in NOT_BASELINES), key=lambda n: table[n]["mean_return"])
    out = {"task": task, "preset": preset, "scene": None, "actuation": actuation, "episodes": episodes, "seed": seed,
           "model": model, "policies": table, "best_baseline": best, "paired_diff_mean": None, "paired_ci95": None,
           "team": team}
    if "policy" in results:
        diff = np.array([p.ret - b.ret for p, b in zip(results["policy"], results[best])])
        out["paired_diff_mean"] = float(diff.mean())
        out["paired_ci95"] = list(paired_ci(diff))
    return out


def markdown(c: dict) -> str:
    """The comparison as a Markdown table and a line for the paired difference."""
    where = "".join(f", {c[k]}" for k in ("scene", "actuation") if c.get(k))
    where += f", team of {c['team']}" if c.get("team") else ""
    lines = [f"{c['task']} ({c['preset'] or 'nominal'}{where}), {c['episodes']} episodes, seeds {c['seed']}.."
             f"{c['seed'] + c['episodes'] - 1}", "",
             "| policy | return (mean ± std) | success | final swing [deg] | mean swing [deg] | settling [s] "
             "| peak tension [N] |", "|---|---|---|---|---|---|---|"]
    for name, s in c["policies"].items():
        mark = " (best baseline)" if name == c["best_baseline"] else ""
        lines.append(f"| {name}{mark} | {s['mean_return']:.1f} ± {s['std_return']:.1f} | "
                     f"{100 * s['success_rate']:.0f} % | {s['mean_final_swing_deg']:.2f} | {s['mean_swing_deg']:.2f} "
                     f"| {s['mean_settling_time_s']:.2f} | {s['mean_peak_tension_N']:.2f} |")
    if c["paired_ci95"] is not None:
        low, high = c["paired_ci95"]
        lines += ["", f"policy - {c['best_baseline']}: {c['paired_diff_mean']:+.1f} "
                      f"(95 % bootstrap CI [{low:+.1f}, {high:+.1f}])"]
    return "\n".join(lines)


def write_comparison(c: dict, out) -> Path:
    """Write the comparison ``c`` to ``out``/compare_{configuration}.md and .json; returns the .json."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stem = "compare_" + configuration_name(c["task"], c["preset"], c["scene"], c["actuation"])
    if c.get("team"):
        stem = f"compare_team{c['team']}_{c['task']}" + "".join(f"_{c[k]}" for k in ("actuation", "preset") if c.get(k))
    (out / f"{stem}.md").write_text(markdown(c) + "\n")
    (out / f"{stem}.json").write_text(json.dumps(c, indent=2) + "\n")
    return out / f"{stem}.json"


def main(argv=None) -> dict:
    ap = ArgumentParser(prog="python -m agents.compare", description=__doc__.split("\n\n")[0])
    ap.add_episode_options(TASKS, episodes=100, preset=True, default_seed=HELD_OUT_SEED)
    ap.minimums["episodes"] = 2  # a paired bootstrap interval needs two differences
    ap.add_argument("--model", default=None, help="model .zip, with --team an agents.team.train checkpoint directory "
                                                  "(default: the one shipped for the configuration, if any)")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the Markdown table")
    ap.add_argument("--out", default=None, metavar="DIR", help="also write compare_TASK[_PRESET].md and .json here")
    ap.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    ap.add_scene_options()
    from esp_gym.team.tasks import TEAM_TASKS

    ap.add_argument("--team", type=int, default=None, metavar="K",
                    help=f"a team of K strings (1-6) carrying one load (esp_gym/team; tasks {', '.join(sorted(TEAM_TASKS))})")
    a = ap.parse_args(argv)
    ap.check_out_dir("--out", a.out)
    if a.team is None:
        ap.check_file("--model", a.model)
    else:
        from esp_gym.layouts import ACTUATIONS as DRONE_ACTUATIONS
        from esp_gym.team import MAX_STRINGS
        from esp_gym.team.tasks import TEAM_TASKS

        if not 1 <= a.team <= MAX_STRINGS:
            ap.error(f"argument --team: a team has 1 to {MAX_STRINGS} strings, got {a.team}")
        if a.task not in TEAM_TASKS:
            ap.error(f"argument --task: a team's tasks are {sorted(TEAM_TASKS)}, got {a.task!r}")
        if a.scene is not None:
            ap.error("argument --scene: not with --team (a team's scene is esp_gym.team.scene.team_scene)")
        if a.actuation is not None and a.actuation not in DRONE_ACTUATIONS:
            ap.error(f"argument --actuation: with --team, a drone's ({', '.join(DRONE_ACTUATIONS)}), or none for point "
                     f"pivots; got {a.actuation!r}")
        if a.model is not None and not (Path(a.model) / "learner_group").is_dir():
            ap.error(f"argument --model: with --team, an agents.team.train checkpoint directory, got {a.model}")
        from agents.team.train import check_team_env

        options = {name: value for name, value in (("preset", a.preset), ("actuation", a.actuation)) if value}
        try:  # the environment built once, before any episode
            check_team_env(a.team, a.task, options)
        except ValueError as err:
            ap.error(str(err))
        try:
            c = compare_team(a.team, a.task, a.preset, a.episodes, a.seed, a.progress, a.model, a.actuation)
        except ConfigurationError as err:
            ap.error(f"argument --model: {err}")
        print(json.dumps(c) if a.json else markdown(c))
        if a.out:
            write_comparison(c, a.out)
        return c
    ap.environment_options(a)  # checked before any episode
    try:
        c = compare(a.task, a.preset, a.episodes, a.seed, a.model, a.progress, a.scene, a.actuation)
    except MODEL_ERRORS as err:  # the model's; an error inside an episode (a baseline's) is not
        ap.error(f"argument --model: {err}")
    print(json.dumps(c) if a.json else markdown(c))
    if a.out:
        write_comparison(c, a.out)
    return c


if __name__ == "__main__":
    main()
