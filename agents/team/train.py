"""Train a team with RLlib (new API stack): PPO on the PettingZoo env (esp_gym.team.parallel_env),
every agent acting with one shared policy (parameter sharing), on this machine or a Ray cluster.

    python -m agents.team.train --team 3 --task transport --preset hard --iterations 100
    python -m agents.team.train --team 3 --iterations 20 --set lr=1e-4 num_env_runners=2
    python -m agents.team.train --team 3 --task transport --preset hard --residual --time-limit 60
    python -m agents.team.train --team 3 --actuation thrust_rates --preset hard --residual --time-limit 60

``--residual`` trains a residual on the team's baseline (agents/team/residual.py: the agents' actions
added, scaled by ``--residual-scale``, to the LQR's, or with the hook observation the LQG's; a
drone team's (``--actuation``) to the drones' cascade's);
the checkpoint then carries residual.json and every evaluation adds the same baseline.
``--central-critic`` gives the network a critic that also reads the team's true state
(agents/team/critic.py); the checkpoint then carries central_critic.json.

Hyper-parameters come from configs/agents/rllib_team_ppo.yaml keyed by ``ElasticStringTeam-v0``
and the task; ``--set KEY=VALUE`` overrides them as in agents.distributed.train. A run directory
``runs/{name}`` (default ``ElasticStringPendulum-v0__rllib_team_ppo__{task}__{seed}__{time}``, as
agents.train names runs) receives config.yaml, args.json, command.txt, status.json, progress.csv
(one row per iteration), references.json (the zero action's and the team's baseline's returns: the
LQR, or with the hook observation the LQG),
checkpoint/ (the last), training.json, evaluation.json (agents/team/evaluate.py's metrics of the
final deterministic policy) and learning_curve.png. ``--time-limit`` stops after that many
minutes and saves. progress.csv's ``episode_return_mean`` is the team's return (RLlib's sum over
the agents, each given the team's reward, divided by K).
"""
from __future__ import annotations

import csv
import dataclasses
import json
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import yaml

from agents import ROOT
from agents.artifacts import judge_configuration
from agents.cli import SettingsError, settings_parser
from agents.common import CONFIG_DIR, ConfigError, json_default
from agents.distributed.cluster import AddressError, check_address
from agents.distributed.rllib import RLlibRunConfig, load_rllib_config
from agents.distributed.train import PROGRESS_FIELDS, build, check_local_runners, plot_curve, progress_row, rllib_main
from agents.evaluate import summarize
from agents.mlp import actor_of_rllib
from agents.runs import new_run_dir, write_status, write_stopped
from agents.team.critic import CRITIC_FILE, write_critic
from agents.team.evaluate import TeamZero, run_team_episodes, team_baselines
from agents.team.residual import (MAX_RESIDUAL_SCALE, RESIDUAL_FILE, RESIDUAL_SCALE, TeamBase, read_residual,
                                  write_residual)
from esp_gym.team.tasks import TEAM_TASKS

ALGO = "rllib_team_ppo"
CONFIG_FILE = CONFIG_DIR / "rllib_team_ppo.yaml"
TEAM_ENV_ID = "ElasticStringTeam-v0"
#: The name the team's environment creator is registered under with Ray Tune's registry.
ENV_NAME = "esp_gym_team"
#: The shared policy's module id.
MODULE = "shared"
EVAL_SEED = 10_000


@dataclass
class Settings:
    team: int = field(default=3, metadata={"help": "strings K (1-6)", "type": int, "min": 1})
    task: str = field(default="transport", metadata={"help": "task", "choices": sorted(TEAM_TASKS)})
    preset: Optional[str] = field(default=None, metadata={"help": "the team's preset", "choices": ["hard"]})
    actuation: Optional[str] = field(default=None, metadata={
        "help": "the pivots are drones flown so (default: point pivots pushed by forces)",
        "choices": ["thrust_rates", "thrust_torque", "motors"]})
    iterations: int = field(default=100, metadata={
        "help": "training iterations (each samples train_batch_size_per_learner steps)", "type": int, "min": 1})
    time_limit: Optional[float] = field(default=None, metadata={
        "help": "minutes of training after which the run stops and saves", "type": float})
    seed: int = field(default=0, metadata={"help": "seed of the algorithm and of the environments", "type": int,
                                           "min": 0})
    set: list = field(default_factory=list, metadata={
        "help": "hyper-parameter overrides KEY=VALUE (YAML values, dotted keys; repeatable)", "nargs": "+",
        "action": "extend"})
    address: Optional[str] = field(default=None, metadata={
        "help": "a Ray cluster's head HOST:PORT or 'auto' (default: start Ray on this machine)"})
    runs: str = field(default=str(ROOT / "runs"), metadata={"help": "where run directories go"})
    run_name: Optional[str] = field(default=None, metadata={"help": "run directory name (default: generated)"})
    eval_episodes: int = field(default=10, metadata={
        "help": f"episodes of the final evaluation (seeds {EVAL_SEED}+)", "type": int, "min": 1})
    reference_episodes: int = field(default=10, metadata={
        "help": "episodes of the zero and LQR reference returns", "type": int, "min": 1})
    residual: bool = field(default=False, metadata={
        "help": "train a residual on the team's baseline (the LQR; with the hook observation the LQG)"})
    residual_scale: float = field(default=RESIDUAL_SCALE, metadata={
        "help": f"the residual's share of the action box, at most {MAX_RESIDUAL_SCALE:g} (with --residual)",
        "type": float})
    central_critic: bool = field(default=False, metadata={
        "help": "a centralised critic: the value function also reads the team's true state (agents/team/critic.py)"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    threads: int = field(default=1, metadata={"help": "torch threads of the learner", "type": int, "min": 1})


def team_parallel_env(env_config: dict):
    """The PettingZoo env of ``env_config``: with ``residual_scale`` the residual team of
    agents/team/residual.py, with ``central_critic`` the team's true state appended to every
    agent's observation (agents/team/critic.py)."""
    from agents.team.residual import TeamResidualParallelEnv
    from esp_gym.team import parallel_env

    options = dict(env_config)
    scale = options.pop("residual_scale", None)
    critic = options.pop("central_critic", False)
    env = parallel_env(**options)
    env = env if scale is None else TeamResidualParallelEnv(env, scale)
    if critic:
        from agents.team.critic import CentralCriticParallelEnv

        env = CentralCriticParallelEnv(env)
    return env


def make_team_env(env_config: dict):
    """RLlib's environment creator: :func:`team_parallel_env` as RLlib's MultiAgentEnv."""
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

    return ParallelPettingZooEnv(team_parallel_env(env_config))


def env_options(s: Settings) -> dict:
    """The team env's options of the run (its preset and actuation), as agents/team/evaluate.py takes them."""
    return {**({"preset": s.preset} if s.preset else {}), **({"actuation": s.actuation} if s.actuation else {})}


def env_config(s: Settings) -> dict:
    return {"team": s.team, "task": s.task, **env_options(s),
            **({"residual_scale": s.residual_scale} if s.residual else {}),
            **({"central_critic": True} if s.central_critic else {})}


def module_spec(cfg: RLlibRunConfig, s: Settings):
    """The shared module's RLModuleSpec: RLlib's default PPO module, or with ``--central-critic``
    agents/team/critic.py's (its actor's input length from the env)."""
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    if not s.central_critic:
        return RLModuleSpec()
    from agents.team.critic_module import CentralCriticModule

    env = team_parallel_env(env_config(s))
    return RLModuleSpec(module_class=CentralCriticModule,
                        model_config={"actor_inputs": env.actor_inputs, "fcnet_hiddens": cfg.model["fcnet_hiddens"],
                                      "fcnet_activation": cfg.model["fcnet_activation"]})


def team_ppo_config(cfg: RLlibRunConfig, s: Settings):
    """PPOConfig with one shared module for every agent."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.tune.registry import register_env

    register_env(ENV_NAME, make_team_env)
    return (PPOConfig()
            .environment(env=ENV_NAME, env_config=env_config(s))
            .multi_agent(policies={MODULE}, policy_mapping_fn=lambda agent_id, episode, **kw: MODULE)
            .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={MODULE: module_spec(cfg, s)}),
                       model_config=DefaultModelConfig(**cfg.model))
            .env_runners(num_env_runners=cfg.num_env_runners, num_envs_per_env_runner=cfg.num_envs_per_env_runner)
            .training(**cfg.training)
            .debugging(seed=s.seed, log_level="ERROR"))


def check_team_env(team: int, task: str, env_kwargs: dict) -> None:
    """Build the team's environment of these options once (no episode): ValueError naming them,
    with the environment's reason, where it refuses the combination (a winch's task for drones)."""
    from esp_gym.team import parallel_env

    try:
        parallel_env(team=team, task=task, **env_kwargs)
    except ValueError as err:
        given = " ".join(f"--{name} {value}" for name, value in (("team", team), ("task", task), *env_kwargs.items()))
        raise ValueError(f"the team's environment refuses {given}: {err}") from None


#: What a team checkpoint's configuration is compared by: its args.json's (agents.team.train's
#: arguments) that choose the environment.
TEAM_CONFIGURATION_FIELDS = ("team", "task", "preset", "actuation")


def team_checkpoint_configuration(checkpoint) -> Optional[dict]:
    """The :data:`TEAM_CONFIGURATION_FIELDS` a checkpoint was trained with, from the run's args.json
    (beside ``checkpoint/`` or in it); None where there is none (nothing to check)."""
    checkpoint = Path(checkpoint)
    for directory in (checkpoint.parent, checkpoint):
        if (directory / "args.json").is_file():
            run = json.loads((directory / "args.json").read_text())
            return {name: run.get(name) for name in TEAM_CONFIGURATION_FIELDS}
    return None


def check_team_checkpoint(checkpoint, team: int, task: str, env_kwargs: dict) -> None:
    """Before running ``checkpoint`` on a team of ``team`` on ``task`` with ``env_kwargs``:
    ConfigurationError where its agents' observations or actions (with a residual's features) do
    not fit these, a warning where only the configuration differs (as a single model's,
    agents.artifacts.check_configuration). Reads args.json and residual.json, not the module."""
    trained = team_checkpoint_configuration(checkpoint)
    if trained is None:
        return
    scale = read_residual(checkpoint)

    def sizes(c: dict) -> tuple:
        options = {name: c[name] for name in ("preset", "actuation") if c[name] is not None}
        env = team_parallel_env({"team": c["team"], "task": c["task"], **options,
                                 **({"residual_scale": scale} if scale is not None else {})})
        agent = env.possible_agents[0]
        return env.observation_space(agent).shape[0], env.action_space(agent).shape[0]

    now = {"team": team, "task": task, "preset": env_kwargs.get("preset"), "actuation": env_kwargs.get("actuation")}
    judge_configuration(checkpoint, trained, now, TEAM_CONFIGURATION_FIELDS, sizes)


class TeamRLlibPolicy:
    """The shared module of a checkpoint as a centralised policy of agents/team/evaluate.py: each
    agent's observation through the module's actor, the action distribution's mean
    (deterministic), clipped to [-1, 1], evaluated in float64 by agents/mlp.py. A checkpoint with
    residual.json (``--residual``) adds that share of it to the team's baseline, whose features it
    appends to each agent's observation, as in training; a centralised critic's
    (``--central-critic``) actor reads the agent's observation alone, as in training."""

    def __init__(self, checkpoint):
        from ray.rllib.core.rl_module.rl_module import RLModule

        checkpoint = Path(checkpoint).resolve()  # an absolute path: RLlib reads it as a URI
        self.module = RLModule.from_checkpoint(checkpoint / MODULE_PATH)
        #: the actor in float64, the same on every processor (agents/mlp.py): the mean of the
        #: module's Gaussian, its first half of outputs
        self.actor = actor_of_rllib(self.module, self.module.action_space.shape[0])
        self.scale = read_residual(checkpoint)
        self.base = None

    def act(self, obs, core) -> np.ndarray:
        agents = np.asarray(obs, dtype=np.float64).reshape(core.size, -1)
        if self.scale is not None:
            if self.base is None:
                self.base = TeamBase(core.observation, core.drones, core.winch)
            command, agents = self.base.observe(agents, core)
        # a centralised critic's actor reads the agent's observation only (agents/team/critic.py)
        mean = self.actor(agents.astype(np.float32))
        if self.scale is None:
            return np.clip(mean, -1.0, 1.0).ravel()
        return self.base.apply(command, mean, self.scale).ravel()


#: What a shipped team model keeps of its run: the shared module, residual.json and the record.
SHIPPED_RECORD = ("config.yaml", "args.json", "command.txt", "training.json", "progress.csv", "learning_curve.png",
                  "references.json", "evaluation.json")
MODULE_PATH = Path("learner_group") / "learner" / "rl_module" / MODULE


def ship(run_dir, target) -> Path:
    """Copy the finished run ``run_dir``'s shared module (``checkpoint/`` with only what
    :class:`TeamRLlibPolicy` reads: the module and residual.json) and its record into ``target``,
    which is replaced; returns ``target``.

        python -c "from agents.team.train import ship; ship('runs/RUN', 'models/team3_transport_hard_rllib')"
    """
    import shutil

    run_dir, target = Path(run_dir), Path(target)
    if not (run_dir / "checkpoint" / MODULE_PATH).is_dir():
        raise FileNotFoundError(f"run {run_dir} has no checkpoint/{MODULE_PATH}: it did not finish (see its status.json)")
    staging = target.with_name(target.name + ".new")
    shutil.rmtree(staging, ignore_errors=True)
    shutil.copytree(run_dir / "checkpoint" / MODULE_PATH, staging / "checkpoint" / MODULE_PATH)
    for name in [f"checkpoint/{RESIDUAL_FILE}", f"checkpoint/{CRITIC_FILE}", *SHIPPED_RECORD]:
        if (run_dir / name).is_file():
            shutil.copy2(run_dir / name, staging / name)
    shutil.rmtree(target, ignore_errors=True)
    staging.rename(target)
    return target


def check_settings(s: Settings) -> tuple:
    """``(config, run_dir)``; SettingsError naming the argument for anything wrong, before anything
    is written or started."""
    from esp_gym.team import MAX_STRINGS

    if s.team > MAX_STRINGS:
        raise SettingsError("--team", f"a team has 1 to {MAX_STRINGS} strings, got {s.team}")
    if s.time_limit is not None and not s.time_limit > 0:
        raise SettingsError("--time-limit", f"must be > 0 minutes, got {s.time_limit}")
    if not 0 < s.residual_scale <= MAX_RESIDUAL_SCALE:  # NaN fails too
        raise SettingsError("--residual-scale", f"must be in (0, {MAX_RESIDUAL_SCALE:g}] (the action box is 2 wide), "
                                                f"got {s.residual_scale}")
    # without --residual the scale is not read: one other than the default would be given for nothing
    if s.residual_scale != RESIDUAL_SCALE and not s.residual:
        raise SettingsError("--residual-scale", "only with --residual (the residual's share of the action box)")
    try:  # the environment built once: a combination it refuses is found before Ray starts
        check_team_env(s.team, s.task, env_options(s))
    except ValueError as err:
        raise SettingsError(None, str(err)) from None
    try:
        cfg = load_rllib_config(s.task, s.set, CONFIG_FILE, TEAM_ENV_ID)
    except ConfigError as err:
        raise SettingsError("--set" if err.override else None, str(err)) from None
    check_local_runners(s.address, cfg)
    run_dir = new_run_dir(s.runs, s.run_name, ALGO, s.task, s.seed)
    try:
        check_address(s.address)
    except AddressError as err:
        raise SettingsError("--address", str(err)) from None
    return cfg, run_dir


def _record(s: Settings, cfg: RLlibRunConfig, run_dir: Path, argv: Optional[list]) -> None:
    args = sys.argv[1:] if argv is None else list(argv)
    (run_dir / "config.yaml").write_text(yaml.safe_dump(cfg.model_dump(), sort_keys=False))
    (run_dir / "args.json").write_text(json.dumps(dataclasses.asdict(s), indent=2, default=json_default))
    (run_dir / "command.txt").write_text(shlex.join([sys.executable, "-m", "agents.team.train", *args]) + "\n")
    from esp_gym.team.tasks import TEAM_PRESETS

    kwargs = env_options(s)
    observation = TEAM_PRESETS.get(s.preset, {}).get("observation", "full")
    # the LQR, or the LQG with hook observations; a drone team's cascade; the lift's hoist
    from esp_gym.team.tasks import get_team_task

    winch = get_team_task(s.task).needs_winch
    baseline = next(iter(team_baselines(observation, s.actuation is not None, winch).values()))
    refs = {name: summarize(run_team_episodes(policy, s.team, s.task, s.reference_episodes, EVAL_SEED, kwargs),
                            s.task)["mean_return"]
            for name, policy in (("baseline_return", baseline), ("zero_return", TeamZero()))}
    (run_dir / "references.json").write_text(json.dumps(refs))


def run(s: Settings, cfg: RLlibRunConfig, run_dir: Path, algo, argv: Optional[list] = None, report=None) -> Path:
    """Train a built algorithm in ``run_dir`` for ``s.iterations`` (or ``s.time_limit``);
    status.json says ``running``, then ``finished``, ``interrupted`` or ``failed``. ``report``, if
    given, is called with each iteration's progress.csv row (agents.team.sweep: Tune's report)."""
    from tqdm.auto import tqdm

    run_dir.mkdir(parents=True)
    steps, done = 0, 0
    try:
        write_status(run_dir, "running", iterations=0, timesteps=0)
        _record(s, cfg, run_dir, argv)
        start = time.perf_counter()
        with open(run_dir / "progress.csv", "w", newline="") as fh, \
                tqdm(total=s.iterations, unit="it", desc="training", disable=not s.progress) as bar:
            log = csv.DictWriter(fh, fieldnames=PROGRESS_FIELDS)
            log.writeheader()
            for k in range(1, s.iterations + 1):
                row = progress_row(algo.train(), k)
                # RLlib sums an episode's rewards over its agents, each given the team's: the team's return
                row["episode_return_mean"] /= s.team
                log.writerow(row)
                fh.flush()
                steps, done = row["env_steps"], k
                bar.set_postfix(steps=steps, ret=f"{row['episode_return_mean']:.1f}")
                bar.update()
                if report is not None:
                    report(row)
                if s.time_limit is not None and time.perf_counter() - start > 60.0 * s.time_limit:
                    break
        wall = time.perf_counter() - start
        algo.save_to_path(str((run_dir / "checkpoint").resolve()))
        if s.residual:
            write_residual(run_dir / "checkpoint", s.residual_scale)
        if s.central_critic:
            env = team_parallel_env(env_config(s))
            write_critic(run_dir / "checkpoint", env.actor_inputs, env.state_size)
        (run_dir / "training.json").write_text(json.dumps(
            {"wall_time_s": wall, "iterations": done, "timesteps": steps, "address": s.address}, indent=2))
        kwargs = env_options(s)
        stats = summarize(run_team_episodes(TeamRLlibPolicy(run_dir / "checkpoint"), s.team, s.task, s.eval_episodes,
                                            EVAL_SEED, kwargs), s.task)
        (run_dir / "evaluation.json").write_text(json.dumps({**stats, "seed": EVAL_SEED}, indent=2))
        kind = ("shared residual on the baseline" if s.residual else "shared") + \
            (", centralised critic" if s.central_critic else "")
        drones = f" drones ({s.actuation})" if s.actuation else ""
        plot_curve(run_dir, f"{TEAM_ENV_ID} team of {s.team}{drones} {s.task} {s.preset or 'nominal'}: RLlib PPO, {kind} "
                            f"(seed {s.seed})")
        write_status(run_dir, "finished", iterations=done, timesteps=steps)
    except BaseException as err:  # Ctrl-C too: the directory says why it stopped
        write_stopped(run_dir, err, timesteps=steps)
        raise
    print(json.dumps({"run_dir": str(run_dir), "timesteps": steps, "wall_time_s": wall,
                      "mean_return": stats["mean_return"]}))
    return run_dir


def main(argv=None) -> Path:
    ap = settings_parser(Settings, prog="python -m agents.team.train", description=__doc__.split("\n\n")[0])
    return rllib_main(ap, Settings, argv, check_settings, lambda s, cfg: build(s, cfg, team_ppo_config), run)


if __name__ == "__main__":
    main()
