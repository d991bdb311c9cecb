"""The energy watchdog (esp_gym/physics/watchdog.py; docs/physics.md, "The energy watchdog"): a run whose
balance |E - E0 - W| passes f (scale + |W|) raises (the simulator) or ends its episode (the
environment, in its compiled step, batched as single), it fires on the steps known to gain
energy, with negative controls that run on without it, and it stays quiet in the shipped
configurations' episodes."""
import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import esp_gym
import esp_gym.scene.stepsize
from agents.baselines.pd import AntiSwayPD, Hoist
from esp_gym.kernels.status import BLOW_UP, ENERGY_BALANCE
from esp_gym.physics.watchdog import STANDARD_GRAVITY, WATCH_EVERY, energy_scale, task_constants, team_energy_scale

ENV_ID = esp_gym.ENV_ID


def test_the_scale_is_the_carried_mass_lifted_one_string_length():
    scene = esp_gym.load_scene("drone_load")
    assert energy_scale(scene) == pytest.approx((0.5 + 0.05 + 1.0) * STANDARD_GRAVITY * 1.0, rel=1e-15)
    paper = esp_gym.load_scene("paper_example")  # a fixed pivot carries nothing of its own
    s = paper.string
    assert energy_scale(paper) == pytest.approx((paper.body.mass + s.mass_per_length * s.length)
                                                * STANDARD_GRAVITY * s.length, rel=1e-15)
    assert task_constants(scene) == (1.0, energy_scale(scene))
    off = esp_gym.load_scene("drone_load", solver={"energy_watchdog": None})
    assert task_constants(off) == (0.0, math.inf)
    for bad in (0.0, -1.0, float("nan"), "1"):
        with pytest.raises(ValueError, match="energy_watchdog"):
            esp_gym.load_scene("drone_load", solver={"energy_watchdog": bad})


def reeled_and_held(watchdog):
    """``drone_load`` reeled in to 0.5 m at 1 m/s, then held (the pivot force balancing the
    weight): the string keeps flickering between slack and taut, and the plain explicit step
    (``solver.slack_switch: plain``) gains energy there (docs/physics.md, "The slack switch of the
    explicit string"). Returns the simulator and the SimulationError that ended 100 s of holding
    (None: none did)."""
    scene = esp_gym.load_scene("drone_load", h=0.02 / 71, **{"initial.direction": [0.3, 0.0, 1.0]},
                               solver={"energy_watchdog": watchdog, "slack_switch": "plain"})
    carried = scene.body.mass + scene.pivot.mass
    sim = esp_gym.Simulator(scene)
    sim.step(int(0.5 / scene.h) + 10, reel_speed=-1.0, pivot_force=[0.0, 0.0, -scene.gravity * (carried + 0.05)])
    assert sim.winch.length == 0.5
    try:
        for _ in range(100):
            sim.step(int(1.0 / scene.h), pivot_force=[0.0, 0.0, -scene.gravity * (carried + 0.025)])
    except esp_gym.SimulationError as error:
        return sim, error
    return sim, None


def test_the_simulator_raises_on_the_reeled_and_held_strings_energy_gain():
    sim, error = reeled_and_held(1.0)
    assert error is not None and error.status == ENERGY_BALANCE, error
    message = str(error)
    assert "solver.energy_watchdog 1 x (the energy scale 15.2 J" in message and "holds the state" in message
    # h against the bound at the string's current length (0.5 m), not at the scene's 1 m
    h_ratio = sim.scene.h / esp_gym.scene.stepsize.at_length(sim.scene, 0.5).stability_bound
    assert f"is {h_ratio:.2g} x the stability bound" in message
    d = sim.diagnostics()  # every step was taken, the state is finite, and the balance is broken
    work = d["work"] + d["winch_work"]
    assert np.isfinite(d["energy"]) and abs(d["energy_balance_residual"]) > energy_scale(sim.scene) + abs(work)
    # negative control: without the watchdog it holds on, later, to the blow-up guard
    off, later = reeled_and_held(None)
    assert later is not None and later.status == BLOW_UP and off.step_count > sim.step_count


def test_the_simulator_looks_every_64_steps_or_more():
    """With a bound of 1e-12 of the scale the watchdog fires at its first look: after the call
    that passes WATCH_EVERY steps, not before."""
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example", solver={"energy_watchdog": 1e-12}))
    for _ in range(WATCH_EVERY - 1):
        sim.step(1)
    with pytest.raises(esp_gym.SimulationError, match="energy_balance|watchdog"):
        sim.step(1)
    assert sim.step_count == WATCH_EVERY


def watched_episode(env_kwargs: dict, steps: int, act):
    """An episode of up to ``steps`` control steps, ``act(k, obs, setup)`` choosing each action:
    (termination reason, control steps, |E - E0 - W| over the watchdog's bound at each step)."""
    env = gym.make(ENV_ID, max_episode_steps=steps, disable_env_checker=True, **env_kwargs)
    obs, _ = env.reset(seed=0)
    u, ratio = env.unwrapped, []
    for k in range(steps):
        obs, _, terminated, truncated, info = env.step(np.asarray(act(k, obs, u.setup), dtype=np.float32))
        d = u.sim.diagnostics()
        work = d["work"] + d["winch_work"]
        ratio.append(abs(d["energy_balance_residual"]) / (energy_scale(u.scene) + abs(work)))
        if terminated or truncated:
            return info.get("termination_reason", ""), k + 1, np.array(ratio)
    return "", steps, np.array(ratio)


def assert_the_watchdog_ends_it(env_kwargs: dict, watchdog_off: dict, steps: int, act, bound: float = 1.0):
    """The episode ends by the watchdog (``solver.energy_watchdog`` = ``bound``) before ``steps``,
    exactly where the same run without it (``watchdog_off``: its env_kwargs) first passes the
    bound, and that run goes on."""
    reason, ended, _ = watched_episode(env_kwargs, steps, act())
    assert reason == "energy_balance" and ended < steps, (reason, ended)
    reason_off, ran, ratio = watched_episode(watchdog_off, ended + 5, act())
    assert reason_off == "" and ran == ended + 5
    assert np.argmax(ratio > bound) + 1 == ended and ratio[:ended - 1].max() <= bound


def pd_with_noise():
    """The PD law plus +-0.5 uniform action noise (its own generator, seed 0)."""
    pd, rng = AntiSwayPD(), np.random.default_rng(0)
    return lambda k, obs, setup: np.clip(pd.act(obs, setup) + 0.5 * rng.uniform(-1, 1, 6), -1, 1)


def hoist_reeling_back_and_forth():
    """The hoist, its reel command replaced by +-1 switching every 25 control steps."""
    hoist = Hoist()

    def act(k, obs, setup):
        action = hoist.act(obs, setup).astype(np.float64)
        action[-1] = 1.0 if (k // 25) % 2 else -1.0
        return action
    return act


def test_the_environment_ends_the_variational_implicit_strings_slow_energy_gain():
    """The implicit string's variational form at EA = 1e7 N under the PD law plus noise gains
    energy slowly at the environment's step (docs/physics.md, "The transverse step"); a watchdog
    bound of 0.005 (0.076 J + 0.005 |W|) ends its episode (at control step 782)."""
    solver = {"string": "implicit", "implicit_form": "variational"}
    tight = {"string": {"EA": 1e7}, "solver": {**solver, "energy_watchdog": 0.005}}
    off = {"string": {"EA": 1e7}, "solver": {**solver, "energy_watchdog": None}}
    assert_the_watchdog_ends_it({"scene_overrides": tight}, {"scene_overrides": off}, 1000, pd_with_noise, 0.005)


def test_the_environment_ends_the_stiff_winchs_energy_gain():
    """``lower`` at EA = 2e5 N, the plain explicit string reeling back and forth, gains energy where
    its elements flicker between slack and taut (docs/physics.md, "The slack switch of the
    explicit string")."""
    scene = {"string": {"EA": 2e5}, "solver": {"slack_switch": "plain"}}
    off = {**scene, "solver": {"energy_watchdog": None, "slack_switch": "plain"}}
    assert_the_watchdog_ends_it({"task": "lower", "scene_overrides": scene},
                                {"task": "lower", "scene_overrides": off}, 2000, hoist_reeling_back_and_forth)


def test_a_tiny_bound_ends_episodes_alike_single_and_batched():
    """The compiled check, with f = 1e-9: every sub-environment ends with ``energy_balance`` at
    the step a single environment of its seed does."""
    kwargs = dict(scene_overrides={"solver": {"energy_watchdog": 1e-9}}, randomize=True)
    ends = []
    for seed in range(3):
        env = gym.make(ENV_ID, **kwargs)
        env.reset(seed=seed)
        for k in range(50):
            _, _, terminated, _, info = env.step(np.full(6, 0.3, np.float32))
            if terminated:
                break
        assert info["termination_reason"] == "energy_balance"
        ends.append(k)
    vec = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", **kwargs)
    vec.reset(seed=[0, 1, 2])
    first = [None] * 3
    for k in range(50):
        _, _, terminated, _, infos = vec.step(np.full((3, 6), 0.3, np.float32))
        for i in np.flatnonzero(terminated):
            if first[i] is None:
                first[i] = k
                assert infos["termination_reason"][i] == "energy_balance"
        if all(f is not None for f in first):
            break
    assert first == ends


@pytest.mark.parametrize("task", ["stabilize", "transport", "track", "lift", "lower"])
@pytest.mark.parametrize("preset", [None, "hard"])
def test_the_watchdog_stays_quiet_in_the_shipped_configurations(task, preset):
    """The task's baseline plus +-0.5 noise for 150 control steps: no episode ends by the
    watchdog, and the balance stays under a tenth of its bound (benchmarks/energy_balance.py
    runs whole episodes: 0.033 of the scale at most)."""
    options = {} if preset is None else {"preset": preset}
    env = gym.make(ENV_ID, task=task, max_episode_steps=150, disable_env_checker=True, **options)
    obs, _ = env.reset(seed=1)
    u = env.unwrapped
    baseline, rng = (Hoist() if u.setup.winch else AntiSwayPD()), np.random.default_rng(1)
    worst = 0.0
    while True:
        action = np.clip(baseline.act(obs, u.setup) + 0.5 * rng.uniform(-1, 1, env.action_space.shape), -1, 1)
        obs, _, terminated, truncated, info = env.step(action.astype(np.float32))
        d = u.sim.diagnostics()
        worst = max(worst, abs(d["energy_balance_residual"]) / energy_scale(u.scene))
        if terminated or truncated:
            break
    assert info.get("termination_reason") != "energy_balance"
    assert worst < 0.1, worst


@settings(max_examples=25, deadline=None)
@given(task=st.sampled_from(["stabilize", "transport", "track", "lift", "lower"]), preset=st.sampled_from([None, "hard"]),
       EA=st.floats(100.0, 2000.0), implicit=st.booleans(), noise=st.floats(0.0, 1.0), seed=st.integers(0, 10**6))
def test_closed_loop_episodes_under_exploration_noise_keep_their_energy(task, preset, EA, implicit, noise, seed):
    """Fuzz: the task's baseline plus exploration noise (random actions alone leave the workspace
    too soon to find a step that gains energy), the winch, the implicit string and the presets,
    at the EAs the shipped configurations use: no physics failure, finite observations, and the
    watchdog never fires. (The variational implicit string at EA >= 2e5 N and the plain switch of a
    flickering winch gain energy: the tests above.)"""
    solver = {"string": "implicit"} if implicit else {}
    options = {} if preset is None else {"preset": preset}
    env = gym.make(ENV_ID, task=task, scene_overrides={"string": {"EA": EA}, "solver": solver},
                   max_episode_steps=150, disable_env_checker=True, **options)
    obs, _ = env.reset(seed=seed)
    u = env.unwrapped
    baseline, rng = (Hoist() if u.setup.winch else AntiSwayPD()), np.random.default_rng(seed)
    while True:
        action = np.clip(baseline.act(obs, u.setup) + noise * rng.uniform(-1, 1, env.action_space.shape), -1, 1)
        obs, reward, terminated, truncated, info = env.step(action.astype(np.float32))
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
        if terminated or truncated:
            break
    reason = info.get("termination_reason", "")
    assert reason != "energy_balance" and not reason.startswith("physics_failure"), reason


@settings(max_examples=12, deadline=None)
@given(task=st.sampled_from(["stabilize", "transport", "track", "lift", "lower"]), preset=st.sampled_from([None, "hard"]),
       EA=st.floats(2e5, 1e7), noise=st.floats(0.0, 1.0), seed=st.integers(0, 10**6))
def test_the_stiff_implicit_string_under_exploration_noise_keeps_its_energy(task, preset, EA, noise, seed):
    """Fuzz, the stiff tethers the implicit string is for (EA 2e5 to 1e7 N, where its variational
    form gained energy): the task's baseline plus exploration noise, the winch and the presets, 300
    control steps: no physics failure, finite observations, the watchdog never fires, and the
    balance stays under a hundredth of the energy scale."""
    options = {} if preset is None else {"preset": preset}
    env = gym.make(ENV_ID, task=task, scene_overrides={"string": {"EA": EA}, "solver": {"string": "implicit"}},
                   max_episode_steps=300, disable_env_checker=True, **options)
    obs, _ = env.reset(seed=seed)
    u = env.unwrapped
    baseline, rng = (Hoist() if u.setup.winch else AntiSwayPD()), np.random.default_rng(seed)
    worst = 0.0
    while True:
        action = np.clip(baseline.act(obs, u.setup) + noise * rng.uniform(-1, 1, env.action_space.shape), -1, 1)
        obs, reward, terminated, truncated, info = env.step(action.astype(np.float32))
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
        worst = max(worst, abs(u.sim.diagnostics()["energy_balance_residual"]) / energy_scale(u.scene))
        if terminated or truncated:
            break
    reason = info.get("termination_reason", "")
    assert reason != "energy_balance" and not reason.startswith("physics_failure"), reason
    assert worst < 0.01, worst


def broken_team_episode(monkeypatch, watchdog, broken: bool, steps: int = 60, compiled: bool = True):
    """A team's ``stabilize`` episode (three point pivots, hovering) under zero actions, its
    watchdog ``solver.energy_watchdog`` = ``watchdog``, stepped by the compiled control step or
    (``compiled`` False) in Python; ``broken``: every control step's physics starts by scaling every
    momentum by 1.02 (a step that pumps energy in, 4 % of the kinetic energy per control step: in
    Python, at the end of each compiled run of steps). Returns (termination reason, control
    steps, the balance over the bound at each step, the env)."""
    from esp_gym.kernels.layout import StateArrays
    from esp_gym.kernels.team.arrays import TeamArrays
    from esp_gym.kernels.team.loops import team_advance as real
    from esp_gym.team import simulator
    from esp_gym.team.control import TeamControl
    from esp_gym.team.core import TeamCore
    from esp_gym.team.env import ElasticStringTeamEnv
    from esp_gym.team.scene import team_scene

    monkeypatch.undo()  # a previous episode's patches
    monkeypatch.setattr(TeamCore, "compiled_steps", compiled)
    if broken and not compiled:
        def pumping(S, W, P, T, A, inputs, n, stats, disturbed):
            real(S, W, P, T, A, inputs, n, stats, disturbed)
            for momenta in (S.p, S.Pi, A.p):
                momenta *= 1.02
        monkeypatch.setattr(simulator, "team_advance", pumping)
    if broken and compiled:
        real_step = TeamControl.step

        def pumped(control, raw, time):
            structs = control.sim.compiled()
            S, A = StateArrays(*structs.state), TeamArrays(*structs.arrays)
            for momenta in (S.p, S.Pi, A.p):
                momenta *= 1.02
            return real_step(control, raw, time)
        monkeypatch.setattr(TeamControl, "step", pumped)
    team = team_scene(3)
    team = team.model_copy(update={"scene": team.scene.model_copy(update={"solver": team.scene.solver.model_copy(
        update={"energy_watchdog": watchdog})})})
    env = ElasticStringTeamEnv(team, task="stabilize")
    env.reset(seed=0)
    core, ratio = env.core, []
    for k in range(steps):
        _, _, terminated, _, info = env.step(np.zeros(env.action_space.shape, np.float32))
        d = core.sim.diagnostics()
        work = d["work"] + d["winch_work"]
        ratio.append(abs(d["energy_balance_residual"]) / (0.01 * (team_energy_scale(team) + abs(work))))
        if terminated:
            return info["termination_reason"], k + 1, np.array(ratio), env
    return "", steps, np.array(ratio), env


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled step", "python step"])
def test_the_team_environment_ends_a_broken_steps_energy_gain(monkeypatch, compiled):
    """The team env's watchdog is the single env's (esp_gym/physics/watchdog.py, through the team's
    simulator): a broken step ends the episode with ``energy_balance`` at the control step where
    |E - E0 - W| first passes 0.01 (the team's scale 40.7 J + |W|), and the simulator then says
    so with the team's scale; the same broken episode without the watchdog runs on (negative
    control), and so does the unbroken one with it (its balance 1e-4 of the bound); in the compiled
    control step (esp_gym/kernels/team/env.py) and in Python (a team with winches steps there)."""
    reason, ended, _, env = broken_team_episode(monkeypatch, 0.01, True, compiled=compiled)
    assert reason == "energy_balance" and ended < 60, (reason, ended)
    with pytest.raises(esp_gym.SimulationError, match=r"energy scale 40\.7 J") as error:
        env.core.sim.step(env.core.substeps)
    assert error.value.status == ENERGY_BALANCE
    reason_off, ran, ratio, _ = broken_team_episode(monkeypatch, None, True, ended + 5, compiled)
    assert reason_off == "" and ran == ended + 5
    assert np.argmax(ratio > 1.0) + 1 == ended and ratio[:ended - 1].max() <= 1.0
    reason_good, ran, ratio, _ = broken_team_episode(monkeypatch, 0.01, False, ended + 5, compiled)
    assert reason_good == "" and ran == ended + 5 and ratio.max() < 1e-2, ratio.max()
