"""Smoke tests of the command line (``esp-gym paper``) and of the step-cost benchmark script."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent

SUMMARY_KEYS = {
    "steps", "wall_time_s", "us_per_step", "us_per_step_recording", "energy_initial",
    "energy_max_abs_error", "energy_drift_slope", "pi3_max_abs_deviation", "orthogonality_max",
    "stretched_length_min", "stretched_length_max", "newton_iterations_mean", "newton_iterations_max",
    "scene", "N", "h",
}
SNAPSHOT_ARRAYS = ("kinetic_string", "kinetic_body", "potential_gravity", "potential_elastic", "energy",
                   "pi3", "orthogonality", "stretched_length")
EVERY_STEP_ARRAYS = ("t_every_step", "energy_every_step", "pi3_every_step", "orthogonality_every_step")


def test_paper_command_writes_consistent_outputs(tmp_path):
    out = tmp_path / "paper"
    proc = subprocess.run(
        [sys.executable, "-m", "esp_gym.cli", "paper", "--out", str(out), "--t-final", "0.05",
         "--record-every", "10", "--no-progress"],
        capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for name in ("summary.json", "trajectory.npz", "fig_ns.png", "fig_sm.png"):
        assert (out / name).is_file(), name
        assert (out / name).stat().st_size > 0, name

    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary), SUMMARY_KEYS - set(summary)
    steps, n, k = 500, 20, 500 // 10 + 1  # 0.05 s / 1e-4 s; N = 20; snapshots incl. t = 0
    assert summary["steps"] == steps and summary["N"] == n and summary["h"] == 1e-4
    assert summary["scene"] == "paper_example"

    data = np.load(out / "trajectory.npz")
    assert data["t"].shape == (k,)
    assert data["nodes"].shape == (k, n + 1, 3)
    assert data["R"].shape == (k, 3, 3)
    assert data["omega"].shape == (k, 3)
    assert data["attach_velocity"].shape == (k, 3)
    assert data["strain_energy"].shape == (k, n)
    for name in SNAPSHOT_ARRAYS:
        assert data[name].shape == (k,), name
    for name in EVERY_STEP_ARRAYS:
        assert data[name].shape == (steps,), name
    assert np.allclose(data["t"], 10 * 1e-4 * np.arange(k))
    # the every-step series and the snapshots describe the same run
    assert np.array_equal(data["energy_every_step"][9::10], data["energy"][1:])
    assert summary["energy_initial"] == float(data["energy"][0])


def test_paper_command_rejects_a_partial_record_interval(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "esp_gym.cli", "paper", "--out", str(tmp_path), "--t-final", "0.0055",
         "--record-every", "10", "--no-progress"],
        capture_output=True, text=True, timeout=600)
    assert proc.returncode == 2
    assert "whole number" in proc.stderr


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # projecting the poison
def test_snapshot_figure_does_not_autoscale_over_uninitialised_memory(tmp_path, monkeypatch):
    """CI stop 9: matplotlib pads the ragged body polygons (quads and 24-gon caps) with
    np.empty and, with autolim, scaled the axes over the padding; whatever the memory held
    could overflow the limits. Poisoning np.empty makes that failure certain."""
    from esp_gym.model import Simulator
    from esp_gym.params import load_scene
    from esp_gym.viz.figures import plot_fig_sm

    scene = load_scene("paper_example", N=5, h=1e-3)
    traj = Simulator(scene).run(t_final=0.04, record_every=10)
    real_empty = np.empty

    def poisoned(shape, dtype=float, *args, **kwargs):
        a = real_empty(shape, dtype, *args, **kwargs)
        if np.issubdtype(a.dtype, np.floating):
            a.fill(-1.79e308)
        return a

    monkeypatch.setattr(np, "empty", poisoned)
    path = plot_fig_sm(traj, scene, tmp_path / "fig_sm.png")
    assert path.stat().st_size > 0


def test_step_cost_quick_runs(tmp_path):
    # --quick takes well under 20 s here (cold compile to the first step is most of it)
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks.step_cost", "--quick", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    results = json.loads((tmp_path / "step_cost.json").read_text())
    assert [r["N"] for r in results["step_cost"]] == [5, 20]
    assert all(r["us_per_step"] > 0 and r["h"] < r["h_bound"] for r in results["step_cost"])
    assert results["startup"]["cold"]["first_step_s"] > 0
    assert (tmp_path / "step_cost.png").stat().st_size > 0


def test_spatial_convergence_quick_shows_order_2_on_smooth_data(tmp_path):
    """The finite elements converge at order 2 in N on smooth data (the hanging start), and
    more slowly from the paper's velocity jump at the attachment point (order ~1)."""
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks.spatial_convergence", "--quick", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    table = json.loads((tmp_path / "spatial_convergence.json").read_text())["table"]
    for mass in ("consistent", "lumped"):
        smooth = [o for o in table[f"hanging/{mass}"]["order"] if o is not None]
        assert smooth and all(abs(o - 2.0) < 0.2 for o in smooth), smooth
    jump = [o for o in table["paper/consistent"]["order"] if o is not None]
    assert jump and all(o < 1.5 for o in jump), jump
    assert (tmp_path / "spatial_convergence.png").stat().st_size > 0


def test_cold_start_quick_measures_a_cold_and_a_warm_start(tmp_path):
    """The start-up benchmark's smoke test: a fresh cache compiles, the second process loads
    what the first one cached, so its first step comes sooner."""
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks.cold_start", "--quick", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    runs = json.loads((tmp_path / "cold_start.json").read_text())["runs"]
    assert [(r["case"], r["cache"]) for r in runs] == [("simulator", "cold"), ("simulator", "warm")]
    cold, warm = runs
    assert 0 < cold["import_s"] <= cold["construct_s"] <= cold["first_step_s"] <= cold["process_s"]
    assert warm["first_step_s"] < cold["first_step_s"]
