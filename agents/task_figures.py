"""One figure per task of ElasticStringPendulum-v0: a seeded episode under a controller, seen from
above and over time (docs/environment.md, "The tasks").

    python -m agents.task_figures --out docs/img [--seed 3] [--steps 500] [--policy baseline] [--drone]
    python -m agents.task_figures --out docs/img --hard-lift [--model models/lift_hard_ppo/model.zip]
    python -m agents.task_figures --out docs/img --team 3

writes ``task_{stabilize,transport,track}.png`` (with ``--drone``: ``drone_transport.png``, a
``transport`` episode of ``quadrotor_load`` under the geometric cascade, ``thrust_rates``, the
drone's roll, pitch and yaw over time below the load's distance; with ``--hard-lift``:
``lift_hard.png``, one episode of the hard preset's ``lift`` (a moving target) under the hoist
and under the shipped policy, drawn together; with ``--team K``: ``team_transport.png``, a team's
transport, :func:`team_figure`): left, the top view (x, y) of the pivot's and the
load's paths with the targets (``track``: the reference the load follows); right, over time, the
load's distance to its target [m] and the swing angle of the string [deg]. The controller is the
task's classical baseline (agents/baselines/pd.py) unless ``--policy zero``; each panel notes the
return. Prints one line per task: return, final distance and final swing.
"""
from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np

import esp_gym
from agents import MODELS
from agents.cli import ArgumentParser
from agents.evaluate import ONE_BLAS_THREAD
from agents.baselines.pd import ZeroPolicy
from agents.baselines.registry import baseline, baselines
from esp_gym.pendulum.tasks import TASKS
from esp_gym.team.tasks import TEAM_TASKS

#: What the top view's markers and lines stand for, and their colours.
COLOURS = {"pivot": "tab:blue", "load": "tab:red", "target": "black"}


@ONE_BLAS_THREAD  # the episode agents.evaluate scores, to the bit
def rollout(task: str, policy, seed: int, steps: int, env_kwargs=None) -> dict:
    """One seeded episode of ``task`` (at most ``steps`` control steps) under ``policy``: the
    pivot's and the load's positions, the pivot and load targets (all spatial [m], (T+1, 3)),
    time [s], swing angle [rad] and the return."""
    env = gym.make(esp_gym.ENV_ID, task=task, **(env_kwargs or {}))
    u = env.unwrapped
    obs, _ = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset(u)
    pivot, load, targets, swing = [u.pivot_position().copy()], [u.load_position().copy()], [u.target], \
        [u.swing_angle()]
    attitude = [u.sim.drone.R.copy()] if u.setup.drone else None
    total, done, k = 0.0, False, 0
    while not done and k < steps:
        obs, reward, terminated, truncated, _ = env.step(policy.act(obs, u.setup))
        total += reward
        done = terminated or truncated
        k += 1
        pivot.append(u.pivot_position().copy())
        load.append(u.load_position().copy())
        targets.append(u.target)
        swing.append(u.swing_angle())
        if attitude is not None:
            attitude.append(u.sim.drone.R.copy())
    targets = np.array(targets)
    run = {"time": u.setup.control_period * np.arange(k + 1), "pivot": np.array(pivot), "load": np.array(load),
           "pivot_target": targets[:, :3], "load_target": targets[:, 3:], "swing": np.array(swing),
           "return": total, "moving": u.setup.task.moving}
    if attitude is not None:  # the drone's roll, pitch and yaw [rad] (body x-y-z, extrinsic)
        from scipy.spatial.transform import Rotation

        run["attitude"] = Rotation.from_matrix(np.array(attitude)).as_euler("xyz")
    return run


def panels():
    """The figures' layout: the top view on the left, distance over swing (or attitude) on the
    right. Returns ``(fig, top, distance_ax, swing_ax)``."""
    from esp_gym.viz.figures import new_figure

    fig = new_figure((10, 4))
    grid = fig.add_gridspec(2, 2, width_ratios=(1, 1.4))
    return fig, fig.add_subplot(grid[:, 0]), fig.add_subplot(grid[0, 1]), fig.add_subplot(grid[1, 1])


def load_distance(run: dict) -> np.ndarray:
    """The load's distance to its target at each time of a rollout [m]."""
    return np.linalg.norm(run["load"] - run["load_target"], axis=1)


def plot_task(run: dict, task: str, path, title: str) -> Path:
    """The figure of one rollout (module docstring)."""
    from esp_gym.viz.figures import save_figure

    fig, top, distance_ax, swing_ax = panels()
    xy = slice(0, 2)  # the horizontal components of a spatial vector
    if run["moving"]:
        ref = run["load_target"][:, xy]
        top.plot(*ref.T, color=COLOURS["target"], lw=1, ls="--", label="reference (load)")
    else:
        top.plot(*run["pivot_target"][0, xy], "s", mfc="none", color=COLOURS["pivot"], ms=9, label="pivot target")
        top.plot(*run["load_target"][0, xy], "x", color=COLOURS["load"], ms=9, label="load target")
    for name in ("pivot", "load"):
        path_xy = run[name][:, xy]
        top.plot(*path_xy.T, color=COLOURS[name], lw=1.2, label=name)
        top.plot(*path_xy[0], "o", color=COLOURS[name], ms=4)
    top.set_aspect("equal", adjustable="datalim")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title("seen from above (dots: start)")
    top.legend(loc="best")
    top.grid(True, alpha=0.3)
    t = run["time"]
    distance_ax.plot(t, load_distance(run), color=COLOURS["load"])
    distance_ax.set_ylabel("load to target [m]")
    distance_ax.set_title(f"return {run['return']:.1f} over {len(t) - 1} steps")
    if "attitude" in run:  # the drone's attitude instead of the swing
        for i, name in enumerate(("roll", "pitch", "yaw")):
            swing_ax.plot(t, np.degrees(run["attitude"][:, i]), lw=1.2, label=name)
        swing_ax.set_ylabel("drone attitude [deg]")
        swing_ax.legend(loc="best", ncol=3)
    else:
        swing_ax.plot(t, np.degrees(run["swing"]), color="tab:green")
        swing_ax.set_ylabel("swing [deg]")
    swing_ax.set_xlabel("time [s]")
    for ax in (distance_ax, swing_ax):
        ax.grid(True, alpha=0.3)
    distance_ax.set_ylim(bottom=0.0)
    if "attitude" not in run:
        swing_ax.set_ylim(bottom=0.0)
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_policies(runs: dict, path, title: str) -> Path:
    """One episode of a moving-target task under several policies (``runs``: name -> rollout, the
    same seed): the top view of the reference and each load's path, each load's distance to its
    target and each swing over time."""
    from esp_gym.viz.figures import save_figure

    fig, top, distance_ax, swing_ax = panels()
    xy = slice(0, 2)
    first = next(iter(runs.values()))
    top.plot(*first["load_target"][:, xy].T, color=COLOURS["target"], lw=1, ls="--", label="reference (load)")
    for (name, run), colour in zip(runs.items(), ("tab:orange", "tab:purple", "tab:cyan")):
        label = f"{name} ({run['return']:.1f})"
        top.plot(*run["load"][:, xy].T, color=colour, lw=1.2, label=label)
        distance_ax.plot(run["time"], load_distance(run), color=colour, label=label)
        swing_ax.plot(run["time"], np.degrees(run["swing"]), color=colour)
    top.plot(*first["load"][0, xy], "o", color="black", ms=4)
    top.set_aspect("equal", adjustable="datalim")
    top.set(xlabel="x [m]", ylabel="y [m]", title="load seen from above (dot: start)")
    top.legend(loc="best")
    distance_ax.set(ylabel="load to target [m]", title="returns in the legend")
    swing_ax.set(ylabel="swing [deg]", xlabel="time [s]")
    for ax in (top, distance_ax, swing_ax):
        ax.grid(True, alpha=0.3)
    distance_ax.set_ylim(bottom=0.0)
    swing_ax.set_ylim(bottom=0.0)
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)


def hard_lift_figure(out: Path, seed: int, steps: int, model: Path) -> dict:
    """``lift_hard.png``: the hard preset's lift under the hoist and, where ``model`` exists, the
    policy, on episode ``seed``; their returns and final distances."""
    from agents.evaluate import SB3Policy

    kwargs = {"preset": "hard"}
    runs = {"hoist": rollout("lift", baselines("lift", kwargs)["pd"], seed, steps, kwargs)}
    if model.exists():
        runs["policy"] = rollout("lift", SB3Policy(model), seed, steps, kwargs)
    path = plot_policies(runs, out / "lift_hard.png", f"task='lift', preset='hard' (a moving target), seed {seed}")
    results = {}
    for name, run in runs.items():
        final = float(load_distance(run)[-1])
        results[f"lift_hard_{name}"] = {"return": run["return"], "final_distance_m": final, "figure": str(path)}
        print(f"hard lift, {name:6s} return {run['return']:7.1f}  final distance {final:.3f} m  -> {path}")
    return results


@ONE_BLAS_THREAD  # the episode agents.team.evaluate scores, to the bit
def _team_episode(env, policy, seed: int, steps: int) -> dict:
    """One episode of the team env ``env`` under ``policy``, up to ``steps`` steps: every pivot's
    and the load's positions and the load's target at each step, each string's pull on its pivot
    and the smallest distance between two pivots after each step, and the return."""
    core = env.core
    obs, _ = env.reset(seed=seed)
    pivots, load, tension, separation, total = [core.pivot_positions()], [core.load_position()], [], [], 0.0
    targets = [core.load_target.copy()]
    for _ in range(steps):
        obs, reward, terminated, _, info = env.step(policy.act(obs, core))
        total += reward
        pivots.append(core.pivot_positions())
        load.append(core.load_position())
        targets.append(core.load_target.copy())
        tension.append(np.linalg.norm(info["tension"], axis=1))
        separation.append(info["min_separation"])
        if terminated:
            break
    return dict(pivots=np.array(pivots), load=np.array(load), targets=np.array(targets), tension=np.array(tension),
                separation=separation, total=total)


def _team_top_view(top, core, run: dict) -> None:
    """The top view: every pivot's and the load's path from its start (dots) to its final target
    (squares, a cross), a moving target's path dashed."""
    pivots, load = run["pivots"], run["load"]
    for k in range(core.size):
        line, = top.plot(*pivots[:, k, :2].T, lw=1.2, label=f"{'drone' if core.drones else 'pivot'}_{k}")
        top.plot(*pivots[0, k, :2], "o", color=line.get_color(), ms=4)
        top.plot(*core.pivot_targets[k, :2], "s", mfc="none", color=line.get_color(), ms=9)
    top.plot(*load[:, :2].T, color=COLOURS["load"], lw=1.6, label="load")
    top.plot(*load[0, :2], "o", color=COLOURS["load"], ms=4)
    if core.task.moving:
        top.plot(*run["targets"][:, :2].T, color=COLOURS["target"], lw=1, ls="--", label="load target's path")
    top.plot(*core.load_target[:2], "x", color=COLOURS["load"], ms=9, label="load target")
    top.set_aspect("equal", adjustable="datalim")
    top.set(xlabel="x [m]", ylabel="y [m]", title="from above (dots: starts, squares: final targets)")
    top.legend(loc="best", fontsize=8)
    top.grid(True, alpha=0.3)


def _team_series(axes, core, run: dict) -> None:
    """Against time, on ``axes`` (three): the load's distance to its target, each string's pull on
    its pivot, and the closest two pivots with the separation and collision distances."""
    from esp_gym.team.tasks import COLLISION, SEPARATION

    distance_ax, tension_ax, separation_ax = axes
    load, t = run["load"], core.control_period * np.arange(len(run["load"]))
    distance_ax.plot(t, np.linalg.norm(load - run["targets"], axis=1), color=COLOURS["load"])
    distance_ax.set(ylabel="load to target [m]", title=f"return {run['total']:.1f} over {len(t) - 1} steps")
    for k, series in enumerate(run["tension"].T):
        tension_ax.plot(t[1:], series, lw=1.0, label=f"{'drone' if core.drones else 'pivot'}_{k}")
    tension_ax.set_ylabel("hook tension [N]")
    tension_ax.legend(loc="best", ncol=core.size, fontsize=8)
    separation_ax.plot(t[1:], run["separation"], color="tab:purple")
    separation_ax.axhline(SEPARATION, color="tab:orange", ls="--", lw=1, label="penalised below")
    separation_ax.axhline(COLLISION, color="tab:red", ls=":", lw=1, label="collision")
    separation_ax.set(ylabel="closest pivots [m]", xlabel="time [s]")
    separation_ax.legend(loc="best", fontsize=8)
    for ax in axes:
        ax.grid(True, alpha=0.3)


def team_figure(out: Path, size: int, seed: int, steps: int, preset=None, task: str = "transport",
                actuation=None) -> dict:
    """``team_{task}.png``: one episode of a team of ``size`` pivots (docs/team.md) under the
    team's LQR (the lift's under its hoist; with a drone ``actuation``, ``team_drones_{task}.png``
    under the drones' cascade):
    the top view of every pivot's and the load's path with their targets (a moving target's path
    dashed), the load's distance to its target, each string's pull on its pivot, and the smallest
    distance between two pivots with the separation and collision distances."""
    from agents.team.evaluate import TeamCascadePolicy, TeamHoistPolicy, TeamLQRPolicy
    from esp_gym.team.env import ElasticStringTeamEnv
    from esp_gym.viz.figures import new_figure, save_figure

    options = {**({"preset": preset} if preset else {}), **({"actuation": actuation} if actuation else {})}
    env = ElasticStringTeamEnv(size, task=task, **options)
    core = env.core
    if core.drones:
        policy, who, what = TeamCascadePolicy(), "drones' cascade", f"drones_{task}"
    elif core.winch:
        policy, who, what = TeamHoistPolicy(), "team's hoist", task
    else:
        policy, who, what = TeamLQRPolicy(), "team's LQR", task
    run = _team_episode(env, policy, seed, steps)
    fig = new_figure((11, 5))
    grid = fig.add_gridspec(3, 2, width_ratios=(1, 1.4))
    _team_top_view(fig.add_subplot(grid[:, 0]), core, run)
    _team_series(tuple(fig.add_subplot(grid[i, 1]) for i in range(3)), core, run)
    kind = f"{size} drones ({actuation})" if core.drones else f"a team of {size}"
    fig.suptitle(f"{kind}, task='{task}'{', ' + preset if preset else ''}, the {who}, seed {seed}")
    fig.tight_layout()
    path = save_figure(fig, out / f"team_{what}.png")
    total, load, separation = run["total"], run["load"], run["separation"]
    result = {"return": total, "final_distance_m": float(np.linalg.norm(load[-1] - core.load_target)),
              "closest_pivots_m": float(min(separation)), "figure": str(path)}
    print(f"team of {size} {task} return {total:7.1f}  final distance {result['final_distance_m']:.3f} m  "
          f"closest pivots {result['closest_pivots_m']:.2f} m  -> {path}")
    return result


def main(argv=None) -> dict:
    ap = ArgumentParser(prog="python -m agents.task_figures", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs/img", help="directory of the figures")
    ap.add_argument("--seed", type=int, default=3, help="the episode's seed (>= 0)")
    ap.add_argument("--steps", type=int, default=500, help="control steps at most (>= 1)")
    ap.add_argument("--policy", choices=("baseline", "zero"), default="baseline")
    ap.add_argument("--drone", action="store_true",
                    help="only drone_transport.png: quadrotor_load's transport under the geometric cascade")
    ap.add_argument("--hard-lift", action="store_true",
                    help="only lift_hard.png: the hard preset's lift under the hoist and the policy of --model")
    ap.add_argument("--model", default=str(MODELS / "lift_hard_ppo" / "model.zip"),
                    help="the policy of --hard-lift (default: the shipped one; left out if absent)")
    ap.add_argument("--team", type=int, default=None, metavar="K",
                    help="only team_TASK.png: a team of K pivots (docs/team.md) under the team's LQR")
    ap.add_argument("--team-task", default="transport", metavar="TASK",
                    help="the task of --team: transport (default), stabilize or track")
    ap.add_argument("--team-actuation", default=None, choices=("thrust_rates", "thrust_torque", "motors"),
                    help="--team's pivots are drones flown so (team_drones_TASK.png, under the drones' cascade)")
    ap.minimums = {"seed": 0, "steps": 1}
    a = ap.parse_args(argv)
    if a.team is not None and not 1 <= a.team <= 6:
        ap.error(f"argument --team: a team has 1 to 6 strings, got {a.team}")
    if a.team_task not in TEAM_TASKS:
        ap.error(f"argument --team-task: a team's tasks are {sorted(TEAM_TASKS)}, got {a.team_task!r}")
    ap.check_out_dir("--out", a.out)  # as compare's and robustness's: a new directory in an existing one
    out = Path(a.out)
    out.mkdir(exist_ok=True)
    results = {}
    if a.hard_lift:
        return hard_lift_figure(out, a.seed, a.steps, Path(a.model))
    if a.team is not None:
        return team_figure(out, a.team, a.seed, a.steps, task=a.team_task, actuation=a.team_actuation)
    if a.drone:
        from agents.baselines.geometric import geometric_controller

        policy = ZeroPolicy() if a.policy == "zero" else geometric_controller("transport")
        run = rollout("transport", policy, a.seed, a.steps, {"scene": "quadrotor_load", "actuation": "thrust_rates"})
        name = "zero action" if a.policy == "zero" else "geometric cascade"
        path = plot_task(run, "transport", out / "drone_transport.png",
                         f"quadrotor_load, task='transport', thrust_rates, {name}, seed {a.seed}")
        final = float(load_distance(run)[-1])
        results["drone_transport"] = {"return": run["return"], "final_distance_m": final, "figure": str(path),
                                      "largest_tilt_deg": float(np.degrees(np.abs(run["attitude"][:, :2]).max()))}
        print(f"drone transport return {run['return']:7.1f}  final distance {final:.3f} m  largest roll or pitch "
              f"{results['drone_transport']['largest_tilt_deg']:.1f} deg  -> {path}")
        return results
    for task in sorted(TASKS):
        policy = ZeroPolicy() if a.policy == "zero" else baseline(task)
        run = rollout(task, policy, a.seed, a.steps)
        name = "zero action" if a.policy == "zero" else "classical baseline"
        path = plot_task(run, task, out / f"task_{task}.png", f"task={task!r}, {name}, seed {a.seed}")
        final = float(load_distance(run)[-1])
        results[task] = {"return": run["return"], "final_distance_m": final,
                         "final_swing_deg": math.degrees(run["swing"][-1]), "figure": str(path)}
        print(f"{task:10s} return {run['return']:7.1f}  final distance {final:.3f} m  "
              f"final swing {results[task]['final_swing_deg']:.2f} deg  -> {path}")
    return results


if __name__ == "__main__":
    main()
