"""Grid search of the classical baseline's gains (agents/controllers.py) on seeded episodes.

    python -m agents.tune --task stabilize --episodes 10
    python -m agents.tune --task stabilize --episodes 20 --grid '{"kp": [3, 4, 6], "kd": [1.5, 2, 3]}'

Every combination of the ``--grid`` values replaces those gains of the task's baseline; each is
scored by its mean return over ``--episodes`` episodes (seeds 1000 + i). Prints the ten best as
JSON lines, best first.
"""
from __future__ import annotations

import argparse
import itertools
import json
from dataclasses import replace

from agents.controllers import baseline
from agents.evaluate import evaluate_policy
from esp_gym.tasks import TASKS

#: The coarse grid of the first search (the default ``--grid``).
COARSE_GRID = dict(kp=[1, 2, 4, 8], kd=[1, 2, 4, 8], k_sway=[0, 1, 2, 4, 8], k_spin=[0, 0.01, 0.02, 0.05])


def tune(task: str, episodes: int, grid: dict, top: int = 10) -> list:
    """``(mean return, gains)`` of every grid point, best first; prints the ``top`` best as JSON lines."""
    results = []
    base = baseline(task)
    for values in itertools.product(*grid.values()):
        gains = dict(zip(grid, values))
        stats = evaluate_policy(replace(base, **gains), task=task, episodes=episodes, seed=1000)
        results.append((stats["mean_return"], gains))
    results.sort(key=lambda x: -x[0])
    for ret, gains in results[:top]:
        print(json.dumps({"mean_return": ret, **gains}))
    return results


def main(argv=None) -> list:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", default="stabilize", choices=sorted(TASKS))
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--grid", type=json.loads, default=COARSE_GRID, help="JSON dict of gain -> values")
    a = ap.parse_args(argv)
    return tune(a.task, a.episodes, a.grid)


if __name__ == "__main__":
    main()
