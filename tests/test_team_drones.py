"""Drones at a team's pivots (esp_gym/kernels/team/drones.py; docs/physics.md, "Drones at a team's
pivots"): one drone's team is the single drone's rig bit for bit; the balances close with the
rotors' work and impulses; symmetry, reversibility, orthogonality; a failing step moves nothing;
what the team refuses."""
import numpy as np
import pytest

from esp_gym.physics.drone import DroneSimulator
from esp_gym.physics.simulator import SimulationError
from esp_gym.scene.params import load_scene
from esp_gym.team import TeamScene, TeamSimulator, TeamString
from esp_gym.team.scene import team_scene


@pytest.mark.parametrize("switch", ["settled", "plain"])
def test_a_team_of_one_drone_flies_as_the_single_drone_bit_for_bit(switch):
    scene = load_scene("quadrotor_load", solver={"slack_switch": switch})
    team = TeamSimulator(TeamScene(scene=scene))
    single = DroneSimulator(scene, specialise=False)
    assert team.drone_pivots == [0]
    assert np.array_equal(team.state.drones[0].rotor_speeds, single.drone_state.rotor_speeds)  # the rig's hover
    commands = single.commands_for(19.0, [0.002, -0.001, 0.0005])
    for _ in range(3):
        team.step(100, rotor_commands=commands[None])
        single.step(100, rotor_commands=commands)
    a, b, q = team.state, single.state, single.drone_state
    for k in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(a.lead, k), getattr(b, k)), k
    for got, want in zip(a.drones[0], q):
        assert np.array_equal(got, want)
    t, s = team.diagnostics(), single.diagnostics()
    assert t["work"] == pytest.approx(s["work"], rel=1e-14)
    assert t["energy"] == pytest.approx(s["energy"], rel=1e-14)
    assert t["pi3"] == pytest.approx(s["pi3"], rel=1e-12, abs=1e-18)
    # the wrench's commands are the single drone's too
    team.step(50, thrust=[18.0], torque=[[0.0, 0.001, 0.0]])
    single.step(50, thrust=18.0, torque=[0.0, 0.001, 0.0])
    assert np.array_equal(team.state.lead.r, single.state.r)
    # negative control: a second string of a thousandth of the mass moves the load
    light = TeamString(string=dict(length=1.0, mass_per_length=2e-5, EA=0.5, elements=2),
                       pivot={"kind": "free", "mass": 1e-3, "position": (0.0, 0.0, 0.0)},
                       attachment=tuple(-np.asarray(scene.body.rho_c)))
    pair = TeamSimulator(TeamScene(scene=scene, strings=[light]))
    for _ in range(3):
        pair.step(100, rotor_commands=commands[None])
    assert not np.array_equal(pair.state.lead.r, a.lead.r)


def flown(team, seconds=0.4, seed=0, chunk=50):
    """A three-drone team flown by the rate controller on random setpoints about hover."""
    sim = TeamSimulator(team)
    rng = np.random.default_rng(seed)
    for _ in range(int(round(seconds / (chunk * team.h)))):
        sim.step(chunk, thrust=sim.fleet.shares() * (1.0 + 0.05 * rng.normal(size=team.size)),
                 rates=rng.normal(0.0, 0.3, (team.size, 3)))
    return sim


def test_the_balances_close_with_the_rotors_work_and_impulses():
    sim = flown(team_scene(3, drones=True))
    d = sim.diagnostics()
    assert abs(d["work"]) > 1.0
    assert abs(d["energy_balance_residual"]) < 1e-7 * abs(d["work"])
    assert np.abs(d["momentum_balance_residual"]).max() < 1e-12
    assert abs(d["pi3_balance_residual"]) < 1e-12 < abs(d["angular_impulse_z"])
    assert np.all(d["kinetic_drones"] > 0.0) and np.all(np.abs(d["pi3_drones"]) > 0.0)
    assert np.all(d["orthogonality_drones"] < 1e-14)
    # the energy balance closes at second order: E - E0 - W, h and h/2
    base = team_scene(3, drones=True)
    residuals = []
    for h in (4e-4, 2e-4):
        team = TeamScene(scene=base.scene.model_copy(update={"h": h}), strings=base.strings)
        sim = TeamSimulator(team)
        rng = np.random.default_rng(1)
        worst = 0.0
        for _ in range(20):
            sim.step(int(round(0.01 / h)), thrust=sim.fleet.shares() * 1.1, torque=rng.normal(0.0, 0.02, (3, 3)))
            worst = max(worst, abs(sim.diagnostics()["energy_balance_residual"]))
        residuals.append(worst)
    assert 3.0 < residuals[0] / residuals[1] < 5.5, residuals
    # negative control: the drones' spin left out of the energy breaks the balance
    d = sim.diagnostics()
    assert abs(d["energy_balance_residual"] - d["kinetic_drones"].sum()) > 1e3 * abs(d["energy_balance_residual"])


def rotate_about_e3(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_a_symmetric_drone_team_under_equal_commands_stays_symmetric():
    """Three equal drones at 120 degrees, each climbing on the same thrust and yawing on the same
    torque (R_q = Rz(psi), so their thrusts stay along -e3), the load spun about e3: each string is
    the last one turned by 120 degrees, to round-off, after 2000 steps."""
    team = team_scene(3, drones=True)
    sim = TeamSimulator(team)
    st = sim.state
    st.lead.Pi = st.lead.Pi + np.array([0.0, 0.0, 0.004])
    sim.set_state(st)
    equal = dict(thrust=sim.fleet.shares() * 1.05, torque=np.tile([0.0, 0.0, 0.01], (3, 1)))
    sim.step(2000, **equal)
    st, T = sim.state, sim.params
    turn = rotate_about_e3(2.0 * np.pi / 3.0)
    strings = [st.lead.r[:-1]] + [st.r[T.start[j]:T.start[j + 1] - 1] for j in range(2)]
    scale = np.abs(st.lead.r).max()
    assert abs(st.lead.r[0, 2]) > 1e-3  # the drones moved
    for k in range(3):
        assert np.abs(strings[k] @ turn.T - strings[(k + 1) % 3]).max() < 1e-13 * scale
    assert np.abs(st.drones[0].R - st.drones[1].R).max() < 1e-15 and st.drones[0].R[0, 1] < -1e-3  # all yawed alike
    # negative control: one drone's roll breaks it
    sim.step(300, thrust=equal["thrust"], torque=[[0.0, 0.0, 0.01], [0.002, 0.0, 0.01], [0.0, 0.0, 0.01]])
    st = sim.state
    assert np.abs(st.lead.r[1:-1] @ turn.T - st.r[T.start[0] + 1:T.start[1] - 1]).max() > 1e-6


def test_a_drone_team_retraces_its_steps_when_its_momenta_are_reversed():
    """Rotors at their commands (no lag) give a thrust and a torque that depend on the
    configuration only: reversing every momentum, the drones' too, retraces the flight."""
    sim = TeamSimulator(team_scene(3, drones=True))
    commands = np.array([sim.fleet.commands()[d] * f for d, f in enumerate((1.02, 0.99, 1.01))])
    commands[1, 0] *= 1.003  # a roll and a yaw
    start = sim.state
    start.drones = tuple(d._replace(rotor_speeds=c) for d, c in zip(start.drones, commands))
    sim.set_state(start)
    sim.step(600, rotor_commands=commands)
    ahead = sim.state
    back = ahead.copy()
    back.lead.p, back.lead.Pi, back.p = -back.lead.p, -back.lead.Pi, -back.p
    back.drones = tuple(d._replace(Pi=-d.Pi) for d in back.drones)
    assert np.abs(back.drones[1].Pi).max() > 1e-5
    sim.set_state(back)
    sim.step(600, rotor_commands=commands)
    end = sim.state
    assert np.abs(end.lead.r - start.lead.r).max() < 1e-11
    assert np.abs(end.r - start.r).max() < 1e-11
    for a, b in zip(end.drones, start.drones):
        assert np.abs(a.R - b.R).max() < 1e-12
        assert np.abs(a.Pi + b.Pi).max() < 1e-12
    # negative control: the drones' momenta not reversed, the flight does not retrace
    back.drones = ahead.drones
    sim.set_state(back)
    sim.step(600, rotor_commands=commands)
    assert max(np.abs(a.R - b.R).max() for a, b in zip(sim.state.drones, start.drones)) > 1e-6


def test_a_failing_step_leaves_the_drones_where_they_were():
    team = team_scene(2, drones=True)
    spin = dict(thrust=[18.0, 19.0], torque=[[0.0, 0.01, 0.002], [0.01, 0.0, -0.002]])
    shove = np.array([2e5, 0.0, 0.0])  # on the load: the strings overstretch after the drones' solves
    sim = TeamSimulator(team)
    sim.step(10, **spin)
    with pytest.raises(SimulationError) as failure:
        sim.step(1000, load_force=shove)
    good = sim.step_count
    assert 10 < good < 1010 and failure.value.step == good
    again = TeamSimulator(team)
    again.step(10, **spin)
    again.step(good - 10, load_force=shove)  # the good steps, taken again, are the state kept
    for a, b in zip(sim.state.drones, again.state.drones):
        for x, y in zip(a, b):
            assert np.array_equal(x, y)
    assert np.array_equal(sim.state.lead.r, again.state.lead.r)
    # the second drone's rotation fails to solve (|h Pi_q| beyond the Cayley map's reach): the
    # first drone, solved already, is not committed either
    st = sim.state
    st.drones = (st.drones[0], st.drones[1]._replace(Pi=np.array([0.0, 2e4, 0.0])))
    sim.set_state(st)
    before = sim.state
    with pytest.raises(SimulationError, match="Newton") as failure:
        sim.step(5)
    assert failure.value.step == before.lead.step
    for a, b in zip(sim.state.drones, before.drones):
        for x, y in zip(a, b):
            assert np.array_equal(x, y)
    assert np.array_equal(sim.state.lead.r, before.lead.r)


def test_a_drone_team_refuses_what_it_does_not_do():
    team = team_scene(2, drones=True)
    hooked = team.scene.pivot.drone.model_copy(update={"rho_q": (0.0, 0.0, 0.05)})
    with pytest.raises(ValueError, match=r"scene.pivot.drone.rho_q"):
        TeamScene(scene=team.scene.model_copy(update={"pivot": team.scene.pivot.model_copy(update={"drone": hooked})}),
                  strings=team.strings)
    sim = TeamSimulator(team)
    with pytest.raises(ValueError, match=r"pivot_forces\[1\].*drone"):
        sim.step(1, pivot_forces=np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    with pytest.raises(ValueError, match=r"rotor_commands must be finite of shape \(2, 4\)"):
        sim.step(1, rotor_commands=np.zeros(4))
    with pytest.raises(ValueError, match=r"rotor_commands must lie in \[0, max_rotor_speed\]"):
        sim.step(1, rotor_commands=np.full((2, 4), 1e4))
    with pytest.raises(ValueError, match="not both"):
        sim.step(1, rotor_commands=np.zeros((2, 4)), thrust=[1.0, 1.0])
    with pytest.raises(ValueError, match="torque or their rates"):
        sim.step(1, thrust=[1.0, 1.0], torque=np.zeros((2, 3)), rates=np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"rates must be finite"):
        sim.step(1, thrust=[1.0, 1.0], rates=np.full((2, 3), np.nan))
    st = sim.state
    st.drones = st.drones[:1]
    with pytest.raises(ValueError, match="state.drones has 1 drones, the team 2"):
        sim.set_state(st)
    st = sim.state
    st.drones = (st.drones[0]._replace(R=2.0 * np.eye(3)), st.drones[1])
    with pytest.raises(ValueError, match=r"state.drones\[0\].R"):
        sim.set_state(st)
    points = TeamSimulator(team_scene(2))
    with pytest.raises(ValueError, match="thrust: the team has no drone"):
        points.step(1, thrust=[1.0, 1.0], rates=np.zeros((2, 3)))
