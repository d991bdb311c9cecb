"""The model zoo (agents/zoo.py, configs/agents/zoo.yaml): its file, its command, and that the
docs' comparisons are the output of the shipped models and baselines of today."""
import json

import numpy as np
import pytest

from agents import ROOT
from agents.compare import HELD_OUT_SEED, NOT_BASELINES, configuration_name
from agents.zoo import MODELS, load_zoo, settings, train_argv

ZOO = load_zoo()
#: Episodes of each documented comparison rerun per configuration (the full rerun is
#: ``python -m agents.zoo --compare``, which rewrites the tables and the quotes).
RERUN_EPISODES = 2


def comparison(name: str) -> dict:
    return json.loads((ROOT / "docs" / "compare" / f"compare_{name}.json").read_text())


def test_every_configuration_is_named_by_its_environment_and_ships_a_model():
    """Each name is agents.compare's configuration_name of its entry, each has a model with its
    run's files, every model under models/ is the zoo's, and a misnamed entry is refused by name
    (the negative control)."""
    assert sorted(p.name for p in MODELS.glob("*_ppo")) == sorted(f"{name}_ppo" for name in ZOO.configurations)
    for name, c in ZOO.configurations.items():
        assert name == configuration_name(c.task, c.preset, c.scene, c.actuation)
        for shipped in ("model.zip", "config.yaml", "command.txt", "training.json", "learning_curve.png"):
            assert (MODELS / f"{name}_ppo" / shipped).is_file(), (name, shipped)
    text = (ROOT / "configs" / "agents" / "zoo.yaml").read_text().replace("  stabilize: {task: stabilize",
                                                                           "  stabilise: {task: stabilize")
    bad = ROOT / "runs" / "zoo_misnamed.yaml"
    bad.parent.mkdir(exist_ok=True)
    bad.write_text(text)
    try:
        with pytest.raises(ValueError, match="'stabilise' is named 'stabilize'"):
            load_zoo(bad)
    finally:
        bad.unlink()


def test_a_configurations_command_is_the_recipe_then_its_own():
    """The recipe's --set items, the base, the critic and the environment, then the
    configuration's own, which override the recipe's."""
    name = "stabilize_hard"
    items = settings(ZOO, name)
    assert items["residual"] == "lqg" and items["privileged_critic"] is True
    assert items["env_kwargs"] == {"preset": "hard"}
    for key, value in ZOO.configurations[name].set.items():
        assert items[key] == value
    argv = train_argv(ZOO, name, ROOT / "runs")
    assert argv[argv.index("--task") + 1] == "stabilize" and argv[argv.index("--run-name") + 1] == "zoo_stabilize_hard"
    assert "env_kwargs={preset: hard}" in argv and "residual=lqg" in argv
    assert argv[argv.index("--time-limit") + 1] == str(ZOO.recipe.time_limit)


@pytest.mark.parametrize("name", list(ZOO.configurations))
def test_each_shipped_model_was_trained_by_the_zoos_recipe_for_it(name):
    """models/NAME_ppo's resolved config, algorithm, task, seed and time limit are what the zoo's
    command for NAME resolves to (agents.train's config from configs/agents/ppo.yaml and the
    command's --set items), so `agents.zoo --train` regenerates what ships."""
    import yaml

    import esp_gym
    from agents.common import RunConfig, load_run_config

    c, shipped = ZOO.configurations[name], MODELS / f"{name}_ppo"
    argv = train_argv(ZOO, name, ROOT / "runs")
    wanted = load_run_config(ZOO.recipe.algo, esp_gym.ENV_ID, c.task, argv[argv.index("--set") + 1:])
    assert RunConfig(**yaml.safe_load((shipped / "config.yaml").read_text())) == wanted
    args = json.loads((shipped / "args.json").read_text())
    seed = ZOO.recipe.seed if c.seed is None else c.seed
    assert (args["algo"], args["task"], args["seed"], args["time_limit"]) == (
        ZOO.recipe.algo, c.task, seed, ZOO.recipe.time_limit)
    assert argv[argv.index("--seed") + 1] == str(seed)


@pytest.mark.parametrize("name", list(ZOO.configurations))
def test_the_documented_comparison_is_todays_models_and_baselines(name):
    """docs/compare/compare_NAME.json was written by the shipped model and today's baselines on the
    documented seeds: its first RERUN_EPISODES episodes, rerun, give each policy's recorded
    returns (a model, a baseline or the physics that changed since fails here)."""
    from agents.baselines.pd import ZeroPolicy
    from agents.baselines.registry import baselines
    from agents.evaluate import SB3Policy, run_episodes

    c, doc = ZOO.configurations[name], comparison(name)
    assert (doc["episodes"], doc["seed"]) == (100, HELD_OUT_SEED)
    assert (doc["task"], doc["preset"], doc["scene"], doc["actuation"]) == (c.task, c.preset, c.scene, c.actuation)
    assert doc["model"].endswith(f"models/{name}_ppo/model.zip")
    policies = {"zero": ZeroPolicy(), **baselines(c.task, c.env_kwargs),
                "policy": SB3Policy(MODELS / f"{name}_ppo" / "model.zip")}
    assert set(policies) == set(doc["policies"])
    assert doc["best_baseline"] == max((n for n in doc["policies"] if n not in NOT_BASELINES),
                                       key=lambda n: doc["policies"][n]["mean_return"])
    for policy_name, policy in policies.items():
        recorded = doc["policies"][policy_name]["returns"]
        assert len(recorded) == doc["episodes"]
        assert np.mean(recorded) == pytest.approx(doc["policies"][policy_name]["mean_return"], rel=1e-12)
        rerun = [e.ret for e in run_episodes(policy, c.task, RERUN_EPISODES, doc["seed"], env_kwargs=c.env_kwargs)]
        assert rerun == pytest.approx(recorded[:RERUN_EPISODES], rel=1e-6), (name, policy_name)


def test_a_comparison_of_other_episodes_does_not_pass_for_the_documented_one():
    """The negative control of the check above: the same policies one seed later (the episodes
    after the documented first ones) miss the recorded returns."""
    from agents.baselines.registry import baselines
    from agents.evaluate import run_episodes

    doc = comparison("stabilize")
    for policy_name, policy in baselines("stabilize").items():
        shifted = [e.ret for e in run_episodes(policy, "stabilize", 1, doc["seed"] + 1)]
        assert shifted != pytest.approx(doc["policies"][policy_name]["returns"][:1], rel=1e-6)


def test_a_changed_model_or_environment_does_not_pass_for_the_documented_comparison():
    """The negative control of the rerun above for what it guards: the shipped policy with its
    last layer's biases moved by 1e-4 (a model retrained or evaluated otherwise), and the same
    policy on a load 0.1 % heavier (the environment changed), miss the recorded first episode."""
    import dataclasses

    from agents.evaluate import SB3Policy, run_episodes

    doc = comparison("stabilize")
    recorded = doc["policies"]["policy"]["returns"][:1]
    policy = SB3Policy(MODELS / "stabilize_ppo" / "model.zip")
    assert [e.ret for e in run_episodes(policy, "stabilize", 1, doc["seed"])] == pytest.approx(recorded, rel=1e-6)
    heavier = {"scene_overrides": {"body.mass": 1.001 * 0.5}}
    assert [e.ret for e in run_episodes(policy, "stabilize", 1, doc["seed"], env_kwargs=heavier)] != pytest.approx(
        recorded, rel=1e-6)
    actor = policy.actor
    policy.actor = dataclasses.replace(actor, biases=actor.biases[:-1] + (actor.biases[-1] + 1e-4,))
    assert [e.ret for e in run_episodes(policy, "stabilize", 1, doc["seed"])] != pytest.approx(recorded, rel=1e-6)


def test_a_shipped_policy_loaded_by_name_acts_as_in_the_documented_comparison():
    """esp_gym.zoo.load's predict, and esp_gym.zoo.baseline's, in a plain Gymnasium loop on the
    environment of esp_gym.zoo.make, give the documented first episode of a hard configuration (its
    base a Kalman filter, which restarts at each episode by itself: the policy twice in a row); BLAS
    on one thread, as the comparison ran. Names and refusals."""
    from threadpoolctl import threadpool_limits

    import esp_gym.zoo

    def episode(policy, env, seed):
        obs, _ = env.reset(seed=seed)
        total, done = 0.0, False
        while not done:
            action, state = policy.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, _ = env.step(action)
            total, done = total + reward, terminated or truncated
        return total

    assert esp_gym.zoo.names() == sorted(p.name for p in MODELS.iterdir() if p.is_dir())
    doc = comparison("stabilize_hard")
    env = esp_gym.zoo.make("stabilize_hard_ppo")
    policy, base = esp_gym.zoo.load("stabilize_hard_ppo", env), esp_gym.zoo.baseline("stabilize_hard_ppo", env)
    with threadpool_limits(limits=1, user_api="blas"):
        returns = [episode(policy, env, doc["seed"]) for _ in range(2)]
        base_return = episode(base, env, doc["seed"])
    assert returns == pytest.approx(doc["policies"]["policy"]["returns"][:1] * 2, rel=1e-6)
    assert base_return == pytest.approx(doc["policies"]["lqg"]["returns"][0], rel=1e-6)
    obs = env.reset(seed=0)[0]
    with pytest.raises(ValueError, match="no shipped policy 'stabilise_ppo'"):
        esp_gym.zoo.load("stabilise_ppo")
    with pytest.raises(ValueError, match="deterministic=False"):
        policy.predict(obs, deterministic=False)
    with pytest.raises(RuntimeError, match=r"reset\(env\)"):
        esp_gym.zoo.load("stabilize_ppo").predict(obs)
