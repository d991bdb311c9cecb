"""The Ray scripts' arguments (agents.distributed.train and .sweep, agents.team.train and
agents.team.sweep): bad input is one line naming the argument, with exit status 2, before anything
is written or a cluster is joined; and the sweeps' spaces. No cluster: these run with the others
(tests/test_ray.py starts one). Each script's main runs here (tests/script_main.py), but for one
case per script that runs ``python -m`` in a subprocess."""
import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

from agents.distributed.cluster import free_port
from agents.distributed.sweep import parse_space
from script_main import call_main

ROOT = Path(__file__).resolve().parent.parent


def run(module, *args, timeout=120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", module, *map(str, args)], capture_output=True, text=True, cwd=ROOT,
                          timeout=timeout, env={**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"})


#: The case of each script run by ``python -m`` in a subprocess: one that reaches its settings' checks.
END_TO_END = {("agents.distributed.train", "--set", "env_kwargs.wnd=3"),
              ("agents.distributed.sweep", "--set", "residual=lqg"),
              ("agents.team.train", "--task", "lower"),
              ("agents.team.sweep", "--space", '{"minibatch_size": [1000, 100000]}')}


CASES = [
    ("agents.distributed.train", ["--address", "127.0.0.1:{port}"], ["--address", "127.0.0.1:{port}"]),
    ("agents.distributed.train", ["--address", "nohostport"], ["--address", "HOST:PORT"]),
    ("agents.distributed.train", ["--task", "balance"], ["--task", "balance"]),
    ("agents.distributed.train", ["--set", "env_kwargs.wnd=3"], ["--set", "'env_kwargs.wnd'", "wind"]),
    ("agents.distributed.train", ["--set", "lr_rate=3"], ["--set", "'lr_rate'", "lr"]),
    ("agents.distributed.train", ["--set", "env_kwargs.observation=eyes"], ["--set", "observation"]),
    ("agents.distributed.sweep", ["--space", '{"learning_rat": [1e-4]}'], ["--space", "'learning_rat'", "learning_rate"]),
    ("agents.distributed.sweep", ["--space", '{"env_kwargs.randomize": [{"EA": [2, 1]}]}'], ["--space", "env_kwargs.randomize"]),
    ("agents.distributed.sweep", ["--space", '{"seed": [-1]}'], ["--space", "seed"]),
    ("agents.distributed.sweep", ["--space", '{"n_steps": 64}'], ["--space", "n_steps", "list"]),
    ("agents.distributed.sweep", ["--space", '{"seed": [0]}', "--address", "127.0.0.1:{port}"], ["--address"]),
    # what every trial would fail on is found before the cluster starts
    ("agents.distributed.sweep", ["--set", "residual=lqg", "--space", '{"seed": [0, 1]}'], ["--set", "'lqg'", "hook"]),
    ("agents.distributed.sweep", ["--space", '{"residual": ["lqg"]}'], ["--space", "'residual' = 'lqg'", "hook"]),
    ("agents.distributed.sweep", ["--space", '{"n_envs": [100000000]}'], ["--space", "num_envs = 100000000", "GiB"]),
    ("agents.team.train", ["--team", "7"], ["--team", "1 to 6"]),
    ("agents.team.train", ["--set", "lr_rate=3"], ["--set", "'lr_rate'"]),
    ("agents.team.train", ["--time-limit", "0"], ["--time-limit"]),
    ("agents.team.train", ["--residual", "--residual-scale", "-1"], ["--residual-scale"]),
    ("agents.team.train", ["--task", "lower"], ["--task", "lower"]),
    ("agents.team.sweep", ["--space", '{"lr": ["fast"]}'], ["--space", "lr"]),
    ("agents.team.sweep", ["--space", '{"lr_rate": [0.1]}'], ["--space", "'lr_rate'"]),
    ("agents.team.sweep", ["--space", '{"seed": [0]}', "--set", "minibatch_size=100000"], ["--set", "minibatch_size"]),
    ("agents.team.sweep", ["--space", '{"minibatch_size": [1000, 100000]}'], ["--space", "'minibatch_size' = 100000"]),
    ("agents.team.sweep", ["--team", "7", "--space", '{"seed": [0]}'], ["--team", "1 to 6"]),
    ("agents.team.sweep", ["--space", '{"seed": [0]}', "--address", "127.0.0.1:{port}"], ["--address"]),
]


@pytest.mark.parametrize("module, args, names", CASES)
def test_bad_input_is_one_line_naming_the_argument_and_writes_nothing(tmp_path, capfd, module, args, names):
    port = str(free_port())  # nothing listens there
    fill = [a.replace("{port}", port) for a in args]
    out = ["--runs", tmp_path / "runs"] if module in ("agents.distributed.train", "agents.team.train") else ["--out", tmp_path / "sweep"]
    if (module, *args[:2]) in END_TO_END:
        proc = run(module, *fill, *out, timeout=120)
    else:
        proc = call_main(importlib.import_module(module).main, [*fill, *out], capfd)
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr[-3000:]
    for name in names:
        assert name.replace("{port}", port) in lines[0], lines[0]
    assert list(tmp_path.iterdir()) == []


def test_each_script_has_one_case_in_a_subprocess():
    alone = [module for module, args, _ in CASES if (module, *args[:2]) in END_TO_END]
    assert sorted(alone) == sorted({module for module, *_ in CASES})


def test_a_space_key_may_complete_what_the_base_settings_lack():
    """The base --set alone is no trial: a residual that needs the hook observation is fine where
    every trial of the space sets it (each value is checked with the others' first values)."""
    from agents.distributed.sweep import Settings, check_space

    s = Settings(set=["residual=lqg"], task="stabilize")
    check_space({"env_kwargs.preset": ["hard"], "seed": [0, 1]}, s)
    with pytest.raises(ValueError, match="'env_kwargs.observation' = 'full'.*hook"):
        check_space({"env_kwargs.observation": ["hook", "full"]}, s)


def test_a_sweep_space_is_a_mapping_of_lists():
    assert parse_space('{"learning_rate": [1e-4, 3e-4], "seed": [0]}') == {"learning_rate": [1e-4, 3e-4], "seed": [0]}
    assert parse_space("{env_kwargs.randomize: [false, true]}") == {"env_kwargs.randomize": [False, True]}
    for bad in ("[1, 2]", "{}", '{"seed": []}', "{a: [1}"):
        with pytest.raises(ValueError):
            parse_space(bad)


#: Settings refused before Ray starts (issue 54): each used to be ignored, accepted, or found
#: after Ray had started (a run directory the process cannot create, runners the machine cannot host).
#: No process creates files in /proc, root's included (file modes do not stop root).
BEFORE_RAY = [
    ("agents.team.train", ["--residual-scale", "0.5"], ["--residual-scale", "--residual"]),
    ("agents.team.train", ["--residual", "--residual-scale", "1e300"], ["--residual-scale", "1e+300"]),
    ("agents.team.train", ["--set", "lr=-1"], ["--set", "lr", "-1"]),
    ("agents.team.train", ["--set", "gamma=1.5"], ["--set", "gamma", "1.5"]),
    ("agents.team.train", ["--set", "num_env_runners=100000"], ["--set", "num_env_runners", "100000", "CPUs"]),
    ("agents.team.train", ["--runs", "/proc/runs"], ["--runs", "/proc"]),
    # an option combination the team env refuses: it used to build PPO for 30 s, then fail in RLlib
    ("agents.team.train", ["--actuation", "thrust_rates", "--task", "lift"],
     ["--task lift", "--actuation thrust_rates", "do not reel"]),
    ("agents.distributed.train", ["--set", "num_env_runners=100000"], ["--set", "num_env_runners", "CPUs"]),
    ("agents.distributed.train", ["--runs", "/proc/runs"], ["--runs", "/proc"]),
]


@pytest.mark.parametrize("module, args, names", BEFORE_RAY)
def test_settings_are_refused_before_ray_starts(monkeypatch, tmp_path, capfd, module, args, names):
    import agents.distributed.train as distributed_train

    def no_ray(address):
        raise AssertionError("Ray was joined before the settings were refused")

    monkeypatch.setattr(distributed_train, "connect", no_ray)
    runs = [] if "--runs" in args else ["--runs", tmp_path / "runs"]
    proc = call_main(importlib.import_module(module).main, [*args, *runs, "--no-progress"], capfd)
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr[-3000:]
    for name in names:
        assert name in lines[0], lines[0]
    assert list(tmp_path.iterdir()) == []


def test_a_residual_scale_within_the_box_is_accepted(tmp_path):
    """The negative control of the refusals above: a residual scale of 2 (the box's width: a
    residual can take any command to either end) with the config file's runners and rates and a
    writable --runs passes every check; a scale above 2 is refused."""
    from agents.cli import SettingsError
    from agents.team.train import Settings, check_settings

    check_settings(Settings(residual=True, residual_scale=2.0, runs=str(tmp_path)))
    with pytest.raises(SettingsError, match="--residual-scale"):
        check_settings(Settings(residual=True, residual_scale=2.5, runs=str(tmp_path)))


@pytest.mark.parametrize("actuation", [None, "thrust_rates", "motors"])
def test_team_sweep_passes_the_actuation_to_each_trial(actuation):
    """agents.team.sweep --actuation reaches each trial's agents.team.train settings, its saved
    command line and the environment its config builds, with agents.team.train's choices (it had
    no --actuation). None, point pivots, is the negative control: no --actuation anywhere."""
    import dataclasses

    from agents.team import sweep as team_sweep, train as team_train

    choices = {f.name: f.metadata.get("choices") for f in dataclasses.fields(team_train.Settings)}["actuation"]
    assert sorted(team_sweep.DRONE_ACTUATIONS) == sorted(choices)
    s = team_sweep.Settings(team=2, task="track", actuation=actuation)
    ts = team_sweep.trial_settings(s, {"seed": 1}, Path("runs"), "trial")
    argv = team_sweep.trial_argv(ts)
    assert ts.actuation == actuation and team_train.env_options(ts).get("actuation") == actuation
    assert (argv[argv.index("--actuation") + 1] if "--actuation" in argv else None) == actuation
    assert "actuation" in team_sweep.SWEEP_SETTINGS  # a resumed sweep keeps it
    team_sweep.check_trial(s, {})  # RLlib's validation of the trial's config, no Ray started
