"""How many worker processes (or Ray actors of one CPU each) a command may start: never more than
the CPUs this process may use, nor more than the pieces of work. One bound for every ``--jobs``
and ``num_env_runners``: ``--jobs 100000`` once forked thousands of processes on two cores.
Light on purpose (no import but ``os`` at load): the command lines' parsers use it.
"""
from __future__ import annotations

import os
from typing import Any, Optional


def available_cpus() -> int:
    """The CPUs this process may run on: its affinity mask where the system has one (a container's
    or ``taskset``'s limit, which os.cpu_count() does not see), else os.cpu_count()."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def beyond_cpus(count: int) -> Optional[str]:
    """What is wrong with ``count`` processes running at once on this machine, or None."""
    cpus = available_cpus()
    return f"must be at most the {cpus} CPUs this process may use" if count > cpus else None


def check_within_cpus(name: str, count: int) -> int:
    """``count`` (processes, or Ray actors of one CPU each, running at once) if this process may use
    that many CPUs; ValueError naming ``name`` otherwise."""
    problem = beyond_cpus(count)
    if problem:
        raise ValueError(f"{name} {problem}, got {count}")
    return count


def worker_count(name: str, jobs: Any, tasks: int) -> int:
    """The worker processes for ``tasks`` pieces of work run ``jobs`` at a time: min(jobs, tasks),
    at least 1. ValueError naming ``name`` unless ``jobs`` is a whole number from 1 to the CPUs."""
    from .pendulum.options import check_count

    return max(1, min(check_within_cpus(name, check_count(name, jobs)), tasks))


def jobs_argument(text: str) -> int:
    """An argparse type for a ``--jobs`` option: a whole number from 1 to the CPUs (argparse
    reports the refusal as ``argument --jobs: ...``)."""
    import argparse

    try:
        count = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    problem = "must be at least 1" if count < 1 else beyond_cpus(count)
    if problem:
        raise argparse.ArgumentTypeError(f"{problem}, got {count}")
    return count
