"""The compiled stepper (Schur complement + Cayley Newton) and the plain-NumPy reference
(dense Newton on all 3N+3 unknowns, esp_gym.verify.reference) produce the same trajectory.

Tolerances (every 50 steps, up to 200 steps):

* positions: |r_kernel - r_ref| <= 1e-12 max|r| [m]. Round-off model: each step adds dr to r
  with a rounding of eps |r|; the two codes round differently, so their difference random-walks
  as sqrt(K) eps |r| ~ 3e-15 |r| after K = 200 steps (the solves' own eps-relative errors in dr
  ~ 5e-5 m are far smaller). Measured: 1e-15 |r|. For scale, flipping the sign of one gravity
  term of (DRLd) in the reference gives 1e-6 |r| and 6e-4 |Pi| (paper scene, N = 3).
* R: |R_kernel - R_ref| <= 1e-12 (entries are O(1); same model; measured 5e-15).
* momenta: |p_kernel - p_ref| <= 1e-12 max|p| [kg m/s] and |Pi_kernel - Pi_ref| <= 1e-12 |Pi|
  [kg m^2/s]: the momenta are sums of O(1/h) terms that cancel to O(1) (e.g. M_tot dr / h), so
  each step carries ~10 eps relative error, random-walking to ~1e-14 after 200 steps.
  Measured: 2e-14.

Each bound leaves a margin of ~50-1000 for platform differences (FMA, BLAS).
"""
import subprocess
import sys

import numpy as np
import pytest

import esp_gym
from esp_gym.verify.reference import reference_run, reference_step

from discrete_lagrangian import GEOMETRIC_OVERRIDES, random_state

TOL = 1e-12  # relative; see the module docstring
CHUNK = 50
CHUNKS = 4


def _scene(kind, N):
    """"paper"/"geometric" (paper_example with GEOMETRIC_OVERRIDES) at N elements, or a scene
    file by name at its own N (N is None)."""
    if kind in ("paper", "geometric"):
        overrides = GEOMETRIC_OVERRIDES if kind == "geometric" else {}
        return esp_gym.load_scene("paper_example", N=N, **overrides)
    return esp_gym.load_scene(kind)


def discrepancies(a, b):
    """Relative differences of two states: positions / max|r|, R (absolute), p / max|p|, Pi / |Pi|."""
    return dict(
        r=float(np.abs(a.r - b.r).max() / np.abs(a.r).max()),
        R=float(np.abs(a.R - b.R).max()),
        p=float(np.abs(a.p - b.p).max() / np.abs(a.p).max()),
        Pi=float(np.linalg.norm(a.Pi - b.Pi) / np.linalg.norm(a.Pi)),
    )


@pytest.mark.parametrize("kind, N, start", [
    pytest.param("paper", 1, "random", id="paper-N1-random"),
    pytest.param("paper", 3, "random", id="paper-N3-random"),
    pytest.param("paper", 8, "random", id="paper-N8-random"),
    pytest.param("geometric", 3, "random", id="geometric-N3-random"),
    pytest.param("paper", 8, "scene", id="paper-N8-initial"),
    pytest.param("geometric", 3, "scene", id="geometric-N3-initial"),
    pytest.param("short_stiff", None, "scene", id="short_stiff-initial"),
    pytest.param("large_offset", None, "scene", id="large_offset-initial"),
])
def test_reference_run_matches_kernel_over_200_steps(kind, N, start):
    """Simulator.step and reference_run agree to 1e-12 (relative; positions [m], R, p [kg m/s],
    Pi [kg m^2/s]) at every 50th of 200 steps, from a random perturbed state or the scene's own
    initial state. "geometric": rho_c = (0.10, 0.04, 0.08) m and the cylinder's real inertia
    (~1e-3 kg m^2) about that point; short_stiff and large_offset: the scene files as they are
    (spinning bodies, h = 1e-4 and 2e-4)."""
    scene = _scene(kind, N)
    sim = esp_gym.Simulator(scene)
    state = random_state(scene, np.random.default_rng(100 + N)) if start == "random" else sim.state
    sim.set_state(state)
    worst = dict(r=0.0, R=0.0, p=0.0, Pi=0.0)
    for _ in range(CHUNKS):
        sim.step(CHUNK)
        state = reference_run(scene, state, CHUNK)
        for key, value in discrepancies(sim.state, state).items():
            worst[key] = max(worst[key], value)
    assert state.step == sim.step_count == CHUNK * CHUNKS
    assert max(worst.values()) < TOL, worst


def test_reference_step_keeps_pivot_and_rotation():
    """The reference step leaves the pivot row (r_1, p_1) untouched and keeps R_{k+1} in SO(3)
    (|R^T R - I| at round-off, det R = 1)."""
    scene = _scene("paper", 3)
    before = random_state(scene, np.random.default_rng(5))
    after = reference_step(scene, before)
    np.testing.assert_array_equal(after.r[0], before.r[0])
    np.testing.assert_array_equal(after.p[0], before.p[0])
    assert np.abs(after.R.T @ after.R - np.eye(3)).max() < 1e-14
    assert abs(np.linalg.det(after.R) - 1.0) < 1e-14
    assert after.step == before.step + 1


def test_reference_module_does_not_import_the_kernels():
    """esp_gym.verify.reference is an independent path: importing it loads no esp_gym.kernels module."""
    code = ("import sys, esp_gym.verify.reference; "
            "bad = [m for m in sys.modules if m.startswith('esp_gym.kernels') or m == 'numba']; "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True)
