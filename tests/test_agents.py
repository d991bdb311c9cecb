"""Agents: the training script end to end on a tiny budget, evaluation, the baselines and the
shipped policy."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from agents.common import load_run_config
from agents.baselines.pd import ZeroPolicy
from agents.evaluate import SB3Policy, evaluate_policy
from esp_gym.pendulum.tasks import TASKS
from script_main import call_main

ROOT = Path(__file__).resolve().parent.parent

SHIPPED = ROOT / "models" / "stabilize_ppo" / "model.zip"


@pytest.mark.parametrize("algo, budget", [
    ("ppo", ["total_timesteps=1024", "n_envs=4", "n_steps=128", "batch_size=256", "n_epochs=2"]),
    # SAC takes a gradient step per environment step from learning_starts on: 250 of them, which
    # on the configured networks (256 x 256, batches of 256) were 90 % of the run (~70 CPU s)
    ("sac", ["total_timesteps=600", "n_envs=2", "learning_starts=100", "buffer_size=2000", "batch_size=32",
             "policy_kwargs.net_arch=[16]"]),
])
def test_training_smoke_writes_a_loadable_run(tmp_path, algo, budget):
    cmd = [sys.executable, "-m", "agents.train", "--algo", algo, "--set", *budget,
           "--eval-freq", "512", "--eval-episodes", "1", "--checkpoint-freq", "512", "--reference-episodes", "1",
           "--runs", str(tmp_path), "--run-name", "smoke", "--no-progress"]
    scratch = tmp_path / "tmp"  # the run's temporary directory: SB3 left an empty SB3-* there per run
    scratch.mkdir()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900, cwd=ROOT,
                          env={**os.environ, "TMPDIR": str(scratch)})
    assert proc.returncode == 0, proc.stderr[-3000:]
    run = tmp_path / "smoke"
    for name in ("model.zip", "vecnormalize.npz", "config.yaml", "args.json", "command.txt", "monitor.csv",
                 "evaluations.npz", "learning_curve.png", "references.json", "training.json", "status.json",
                 "progress.csv"):
        assert (run / name).is_file(), name
    if algo == "ppo":  # SB3 writes a row per PPO update (SAC's after every 4th episode: none here)
        assert "time/total_timesteps" in (run / "progress.csv").read_text().splitlines()[0]
    assert not list(scratch.glob("SB3-*"))
    assert json.loads((run / "status.json").read_text())["status"] == "finished"
    assert list((run / "checkpoints").glob("model_*_steps.zip"))
    assert not list(run.rglob("*.pkl"))  # normalisation statistics are data (.npz), not pickles
    policy = SB3Policy(run / "model.zip")
    assert policy.normalization is not None
    stats = evaluate_policy(policy, episodes=1, seed=0)
    assert np.isfinite(stats["mean_return"])


def test_unknown_hyper_parameter_is_named():
    with pytest.raises(ValueError, match="learning_rat"):
        load_run_config("ppo", "ElasticStringPendulum-v0", "stabilize", ["learning_rat=0.1"])
    with pytest.raises(ValueError, match="KEY=VALUE"):
        load_run_config("ppo", "ElasticStringPendulum-v0", "stabilize", ["n_envs"])


# margins: about half the gain measured on these seeds (track: +43 over 8 episodes, the PD law
# without feed-forward; stabilize +327 and transport +223 over 4)
@pytest.mark.parametrize("task, episodes, margin", [("stabilize", 4, 50), ("transport", 4, 50), ("track", 8, 20)])
def test_baseline_beats_the_zero_action(task, episodes, margin):
    base = evaluate_policy(None, task=task, episodes=episodes, seed=123)
    zero = evaluate_policy(ZeroPolicy(), task=task, episodes=episodes, seed=123)
    assert base["mean_return"] > zero["mean_return"] + margin


def test_evaluate_cli_prints_one_json_line():
    proc = subprocess.run([sys.executable, "-m", "agents.evaluate", "--policy", "zero",
                           "--episodes", "2", "--seed", "3"], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert len(lines) == 1
    stats = json.loads(lines[0])
    assert {"mean_return", "std_return", "success_rate", "mean_final_swing_deg"} <= set(stats)


def test_shipped_policy_loads_and_stabilizes():
    """The shipped policy (with its VecNormalize statistics) runs seeded episodes to the time limit
    and brings the load to rest: far above the zero action's ~165 (the 100-episode comparison
    with the baselines is agents/compare.py, quoted in the README)."""
    assert SHIPPED.is_file() and (SHIPPED.parent / "vecnormalize.npz").is_file()
    policy = SB3Policy(SHIPPED)
    assert policy.normalization is not None
    stats = evaluate_policy(policy, episodes=3, seed=777)
    assert stats["mean_return"] > 420 and stats["success_rate"] == 1.0


def test_task_figures_rollout_is_the_evaluated_episode(tmp_path):
    """The figure's episode is the one agents.evaluate scores (same seed, same return), and the
    script writes one figure per task."""
    from agents import task_figures
    from agents.baselines.registry import baseline

    run = task_figures.rollout("stabilize", baseline("stabilize"), seed=7, steps=10_000)
    assert run["return"] == evaluate_policy(None, task="stabilize", episodes=1, seed=7)["mean_return"]
    assert run["pivot"].shape == run["load_target"].shape == (len(run["time"]), 3)
    results = task_figures.main(["--out", str(tmp_path), "--steps", "5"])
    assert sorted(results) == sorted(TASKS)
    for task in results:
        assert (tmp_path / f"task_{task}.png").stat().st_size > 10_000


def test_the_drone_figure_is_the_geometric_cascades_evaluated_episode(tmp_path):
    """``--drone``: quadrotor_load's transport under the geometric cascade, the episode
    agents.evaluate scores, with the drone's attitude recorded at every step."""
    from agents import task_figures
    from agents.baselines.geometric import geometric_controller

    kw = {"scene": "quadrotor_load", "actuation": "thrust_rates"}
    run = task_figures.rollout("transport", geometric_controller("transport"), seed=3, steps=10_000, env_kwargs=kw)
    assert run["return"] == evaluate_policy(geometric_controller("transport"), task="transport", episodes=1, seed=3,
                                            env_kwargs=kw)["mean_return"]
    assert run["attitude"].shape == (len(run["time"]), 3)
    results = task_figures.main(["--out", str(tmp_path), "--steps", "5", "--drone"])
    assert list(results) == ["drone_transport"] and (tmp_path / "drone_transport.png").stat().st_size > 10_000


def test_the_hard_lift_figure_draws_the_evaluated_episodes_of_the_hoist_and_the_policy(tmp_path):
    """``--hard-lift``: the hard preset's lift under the hoist and the shipped policy, each the
    episode agents.evaluate scores; without a model file only the hoist is drawn."""
    from agents import task_figures
    from agents.baselines.registry import baselines

    kw = {"preset": "hard"}
    results = task_figures.main(["--out", str(tmp_path), "--steps", "500", "--hard-lift", "--seed", "5"])
    assert sorted(results) == ["lift_hard_hoist", "lift_hard_policy"]
    assert results["lift_hard_hoist"]["return"] == evaluate_policy(baselines("lift", kw)["pd"], task="lift",
                                                                   episodes=1, seed=5, env_kwargs=kw)["mean_return"]
    assert (tmp_path / "lift_hard.png").stat().st_size > 10_000
    alone = task_figures.main(["--out", str(tmp_path), "--steps", "5", "--hard-lift", "--model",
                               str(tmp_path / "absent.zip")])
    assert list(alone) == ["lift_hard_hoist"]


def test_the_team_figure_draws_the_evaluated_team_episode(tmp_path):
    """``--team K --team-task T``: team_T.png, the episode agents.team.evaluate scores under the
    team's LQR (the lift's under its hoist); a task a team does not have is one line naming the
    argument."""
    from agents import task_figures
    from agents.team.evaluate import TeamHoistPolicy, TeamLQRPolicy, run_team_episodes

    result = task_figures.main(["--out", str(tmp_path), "--team", "3", "--team-task", "track", "--seed", "4"])
    assert result["return"] == pytest.approx(run_team_episodes(TeamLQRPolicy(), 3, "track", 1, seed=4)[0].ret,
                                             rel=1e-12)
    assert (tmp_path / "team_track.png").stat().st_size > 10_000
    lifted = task_figures.main(["--out", str(tmp_path), "--team", "3", "--team-task", "lift", "--seed", "4"])
    assert lifted["return"] == pytest.approx(run_team_episodes(TeamHoistPolicy(), 3, "lift", 1, seed=4)[0].ret,
                                             rel=1e-12)
    with pytest.raises(SystemExit):
        task_figures.main(["--out", str(tmp_path), "--team", "3", "--team-task", "lower"])


def test_the_drone_team_figure_draws_the_evaluated_episode_under_the_cascade(tmp_path):
    """``--team K --team-actuation A``: team_drones_transport.png, the episode agents.team.evaluate
    scores under the drones' cascade (100 steps), BLAS on one thread as agents.team.evaluate runs
    it (the cascade's Riccati solution moves by ~1e-12 with the BLAS threads)."""
    from agents import task_figures
    from agents.evaluate import ONE_BLAS_THREAD
    from agents.team.evaluate import TeamCascadePolicy
    from esp_gym.team.env import ElasticStringTeamEnv

    result = task_figures.main(["--out", str(tmp_path), "--team", "3", "--team-actuation", "thrust_rates",
                                "--steps", "100"])

    @ONE_BLAS_THREAD
    def episode() -> float:
        env = ElasticStringTeamEnv(3, actuation="thrust_rates")
        obs, _ = env.reset(seed=3)
        policy, total = TeamCascadePolicy(), 0.0
        for _ in range(100):
            obs, reward, *_ = env.step(policy.act(obs, env.core))
            total += reward
        return total
    total = episode()
    assert result["return"] == pytest.approx(total, rel=1e-12)
    assert (tmp_path / "team_drones_transport.png").stat().st_size > 10_000


SHIPPED_POLICIES = sorted(p.parent for p in (ROOT / "models").glob("*_ppo/model.zip"))


@pytest.mark.parametrize("run", SHIPPED_POLICIES, ids=[p.name for p in SHIPPED_POLICIES])
def test_shipped_policies_beat_the_zero_action(run):
    """Every policy under models/ loads with its statistics, sits where agents.compare looks for
    its configuration (the one it was trained in: TASK[_SCENE][_ACTUATION][_PRESET]_ppo), and
    beats the zero action on 3 seeds of it. Margin 20: the smallest gap over 100 held-out episodes
    is hard transport's 47 (docs/compare; 43 on these seeds), the others 197-315."""
    from agents.compare import configuration_name

    policy = SB3Policy(run / "model.zip")
    task, env_kwargs = policy.configuration["task"], policy.configuration["env_kwargs"]
    assert run.name == configuration_name(task, *(env_kwargs.get(k) for k in ("preset", "scene", "actuation"))) + "_ppo"
    assert policy.normalization is not None
    trained = evaluate_policy(policy, task, 3, 4242, env_kwargs=env_kwargs)
    zero = evaluate_policy(ZeroPolicy(), task, 3, 4242, env_kwargs=env_kwargs)
    assert trained["mean_return"] > zero["mean_return"] + 20, (trained["mean_return"], zero["mean_return"])


def test_the_zoo_command_trains_ships_and_compares(tmp_path, capfd):
    """python -m agents.zoo --train --compare on one configuration and a tiny budget: the run
    ships its files to --models, and the comparison (written to --out, not to the docs) has the
    shipped model as its policy."""
    from agents.zoo import SHIPPED_FILES

    runs, models, out = tmp_path / "runs", tmp_path / "models", tmp_path / "compare"
    cmd = [sys.executable, "-m", "agents.zoo", "--train", "--compare", "--only", "stabilize", "--jobs", "2",
           "--no-progress", "--runs", str(runs), "--models", str(models), "--out", str(out), "--episodes", "2",
           "--set", "total_timesteps=1024", "n_envs=4", "n_steps=128", "batch_size=256", "n_epochs=2",
           "critic_warmup=256"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:] + (runs / "zoo_stabilize.log").read_text()[-3000:]
    shipped = models / "stabilize_ppo"
    # every file of a finished run but the evaluations, which a run this short never makes
    assert {p.name for p in shipped.iterdir()} == set(SHIPPED_FILES) - {"evaluations.npz"}
    assert "residual=lqr" in (shipped / "command.txt").read_text()
    result = json.loads((out / "compare_stabilize.json").read_text())
    assert result["model"] == str(shipped / "model.zip") and result["episodes"] == 2
    assert set(result["policies"]) == {"zero", "pd", "lqr", "policy"}
    from agents.zoo import main

    bad = call_main(main, ["--train", "--only", "stabilise"], capfd)  # python -m agents.zoo ran above
    assert bad.returncode == 2 and "--only" in bad.stderr and "'stabilise'" in bad.stderr


def test_time_limit_stops_training_and_saves(tmp_path):
    from agents.train import Settings, train

    run = train(Settings(runs=str(tmp_path), run_name="limited", progress=False, time_limit=0.02,
                         reference_episodes=1, set=["total_timesteps=10000000", "n_envs=2", "n_steps=64",
                                                    "batch_size=64", "n_epochs=1"]))
    summary = json.loads((run / "training.json").read_text())
    assert summary["stopped_by_time_limit"] and summary["timesteps"] < 10_000_000
    assert (run / "model.zip").is_file()
    assert json.loads((run / "status.json").read_text())["status"] == "finished"
