"""Compiling the environment's configurations ahead of use (``esp-gym compile``).

Each configuration of the environment's compiled step (each rig of esp_gym/physics/rig.py, single or
batched; a team's, of point pivots or of drones, single and batched (esp_gym/kernels/team/env.py), or on
winches (``team_winch_advance`` in esp_gym/kernels/team/loops.py)) compiles on its
first step and is cached on disk (docs/performance.md, "Start-up"). This takes them all in worker
processes, so that a machine (a container image, a CI run, a cluster's nodes)
pays the compile once, in parallel, instead of at the first step of each. A vector env's threaded
entry (``threads`` > 1, docs/performance.md "Threads") is left to its first use.
"""
from __future__ import annotations

import concurrent.futures
import multiprocessing
import time
from dataclasses import dataclass
from typing import Optional

from .physics.rig import RIGS
from .workers import available_cpus, worker_count


@dataclass(frozen=True)
class Configuration:
    """One compiled configuration of the environment's step, and an environment that runs it."""

    winch: bool
    implicit: bool
    batched: bool
    drone: bool = False
    hook: bool = False  #: the drone's hook off its centre of mass (pivot.drone.rho_q)
    team: bool = False  #: a team of TEAM_SIZE strings on one load (ElasticStringTeam-v0)
    damped: bool = False  #: the string's damper (string.damping_time > 0)

    @property
    def name(self) -> str:
        kind = ("drone-winch" if self.winch else "drone-hook" if self.hook else "drone") if self.drone \
            else "winch" if self.winch else "fixed"
        if self.team:
            return f"team-{kind}-" + ("batched" if self.batched else "single")
        return "-".join((kind, "implicit" if self.implicit else "explicit") + (("damped",) if self.damped else ())
                        + ("batched" if self.batched else "single",))


#: Every configuration: each rig of the table (esp_gym/physics/rig.py RIGS, the first environment's
#: first, a team's last), single and batched (a team whose strings reel steps one by one, in Python).
CONFIGURATIONS = tuple(Configuration(rig.winch, rig.string == "implicit", batched, rig.pivot == "drone", rig.hook,
                                     rig.team, rig.damper)
                       for rig in RIGS for batched in ((False, True) if rig.compiled else (False,)))
#: The strings of the team the team configurations compile with (any size: the same kernels).
TEAM_SIZE = 3
#: Worker processes by default; fewer on a machine with fewer CPUs (:func:`default_jobs`).
DEFAULT_JOBS = 2
#: The offset hook the hook configurations compile with [m] (any non-zero one: the same kernels).
OFFSET_HOOK = [0.0, 0.0, 0.05]
#: The damping time the damped configurations compile with [s] (any positive one: the same kernels).
DAMPING_TIME = 1e-3


def make_env(config: Configuration):
    """An environment that runs ``config``'s compiled step."""
    import gymnasium as gym

    import esp_gym

    if config.team:
        options = {"task": "lift", "winch": True} if config.winch else {"task": "transport"}
        if config.drone:
            options["actuation"] = "thrust_rates"
        if config.batched:
            return gym.make_vec(esp_gym.TEAM_ENV_ID, num_envs=2, vectorization_mode="vector_entry_point",
                                team=TEAM_SIZE, **options)
        return gym.make(esp_gym.TEAM_ENV_ID, team=TEAM_SIZE, disable_env_checker=True, **options)
    options = {"task": "lift" if config.winch else "stabilize"}
    if config.drone:
        options["scene"] = "quadrotor_load"
    if config.implicit:
        options["scene_overrides"] = {"solver": {"string": "implicit"}}
    if config.hook:
        options["scene_overrides"] = {"pivot": {"drone": {"rho_q": OFFSET_HOOK}}}
    if config.damped:
        options["scene_overrides"] = {**options.get("scene_overrides", {}), "string": {"damping_time": DAMPING_TIME}}
    if config.batched:
        return gym.make_vec(esp_gym.ENV_ID, num_envs=2, **options)
    return gym.make(esp_gym.ENV_ID, disable_env_checker=True, **options)


def compile_configuration(config: Configuration) -> float:
    """Build an environment of ``config``, reset it and take one step (which compiles, or loads,
    its kernels); returns the seconds it took. Runs in a worker process."""
    start = time.perf_counter()
    from esp_gym.kernels import jit

    jit.COMPILE_NOTICE = False  # the command reports its own progress
    env = make_env(config)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
    return time.perf_counter() - start


def rig_groups(configurations) -> list:
    """``configurations`` in groups of one rig each (its single and batched steps), in the reverse
    order of first appearance. A group compiles in one worker, its single step first: the batched
    step then loads every kernel below its loop from the cache, where two workers running them at
    once each compiled them all. Reversed, the teams and the drones come first: they take longest
    (18-28 s each here), and the longest left for last kept one worker busy for about 17 s while the
    other had nothing to do."""
    groups = {}
    for config in configurations:
        key = (config.winch, config.implicit, config.drone, config.hook, config.team, config.damped)
        groups.setdefault(key, []).append(config)
    return [tuple(sorted(group, key=lambda c: c.batched)) for group in reversed(list(groups.values()))]


def compile_group(configs) -> dict:
    """:func:`compile_configuration` of each of ``configs`` in turn: their seconds by name."""
    return {config.name: compile_configuration(config) for config in configs}


def default_jobs() -> int:
    """:data:`DEFAULT_JOBS`, or fewer on a machine with fewer CPUs."""
    return min(DEFAULT_JOBS, available_cpus())


def precompile(jobs: Optional[int] = None, configurations=CONFIGURATIONS, progress: bool = True) -> dict:
    """Compile ``configurations`` in ``jobs`` worker processes (spawned: each a fresh interpreter,
    as a user's would be; default :func:`default_jobs`; never more than the rigs), a rig's
    configurations in one worker (:func:`rig_groups`).
    Returns the seconds of each, by name. ValueError naming ``jobs`` unless it is a whole number
    from 1 to the CPUs, before any process starts."""
    groups = rig_groups(configurations)
    workers = worker_count("jobs", default_jobs() if jobs is None else jobs, len(groups))
    from tqdm import tqdm

    seconds = {}
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        futures = [pool.submit(compile_group, group) for group in groups]
        with tqdm(total=len(configurations), desc="compiling esp_gym's environment", unit="configuration",
                  disable=not progress) as bar:
            for future in concurrent.futures.as_completed(futures):
                done = future.result()
                seconds.update(done)
                bar.update(len(done))
    return seconds
