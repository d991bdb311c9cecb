"""Kelvin–Voigt damping of the string (docs/physics.md, "Material damping"): the energy balance
with the dissipation closes to order 2, the dissipation is the integral of the dampers' power,
the damper moves no momentum and no pi3, a held damper never pulls, the bounce mode decays at
its analytic rate; the rigs without a damper refuse one. tau = 0 is today's step bit for bit:
the rollout hashes (tests/test_inputs.py, tests/test_env_rollouts.py) hold it, and a tiny tau
moves them (the negative control below)."""
import hashlib

import numpy as np
import pytest

import esp_gym
from esp_gym.kernels.jit import python_callable
from esp_gym.kernels.layout import StateArrays, Work
from esp_gym.kernels.step.damper import ACTIVE, HELD, damper_half_step
from esp_gym.scene.params import SceneError


def _hash(sim):
    st = sim.state
    return hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in (st.r, st.p, st.R, st.Pi))).hexdigest()


def _damped(tau, name="paper_example", **kw):
    return esp_gym.load_scene(name, string={"damping_time": tau, "law": "slack"}, **kw)


def test_no_damping_time_is_the_undamped_step_and_a_tiny_one_is_not():
    """damping_time 0 gives the bits of a scene that never heard of it; 1e-12 s changes them
    (the negative control: the hashes of tests/test_inputs.py can see a damper)."""
    base = esp_gym.Simulator(esp_gym.load_scene("paper_example", string={"law": "slack"}))
    zero = esp_gym.Simulator(_damped(0.0))
    tiny = esp_gym.Simulator(_damped(1e-12))
    for sim in (base, zero, tiny):
        sim.step(2000)
    assert _hash(zero) == _hash(base)
    assert _hash(tiny) != _hash(base)
    assert zero.diagnostics()["dissipation"] == 0.0 < tiny.diagnostics()["dissipation"]


def _largest_residuals(scene, t_final):
    sim = esp_gym.Simulator(scene)
    tr = sim.run(t_final=t_final, record_every=max(1, round(1e-3 / scene.h)))
    undamped = tr.energy - tr.energy[0] - tr.work  # the balance without the dissipation
    return np.abs(tr.energy_balance_residual).max(), np.abs(undamped).max(), tr.dissipation[-1]


def test_the_energy_balance_with_the_dissipation_closes_to_second_order():
    """|E - E0 - W + D| falls 4x per halving of h (the LGVI's error and the splitting's, both of
    order 2). Negative control: without D the balance misses by the dissipated energy, h or not."""
    out = [_largest_residuals(_damped(1e-3, h=h), 0.3) for h in (2e-4, 1e-4, 5e-5)]
    residuals = [r for r, _, _ in out]
    ratios = [residuals[i] / residuals[i + 1] for i in range(2)]
    assert all(3.6 < q < 4.4 for q in ratios), (residuals, ratios)  # measured 4.00, 4.00
    for residual, undamped, lost in out:
        assert lost > 1e-4  # it dissipates something (1.6e-4 J of the paper's example's 0.3 s)
        assert undamped > 0.5 * lost > 100 * residual


def test_a_run_takes_the_dampers_halves_between_steps_as_one_flow():
    """Within one call the damper's two halves at a step's end are one flow over h (kernels/step/loops.py):
    a run of n steps is not n single steps bit for bit (the negative control: the merge happens),
    but the two differ by the splitting's order, 4x less per halving of h over the same 0.05 s
    (2.1e-10, 5.1e-11, 1.3e-11 m or kg m/s measured), and their balances agree."""
    base = esp_gym.load_scene("paper_example")
    gaps = []
    for fraction in (1 / 8, 1 / 16, 1 / 32):
        scene = _damped(1e-3, h=base.stability_bound * fraction)
        steps = int(round(0.05 / scene.h))
        run, single = esp_gym.Simulator(scene), esp_gym.Simulator(scene)
        run.step(steps)
        for _ in range(steps):
            single.step(1)
        a, b = run.state, single.state
        gaps.append(max(np.max(np.abs(a.r - b.r)), np.max(np.abs(a.p - b.p))))
        residuals = [sim.diagnostics()["energy_balance_residual"] for sim in (run, single)]
        assert abs(residuals[0] - residuals[1]) < 1e-3 * abs(residuals[1])
    assert gaps[0] > 0.0
    assert all(3.5 < coarse / fine < 4.5 for coarse, fine in zip(gaps, gaps[1:])), gaps


def test_a_damped_run_that_fails_holds_the_last_good_step():
    """A damped step that fails past a checkpoint (1.5x the bound, the watchdog off: step 84) is
    undone by the rewind and replay, which close the last good step with the damper's half: the
    simulator holds bit for bit the state of a fresh run of the good steps."""
    base = esp_gym.load_scene("paper_example")
    scene = _damped(1e-3, h=1.5 * base.stability_bound, allow_unstable_h=True, solver={"energy_watchdog": None})
    sim = esp_gym.Simulator(scene)
    with pytest.raises(esp_gym.SimulationError):
        sim.step(20_000)
    k = sim.step_count
    assert k > 64 and k % 64 != 0, k
    again = esp_gym.Simulator(scene)
    again.step(k)
    for name in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(sim.state, name), getattr(again.state, name)), name
    assert sim.diagnostics()["dissipation"] == again.diagnostics()["dissipation"]


def test_a_damped_drone_step_that_fails_holds_the_last_good_step():
    """The drone's loop keeps no checkpoint: a failing step (2x the bound: step 24) puts back the
    state saved before the last step's merged half and closes that step with h/2 (kernels/drone/loops.py),
    bit for bit the state of a fresh run of the good steps."""
    from esp_gym.physics.drone import DroneSimulator
    pinned = {"pivot": {"drone": {"rate_loop_period": None}}}  # 8 elements at any h
    base = esp_gym.load_scene("quadrotor_load", string={"elements": 8}, **pinned)
    scene = esp_gym.load_scene("quadrotor_load", string={"elements": 8, "damping_time": 1e-3},
                               h=2.0 * base.stability_bound, allow_unstable_h=True, solver={"energy_watchdog": None},
                               **pinned)
    sim = DroneSimulator(scene)
    with pytest.raises(esp_gym.SimulationError):
        sim.step(20_000)
    k = sim.step_count
    assert k > 1, k
    again = DroneSimulator(scene)
    again.step(k)
    for name in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(sim.state, name), getattr(again.state, name)), name
    for a, b in zip(sim.drone_state, again.drone_state):
        assert np.array_equal(a, b)
    assert sim.diagnostics()["dissipation"] == again.diagnostics()["dissipation"]


def _power(r, v, c):
    """The dampers' power sum_a c (n_a . (v_{a+1} - v_a))^2 [W] of the two-sided law (no hold)."""
    x = np.diff(r, axis=0)
    n = x / np.linalg.norm(x, axis=1, keepdims=True)
    rate = np.einsum("ij,ij->i", n, np.diff(v, axis=0))
    return c * np.sum(rate * rate)


def test_the_dissipation_is_the_integral_of_the_dampers_power():
    """D of the kernel against the trapezoid rule of the dampers' power, the velocities taken by
    central differences of the positions (nothing of the kernel's Legendre maps): they agree to
    1e-4, and much worse without the damper's midpoint rule (the power at the state's
    velocities alone, the negative control, is not what is integrated)."""
    scene = esp_gym.load_scene("paper_example", string={"damping_time": 2e-3}, h=5e-5)
    sim = esp_gym.Simulator(scene)
    c = scene.string.damping
    rs = [sim.state.r]
    for _ in range(4001):
        sim.step(1)
        rs.append(sim.state.r)
    rs = np.array(rs)
    h = scene.h
    v = (rs[2:] - rs[:-2]) / (2 * h)
    power = np.array([_power(rs[k + 1], v[k], c) for k in range(len(v))])
    integral = h * (0.5 * power[0] + power[1:-1].sum() + 0.5 * power[-1])
    # D over the same span: steps 1 .. 4000
    sim2 = esp_gym.Simulator(scene)
    sim2.step(1)
    d1 = sim2.diagnostics()["dissipation"]
    sim2.step(3999)
    lost = sim2.diagnostics()["dissipation"] - d1
    assert lost > 0
    assert abs(integral - lost) < 1e-4 * lost, (integral, lost)


def test_the_damper_moves_no_momentum_and_no_pi3():
    """Free pivot under gravity and torques: the total momentum changes by the impulses only and
    pi3 by the angular impulse, to round-off, with the damper on."""
    scene = esp_gym.load_scene("paper_example_consistent", pivot={"kind": "free", "mass": 0.5},
                               string={"damping_time": 2e-3, "law": "slack"})
    sim = esp_gym.Simulator(scene)
    sim.step(5000, body_torque=[0.01, 0.02, -0.01], spatial_torque=[0.0, 0.01, 0.02])
    d = sim.diagnostics()
    assert d["dissipation"] > 1e-4
    assert np.abs(d["momentum_balance_residual"]).max() < 1e-12 * np.abs(d["gravity_impulse"]).max()
    assert abs(d["pi3_balance_residual"]) < 1e-15


def _structs(sim):
    """Copies of a simulator's state and work arrays (the damper's half step runs on them)."""
    b = sim.buffers
    return StateArrays(*(np.copy(a) for a in b.state)), Work(*(np.copy(a) for a in b.work)), b.params


def _element_tensions(r, dp, eta):
    """The tensions T_a [N] of the impulses dp = sum_a eta T_a (n_a on node a, -n_a on node a+1),
    recovered from the free end up (a chain: node N+1 has element N-1 only; every node but a
    fixed pivot's moves)."""
    x = np.diff(r, axis=0)
    n = x / np.linalg.norm(x, axis=1, keepdims=True)
    T = np.zeros(len(n))
    carried = np.zeros(3)
    for a in range(len(n) - 1, -1, -1):
        carried = carried - dp[a + 1]  # = eta T_a n_a
        T[a] = carried @ n[a] / eta
    return T


def test_a_held_damper_never_pulls():
    """The load of ``drone_load`` thrown up at 3 m/s on a barely stretched string (1 %) under a
    strong damper: the last element unloads fast, its damper would pull (c e < -T_e) and is held
    at -T_e instead, so elastic plus damper tension is never negative. The tensions are recovered
    from a half step's impulses. Negative control: the held elements' free dampers, c e at the
    mean velocities, would pull."""
    scene = esp_gym.load_scene("drone_load", string={"damping_time": 2e-2}, h=1e-4,
                               initial={"stretch": 1.01, "attach_velocity": [0.0, 0.0, -3.0]})
    sim = esp_gym.Simulator(scene)
    step = python_callable(damper_half_step)
    eta = 0.5 * scene.h
    held = 0
    for _ in range(40):
        S, W, P = _structs(sim)
        p0 = S.p.copy()
        step(S, W, P, eta, P.first == 0, True)
        T_d = _element_tensions(S.r, S.p - p0, eta)
        T_e = W.dten
        taut = W.dset != 0
        assert np.all(T_e[taut] + T_d[taut] >= -1e-9 * np.abs(T_e).max())
        assert np.all(np.abs(T_d[~taut]) <= 1e-9 * np.abs(T_e).max())
        h = W.dset == HELD
        if h.any():
            held += int(h.sum())
            free_rate = np.array([W.ddir[a] @ ((W.dvel[a + 1] + 0.5 * W.dinc[a + 1]) - (W.dvel[a] + 0.5 * W.dinc[a]))
                                  for a in np.flatnonzero(h)])
            assert np.all(scene.string.damping * free_rate < -T_e[h])
            np.testing.assert_allclose(T_d[h], -T_e[h], rtol=1e-9)
        assert np.all(np.isin(W.dset[taut], (ACTIVE, HELD)))
        sim.step(5)
    assert held > 0


def test_the_bounce_mode_decays_at_its_analytic_rate():
    """A 1 kg point load on 1 m of light string (EA 1000 N, 1 g/m, tau 2 ms) bouncing vertically
    (benchmarks/damping.py's bounce and fit):
    M x'' + (EA tau / l) x' + (EA / l) x = 0, so the amplitude decays as exp(-sigma t) with
    sigma = EA tau / (2 l M_eff), M_eff = M + mu l / 3 (the string's share), within 1e-4
    (measured 3.7e-6: benchmarks/damping.py)."""
    from benchmarks.damping import BOUNCE, decay

    tau = 2e-3
    EA, M, mu, length = BOUNCE["EA"], BOUNCE["M"], BOUNCE["mu"], BOUNCE["length"]
    row = decay(tau, 3.0)  # the bounce scene, its peak-to-trough swings' decay fitted
    sigma = EA * tau / (2.0 * length * (M + mu * length / 3.0))
    assert row["cycles"] > 10
    assert abs(row["measured"] - sigma) < 1e-4 * sigma, (row["measured"], sigma)


def test_rigs_without_a_damper_refuse_one():
    """A drone's offset hook, a team and the winch have no damper yet: each refuses a damped string
    by name; the point pivot's rigs and the drone's at its centre of mass take one."""
    with pytest.raises(SceneError, match="damping_time: a drone's offset hook has no damper yet"):
        esp_gym.load_scene("quadrotor_load", string={"damping_time": 1e-3}, pivot={"drone": {"rho_q": [0, 0, 0.05]}})
    assert esp_gym.load_scene("quadrotor_load", string={"damping_time": 1e-3}).string.damping > 0
    sim = esp_gym.Simulator(_damped(1e-3))
    with pytest.raises(ValueError, match="the winch does not reel a damped string yet"):
        sim.step(1, reel_speed=0.1)
    from esp_gym.physics.rig import find_rig

    with pytest.raises(ValueError, match="no rig is point-explicit-winch-damped"):
        find_rig("point", "explicit", True, False, damped=True)
    with pytest.raises(ValueError, match="no rig is team-point-explicit-damped"):
        find_rig("point", "explicit", False, False, team=True, damped=True)
    assert find_rig("point", "implicit", False, False, damped=True).name == "point-implicit-damped"


@pytest.mark.parametrize("scene, rig", [("drone_load", "point-explicit-damped"),
                                       ("quadrotor_load", "drone-explicit-damped")])
def test_the_damped_environment_passes_gymnasiums_check_and_its_balance_closes(scene, rig):
    """ElasticStringPendulum-v0 on a damped string (its own rig), from a point pivot and from a
    drone: Gymnasium's env checker; seeded
    episodes repeat bit for bit; under random actions the energy balance with the dissipation,
    E - E0 - W + D, stays at the scheme's error while D grows to a visible share of the work.
    Negative control: the balance without D misses by D."""
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    kwargs = dict(scene=scene, scene_overrides={"string": {"damping_time": 2e-3}}, disable_env_checker=True)
    env = gym.make(esp_gym.ENV_ID, **kwargs)
    assert env.unwrapped.control.rig.name == rig
    check_env(env.unwrapped, skip_render_check=True)
    runs = []
    for _ in range(2):
        env.reset(seed=3)
        env.action_space.seed(3)
        obs = []
        for _ in range(100):
            o, _, terminated, truncated, _ = env.step(0.5 * env.action_space.sample())
            obs.append(o)
            if terminated or truncated:
                break
        runs.append(np.array(obs))
    np.testing.assert_array_equal(runs[0], runs[1])
    d = env.unwrapped.sim.diagnostics()
    assert len(runs[0]) > 20 and d["dissipation"] > 1e-4
    assert abs(d["energy_balance_residual"]) < 1e-2 * d["dissipation"]
    assert abs(d["energy_balance_residual"] - d["dissipation"]) > 0.9 * d["dissipation"]


def test_the_damping_benchmark_runs_and_writes_its_files(tmp_path):
    """``python -m benchmarks.damping --quick``: its tables' figures, its JSON and its plot."""
    from benchmarks.damping import main

    result = main(["--quick", "--out", str(tmp_path)])
    assert all(abs(row["error"]) < 1e-3 for row in result["decay"])
    assert 1.8 < result["order"]["slope"] < 2.2
    assert 0.0 < result["cost"]["ratio"] < 1.0
    assert (tmp_path / "damping.json").stat().st_size > 0 and (tmp_path / "damping.png").stat().st_size > 0


def test_the_tether_scenes_carry_their_sources_values():
    """The four tether scenes load by name, damped and resolved by the rule, with the values their
    sources give (docs/scenes.md, "Tether scenes"): the Dyneema tether's tau is its damping over
    its EA, its mass the rope density over the 4 mm circle; the nylon rope's EA is MoorPy's
    dynamic stiffness at 12 mm; the steel rope's EA and mass the wire-core formulas at 16 mm."""
    for name in ("dyneema_tether", "dyneema_tether_drone"):
        s = esp_gym.load_scene(name).string
        assert s.auto and s.law == "slack"
        assert s.damping_time == pytest.approx(473.0 / 614600.0, rel=1e-3)
        assert s.mass_per_length == pytest.approx(724.0 * np.pi * 0.002**2, rel=1e-3)
    assert esp_gym.load_scene("dyneema_tether_drone").pivot.is_drone
    nylon = esp_gym.load_scene("nylon_rope")
    d = 0.012
    mbl = 230.29e6 * d**3 + 207.0e6 * d**2
    weight = 9.81 * nylon.body.mass
    assert nylon.string.EA == pytest.approx(2.08 * mbl + 0.39 * weight, rel=2e-3)
    assert nylon.string.mass_per_length == pytest.approx(585.15 * d**2, rel=2e-3)
    steel = esp_gym.load_scene("steel_wire_crane").string
    assert steel.EA == pytest.approx(4.04e10 * 0.016**2, rel=2e-3)
    assert steel.mass_per_length == pytest.approx(3.9897e3 * 0.016**2, rel=2e-3)
    assert all(esp_gym.load_scene(n).string.damping_time > 0 for n in ("nylon_rope", "steel_wire_crane"))
