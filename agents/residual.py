"""Residual policies: the trained network's action is added to a classical baseline's, and the
sum clipped to the box, so learning starts from the baseline and refines it (residual policy
learning). A run with ``residual: pd`` in its config trains through :class:`ResidualVecEnv`
and writes ``residual.json`` beside its model; agents.evaluate.SB3Policy reads it back and
adds the same baseline when it acts.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import numpy as np
from stable_baselines3.common.vec_env import VecEnvWrapper

#: The baselines a residual may start from (stateless, batched: they act on the raw observation).
BASES = ("pd",)
RESIDUAL_FILE = "residual.json"


def base_policy(name: str, task: str):
    """The baseline ``name`` of ``task``."""
    from agents.controllers import baseline

    if name not in BASES:
        raise ValueError(f"residual must be one of {BASES}, got {name!r}")
    return baseline(task)


class ResidualVecEnv(VecEnvWrapper):
    """Steps ``venv`` with clip(action + base(observation)): the base acts on the observation the
    policy was given (raw, before any normalisation), ``setup`` the environments' EnvSetup."""

    def __init__(self, venv, base, setup):
        super().__init__(venv)
        self.base, self.setup = base, setup
        self._obs = None

    def reset(self):
        self._obs = self.venv.reset()
        return self._obs

    def step_async(self, actions: np.ndarray) -> None:
        self.venv.step_async(np.clip(actions + self.base.act(self._obs, self.setup), -1.0, 1.0).astype(np.float32))

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        self._obs = obs  # after an automatic reset: the next episode's first observation
        return obs, rewards, dones, infos


def write_residual(run_dir: Path, name: str, task: str) -> None:
    (Path(run_dir) / RESIDUAL_FILE).write_text(json.dumps({"base": name, "task": task}) + "\n")


def residual_for(model: Path) -> Optional[object]:
    """The base policy of the run a model file belongs to (``residual.json`` beside it, or in
    the run directory above a checkpoint), or None for a plain policy."""
    model = Path(model)
    for directory in (model.parent, model.parent.parent):
        path = directory / RESIDUAL_FILE
        if path.is_file():
            spec = json.loads(path.read_text())
            return base_policy(spec["base"], spec["task"])
    return None
