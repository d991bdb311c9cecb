"""How much return a configuration's best classical controller leaves on the table, episode by
episode: the controller plus an open-loop feed-forward, optimised for each episode.

    python -m agents.headroom --task transport --policy lqr --episodes 3 --out docs/compare

For each episode (seeds ``--seed`` + i) the feed-forward is piecewise linear in time, ``--knots``
values per force axis (and the reel, with a winch; per action entry for a drone, through
:class:`Episode`'s ``env_kwargs``) spread over the episode, added to the controller's action
before the environment's clip; Powell's method (scipy.optimize) maximises the
episode's return over those values within ``--evaluations`` episodes. The optimised return is a
lower bound on what a policy that knew the episode could reach, so its gain over the controller
tells whether a learned policy has anything to find. Writes ``headroom_TASK.json`` (per episode:
the controller's return, the optimised one and the feed-forward) and prints a table.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import gymnasium as gym
import numpy as np

import esp_gym
from agents.cli import ArgumentParser
from esp_gym.layouts import ACTION_SIZE
from esp_gym.pendulum.tasks import TASKS


def feedforward_axes(action_size: int, drone: bool = False) -> list:
    """The action entries a feed-forward drives: a point pivot's force (three) and the reel (the
    last) with a winch; every entry of a drone's action (thrust and its actuation's rest)."""
    if drone:
        return list(range(action_size))
    return [0, 1, 2] + ([action_size - 1] if action_size > ACTION_SIZE else [])


class Episode:
    """One seeded episode of ``task`` under ``controller`` plus a feed-forward, as a function of the
    feed-forward's knot values ((knots, axes), flattened)."""

    def __init__(self, task: str, controller, seed: int, knots: int, env_kwargs=None):
        self.env = gym.make(esp_gym.ENV_ID, task=task, **(env_kwargs or {}))
        self.controller, self.seed = controller, seed
        self.axes = feedforward_axes(self.env.action_space.shape[0], self.env.unwrapped.setup.drone)
        self.steps = self.env.spec.max_episode_steps
        self.knot_steps = np.linspace(0.0, self.steps, knots)
        self.size = knots * len(self.axes)

    def feedforward(self, values: np.ndarray) -> np.ndarray:
        """(steps, axes): the piecewise-linear feed-forward through the knot values [action units]."""
        values = np.asarray(values, dtype=float).reshape(len(self.knot_steps), len(self.axes))
        k = np.arange(self.steps)
        return np.stack([np.interp(k, self.knot_steps, values[:, j]) for j in range(len(self.axes))], axis=1)

    def __call__(self, values: np.ndarray, record: Optional[list] = None) -> float:
        """The episode's return with the feed-forward of ``values``; with ``record``, each step's
        (observation, the controller's features after it acted, the feed-forward over the whole
        action: zero off :attr:`axes`) is appended to it (agents/distill.py)."""
        from agents.residual import base_features

        extra = self.feedforward(values)
        u = self.env.unwrapped
        obs, _ = self.env.reset(seed=self.seed)
        if hasattr(self.controller, "reset"):
            self.controller.reset(u)
        total = 0.0
        for k in range(self.steps):
            action = np.array(self.controller.act(obs, u.setup), dtype=np.float64)
            if record is not None:
                applied = np.zeros_like(action)
                applied[self.axes] = extra[k]
                record.append((np.asarray(obs, dtype=np.float64), base_features(self.controller), applied))
            action[self.axes] += extra[k]
            obs, reward, terminated, truncated, _ = self.env.step(np.clip(action, -1.0, 1.0))
            total += reward
            if terminated or truncated:
                break
        return total


def optimise(episode: Episode, evaluations: int) -> dict:
    """Powell's method on ``episode``'s return from the zero feed-forward, at most ``evaluations``
    episodes: the controller's return, the best one found and its knot values."""
    from scipy.optimize import minimize

    base = episode(np.zeros(episode.size))
    result = minimize(lambda v: -episode(v), np.zeros(episode.size), method="Powell",
                      options={"maxfev": evaluations, "xtol": 1e-3, "ftol": 1e-7})
    best = max(base, -float(result.fun))
    values = result.x if -float(result.fun) >= base else np.zeros(episode.size)
    return {"seed": episode.seed, "controller_return": base, "optimised_return": best, "gain": best - base,
            "episodes_run": int(result.nfev) + 1,
            "knots": values.reshape(len(episode.knot_steps), len(episode.axes)).tolist()}


def main(argv=None) -> dict:
    from tqdm import tqdm

    from agents.baselines.registry import baselines

    ap = ArgumentParser(prog="python -m agents.headroom", description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", default="transport", choices=sorted(TASKS))
    ap.add_argument("--policy", default="lqr", help="the controller (a baseline's name for the task: pd, lqr, ...)")
    ap.add_argument("--episodes", type=int, default=3, help="episodes, each optimised on its own (>= 1)")
    ap.add_argument("--seed", type=int, default=100000, help="the first episode's seed (>= 0)")
    ap.add_argument("--knots", type=int, default=11, help="feed-forward values per axis over the episode (>= 2)")
    ap.add_argument("--evaluations", type=int, default=1000, help="episodes Powell may run per episode (>= 1)")
    ap.add_argument("--out", default=None, help="directory of headroom_TASK.json (default: none written)")
    ap.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    ap.minimums = {"episodes": 1, "seed": 0, "knots": 2, "evaluations": 1}
    a = ap.parse_args(argv)
    if a.out is not None:
        ap.check_out_dir("--out", a.out)
    known = baselines(a.task)
    if a.policy not in known:
        ap.error(f"argument --policy: {a.policy!r} is not a baseline of task {a.task!r}; it has {sorted(known)}")
    rows = []
    for i in tqdm(range(a.episodes), desc=f"headroom {a.task}", unit="episode", disable=not a.progress):
        rows.append(optimise(Episode(a.task, known[a.policy], a.seed + i, a.knots), a.evaluations))
    gains = np.array([r["gain"] for r in rows])
    result = {"task": a.task, "policy": a.policy, "knots": a.knots, "evaluations": a.evaluations,
              "episodes": rows, "mean_gain": float(gains.mean())}
    print(f"| seed | {a.policy} | optimised feed-forward | gain |\n|---|---|---|---|")
    for r in rows:
        print(f"| {r['seed']} | {r['controller_return']:.2f} | {r['optimised_return']:.2f} | +{r['gain']:.2f} |")
    if a.out is not None:
        out = Path(a.out)
        out.mkdir(exist_ok=True)
        (out / f"headroom_{a.task}.json").write_text(json.dumps(result, indent=1) + "\n")
    return result


if __name__ == "__main__":
    main()
