"""Sweep agents.train runs with Ray Tune: hyper-parameters x seeds x environment options, on this
machine or a Ray cluster, gathered into one table and plot, resumable after an interruption.

    python -m agents.distributed.sweep --task stabilize --space '{"learning_rate": [1e-4, 3e-4], "seed": [0, 1, 2]}'
    python -m agents.distributed.sweep --task transport --space '{"env_kwargs.randomize": [false, true], "seed": [0, 1]}' \\
        --set total_timesteps=500000 --address 10.0.0.1:6379 --out sweeps/randomize
    python -m agents.distributed.sweep --resume sweeps/randomize

``--space`` maps keys to lists of values (JSON or YAML): every combination is a trial (Tune's
grid search). A key is a ``--set`` key of agents.train (``learning_rate``, ``n_steps``,
``policy_kwargs.net_arch``, ``env_kwargs.randomize`` for the randomisation ranges, ...) or
``seed``; every key and value is checked, with ``--set``'s base overrides, before anything starts.
Each trial is one CPU and a normal agents.train run directory, ``OUT/runs/TRIAL``, plus
``evaluation.json``: agents/evaluate.py's metrics of its final model on ``--episodes`` episodes
(seeds 10000+). ``OUT/results.{csv,md}`` hold one row per trial and ``OUT/results.png`` their
learning curves and final returns; ``OUT/tune/`` is Tune's experiment. While it trains, a trial
reports to Tune every ``--eval-freq`` steps (``mean_return``: its recent training episodes, a
stochastic policy; the last report is the evaluation), which is also where Tune can stop it: Ctrl-C
stops a sweep within one report interval and leaves its trials ``interrupted``.

``--resume OUT`` continues an interrupted sweep with its own settings (``OUT/sweep.json``): Tune
reruns the trials that had not finished, and a trial whose run directory holds a checkpoint
resumes agents.train from its last one.
"""
from __future__ import annotations

import dataclasses
import json
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import yaml

import esp_gym
from agents.artifacts import checkpoint_steps
from agents.cli import SettingsError, one_line, option_name, parse_settings, settings_parser
from esp_gym.paths import cannot_write
from agents import ROOT
from agents.common import ConfigError, load_run_config
from agents.distributed.sweep_results import gather
from agents.distributed.cluster import AddressError, check_address, connect, shutdown, token_auth
from esp_gym.pendulum.tasks import TASKS

#: Seeds of each trial's final evaluation (episode i: seed + i), as agents.train's references.
EVAL_SEED = 10_000
METRICS = ("mean_return", "std_return", "success_rate", "mean_final_swing_deg", "mean_swing_deg")


@dataclass
class Settings:
    space: Optional[str] = field(default=None, metadata={
        "help": "the grid: a JSON/YAML mapping of --set keys (or seed) to lists of values", "run": True})
    algo: str = field(default="ppo", metadata={"help": "algorithm", "choices": ["ppo", "sac"], "run": True})
    task: str = field(default="stabilize", metadata={"help": "task", "choices": sorted(TASKS), "run": True})
    set: list = field(default_factory=list, metadata={
        "help": "overrides every trial shares, as agents.train's --set (repeatable)", "nargs": "+", "action": "extend",
        "run": True})
    out: Optional[str] = field(default=None, metadata={
        "help": "the sweep's directory (default: sweeps/{env}__{algo}__{task}__{time}); on a cluster of several "
                "machines, a path every node sees", "run": True})
    address: Optional[str] = field(default=None, metadata={
        "help": "a Ray cluster's head HOST:PORT or 'auto' (default: start Ray on this machine)"})
    episodes: int = field(default=10, metadata={"help": f"episodes of each trial's final evaluation (seeds "
                                                        f"{EVAL_SEED}+)", "type": int, "min": 1, "run": True})
    eval_freq: int = field(default=50_000, metadata={"help": "agents.train --eval-freq", "type": int, "min": 1,
                                                     "run": True})
    eval_episodes: int = field(default=10, metadata={"help": "agents.train --eval-episodes", "type": int, "min": 1,
                                                     "run": True})
    checkpoint_freq: int = field(default=500_000, metadata={"help": "agents.train --checkpoint-freq", "type": int,
                                                            "min": 1, "run": True})
    reference_episodes: int = field(default=10, metadata={"help": "agents.train --reference-episodes", "type": int,
                                                          "min": 1, "run": True})
    resume: Optional[str] = field(default=None, metadata={"help": "an interrupted sweep's directory to continue"})


#: Settings that define a sweep: a resumed sweep takes them from its sweep.json.
SWEEP_SETTINGS = frozenset(f.name for f in dataclasses.fields(Settings) if f.metadata.get("run"))


def parse_space(text: Optional[str]) -> dict:
    """``--space``'s mapping of keys to non-empty lists (ValueError naming the fault)."""
    if text is None:
        raise ValueError("required: a mapping of --set keys (or seed) to lists of values, e.g. "
                         "'{\"learning_rate\": [1e-4, 3e-4], \"seed\": [0, 1]}'")
    try:
        space = json.loads(text)  # JSON first: YAML 1.1 reads 1e-4 as a string
    except json.JSONDecodeError:
        try:
            space = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise ValueError(f"not JSON or YAML ({one_line(getattr(err, 'problem', None) or err)})") from None
    if not isinstance(space, dict) or not space:
        raise ValueError(f"expected a mapping of keys to lists of values, got {space!r}")
    for key, values in space.items():
        if not isinstance(values, list) or not values:
            raise ValueError(f"{key}: expected a non-empty list of values, got {values!r}")
    return space


def check_space(space: dict, s: Settings) -> None:
    """The trials of ``space`` as agents.train would take them (with the base ``--set``): every
    value of every key, the other keys at their first values (:func:`check_trial`); a space of
    seeds alone, the base settings' trial. SettingsError naming ``--space`` (the key and value)
    or ``--set``."""
    for value in space.get("seed", []):
        if not isinstance(value, int) or isinstance(value, bool) or value < 0:
            raise SettingsError("--space", f"seed: {value!r} is not an integer >= 0")
    keys = [key for key in space if key != "seed"]
    first = [override(key, space[key][0]) for key in keys]
    if not keys:
        try:
            check_trial(s, [])
        except (ValueError, TypeError, MemoryError) as err:
            raise SettingsError("--set", one_line(err)) from None
    for i, key in enumerate(keys):
        for value in space[key]:
            try:
                check_trial(s, first[:i] + [override(key, value)] + first[i + 1:])
            except ConfigError as err:
                raise SettingsError("--space", f"key {key!r}: {err}") from None
            except (ValueError, TypeError, MemoryError) as err:
                raise SettingsError("--space", f"key {key!r} = {value!r}: {one_line(err)}") from None


def check_trial(s: Settings, extra: list) -> None:
    """What a trial with ``--set`` and ``extra`` would build, before a cluster starts: its config,
    its environment's options, the residual's baseline and the batch's memory (ConfigError,
    ValueError, TypeError or MemoryError, as the trial would raise them)."""
    from agents.residual import base_policy
    from esp_gym.pendulum.env_setup import make_setup
    from esp_gym.physics.state import check_memory

    cfg = load_run_config(s.algo, esp_gym.ENV_ID, s.task, list(s.set) + list(extra))
    setup = make_setup(task=s.task, **cfg.env_kwargs)
    if cfg.residual is not None:
        base_policy(cfg.residual, s.task, cfg.env_kwargs)
    check_memory(setup.scene.string.elements, cfg.n_envs)


def override(key: str, value) -> str:
    """A ``--set`` item for ``key`` and ``value`` (flow-style YAML)."""
    return f"{key}={yaml.safe_dump(value, default_flow_style=True, width=10**6).strip().removesuffix('...').strip()}"


@dataclass(frozen=True)
class Spec:
    """What every trial of a sweep shares (sweep.json)."""

    settings: dict
    space: dict
    out: str


def progress_reporter(every: int):
    """An SB3 callback that reports to Tune every ``every`` steps: the step count and the mean return
    of the recent training episodes. A report is where Tune stops a trial (it raises SystemExit in
    the trial's thread), so a stopped sweep does not wait for its trials to end."""
    from ray import tune
    from stable_baselines3.common.callbacks import BaseCallback

    class TuneProgress(BaseCallback):
        def _on_training_start(self) -> None:
            self.next_report = (self.num_timesteps // every + 1) * every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next_report:
                self.next_report += every * ((self.num_timesteps - self.next_report) // every + 1)
                episodes = [info["r"] for info in self.model.ep_info_buffer]
                tune.report({"timesteps": int(self.num_timesteps),
                             "mean_return": float(np.mean(episodes)) if episodes else float("nan")})
            return True

    return TuneProgress()


def run_trial(config: dict, spec: Spec) -> dict:
    """One Tune trial (in a Ray worker): agents.train in ``OUT/runs/TRIAL`` (resumed from its last
    checkpoint if an interrupted sweep left one), then the final evaluation; reports its metrics."""
    import ray
    from ray import tune

    from agents import train
    from agents.evaluate import SB3Policy, evaluate_policy

    s = Settings(**spec.settings)
    seed = int(config.get("seed", 0))
    overrides = list(s.set) + [override(k, v) for k, v in config.items() if k != "seed"]
    runs = Path(spec.out) / "runs"
    run_dir = runs / tune.get_context().get_trial_name()
    status = json.loads((run_dir / "status.json").read_text())["status"] if (run_dir / "status.json").is_file() else None
    if status != "finished":
        last = max((p for p in (run_dir / "checkpoints").glob("model_*_steps.zip") if checkpoint_steps(p)),
                   key=checkpoint_steps, default=None)
        if last is not None:
            args = ["--resume", str(last), "--no-progress"]
        else:
            shutil.rmtree(run_dir, ignore_errors=True)  # started, no checkpoint yet: start again
            args = ["--algo", s.algo, "--task", s.task, "--seed", str(seed), "--runs", str(runs),
                    "--run-name", run_dir.name, "--eval-freq", str(s.eval_freq), "--eval-episodes",
                    str(s.eval_episodes), "--checkpoint-freq", str(s.checkpoint_freq), "--reference-episodes",
                    str(s.reference_episodes), "--no-progress", "--set", *overrides]
        settings, given, _ = train.parse_args(args)
        train.train(settings, argv=args, given=given, callbacks=[progress_reporter(s.eval_freq)])
    cfg = load_run_config(s.algo, esp_gym.ENV_ID, s.task, overrides)
    stats = evaluate_policy(SB3Policy(run_dir / "model.zip"), s.task, s.episodes, seed=EVAL_SEED,
                            env_kwargs=cfg.env_kwargs)
    (run_dir / "evaluation.json").write_text(json.dumps({**stats, "seed": EVAL_SEED}, indent=2))
    done = json.loads((run_dir / "training.json").read_text())
    return {**{k: stats[k] for k in METRICS}, "timesteps": done["timesteps"], "wall_time_s": done["wall_time_s"],
            "node_id": ray.get_runtime_context().get_node_id(), "run_dir": str(run_dir)}


def new_out(out: Optional[str], default: str) -> Path:
    """A new sweep's directory: ``out``, or ``sweeps/{default}__{time}``; SettingsError naming
    ``--out`` if it exists, its parent does not, or this process cannot write there."""
    out = Path(out) if out else ROOT / "sweeps" / f"{default}__{time.strftime('%Y%m%d-%H%M%S')}"
    if out.exists():
        raise SettingsError("--out", f"{out} already exists (--resume {out} continues a sweep)")
    if not out.resolve().parent.is_dir():
        raise SettingsError("--out", f"no directory {out.resolve().parent} for {out}")
    problem = cannot_write(out)
    if problem:
        raise SettingsError("--out", problem)
    return out


def start_or_resume(s, given: frozenset, sweep_settings: frozenset) -> Optional[Spec]:
    """What every sweep command checks first: ``--address``; with ``--resume``, that no setting
    of ``sweep_settings`` is given and the directory is a sweep's, and its Spec (None without
    ``--resume``). SettingsError naming the argument."""
    try:
        check_address(s.address)
    except AddressError as err:
        raise SettingsError("--address", str(err)) from None
    if not s.resume:
        return None
    clash = sorted(given & sweep_settings)
    if clash:
        raise SettingsError(option_name(clash[0]), "not allowed with --resume (a resumed sweep keeps its settings)")
    saved = Path(s.resume) / "sweep.json"
    if not saved.is_file() or not (Path(s.resume) / "tune").is_dir():
        raise SettingsError("--resume", f"{s.resume} is not a sweep's directory (no sweep.json and tune/)")
    return Spec(**json.loads(saved.read_text()))


def checked_space(s) -> dict:
    """``--space`` parsed; SettingsError naming it."""
    try:
        return parse_space(s.space)
    except ValueError as err:
        raise SettingsError("--space", str(err)) from None


def prepare(s: Settings, given: frozenset) -> tuple:
    """``(spec, resuming)`` of checked settings; SettingsError before anything is written."""
    resumed = start_or_resume(s, given, SWEEP_SETTINGS)
    if resumed is not None:
        return resumed, True
    try:
        load_run_config(s.algo, esp_gym.ENV_ID, s.task, list(s.set))
    except ConfigError as err:
        raise SettingsError("--set", str(err)) from None
    space = checked_space(s)
    check_space(space, s)
    out = new_out(s.out, f"{esp_gym.ENV_ID}__{s.algo}__{s.task}")
    return Spec({k: v for k, v in dataclasses.asdict(s).items() if k in SWEEP_SETTINGS}, space,
                str(out.resolve())), False


def sweep(spec: Spec, resuming: bool, address: Optional[str], trial=run_trial):
    """Run (or continue) the sweep on Ray Tune, each point a one-CPU ``trial(config, spec)``, and
    gather its results; returns Tune's ResultGrid."""
    from ray import tune

    out = Path(spec.out)
    connect(address)
    trainable = tune.with_resources(tune.with_parameters(trial, spec=spec), {"cpu": 1})
    if resuming:
        tuner = tune.Tuner.restore(str(out / "tune"), trainable=trainable, resume_unfinished=True,
                                   resume_errored=True)
    else:
        out.mkdir(parents=True)
        (out / "sweep.json").write_text(json.dumps(dataclasses.asdict(spec), indent=2))
        tuner = tune.Tuner(trainable, param_space={k: tune.grid_search(v) for k, v in spec.space.items()},
                           tune_config=tune.TuneConfig(metric="mean_return", mode="max"),
                           run_config=tune.RunConfig(name="tune", storage_path=str(out), verbose=1))
    results = tuner.fit()
    gather(results, spec)
    return results


def sweep_main(ap, settings_class, argv, check, trial):
    """A sweep command's life (this module's and agents.team.sweep's): the settings from ``ap``,
    Ray's token, ``check(s, given) -> (spec, resuming)`` (a SettingsError is one line naming the
    argument), :func:`sweep` with ``trial``, and Ray left whatever happens."""
    s, given = parse_settings(ap, settings_class, argv)
    token_auth(s.address)  # before anything imports ray
    try:
        spec, resuming = check(s, given)
    except SettingsError as err:
        ap.error(str(err))
    try:
        return sweep(spec, resuming, s.address, trial)
    finally:
        shutdown()


def main(argv=None):
    ap = settings_parser(Settings, prog="python -m agents.distributed.sweep", description=__doc__.split("\n\n")[0])
    return sweep_main(ap, Settings, argv, prepare, run_trial)


if __name__ == "__main__":
    main()
