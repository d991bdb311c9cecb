"""Shared pieces of the agent scripts: run configs (with ``--set`` overrides), schedules, the
progress bar, learning curves."""
from __future__ import annotations

import copy
import inspect
import json
import re
import time
from pathlib import Path
from typing import Any, Callable, Literal, Optional

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from stable_baselines3.common.callbacks import BaseCallback
from tqdm.auto import tqdm

from agents import CONFIG_DIR


class RunConfig(BaseModel):
    """The validated hyper-parameters of one run (the algorithm's keyword arguments in ``algo``)."""

    model_config = ConfigDict(extra="forbid")
    n_envs: int = Field(ge=1)
    total_timesteps: int = Field(ge=1)
    normalize: Optional[dict] = None
    env_kwargs: dict = {}
    policy: str = "MlpPolicy"
    #: observations per input: the policy sees the last ``frame_stack`` (normalised) ones
    #: (SB3 VecFrameStack), the memory an observation without the load's state needs
    frame_stack: int = Field(default=1, ge=1)
    #: a baseline the policy's action is added to (agents/residual.py), or None
    residual: Optional[Literal["pd", "lqr", "lqg", "geometric"]] = None
    #: PPO only: the critic also sees the simulator's state and the episode's parameters
    #: (agents/privileged.py), the actor the observation alone
    privileged_critic: bool = False
    #: PPO only: environment steps during which the actor is held (only the critic learns), so
    #: that a residual policy's first updates follow a trained critic, not a random one
    critic_warmup: int = Field(default=0, ge=0)
    #: training episodes end (truncated, their value bootstrapped) after this many steps, so that
    #: more of the samples are transients; None: the environment's own. Evaluations keep the
    #: environment's full episodes
    episode_steps: Optional[int] = Field(default=None, ge=1)
    #: PPO with a residual: before training, fit the actor to this many teacher episodes (the base
    #: plus a feed-forward optimised per episode, agents/distill.py); 0: none
    distill_episodes: int = Field(default=0, ge=0)
    #: episodes the teacher's optimiser may run per teacher episode
    distill_evaluations: int = Field(default=600, ge=1)
    #: the teacher's feed-forward values per axis over an episode
    distill_knots: int = Field(default=11, ge=2)
    algo: dict = {}


class ConfigError(ValueError):
    """A bad hyper-parameter, named with its dotted key; ``override`` is the ``--set`` item at
    fault, or None when the config file itself is."""

    def __init__(self, message: str, override: Optional[str] = None):
        super().__init__(message)
        self.override = override


class ValueLoader(yaml.SafeLoader):
    """YAML as written on a command line: ``3e-4`` is a float (YAML 1.1 wants ``3.0e-4``)."""


ValueLoader.add_implicit_resolver("tag:yaml.org,2002:float",
                                   re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
                                   list("-+0123456789"))

#: Run keys the training script passes itself, so a config may not set them.
MANAGED_KEYS = {"self", "env", "policy", "seed", "device", "verbose", "_init_setup_model"}
#: The keys of a dict ``policy_kwargs.net_arch`` (the actor's and the critic's layers).
NET_ARCH_KEYS = {"ppo": {"pi", "vf"}, "sac": {"pi", "qf"}}


def _parameters(func, exclude) -> set:
    return set(inspect.signature(func).parameters) - set(exclude)


def valid_keys(algo_name: str, path: tuple, tree: dict) -> Optional[set]:
    """The keys a mapping at dotted ``path`` of a run config may hold, or None where this is
    checked by whoever uses the value (e.g. ``env_kwargs.scene_overrides``, by the scene loader)."""
    from stable_baselines3 import PPO, SAC

    algo = {"ppo": PPO, "sac": SAC}[algo_name]
    if path == ():
        return (set(RunConfig.model_fields) - {"algo"}) | _parameters(algo.__init__, MANAGED_KEYS)
    if path == ("normalize",):
        from stable_baselines3.common.vec_env import VecNormalize

        return _parameters(VecNormalize.__init__, {"self", "venv", "training", "gamma"})  # gamma: the algorithm's
    if path == ("policy_kwargs",):
        policy = algo.policy_aliases.get(tree.get("policy", "MlpPolicy"))
        if policy is None:
            return None  # an unknown policy is the algorithm's error
        return _parameters(policy.__init__, {"self", "observation_space", "action_space", "lr_schedule"})
    if path == ("policy_kwargs", "net_arch"):
        return NET_ARCH_KEYS[algo_name]
    if path == ("env_kwargs",):
        from esp_gym.pendulum.env_setup import make_setup

        return _parameters(make_setup, {"task"})  # the task is --task
    return None


#: The keys a mapping may hold: ``rule(path, root)`` for the mapping at dotted ``path`` of the
#: config ``root``, or None where whoever reads the value checks it.
KeyRule = Callable[[tuple, dict], Optional[set]]


def sb3_keys(algo_name: str) -> KeyRule:
    """The key rule of an SB3 run config (:func:`valid_keys`)."""
    return lambda path, root: valid_keys(algo_name, path, root)


def first_unknown_key(rule: KeyRule, root: dict, node: Optional[dict] = None, path: tuple = ()) -> Optional[str]:
    """The first key of the mapping ``node`` at dotted ``path`` of the config ``root`` (default: the
    whole config) that ``rule`` does not allow, as a message naming it and the valid keys."""
    node = root if node is None else node
    if not node:
        return None
    valid = rule(path, root)
    for key, value in node.items():
        if valid is not None and key not in valid:
            return _unknown(path + (key,), valid)
        if isinstance(value, dict):
            found = first_unknown_key(rule, root, value, path + (key,))
            if found:
                return found
    return None


def _unknown(path: tuple, valid: set) -> str:
    where = f" of {'.'.join(path[:-1])}" if len(path) > 1 else ""
    return f"unknown key {'.'.join(path)!r}; valid keys{where}: {', '.join(sorted(valid))}"


def apply_override(rule: KeyRule, tree: dict, item: str, example: str = "policy_kwargs.net_arch=[64,64]") -> None:
    """Set ``KEY=VALUE`` in ``tree``: the value parsed as YAML, a dotted key walking into
    nested mappings (created where absent); each key along the way must be one ``rule`` allows.
    ``example``: a dotted item for the message about a malformed one."""
    key, sep, text = item.partition("=")
    parts = key.strip().split(".")
    if not sep or not all(parts):
        raise ConfigError(f"{item!r} is not KEY=VALUE (KEY may be dotted: {example})", item)
    try:
        value = yaml.load(text, Loader=ValueLoader)
    except yaml.YAMLError as err:
        problem = getattr(err, "problem", None) or " ".join(str(err).split())
        raise ConfigError(f"{item!r}: the value is not YAML ({problem})", item) from None
    node = tree
    for i, part in enumerate(parts):
        valid = rule(tuple(parts[:i]), tree)
        if valid is not None and part not in valid:
            raise ConfigError(_unknown(tuple(parts[:i + 1]), valid) + f" (in {item!r})", item)
        if i == len(parts) - 1:
            node[part] = value
        else:
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            elif not isinstance(child, dict):
                raise ConfigError(f"{'.'.join(parts[:i + 1])} is {child!r}, not a mapping, so {key!r} cannot be set "
                                  f"(in {item!r})", item)
            node = child
    if isinstance(value, dict):
        found = first_unknown_key(rule, tree, value, tuple(parts))
        if found:
            raise ConfigError(f"{found} (in {item!r})", item)


def _build(algo_name: str, raw: dict) -> "RunConfig":
    top = set(RunConfig.model_fields) - {"algo"}
    algo_kwargs = {k: v for k, v in raw.items() if k not in top}
    try:
        cfg = RunConfig(**{k: v for k, v in raw.items() if k in top}, algo=algo_kwargs)
    except ValidationError as err:
        problems = "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']} (got {e.get('input')!r})"
                             for e in err.errors())
        raise ValueError(problems) from None
    resolve_schedules(cfg.algo)  # "lin_X" or a number
    return cfg


def load_run_config(algo_name: str, env_id: str, task: str, overrides: list[str]) -> RunConfig:
    """Hyper-parameters from configs/agents/ALGO.yaml[env_id][task] with ``KEY=VALUE`` overrides
    applied in order (see :func:`apply_override`). A bad key or value raises :class:`ConfigError`
    naming it and, for a key, the valid ones."""
    path = CONFIG_DIR / f"{algo_name}.yaml"
    data = yaml.load(path.read_text(), Loader=ValueLoader)
    try:
        raw = copy.deepcopy(dict(data[env_id][task]))
    except (KeyError, TypeError):
        raise ConfigError(f"{path} has no entry {env_id}/{task}") from None
    where = f"{path} [{env_id}][{task}]"
    found = first_unknown_key(sb3_keys(algo_name), raw)
    if found:
        raise ConfigError(f"{where}: {found}")
    try:
        cfg = _build(algo_name, raw)
    except ValueError as err:
        raise ConfigError(f"{where}: {err}") from None
    for item in overrides:
        apply_override(sb3_keys(algo_name), raw, item)
        try:
            cfg = _build(algo_name, raw)
        except ValueError as err:
            raise ConfigError(f"{err} (after {item!r})", item) from None
    return cfg


def linear_schedule(start: float):
    """SB3 schedule falling linearly from ``start`` to 0 over training (progress 1 -> 0)."""
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * start
    return schedule


def resolve_schedules(algo_kwargs: dict) -> dict:
    """Turn "lin_X" values of learning_rate / clip_range into linear schedules (zoo style)."""
    out = dict(algo_kwargs)
    for key in ("learning_rate", "clip_range"):
        value = out.get(key)
        if isinstance(value, str):
            if not value.startswith("lin_"):
                raise ValueError(f"{key}: {value!r} is neither a number nor lin_<start>")
            out[key] = linear_schedule(float(value[4:]))
    return out


class TqdmCallback(BaseCallback):
    """A tqdm progress bar over the training timesteps (SB3's own needs `rich`)."""

    def __init__(self, total: int, disable: bool = False):
        super().__init__()
        self.total, self.disable = total, disable

    def _on_training_start(self) -> None:
        self.bar = tqdm(total=self.total, initial=self.model.num_timesteps, unit="step", unit_scale=True,
                        disable=self.disable, desc="training")

    def _on_step(self) -> bool:
        self.bar.update(self.model.num_timesteps - self.bar.n)
        return True

    def _on_training_end(self) -> None:
        self.bar.close()


class TimeLimitCallback(BaseCallback):
    """Stops training once ``seconds`` of wall time have passed since it started (checked after
    every environment step; the run then saves its model as at the end)."""

    def __init__(self, seconds: float):
        super().__init__()
        self.seconds = float(seconds)
        self.stopped = False

    def _on_training_start(self) -> None:
        self.start = time.perf_counter()

    def _on_step(self) -> bool:
        self.stopped = time.perf_counter() - self.start >= self.seconds
        return not self.stopped


class CriticWarmup(BaseCallback):
    """Holds the actor of an SB3 actor-critic (its layers, its mean's output and its log std) for
    the first ``steps`` environment steps, so that only the critic learns (the optimiser skips
    parameters without a gradient); then lets it learn as usual."""

    def __init__(self, steps: int):
        super().__init__()
        self.steps = int(steps)
        self.held = False

    def _actor(self) -> list:
        policy = self.model.policy
        return (list(policy.mlp_extractor.policy_net.parameters()) + list(policy.action_net.parameters())
                + [policy.log_std])

    def _hold(self, held: bool) -> None:
        for parameter in self._actor():
            parameter.requires_grad_(not held)
        self.held = held

    def _on_training_start(self) -> None:
        if self.model.num_timesteps < self.steps:
            self._hold(True)

    def _on_rollout_start(self) -> None:
        if self.held and self.model.num_timesteps >= self.steps:
            self._hold(False)

    def _on_step(self) -> bool:
        return True


#: Evaluations averaged for the residual panel's running mean (each is 10 episodes, 50,000 steps apart).
EVALUATION_WINDOW = 10


def plot_learning_curve(run_dir: Path, title: str) -> Optional[Path]:
    """learning_curve.png from the training episodes (monitor) and EvalCallback's evaluations,
    with the reference returns as lines. A residual run's curve gets a second panel near its
    base's return: the evaluations' running mean over EVALUATION_WINDOW of them against it (the
    full scale, down to the zero action, hides a gain of a few points)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = run_dir / "references.json"
    references = json.loads(ref.read_text()) if ref.is_file() else {}
    base = references.get("residual_base_return")
    fig, axes = plt.subplots(1, 2 if base is not None else 1, figsize=(12 if base is not None else 7, 4),
                             layout="constrained", squeeze=False)
    ax = axes[0, 0]
    mon = run_dir / "monitor.csv"
    if mon.is_file():
        rows = np.genfromtxt(mon, delimiter=",", skip_header=2)
        if rows.ndim == 2 and len(rows):
            steps = np.cumsum(rows[:, 1])
            k = max(1, len(rows) // 50)
            smooth = np.convolve(rows[:, 0], np.ones(k) / k, mode="valid")
            ax.plot(steps[k - 1:], smooth, color="tab:blue", alpha=0.8, label=f"training episodes (mean of {k})")
    ev = run_dir / "evaluations.npz"
    evaluations = None
    if ev.is_file():
        d = np.load(ev)
        evaluations = d["timesteps"], d["results"].mean(1)
        ax.errorbar(d["timesteps"], evaluations[1], yerr=d["results"].std(1), fmt="o-", color="tab:red", ms=3,
                    label="deterministic evaluation")
    for name, style in (("baseline_return", "--"), ("residual_base_return", "-."), ("zero_return", ":")):
        if references.get(name) is not None:
            ax.axhline(references[name], color="k", ls=style, lw=1, label=name.replace("_", " "))
    if base is not None:
        near = axes[0, 1]
        if evaluations is not None and len(evaluations[0]) >= EVALUATION_WINDOW:
            steps, means = evaluations
            window = np.ones(EVALUATION_WINDOW) / EVALUATION_WINDOW
            near.plot(steps, means, ".", color="tab:red", alpha=0.35, ms=3, label="evaluation (10 episodes)")
            near.plot(steps[EVALUATION_WINDOW - 1:], np.convolve(means, window, mode="valid"), color="tab:red",
                      label=f"running mean of {EVALUATION_WINDOW} evaluations")
            spread = max(np.percentile(np.abs(means - base), 95), 1.0)
            near.set_ylim(base - 1.5 * spread, base + 1.5 * spread)
        near.axhline(base, color="k", ls="-.", lw=1, label="residual base return")
        if references.get("baseline_return") is not None:
            near.axhline(references["baseline_return"], color="k", ls="--", lw=1, label="baseline return")
        near.set(xlabel="environment steps", ylabel="episode return", title="near the base")
        near.grid(True, alpha=0.3)
        near.legend(loc="lower right", fontsize=8)
    return save_learning_curve(fig, ax, run_dir, title)


def save_learning_curve(fig, ax, run_dir: Path, title: str) -> Path:
    """Label a learning curve's axes (environment steps, episode return), title, grid and legend,
    and write it to ``run_dir/learning_curve.png``; closes the figure."""
    import matplotlib.pyplot as plt

    ax.set(xlabel="environment steps", ylabel="episode return", title=title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    out = run_dir / "learning_curve.png"
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def json_default(x: Any):
    if isinstance(x, (np.integer, np.floating)):
        return x.item()
    if isinstance(x, Path):
        return str(x)
    return str(x)
