"""agents/headroom.py: the controller-plus-feed-forward episode is the evaluated episode when the
feed-forward is zero, the feed-forward passes through its knots, and the optimiser never reports
less than the controller."""
import numpy as np
import pytest

from agents.baselines.registry import baselines
from agents.evaluate import run_episodes
from agents.headroom import Episode, feedforward_axes, main


def test_a_zero_feedforward_is_the_controllers_evaluated_episode_and_a_push_changes_it():
    law = baselines("transport")["lqr"]
    episode = Episode("transport", law, seed=100000, knots=4)
    expected = run_episodes(law, "transport", 1, seed=100000)[0].ret
    assert episode(np.zeros(episode.size)) == expected
    assert episode(np.full(episode.size, 0.2)) < expected - 1.0  # negative control: a constant push costs


def test_the_feedforward_is_linear_between_its_knots_on_the_force_and_reel_axes():
    episode = Episode("lift", baselines("lift")["pd"], seed=1, knots=3)
    assert episode.axes == feedforward_axes(7) == [0, 1, 2, 6]
    assert feedforward_axes(4, drone=True) == [0, 1, 2, 3]  # a drone's thrust and rates
    values = np.arange(12.0).reshape(3, 4)
    f = episode.feedforward(values.ravel())
    assert f.shape == (500, 4)
    np.testing.assert_allclose(f[0], values[0])
    np.testing.assert_allclose(f[250], values[1])
    np.testing.assert_allclose(f[125], 0.5 * (values[0] + values[1]))


def test_the_script_writes_gains_that_are_never_negative(tmp_path):
    result = main(["--task", "transport", "--episodes", "1", "--knots", "2", "--evaluations", "12",
                   "--out", str(tmp_path / "h"), "--no-progress"])
    row = result["episodes"][0]
    assert row["optimised_return"] >= row["controller_return"] and row["gain"] >= 0.0
    assert (tmp_path / "h" / "headroom_transport.json").is_file()
    with pytest.raises(SystemExit):
        main(["--task", "transport", "--policy", "lqg", "--episodes", "1"])  # not a nominal transport baseline
