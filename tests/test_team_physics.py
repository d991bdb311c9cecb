"""A team's step (esp_gym/kernels/team/step.py; docs/physics.md, "A team: several strings on one body"):
one string reproduces the single string's step bit for bit; the step satisfies the discrete
Legendre transforms of the team's discrete Lagrangian, written here from the docs' formulas;
energy, momentum, pi3, orthogonality, order, reversibility and symmetry."""
import numpy as np
import pytest

from esp_gym.physics.simulator import SimulationError, Simulator
from esp_gym.scene.params import load_scene
from esp_gym.scene.stability import hat
from esp_gym.team import TeamScene, TeamSimulator, TeamString, symmetric_team

FREE = {"kind": "free", "mass": 0.5}


def kicked(sim, dPi=(0.002, -0.001, 0.003), dpx=(0.05, 0.02, 0.0)):
    """The team's state with the body's momenta nudged (a swing and a twist)."""
    st = sim.state
    st.lead.Pi = st.lead.Pi + np.asarray(dPi)
    st.lead.p[-1] += np.asarray(dpx)
    sim.set_state(st)
    return sim


def asymmetric_team(pivot=None, mass_model="consistent"):
    """Three unequal strings at unequal points of a box (string 0 from the symmetric team)."""
    base = symmetric_team(3, pivot=pivot, stretch=1.01)
    pivot = dict(pivot or {"kind": "fixed"})
    others = [
        TeamString(string=dict(length=1.07, mass_per_length=0.08, EA=1500.0, elements=5, mass_model=mass_model),
                   pivot={**pivot, "position": (-0.4, 0.5, -0.05)}, attachment=(-0.15, 0.1, -0.05)),
        TeamString(string=dict(length=1.0, mass_per_length=0.03, EA=2500.0, elements=1, mass_model=mass_model),
                   pivot={**pivot, "position": (-0.2, -0.7, 0.1)}, attachment=(0.05, -0.18, -0.05)),
    ]
    return TeamScene(scene=base.scene, strings=others)


# -- one string is the single string ------------------------------------------------------------

@pytest.mark.parametrize("name", ["paper_example", "paper_example_free_pivot", "large_offset"])
def test_a_team_of_one_string_steps_as_the_single_string_bit_for_bit(name):
    scene = load_scene(name)
    team = TeamSimulator(TeamScene(scene=scene))
    single = Simulator(scene, specialise=False)
    force = np.array([0.3, -0.2, -1.0]) if scene.pivot.is_free else np.zeros(3)
    for _ in range(3):
        team.step(100, pivot_forces=force[None])
        single.step(100, pivot_force=force if scene.pivot.is_free else None)
    a, b = team.state.lead, single.state
    for k in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    # negative control: a second string of a thousandth of the mass moves the load
    light = TeamString(string=dict(length=scene.string.length, mass_per_length=1e-3 * scene.string.mass_per_length,
                                   EA=1e-3 * scene.string.EA, elements=2),
                       pivot=scene.pivot.model_dump(), attachment=tuple(-np.asarray(scene.body.rho_c)))
    pair = TeamSimulator(TeamScene(scene=scene, strings=[light]))
    pair.step(300, pivot_forces=np.stack([force, np.zeros(3)]) if scene.pivot.is_free else None)
    assert not np.array_equal(pair.state.lead.r, b.r)


# -- the discrete Lagrangian --------------------------------------------------------------------

def strings_of(team, x, R, lead_nodes, other_nodes, sim):
    """Every string's nodes (with its end on the body at x + R rho_k), its params and pivot."""
    T = sim.params
    out = [(np.vstack([lead_nodes, x]), team.scene.string, team.scene.pivot)]
    for j, s in enumerate(team.strings):
        a, b = T.start[j], T.start[j + 1]
        nodes = np.vstack([other_nodes[a:b - 1], x + R @ T.rho[j]])
        out.append((nodes, s.string, s.pivot))
    return out


def discrete_lagrangian(team, sim, q0, q1):
    """L_d(q_k, q_{k+1}) of docs/physics.md ("The discrete Lagrangian", "A team"): each string's
    elements (kinetic, trapezoid gravity and elastic), the free pivots' and the body's terms.
    q = (x, R, string 0's nodes before its end, the other strings' stacked rows)."""
    h, g = team.h, team.scene.gravity
    body = team.scene.body
    M, rho = body.mass, np.asarray(body.rho_c, dtype=float)
    J = body.J
    Jd = 0.5 * np.trace(J) * np.eye(3) - J
    (x0, R0, l0, o0), (x1, R1, l1, o1) = q0, q1
    L = 0.0
    for (r0, string, pivot), (r1, _, _) in zip(strings_of(team, x0, R0, l0, o0, sim),
                                              strings_of(team, x1, R1, l1, o1, sim)):
        m, kappa, u = string.m, string.kappa, string.u
        d = r1 - r0
        for a in range(r0.shape[0] - 1):
            da, db = d[a], d[a + 1]
            if string.mass_model == "consistent":
                L += m / (6 * h) * (da @ da + da @ db + db @ db)
            else:
                L += m / (4 * h) * (da @ da + db @ db)
            L += h / 4 * m * g * (2 * r0[a, 2] + 2 * r0[a + 1, 2] + da[2] + db[2])
            for r in (r0, r1):
                stretch = np.linalg.norm(r[a + 1] - r[a]) - u
                if string.law == "slack":
                    stretch = max(stretch, 0.0)
                L -= h / 4 * kappa * stretch ** 2
        if pivot.is_free:
            L += pivot.mass / (2 * h) * d[0] @ d[0] + h / 2 * pivot.mass * g * (2 * r0[0, 2] + d[0, 2])
    F = R0.T @ R1
    dx = x1 - x0
    L += M / (2 * h) * dx @ dx + np.trace((np.eye(3) - F) @ Jd) / h + M / h * dx @ (R0 @ (F - np.eye(3)) @ rho)
    L += h / 2 * M * g * ((x0 + R0 @ rho)[2] + (x1 + R1 @ rho)[2])
    return L


def configuration(sim):
    st = sim.state
    return (st.lead.r[-1].copy(), st.lead.R.copy(), st.lead.r[:-1].copy(), st.r.copy()), st


def legendre_by_differences(team, sim, q0, q1, side, eps=1e-5):
    """-D_1 L_d (side 0) or D_2 L_d (side 1) by central differences of ``eps`` (smaller steps meet
    the round-off of L_d), left-trivialised in R:
    (string 0's rows before its end, p_x, Pi, the other strings' rows)."""
    def L_at(q):
        return discrete_lagrangian(team, sim, *((q, q1) if side == 0 else (q0, q)))
    q = q0 if side == 0 else q1
    sign = -1.0 if side == 0 else 1.0

    def diff(make):
        return sign * (L_at(make(eps)) - L_at(make(-eps))) / (2 * eps)

    x, R, lead, other = q
    px = np.array([diff(lambda e, i=i: (x + e * np.eye(3)[i], R, lead, other)) for i in range(3)])
    Pi = np.array([diff(lambda e, i=i: (x, R @ rotation(e * np.eye(3)[i]), lead, other)) for i in range(3)])
    def node_momenta(nodes, configuration):
        """The differences in each coordinate of ``nodes``; ``configuration(moved nodes)`` is q."""
        out = np.zeros_like(nodes)
        for a in range(nodes.shape[0]):
            for i in range(3):
                def moved(e, a=a, i=i):
                    shifted = nodes.copy()
                    shifted[a, i] += e
                    return configuration(shifted)
                out[a, i] = diff(moved)
        return out

    pl = node_momenta(lead, lambda nodes: (x, R, nodes, other))
    po = node_momenta(other, lambda nodes: (x, R, lead, nodes))
    return pl, px, Pi, po


def rotation(v):
    th = np.linalg.norm(v)
    if th == 0.0:
        return np.eye(3)
    K = hat(v / th)
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


@pytest.mark.parametrize("pivot, mass_model", [(None, "consistent"), (FREE, "lumped")])
def test_the_step_satisfies_the_discrete_legendre_transforms_of_the_teams_lagrangian(pivot, mass_model):
    team = asymmetric_team(pivot, mass_model)
    sim = kicked(TeamSimulator(team))
    sim.step(20)
    q0, s0 = configuration(sim)
    sim.step(1)
    q1, s1 = configuration(sim)
    scale = max(np.abs(s0.lead.p).max(), np.abs(s0.lead.Pi).max(), np.abs(s0.p).max())
    T = sim.params
    rows = np.concatenate([np.arange(T.start[j] + T.first[j], T.start[j + 1] - 1) for j in range(len(team.strings))])
    first = 0 if team.scene.pivot.is_free else 1
    for side, st in ((0, s0), (1, s1)):
        pl, px, Pi, po = legendre_by_differences(team, sim, q0, q1, side)
        assert np.abs(pl[first:] - st.lead.p[first:-1]).max() < 1e-7 * scale, side
        assert np.abs(px - st.lead.p[-1]).max() < 1e-7 * scale, side
        assert np.abs(Pi - st.lead.Pi).max() < 1e-7 * scale, side
        assert np.abs(po[rows] - st.p[rows]).max() < 1e-7 * scale, side
    # negative control: the single string's step from the same state (the other strings ignored)
    # is not the team's: the differences see them
    single = Simulator(team.scene, specialise=False)
    single.set_state(s0.lead)
    single.step(1)
    assert np.abs(single.state.Pi - Pi).max() > 1e-3 * scale
    assert np.abs(single.state.p[-1] - px).max() > 1e-3 * scale


# -- balances, order, reversibility, symmetry ---------------------------------------------------

def energy_error(team, seconds, samples=40):
    """The largest |E - E0 - W| over ``seconds`` of a kicked team, sampled ``samples`` times."""
    sim = kicked(TeamSimulator(team))
    n = int(round(seconds / team.h / samples))
    worst = 0.0
    for _ in range(samples):
        sim.step(n)
        worst = max(worst, abs(sim.diagnostics()["energy_balance_residual"]))
    return worst, sim


def test_the_energy_error_is_of_second_order_and_bounded():
    errors = [energy_error(symmetric_team(3, h=h, stretch=1.01), 0.48, samples=400)[0] for h in (3e-4, 1.5e-4)]
    assert 3.5 < errors[0] / errors[1] < 4.5, errors
    # bounded: ten times longer, the same size of error (no drift)
    longer, sim = energy_error(symmetric_team(3, h=3e-4, stretch=1.01), 4.8)
    assert longer < 2.0 * errors[0], (longer, errors)
    assert sim.diagnostics()["orthogonality"] < 1e-14


def test_free_pivots_balance_momentum_and_pi3_with_their_forces():
    team = asymmetric_team(FREE)
    sim = kicked(TeamSimulator(team))
    rng = np.random.default_rng(0)
    for _ in range(20):
        sim.step(50, pivot_forces=rng.normal(0.0, 2.0, (team.size, 3)))
    d = sim.diagnostics()
    assert np.abs(d["momentum_balance_residual"]).max() < 1e-12
    assert abs(d["pi3_balance_residual"]) < 1e-12
    assert abs(d["energy_balance_residual"]) < 2e-3
    assert abs(d["work"]) > 0.1
    # the energy balance closes at second order: E - E0 - W with held forces, h and h/2
    residuals = []
    for h in (2e-4, 1e-4):
        halved = TeamScene(scene=team.scene.model_copy(update={"h": h}), strings=team.strings)
        sim = kicked(TeamSimulator(halved))
        worst = 0.0
        for _ in range(20):
            sim.step(int(round(0.01 / h)), pivot_forces=np.array([[0.5, 0.0, -1.0], [0.0, 1.0, -2.0], [-1.0, 0.0, 0.5]]))
            worst = max(worst, abs(sim.diagnostics()["energy_balance_residual"]))
        residuals.append(worst)
    assert 3.0 < residuals[0] / residuals[1] < 5.5, residuals
    # negative control: fixed pivots' reactions are not inputs, so the momentum balance fails
    fixed = kicked(TeamSimulator(asymmetric_team()))
    fixed.step(1000)
    assert np.abs(fixed.diagnostics()["momentum_balance_residual"]).max() > 0.1


def test_a_force_on_the_load_joins_the_balances():
    team = asymmetric_team(FREE)
    sim = kicked(TeamSimulator(team))
    rng = np.random.default_rng(1)
    for _ in range(20):
        sim.step(50, load_force=rng.normal(0.0, 3.0, 3))
    d = sim.diagnostics()
    assert np.abs(d["momentum_balance_residual"]).max() < 1e-12
    assert abs(d["pi3_balance_residual"]) < 1e-12
    assert abs(d["energy_balance_residual"]) < 2e-3 < abs(d["work"])
    with pytest.raises(ValueError, match="load_force"):
        sim.step(1, load_force=[1.0, np.nan, 0.0])
    # the force's impulse is what the momentum gains besides gravity's: F n h along x
    sim = kicked(TeamSimulator(team))
    sim.step(50)
    before = sim.diagnostics()["linear_momentum"]
    sim.step(50, load_force=[5.0, 0.0, 0.0])
    assert sim.diagnostics()["linear_momentum"][0] - before[0] == pytest.approx(5.0 * 50 * team.h, abs=1e-12)


def test_a_team_retraces_its_steps_when_its_momenta_are_reversed():
    team = asymmetric_team(FREE, "lumped")
    sim = kicked(TeamSimulator(team))
    start = sim.state
    sim.step(500)
    back = sim.state
    back.lead.p, back.lead.Pi, back.p = -back.lead.p, -back.lead.Pi, -back.p
    sim.set_state(back)
    sim.step(500)
    end = sim.state
    assert np.abs(end.lead.r - start.lead.r).max() < 1e-11
    assert np.abs(end.r - start.r).max() < 1e-11
    assert np.abs(end.lead.R - start.lead.R).max() < 1e-11
    assert np.abs(end.lead.p + start.lead.p).max() < 1e-9
    assert np.abs(end.lead.Pi + start.lead.Pi).max() < 1e-9


def rotate_about_e3(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("pivot", [None, FREE])
def test_a_symmetric_team_stays_symmetric(pivot):
    """Three equal strings at 120 degrees, the load spun about e3 and bouncing on the strings'
    stretch: each string is the last one turned by 120 degrees, to round-off, after 3000 steps.
    (A hard bounce, 0.1 kg m/s through the centre of mass at stretch 1.02, excites a parametric
    swing that grows round-off ~10x per 0.05 s: the dynamics', not the step's.)"""
    team = symmetric_team(3, pivot=pivot, stretch=1.0)
    sim = kicked(TeamSimulator(team), dPi=(0.0, 0.0, 0.004), dpx=(0.0, 0.0, 0.0))
    sim.step(3000)
    st = sim.state
    T = sim.params
    turn = rotate_about_e3(2.0 * np.pi / 3.0)
    strings = [st.lead.r[:-1]] + [st.r[T.start[j]:T.start[j + 1] - 1] for j in range(2)]
    scale = np.abs(st.lead.r).max()
    for k in range(3):
        assert np.abs(strings[k] @ turn.T - strings[(k + 1) % 3]).max() < 1e-13 * scale
    centre = st.lead.r[-1] + st.lead.R @ np.asarray(team.scene.body.rho_c)
    assert np.abs(centre[:2]).max() < 1e-12 * scale
    assert np.abs(st.lead.R[2, :2]).max() < 1e-12 and np.abs(st.lead.R[:2, 2]).max() < 1e-12  # turned about e3 only
    # negative control: an asymmetric push breaks it
    sim.step(200, pivot_forces=np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]) if pivot else None)
    if pivot:
        st = sim.state
        assert np.abs(st.lead.r[1:-1] @ turn.T - st.r[T.start[0] + 1:T.start[1] - 1]).max() > 1e-6


def test_positions_converge_at_second_order():
    finals = []
    for h in (2e-4, 1e-4, 5e-5):
        sim = kicked(TeamSimulator(symmetric_team(3, h=h, stretch=1.01)))
        sim.step(int(round(0.1 / h)))
        finals.append(np.concatenate([sim.state.lead.r.ravel(), sim.state.r.ravel()]))
    a, b = np.abs(finals[0] - finals[1]).max(), np.abs(finals[1] - finals[2]).max()
    assert 3.5 < a / b < 4.5, (a, b)


# -- what a team refuses ------------------------------------------------------------------------

def test_a_team_refuses_what_its_step_does_not_do():
    base = symmetric_team(2)
    one = base.strings[0]
    with pytest.raises(ValueError, match="at most 6"):
        TeamScene(scene=base.scene, strings=[one] * 6)
    composed = base.scene.model_copy(update={"solver": base.scene.solver.model_copy(update={"order": 4})})
    with pytest.raises(ValueError, match="order 2"):
        TeamScene(scene=composed)
    with pytest.raises(ValueError, match=r"strings\[0\]"):  # its own stability bound at the team's h
        TeamScene(scene=base.scene, strings=[one.model_copy(update={"string": one.string.model_copy(
            update={"EA": 1e8})})])
    sim = TeamSimulator(base)
    with pytest.raises(ValueError, match=r"shape \(2, 3\)"):
        sim.step(1, pivot_forces=np.zeros(3))
    with pytest.raises(ValueError, match=r"pivot_forces\[1\].*fixed"):
        sim.step(1, pivot_forces=np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    with pytest.raises(ValueError, match="finite"):
        sim.step(1, pivot_forces=np.full((2, 3), np.nan))


def test_a_failing_step_leaves_the_team_where_it_was():
    push = np.array([[0.0, 0.0, 0.0], [1e7, 0.0, 0.0]])
    sim = TeamSimulator(symmetric_team(2, pivot=FREE))
    sim.step(10)
    with pytest.raises(SimulationError) as failure:
        sim.step(100, pivot_forces=push)
    good = sim.step_count
    assert 10 <= good < 110 and failure.value.step == good
    again = TeamSimulator(symmetric_team(2, pivot=FREE))
    again.step(10)
    again.step(good - 10, pivot_forces=push)  # the good steps, taken again, are the state kept
    for a, b in ((sim.state.lead.r, again.state.lead.r), (sim.state.r, again.state.r),
                 (sim.state.lead.Pi, again.state.lead.Pi), (sim.state.p, again.state.p)):
        assert np.array_equal(a, b)


def test_elements_auto_chooses_each_strings_resolution_and_the_smallest_step():
    from esp_gym.scene.params import Scene

    base = asymmetric_team()
    soft = dict(base.strings[0].string.model_dump(), elements="auto")
    stiff = dict(base.strings[1].string.model_dump(), elements="auto", EA=2e7, length=1.0)
    team = TeamScene.model_validate({"scene": base.scene, "strings": [
        {"string": soft, "pivot": base.strings[0].pivot, "attachment": base.strings[0].attachment},
        {"string": stiff, "pivot": base.strings[1].pivot, "attachment": base.strings[1].attachment}]})
    alone = [Scene.model_validate({**base.scene.model_dump(), "string": s, "pivot": p.model_dump(), "initial": {}})
             for s, p in ((soft, base.strings[0].pivot), (stiff, base.strings[1].pivot))]
    assert [s.string.elements for s in team.strings] == [a.string.elements for a in alone]
    assert all(s.string.auto for s in team.strings)
    assert team.h == min(base.scene.h, *(a.h for a in alone)) < base.scene.h  # the stiff string's step
    TeamSimulator(team).step(10)


def test_the_tridiagonal_solve_is_scipys_solve_banded_bit_for_bit():
    """team/velocities.py's tridiagonal_solve against scipy.linalg.solve_banded((1, 1), ...) on
    random string-like systems (1 x 1 to 17 x 17, a vector and three columns): equal bits; a NaN
    and a singular matrix are refused as there. Negative control: another diagonal, other bits."""
    from scipy.linalg import LinAlgError, solve_banded

    from esp_gym.team.assembly import banded
    from esp_gym.team.velocities import tridiagonal_solve

    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 8, 17):
        for _ in range(50):
            ab = banded(rng.uniform(0.01, 2.0, n), -rng.uniform(0.0, 0.004))
            for b in (rng.normal(size=(n, 3)), rng.normal(size=n)):
                assert np.array_equal(tridiagonal_solve(ab, b), solve_banded((1, 1), ab, b))
    other = ab.copy()
    other[1, 0] = np.nextafter(other[1, 0], 3.0)
    assert not np.array_equal(tridiagonal_solve(other, b), solve_banded((1, 1), ab, b))
    with pytest.raises(ValueError, match="infs or NaNs"):
        tridiagonal_solve(ab, np.full(ab.shape[1], np.nan))
    with pytest.raises(LinAlgError, match="singular"):
        tridiagonal_solve(banded(np.zeros(3), 0.0), np.ones(3))
