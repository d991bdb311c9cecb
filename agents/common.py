"""Shared pieces of the agent scripts: dataclass settings -> argparse, configs, environments,
progress bar, learning curves."""
from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
from pathlib import Path
from typing import Any, Optional

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from stable_baselines3.common.callbacks import BaseCallback
from tqdm.auto import tqdm

ROOT = Path(__file__).resolve().parent.parent
CONFIG_DIR = ROOT / "configs" / "agents"


def parse_settings(cls, argv=None, description: str = ""):
    """Build an argparse parser from a dataclass whose fields carry ``metadata={"help": ...}``."""
    ap = argparse.ArgumentParser(description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    for f in dataclasses.fields(cls):
        name = "--" + f.name.replace("_", "-")
        help_ = f.metadata.get("help", "")
        if f.type in ("bool", bool):
            ap.add_argument(name, action=argparse.BooleanOptionalAction, default=f.default, help=help_)
        elif f.metadata.get("nargs"):
            ap.add_argument(name, nargs=f.metadata["nargs"], default=[], metavar="KEY=VALUE", help=help_)
        else:
            typ = f.metadata.get("type", str)
            ap.add_argument(name, type=typ, default=f.default, choices=f.metadata.get("choices"), help=help_)
    return cls(**vars(ap.parse_args(argv)))


class RunConfig(BaseModel):
    """The validated hyper-parameters of one run (the algorithm's keyword arguments in ``algo``)."""

    model_config = ConfigDict(extra="forbid")
    n_envs: int = Field(ge=1)
    total_timesteps: int = Field(ge=1)
    normalize: Optional[dict] = None
    env_kwargs: dict = {}
    policy: str = "MlpPolicy"
    algo: dict = {}


def load_run_config(algo_name: str, env_id: str, task: str, overrides: list[str]) -> RunConfig:
    """Hyper-parameters from configs/agents/ALGO.yaml[env_id][task], with KEY=VALUE overrides
    (values parsed as YAML, dotted keys for nested dicts). Unknown keys raise ValueError naming them."""
    from stable_baselines3 import PPO, SAC

    path = CONFIG_DIR / f"{algo_name}.yaml"
    data = yaml.safe_load(path.read_text())
    try:
        raw = dict(data[env_id][task])
    except KeyError:
        raise ValueError(f"{path} has no entry {env_id}/{task}") from None
    for item in overrides:
        if "=" not in item:
            raise ValueError(f"override {item!r} is not KEY=VALUE")
        key, value = item.split("=", 1)
        node = raw
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = yaml.safe_load(value)
    cls = {"ppo": PPO, "sac": SAC}[algo_name]
    accepted = set(inspect.signature(cls.__init__).parameters) - {"self", "env", "policy"}
    top = set(RunConfig.model_fields) - {"algo"}
    algo_kwargs = {k: v for k, v in raw.items() if k not in top}
    unknown = sorted(set(algo_kwargs) - accepted)
    if unknown:
        raise ValueError(f"unknown hyper-parameter(s) {unknown} for {algo_name.upper()} (in {path} or overrides)")
    try:
        return RunConfig(**{k: v for k, v in raw.items() if k in top}, algo=algo_kwargs)
    except ValidationError as err:
        raise ValueError(f"invalid config {algo_name}/{env_id}/{task}: {err}") from None


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


def plot_learning_curve(run_dir: Path, title: str) -> Optional[Path]:
    """learning_curve.png from the training episodes (monitor) and EvalCallback's evaluations."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    mon = run_dir / "monitor.csv"
    if mon.is_file():
        rows = np.genfromtxt(mon, delimiter=",", skip_header=2)
        if rows.ndim == 2 and len(rows):
            steps = np.cumsum(rows[:, 1])
            k = max(1, len(rows) // 50)
            smooth = np.convolve(rows[:, 0], np.ones(k) / k, mode="valid")
            ax.plot(steps[k - 1:], smooth, color="tab:blue", alpha=0.8, label=f"training episodes (mean of {k})")
    ev = run_dir / "evaluations.npz"
    if ev.is_file():
        d = np.load(ev)
        mean, std = d["results"].mean(1), d["results"].std(1)
        ax.errorbar(d["timesteps"], mean, yerr=std, fmt="o-", color="tab:red", ms=3, label="deterministic evaluation")
    for name, style in (("baseline_return", "--"), ("zero_return", ":")):
        ref = run_dir / "references.json"
        if ref.is_file():
            val = json.loads(ref.read_text()).get(name)
            if val is not None:
                ax.axhline(val, color="k", ls=style, lw=1, label=name.replace("_", " "))
    ax.set_xlabel("environment steps")
    ax.set_ylabel("episode return")
    ax.set_title(title)
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
