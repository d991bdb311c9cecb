"""The MuJoCo point-mass chain (esp_gym/verify/mujoco_chain.py) is the same model as our lumped LGVI.

Evidence, from the cheapest to the strongest: the energy at t = 0 agrees to round-off on every
scene (kinetic, gravity and elastic terms, R0, Omega0, free pivot, slack law); the state
conventions (node sites, attitude, body-frame angular velocity) read back exactly; MuJoCo's RK4
converges at order 4 to the Richardson extrapolation of the LGVI, and the LGVI at order 2 to
MuJoCo; and each single mistake one could make in the MJCF (gravity sign, rho_c sign, inertia,
one stiffness, angular velocity frame, quaternion order, two-sided instead of slack springs)
leaves a difference >= 1e7 times the correct model's (2.7e4 times for the slack law).
"""
import json
import subprocess
import sys
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np
import pytest

import esp_gym
from esp_gym.verify.mujoco_chain import MujocoChain, quaternion

ROOT = Path(__file__).resolve().parent.parent
T = 0.2  # [s] the motion is smooth and far from chaotic divergence (~2 s) over this horizon
SAMPLE = 0.01  # [s] attachment point compared every SAMPLE
#: Scenes compared along trajectories: fixed and free pivot, R0 != I, Omega0 != 0, stretched
#: start. Not drone_load: its free pivot starts at rest with the string straight and unstretched,
#: so the whole system falls freely with no relative motion, which every integrator gets exactly.
TRAJECTORY_SCENES = ["paper_example", "large_offset", "short_stiff", "paper_example_free_pivot"]


def lumped(name: str, **overrides):
    string = {"mass_model": "lumped", **overrides.pop("string", {})}
    return esp_gym.load_scene(name, string=string, **overrides)


def distance(x, y) -> float:
    """Max over samples of the attachment point distance [m]."""
    return float(np.linalg.norm(x - y, axis=1).max())


@lru_cache(maxsize=None)
def lgvi_samples(name: str, h: float, law: str = "elastic") -> np.ndarray:
    sim = esp_gym.Simulator(lumped(name, h=h, string={"law": law}))
    return sim.run(T, record_every=int(round(SAMPLE / h))).nodes[:, -1]


@lru_cache(maxsize=None)
def lgvi_reference(name: str, law: str = "elastic") -> np.ndarray:
    """Richardson extrapolation of the LGVI at h = 1e-5, 5e-6 s: the LGVI is symmetric, its
    error expands in h^2, h^4, so this removes the h^2 term (measured: MuJoCo RK4 at
    h = 2.5e-5 s comes within 7e-15 .. 2.8e-13 m of it on TRAJECTORY_SCENES)."""
    x1, x2 = lgvi_samples(name, 1e-5, law), lgvi_samples(name, 5e-6, law)
    return x2 + (x2 - x1) / 3.0


def mujoco_samples(name: str, h: float, integrator: str = "RK4", law: str = "elastic", mutate=None) -> np.ndarray:
    chain = MujocoChain(lumped(name, string={"law": law}), integrator, h=h)
    if mutate is not None:
        mutate(chain)
    x = chain.samples(T, int(round(SAMPLE / h)))
    assert chain.warnings() == 0
    return x


@pytest.mark.parametrize("name", esp_gym.available_scenes())
def test_energy_at_t0_equals_the_lgvi_scene_energy(name):
    scene = lumped(name)
    E0 = esp_gym.Simulator(scene).diagnostics()["energy"]
    E = MujocoChain(scene).total_energy()
    # the same terms summed differently by each side: round-off (measured <= 4e-16 relative)
    assert E == pytest.approx(E0, rel=1e-12, abs=1e-14)


def test_slack_law_energy_at_t0_counts_no_compressed_element():
    # nodes bunched at 0.9 u: every element compressed; the slack law stores no elastic energy
    scene = lumped("short_stiff", string={"law": "slack"}, initial={"stretch": 0.9})
    E0 = esp_gym.Simulator(scene).diagnostics()["energy"]
    elastic = lumped("short_stiff", initial={"stretch": 0.9})
    assert esp_gym.Simulator(elastic).diagnostics()["energy"] > E0 + 1e-3
    assert MujocoChain(scene).total_energy() == pytest.approx(E0, rel=1e-12)


def test_state_conventions_read_back_exactly():
    scene = lumped("large_offset")  # R0 != I, Omega0 = (0, 0, 5) rad/s, attach velocity (0, 1, 0)
    chain = MujocoChain(scene)
    m, d = chain.model, chain.data
    mujoco.mj_forward(m, d)
    sites = np.array([d.site(f"s{a}").xpos for a in range(scene.string.elements + 1)])
    np.testing.assert_array_equal(sites, scene.initial_nodes())
    np.testing.assert_allclose(d.xmat[chain.load_body].reshape(3, 3), scene.initial.R0, rtol=0, atol=1e-15)
    vel = np.zeros(6)  # (angular, linear) of the body frame: local orientation, then world
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, chain.load_body, vel, 1)
    np.testing.assert_allclose(vel[:3], scene.initial.Omega0, rtol=0, atol=1e-14)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, chain.load_body, vel, 0)
    np.testing.assert_allclose(vel[3:], scene.initial.attach_velocity, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(chain.node_positions(), scene.initial_nodes())


def slope(hs, errors) -> float:
    """Least-squares slope of log(error) against log(h)."""
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


@pytest.mark.parametrize("name", TRAJECTORY_SCENES)
def test_mujoco_rk4_converges_to_the_lgvi_at_order_4(name):
    ref = lgvi_reference(name)
    hs = (2e-4, 1e-4, 5e-5)
    errors = [distance(mujoco_samples(name, h), ref) for h in hs]
    # measured slopes 4.00-4.09; a wrong model plateaus (slope ~0, see the test below)
    assert 3.6 < slope(hs, errors) < 4.4, errors
    # measured 7.5e-14 (paper example) .. 4.7e-12 m (short_stiff) at h = 5e-5 s
    assert errors[-1] < 2e-11, errors


@pytest.mark.parametrize("name", TRAJECTORY_SCENES)
def test_lgvi_converges_to_mujoco_at_order_2(name):
    ref = mujoco_samples(name, 2.5e-5)  # RK4, within ~1e-12 m of the LGVI's limit
    hs = (2e-4, 1e-4, 5e-5)
    errors = [distance(lgvi_samples(name, h), ref) for h in hs]
    assert 1.9 < slope(hs, errors) < 2.1, errors  # measured 1.985-1.999


def test_slack_springs_agree_with_the_slack_lgvi():
    # short_stiff compresses elements within T; the law's kink at |r'| = 1 costs RK4 its order
    # (measured 9.7e-9, 1.0e-9, 5.8e-10 m at h = 2e-4, 1e-4, 5e-5 s), so this checks agreement
    ref = lgvi_reference("short_stiff", law="slack")
    assert distance(mujoco_samples("short_stiff", 5e-5, law="slack"), ref) < 3e-9
    two_sided = mujoco_samples("short_stiff", 5e-5, law="slack", mutate=_two_sided_springs)
    assert distance(two_sided, ref) > 1e-6  # measured 1.6e-5 m


def _two_sided_springs(chain):
    chain.model.tendon_lengthspring[:, 0] = chain.model.tendon_lengthspring[:, 1]


def _flip_gravity(chain):
    chain.model.opt.gravity[2] *= -1.0


def _flip_rho(chain):
    chain.model.body_ipos[chain.load_body] *= -1.0


def _inertia_plus_1pct(chain):
    chain.model.body_inertia[chain.load_body] *= 1.01


def _one_stiffness_plus_1pct(chain):
    chain.model.tendon_stiffness[7] *= 1.01


def _omega_in_world_frame(chain):
    i = chain.load_qvel + 3
    R0 = np.array(chain.scene.initial.R0)
    chain.data.qvel[i:i + 3] = R0 @ chain.data.qvel[i:i + 3]


def _quaternion_xyzw(chain):
    i = chain.load_qpos + 3
    chain.data.qpos[i:i + 4] = np.roll(quaternion(np.array(chain.scene.initial.R0)), -1)


@pytest.mark.parametrize("name, mutate", [
    ("paper_example", _flip_gravity),
    ("paper_example", _one_stiffness_plus_1pct),
    # large_offset: a light body far off its attachment point, spinning, R0 != I (the paper
    # example's J is so large that its body hardly turns in T: rho_c and J barely show there)
    ("large_offset", _flip_rho),
    ("large_offset", _inertia_plus_1pct),
    ("large_offset", _omega_in_world_frame),
    ("large_offset", _quaternion_xyzw),
])
def test_a_wrong_model_is_far_outside_the_agreement(name, mutate):
    # the correct models are within 4e-13 m at h = 5e-5 s (above); each mistake is >= 1e-6 m off
    # over T (measured: the smallest, element 7 1 % too stiff, 4.8e-6 m; the largest 0.39 m)
    assert distance(mujoco_samples(name, 5e-5, mutate=mutate), lgvi_reference(name)) > 1e-6


def test_mujoco_chain_benchmark_quick_runs(tmp_path):
    # --quick: a few points per method, a 2-s long run: ~15 s here, most of it compiling
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks.mujoco_chain", "--quick", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    results = json.loads((tmp_path / "mujoco_chain.json").read_text())
    assert results["reference"]["vs_mujoco_rk4_m"] < 1e-9
    assert all(row["status"] == "ok" for rows in results["work_precision"].values() for row in rows)
    assert {s["integrator"] for s in results["stability"]} >= {"LGVI (esp_gym)", "MuJoCo RK4", "MuJoCo Euler"}
    assert (tmp_path / "mujoco_chain.png").stat().st_size > 0


def test_stiff_work_precision_quick_runs(tmp_path):
    """The stiff work-precision benchmark's smoke test: every method runs (or is abandoned or
    fails with its status), and the resolution rule's point is the fastest to 1 cm."""
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks.stiff_work_precision", "--quick", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    result = json.loads((tmp_path / "stiff_work_precision.json").read_text())
    assert set(result["results"]) >= {"LGVI, elements auto", "LGVI, N = 8 explicit", "MuJoCo discrete, N = 8 lumped"}
    fastest = {name: t for name, t in result["time_to_error"]["0.01"].items() if t is not None}
    assert min(fastest, key=fastest.get) == "LGVI, elements auto"
