"""Grid search of the classical baseline's gains (agents/baselines/pd.py) on seeded episodes.

    python -m agents.baselines.gain_search --task stabilize --episodes 10
    python -m agents.baselines.gain_search --task stabilize --episodes 20 --grid '{"kp": [3, 4, 6], "kd": [1.5, 2, 3]}'
    python -m agents.baselines.gain_search --controller geometric --scene quadrotor_load --task track \
        --grid '{"k_load": [2, 4, 6], "k_drone_d": [2, 4, 8]}'

Every combination of the ``--grid`` values replaces those gains of the task's baseline; each is
scored by its mean return over ``--episodes`` episodes (seeds 1000 + i). Prints the ten best as
JSON lines, best first. The winch's tasks (lift, lower) tune their Hoist: the PD law's gains and
``k_length``. ``--controller geometric`` tunes the drone's load-led cascade
(agents/baselines/geometric.py) on ``--scene`` (a drone's) in ``--actuation`` (with ``--preset hard``
on the hook observation, through its load estimate); ``--controller pd``
with a drone's scene, the PD law flying it.
"""
from __future__ import annotations

import itertools
import json
from dataclasses import fields, replace

from agents.cli import ArgumentParser
from agents.baselines.geometric import HookGeometricController
from agents.baselines.pd import Hoist
from agents.baselines.registry import baseline
from agents.evaluate import evaluate_policy
from esp_gym.pendulum.tasks import TASKS

#: The coarse grid of the first search (the default ``--grid``).
COARSE_GRID = dict(kp=[1, 2, 4, 8], kd=[1, 2, 4, 8], k_sway=[0, 1, 2, 4, 8], k_spin=[0, 0.01, 0.02, 0.05])


def gain_names(law) -> list:
    """The gains ``--grid`` may set: the PD law's, and a Hoist's ``k_length`` besides its PD's (the
    numbers among a controller's fields: not its inner loops or its episode's record); the hook's
    geometric cascade's are its law's."""
    if isinstance(law, HookGeometricController):
        return gain_names(law.law)
    if isinstance(law, Hoist):
        return sorted(gain_names(law.pd) + ["k_length"])
    return sorted(f.name for f in fields(law) if f.type in ("float", float) and not f.name.startswith("_"))


def controller(name: str, task: str, env_kwargs: dict):
    """The task's controller to tune: ``pd`` (the PD law, flying the drone with a drone's scene) or
    ``geometric`` (the drone's load-led cascade)."""
    from esp_gym.pendulum.env_setup import make_setup

    setup = make_setup(task=task, **env_kwargs)
    if name == "geometric":
        if not setup.drone:
            raise ValueError("the geometric cascade flies a drone: give a drone's --scene (quadrotor_load)")
        from agents.baselines.registry import baseline_factories

        known = baseline_factories(task, env_kwargs)
        return known["geometric"]()  # on the hook observation: with its load estimate
    return baseline(task, setup.winch, setup.drone)


def with_gains(law, gains: dict):
    """``law`` with ``gains`` replaced (a Hoist's PD gains go to its PD law, the hook's geometric
    cascade's to its law, with an estimate of its own)."""
    if isinstance(law, HookGeometricController):
        return replace(law.clone(), law=replace(law.law, **gains))
    if isinstance(law, Hoist):
        pd = {k: v for k, v in gains.items() if k != "k_length"}
        return replace(law, pd=with_gains(law.pd, pd), k_length=gains.get("k_length", law.k_length))
    return replace(law, **gains)


def tune(task: str, episodes: int, grid: dict, top: int = 10, base=None, env_kwargs=None) -> list:
    """``(mean return, gains)`` of every grid point, best first; prints the ``top`` best as JSON lines.
    ``base``: the controller whose gains the grid replaces (default the task's PD law);
    ``env_kwargs``: the environment's options (a drone's scene and actuation)."""
    results = []
    base = baseline(task) if base is None else base
    for values in itertools.product(*grid.values()):
        gains = dict(zip(grid, values))
        stats = evaluate_policy(with_gains(base, gains), task=task, episodes=episodes, seed=1000,
                                env_kwargs=env_kwargs)
        results.append((stats["mean_return"], gains))
    results.sort(key=lambda x: -x[0])
    for ret, gains in results[:top]:
        print(json.dumps({"mean_return": ret, **gains}))
    return results


def main(argv=None) -> list:
    ap = ArgumentParser(prog="python -m agents.baselines.gain_search", description=__doc__.split("\n\n")[0])
    ap.add_episode_options(TASKS, episodes=20, seed=False, preset=True)
    ap.add_argument("--grid", type=str, default=None,
                    help=f"JSON object gain -> list of values (default: {json.dumps(COARSE_GRID)}; "
                         "required with --controller geometric)")
    ap.add_argument("--controller", choices=("pd", "geometric"), default="pd")
    ap.add_scene_options()
    a = ap.parse_args(argv)
    env_kwargs = ap.environment_options(a)
    try:
        base = controller(a.controller, a.task, env_kwargs)
    except ValueError as err:
        ap.error(f"argument --controller/--scene/--actuation: {err}")
    if a.grid is None and a.controller == "geometric":
        ap.error("argument --grid: the geometric cascade has no default grid; give one")
    try:
        grid = COARSE_GRID if a.grid is None else checked_grid(json.loads(a.grid), a.task, base)
    except json.JSONDecodeError as err:
        ap.error(f"argument --grid: not JSON ({err})")
    except ValueError as err:
        ap.error(f"argument --grid: {err}")
    return tune(a.task, a.episodes, grid, base=base, env_kwargs=env_kwargs)


def checked_grid(grid, task: str, base=None) -> dict:
    """``grid`` if it maps gains of ``base`` (default the task's baseline) to non-empty lists of
    numbers."""
    gains = gain_names(baseline(task) if base is None else base)
    if not isinstance(grid, dict) or not grid:
        raise ValueError(f"expected a JSON object of gain -> list of values, got {grid!r}")
    for name, values in grid.items():
        if name not in gains:
            raise ValueError(f"unknown gain {name!r}; the {task} baseline's gains: {', '.join(gains)}")
        if not isinstance(values, list) or not values or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            raise ValueError(f"{name}: expected a non-empty list of numbers, got {values!r}")
    return grid


if __name__ == "__main__":
    main()
