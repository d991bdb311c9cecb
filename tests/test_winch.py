"""The winch (docs/physics.md, "The winch"; kernels/step/winch.py): the step is the discrete
Euler-Lagrange equations of the reeling string's L_d; the energy balance with the winch's work
closes at order 2; momentum and pi3 balances close to round-off; reeling out and back in with
the momenta reversed returns the state; the range is kept; bad commands change nothing; with
the reel at rest nothing changes, bit for bit."""
import hashlib

import numpy as np
import pytest

import esp_gym
from esp_gym.scene.stepsize import shortest
from esp_gym.errors import SimulationError
from esp_gym.physics.simulator import Simulator, State
from discrete_lagrangian import GEOMETRIC_OVERRIDES, random_state, winch_lagrangian
from test_discrete_lagrangian import legendre_errors
from test_inputs import CORE_PATH_HASHES


def state_hash(sim) -> str:
    st = sim.state
    return hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in (st.r, st.p, st.R, st.Pi))).hexdigest()


# -- the reel at rest changes nothing ------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(CORE_PATH_HASHES))
def test_a_reel_at_rest_is_todays_scheme_bit_for_bit(name):
    sim = Simulator(esp_gym.load_scene(name))
    sim.step(10_000, reel_speed=0.0)
    assert state_hash(sim) == CORE_PATH_HASHES[name]
    moved = Simulator(esp_gym.load_scene(name))  # negative control: a reel that moves at all
    moved.step(10_000, reel_speed=1e-9)
    assert state_hash(moved) != CORE_PATH_HASHES[name]


# -- the discrete Euler-Lagrange equations ------------------------------------------------------
WINCH_SCENES = {
    "paper-N5": dict(N=5),
    "geometric-N3": dict(N=3, **GEOMETRIC_OVERRIDES),
    "lumped-free-N4": dict(N=4, string={"mass_model": "lumped"}, pivot={"kind": "free", "mass": 0.3}),
    "slack-N5": dict(N=5, string={"law": "slack"}),
}


def reel_step(scene, before, length, speed):
    """One step of the compiled winch from ``before`` at unstretched ``length`` [m] whose momenta
    are those of reel ``speed`` [m/s]; returns the state after it."""
    sim = Simulator(scene)
    sim.set_state(State(before.r, before.p, before.R, before.Pi, winch=(length, speed)))
    sim.step(1, reel_speed=speed)
    return sim.state


@pytest.mark.parametrize("scene_id, seed, length, speed", [
    ("paper-N5", 1, 1.0, 0.5), ("paper-N5", 2, 1.3, -0.8), ("geometric-N3", 3, 0.7, 0.6),
    ("lumped-free-N4", 4, 1.1, 0.4), ("slack-N5", 5, 0.9, -0.5)])
def test_the_step_satisfies_the_discrete_legendre_transforms_of_the_reeling_string(scene_id, seed, length, speed):
    """p_k = -D_1 L_d and p_{k+1} = D_2 L_d of L_d from its integral definition (material moving
    through the nodes), by finite differences, at a random state: relative 1e-7 (measured 4e-10).
    h = 1e-3 makes the step's reeling 0.4-0.8 mm. Negative control: L_d without the material's
    flow (only the mass, rest length and stiffness following l) misses by orders of magnitude."""
    scene = esp_gym.load_scene("paper_example", h=1e-3, **WINCH_SCENES[scene_id])
    before = random_state(scene, np.random.default_rng(seed))
    after = reel_step(scene, before, length, speed)
    assert after.winch[0] == pytest.approx(length + scene.h * speed, rel=1e-15)
    errors = legendre_errors(scene, before, after, L=winch_lagrangian(length, after.winch[0]))
    assert max(errors.values()) < 1e-7, errors
    static = legendre_errors(scene, before, after, L=winch_lagrangian(length, after.winch[0], convective=False))
    assert max(static.values()) > 1e-4, static


# -- balances ------------------------------------------------------------------------------------
def reel_profile(sim, steps, samples=20):
    """Reel out at 0.2 m/s, stop, in at 0.3 m/s (the speed jumps twice; ``steps`` steps each);
    returns E - E0 - W - W_winch at ``samples`` times per phase."""
    out = []
    for speed in (0.2, 0.0, -0.3):
        for _ in range(samples):
            sim.step(steps // samples, reel_speed=speed)
            out.append(sim.diagnostics()["energy_balance_residual"])
    return np.array(out)


def reel_balance_by_h(scenes):
    """:func:`reel_profile` over 0.3 s for each scene (one per h): the residual's root mean
    squares, the winch's work at the end of each, and the last run's balance without W_winch
    (the negative control)."""
    rms, winch_work = [], []
    for scene in scenes:
        sim = Simulator(scene)
        residual = reel_profile(sim, int(round(0.1 / scene.h)))
        rms.append(float(np.sqrt(np.mean(residual ** 2))))
        d = sim.diagnostics()
        winch_work.append(d["winch_work"])
        unbalanced = d["energy_balance_residual"] + d["winch_work"]
    return rms, winch_work, unbalanced


def test_the_energy_balance_with_the_winch_is_second_order():
    """E - E0 - W - W_winch over 0.3 s of reeling (h = 200, 100, 50 us): its root mean square over
    60 times falls 4x per halving (measured 3.94, 3.99) and is below 1e-5 of the winch's work
    (measured 2.5e-8 J against 12 mJ; the energy is about 40 mJ). Negative control: without W_winch
    the balance is O(1)."""
    rms, winch_work, unbalanced = reel_balance_by_h(esp_gym.load_scene("paper_example", h=h)
                                                    for h in (2e-4, 1e-4, 5e-5))
    ratios = [rms[i] / rms[i + 1] for i in range(2)]
    assert all(3.6 < q < 4.4 for q in ratios), (rms, ratios)
    assert rms[-1] < 1e-5 * abs(winch_work[-1]) and abs(winch_work[-1]) > 1e-3
    assert abs(unbalanced) > 1e3 * rms[-1]


def test_momentum_and_pi3_balance_with_the_winch_and_every_input():
    """A free pivot pushed and twisted while the winch reels out and in: the total momentum
    changes by the gravity and pivot-force impulses only (relative 1e-12: the convective impulse
    c C dr sums to zero over the nodes) and pi3 by the angular impulse (round-off), with the weight
    of the string taken at each step's mean length."""
    scene = esp_gym.load_scene("paper_example_consistent", pivot={"kind": "free", "mass": 0.5})
    sim = Simulator(scene)
    inputs = dict(pivot_force=[0.2, -0.1, -1.5], body_torque=[0.01, 0.02, -0.01], spatial_torque=[0.0, 0.01, 0.02])
    for speed in (0.3, -0.5, 0.0):
        sim.step(3000, reel_speed=speed, **inputs)
    d = sim.diagnostics()
    scale = np.abs(d["gravity_impulse"]).max()
    assert np.abs(d["momentum_balance_residual"]).max() < 1e-12 * scale
    assert abs(d["pi3_balance_residual"]) < 1e-14
    assert d["unstretched_length"] == pytest.approx(1.0 + 0.3 * 0.3 - 0.5 * 0.3, abs=1e-12)


def test_reeling_out_then_in_with_the_momenta_reversed_returns_the_state():
    """The step is symmetric (L_d of (q_{k+1}, q_k) at -v is L_d of (q_k, q_{k+1}) at v), so 2,000
    steps reeling out at 0.4 m/s, the momenta and the reel reversed, and 2,000 steps reeling in
    come back to the start: positions within 1e-12 m, the length to round-off (the mesh is the
    length's: u = l/N). Without the reversal the string keeps swinging and the state does not
    return (negative control)."""
    scene = esp_gym.load_scene("paper_example")
    sim = Simulator(scene)
    start = sim.state
    sim.step(2000, reel_speed=0.4)
    out = sim.state
    rc, pc, Rc, Pic, owed = out.remainders
    sim.set_state(State(out.r, -out.p, out.R, -out.Pi, out.step, (rc, -pc, Rc, -Pic, owed), (out.winch[0], -0.4)))
    sim.step(2000, reel_speed=-0.4)
    back = sim.state
    assert np.abs(back.r - start.r).max() < 1e-12
    assert np.abs(back.p + start.p).max() < 1e-12 * np.abs(out.p).max()
    assert back.winch[0] == pytest.approx(1.0, abs=1e-14)
    on = Simulator(scene)
    on.step(2000, reel_speed=0.4)
    on.step(2000, reel_speed=-0.4)
    assert on.state.winch[0] == pytest.approx(1.0, abs=1e-14) and np.abs(on.state.r - start.r).max() > 1e-3


# -- the range, bad commands ----------------------------------------------------------------------
def test_the_winch_stops_at_the_ends_of_its_range_and_the_balance_closes_there():
    """Reeling at 2 m/s past either end stops the winch there (the last step's speed is cut to
    land on the end); the energy balance closes across the stops at order 2 (measured 1.7e-4 of
    the winch's 1.05 J at h = 100 us, 4.7e-5 at 50 us)."""
    residual = []
    for h in (1e-4, 5e-5):
        scene = esp_gym.load_scene("paper_example", h=h,
                                   winch={"min_length": 0.8, "max_length": 1.1, "max_speed": 2.0})
        sim = Simulator(scene)
        steps = int(round(0.1 / h))
        sim.step(steps, reel_speed=2.0)  # would be 1.2 m
        d = sim.diagnostics()
        assert (d["unstretched_length"], d["reel_speed"]) == (1.1, 0.0)
        sim.step(2 * steps, reel_speed=-2.0)
        d = sim.diagnostics()
        assert (d["unstretched_length"], d["reel_speed"]) == (0.8, 0.0)
        residual.append(abs(d["energy_balance_residual"]) / abs(d["winch_work"]))
    assert residual[0] < 3e-4 and 3.0 < residual[0] / residual[1] < 5.0, residual


@pytest.mark.parametrize("bad, message", [
    (float("nan"), "finite"), (float("inf"), "finite"), (1.5, "max_speed"), (-1.01, "max_speed"),
    ("fast", "real number"), (True, "real number"), ([0.1], "real number")])
def test_a_bad_reel_command_raises_and_changes_nothing(bad, message):
    sim = Simulator(esp_gym.load_scene("paper_example"))
    sim.step(100, reel_speed=0.3)
    before, length = state_hash(sim), sim.winch.length
    with pytest.raises(ValueError, match=f"reel_speed.*{message}|{message}.*reel_speed"):
        sim.step(10, reel_speed=bad)
    assert (state_hash(sim), sim.winch.length) == (before, length)


def test_what_cannot_reel_says_why():
    near = esp_gym.load_scene("paper_example", h=6e-4)  # stable at 1 m, not at the winch's 0.5 m
    with pytest.raises(ValueError, match="winch.min_length"):
        Simulator(near).step(1, reel_speed=0.1)
    Simulator(esp_gym.load_scene(near, winch={"min_length": 0.9})).step(1, reel_speed=0.1)
    with pytest.raises(ValueError, match="winch's range"):
        esp_gym.load_scene("paper_example", winch={"max_length": 0.9})


@pytest.mark.parametrize("string", ["explicit", "implicit"])
def test_run_while_reeling_records_the_states_of_step(string):
    """run(reel_speed=...) is step(reel_speed=...) with snapshots: every row equals the state and
    diagnostics after the same steps taken by step, bit for bit, per step with every_step; a run
    at a moved length holds it. The energy balance with the winch's work closes."""
    scene = esp_gym.load_scene("paper_example", N=6, solver={"string": string})
    ran, stepped = Simulator(scene), Simulator(scene)
    traj = ran.run(23 * 10 * scene.h, record_every=10, every_step=True, reel_speed=0.4)
    assert traj.nodes.shape[0] == 24 and traj.energy_every_step.shape == (230,)
    for j in range(24):
        d = stepped.diagnostics()
        assert np.array_equal(traj.nodes[j], stepped.state.r)
        assert traj.unstretched_length[j] == d["unstretched_length"] and traj.winch_work[j] == d["winch_work"]
        assert traj.energy_balance_residual[j] == d["energy_balance_residual"]
        for i in range(10 if j < 23 else 0):
            stepped.step(1, reel_speed=0.4)
            assert traj.energy_every_step[10 * j + i] == stepped.diagnostics()["energy"]
    assert traj.unstretched_length[-1] == pytest.approx(1.0 + 0.4 * 230 * scene.h, rel=1e-12)
    assert abs(traj.energy_balance_residual).max() < 1e-3 * abs(traj.winch_work[-1])
    held = ran.run(95 * scene.h, record_every=10)  # the reel stopped at a moved length: 9 rows and 5 steps
    stepped.step(90)
    assert np.array_equal(held.nodes[-1], stepped.state.r) and held.unstretched_length.shape == (10,)
    stepped.step(5)
    assert np.array_equal(ran.state.r, stepped.state.r)
    assert np.all(held.unstretched_length == traj.unstretched_length[-1]) and np.allclose(held.winch_work[1:], held.winch_work[1], rtol=1e-9)
    assert abs(held.energy_balance_residual).max() < 1e-3 * abs(held.winch_work[-1])  # with the stop's jump of H


def test_choose_h_for_a_reeling_string_is_stable_at_the_winchs_shortest():
    scene = esp_gym.load_scene("paper_example", winch={"min_length": 0.4})
    fixed, reeling = esp_gym.choose_h(scene), esp_gym.choose_h(scene, reeling=True)
    assert reeling.h == pytest.approx(0.7 * shortest(scene).stability_bound, rel=1e-12)
    # the bound of the assembled string scales with the element length but for its end masses
    assert reeling.h == pytest.approx(0.4 * fixed.h, rel=1e-5)
    Simulator(reeling.scene(scene)).step(10, reel_speed=0.5)  # accepted at the shortest length
    with pytest.raises(ValueError, match="winch.min_length"):
        Simulator(fixed.scene(scene)).step(10, reel_speed=0.5)


def test_a_state_with_a_bad_winch_is_refused_whole():
    sim = Simulator(esp_gym.load_scene("paper_example"))
    sim.step(50, reel_speed=0.2)
    good = sim.state
    for winch, message in (((5.0, 0.0), "range"), ((1.0, float("nan")), "finite"), ((1.0, 3.0), "max_speed")):
        bad = State(good.r, good.p, good.R, good.Pi, good.step, good.remainders, winch)
        with pytest.raises(ValueError, match=message):
            sim.set_state(bad)
        assert sim.state.winch == good.winch and np.array_equal(sim.state.r, good.r)


def test_a_composed_reeling_step_that_fails_holds_the_last_good_step():
    """A composed (order-4) step that fails part-way while the winch reels in is undone from
    its checkpoint, the winch's length and reel with it (kernels/step/loops.py): the simulator holds
    exactly (bit for bit) the state and length a fresh run of the completed steps reaches.
    Negative control: one step fewer is another state."""
    solver = {"solver": {"order": 4, "energy_watchdog": None}}
    base = esp_gym.load_scene("paper_example", **solver)
    scene = esp_gym.load_scene("paper_example", h=1.03 * base.stability_bound, allow_unstable_h=True, **solver)
    sim = Simulator(scene)
    with pytest.raises(SimulationError):
        sim.step(20_000, reel_speed=-0.05)
    k = sim.step_count
    assert k > 64, k
    again, short = Simulator(scene), Simulator(scene)
    again.step(k, reel_speed=-0.05)
    short.step(k - 1, reel_speed=-0.05)
    a, b = sim.state, again.state
    for name in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.winch == b.winch and sim.diagnostics()["winch_work"] == again.diagnostics()["winch_work"]
    assert not np.array_equal(a.r, short.state.r)
