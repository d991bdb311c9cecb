"""A drone at the pivot (esp_gym/physics/drone.py, esp_gym/kernels/drone/quadrotor.py; docs/physics.md, "A drone at the
pivot"): the rig's balances with the thrust's and the rotors' torque's work and impulses, the
thrust along the body axis at both ends of every step (independent of the kernel's own
balances, with off-axis thrusts as negative controls), free fall without inputs, order 2,
reversibility, and the scene's and the simulator's clear errors."""
import numpy as np
import pytest

import esp_gym
from esp_gym.physics.drone import DroneSimulator
from esp_gym.physics.state import total_weight
from esp_gym.scene.params import SceneError

SCENE = "quadrotor_load"
#: quadrotor_load as its physics was verified: 8 elements at the scene file's h, the rate loop at
#: every step (its own resolution and loop are tests/test_rate_loop.py's).
PINNED = {"string.elements": 8, "pivot.drone.rate_loop_period": None}


def pinned_scene(**overrides):
    return esp_gym.load_scene(SCENE, **{**PINNED, **overrides})
E3 = np.array([0.0, 0.0, 1.0])
#: The drone's hooks the physics tests run on: its centre of mass, and 6 cm below it and off its
#: axes (hook -> centre of mass, body frame [m]; tests/test_drone_hook.py).
HOOKS = {"centre": [0.0, 0.0, 0.0], "offset": [0.02, -0.01, -0.06]}


def hooked(hook, **overrides):
    """The drone scene with the hook ``hook`` (a key of HOOKS)."""
    return pinned_scene(**{"pivot.drone.rho_q": HOOKS[hook], **overrides})


def wobbling_commands(sim, k):
    """Motor commands [rad/s] about the rig's hover that change every 10 steps (so the lag keeps
    the rotors moving): collective +-5 %, and torques that tilt and yaw the drone."""
    phase = 0.7 * (k // 10)
    torque = 0.02 * np.array([np.sin(phase), np.cos(1.3 * phase), 0.5 * np.sin(0.4 * phase)])
    thrust = total_weight(sim.scene) * (1.0 + 0.05 * np.sin(0.3 * phase))
    return sim.commands_for(thrust, torque)


def momenta(sim):
    """The rig's linear momentum [kg m/s] and its angular momentum about e3 [kg m^2/s]."""
    d = sim.diagnostics()
    return d["linear_momentum"], d["pi3"]


def balanced_run(h, hook, duration=1.6):
    """A run of ``duration`` [s] at step ``h`` under motor commands that change every 4 ms (the
    motors lagging): the last diagnostics and the largest |energy balance residual| [J] seen."""
    sim = DroneSimulator(hooked(hook, h=h))
    every = int(round(4e-3 / h))
    worst = 0.0
    for k in range(int(round(duration / 4e-3))):
        sim.step(every, rotor_commands=wobbling_commands(sim, 10 * k))
        worst = max(worst, abs(sim.diagnostics()["energy_balance_residual"]))
    return sim.diagnostics(), worst


@pytest.mark.parametrize("hook", HOOKS)
def test_the_balances_close_with_the_rotors_work_and_impulses(hook):
    """1.6 s under changing motor commands: the linear momentum moves by the gravity and thrust
    impulses to 1e-13 of them, pi3 by the angular impulse to 1e-13 kg m^2/s, R_q stays orthogonal
    to 1e-14, and the energy moves by the thrust's and torques' work up to an O(h^2) residual:
    at most 1e-4 of the 2.2 J of work at h = 4e-4 s (measured 6.3e-5), and at least 3 times
    smaller at h/2 (measured 8.7)."""
    d, worst = balanced_run(4e-4, hook)
    _, finer = balanced_run(2e-4, hook)
    impulse = d["gravity_impulse"] + d["pivot_impulse"]
    assert np.abs(d["momentum_balance_residual"]).max() <= 1e-13 * np.abs(impulse).max()
    assert abs(d["pi3_balance_residual"]) <= 1e-13
    assert abs(d["angular_impulse_z"]) > 1e-3  # the yaw torque did act
    assert abs(d["work"]) > 1.0
    assert worst <= 1e-4 * abs(d["work"])
    assert finer <= worst / 3.0
    assert d["orthogonality_drone"] <= 1e-14
    assert d["kinetic_drone"] > 1e-6  # it did turn


def thrust_pair_defects(sim, steps, end_rotation):
    """Step ``sim`` one step at a time; per step, |P_{k+1} - P_k - gravity impulse - h/2 (u_k + u_{k+1})|
    with u = -f R e3 built here from the drone's attitude and thrust at each end
    (``end_rotation(R_k, R_{k+1})`` is the rotation used for u_{k+1}: R_{k+1} is the scheme's).
    Returns the largest defect and the largest thrust impulse [kg m/s]."""
    h = sim.h
    weight = total_weight(sim.scene) * h * E3
    defect = size = 0.0
    for k in range(steps):
        d0 = sim.diagnostics()
        sim.step(1, rotor_commands=wobbling_commands(sim, k))
        d1 = sim.diagnostics()
        R0, R1 = d0["drone_attitude"], d1["drone_attitude"]
        impulse = 0.5 * h * (-d0["thrust"] * R0 @ E3 - d1["thrust"] * end_rotation(R0, R1) @ E3)
        defect = max(defect, np.abs(d1["linear_momentum"] - d0["linear_momentum"] - weight - impulse).max())
        size = max(size, np.abs(impulse).max())
    return defect, size


@pytest.mark.parametrize("name, end_rotation, agrees", [
    ("the body axis at both ends", lambda R0, R1: R1, True),
    ("the start's axis at the end (negative control)", lambda R0, R1: R0, False),
    ("1 mrad off the axis (negative control)", lambda R0, R1: R1 @ np.array(
        [[1.0, 0.0, 0.0], [0.0, np.cos(1e-3), -np.sin(1e-3)], [0.0, np.sin(1e-3), np.cos(1e-3)]]), False)])
def test_the_thrust_acts_along_the_body_axis_at_both_ends_of_the_step(name, end_rotation, agrees):
    """Each step's momentum change against the impulse h/2 (u_k + u_{k+1}), u = -f R_q e3, rebuilt
    from the drone's state: it agrees to 1e-13 of the impulse (the scheme); a thrust held along
    the start's axis, or tilted 1 mrad at the end, misses by more than 1e-7 of it."""
    sim = DroneSimulator(pinned_scene())
    sim.set_drone_state(Pi=sim.drone.inertia @ np.array([0.5, -0.8, 0.3]))  # turning, so R_{k+1} != R_k
    defect, size = thrust_pair_defects(sim, 40, end_rotation)
    if agrees:
        assert defect <= 1e-13 * size
    else:
        assert defect > 1e-7 * size


@pytest.mark.parametrize("hook", HOOKS)
def test_free_fall_keeps_momentum_pi3_and_energy(hook):
    """Rotors stopped, the drone spinning about a tilted axis: the rig falls with P changing by the
    gravity impulse only (1e-13), pi3 with the drone's e3 . R_q Pi_q in it constant to 1e-15,
    the energy without drift (the second half's error within 1.2 of the first's)."""
    sim = DroneSimulator(hooked(hook))
    sim.set_drone_state(Pi=sim.drone.inertia @ np.array([1.0, -2.0, 3.0]), rotor_speeds=np.zeros(4))
    energy = []
    for _ in range(100):
        sim.step(20, rotor_commands=np.zeros(4))
        energy.append(sim.diagnostics()["energy_balance_residual"])
    d = sim.diagnostics()
    assert d["work"] == 0.0 and d["angular_impulse_z"] == 0.0
    assert np.abs(d["momentum_balance_residual"]).max() <= 1e-13 * np.abs(d["gravity_impulse"]).max()
    assert abs(d["pi3_balance_residual"]) <= 1e-15
    assert abs(d["pi3_drone"]) > 1e-2  # the drone's spin is in pi3
    half = len(energy) // 2
    assert np.abs(energy[half:]).max() <= 1.2 * np.abs(energy[:half]).max() + 1e-12


def final_state(h, hook, duration=0.2):
    """The load's attachment and the drone's attitude after ``duration`` under held commands."""
    sim = DroneSimulator(hooked(hook, h=h, **{"string.law": "elastic"}))
    sim.set_drone_state(Pi=sim.drone.inertia @ np.array([0.4, -0.3, 0.6]))
    sim.step(int(round(duration / h)), thrust=19.0, torque=[0.01, -0.02, 0.005])
    d = sim.diagnostics()
    return np.concatenate([d["attach_position"], d["pivot_position"], d["drone_attitude"].ravel()])


#: The coarsest step of the order test per hook [s]: from 1e-4 s the offset hook's first ratio
#: is 4.55 (still pre-asymptotic: 4.55, 3.85, 3.97, 4.04 from 1e-4 s against 1e-4/128 s).
ORDER_START = {"centre": 1e-4, "offset": 5e-5}


@pytest.mark.parametrize("hook", HOOKS)
def test_order_two(hook):
    """Errors against 1e-4/64 s at h, h/2, h/4 (h = ORDER_START), on the elastic string law: each
    halving divides them by 4 within 10 % (measured 3.99, 3.89 at the centre; 3.85, 3.97 at the
    offset hook). From 2e-4 s the centre's first ratio is 5.2; on the slack law the ratios wander
    (3.9, 2.8, 5.0), as an element's switch is not smooth."""
    h = ORDER_START[hook]
    ref = final_state(1e-4 / 64, hook)
    errors = [np.abs(final_state(h / 2 ** i, hook) - ref).max() for i in range(3)]
    ratios = [errors[i] / errors[i + 1] for i in range(2)]
    assert all(3.6 <= r <= 4.4 for r in ratios), (errors, ratios)


@pytest.mark.parametrize("hook", HOOKS)
def test_reversible_without_inputs(hook):
    """Rotors stopped: 500 steps, every momentum negated (the string's, the load's and the
    drone's), 500 steps, negated back: the start to 1e-12. The offset hook's turning stretches and
    slackens elements within these steps, and a slack switch is not time-symmetric
    (docs/physics.md, "The slack switch of the explicit string"): its run takes the elastic law (on the slack law it
    returns 3.8e-4 m off)."""
    sim = DroneSimulator(hooked(hook, **({"string.law": "elastic"} if hook == "offset" else {})))
    sim.set_drone_state(Pi=sim.drone.inertia @ np.array([1.0, -2.0, 3.0]), rotor_speeds=np.zeros(4))
    start, drone_start = sim.state, sim.drone_state
    sim.step(500, rotor_commands=np.zeros(4))
    moved = sim.drone_state
    st = sim.state
    st.p *= -1
    st.Pi *= -1
    st.remainders = None
    sim.set_state(st)
    sim.set_drone_state(Pi=-moved.Pi)
    sim.step(500)
    back, drone_back = sim.state, sim.drone_state
    assert np.abs(back.r - start.r).max() <= 1e-12
    assert np.abs(back.p + start.p).max() <= 1e-12
    assert np.abs(drone_back.R - drone_start.R).max() <= 1e-12
    assert np.abs(drone_back.Pi + drone_start.Pi).max() <= 1e-12 * np.abs(drone_start.Pi).max()
    assert np.abs(moved.R - drone_start.R).max() > 1e-2  # it did turn


def test_zero_lag_makes_the_wrench_the_command_at_once():
    """t_m = 0: after one step the rotors turn at the command and the thrust is the wrench asked for."""
    scene = pinned_scene(**{"pivot.drone.motor_time_constant_up": 0.0, "pivot.drone.motor_time_constant_down": 0.0})
    sim = DroneSimulator(scene)
    sim.step(1, thrust=15.0, torque=[0.01, 0.0, -0.002])
    d = sim.diagnostics()
    assert d["thrust"] == pytest.approx(15.0, rel=1e-13)
    np.testing.assert_allclose(d["drone_torque"], [0.01, 0.0, -0.002], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("overrides, message", [
    ({"pivot.kind": "free"}, "belongs to pivot.kind: drone"),
    ({"pivot.drone.inertia": [0.01, 0.01, 0.05]}, "triangle inequality"),
    ({"pivot.drone.inertia": [0.01, -0.01, 0.015]}, "pivot.drone.inertia must be three values > 0"),
    ({"pivot.drone.arm_length": 0.0}, "arm_length"),
])
def test_a_bad_drone_section_names_what_is_wrong(overrides, message):
    with pytest.raises(SceneError, match=message):
        pinned_scene(**overrides)


def test_the_drone_simulator_refuses_what_it_cannot_run():
    with pytest.raises(ValueError, match="needs pivot.kind: drone"):
        DroneSimulator(esp_gym.load_scene("drone_load"))
    with pytest.raises(ValueError, match="explicit string of order 2"):
        DroneSimulator(pinned_scene(**{"solver.string": "implicit"}))
    sim = DroneSimulator(pinned_scene())
    with pytest.raises(ValueError, match="rotor_commands must lie in"):
        sim.step(1, rotor_commands=[0.0, 0.0, 0.0, 2000.0])
    with pytest.raises(ValueError, match="not both"):
        sim.step(1, rotor_commands=np.zeros(4), thrust=1.0)
    with pytest.raises(NotImplementedError):
        sim.run(0.1)
