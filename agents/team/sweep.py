"""Sweep agents.team.train runs with Ray Tune: hyper-parameters x seeds for a team, on this machine
or a Ray cluster, gathered into one table and plot (as agents/distributed/sweep.py does for
agents.train).

    python -m agents.team.sweep --team 3 --task transport --preset hard --residual --iterations 200 \\
        --space '{"lr": [1e-4, 3e-4], "seed": [0, 1]}'
    python -m agents.team.sweep --team 3 --actuation thrust_rates --task track --space '{"seed": [0, 1]}'
    python -m agents.team.sweep --resume sweeps/team

``--space`` maps keys to lists of values (JSON or YAML): every combination is a trial. A key is a
``--set`` key of agents.team.train (configs/agents/rllib_team_ppo.yaml: ``lr``, ``minibatch_size``,
``model.fcnet_hiddens``, ...) or ``seed``; every key and value is checked, with ``--set``'s base
overrides, before anything starts. Each trial takes one CPU and samples in its own process (RLlib's
local env runner: ``num_env_runners=0``, whatever ``--set`` says), and is a normal agents.team.train
run directory ``OUT/runs/TRIAL`` (config.yaml, progress.csv, checkpoint/, evaluation.json on
``--eval-episodes`` episodes of seeds 10000+, learning_curve.png). It reports every iteration's
training return to Tune. ``OUT/results.{csv,md,png}`` gather the trials
(agents/distributed/sweep_results.py); ``OUT/tune/`` is Tune's experiment.

``--resume OUT`` continues an interrupted sweep with its own settings (``OUT/sweep.json``): a
finished trial keeps its run, an unfinished one starts again from scratch (an RLlib run has no
resumable checkpoint before it ends).
"""
from __future__ import annotations

import dataclasses
import json
import logging
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from agents.cli import SettingsError, one_line, settings_parser
from agents.common import ConfigError
from agents.distributed.rllib import load_rllib_config
from agents.distributed.sweep import (METRICS, Spec, checked_space, new_out, override, start_or_resume,
                                      sweep_main)
from esp_gym.pendulum.options import ACTUATION_CHOICES
from esp_gym.team.tasks import TEAM_TASKS

#: What every trial sets over ``--set`` and the space: sampling in the trial's own process (one CPU).
TRIAL_OVERRIDES = ("num_env_runners=0",)
#: ``--actuation``'s choices: a drone team's (every actuation but the point pivot's force).
DRONE_ACTUATIONS = [name for name in ACTUATION_CHOICES if name != "force"]


@dataclass
class Settings:
    space: Optional[str] = field(default=None, metadata={
        "help": "the grid: a JSON/YAML mapping of --set keys (or seed) to lists of values", "run": True})
    team: int = field(default=3, metadata={"help": "strings K (1-6)", "type": int, "min": 1, "run": True})
    task: str = field(default="transport", metadata={"help": "task", "choices": sorted(TEAM_TASKS), "run": True})
    preset: Optional[str] = field(default=None, metadata={"help": "the team's preset", "choices": ["hard"],
                                                          "run": True})
    actuation: Optional[str] = field(default=None, metadata={
        "help": "the pivots are drones flown so, as agents.team.train's (default: point pivots pushed by forces)",
        "choices": DRONE_ACTUATIONS, "run": True})
    residual: bool = field(default=False, metadata={"help": "train residuals on the team's baseline", "run": True})
    central_critic: bool = field(default=False, metadata={"help": "trials with a centralised critic", "run": True})
    iterations: int = field(default=100, metadata={"help": "training iterations of each trial", "type": int,
                                                   "min": 1, "run": True})
    time_limit: Optional[float] = field(default=None, metadata={
        "help": "minutes of training after which a trial stops and saves", "type": float, "run": True})
    set: list = field(default_factory=list, metadata={
        "help": "overrides every trial shares, as agents.team.train's --set (repeatable)", "nargs": "+",
        "action": "extend", "run": True})
    out: Optional[str] = field(default=None, metadata={
        "help": "the sweep's directory (default: sweeps/team{K}__{task}__{time}); on a cluster of several machines, "
                "a path every node sees", "run": True})
    address: Optional[str] = field(default=None, metadata={
        "help": "a Ray cluster's head HOST:PORT or 'auto' (default: start Ray on this machine)"})
    eval_episodes: int = field(default=10, metadata={"help": "episodes of each trial's final evaluation",
                                                     "type": int, "min": 1, "run": True})
    reference_episodes: int = field(default=10, metadata={"help": "episodes of each trial's reference returns",
                                                          "type": int, "min": 1, "run": True})
    resume: Optional[str] = field(default=None, metadata={"help": "an interrupted sweep's directory to continue"})


#: Settings that define a sweep: a resumed sweep takes them from its sweep.json.
SWEEP_SETTINGS = frozenset(f.name for f in dataclasses.fields(Settings) if f.metadata.get("run"))


def trial_settings(s: Settings, config: dict, runs: Path, name: str):
    """agents.team.train's Settings of the trial ``config`` (a grid point) of the sweep ``s``."""
    from agents.team import train as team_train

    overrides = list(s.set) + [override(k, v) for k, v in config.items() if k != "seed"] + list(TRIAL_OVERRIDES)
    return team_train.Settings(team=s.team, task=s.task, preset=s.preset, actuation=s.actuation,
                               iterations=s.iterations,
                               time_limit=s.time_limit, seed=int(config.get("seed", 0)), set=overrides,
                               runs=str(runs), run_name=name, eval_episodes=s.eval_episodes,
                               reference_episodes=s.reference_episodes, residual=s.residual,
                               central_critic=s.central_critic, progress=False)


def trial_argv(ts) -> list:
    """The agents.team.train command line of a trial's settings ``ts``, saved with its run."""
    return ["--team", str(ts.team), "--task", ts.task, *(["--preset", ts.preset] if ts.preset else []),
            *(["--actuation", ts.actuation] if ts.actuation else []),
            *(["--residual"] if ts.residual else []), *(["--central-critic"] if ts.central_critic else []),
            "--iterations", str(ts.iterations),
            "--seed", str(ts.seed), "--runs", str(ts.runs), "--run-name", ts.run_name, "--set", *ts.set]


def check_trial(s: Settings, point: dict) -> None:
    """What the trial of grid point ``point`` would build, before a cluster starts: its config and
    RLlib's validation of it (ConfigError or ValueError, as the trial would raise them)."""
    from agents.team import train as team_train

    ts = trial_settings(s, point, Path("."), "check")
    cfg = load_rllib_config(ts.task, ts.set, team_train.CONFIG_FILE, team_train.TEAM_ENV_ID)
    quiet = logging.getLogger("ray.rllib")  # a new config warns of RLlib's API stack, each time
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        team_train.team_ppo_config(cfg, ts).validate()
    finally:
        quiet.setLevel(level)


def check_space(space: dict, s: Settings) -> None:
    """Every value of every key as a trial would take it (the other keys at their first values):
    SettingsError naming ``--space`` (the key and value), or ``--set`` where the base settings fail
    alone."""
    for value in space.get("seed", []):
        if not isinstance(value, int) or isinstance(value, bool) or value < 0:
            raise SettingsError("--space", f"seed: {value!r} is not an integer >= 0")
    keys = [key for key in space if key != "seed"]
    first = {key: space[key][0] for key in keys}
    for key, value in [(None, None)] + [(key, value) for key in keys for value in space[key]]:
        try:
            check_trial(s, first if key is None else {**first, key: value})
        except (ConfigError, ValueError, TypeError) as err:
            try:
                check_trial(s, {})
            except (ConfigError, ValueError, TypeError) as base:
                raise SettingsError("--set", one_line(base)) from None
            where = "" if key is None else f"key {key!r} = {value!r}: "
            raise SettingsError("--space", where + one_line(err)) from None


def run_trial(config: dict, spec: Spec) -> dict:
    """One Tune trial (in a Ray worker, Ray already joined): agents.team.train's run in
    ``OUT/runs/TRIAL``, reporting each iteration; then its evaluation's metrics."""
    import ray
    from ray import tune

    from agents.team import train as team_train

    s = Settings(**spec.settings)
    runs = Path(spec.out) / "runs"
    name = tune.get_context().get_trial_name()
    run_dir = runs / name
    status = json.loads((run_dir / "status.json").read_text())["status"] if (run_dir / "status.json").is_file() else None
    if status != "finished":
        shutil.rmtree(run_dir, ignore_errors=True)  # an unfinished RLlib run starts again
        ts = trial_settings(s, config, runs, name)
        cfg = load_rllib_config(ts.task, ts.set, team_train.CONFIG_FILE, team_train.TEAM_ENV_ID)
        algo = team_train.team_ppo_config(cfg, ts).build_algo()
        try:
            team_train.run(ts, cfg, run_dir, algo, argv=trial_argv(ts), report=lambda row: tune.report(
                {"timesteps": row["env_steps"], "mean_return": row["episode_return_mean"]}))
        finally:
            algo.stop()
    stats = json.loads((run_dir / "evaluation.json").read_text())
    done = json.loads((run_dir / "training.json").read_text())
    return {**{k: stats[k] for k in METRICS}, "timesteps": done["timesteps"], "wall_time_s": done["wall_time_s"],
            "node_id": ray.get_runtime_context().get_node_id(), "run_dir": str(run_dir)}


def prepare(s: Settings, given: frozenset) -> tuple:
    """``(spec, resuming)`` of checked settings; SettingsError before anything is written."""
    from esp_gym.team import MAX_STRINGS

    resumed = start_or_resume(s, given, SWEEP_SETTINGS)
    if resumed is not None:
        return resumed, True
    if s.team > MAX_STRINGS:
        raise SettingsError("--team", f"a team has 1 to {MAX_STRINGS} strings, got {s.team}")
    if s.time_limit is not None and not s.time_limit > 0:
        raise SettingsError("--time-limit", f"must be > 0 minutes, got {s.time_limit}")
    space = checked_space(s)
    check_space(space, s)
    out = new_out(s.out, f"team{s.team}__{s.task}")
    return Spec({k: v for k, v in dataclasses.asdict(s).items() if k in SWEEP_SETTINGS}, space,
                str(out.resolve())), False


def main(argv=None):
    ap = settings_parser(Settings, prog="python -m agents.team.sweep", description=__doc__.split("\n\n")[0])
    return sweep_main(ap, Settings, argv, prepare, run_trial)


if __name__ == "__main__":
    main()
