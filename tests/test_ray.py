"""RLlib training and Tune sweeps on a real two-node Ray cluster on this machine (loopback): a head
and a worker node, one CPU each, with their own temporary directories. The env runners and the
trials must run on both nodes, the runs must leave checkpoints and results, an interrupted sweep
must resume its trials from their checkpoints, and the cluster's processes must all be gone
afterwards (stopped by process id, failures included). Bad input: tests/test_ray_arguments.py.
"""
import csv
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil
import pytest

from agents.distributed.cluster import LocalCluster

ROOT = Path(__file__).resolve().parent.parent
#: An RLlib run of a few seconds: 2 runners x 4 environments, 512 steps per iteration.
RLLIB_TINY = ["num_env_runners=2", "num_envs_per_env_runner=4", "train_batch_size_per_learner=512",
              "minibatch_size=256", "num_epochs=1"]
#: agents.train runs of a few seconds, checkpointed every 128 steps.
SB3_TINY = ["n_envs=2", "n_steps=64", "batch_size=64", "n_epochs=1", "policy_kwargs.net_arch=[16]"]
SB3_OPTIONS = ["--episodes", "1", "--eval-freq", "128", "--eval-episodes", "1", "--reference-episodes", "1",
               "--checkpoint-freq", "128"]


def child_env(env=None) -> dict:
    """A command's environment: ours with one thread for numba and OpenMP, and ``env``."""
    return {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", **(env or {})}


def run(module, *args, env=None, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", module, *map(str, args)], capture_output=True, text=True, cwd=ROOT,
                          timeout=timeout, env=child_env(env))


def sampling_nodes(training: dict) -> set:
    """The nodes whose env runners sampled environment steps (training.json of agents.distributed.train)."""
    return {r["node_id"] for r in training["env_runners"] if r["env_steps"] > 0}


class FlakyCluster(LocalCluster):
    """A local cluster whose node ``i``'s attempt ``a`` runs a command that exits at once, for
    each ``(i, a)`` in ``fail``."""

    EXITS = "import sys; print('raylet did not register'); sys.exit(1)"
    HANGS = "import time; print('raylet hangs', flush=True); time.sleep(600)"

    def __init__(self, fail: set, failure: str = EXITS, **kwargs):
        self.fail, self.failure, self.tries = fail, failure, {}
        super().__init__(**kwargs)

    def node_command(self, index, temp):
        attempt = self.tries[index] = self.tries.get(index, -1) + 1
        if (index, attempt) in self.fail:
            return [sys.executable, "-c", self.failure]
        return super().node_command(index, temp)


@pytest.fixture(scope="module")
def cluster():
    """A head and a worker node, the worker started again after a failed first attempt;
    afterwards, no process of theirs is left."""
    with FlakyCluster(fail={(1, 0)}, nodes=2, cpus=1) as c:
        assert c.tries == {0: 0, 1: 1} and [log.name for log in c.logs] == ["n0.log", "n1.1.log"]
        started = [p.pid for p in c.processes()]
        yield c
    alive = [pid for pid in started if psutil.pid_exists(pid) and psutil.Process(pid).status() != psutil.STATUS_ZOMBIE]
    assert alive == [], f"processes of the cluster still running: {alive}"


def test_rllib_ppo_samples_on_both_nodes_and_checkpoints(cluster, tmp_path):
    proc = run("agents.distributed.train", "--task", "stabilize", "--iterations", "2", "--address", cluster.address,
               "--runs", tmp_path, "--run-name", "r", "--checkpoint-every", "1", "--eval-episodes", "1",
               "--reference-episodes", "1", "--no-progress", "--set", *RLLIB_TINY, env=cluster.env)
    assert proc.returncode == 0, proc.stderr[-4000:]
    run_dir = tmp_path / "r"
    assert json.loads((run_dir / "status.json").read_text())["status"] == "finished"
    training = json.loads((run_dir / "training.json").read_text())
    nodes = {n["node_id"] for n in training["nodes"]}
    assert len(nodes) == 2
    # both nodes sampled: one runner each (one CPU per node), and together at least what was trained on
    assert sampling_nodes(training) == nodes
    assert sum(r["env_steps"] for r in training["env_runners"]) >= training["timesteps"] >= 2 * 512
    with open(run_dir / "progress.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["iteration"]) for r in rows] == [1, 2]
    assert int(rows[1]["env_steps"]) > int(rows[0]["env_steps"]) >= 512
    for ckpt in (run_dir / "checkpoints" / "iteration_1", run_dir / "checkpoint"):
        assert (ckpt / "rllib_checkpoint.json").is_file(), ckpt
    evaluation = json.loads((run_dir / "evaluation.json").read_text())
    assert evaluation["episodes"] == 1 and 0 <= evaluation["mean_return"] <= 500  # the reward is in [0, 1] per step
    for name in ("config.yaml", "args.json", "command.txt", "references.json", "learning_curve.png"):
        assert (run_dir / name).is_file(), name
    # negative control: a runner that sampled nothing does not count its node
    assert sampling_nodes({"env_runners": [{"node_id": "a", "env_steps": 5}, {"node_id": "b", "env_steps": 0}]}) == {"a"}


def start(module, *args, env=None) -> tuple:
    """:func:`run`'s command started, not waited for (runs that sample in their own processes at
    once): its Popen, its output going to two temporary files (a pipe left unread would stall it)."""
    out, err = tempfile.TemporaryFile("w+"), tempfile.TemporaryFile("w+")
    proc = subprocess.Popen([sys.executable, "-m", module, *map(str, args)], stdout=out, stderr=err, text=True,
                            cwd=ROOT, env=child_env(env))
    return proc, out, err


def finished(started: dict, timeout=300) -> dict:
    """Each of ``started`` (:func:`start`'s by name) waited for: its ``(returncode, stdout, stderr)``."""
    results = {}
    try:
        for name, (proc, out, err) in started.items():
            proc.wait(timeout=timeout)
            out.seek(0), err.seek(0)
            results[name] = (proc.returncode, out.read(), err.read())
    finally:
        for proc, out, err in started.values():
            if proc.poll() is None:
                proc.kill()
            out.close(), err.close()
    return results


#: The team trainings' variants: (--residual, --central-critic) by name.
TEAM_VARIANTS = {"central-critic": (False, True), "residual": (True, False)}


def test_a_team_trains_with_one_shared_policy_and_checkpoints(cluster, tmp_path):
    """agents.team.train: RLlib PPO on the PettingZoo team, one module for every agent (with
    --residual, on the team's LQR: the checkpoint says so and the compare adds the LQR; with
    --central-critic, the critic reads the team's state: the checkpoint says so and the compare
    acts without it). The two variants' runs sample in their own processes (no env runners), so
    they run at the same time, one per CPU."""
    trainings = finished({
        name: start("agents.team.train", "--team", "2", "--task", "transport", "--iterations", "2", "--address",
                    cluster.address, "--runs", tmp_path / name, "--run-name", "t", "--eval-episodes", "1",
                    "--reference-episodes", "1", "--no-progress", *(["--residual"] if residual else []),
                    *(["--central-critic"] if critic else []), "--set",
                    "num_env_runners=0", "train_batch_size_per_learner=200", "minibatch_size=100", "num_epochs=1",
                    env=cluster.env)
        for name, (residual, critic) in TEAM_VARIANTS.items()})
    compares, evaluations = {}, {}
    for name, (residual, critic) in TEAM_VARIANTS.items():
        returncode, _, stderr = trainings[name]
        assert returncode == 0, (name, stderr[-4000:])
        run_dir = tmp_path / name / "t"
        assert json.loads((run_dir / "status.json").read_text())["status"] == "finished"
        with open(run_dir / "progress.csv") as fh:
            rows = list(csv.DictReader(fh))
        assert [int(r["iteration"]) for r in rows] == [1, 2] and int(rows[1]["env_steps"]) >= 400
        assert (run_dir / "checkpoint" / "learner_group" / "learner" / "rl_module" / "shared").is_dir()
        assert (run_dir / "checkpoint" / "residual.json").is_file() == residual
        assert (run_dir / "checkpoint" / "central_critic.json").is_file() == critic
        refs = json.loads((run_dir / "references.json").read_text())
        assert refs["baseline_return"] > 300.0 > 50.0 > refs["zero_return"]  # the team's LQR, the zero action
        evaluation = evaluations[name] = json.loads((run_dir / "evaluation.json").read_text())
        assert evaluation["episodes"] == 1 and -100.0 <= evaluation["mean_return"] <= 500.0
        if residual:  # two iterations move the LQR by a little: the team still carries the load
            assert evaluation["mean_return"] > 200.0
        for file in ("config.yaml", "args.json", "command.txt", "training.json", "learning_curve.png"):
            assert (run_dir / file).is_file(), (name, file)
        # the checkpoint (with --residual: as shipped) as agents.compare's team policy, paired with the
        # baseline; its first episode is the run's own evaluation's (seed 10000)
        checkpoint = run_dir / "checkpoint"
        if residual or critic:
            from agents.team.train import ship

            checkpoint = ship(run_dir, tmp_path / name / "model") / "checkpoint"
            assert (checkpoint / "central_critic.json").is_file() == critic
        compares[name] = start("agents.compare", "--team", "2", "--task", "transport", "--episodes", "2", "--seed",
                               "10000", "--model", checkpoint, "--json", "--no-progress")
    for name, (returncode, stdout, stderr) in finished(compares).items():
        assert returncode == 0, (name, stderr[-4000:])
        c = json.loads(stdout)
        assert c["best_baseline"] == "lqr" and len(c["policies"]["policy"]["returns"]) == 2 and c["paired_ci95"]
        assert c["policies"]["policy"]["returns"][0] == pytest.approx(evaluations[name]["mean_return"], abs=1e-9)


def _wait_for(predicate, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > end:
            raise TimeoutError(f"waited {timeout} s for {what}")
        time.sleep(0.2)


def interrupt_sweep(module: str, args: list, cluster, ready, what: str) -> list:
    """Run the sweep ``module`` with ``args``, Ctrl-C it once ``ready()`` (or once it ends: Tune
    saves its state and stops), and return its two trials' run directories."""
    sweep = subprocess.Popen([sys.executable, "-m", module, *map(str, args)], cwd=ROOT, env=child_env(cluster.env),
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _wait_for(lambda: ready() or sweep.poll() is not None, 240, what)
        sweep.send_signal(signal.SIGINT)
        sweep.communicate(timeout=120)
    finally:
        if sweep.poll() is None:
            sweep.kill()
    runs = sorted((Path(args[args.index("--out") + 1]) / "runs").iterdir())
    assert len(runs) == 2
    return runs


def test_tune_sweep_runs_on_both_nodes_and_resumes_after_interruption(cluster, tmp_path):
    out = tmp_path / "sweep"
    args = ["--task", "stabilize", "--space", '{"seed": [0, 1]}', "--out", out, "--address", cluster.address,
            *SB3_OPTIONS, "--set", *SB3_TINY, "total_timesteps=6000"]
    # interrupted once every trial has a checkpoint
    runs = interrupt_sweep("agents.distributed.sweep", args, cluster,
                           lambda: len(list(out.glob("runs/*/checkpoints/model_*_steps.zip"))) >= 2,
                           "both trials to checkpoint")
    statuses = {r: json.loads((r / "status.json").read_text())["status"] for r in runs}
    assert set(statuses.values()) <= {"interrupted", "finished"}, statuses
    # Tune stops a trial at its next progress report (every 128 steps), not at its end
    interrupted = [r for r in runs if statuses[r] == "interrupted"]
    assert interrupted, "the sweep finished before the interruption: nothing to resume"
    with open(out / "results.csv") as fh:  # a stopped trial's row: no evaluation, says why
        stopped_rows = [r for r in csv.DictReader(fh) if r["mean_return"] == ""]
    assert len(stopped_rows) == len(interrupted) and all("did not finish" in r["error"] for r in stopped_rows)

    resumed = run("agents.distributed.sweep", "--resume", out, "--address", cluster.address, env=cluster.env)
    assert resumed.returncode == 0, resumed.stderr[-4000:]
    with open(out / "results.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert sorted(int(r["seed"]) for r in rows) == [0, 1]
    for row in rows:
        run_dir = Path(row["run_dir"])
        assert json.loads((run_dir / "status.json").read_text())["status"] == "finished"
        assert int(row["timesteps"]) >= 6000 and 0 <= float(row["mean_return"]) <= 500
        assert (run_dir / "model.zip").is_file() and (run_dir / "evaluation.json").is_file()
    for run_dir in interrupted:  # resumed from a checkpoint: a second command, not a fresh run
        assert len((run_dir / "command.txt").read_text().splitlines()) == 2
        assert "--resume" in (run_dir / "command.txt").read_text().splitlines()[1]
    assert len({r["node_id"] for r in rows}) == 2  # the two one-CPU trials ran at once, one on each node
    for name in ("results.md", "results.png"):
        assert (out / name).is_file()


def _progress_rows(run_dir: Path) -> int:
    path = run_dir / "progress.csv"
    return max(0, len(path.read_text().splitlines()) - 1) if path.is_file() else 0


def test_a_team_sweep_runs_its_trials_on_both_nodes_and_restarts_them_after_interruption(cluster, tmp_path):
    """agents.team.sweep: each trial an agents.team.train run directory (sampling in the trial's
    own process), one per node at once; interrupted (Ctrl-C) while both train, then resumed, the
    unfinished trials start again from scratch and finish, and the results are gathered into
    results.{csv,md,png}."""
    out = tmp_path / "team_sweep"
    iterations = 12
    args = ["--team", "2", "--task", "track", "--iterations", iterations, "--space", '{"seed": [0, 1], "lr": [0.0003]}',
            "--out", out, "--address", cluster.address, "--eval-episodes", "1", "--reference-episodes", "1", "--set",
            "train_batch_size_per_learner=100", "minibatch_size=50", "num_epochs=1"]
    # interrupted once both trials have trained an iteration (measured: 2 and 3 done then, of 25 asked)
    runs = interrupt_sweep("agents.team.sweep", args, cluster,
                           lambda: sum(_progress_rows(r) >= 1 for r in (out / "runs").glob("*")) >= 2,
                           "both trials to train")
    stopped = [r for r in runs if json.loads((r / "status.json").read_text())["status"] != "finished"]
    assert stopped, "the sweep finished before the interruption: nothing to restart"

    resumed = run("agents.team.sweep", "--resume", out, "--address", cluster.address, env=cluster.env)
    assert resumed.returncode == 0, resumed.stderr[-4000:]
    with open(out / "results.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert sorted(int(r["seed"]) for r in rows) == [0, 1]
    for row in rows:
        run_dir = Path(row["run_dir"])
        assert json.loads((run_dir / "status.json").read_text())["status"] == "finished"
        assert (run_dir / "checkpoint" / "learner_group" / "learner" / "rl_module" / "shared").is_dir()
        with open(run_dir / "progress.csv") as fh:  # from scratch: one run of every iteration
            assert [int(r["iteration"]) for r in csv.DictReader(fh)] == list(range(1, iterations + 1))
        evaluation = json.loads((run_dir / "evaluation.json").read_text())
        assert evaluation["episodes"] == 1 and float(row["mean_return"]) == evaluation["mean_return"]
        command = (run_dir / "command.txt").read_text()
        assert "agents.team.train" in command and "num_env_runners=0" in command and "lr=0.0003" in command
        assert len(command.splitlines()) == 1
    assert len({r["node_id"] for r in rows}) == 2  # the two one-CPU trials ran at once, one on each node
    for name in ("results.md", "results.png", "sweep.json"):
        assert (out / name).is_file()


def test_a_node_that_fails_to_start_every_time_is_an_error_quoting_its_last_attempt():
    # (that a failed attempt is followed by one that starts: the cluster fixture's worker)
    flaky = FlakyCluster(fail={(0, 0), (0, 1)}, nodes=1, cpus=1, attempts=2)
    with pytest.raises(RuntimeError, match=r"(?s)node 0 exited \(1\) 2 times in all.*n0\.1\.log.*raylet did not register"):
        flaky.__enter__()
    assert not flaky.root.exists()
    # one that hangs is ended after the timeout and started again; every time, an error too
    hanging = FlakyCluster(fail={(0, 0), (0, 1)}, failure=FlakyCluster.HANGS, nodes=1, cpus=1, attempts=2, timeout=1)
    with pytest.raises(RuntimeError, match=r"(?s)did not start within 1 s 2 times in all.*raylet hangs"):
        hanging.__enter__()
    assert all(p.poll() is not None for p in hanging.procs)
    with pytest.raises(ValueError, match="attempts=0"):
        LocalCluster(attempts=0)
