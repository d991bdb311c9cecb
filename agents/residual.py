"""Residual policies: the trained network's action is added to a classical baseline's, and the
sum clipped to the box, so learning starts from the baseline and refines it (residual policy
learning). A run with ``residual: pd``, ``lqg`` or ``geometric`` in its config trains through
:class:`ResidualVecEnv` and writes ``residual.json`` beside its model; agents.evaluate.SB3Policy
reads it back and adds the same baseline when it acts.

``pd`` and ``lqr`` (stabilize, transport) are stateless and act on the raw observation; ``track``'s
``lqr`` follows each episode's reference and appends its context (agents/baselines/lqr.py
REFERENCE_CONTEXT) to the observation. ``lqg`` (hook observation) is a Kalman
filter per environment: it is told the action actually applied (base plus network), and the
network also sees its estimate [z; q; f] (agents/baselines/lqg.py; for ``track`` also the reference's
feed-forward, velocity and displacement ahead), appended to the observation, so the
policy starts from the filter's state rather than from raw hook readings. ``geometric`` (a drone
at the pivot) is the load-led cascade of agents/baselines/geometric.py; on the hook observation it
is stateful too, its load estimate (agents/baselines/load_estimate.py ESTIMATE) appended likewise.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnvWrapper

#: The baselines a residual may start from.
BASES = ("pd", "lqr", "lqg", "geometric")
RESIDUAL_FILE = "residual.json"


def base_policy(name: str, task: str, env_kwargs: Optional[dict] = None):
    """The baseline ``name`` of ``task`` under the environment options ``env_kwargs`` (one
    environment's; :class:`BatchedBase` runs it over a batch)."""
    from agents.baselines.registry import baseline_factories

    if name not in BASES:
        raise ValueError(f"residual must be one of {BASES}, got {name!r}")
    if name == "lqr":
        return nominal_lqr(task, env_kwargs)
    known = baseline_factories(task, env_kwargs)  # "pd" is the winch's Hoist where the task reels
    if name not in known:
        needs = ("a drone's scene (with a winch, the full observation)" if name == "geometric"
                 else "the hook observation (env_kwargs observation: hook or preset: hard)")
        raise ValueError(f"residual {name!r} needs {needs}; with {env_kwargs or {}} the baselines are {sorted(known)}")
    base = known[name]()
    if task == "track" and not hasattr(base, "clone"):  # a law that holds no reference: tell the network it
        return ReferenceContext(base)
    return base


#: What :class:`ReferenceContext` tells a residual network of a ``track`` reference: its velocity
#: [m/s] and acceleration [m/s^2] now and its displacement [m] over the next PREVIEW_TIMES [s]
#: (agents/baselines/lqr.py's, the LQR tracker's preview).
TRACK_CONTEXT = (("reference_velocity", 3), ("reference_acceleration", 3), ("reference_ahead", 6))


class ReferenceContext:
    """A stateless law on ``track`` (the drone's geometric cascade, which reads the errors against
    the moving target but not its curve) as a residual's stateful base: one copy per environment
    following its episode's reference (:meth:`start` with the live TARGET view), the law's action
    unchanged, and the reference's TRACK_CONTEXT as its :attr:`features`, as the LQR tracker tells
    its network the reference's REFERENCE_CONTEXT."""

    def __init__(self, law):
        self.law = law
        self.start(None)

    def clone(self) -> "ReferenceContext":
        return ReferenceContext(self.law)

    def reset(self, env) -> None:
        if hasattr(self.law, "reset"):
            self.law.reset(env)
        self.start(env.control.target)

    def start(self, target) -> None:
        self._target = target
        self._context = np.zeros(sum(size for _, size in TRACK_CONTEXT))

    def applied(self, action) -> None:
        """The law holds no estimate: what was applied changes nothing."""

    @property
    def features(self) -> np.ndarray:
        return self._context

    def act(self, obs, setup) -> np.ndarray:
        from agents.baselines.lqr import PREVIEW_TIMES, REDUCED, reference_basis, reference_map
        from esp_gym.layouts import TARGET
        from esp_gym.pendulum.tasks import reference_acceleration

        target = self._target
        if target is not None and target[TARGET.scalar("rate")] != 0.0:
            z = reference_map(target, np.array((0.0,) + PREVIEW_TIMES)) @ reference_basis(target)
            place = REDUCED["pivot_error"]
            self._context = np.concatenate((z[0, REDUCED["pivot_velocity"]],
                                            reference_acceleration(target, float(target[TARGET.scalar("clock")])),
                                            (z[1:, place] - z[0, place]).ravel()))
        return self.law.act(obs, setup)


def nominal_lqr(task: str, env_kwargs: Optional[dict] = None):
    """The LQR of ``task`` designed once for the nominal scene (agents/baselines/lqr.py, the
    registry's weights): the registry's ``lqr`` on every episode of a configuration that draws no
    scene. stabilize's and transport's is stateless, so a batch shares it; ``track``'s
    (LQRTracker) follows each episode's reference, one copy per environment, and tells the network
    the reference's context."""
    from agents.baselines.lqr import LQR, LQRTracker
    from agents.baselines.registry import LQR_WEIGHT
    from esp_gym.pendulum.env_setup import make_setup

    setup = make_setup(task=task, **(env_kwargs or {}))
    if task not in LQR_WEIGHT:
        raise ValueError(f"residual 'lqr' has a design for the tasks {sorted(LQR_WEIGHT)}; task {task!r} has none")
    if setup.randomizer is not None or setup.drone or setup.winch or setup.observer.mode != "full":
        raise ValueError(f"residual 'lqr' is one design for the nominal scene: it needs the point pivot, the full "
                         f"observation, no winch and no randomize; got {env_kwargs or {}}")
    design = LQRTracker.design if task == "track" else LQR.design
    return design(setup, None, LQR_WEIGHT[task])


def base_features(base, batch: tuple = ()) -> np.ndarray:
    """What the network sees of a base beside the observation: a stateful base's ``features``
    (its estimate, and a ``track`` design's reference context, agents/baselines/lqg.py), shape batch + (k,),
    or an empty (..., 0) array for a stateless one."""
    features = getattr(base, "features", None)
    return np.zeros(batch + (0,)) if features is None else np.asarray(features, dtype=np.float64)


class BatchedBase:
    """A baseline over a batch of environments: a stateless one acts on the whole batch at once,
    a stateful one (with ``clone``, ``start``, ``applied``, ``features``) as one copy each."""

    def __init__(self, base, num_envs: int):
        self.stateful = hasattr(base, "clone")
        self.base = base
        self.copies = [base.clone() for _ in range(num_envs)] if self.stateful else []
        self.num_envs = num_envs

    @property
    def feature_size(self) -> int:
        return base_features(self.copies[0]).shape[-1] if self.stateful else 0

    def start(self, i: int, target) -> None:
        if self.stateful:
            self.copies[i].start(target)

    def act(self, obs: np.ndarray, setup) -> np.ndarray:
        if not self.stateful:
            return self.base.act(obs, setup)
        return np.stack([law.act(o, setup) for law, o in zip(self.copies, obs)])

    def act_one(self, i: int, obs: np.ndarray, setup) -> np.ndarray:
        return self.copies[i].act(obs, setup) if self.stateful else self.base.act(obs, setup)

    def applied(self, actions: np.ndarray) -> None:
        for law, a in zip(self.copies, actions):
            law.applied(a)

    def features(self, i: Optional[int] = None) -> np.ndarray:
        if i is not None:
            return base_features(self.copies[i]) if self.stateful else np.zeros(0)
        if not self.stateful:
            return np.zeros((self.num_envs, 0))
        return np.stack([base_features(law) for law in self.copies])


class ResidualVecEnv(VecEnvWrapper):
    """Steps ``venv`` with clip(action + base(observation)): the base acts on the observation the
    policy was given (raw, before any normalisation), ``setup`` the environments' EnvSetup. A
    stateful base's estimate is appended to each observation (and to the terminal ones)."""

    def __init__(self, venv, base, setup):
        self.batch = BatchedBase(base, venv.num_envs)
        extra = self.batch.feature_size
        space = venv.observation_space
        if extra:
            space = gym.spaces.Box(-np.inf, np.inf, (space.shape[0] + extra,), dtype=space.dtype)
        super().__init__(venv, observation_space=space)
        self.base, self.setup = base, setup
        self._base_action = None

    def _targets(self):
        control = getattr(self.venv, "control", None)  # the batched esp_gym VecEnv: each env's TARGET row
        return [None] * self.num_envs if control is None else list(control.target)

    def _with_features(self, obs: np.ndarray) -> np.ndarray:
        return np.concatenate([obs, self.batch.features()], axis=-1).astype(obs.dtype) if self.batch.stateful \
            else obs

    def reset(self):
        obs = self.venv.reset()
        for i, target in enumerate(self._targets()):
            self.batch.start(i, target)
        self._base_action = self.batch.act(obs, self.setup)
        return self._with_features(obs)

    def step_async(self, actions: np.ndarray) -> None:
        total = np.clip(actions + self._base_action, -1.0, 1.0).astype(np.float32)
        if self.batch.stateful:
            self.batch.applied(total)
        self.venv.step_async(total)

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        targets = self._targets()
        for i in np.flatnonzero(dones):
            if self.batch.stateful and "terminal_observation" in infos[i]:  # the ended episode's filter, then a new one
                last = infos[i]["terminal_observation"]
                self.batch.act_one(i, last, self.setup)
                infos[i]["terminal_observation"] = np.concatenate([last, self.batch.features(i)]).astype(last.dtype)
            self.batch.start(i, targets[i])
        self._base_action = self.batch.act(obs, self.setup)  # after a reset: the next episode's first observation
        return self._with_features(obs), rewards, dones, infos


def write_residual(run_dir: Path, name: str, task: str, env_kwargs: Optional[dict] = None) -> None:
    spec = {"base": name, "task": task, "env_kwargs": env_kwargs or {}}
    (Path(run_dir) / RESIDUAL_FILE).write_text(json.dumps(spec) + "\n")


def residual_for(model: Path) -> Optional[object]:
    """The base policy of the run a model file belongs to (``residual.json`` beside it, or in
    the run directory above a checkpoint), or None for a plain policy."""
    model = Path(model)
    for directory in (model.parent, model.parent.parent):
        path = directory / RESIDUAL_FILE
        if path.is_file():
            spec = json.loads(path.read_text())
            return base_policy(spec["base"], spec["task"], spec.get("env_kwargs"))
    return None
