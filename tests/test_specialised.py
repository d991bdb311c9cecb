"""Specialised kernels (esp_gym.kernels.step.specialise.specialised_kernels): each drops what its scene does
not need and must give the general kernel's numbers bit for bit; the decoupled (rho_c = 0)
path must show the physics of a decoupled body."""
import numpy as np
import pytest

import esp_gym
from esp_gym.kernels.step.loops import lgvi_advance
from esp_gym.kernels.step.specialise import specialised_kernels

FREE = {"pivot": {"kind": "free", "mass": 0.3}}
DECOUPLED = {"rho_c": [0.0, 0.0, 0.0], "initial": {"Omega0": [0.3, -2.0, 5.0]}}

CASES = {
    # scene overrides, inputs, the flags the simulator must pick (coupled [, compensated]): the
    # pivot and the inputs are read at run time, so a free pivot, inputs or none share a kernel
    "fixed-unforced": ({}, {}, (True,)),
    "fixed-torques": ({}, {"body_torque": [0.0, 0.01, 0.02], "spatial_torque": [0.0, 0.0, 0.03]},
                      (True,)),
    "free-unforced": (FREE, {}, (True,)),
    "free-pushed": (FREE, {"pivot_force": [0.2, -0.1, -3.0], "body_torque": [0.01, 0.0, 0.0]},
                    (True,)),
    "decoupled": (DECOUPLED, {}, (False,)),
    "decoupled-free-pushed": ({**DECOUPLED, **FREE}, {"pivot_force": [0.0, 0.5, -3.0]}, (False,)),
    "order6-free-pushed": ({**FREE, "solver": {"order": 6}}, {"pivot_force": [0.1, 0.0, -3.0]},
                           (True,)),
    # plain (uncompensated) state updates: the general path reads P.compensated at run time
    "plain-fixed-unforced": ({"solver": {"compensated": False}}, {}, (True, False)),
    "plain-order4-free-pushed": ({**FREE, "solver": {"order": 4, "compensated": False}},
                                 {"pivot_force": [0.1, 0.0, -3.0], "spatial_torque": [0.0, 0.0, 0.02]},
                                 (True, False)),
}


def _run(overrides, inputs, specialise, steps=3000):
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example", **overrides), specialise=specialise)
    traj = sim.run(t_final=steps * sim.h, record_every=500, **inputs)
    return sim, traj


@pytest.mark.parametrize("case", sorted(CASES))
def test_specialised_kernel_is_the_general_one_bit_for_bit(case):
    """Every dropped term is an exact zero on the general path, so states, snapshots and the
    input balances agree exactly (not merely to round-off)."""
    overrides, inputs, flags = CASES[case]
    fast, tf = _run(overrides, inputs, True)
    slow, ts = _run(overrides, inputs, False)
    assert fast._kernels()[0] is specialised_kernels(*flags)[0]
    assert slow._kernels()[0] is lgvi_advance
    a, b = fast.state, slow.state
    for name in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    for name, x in tf.arrays().items():
        assert np.array_equal(x, getattr(ts, name), equal_nan=True), name
    da, db = fast.diagnostics(), slow.diagnostics()
    for key in ("work", "angular_impulse_z", "pivot_impulse", "gravity_impulse"):
        assert np.array_equal(da[key], db[key]), key


def test_inputs_switched_on_and_off_keep_the_paths_identical():
    """A run that alternates between zero and non-zero inputs keeps one kernel (the inputs are
    read at run time), and its state equals the general kernel's bit for bit."""
    sims = [esp_gym.Simulator(esp_gym.load_scene("paper_example", **FREE), specialise=s) for s in (True, False)]
    for k in range(6):
        force = [0.0, 0.3 * k, -2.0] if k % 2 else None
        for sim in sims:
            sim.step(400, pivot_force=force)
    assert len(sims[0]._kernel_cache) == 1
    a, b = (s.state for s in sims)
    for name in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_decoupled_body_does_not_move_the_string_and_keeps_its_spatial_momentum():
    """rho_c = 0: the string cannot feel the body's rotation, so two runs that differ only in
    Omega0 give bit-identical node trajectories; the body is a free rigid body, whose spatial
    angular momentum R Pi the LGVI conserves to round-off (asserted to 1e-14 relative over
    2e4 steps; measured ~1e-16)."""
    base = {"rho_c": [0.0, 0.0, 0.0]}
    runs = []
    for omega in ([0.0, 0.0, 0.0], [0.3, -2.0, 5.0]):
        sim = esp_gym.Simulator(esp_gym.load_scene("paper_example", **base, initial={"Omega0": omega}))
        pi_spatial0 = sim.state.R @ sim.state.Pi
        traj = sim.run(t_final=20_000 * sim.h, record_every=1000)
        st = sim.state
        runs.append(traj.nodes)
        if np.any(omega):
            drift = np.abs(st.R @ st.Pi - pi_spatial0).max() / np.abs(pi_spatial0).max()
            assert drift <= 1e-14, drift
            assert np.abs(traj.R[-1] - traj.R[0]).max() > 0.1  # it did rotate
    assert np.array_equal(runs[0], runs[1])
