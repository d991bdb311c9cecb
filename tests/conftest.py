"""Shared fixtures and small reusable checkers for the physics tests."""
import os

import numpy as np
import pytest
from hypothesis import settings

import esp_gym

#: Modules whose tests hold wall-clock limits on signals and subprocesses, or start a Ray
#: cluster: `make test` runs them after the others, in one process (the rest on two, with
#: pytest-xdist), so another worker's load cannot stretch their clocks (docs/testing.md).
SERIAL_MODULES = {"test_interrupt.py", "test_recording_failures.py", "test_ray.py"}
#: Single tests that bound a wall time of their own (a median over repeats), run with them, by module.
SERIAL_TESTS = {"test_randomize.py": {"test_a_randomised_reset_costs_at_most_two_and_a_half_plain_ones"}}


def pytest_ignore_collect(collection_path, config):
    """With ``-m serial`` (make test's second part), only the modules that hold serial tests are
    collected: importing the others took about 5 s for nothing."""
    if config.getoption("markexpr", "") == "serial" and collection_path.suffix == ".py":
        return collection_path.name not in SERIAL_MODULES | set(SERIAL_TESTS)
    return None


#: Modules that run the scripts end to end in subprocesses (the command lines, the benchmarks' and
#: the training's smoke runs, the wheel installed in a new environment): marked slow, which `make check`
#: leaves to `make test`.
SLOW_MODULES = {"test_cli.py", "test_agents.py", "test_agents_cli.py", "test_mujoco_chain.py", "test_ray_arguments.py",
                "test_wheel.py"}


#: The modules that take longest (30-65 s of a worker each in `make test`), collected first: with
#: ``--dist loadfile`` a worker takes the next module when it is free, so a long one collected last
#: keeps one worker busy after the other has run out of work.
LONGEST_FIRST = ("test_cli.py", "test_wheel.py", "test_watchdog.py", "test_team_env.py", "test_agents.py")


def pytest_collection_modifyitems(items):
    for item in items:
        if item.path.name in SERIAL_MODULES or item.name in SERIAL_TESTS.get(item.path.name, ()):
            item.add_marker(pytest.mark.serial)
        if item.path.name in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the rest keep their order


#: Hypothesis draws the same examples on every run (profile "ci", the default: a red CI is a
#: defect, not a draw) or fresh ones saved in .hypothesis/ (``HYPOTHESIS_PROFILE=explore``,
#: `make fuzz`); the tests' own settings (max_examples, deadline) apply under both.
settings.register_profile("ci", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


#: The paper's example and two scenes far from it (see esp_gym/scenes/*.yaml).
INVARIANT_SCENES = ["paper_example", "short_stiff", "large_offset"]


def state_distance(a, b):
    """Max abs difference of positions [m], momenta and attitude between two states."""
    return max(np.abs(a.r - b.r).max(), np.abs(a.p - b.p).max(), np.abs(a.R - b.R).max(),
               np.abs(a.Pi - b.Pi).max())


def drift_ratio(t, de):
    """|least-squares slope| * duration / max|dE|: ~1 for a steady drift, small for bounded noise."""
    slope = np.polyfit(t - t[0], de, 1)[0]
    return abs(slope) * (t[-1] - t[0]) / np.abs(de).max()


@pytest.fixture(scope="session")
def long_runs():
    """1e5 steps of each invariant scene with every-step diagnostics (computed once)."""
    runs = {}
    for name in INVARIANT_SCENES:
        sim = esp_gym.Simulator(esp_gym.load_scene(name))
        runs[name] = sim.run(t_final=100_000 * sim.h, record_every=1000, every_step=True)
    return runs
