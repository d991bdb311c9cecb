"""ElasticStringPendulum-v0 with a drone at the pivot (kernels/drone/env.py; docs/environment.md,
"A drone at the pivot"): the spaces and checkers in every actuation, a zero action that hovers,
the flip's termination, the energy balance with the drone's rotation, the drone's observation
fields against its state, and clear errors. The batched environments' equality with the single
one is tests/test_env.py's (its VECTOR_OPTIONS include the drone)."""
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import esp_gym  # noqa: F401  (registers the environment)
from esp_gym.physics.drone import DroneSimulator
from esp_gym.kernels.drone.quadrotor import ACTUATIONS, DRONE
from esp_gym.viz.render import FrameRenderer

ENV_ID = "ElasticStringPendulum-v0"
SCENE = "quadrotor_load"


@pytest.mark.parametrize("actuation", ACTUATIONS)
def test_both_env_checkers_pass_in_every_actuation(actuation):
    env = gym.make(ENV_ID, scene=SCENE, actuation=actuation)
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    assert isinstance(env.unwrapped.sim, DroneSimulator)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(gym.make(ENV_ID, scene=SCENE, actuation=actuation).unwrapped, warn=True)


@pytest.mark.parametrize("actuation", ACTUATIONS)
def test_a_zero_action_hovers_level(actuation):
    """From rest (the stabilize task's start, its velocities zeroed), 50 steps of a zero action: the
    drone stays level (R_q = I to 1e-12: the hook at its centre of mass, no torque), its rotors at
    the rig's hover thrust, and the rig's vertical momentum moves only by the string's settling
    (below 2 % of the weight's impulse over the second)."""
    env = gym.make(ENV_ID, scene=SCENE, actuation=actuation).unwrapped
    env.reset(seed=0)
    for _ in range(50):
        env.step(np.zeros(4))
    d = env.sim.diagnostics()
    assert np.abs(d["drone_attitude"] - np.eye(3)).max() <= 1e-12
    assert d["thrust"] == pytest.approx(env.setup.action_params[1], rel=1e-12)  # the hover thrust
    weight_impulse = abs(d["gravity_impulse"][2])
    assert abs(d["momentum_balance_residual"]).max() <= 1e-12 * weight_impulse
    assert abs(d["linear_momentum"][2]) <= 0.02 * weight_impulse + 0.05


def test_rolling_on_flips_the_drone_and_ends_the_episode():
    """Full roll rate (4 rad/s) flips the drone past the horizontal within half a second."""
    env = gym.make(ENV_ID, scene=SCENE, actuation="thrust_rates")
    env.reset(seed=0)
    for k in range(40):
        _, _, terminated, _, info = env.step(np.array([0.0, 1.0, 0.0, 0.0]))
        if terminated:
            break
    assert terminated and info["termination_reason"] == "drone_flipped"
    assert env.unwrapped.sim.diagnostics()["drone_attitude"][2, 2] < 0.0
    assert 0.3 <= (k + 1) * 0.02 <= 0.5  # pi/2 at 4 rad/s after the rate controller's lag


def descend(ground, pivot="drone"):
    """Steps of a descent (the drone's thrust at 40 % of hover; a point pivot pushed down at 40 %
    of the hover force) until the episode ends, on quadrotor_load (drone_load) with ``ground``:
    (steps, termination reason, the pivot's and the load's depth [m] at the end)."""
    scene = esp_gym.load_scene(SCENE if pivot == "drone" else "drone_load",
                               **({} if ground is None else {"ground": ground}))
    env = gym.make(ENV_ID, scene=scene).unwrapped
    env.reset(seed=0)
    action = np.array([-0.6, 0.0, 0.0, 0.0]) if pivot == "drone" else np.array([0.0, 0.0, 0.4, 0.0, 0.0, 0.0])
    for k in range(500):
        _, _, terminated, truncated, info = env.step(action[:env.action_space.shape[0]])
        if terminated or truncated:
            break
    return k + 1, info.get("termination_reason"), env.pivot_position()[2], env.load_position()[2]


@pytest.mark.parametrize("pivot", ["drone", "point"])
def test_the_ground_plane_ends_a_descent_where_the_load_reaches_it(pivot):
    """The load (1.05 m below the drone, 1.6 m of ground) touches down first: the episode ends
    the step its centre of mass passes the plane, within a step's fall of it; without a ground the
    same descent goes on until it leaves the workspace (the negative control)."""
    steps, reason, pivot_depth, load_depth = descend(1.6, pivot)
    assert reason == "hit_ground" and pivot_depth < 1.6 <= load_depth < 1.6 + 0.05, (steps, load_depth)
    later, reason, _, load_depth = descend(None, pivot)
    assert reason == "left_workspace" and later > steps and load_depth > 1.6 + 1.0


def test_a_ground_above_the_loads_target_is_refused():
    with pytest.raises(ValueError, match="ground 0.9 m is not below the load's deepest target"):
        gym.make(ENV_ID, scene=esp_gym.load_scene(SCENE, ground=0.9))
    with pytest.raises(ValueError, match="ground"):
        esp_gym.load_scene(SCENE, ground=-1.0)


#: The hook at the drone's centre of mass, and 6 cm below it and off its axes (tests/test_drone_hook.py).
HOOKS = {"centre": {}, "offset": {"pivot": {"drone": {"rho_q": [0.02, -0.01, -0.06]}}}}


@pytest.mark.parametrize("hook", HOOKS)
def test_the_energy_balance_holds_the_drones_rotation_and_the_watchdog_stays_quiet(hook):
    """200 steps of random rates and thrust: E - E0 - W (E with the drone's rotational energy, W
    the thrust's and the rotors' torques' work) stays below 1e-4 of the work; leaving the
    drone's rotation out of E would miss by its kinetic energy (the negative control). At the
    offset hook the rate controller and the rates sensor take Omega_q from the Legendre transform
    at both ends: the observed rates are the simulator's diagnostics'."""
    env = gym.make(ENV_ID, scene=SCENE, actuation="thrust_rates", scene_overrides=HOOKS[hook]).unwrapped
    env.reset(seed=4)
    rng = np.random.default_rng(1)
    for _ in range(200):
        obs, _, terminated, _, info = env.step(rng.uniform(-0.2, 0.2, 4))
        assert info.get("termination_reason") != "energy_balance"
        if terminated:
            break
    d = env.sim.diagnostics()
    assert abs(d["energy_balance_residual"]) <= 1e-4 * abs(d["work"])
    assert abs(d["kinetic_drone"]) > 1e3 * abs(d["energy_balance_residual"])  # with the hook's cross term
    np.testing.assert_allclose(obs[env.observation_structure["drone_rates"]], d["drone_rates"], rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("observation", ["full", "hook"])
def test_the_drones_observation_fields_hold_its_attitude_and_rates(observation):
    env = gym.make(ENV_ID, scene=SCENE, observation=observation).unwrapped
    env.reset(seed=2)
    obs, *_ = env.step(np.array([0.1, 0.3, -0.2, 0.4]))
    structure = env.observation_structure
    assert list(structure)[-2:] == ["drone_attitude_6d", "drone_rates"]
    d = env.sim.diagnostics()
    R = d["drone_attitude"]
    np.testing.assert_allclose(obs[structure["drone_attitude_6d"]], np.concatenate([R[:, 0], R[:, 1]]), rtol=1e-6,
                               atol=1e-7)
    np.testing.assert_allclose(obs[structure["drone_rates"]], d["drone_rates"], rtol=1e-6, atol=1e-7)
    assert np.abs(d["drone_rates"]).max() > 0.05  # it did turn


@pytest.mark.parametrize("task", ["lift", "lower"])
def test_the_drone_reels_with_the_winch(task):
    """``lift`` and ``lower`` fly the drone with the winch: a (5,) action (the reel speed last),
    the observation's unstretched length before the drone's fields; the drone's hoist (its PD
    law with the reel law) ends 5 episodes (seeds 0-4) far above the zero action (measured 450.8
    against 281.2 on lift, 349.2 against 190.9 on lower), and the energy balance, the winch's work
    in it, holds to 1e-3 of the work done (the inputs' and the winch's; measured 1.7e-4 on lift,
    as the point pivot's winch: an O(h^2) residual)."""
    from agents.baselines.pd import ZeroPolicy
    from agents.baselines.registry import baseline
    from agents.evaluate import run_episodes

    kw = {"scene": SCENE}
    env = gym.make(ENV_ID, task=task, **kw).unwrapped
    assert env.action_space.shape == (5,)
    assert list(env.observation_structure)[-3:] == ["unstretched_length", "drone_attitude_6d", "drone_rates"]
    hoist = [r.ret for r in run_episodes(baseline(task, True, True), task, 5, 0, env_kwargs=kw)]
    zero = [r.ret for r in run_episodes(ZeroPolicy(), task, 5, 0, env_kwargs=kw)]
    assert np.mean(hoist) > np.mean(zero) + 100.0
    obs, _ = env.reset(seed=1)
    policy = baseline(task, True, True)
    for _ in range(100):
        obs, *_ = env.step(policy.act(obs, env.setup))
    d = env.sim.diagnostics()
    done = abs(d["work"]) + abs(d["winch_work"])
    assert abs(d["winch_work"]) > 0.1 and abs(d["energy_balance_residual"]) <= 1e-3 * done


@pytest.mark.parametrize("options, message", [
    ({"scene": SCENE, "actuation": "force"}, "does not fly scene 'quadrotor_load'"),
    ({"actuation": "thrust_rates"}, "does not fly scene 'drone_load'"),
    ({"scene": SCENE, "scene_overrides": {"solver": {"string": "implicit"}, "string": {"elements": 8}}},
     r"no rig is drone-implicit \(scene 'quadrotor_load': solver.string 'implicit', winch=False\); the rigs are "
     r"point-explicit, .*drone-explicit-offset-hook, drone-explicit-damped \(esp_gym.rigs\(\)\)$"),
    ({"scene": SCENE, "scene_overrides": {"solver": {"order": 4}}}, "explicit string of order 2"),
    ({"scene": SCENE, "actuation": "rates"}, "actuation"),
    ({"scene": SCENE, "winch": True, "scene_overrides": {"pivot": {"drone": {"rho_q": [0.0, 0.0, -0.05]}}}},
     r"no rig is drone-explicit-winch-offset-hook \(.*winch=True, pivot.drone.rho_q = \[0.0, 0.0, -0.05\]\)"),
])
def test_a_mismatched_actuation_or_option_is_refused_by_name(options, message):
    with pytest.raises(ValueError, match=message):
        gym.make(ENV_ID, **options)


def test_the_hard_preset_draws_the_drone_and_the_step_flies_the_drawn_one():
    """With randomize, each episode draws the drone's inertia, rotor coefficients and motor lag
    (after the tether's and the load's draws, which stay the point pivot's stream); the compiled
    step's constants are the episode's: k_f, the lag's decays over the episode's h, J_q."""
    env = gym.make(ENV_ID, scene=SCENE, preset="hard").unwrapped
    seen = []
    for seed in range(3):
        _, info = env.reset(seed=seed)
        scales = info["scene_params"]
        drone = env.scene.pivot.drone
        nominal = env.setup.scene.pivot.drone
        assert 0.75 <= scales["drone_inertia_scale"] <= 4 / 3 and 0.9 <= scales["rotor_coefficient_scale"] <= 1.1
        assert 0.5 <= scales["motor_lag_scale"] <= 2.0
        assert drone.thrust_coefficient == pytest.approx(scales["rotor_coefficient_scale"] * nominal.thrust_coefficient)
        consts = env.sim.drone.consts
        assert consts[DRONE.scalar("thrust_coefficient")] == drone.thrust_coefficient
        assert consts[DRONE.scalar("decay_up")] == pytest.approx(np.exp(-env.scene.h / drone.motor_time_constant_up), rel=1e-14)
        np.testing.assert_array_equal(env.sim.drone.inertia, drone.inertia_matrix())
        seen.append(scales["drone_inertia_scale"])
    assert len(set(seen)) == 3
    # the same rig with a point mass at the pivot draws the same tether and load
    point = gym.make(ENV_ID, scene=SCENE, preset="hard", scene_overrides={"pivot": {"kind": "free", "drone": None}})
    _, point_info = point.unwrapped.reset(seed=0)
    _, drone_info = env.reset(seed=0)
    tether_and_load = [k for k in point_info["scene_params"] if k not in ("pivot_mass",) and not k.startswith("wind")]
    assert len(tether_and_load) == 9
    assert [point_info["scene_params"][k] for k in tether_and_load] == [drone_info["scene_params"][k]
                                                                        for k in tether_and_load]


def test_a_drone_that_cannot_carry_its_rig_is_refused():
    with pytest.raises(ValueError, match="the drone cannot carry the rig"):
        gym.make(ENV_ID, scene=SCENE, scene_overrides={"body.mass": 12.0, "EA": 5e4})
    with pytest.raises(ValueError, match="heaviest, weakest corner"):
        gym.make(ENV_ID, scene=SCENE, randomize={"pivot_mass": (1.5, 3.0)})


def test_the_frames_draw_the_drone_as_it_turns():
    """rgb_array frames draw the drone's arms and rotors at its attitude: rolling it changes the
    pixels around the pivot, and the same state drawn with the point pivot's icon differs there."""
    env = gym.make(ENV_ID, scene=SCENE, render_mode="rgb_array")
    env.reset(seed=0)
    level = env.render()
    for _ in range(8):
        env.step(np.array([0.0, 0.8, 0.0, 0.0]))
    rolled = env.render()
    u = env.unwrapped
    st = u.sim.state
    renderer = FrameRenderer(u.scene.body.shape, u.scene.body.rho_c, u.scene.string.length)
    icon = renderer.render(st.r, st.R, u.sim.diagnostics()["strain_energy"])
    top = slice(60, 160)  # the rows around the pivot (it starts at the origin, drawn near y = 120)
    assert level.dtype == np.uint8 and level.shape == rolled.shape
    assert np.abs(level[top].astype(int) - rolled[top].astype(int)).sum() > 0
    assert np.abs(icon[top].astype(int) - rolled[top].astype(int)).sum() > 0


def test_thrust_noise_scales_each_rotor_per_step_as_documented():
    """``thrust_noise=s``: before every step each rotor's thrust scale is 1 + s N(0, 1) from the
    environment's generator (over 400 steps: mean 1 within 4 standard errors, deviation s within
    10 %), the energy balance still closes on the thrust actually applied, and a bad action draws
    nothing (the next scales are those of a twin env that never saw it). The hard preset's is
    0.05; a point pivot refuses it."""
    s = 0.1
    env = gym.make(ENV_ID, scene=SCENE, thrust_noise=s).unwrapped
    twin = gym.make(ENV_ID, scene=SCENE, thrust_noise=s).unwrapped
    env.reset(seed=5)
    twin.reset(seed=5)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.0, np.nan, 0.0, 0.0]))
    scales = []
    for _ in range(400):
        env.step(np.zeros(4))
        twin.step(np.zeros(4))
        scales.append(env.sim.drone.thrust_scale.copy())
        assert np.array_equal(scales[-1], twin.sim.drone.thrust_scale)
    scales = np.array(scales)
    assert abs(scales.mean() - 1.0) <= 4 * s / np.sqrt(scales.size)
    assert abs(scales.std() - s) <= 0.1 * s
    d = env.sim.diagnostics()
    assert abs(d["energy_balance_residual"]) <= 1e-4 * max(abs(d["work"]), 1.0)
    assert gym.make(ENV_ID, scene=SCENE, preset="hard").unwrapped.setup.thrust_noise == 0.05
    assert gym.make(ENV_ID, preset="hard").unwrapped.setup.thrust_noise == 0.0
    with pytest.raises(ValueError, match="thrust_noise"):
        gym.make(ENV_ID, thrust_noise=0.1)
