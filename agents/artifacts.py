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
