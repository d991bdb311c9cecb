"""The agent scripts' arguments and files: ``--set`` (repeatable, dotted keys, YAML values,
checked keys), errors that are one line naming the argument and write nothing, model files named
when they cannot be loaded, and normalisation statistics read as data, never unpickled. The
one-line errors are checked on each script's main in the test's process (tests/script_main.py),
but for one case per script that runs ``python -m`` in a subprocess."""
import importlib
import json
import pickle
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from agents.common import load_run_config
from agents.evaluate import SB3Policy
from script_main import call_main

ROOT = Path(__file__).resolve().parent.parent
ENV_ID = "ElasticStringPendulum-v0"
SHIPPED = ROOT / "models" / "stabilize_ppo" / "model.zip"
#: A budget that keeps a run short should an argument wrongly be accepted (in the same --set, as
#: the old script kept only the last --set).
TINY = ["total_timesteps=64", "n_envs=1", "n_steps=64", "batch_size=64", "n_epochs=1"]
TINY_OPTIONS = ["--reference-episodes", "1", "--eval-episodes", "1", "--no-progress"]


def cli(module: str, *args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", module, *map(str, args)], capture_output=True, text=True,
                          timeout=900, cwd=ROOT)


def main_of(module: str, capfd, *args) -> subprocess.CompletedProcess:
    """``module``'s main with ``args`` in this process, read as :func:`cli` reads a subprocess."""
    return call_main(importlib.import_module(module).main, args, capfd)


def assert_usage_error(proc: subprocess.CompletedProcess, *names: str) -> str:
    """Exit code 2 and a single line on stderr that names each of ``names``."""
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr[-3000:]
    for name in names:
        assert name in lines[0], lines[0]
    return lines[0]


def tree(path: Path) -> list:
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


# --- item 4: --set ---------------------------------------------------------------------------

def test_repeated_and_multi_valued_set_options_all_apply():
    from agents.train import parse_args

    s, given, _ = parse_args(["--set", "a=1", "b=2", "--set", "c=3", "--seed", "4"])
    assert s.set == ["a=1", "b=2", "c=3"]
    assert given == {"set", "seed"}
    cfg = load_run_config("ppo", ENV_ID, "stabilize", ["n_envs=2", "n_steps=64", "n_envs=3"])
    assert (cfg.n_envs, cfg.algo["n_steps"]) == (3, 64)  # in order: the last value of a key wins


def test_dotted_keys_reach_nested_settings():
    cfg = load_run_config("ppo", ENV_ID, "stabilize", [
        "policy_kwargs.net_arch.pi=[64, 64]", "normalize.clip_obs=5", "env_kwargs.safety=0.4"])
    assert cfg.algo["policy_kwargs"]["net_arch"] == {"pi": [64, 64], "vf": [128, 128]}
    assert cfg.algo["policy_kwargs"]["log_std_init"] == -1.0  # the rest of the mapping stays
    assert cfg.normalize == {"norm_obs": True, "norm_reward": True, "clip_obs": 5}
    assert cfg.env_kwargs == {"safety": 0.4}
    # a dotted key into a setting that is null makes it a mapping
    cfg = load_run_config("ppo", ENV_ID, "stabilize", ["normalize=null", "normalize.norm_reward=false"])
    assert cfg.normalize == {"norm_reward": False}
    # the config file itself is not changed by overrides
    assert load_run_config("ppo", ENV_ID, "stabilize", []).algo["policy_kwargs"]["net_arch"]["pi"] == [128, 128]


def test_set_values_are_yaml():
    cfg = load_run_config("sac", ENV_ID, "stabilize", [
        "learning_rate=3e-4", "policy_kwargs.net_arch=[64, 64]", "target_entropy=-3", "normalize=null",
        "policy_kwargs={net_arch: {pi: [32], qf: [64]}}"])
    assert cfg.algo["learning_rate"] == pytest.approx(3e-4) and isinstance(cfg.algo["learning_rate"], float)
    assert cfg.algo["policy_kwargs"] == {"net_arch": {"pi": [32], "qf": [64]}}
    assert cfg.algo["target_entropy"] == -3 and cfg.normalize is None
    assert load_run_config("ppo", ENV_ID, "stabilize", ["learning_rate=lin_1e-3"]).algo["learning_rate"] == "lin_1e-3"


@pytest.mark.parametrize("item, named, listed", [
    ("learning_rat=0.1", "'learning_rat'", "learning_rate"),
    ("seed=3", "'seed'", "n_steps"),  # the script sets the seed (--seed)
    ("policy_kwargs.net_arhc=[8]", "'policy_kwargs.net_arhc'", "net_arch"),
    ("policy_kwargs.net_arch.pii=[8]", "'policy_kwargs.net_arch.pii'", "pi, vf"),
    ("policy_kwargs={net_arch: [8], ortho: false}", "'policy_kwargs.ortho'", "ortho_init"),
    ("normalize.clip_ob=5", "'normalize.clip_ob'", "clip_obs"),
    ("env_kwargs.safty=0.5", "'env_kwargs.safty'", "safety"),
])
def test_unknown_keys_are_named_with_the_valid_ones(item, named, listed):
    with pytest.raises(ValueError, match=re.escape(named)) as err:
        load_run_config("ppo", ENV_ID, "stabilize", [item])
    assert listed in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("item, message", [
    ("n_steps.x=1", "n_steps is 256, not a mapping"),
    ("n_envs", "KEY=VALUE"),
    ("n_envs=[2", "not YAML"),
    ("n_envs=0", "n_envs"),
    ("learning_rate=fast", "learning_rate"),
])
def test_bad_overrides_are_value_errors_naming_them(item, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        load_run_config("ppo", ENV_ID, "stabilize", [item])


# --- one-line errors that write nothing ---------------------------------------------------------

def _fake_run(tmp_path: Path) -> Path:
    """A run directory (args.json of the shipped model) with a checkpoints/ folder."""
    run = tmp_path / "runs" / "fake"
    (run / "checkpoints").mkdir(parents=True)
    shutil.copy(SHIPPED.parent / "args.json", run / "args.json")
    return run


@pytest.mark.parametrize("case", ["unknown_key_in_an_earlier_set", "nested_unknown_key", "eval_freq_zero",
                                  "run_exists", "algorithm_rejects", "resume_not_a_checkpoint_name",
                                  "resume_outside_a_run", "resume_missing", "resume_with_run_setting",
                                  "residual_without_its_observation", "batch_past_memory"])
def test_train_errors_are_one_line_and_write_nothing(tmp_path, capfd, case):
    run = _fake_run(tmp_path)
    shutil.copy(SHIPPED, run / "checkpoints" / "model.zip")
    (tmp_path / "loose").mkdir()
    shutil.copy(SHIPPED, tmp_path / "loose" / "model_100_steps.zip")
    shutil.copy(SHIPPED, run / "checkpoints" / "model_100_steps.zip")
    (tmp_path / "runs" / "taken").mkdir()
    new = ["--runs", tmp_path / "runs", *TINY_OPTIONS]
    args, names = {
        "unknown_key_in_an_earlier_set": (["--set", "bogus=1", "--set", *TINY, *new], ["--set", "'bogus'", "n_steps"]),
        "nested_unknown_key": (["--set", *TINY, "policy_kwargs.net_arch.pii=[8]", *new], ["--set", "pii", "pi, vf"]),
        "eval_freq_zero": (["--eval-freq", "0", "--set", *TINY, *new], ["--eval-freq", ">= 1"]),
        "run_exists": (["--run-name", "taken", "--set", *TINY, *new], ["--run-name", "taken", "exists"]),
        "algorithm_rejects": (["--set", *TINY, "n_steps=1", *new], ["--set", "PPO", "n_steps"]),
        "resume_not_a_checkpoint_name": (["--resume", run / "checkpoints" / "model.zip"],
                                         ["--resume", "model.zip", "model_N_steps.zip"]),
        "resume_outside_a_run": (["--resume", tmp_path / "loose" / "model_100_steps.zip"],
                                 ["--resume", "model_100_steps.zip", "checkpoints/"]),
        "resume_missing": (["--resume", tmp_path / "nothing.zip"], ["--resume", "nothing.zip"]),
        "resume_with_run_setting": (["--resume", run / "checkpoints" / "model_100_steps.zip", "--seed", "3"],
                                    ["--seed", "--resume"]),
        "residual_without_its_observation": (["--set", *TINY, "residual=lqg", *new], ["--set", "'lqg'", "hook"]),
        "batch_past_memory": (["--set", *TINY, "n_envs=100000000", *new],
                              ["--set", "num_envs = 100000000 environments", "GiB"]),
    }[case]
    before = tree(tmp_path)
    # one case runs python -m agents.train (tests/test_agents.py runs its successes so)
    alone = case == "unknown_key_in_an_earlier_set"
    proc = cli("agents.train", *args) if alone else main_of("agents.train", capfd, *args)
    assert_usage_error(proc, *names)
    assert tree(tmp_path) == before


def test_evaluate_flies_the_drone_with_the_geometric_controller(capfd):
    """The drone's interface (issue 34): ``--policy geometric --scene quadrotor_load --actuation
    thrust_rates`` runs and reports its configuration; a point pivot has no geometric controller
    (its main here: tests/test_agents.py runs python -m agents.evaluate)."""
    proc = main_of("agents.evaluate", capfd, "--policy", "geometric", "--scene", "quadrotor_load", "--actuation",
                   "thrust_rates", "--task", "stabilize", "--episodes", "1")
    assert proc.returncode == 0, proc.stderr[-3000:]
    stats = json.loads(proc.stdout.strip().splitlines()[-1])
    assert (stats["policy"], stats["scene"], stats["actuation"]) == ("geometric", "quadrotor_load", "thrust_rates")
    assert stats["mean_return"] > 300.0
    assert_usage_error(main_of("agents.evaluate", capfd, "--policy", "geometric", "--episodes", "1"),
                       "--policy", "'geometric'")
    assert_usage_error(main_of("agents.evaluate", capfd, "--scene", "quadrotor_load", "--actuation", "force",
                               "--episodes", "1"), "--scene/--actuation", "does not fly")


def test_evaluate_rejects_policy_names_it_does_not_know():
    # agents.evaluate's usage error in a subprocess (the others run its main here)
    line = assert_usage_error(cli("agents.evaluate", "--policy", "baselineXYZ", "--episodes", "1"),
                              "--policy", "baselineXYZ")
    assert "zero" in line and "baseline" in line


#: The case of each script run by ``python -m`` in a subprocess (agents.evaluate's: the test above).
END_TO_END = {("agents.compare", "--task", "stabilize"), ("agents.task_figures", "--out", "{missing}/figures"),
              ("agents.baselines.gain_search", "--grid", '{"kq": [1]}')}


SCRIPT_ERRORS = [
    ("agents.evaluate", ["--episodes", "0"], ["--episodes"]),
    ("agents.evaluate", ["--policy", "zero", "--episodes", "1", "--record", "{missing}/x.rrd"], ["--record", "{missing}"]),
    ("agents.evaluate", ["--policy", "lqr", "--preset", "hard", "--episodes", "1"], ["--policy", "'lqr'", "lqg"]),
    ("agents.compare", ["--model", "no_such_model.zip"], ["--model", "no_such_model.zip"]),
    ("agents.compare", ["--model", SHIPPED, "--episodes", "2", "--out", "{missing}/x.json"], ["--out", "{missing}"]),
    ("agents.compare", ["--episodes", "1"], ["--episodes", ">= 2"]),
    ("agents.evaluate", ["--policy", "zero", "--episodes", "1", "--record", "{tmp}"], ["--record", "is a directory"]),
    ("agents.task_figures", ["--out", "{missing}/figures", "--steps", "2"], ["--out", "{missing}"]),
    # a model where its observations do not fit: one line naming both configurations
    ("agents.evaluate", ["--policy", ROOT / "models" / "lift_ppo" / "model.zip", "--task", "stabilize"],
     ["--policy", "task 'stabilize' (trained with 'lift')", "do not fit"]),
    ("agents.compare", ["--task", "stabilize", "--model", ROOT / "models" / "lift_ppo" / "model.zip", "--episodes", "2"],
     ["--model", "winch False (trained with True)"]),
    ("agents.baselines.gain_search", ["--grid", '{"kq": [1]}'], ["--grid", "'kq'", "kp"]),
    ("agents.baselines.gain_search", ["--grid", '{"kp": [1'], ["--grid", "not JSON"]),
    ("agents.baselines.gain_search", ["--controller", "geometric", "--grid", '{"k_load": [1]}'],
     ["--controller/--scene/--actuation", "flies a drone"]),
    ("agents.baselines.gain_search", ["--controller", "geometric", "--scene", "quadrotor_load"],
     ["--grid", "no default grid"]),
    ("agents.baselines.gain_search", ["--controller", "geometric", "--scene", "quadrotor_load", "--grid",
                                      '{"kp": [1]}'], ["--grid", "'kp'", "k_load"]),
    ("agents.baselines.gain_search", ["--controller", "geometric", "--scene", "quadrotor_load", "--preset", "hard",
                                      "--grid", '{"kp": [1]}'], ["--grid", "'kp'", "k_load"]),
    ("agents.compare", ["--scene", "quadrotor_load", "--actuation", "force", "--episodes", "2"],
     ["--scene/--actuation", "does not fly"]),
]


@pytest.mark.parametrize("module, args, names", SCRIPT_ERRORS)
def test_script_errors_are_one_line(tmp_path, capfd, module, args, names):
    missing = tmp_path / "missing"  # a directory that does not exist

    def fill(text):
        return str(text).replace("{missing}", str(missing)).replace("{tmp}", str(tmp_path))

    alone = (module, *map(str, args[:2])) in END_TO_END
    proc = cli(module, *map(fill, args)) if alone else main_of(module, capfd, *map(fill, args))
    assert_usage_error(proc, *map(fill, names))
    assert not missing.exists()


def test_each_script_has_one_error_case_in_a_subprocess():
    alone = [module for module, args, _ in SCRIPT_ERRORS if (module, *map(str, args[:2])) in END_TO_END]
    assert sorted(alone) == sorted({module for module, *_ in SCRIPT_ERRORS} - {"agents.evaluate"})


def test_a_model_knows_its_configuration_and_says_where_it_is_run_elsewhere():
    """The task and options of its run directory: the same configuration is silent, another one
    whose sizes fit warns, one whose observations do not fit refuses (the Python API)."""
    import warnings

    from agents.artifacts import ConfigurationError

    policy = SB3Policy(ROOT / "models" / "stabilize_hard_ppo" / "model.zip")
    assert policy.configuration == {"task": "stabilize", "env_kwargs": {"preset": "hard"}}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        policy.check("stabilize", {"preset": "hard"})
    with pytest.warns(UserWarning, match=r"task 'track' \(trained with 'stabilize'\); it runs"):
        policy.check("track", {"preset": "hard"})
    with pytest.raises(ConfigurationError, match=r"observation 'full' \(trained with 'hook'\)"):
        policy.check("stabilize", {})


# --- model files --------------------------------------------------------------------------------

def _damaged_models(tmp_path: Path) -> dict:
    paths = {name: tmp_path / f"{name}.zip" for name in ("empty", "garbage", "empty_archive", "no_data", "truncated")}
    paths["empty"].write_bytes(b"")
    paths["garbage"].write_bytes(b"not a zip at all\n")
    with zipfile.ZipFile(paths["empty_archive"], "w"):
        pass
    with zipfile.ZipFile(SHIPPED) as src, zipfile.ZipFile(paths["no_data"], "w") as dst:
        dst.writestr("policy.pth", src.read("policy.pth"))
    paths["truncated"].write_bytes(SHIPPED.read_bytes()[:4000])
    return paths


@pytest.mark.parametrize("name", ["empty", "garbage", "empty_archive", "no_data", "truncated"])
def test_unloadable_model_files_are_errors_naming_the_file(tmp_path, name):
    path = _damaged_models(tmp_path)[name]
    with pytest.raises(ValueError, match=re.escape(str(path))):
        SB3Policy(path)


def test_evaluate_names_an_unloadable_model_file(tmp_path, capfd):
    path = _damaged_models(tmp_path)["empty_archive"]
    assert_usage_error(main_of("agents.evaluate", capfd, "--policy", path, "--episodes", "1"), "--policy", str(path))


# --- normalisation statistics -------------------------------------------------------------------

class _Planted:
    """Unpickling this creates the file ``path`` (it stands for any code a pickle can run)."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return open, (self.path, "w")


def test_a_crafted_statistics_pickle_beside_a_model_is_refused_not_run(tmp_path):
    model = tmp_path / "model.zip"
    shutil.copy(SHIPPED, model)
    planted = tmp_path / "planted"
    (tmp_path / "vecnormalize.pkl").write_bytes(pickle.dumps(_Planted(planted)))
    with pytest.raises(ValueError, match="vecnormalize.pkl") as err:
        SB3Policy(model)
    assert not planted.exists()
    assert "open" in str(err.value)  # the global it refused


def test_a_legacy_statistics_pickle_reads_as_data_equal_to_the_pickle(tmp_path):
    """SB3's own VecNormalize pickle (what runs before the .npz statistics wrote) read as data
    (agents/normalization.py read_legacy_pickle) holds what unpickling it gives."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from agents.normalization import NormStats

    rng = np.random.default_rng(1)
    written = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]), clip_obs=5.0, gamma=0.98)
    written.obs_rms.update(rng.normal(1.0, 3.0, size=(40, 3)))
    written.ret_rms.update(rng.normal(size=40))
    written.save(str(tmp_path / "vecnormalize.pkl"))
    stats = NormStats.load(tmp_path / "vecnormalize.pkl")
    with open(tmp_path / "vecnormalize.pkl", "rb") as fh:  # written here: trusted
        vn = pickle.load(fh)
    np.testing.assert_array_equal(stats.obs_mean, vn.obs_rms.mean)
    np.testing.assert_array_equal(stats.obs_var, vn.obs_rms.var)
    assert (stats.obs_count, stats.ret_count) == (vn.obs_rms.count, vn.ret_rms.count)
    assert (stats.clip_obs, stats.epsilon, stats.norm_obs, stats.norm_reward, stats.gamma) == (
        vn.clip_obs, vn.epsilon, vn.norm_obs, vn.norm_reward, vn.gamma)
    assert stats.obs_count > 1 and stats.clip_obs == 5.0  # not a default-built record


def test_statistics_round_trip_through_npz_and_normalise_like_vecnormalize(tmp_path):
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from agents.normalization import NormStats

    rng = np.random.default_rng(0)
    vn = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]), clip_obs=2.0, gamma=0.95)
    vn.obs_rms.update(rng.normal(3.0, 2.0, size=(50, 3)))
    vn.ret_rms.update(rng.normal(size=50))
    path = NormStats.from_vecnormalize(vn).save(tmp_path / "vecnormalize.npz")
    stats = NormStats.load(path)
    again = stats.to_vecnormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]))
    obs = rng.normal(3.0, 4.0, size=(7, 3)).astype(np.float32)
    np.testing.assert_allclose(stats.normalize_obs(obs), vn.normalize_obs(obs), rtol=1e-6)
    np.testing.assert_array_equal(again.normalize_obs(obs), vn.normalize_obs(obs))
    np.testing.assert_array_equal(again.normalize_reward(np.ones(1)), vn.normalize_reward(np.ones(1)))
    assert (again.gamma, again.clip_obs) == (0.95, 2.0)


def test_statistics_files_holding_pickled_objects_are_refused(tmp_path):
    from agents.normalization import NormStats

    path = tmp_path / "vecnormalize.npz"
    np.savez(path, obs_mean=np.array([object()], dtype=object))  # an object array is a pickle inside
    with pytest.raises(ValueError, match=re.escape(str(path))):
        NormStats.load(path)


# --- issue 54: worker counts and outputs checked before any work ----------------------------------

#: A directory in which no process creates files, root's included (file modes do not stop root).
UNWRITABLE = Path("/proc")


@pytest.fixture
def no_work(monkeypatch):
    """The zoo's and compare's work (process pools, trainings, episodes) replaced by errors: a
    refusal must come before it. Returns the worker counts of the pools asked for (none started)."""
    import concurrent.futures

    from agents import compare, zoo

    made = []

    def no_pool(max_workers=None, **kwargs):
        made.append(max_workers)
        raise RuntimeError(f"a pool of {max_workers} worker processes was made")

    def started(*args, **kwargs):
        raise AssertionError("the work started before the arguments were refused")

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", no_pool)
    for module, name in ((zoo, "train"), (compare, "compare"), (compare, "compare_team")):
        monkeypatch.setattr(module, name, started)
    return made


def test_zoo_comparisons_take_at_most_one_worker_per_configuration(monkeypatch, tmp_path, no_work):
    """compare_all's pool has min(jobs, configurations) workers, and a count above the CPUs is
    refused before any pool (the fork bomb of --jobs 100000)."""
    import esp_gym.workers
    from agents import MODELS, zoo

    monkeypatch.setattr(esp_gym.workers, "available_cpus", lambda: 8)  # the same on any machine
    names = ["stabilize", "transport"]
    with pytest.raises(RuntimeError, match="pool of 2 worker"):
        zoo.compare_all(zoo.load_zoo(), names, MODELS, tmp_path, 2, 0, jobs=8, progress=False)
    with pytest.raises(ValueError, match=r"jobs .*8 CPUs.*got 9"):
        zoo.compare_all(zoo.load_zoo(), names, MODELS, tmp_path, 2, 0, jobs=9, progress=False)
    assert no_work == [2]


@pytest.mark.parametrize("action", ["--compare", "--train"])
def test_the_zoo_refuses_more_jobs_than_cpus_before_any_worker(tmp_path, capfd, no_work, action):
    from esp_gym.workers import available_cpus

    jobs = available_cpus() + 1
    proc = main_of("agents.zoo", capfd, action, "--jobs", jobs, "--only", "stabilize", "--runs", tmp_path / "runs",
                   "--models", tmp_path / "models" if action == "--train" else ROOT / "models",
                   "--out", tmp_path / "out", "--no-progress")
    assert_usage_error(proc, "--jobs", f"{available_cpus()} CPUs", f"got {jobs}")
    assert no_work == [] and list(tmp_path.iterdir()) == []


#: Paths and settings that failed only after the work (a traceback after every episode, or after a
#: training started), each refused first: (module, arguments, what the line names).
BAD_BEFORE_WORK = [
    ("agents.zoo", ["--compare", "--only", "stabilize", "--models", "{missing}"],
     ["--models", "'stabilize'", "{missing}/stabilize_ppo/model.zip"]),
    ("agents.zoo", ["--compare", "--only", "stabilize", "--out", f"{UNWRITABLE}/compare"], ["--out", str(UNWRITABLE)]),
    ("agents.zoo", ["--train", "--only", "stabilize", "--runs", f"{UNWRITABLE}/runs", "--models", "{tmp}/models"],
     ["--runs", str(UNWRITABLE)]),
    ("agents.zoo", ["--train", "--only", "stabilize", "--runs", "{tmp}/runs", "--models", f"{UNWRITABLE}/models"],
     ["--models", str(UNWRITABLE)]),
    ("agents.zoo", ["--train", "--only", "stabilize", "--runs", "{tmp}/runs", "--models", "{tmp}/models", "--set",
                    "bogus_key=1"], ["'stabilize'", "--set", "'bogus_key'"]),
    ("agents.zoo", ["--train", "--only", "stabilize", "--runs", "{tmp}/runs", "--models", "{tmp}/models", "--set",
                    "total_timesteps=-5"], ["'stabilize'", "--set", "total_timesteps"]),
    ("agents.compare", ["--team", "2", "--episodes", "2", "--out", f"{UNWRITABLE}/compare"], ["--out", str(UNWRITABLE)]),
    ("agents.compare", ["--episodes", "2", "--out", f"{UNWRITABLE}/compare"], ["--out", str(UNWRITABLE)]),
]


@pytest.mark.parametrize("module, args, names", BAD_BEFORE_WORK)
def test_bad_paths_and_settings_are_refused_before_any_work(tmp_path, capfd, no_work, module, args, names):
    def fill(text):
        return str(text).replace("{missing}", str(tmp_path / "missing")).replace("{tmp}", str(tmp_path))

    assert_usage_error(main_of(module, capfd, *map(fill, args), "--no-progress"), *map(fill, names))
    assert list(tmp_path.iterdir()) == [] and no_work == []


def test_team_evaluate_says_it_is_a_library_not_a_command(capfd):
    """python -m agents.team.evaluate printed nothing and exited 0, as though it had run."""
    from agents.team import evaluate as team_evaluate

    assert_usage_error(call_main(team_evaluate.main, ["--help"], capfd), "library", "agents.compare --team")
