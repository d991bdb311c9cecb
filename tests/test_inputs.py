"""Inputs through the discrete Lagrange-d'Alembert principle: balances of momentum, angular
momentum and energy; the slack law; input validation; the unforced scheme kept bit for bit."""
import hashlib

import numpy as np
import pytest

import esp_gym
from esp_gym.kernels.jit import python_callable
from esp_gym.kernels.step.string import nodal_forces
from conftest import drift_ratio


def _state_hash(sim):
    st = sim.state
    return hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in (st.r, st.p, st.R, st.Pi))).hexdigest()


#: sha256 of (r, p, R, Pi) after 10,000 steps of the unforced scheme: a regression guard on its
#: bits. First computed with the kernel before inputs existed (commit "Kernel speed: inline the
#: step ..."), and unchanged by the inputs, the specialised kernels and the one-pass string
#: kernels; recomputed when the Thomas sweeps moved to fused multiply-adds (llvm.fma is
#: correctly rounded on every machine, so the bits do not depend on the CPU) and when Newton
#: learned to stop on its predicted next correction (paper_example only: on large_offset the
#: third iteration's correction never changed a bit).
CORE_PATH_HASHES = {
    "paper_example": "e8f0d87e2fc01d87601f98ab044de5745080ee4fb80a7456ee22dd27d55863b3",
    "large_offset": "4cd1d3d25de6212ac15b4e43c847b9c7f6b6d0ae852a0f5f10b322ac417f8587",
}


@pytest.mark.parametrize("name", sorted(CORE_PATH_HASHES))
@pytest.mark.parametrize("explicit_zeros", [False, True])
@pytest.mark.parametrize("specialise", [True, False])
def test_fixed_pivot_without_inputs_is_the_papers_scheme_bit_for_bit(name, explicit_zeros, specialise):
    sim = esp_gym.Simulator(esp_gym.load_scene(name), specialise=specialise)
    zeros = dict(body_torque=np.zeros(3), spatial_torque=np.zeros(3), pivot_force=np.zeros(3)) if explicit_zeros else {}
    sim.step(10_000, **zeros)
    assert _state_hash(sim) == CORE_PATH_HASHES[name]


def _free(name="paper_example_consistent", **kw):
    """A scene with a free 0.5 kg pivot (the consistent body rotates visibly under torques)."""
    return esp_gym.load_scene(name, pivot={"kind": "free", "mass": 0.5}, **kw)


def _weight(scene):
    return scene.gravity * (scene.body.mass + scene.pivot.mass + scene.string.length * scene.string.mass_per_length)


INPUTS = dict(pivot_force=None, body_torque=[0.01, 0.02, -0.01], spatial_torque=[0.0, 0.01, 0.02])


def test_free_pivot_without_inputs_conserves_momentum_and_pi3():
    """Free fall of the whole system: P changes only by the gravity impulse (relative 1e-12),
    pi3 is conserved to round-off, the energy oscillates without drift."""
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example_free_pivot"))
    tr = sim.run(t_final=5.0, record_every=100, every_step=True)
    resid = tr.linear_momentum - tr.linear_momentum[0] - tr.gravity_impulse
    assert np.abs(resid).max() <= 1e-12 * np.abs(tr.gravity_impulse).max()
    assert np.abs(tr.pivot_impulse).max() == 0.0
    assert np.abs(tr.pi3_every_step - tr.pi3[0]).max() <= 1e-15
    de = tr.energy_every_step - tr.energy[0]
    assert drift_ratio(tr.t_every_step, de) < 0.5


def test_spatial_torque_about_e3_changes_pi3_by_its_impulse():
    """pi3(k) - pi3(0) = k h T_z to round-off (the left half uses R_k^T, the right R_{k+1}^T)."""
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example"))
    T = np.array([0.0, 0.0, 0.05])
    tr = sim.run(t_final=5.0, record_every=100, spatial_torque=T)
    np.testing.assert_allclose(tr.angular_impulse_z, tr.t * T[2], rtol=1e-14, atol=1e-18)
    assert np.abs(tr.pi3[-1] - tr.pi3[0]) > 0.2  # it did spin up
    assert np.abs(tr.pi3_balance_residual).max() <= 1e-12


@pytest.mark.parametrize("hover", [0.0, 1.0, 1.3])
def test_all_inputs_balance_momentum_and_pi3(hover):
    """Pivot force (with hover feed-forward), body and spatial torques together: the linear
    momentum equals the gravity plus pivot-force impulses, and pi3 moves by exactly the
    discrete angular impulse, both to round-off over 2e4 steps."""
    scene = _free()
    sim = esp_gym.Simulator(scene)
    force = [0.3, -0.2, -hover * _weight(scene)]
    tr = sim.run(t_final=2.0, record_every=100, **{**INPUTS, "pivot_force": force})
    J = tr.gravity_impulse + tr.pivot_impulse
    resid = tr.linear_momentum - tr.linear_momentum[0] - J
    assert np.abs(resid).max() <= 1e-12 * max(np.abs(tr.gravity_impulse).max(), 1.0)
    assert np.abs(tr.pi3_balance_residual).max() <= 1e-12
    np.testing.assert_allclose(tr.pivot_impulse[-1], 2.0 * np.array(force), rtol=1e-13)


def test_energy_balance_residual_is_second_order():
    """|E - E0 - W| over 0.2 s falls as h^2 (fitted order >= 1.9): W, the discrete work
    u_p . dr_0 + tau_avg . theta, is consistent to second order."""
    hs = [1e-4, 5e-5, 2.5e-5, 1.25e-5]
    errs = []
    for h in hs:
        scene = _free(h=h)
        sim = esp_gym.Simulator(scene)
        tr = sim.run(t_final=0.2, record_every=int(round(0.005 / h)),
                     **{**INPUTS, "pivot_force": [0.3, -0.2, -1.2 * _weight(scene)]})
        assert tr.work[-1] > 0.1  # the inputs do real work
        errs.append(np.abs(tr.energy_balance_residual).max())
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert order >= 1.9, (order, errs)


def _slack_run(h, t_final=2.0):
    scene = esp_gym.load_scene("paper_example", h=h, **{"string.law": "slack"})
    return scene, esp_gym.Simulator(scene).run(t_final, record_every=int(round(1e-3 / h)), every_step=True)


#: The string's forces, called from Python (an internal kernel: esp_gym/kernels/jit.py).
_nodal_forces = python_callable(nodal_forces)


def _element_pull(nodes, kappa, u, slack):
    """Axial force each element exerts on its far node, projected on the element (>0 pushes)."""
    f = np.zeros((2, 3))
    out = []
    for a in range(nodes.shape[0] - 1):
        pair = np.ascontiguousarray(nodes[a:a + 2])
        _nodal_forces(pair, kappa, u, 0.0, 0.0, 0.0, 0.0, slack, f)
        out.append(f[1] @ (pair[1] - pair[0]))
    return np.array(out)


def test_slack_string_never_pushes():
    """Tension only: along a run with slack elements, no element pushes its nodes apart;
    the same configurations under the elastic law do push (negative control)."""
    scene, tr = _slack_run(1e-4)
    L = np.linalg.norm(np.diff(tr.nodes, axis=1), axis=2)
    slack_rows = np.where((L < scene.string.u).any(axis=1))[0]
    assert len(slack_rows) > 20  # the run does go slack
    k, u = scene.string.kappa, scene.string.u
    for row in slack_rows[:: max(1, len(slack_rows) // 40)]:
        assert _element_pull(tr.nodes[row], k, u, True).max() <= 0.0
        assert _element_pull(tr.nodes[row], k, u, False).max() > 0.0
        compressed = L[row] < u
        assert np.all(tr.strain_energy[row][compressed] == 0.0)


def test_slack_string_energy_is_second_order_through_snaps():
    """The tension-only energy is C^1 only; the energy error through slack-to-taut snaps still
    falls as h^2 (measured 1.98)."""
    hs = [1e-4, 5e-5, 2.5e-5, 1.25e-5]
    errs = []
    for h in hs:
        _, tr = _slack_run(h, t_final=1.0)
        errs.append(np.abs(tr.energy_every_step - tr.energy[0]).max())
    assert np.polyfit(np.log(hs), np.log(errs), 1)[0] >= 1.8, errs


@pytest.mark.parametrize("kwargs, match", [
    (dict(body_torque=[1.0, 2.0]), "body_torque must be a 3-vector"),
    (dict(spatial_torque=[[0, 0, 1]]), "spatial_torque must be a 3-vector"),
    (dict(body_torque=[0.0, np.nan, 0.0]), "body_torque must be finite"),
    (dict(spatial_torque=[np.inf, 0.0, 0.0]), "spatial_torque must be finite"),
    (dict(pivot_force=[1.0, 0.0, 0.0]), "needs a free pivot"),
])
def test_bad_inputs_raise_and_leave_the_state_untouched(kwargs, match):
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example"))
    sim.step(10)
    before = sim.state
    with pytest.raises(ValueError, match=match):
        sim.step(5, **kwargs)
    after = sim.state
    assert after.step == before.step and np.array_equal(after.r, before.r) and np.array_equal(after.Pi, before.Pi)


def test_free_pivot_rejects_nan_force():
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example_free_pivot"))
    with pytest.raises(ValueError, match="pivot_force must be finite"):
        sim.step(1, pivot_force=[0.0, 0.0, np.nan])
    assert sim.step_count == 0


def test_hover_force_holds_the_pivot_up():
    """A pivot force equal to the whole weight (upwards, -e3) keeps the total momentum's vertical
    component constant: the impulses cancel exactly at every step."""
    scene = esp_gym.load_scene("paper_example_free_pivot")
    sim = esp_gym.Simulator(scene)
    tr = sim.run(1.0, record_every=100, pivot_force=[0.0, 0.0, -_weight(scene)])
    np.testing.assert_allclose(tr.linear_momentum[:, 2], tr.linear_momentum[0, 2], atol=1e-13)
