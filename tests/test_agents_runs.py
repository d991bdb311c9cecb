"""A training run's directory over its life: a resumed run continues its monitor log and its
evaluations from the checkpoint it starts at, and a run that fails after it started says so in
status.json. Tiny budgets: 1 environment, episodes end early under the untrained policy."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from agents import train

BUDGET = ["total_timesteps=1024", "n_envs=1", "n_steps=128", "batch_size=64", "n_epochs=1"]
OPTIONS = ["--eval-freq", "512", "--eval-episodes", "1", "--checkpoint-freq", "512", "--reference-episodes", "1",
           "--no-progress"]


def monitor_rows(run: Path) -> list:
    lines = (run / "monitor.csv").read_text().splitlines()
    assert lines[1] == "r,l,t"
    return lines[2:]


def evaluations(run: Path) -> dict:
    with np.load(run / "evaluations.npz") as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    """A run of 1024 steps with checkpoints at 512 and 1024, and a pristine copy of it."""
    runs = tmp_path_factory.mktemp("runs")
    train.main(["--algo", "ppo", "--set", *BUDGET[:2], "--set", *BUDGET[2:], *OPTIONS, "--runs", str(runs),
                "--run-name", "base"])
    shutil.copytree(runs / "base", runs / "pristine")
    return runs


def test_a_run_records_every_set_option(finished_run):
    run = finished_run / "pristine"
    assert json.loads((run / "args.json").read_text())["set"] == BUDGET
    cfg = (run / "config.yaml").read_text()
    assert "total_timesteps: 1024" in cfg and "n_steps: 128" in cfg and "n_epochs: 1" in cfg


def test_resuming_from_the_last_checkpoint_extends_the_history(finished_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(finished_run / "pristine", run)
    before_rows, before = monitor_rows(run), evaluations(run)
    assert list(before["timesteps"]) == [512, 1024] and before_rows
    train.main(["--resume", str(run / "checkpoints" / "model_1024_steps.zip"), "--set", "total_timesteps=1536",
                "--no-progress"])
    rows, after = monitor_rows(run), evaluations(run)
    assert rows[:len(before_rows)] == before_rows and len(rows) > len(before_rows)  # appended, not truncated
    times = [float(r.split(",")[2]) for r in rows]
    assert times == sorted(times)  # "t" keeps counting from the run's first start
    assert list(after["timesteps"]) == [512, 1024, 1536]
    np.testing.assert_array_equal(after["results"][:2], before["results"])
    status = json.loads((run / "status.json").read_text())
    assert (status["status"], status["timesteps"]) == ("finished", 1536)
    commands = (run / "command.txt").read_text().splitlines()
    assert len(commands) == 2 and "--resume" in commands[1]
    assert json.loads((run / "args.json").read_text())["set"] == BUDGET + ["total_timesteps=1536"]
    assert (run / "checkpoints" / "model_vecnormalize_1536_steps.npz").is_file()


def test_resuming_from_an_earlier_checkpoint_replaces_what_followed_it(finished_run, tmp_path):
    """Rows and evaluations after the checkpoint belong to training the resumed run replaces."""
    run = tmp_path / "run"
    shutil.copytree(finished_run / "pristine", run)
    before_rows, before = monitor_rows(run), evaluations(run)
    kept = json.loads((run / "checkpoints" / "model_history_512_steps.json").read_text())["monitor_rows"]
    assert 0 < kept < len(before_rows)
    train.main(["--resume", str(run / "checkpoints" / "model_512_steps.zip"), "--no-progress"])
    rows, after = monitor_rows(run), evaluations(run)
    assert rows[:kept] == before_rows[:kept] and len(rows) > kept
    assert list(after["timesteps"]) == [512, 1024]
    np.testing.assert_array_equal(after["results"][:1], before["results"][:1])
    assert sorted(p.name for p in (run / "checkpoints").glob("model_*_steps.zip")) == [
        "model_1024_steps.zip", "model_512_steps.zip"]  # on the run's step grid, not 512 + 512 k + 1


def test_a_run_that_fails_after_starting_is_marked_failed(tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("reference episodes broke")

    monkeypatch.setattr(train, "evaluate_policy", broken)
    with pytest.raises(RuntimeError, match="reference episodes broke"):
        train.main(["--set", *BUDGET, *OPTIONS, "--runs", str(tmp_path), "--run-name", "broken"])
    status = json.loads((tmp_path / "broken" / "status.json").read_text())
    assert status["status"] == "failed" and "reference episodes broke" in status["error"]
