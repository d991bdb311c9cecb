"""Reading back what training writes: a model archive (with a clear error naming the file when
it is not one) and the normalisation statistics that belong to it.

Trust: an SB3 ``.zip`` holds cloudpickled Python objects, and loading one can run code from it;
load only models you trust (docs/agents.md, "Trust"). The statistics are read as data
(agents/normalization.py).
"""
from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path
from typing import Optional

#: Checkpoints are ``RUN/checkpoints/model_N_steps.zip`` (N: environment steps).
CHECKPOINT = re.compile(r"model_(\d+)_steps\.zip")
#: The policy class's module in an SB3 archive's ``data`` -> the algorithm that trained it.
#: The modules a model's policy class may come from, and the algorithm it belongs to (this
#: project's own: the asymmetric actor-critic of agents/privileged.py, trained with PPO).
POLICY_MODULES = {"stable_baselines3.common.policies": "ppo", "stable_baselines3.sac.policies": "sac",
                  "agents.privileged": "ppo"}


class ModelFileError(ValueError):
    """A model file that is missing or cannot be loaded; the message names the file."""


def checkpoint_steps(path: str | Path) -> Optional[int]:
    """N of a checkpoint named ``model_N_steps.zip``; None for any other name."""
    m = CHECKPOINT.fullmatch(Path(path).name)
    return int(m.group(1)) if m else None


def checkpoint_files(directory: Path, steps: int) -> dict:
    """The files of the checkpoint at ``steps``: the model, its normalisation statistics and the
    history marker (how far the run's monitor log had got)."""
    return {"model": directory / f"model_{steps}_steps.zip",
            "stats": directory / f"model_vecnormalize_{steps}_steps.npz",
            "history": directory / f"model_history_{steps}_steps.json"}


def stats_path_for(model: str | Path) -> Optional[Path]:
    """The normalisation statistics that belong to a model file, or None: beside a checkpoint
    ``model_N_steps.zip`` they are ``model_vecnormalize_N_steps``, beside any other model
    ``vecnormalize``; ``.npz`` is preferred to a legacy ``.pkl``."""
    model = Path(model)
    steps = checkpoint_steps(model)
    stem = f"model_vecnormalize_{steps}_steps" if steps is not None else "vecnormalize"
    for suffix in (".npz", ".pkl"):
        candidate = model.parent / (stem + suffix)
        if candidate.is_file():
            return candidate
    return None


def model_algorithm(path: str | Path) -> str:
    """"ppo" or "sac", read from the archive's JSON metadata (nothing is unpickled)."""
    path = Path(path)
    if path.is_dir():
        raise ModelFileError(f"{path}: a directory, not a model .zip")
    if not path.is_file():
        raise ModelFileError(f"{path}: no such model file")
    try:
        with zipfile.ZipFile(path) as archive:
            names = set(archive.namelist())
            missing = [n for n in ("data", "policy.pth") if n not in names]
            if missing:
                raise ModelFileError(f"{path}: not a Stable-Baselines3 model (the archive has no {' or '.join(missing)})")
            data = json.loads(archive.read("data"))
    except (zipfile.BadZipFile, OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ModelFileError(f"{path}: not a Stable-Baselines3 model ({type(err).__name__}: {err})") from None
    module = data.get("policy_class", {}).get("__module__") if isinstance(data, dict) else None
    if module not in POLICY_MODULES:
        raise ModelFileError(f"{path}: not a PPO or SAC model (policy class from {module!r})")
    return POLICY_MODULES[module]


def load_model(path: str | Path, env=None):
    """The SB3 model in ``path`` (on the CPU, with ``env`` attached if given). Raises
    :class:`ModelFileError` naming the file for anything that is not a loadable PPO or SAC model."""
    from stable_baselines3 import PPO, SAC

    algo = model_algorithm(path)
    try:
        return {"ppo": PPO, "sac": SAC}[algo].load(path, env=env, device="cpu")
    except Exception as err:  # SB3 reports a damaged archive by assert, KeyError, RuntimeError, ...
        reason = " ".join(f"{type(err).__name__}: {err}".split())
        raise ModelFileError(f"{path}: cannot be loaded as a {algo.upper()} model ({reason})") from err


class ConfigurationError(ValueError):
    """A model run in a configuration whose observations or actions it cannot take."""


#: What a model's configuration is compared by: the task, the preset, the observation mode and
#: the winch (the ones that change the observation or the action: ``layout``) and the realism
#: options that change the task's difficulty.
CONFIGURATION_FIELDS = ("task", "preset", "observation", "winch", "randomize", "wind", "sensor_noise",
                        "action_latency")


def model_configuration(model: str | Path) -> Optional[dict]:
    """The configuration a model was trained in: ``{"task": ..., "env_kwargs": ...}`` from the
    ``args.json`` and ``config.yaml`` of its run directory (beside the model, or above a
    checkpoint); None where they are missing (a model saved by hand)."""
    import yaml

    model = Path(model)
    for directory in (model.parent, model.parent.parent):
        args, config = directory / "args.json", directory / "config.yaml"
        if args.is_file() and config.is_file():
            task = json.loads(args.read_text()).get("task")
            env_kwargs = (yaml.safe_load(config.read_text()) or {}).get("env_kwargs") or {}
            if isinstance(task, str) and isinstance(env_kwargs, dict):
                return {"task": task, "env_kwargs": env_kwargs}
    return None


def describe_configuration(task: str, env_kwargs: Optional[dict]) -> dict:
    """The resolved :data:`CONFIGURATION_FIELDS` of a task and its environment options, with the
    observation and action sizes (``layout``)."""
    from esp_gym.pendulum.env_setup import make_setup

    setup = make_setup(task=task, **(env_kwargs or {}))
    return {"task": setup.task.name, "preset": (env_kwargs or {}).get("preset"), "observation": setup.observer.mode,
            "winch": setup.winch, "randomize": setup.randomizer is not None, "wind": setup.wind is not None,
            "sensor_noise": bool(setup.observer.noise_std.any()), "action_latency": setup.action_latency,
            "layout": (setup.observer.layout.size, setup.action_size)}


def check_configuration(model: str | Path, trained: Optional[dict], task: str, env_kwargs: Optional[dict]) -> None:
    """A model trained in ``trained`` (:func:`model_configuration`; None: unknown, nothing to
    check) run on ``task`` with ``env_kwargs``: ConfigurationError naming both where its
    observations or actions differ in size, a warning naming the differences where only the
    configuration does."""
    if trained is None:
        return
    was = describe_configuration(trained["task"], trained["env_kwargs"])
    now = describe_configuration(task, env_kwargs)
    judge_configuration(model, was, now, CONFIGURATION_FIELDS, lambda configuration: configuration["layout"])


def judge_configuration(model, was: dict, now: dict, fields, sizes) -> None:
    """The verdict on a model trained in the configuration ``was`` run in ``now`` (dicts holding
    ``fields``): nothing where they agree; where they differ, ConfigurationError naming the
    differences where ``sizes(configuration)`` (the observation and action sizes) differ too, else
    a warning naming them. ``sizes`` is called only then (it may build an environment)."""
    differ = [f"{name} {now[name]!r} (trained with {was[name]!r})" for name in fields if now[name] != was[name]]
    if not differ:
        return
    text = f"{model} was trained on another configuration: " + ", ".join(differ)
    trained, running = sizes(was), sizes(now)
    if running != trained:
        raise ConfigurationError(f"{text}; its observations and actions (sizes {trained}) do not fit these ({running})")
    import warnings

    warnings.warn(f"{text}; it runs (the sizes fit), but it did not learn this configuration", stacklevel=4)
