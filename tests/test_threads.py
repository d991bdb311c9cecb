"""The batched env on numba's threads (``threads`` > 1) against its own thread (the default): the
same numbers bit for bit, the option's refusals, and the benchmark that chose the default
(docs/performance.md, "Threads")."""
import gymnasium as gym
import numpy as np
import pytest

from esp_gym import ENV_ID
from esp_gym.workers import available_cpus
from tests.test_cli import quick_benchmark

needs_two_cpus = pytest.mark.skipif(available_cpus() < 2, reason="threads > 1 needs two CPUs")


def _rollout(threads: int, options: dict, steps: int = 120) -> list:
    """Observations, rewards and ends of a batch of 4 under the same random actions."""
    venv = gym.make_vec(ENV_ID, num_envs=4, max_episode_steps=40, threads=threads, **options)
    out = [venv.reset(seed=7)[0]]
    rng = np.random.default_rng(1)
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = venv.step(rng.uniform(-1.2, 1.2, venv.action_space.shape))
        out += [obs, reward, terminated, truncated]
    return out


@needs_two_cpus
def test_threads_give_the_batchs_numbers_bit_for_bit():
    """The threaded entry runs the same control step per sub-environment as the one-thread entry
    (kernels/env/step.py's batch_loop), through resets, wind and pushes (the hard preset)."""
    options = {"preset": "hard", "task": "transport"}
    one, two = _rollout(1, options), _rollout(2, options)
    assert all(np.array_equal(a, b) for a, b in zip(one, two))
    # negative control: another task gives other numbers, so the comparison can fail
    assert not all(np.array_equal(a, b) for a, b in zip(one, _rollout(1, {**options, "task": "track"})))


@pytest.mark.parametrize("threads, message", [(0, "threads must be a whole number >= 1"),
                                              (1.5, "threads must be a whole number >= 1"),
                                              (True, "threads must be a whole number >= 1"),
                                              (available_cpus() + 1, "threads must be at most the")])
def test_a_bad_thread_count_is_refused_naming_threads(threads, message):
    with pytest.raises(ValueError, match=message):
        gym.make_vec(ENV_ID, num_envs=2, threads=threads)


@needs_two_cpus
def test_threads_benchmark_quick_runs(tmp_path):
    table = quick_benchmark("env_throughput", tmp_path, "env_throughput_threads", "--threads")["table"]
    assert {(row["condition"], row["threads"]) for row in table} == {(c, t) for c in ("idle", "busy")
                                                                     for t in (1, available_cpus())}
    assert all(row["steps_per_s"] > 0 for row in table)
