"""The shipped policies by name, Stable-Baselines3's way (the ``agents`` extra).

    import esp_gym.zoo

    env = esp_gym.zoo.make("stabilize_hard_ppo")          # the environment it was trained for
    policy = esp_gym.zoo.load("stabilize_hard_ppo", env)  # follows env's episodes
    obs, _ = env.reset(seed=0)
    action, _ = policy.predict(obs, deterministic=True)   # the whole action: the base controller's
                                                          # plus the network's residual, clipped

Every directory under ``models/`` is a name (:func:`names`): the single environment's ``*_ppo``
policies and the teams' ``team3_*_rllib``. A policy's network acts in float64 with the same bits
on every x86-64 processor (agents/mlp.py); with its base's matrix products on one BLAS thread
(``threadpoolctl.threadpool_limits(1, "blas")``) and OpenBLAS's Haswell kernels
(``OPENBLAS_CORETYPE=Haswell``), an episode's return is the documented one (docs/compare,
docs/agents.md "The same returns on every x86-64 processor").
Its base controller (agents/baselines) reads the environment it acts in: the episode's target and
its physics; give that environment to :func:`load` or to :meth:`ZooPolicy.reset`. A stateful base
(a Kalman filter, a reference preview) starts afresh at each episode's first step.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from . import ENV_ID, TEAM_ENV_ID
from .extras import require


def models_dir() -> Path:
    """Where the shipped policies are (inside the installed ``agents`` package, or the checkout's
    ``models/``), once the agents extra (SB3 and torch, which the archives need) is there."""
    require("stable_baselines3", "esp_gym.zoo")
    import agents

    return agents.MODELS


def names() -> list:
    """The shipped policies' names: every directory under :func:`models_dir`."""
    return sorted(p.name for p in models_dir().iterdir() if p.is_dir() and not p.name.startswith((".", "_")))


def _path(name: str) -> Path:
    known = names()
    if name not in known:
        raise ValueError(f"no shipped policy {name!r}: the zoo has {', '.join(known)}")
    return models_dir() / name


def _is_team(path: Path) -> bool:
    """A team's RLlib checkpoint (``team3_*_rllib``), not a single environment's SB3 archive."""
    return (path / "checkpoint").is_dir()


def configuration(name: str) -> dict:
    """``{"env_id", "task", "env_kwargs"}`` of the environment ``name`` was trained for (and, for a
    team, ``"team"``)."""
    path = _path(name)
    if _is_team(path):  # agents.team.train's arguments
        run = json.loads((path / "args.json").read_text())
        return {"env_id": TEAM_ENV_ID, "team": run["team"], "task": run["task"],
                "env_kwargs": {k: run[k] for k in ("preset", "actuation") if run.get(k) is not None}}
    from agents.artifacts import model_configuration

    c = model_configuration(path / "model.zip")
    return {"env_id": ENV_ID, "task": c["task"], "env_kwargs": dict(c.get("env_kwargs") or {})}


def make(name: str, **overrides):
    """``gym.make`` of the environment ``name`` was trained for (``overrides``: more options)."""
    import gymnasium as gym

    c = configuration(name)
    extra = {"team": c["team"]} if "team" in c else {}
    return gym.make(c["env_id"], task=c["task"], **extra, **{**c["env_kwargs"], **overrides})


class ZooPolicy:
    """A shipped policy (or its base controller) acting in an environment: :meth:`predict` as
    Stable-Baselines3's, one call per step. ``env``: the environment it acts in (any wrapper of
    ``ElasticStringPendulum-v0`` or ``ElasticStringTeam-v0``), or None until :meth:`reset`."""

    def __init__(self, name: str, policy, env=None):
        self.name, self.policy = name, policy
        self._env = None
        if env is not None:
            self.reset(env)

    def reset(self, env) -> None:
        """Act in ``env`` from now on; its next step is an episode's first."""
        self._env = env.unwrapped
        self._team = hasattr(self._env, "core")  # ElasticStringTeam-v0 (its TeamCore)
        self._last_step = None

    def _new_episode(self) -> bool:
        step = self._env.sim.step_count
        new = self._last_step is None or step == 0 or step < self._last_step
        self._last_step = step
        return new

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """``(action, None)``: the whole action for ``observation`` (the base controller's plus
        the network's, clipped to the box). ``episode_start``: True restarts a stateful base (it also
        restarts by itself at each episode's first step). Shipped policies act by their mean:
        ``deterministic=False`` is refused."""
        if not deterministic:
            raise ValueError(f"{self.name}: shipped policies act deterministically (the mean action); "
                             f"deterministic=False is not available")
        if self._env is None:
            raise RuntimeError(f"{self.name}: its base controller reads the environment it acts in: "
                               f"esp_gym.zoo.load({self.name!r}, env) or policy.reset(env) first")
        if self._team:
            return np.asarray(self.policy.act(observation, self._env.core), dtype=np.float32), None
        if self._new_episode() or (episode_start is not None and bool(np.any(episode_start))):
            if hasattr(self.policy, "reset"):
                self.policy.reset(self._env)
        return np.asarray(self.policy.act(observation, self._env.setup), dtype=np.float32), None


def load(name: str, env=None) -> ZooPolicy:
    """The shipped policy ``name`` (one of :func:`names`), acting in ``env`` if given."""
    path = _path(name)
    if _is_team(path):
        from agents.team.train import TeamRLlibPolicy

        return ZooPolicy(name, TeamRLlibPolicy(path / "checkpoint"), env)
    from agents.evaluate import SB3Policy

    return ZooPolicy(name, SB3Policy(path / "model.zip"), env)


def baseline(name: str, env=None) -> ZooPolicy:
    """The classical controller the single-environment policy ``name`` adds its residual to (its
    configuration's best baseline), acting in ``env`` if given."""
    path = _path(name)
    from agents.residual import residual_for

    base = None if _is_team(path) else residual_for(path / "model.zip")
    if base is None:
        raise ValueError(f"{name} has no base controller (only the single environment's residual policies do)")
    # a stateful base is shared with the policy's (agents.baselines.registry): a copy of its own
    return ZooPolicy(f"{name} base", base.clone() if hasattr(base, "clone") else base, env)
