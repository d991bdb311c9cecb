"""Long simulator calls can be interrupted (esp_gym/physics/simulator.py, ``Simulator.call_seconds``): a long
``step`` or ``run`` is a Python loop over compiled calls of ~50 ms, so Ctrl-C stops it, and
the simulator keeps the state and step count of the calls it made. The cut changes no bit.
"""
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import esp_gym
from esp_gym.physics.simulator import SimulationError

FREE = {"pivot": {"kind": "free", "mass": 0.3}}
#: scene overrides and inputs: the plain LGVI unforced, and a composed (order 6, checkpointed)
#: stepper with a free pivot pushed
CASES = {
    "fixed-unforced": ({}, {}),
    "order6-free-pushed": ({**FREE, "solver": {"order": 6}}, {"pivot_force": [0.1, 0.0, -3.0]}),
}


def simulator(overrides=None, one_call=False, scene="paper_example"):
    sim = esp_gym.Simulator(esp_gym.load_scene(scene, **(overrides or {})))
    if one_call:
        sim.steps_per_call = 10 ** 12  # every step() is one compiled call
    else:
        sim.steps_per_call, sim.call_seconds = 1000, 1e-9  # calls of 1000, then 256 steps
    return sim


def state_arrays(sim):
    st = sim.state
    d = sim.diagnostics()
    return dict(r=st.r, p=st.p, R=st.R, Pi=st.Pi, **{f"remainder{i}": x for i, x in enumerate(st.remainders)},
                work=d["work"], pivot_impulse=d["pivot_impulse"], angular_impulse_z=d["angular_impulse_z"],
                step=sim.step_count, newton=sim.newton_iterations, newton_max=sim.newton_iterations_max)


def assert_same(a, b):
    for key, x in state_arrays(a).items():
        assert np.array_equal(x, state_arrays(b)[key]), key


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_step_cut_into_calls_is_bit_identical_to_one_call(case):
    overrides, inputs = CASES[case]
    one, cut = simulator(overrides, one_call=True), simulator(overrides)
    for sim in (one, cut):
        sim.step(30_011, **inputs)
    assert cut.steps_per_call == 256  # it was cut (the shortest call)
    assert_same(one, cut)


def test_a_run_cut_into_calls_is_bit_identical_to_one_call():
    one, cut = simulator(one_call=True), simulator()
    ta, tb = (sim.run(t_final=25_050 * sim.h, record_every=100) for sim in (one, cut))  # 250 rows and a rest
    assert cut.steps_per_call == 256
    for name, x in ta.arrays().items():
        assert np.array_equal(x, getattr(tb, name)), name
    assert_same(one, cut)


@pytest.mark.parametrize("order, factor", [(2, 1.003), (4, 1.212)])
def test_a_failure_in_a_cut_step_keeps_the_last_good_state(order, factor):
    """Just above the stability bound a run fails after some 10^4 steps (a composed step then
    rewinds to its last checkpoint and replays): the same step, the same last good state,
    whether the steps are one call or many."""
    bound = esp_gym.load_scene("paper_example").string.element_bound
    # the energy watchdog off: it looks at the end of calls, so where it fires depends on how the
    # calls are cut (the steps do not); the blow-up guard's step is what is compared here
    over = {"h": factor * bound, "allow_unstable_h": True, "solver": {"order": order, "energy_watchdog": None}}
    one, cut = simulator(over, one_call=True), simulator(over)
    errors = []
    for sim in (one, cut):
        with pytest.raises(SimulationError) as err:
            sim.step(1_000_000)
        errors.append(err.value)
    assert errors[0].step == errors[1].step == one.step_count > 5000
    assert_same(one, cut)


def default_sigint() -> None:
    """In a child before it starts: SIGINT's default disposition, so Python raises KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


CHILD = r'''
import sys, time, numpy as np, esp_gym
sim = esp_gym.Simulator(esp_gym.load_scene("paper_example"))
sim.step(100)  # compiled (or loaded from the kernel cache)
print("ready", flush=True)
try:
    sim.step(2_000_000_000)  # ~20 minutes
except KeyboardInterrupt:
    st = sim.state
    np.savez(sys.argv[1], r=st.r, p=st.p, R=st.R, Pi=st.Pi, remainders=np.concatenate([x.ravel() for x in st.remainders]),
             step=sim.step_count, time=sim.time, newton=sim.newton_iterations, caught=time.monotonic())
    raise
'''


def test_ctrl_c_stops_a_long_step_with_a_consistent_state(tmp_path):
    out = tmp_path / "interrupted.npz"
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=default_sigint)  # as a terminal leaves it, not a background job
    watchdog = threading.Timer(120, proc.kill)  # a child that hangs before it is ready fails the test
    watchdog.start()
    try:
        assert proc.stdout.readline().strip() == "ready", proc.stderr.read()
        time.sleep(1.0)
        sent = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=20)
        ended = time.monotonic() - sent
    finally:
        watchdog.cancel()
        proc.kill()
    err = proc.stderr.read()
    assert proc.returncode == -signal.SIGINT and "KeyboardInterrupt" in err, err
    assert ended < 2.0, ended
    saved = np.load(out)
    assert float(saved["caught"]) - sent < 0.5  # the compiled call in progress was ~50 ms long
    steps = int(saved["step"])
    assert 100 < steps < 2_000_000_000
    # the counted steps are the steps taken: a fresh simulator stepped as many lands on the same bits
    sim = simulator(one_call=True)
    assert float(saved["time"]) == steps * sim.h
    for name in ("r", "p", "R", "Pi"):
        assert np.all(np.isfinite(saved[name])), name
    sim.step(steps)
    st = sim.state
    for name in ("r", "p", "R", "Pi"):
        assert np.array_equal(saved[name], getattr(st, name)), name
    assert np.array_equal(saved["remainders"], np.concatenate([x.ravel() for x in st.remainders]))
    assert int(saved["newton"]) == sim.newton_iterations
