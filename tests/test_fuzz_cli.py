"""Fuzzed command lines (issue 12): ``esp_gym.cli.main`` answers every argument vector with a
documented exit status, one clear line on stderr when it refuses, no traceback, and nothing on
disk unless it ran. The runners are replaced by recorders, so no simulation runs: what reaches
them must be within the checked limits.

Derandomized and few examples (well under 10 s), so CI sees the same ones on every run.
"""
import math

import pytest
from hypothesis import HealthCheck, event, given, settings, strategies as st

from esp_gym import cli
from esp_gym.physics import simulator as model
from esp_gym.scene.params import SCENES_DIR
from esp_gym.viz import recording

FUZZ = settings(deadline=None, max_examples=400,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
STATUSES = {cli.EXIT_OK, cli.EXIT_USAGE, cli.EXIT_SCENE}  # 1 and 4 need a run, and nothing runs here

numbers = st.one_of(st.sampled_from(["5", "0.05", "0.0001", "1e-4", "0", "-1", "inf", "-inf", "nan", "1e9", "1e300",
                                     "2000", "1e5", "0.00015", "3", "100", "1", "x", "", " 1", "0x10", "1_0"]),
                    st.floats().map(repr), st.integers().map(str), st.text(max_size=5))
paths = st.sampled_from(["{root}/out", "{root}/out/x.rrd", "{root}/file", "{root}/file/x.rrd", "{root}", "{root}/",
                         "", " ", "{root}/dir", "{root}/dir/", "{root}/new/deep/x.rrd", "rel/x.rrd", "\x00"])
scenes = st.sampled_from(["paper_example", "drone_load", "no_such", "{root}/bad.yaml", "{root}/good.YAML",
                          "{root}/dir", "{root}/missing.yml", ""])
options = st.one_of(
    st.tuples(st.just("--t-final"), numbers), st.tuples(st.just("--record-every"), numbers),
    st.tuples(st.just("--out"), paths), st.tuples(st.just("--scene"), scenes),
    st.tuples(st.sampled_from(["--no-progress", "--help", "-h", "--bogus", "--t-final", "-x"])),
    st.tuples(st.text(max_size=6)))
commands = st.sampled_from(["paper"] * 5 + ["record"] * 5 + ["bogus", "", "--help"])
argvs = st.tuples(commands, st.lists(options, max_size=4)).map(
    lambda t: [t[0]] + [part for option in t[1] for part in option])


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli")
    (root / "file").write_text("")
    (root / "dir").mkdir()
    (root / "bad.yaml").write_text("string: [1,\n")
    (root / "good.YAML").write_text((SCENES_DIR / "paper_example.yaml").read_text())
    return root


@pytest.fixture(scope="module")
def runs():
    """Replace the runners by recorders of their arguments (module-wide, undone at the end)."""
    calls = []
    patch = pytest.MonkeyPatch()

    def run_paper(out, t_final, record_every, progress, argv):
        calls.append(("paper", t_final, record_every, None))
        return {}

    class Simulator:
        def __init__(self, scene):
            self.scene, self.h = scene, scene.h

    def record_simulation(sim, path, t_final, record_every, progress, **kwargs):
        calls.append(("record", t_final, record_every, sim.scene))
        return {"scene": sim.scene.name, "steps": 0, "samples": 0, "record_every": record_every,
                "wall_time_s": 0.0, "max_abs_energy_balance_residual": 0.0, "max_abs_pi3_balance_residual": 0.0}

    patch.setattr(cli, "run_paper", run_paper)
    patch.setattr(cli, "_print_summary", lambda summary, out: None)
    patch.setattr(model, "Simulator", Simulator)
    patch.setattr(recording, "record_simulation", record_simulation)
    yield calls
    patch.undo()


def _tree(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@FUZZ
@given(argv=argvs)
def test_any_command_line_gets_a_documented_status_and_one_line(root, runs, capsys, argv):
    argv = [a.replace("{root}", str(root)) for a in argv]
    before, calls = _tree(root), len(runs)
    status = cli.main(argv)
    out, err = capsys.readouterr()
    event(f"{argv[0] or 'no command'}: exit status {status}")
    assert status in STATUSES, (argv, status, err)
    assert "Traceback" not in err + out
    assert _tree(root) == before  # refusals create nothing, and the recorders write nothing
    if status != cli.EXIT_OK:
        assert err.count("\n") == 1 and err.startswith("esp-gym"), (argv, err)
        assert len(runs) == calls
        return
    if len(runs) == calls:  # --help
        assert "usage: esp-gym" in out
        return
    command, t_final, record_every, scene = runs[-1]
    h = cli.PAPER["h"] if command == "paper" else scene.h
    assert math.isfinite(t_final) and t_final > 0 and record_every >= 1
    steps = round(t_final / h)
    assert steps <= cli.MAX_STEPS and abs(steps * h - t_final) <= 1e-9 * max(1.0, t_final)
