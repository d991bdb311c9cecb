"""A training run's directory over its life: its status, its checkpoints, and how a resumed run
continues its history (the monitor log and the evaluations) from the checkpoint it starts at.

Status (``status.json``): ``running`` while training, then ``finished`` or ``failed`` (with the
error and the step reached). A run directory is created only after the settings are checked and
the environments and the model are built, so a run that cannot start leaves nothing behind.

History: a checkpoint ``model_N_steps.zip`` comes with ``model_history_N_steps.json``, the number
of monitor rows written by then. Resuming from it keeps those rows of ``monitor.csv`` and the
evaluations up to step N, and appends to both: the history reads as one run, even when it resumes
from an earlier checkpoint than the last one (the rows and evaluations after it belonged to
training that the resumed run replaces).
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, EvalCallback
from stable_baselines3.common.monitor import ResultsWriter
from stable_baselines3.common.vec_env import VecMonitor

import esp_gym
from agents.cli import SettingsError, one_line
from esp_gym.paths import cannot_write
from agents.artifacts import checkpoint_files, checkpoint_steps, stats_path_for
from agents.normalization import NormalizationFileError, NormStats

EVALUATION_KEYS = ("timesteps", "results", "ep_lengths", "successes")


def write_status(run_dir: Path, status: str, **details) -> None:
    """``status.json``: ``running``, ``finished``, ``interrupted`` or ``failed`` (both with ``error``), and
    ``timesteps``."""
    (run_dir / "status.json").write_text(json.dumps({"status": status, **details,
                                                     "time": time.strftime("%Y-%m-%dT%H:%M:%S")}, indent=2) + "\n")


def new_run_dir(runs: str, run_name: Optional[str], algo: str, task: str, seed: int) -> Path:
    """``runs/run_name`` (default ``{env}__{algo}__{task}__{seed}__{time}``), checked before anything
    is written: SettingsError naming ``--run-name`` (not a plain directory name, or taken) or
    ``--runs`` (not a directory this process can make and write in, or the default name taken)."""
    if run_name is not None and (Path(run_name).name != run_name or run_name in ("", ".", "..")):
        raise SettingsError("--run-name", f"{run_name!r} is not a directory name")
    root = Path(runs)
    if root.exists() and not root.is_dir():
        raise SettingsError("--runs", f"{root} is not a directory")
    problem = cannot_write(root)
    if problem:
        raise SettingsError("--runs", problem)
    run_dir = root / (run_name or f"{esp_gym.ENV_ID}__{algo}__{task}__{seed}__{time.strftime('%Y%m%d-%H%M%S')}")
    if run_dir.exists():
        raise SettingsError("--run-name" if run_name else "--runs", f"{run_dir} already exists")
    return run_dir


def write_stopped(run_dir: Path, err: BaseException, **details) -> None:
    """status.json of a run that ``err`` ended: ``interrupted`` for Ctrl-C or a caller's SystemExit
    (a sweep stopping its trial), ``failed`` for anything else; the error in one line."""
    status = "interrupted" if isinstance(err, (KeyboardInterrupt, SystemExit)) else "failed"
    write_status(run_dir, status, **details, error=one_line(f"{type(err).__name__}: {err}"))


class RunMonitor(VecMonitor):
    """VecMonitor whose log is opened once the run directory exists (:meth:`open_log`): a new
    ``monitor.csv``, or the rows a resumed run keeps (:class:`MonitorLog`) followed by new ones."""

    def __init__(self, venv):
        super().__init__(venv)
        self.kept_rows = 0

    @property
    def rows(self) -> int:
        """Episodes in the log so far (kept from before a resume, and written since)."""
        return self.kept_rows + self.episode_count

    def open_log(self, path: Path, previous: Optional["MonitorLog"] = None) -> None:
        header = {"t_start": self.t_start, "env_id": esp_gym.ENV_ID}
        if previous is None:
            self.results_writer = ResultsWriter(str(path), header=header)
            return
        # times continue from the run's first start (SB3's "t": seconds since t_start)
        self.t_start = previous.t_start
        path.write_text("".join(previous.header_lines + previous.rows))
        self.kept_rows = len(previous.rows)
        self.results_writer = ResultsWriter(str(path), header=header, override_existing=False)


@dataclass
class MonitorLog:
    """The part of a run's ``monitor.csv`` a resumed run keeps."""

    header_lines: list
    rows: list
    t_start: float

    @classmethod
    def read(cls, path: Path, keep_rows: Optional[int]) -> Optional["MonitorLog"]:
        if not path.is_file():
            return None
        lines = path.read_text().splitlines(keepends=True)
        try:
            t_start = float(json.loads(lines[0][1:])["t_start"])
        except (IndexError, ValueError, KeyError, TypeError):
            raise ValueError(f"{path}: not a monitor log (its first line is not SB3's #{{...}} header)") from None
        rows = [r if r.endswith("\n") else r + "\n" for r in lines[2:]]
        return cls(lines[:2], rows if keep_rows is None else rows[:keep_rows], t_start)


@dataclass
class Evaluations:
    """The part of a run's ``evaluations.npz`` (EvalCallback's log) a resumed run keeps."""

    arrays: dict

    @classmethod
    def read(cls, path: Path, up_to: int) -> Optional["Evaluations"]:
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in EVALUATION_KEYS if k in data or k != "successes"}
            keep = arrays["timesteps"] <= up_to
            return cls({k: v[keep] for k, v in arrays.items()})
        except (OSError, ValueError, KeyError, IndexError) as err:
            raise ValueError(f"{path}: not an evaluation log ({type(err).__name__}: {err})") from None

    def continue_in(self, callback: EvalCallback, path: Path) -> None:
        """Start ``callback`` from these evaluations, and write them back (the log then holds
        the run's history up to the resumed step even before the next evaluation)."""
        a = self.arrays
        callback.evaluations_timesteps = [int(t) for t in a["timesteps"]]
        callback.evaluations_results = [list(r) for r in a["results"]]
        callback.evaluations_length = [list(r) for r in a["ep_lengths"]]
        if "successes" in a:
            callback.evaluations_successes = [list(r) for r in a["successes"]]
        if len(a["results"]):
            callback.best_mean_reward = float(np.max(np.mean(a["results"], axis=1)))
        np.savez(path, **a)


@dataclass
class Resume:
    """A checked ``--resume`` checkpoint and everything read from its run directory (nothing is
    written until the resumed run starts)."""

    checkpoint: Path
    run_dir: Path
    steps: int
    saved: dict  # the run's args.json
    stats: Optional[NormStats]
    monitor: Optional[MonitorLog]
    evaluations: Optional[Evaluations]

    @classmethod
    def read(cls, checkpoint: str | Path) -> "Resume":
        """Raises ValueError with a one-line message for anything that is not a checkpoint of a run."""
        ckpt = Path(checkpoint)
        if not ckpt.is_file():
            raise ValueError(f"no such file: {ckpt}")
        steps = checkpoint_steps(ckpt)
        if steps is None:
            raise ValueError(f"{ckpt} is not a checkpoint: expected RUN/checkpoints/model_N_steps.zip")
        if ckpt.resolve().parent.name != "checkpoints":
            raise ValueError(f"{ckpt} is not in the checkpoints/ directory of a run: expected RUN/checkpoints/"
                             "model_N_steps.zip")
        run_dir = ckpt.resolve().parent.parent
        args = run_dir / "args.json"
        if not args.is_file():
            raise ValueError(f"{ckpt} is not in a run directory: {run_dir} has no args.json")
        try:
            saved = json.loads(args.read_text())
            if not isinstance(saved, dict) or not {"algo", "task", "seed", "set"} <= set(saved):
                raise ValueError("lacks algo, task, seed or set")
        except ValueError as err:
            raise ValueError(f"{args}: not the arguments of a run ({err})") from None
        stats_path = stats_path_for(ckpt)
        try:
            stats = NormStats.load(stats_path) if stats_path else None
        except NormalizationFileError as err:
            raise ValueError(str(err)) from None
        marker = checkpoint_files(ckpt.parent, steps)["history"]
        keep_rows = None  # a checkpoint without a marker (older runs): keep every row
        if marker.is_file():
            try:
                keep_rows = int(json.loads(marker.read_text())["monitor_rows"])
            except (ValueError, KeyError, TypeError) as err:
                raise ValueError(f"{marker}: not a history marker ({type(err).__name__}: {err})") from None
        return cls(ckpt, run_dir, steps, saved, stats, MonitorLog.read(run_dir / "monitor.csv", keep_rows),
                   Evaluations.read(run_dir / "evaluations.npz", steps))


class RunCheckpoint(BaseCallback):
    """Checkpoints at every multiple of ``every`` environment steps (counted over the whole run,
    across resumes): the model, its normalisation statistics (.npz) and the history marker."""

    def __init__(self, directory: Path, every: int, monitor: RunMonitor):
        super().__init__()
        self.directory, self.every, self.monitor = Path(directory), int(every), monitor

    def _init_callback(self) -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        self.saved_up_to = self.model.num_timesteps // self.every  # a resumed run starts past 0

    def _on_step(self) -> bool:
        if self.num_timesteps // self.every > self.saved_up_to:
            self.saved_up_to = self.num_timesteps // self.every
            files = checkpoint_files(self.directory, self.num_timesteps)
            self.model.save(files["model"])
            vn = self.model.get_vec_normalize_env()
            if vn is not None:
                NormStats.from_vecnormalize(vn).save(files["stats"])
            files["history"].write_text(json.dumps({"timesteps": self.num_timesteps,
                                                    "monitor_rows": self.monitor.rows}) + "\n")
        return True
