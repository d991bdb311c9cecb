"""agents/compare.py: the bootstrap interval of a paired difference covers the true one as often
as it claims on synthetic data, the comparison runs end to end on a tiny budget with the
issue's JSON interface, and a frame-stacked policy sees at evaluation what it saw in training."""
import json

import numpy as np
import pytest

from agents import compare
from script_main import call_main


def test_paired_ci_covers_a_known_difference():
    """Synthetic paired returns with a known mean difference 1.5: the 95 % interval covers it
    in 88-99 % of 200 draws of 40 pairs (binomial spread about 95 %), and with 400 pairs it
    excludes 0 (and a shifted truth 3.0: negative control)."""
    rng = np.random.default_rng(0)
    truth = 1.5
    covered = 0
    for _ in range(200):
        base = rng.normal(300.0, 40.0, 40)
        policy = base + truth + rng.normal(0.0, 3.0, 40)  # paired: the episodes' spread cancels
        low, high = compare.paired_ci(policy - base, resamples=2000, seed=1)
        covered += low <= truth <= high
    assert 0.88 <= covered / 200 <= 0.99
    d = truth + rng.normal(0.0, 3.0, 400)
    low, high = compare.paired_ci(d)
    assert 0.0 < low <= truth <= high < 3.0


def test_paired_ci_needs_two_pairs():
    with pytest.raises(ValueError, match="at least 2"):
        compare.paired_ci([1.0])
    assert compare.paired_ci([2.0, 2.0, 2.0]) == (2.0, 2.0)


def test_compare_prints_the_interface_json(capsys):
    """Tiny budget (2 episodes): zero, each baseline and the shipped stabilize policy, the best
    baseline by mean return and the paired difference with its interval."""
    c = compare.main(["--task", "stabilize", "--episodes", "2", "--json", "--no-progress"])
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads(json.dumps(c))
    assert {"task", "preset", "episodes", "policies", "best_baseline", "paired_diff_mean", "paired_ci95"} <= set(c)
    assert set(c["policies"]) == {"zero", "pd", "lqr", "policy"}
    for s in c["policies"].values():
        assert {"mean_return", "std_return", "success_rate", "mean_settling_time_s", "mean_peak_tension_N"} <= set(s)
    best = c["best_baseline"]
    assert best in ("pd", "lqr")
    assert c["policies"][best]["mean_return"] == max(c["policies"][n]["mean_return"] for n in ("pd", "lqr"))
    low, high = c["paired_ci95"]
    assert low <= c["paired_diff_mean"] <= high
    assert c["paired_diff_mean"] == pytest.approx(c["policies"]["policy"]["mean_return"] - c["policies"][best]["mean_return"])


def test_compare_rejects_a_missing_model(capsys):
    with pytest.raises(SystemExit) as exc:
        compare.main(["--task", "stabilize", "--episodes", "2", "--model", "nowhere.zip"])
    assert exc.value.code == 2
    assert "--model" in capsys.readouterr().err


def test_the_help_names_every_team_task(capsys):
    """--team's help lists the team's tasks from esp_gym/team/tasks.py (it named stabilize and
    transport only, though track and lift run)."""
    from esp_gym.team.tasks import TEAM_TASKS

    with pytest.raises(SystemExit):
        compare.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"(esp_gym/team; tasks {', '.join(sorted(TEAM_TASKS))})" in text and {"track", "lift"} <= set(TEAM_TASKS)


def test_frame_stacked_policy_sees_what_training_showed(tmp_path):
    """SB3Policy stacks the normalised observations as VecFrameStack did in training: the same
    inputs, step by step, including the zeros before the first observation."""
    from stable_baselines3.common.vec_env import VecFrameStack

    from agents.evaluate import SB3Policy
    from agents.train import Settings, train
    from esp_gym.pendulum.sb3_vector import ElasticStringPendulumSB3VecEnv

    run = train(Settings(task="stabilize", runs=str(tmp_path), run_name="stack", progress=False, eval_freq=10_000,
                         reference_episodes=1, set=["total_timesteps=256", "n_envs=2", "n_steps=128",
                                                    "batch_size=128", "n_epochs=1", "frame_stack=3",
                                                    "env_kwargs={observation: hook}"]))
    policy = SB3Policy(run / "model.zip")
    assert policy.input_size == 3 * 12
    seen = []
    policy.actor = lambda obs: (seen.append(np.array(obs)), np.zeros(6))[1]  # what the network is given
    zero = np.zeros((1, 6), dtype=np.float32)

    def env():
        venv = ElasticStringPendulumSB3VecEnv(num_envs=1, task="stabilize", observation="hook")
        venv.seed(5)
        return venv

    stacked = VecFrameStack(policy.normalization.to_vecnormalize(env(), training=False), 3)
    expected = [stacked.reset()[0]] + [stacked.step(zero)[0][0] for _ in range(3)]
    raw = env()  # the same seeded episode, raw: the policy normalises it itself
    observations = [raw.reset()[0]] + [raw.step(zero)[0][0] for _ in range(3)]
    policy.reset()
    for obs in observations:
        policy.act(obs, None)
    assert len(seen) == 4
    for got, want in zip(seen, expected):
        assert np.allclose(got, want, rtol=0, atol=1e-6)
    assert np.all(seen[0][:24] == 0.0)  # two zero frames before the first observation
    assert not np.allclose(seen[1][12:24], 0.0)  # then the first observation moves up


def test_robustness_sweeps_write_the_plot(tmp_path, monkeypatch):
    """One value per sweep, one episode (tiny budget): the JSON has every swept quantity with a
    (mean, standard error) per policy and value, and the figure is written."""
    from agents import robustness

    short = {name: ((values[2],), trained, label) for name, (values, trained, label) in robustness.SWEEPS.items()}
    monkeypatch.setattr(robustness, "SWEEPS", short)
    result = robustness.main(["--task", "stabilize", "--episodes", "1", "--out", str(tmp_path), "--no-progress"])
    assert set(result) == set(short)
    for rows in result.values():
        assert {"pd", "lqg"} <= set(rows)
        assert all(len(rows[p]) == 1 and np.isfinite(rows[p][0][0]) for p in rows if p != "values")
    assert (tmp_path / "robustness_stabilize.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "robustness_stabilize.json").read_text())["EA"]["values"] == [1.0]


def test_sweep_options_change_one_thing():
    from agents.robustness import sweep_options
    from esp_gym.pendulum.env_setup import PRESETS

    assert sweep_options("wind_speed", 9.0)["wind"]["speed"] == 9.0
    assert PRESETS["hard"]["wind"]["speed"] == 6.0  # the preset itself is untouched
    low, high = sweep_options("load_mass", 4.0)["randomize"]["load_mass"]
    assert low == high > 0


def test_compare_flies_the_drone_on_the_hard_preset(tmp_path, capsys):
    """``--scene quadrotor_load --actuation thrust_rates --preset hard`` (issue 34's command): the
    drone's baselines (the PD law and the geometric cascade on its hook estimate), the configuration
    in the JSON and in the files' names, and the shipped drone policy when there is one."""
    c = compare.main(["--task", "stabilize", "--scene", "quadrotor_load", "--actuation", "thrust_rates", "--preset",
                      "hard", "--episodes", "2", "--json", "--no-progress", "--out", str(tmp_path)])
    capsys.readouterr()
    assert (c["scene"], c["actuation"], c["preset"]) == ("quadrotor_load", "thrust_rates", "hard")
    assert {"zero", "pd", "geometric"} <= set(c["policies"])
    shipped = compare.shipped_model("stabilize", "hard", "quadrotor_load", "thrust_rates")
    assert ("policy" in c["policies"]) == shipped.is_file()
    assert (tmp_path / "compare_stabilize_quadrotor_load_hard.json").is_file()


def test_configuration_names_leave_out_the_defaults():
    """The scene's default actuation and the default scene add nothing: one configuration, one name."""
    name = compare.configuration_name
    assert name("track", "hard") == name("track", "hard", "drone_load", "force") == "track_hard"
    assert name("stabilize", "hard", "quadrotor_load", "thrust_rates") == name("stabilize", "hard", "quadrotor_load")
    assert name("stabilize", None, "quadrotor_load", "motors") == "stabilize_quadrotor_load_motors"


def test_a_failing_baseline_is_not_blamed_on_the_model(monkeypatch, capfd):
    """An error inside an episode (here a baseline's NaN action, as crazyflie_load's hard preset
    gave the geometric cascade) propagates as itself: it used to exit 2 as ``argument --model``,
    with no --model given. A missing model file is still the model's (the negative control)."""
    def failing(policy, task, episodes, seed, env_kwargs=None):
        raise ValueError("action must be finite, got [nan, 0.0, 0.0, 0.0]")

    monkeypatch.setattr(compare, "run_episodes", failing)
    with pytest.raises(ValueError, match="action must be finite"):
        call_main(compare.main, ["--task", "stabilize", "--episodes", "2", "--no-progress"], capfd)
    proc = call_main(compare.main, ["--task", "stabilize", "--episodes", "2", "--model", "nowhere.zip"], capfd)
    assert proc.returncode == 2 and "--model" in proc.stderr


@pytest.fixture
def no_team_episode(monkeypatch):
    """The team's episodes fail the test: what is refused is refused before any of them."""
    import agents.team.evaluate

    def ran(*args, **kwargs):
        raise AssertionError("an episode ran before the arguments were checked")

    monkeypatch.setattr(agents.team.evaluate, "run_team_episodes", ran)


TEAM_POINTS, TEAM_DRONES = "models/team3_transport_hard_rllib/checkpoint", "models/team3_drones_transport_hard_rllib/checkpoint"


@pytest.mark.parametrize("model, args, names", [
    (TEAM_POINTS, ["--team", "3", "--task", "transport"], ["preset None (trained with 'hard')", "sizes"]),
    (TEAM_POINTS, ["--team", "2", "--task", "transport", "--preset", "hard"], ["team 2 (trained with 3)", "sizes"]),
    (TEAM_DRONES, ["--team", "3", "--task", "transport", "--preset", "hard"],
     ["actuation None (trained with 'thrust_rates')", "sizes"]),
])
def test_a_team_checkpoint_of_other_sizes_is_refused_in_one_line(capfd, no_team_episode, model, args, names):
    """Each used to end in an 81-line torch shape traceback after the baselines' episodes."""
    proc = call_main(compare.main, [*args, "--model", model, "--episodes", "2", "--no-progress"], capfd)
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "--model" in lines[0], proc.stderr[-3000:]
    for name in names:
        assert name in lines[0], lines[0]


def test_a_team_checkpoint_of_the_same_sizes_on_another_task_is_a_warning():
    """The hard transport checkpoint on hard track: the sizes fit, so it runs, with a warning naming
    the task (it used to run silently); on its own configuration nothing is said (the negative control)."""
    import warnings

    from agents.team.train import check_team_checkpoint

    with pytest.warns(UserWarning, match="task 'track' \\(trained with 'transport'\\)"):
        check_team_checkpoint(TEAM_POINTS, 3, "track", {"preset": "hard"})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_team_checkpoint(TEAM_POINTS, 3, "transport", {"preset": "hard"})
        check_team_checkpoint(TEAM_DRONES, 3, "transport", {"preset": "hard", "actuation": "thrust_rates"})


def test_the_team_compare_finds_the_shipped_checkpoint(monkeypatch, capfd):
    """Without --model the team compare runs the shipped checkpoint of its configuration, as the
    single compare runs the zoo's model; a configuration with none ships runs the baselines alone."""
    import agents.team.evaluate
    import agents.team.train

    seen = {}

    class Loaded:
        def __init__(self, checkpoint):
            seen["model"] = str(checkpoint)

    class Stop(Exception):
        pass

    def first(policy, *args, **kwargs):
        raise Stop

    monkeypatch.setattr(agents.team.train, "TeamRLlibPolicy", Loaded)
    monkeypatch.setattr(agents.team.evaluate, "run_team_episodes", first)
    for actuation, model in (([], TEAM_POINTS), (["--actuation", "thrust_rates"], TEAM_DRONES)):
        seen.clear()
        with pytest.raises(Stop):
            call_main(compare.main, ["--team", "3", "--task", "transport", "--preset", "hard", *actuation,
                                     "--episodes", "2", "--no-progress"], capfd)
        assert seen["model"].endswith(model), seen
    seen.clear()
    with pytest.raises(Stop):
        call_main(compare.main, ["--team", "2", "--task", "transport", "--episodes", "2", "--no-progress"], capfd)
    assert seen == {}
    assert compare.shipped_team_model(3, "transport", "hard", None).is_dir()


def test_a_team_option_combination_the_env_refuses_is_one_line(capfd, no_team_episode):
    """Drones with a winch's task: the env is built once while the arguments are checked (it used
    to be a 23-line traceback from the first episode)."""
    proc = call_main(compare.main, ["--team", "3", "--actuation", "thrust_rates", "--task", "lift", "--episodes", "2"],
                     capfd)
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "--task lift" in lines[0] and "do not reel" in lines[0], proc.stderr[-3000:]
