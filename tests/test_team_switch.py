"""The slack switch of a team's strings (esp_gym/kernels/team/switch.py; docs/physics.md, "The slack
switch of a team's strings"): the settling impulses see every string through the body. One slack
string settles as the single string bit for bit (fixed length and reeling); the compiled inverse of
the team's Legendre transform is the diagnostics' (point pivots and reeling), the compiled read-out
the Python one (point pivots and drones); a team whose motion is
1-D keeps its modified energy to round-off through thousands of switches; the impulses are internal.
Each with the plain step (``solver.slack_switch: plain``) as the negative control."""
import numpy as np
import pytest

from esp_gym.kernels.layout import WINCH
from esp_gym.kernels.team.readout import TEAM_READ, team_read
from esp_gym.kernels.team.switch import node_velocities_entry as velocities
from esp_gym.kernels.team.winch import flow_free_momenta, velocity_params
from esp_gym.physics.simulator import Simulator
from esp_gym.scene.params import load_scene
from esp_gym.team import TeamScene, TeamSimulator, TeamString, symmetric_team
from esp_gym.team.scene import team_scene
from esp_gym.team.assembly import string_mass
from esp_gym.team.velocities import team_velocities

SWITCHES = ("settled", "plain")
FREE = {"kind": "free", "mass": 0.5}
SOLVER = {"energy_watchdog": None}


def with_switch(scene, switch: str):
    return scene.model_copy(update={"solver": scene.solver.model_copy(update={"slack_switch": switch})})


def test_one_slack_string_settles_as_the_single_string_bit_for_bit():
    """K = 1: ``drone_load`` (slack, free pivot) pushed by random forces, and a slack string reeling
    out, holding and reeling in: the team's settled step is the single string's (kernels/step/switch.py,
    kernels/step/winch.py) to the bit. Negative control: the plain team's state differs (the switches
    did act)."""
    rng = np.random.default_rng(1)
    scene = load_scene("drone_load", **{"initial.direction": [0.3, 0.0, 1.0]})
    reeled = symmetric_team(1, elements=8, stretch=1.01, pivot=FREE, h=1e-4, law="slack").scene
    for rig, speeds in ((scene, (None,)), (reeled, (0.2, 0.0, -0.3))):
        single, team, plain = (Simulator(rig, specialise=False), TeamSimulator(TeamScene(scene=rig)),
                               TeamSimulator(TeamScene(scene=with_switch(rig, "plain"))))
        weight = rig.gravity * (rig.body.mass + rig.pivot.mass + rig.string.mass_per_length * rig.string.length)
        for v in speeds:
            for _ in range(10):
                force = rng.uniform(-4.0, 4.0, 3) - [0.0, 0.0, weight]
                reel = {} if v is None else {"reel_speed": v}
                single.step(50, pivot_force=force, **reel)
                for sim in (team, plain):
                    sim.step(50, pivot_forces=force[None], **({} if v is None else {"reel_speeds": [v]}))
        a, b = single.state, team.state.lead
        assert all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("r", "p", "R", "Pi"))
        assert not np.array_equal(a.r, plain.state.lead.r)


def unequal_team(switch: str = "settled", last=None):
    """Three unequal slack strings at unequal points of a box, two on free pivots, one of a single
    element from ``last`` (default a fixed pivot)."""
    base = symmetric_team(3, pivot=FREE, stretch=1.01, law="slack", h=1e-4, solver={"slack_switch": switch})
    others = [TeamString(string=dict(length=1.07, mass_per_length=0.08, EA=1500.0, elements=5, law="slack"),
                         pivot={**FREE, "position": (-0.4, 0.5, -0.05)}, attachment=(-0.15, 0.1, -0.05)),
              TeamString(string=dict(length=1.0, mass_per_length=0.03, EA=2500.0, elements=1, law="slack"),
                         pivot={**(last or {"kind": "fixed"}), "position": (-0.2, -0.7, 0.1)},
                         attachment=(0.05, -0.18, -0.05))]
    return TeamSimulator(TeamScene(scene=base.scene, strings=others))


PUSH = np.array([[0.3, -0.2, -4.0], [0.1, 0.2, -4.5], [0.0, 0.0, 0.0]])  # the fixed pivot's row 0


def test_the_compiled_inverse_legendre_transform_is_the_diagnostics():
    """kernels/team/switch.py's node velocities and Omega against esp_gym/team/velocities.py's
    (banded solves and the 6x6 body system): a turning team at its fixed lengths, to 1e-15 m/s;
    reeling at 0.2, -0.1, 0.3 m/s, its momenta less the flow's and its masses at the new lengths
    (kernels/team/winch.py ``velocity_params``), to 1e-11 m/s (the flow's momenta summed in
    another order)."""
    sim = unequal_team()
    st = sim.state
    st.lead.Pi = st.lead.Pi + np.array([0.002, -0.001, 0.003])
    sim.set_state(st)
    sim.step(300, pivot_forces=PUSH)
    sim.compiled_reads = False  # the diagnostics' own inverse (at rest winches read out compiled)
    S, A, T, P = sim._S, sim._A, sim.params, sim._P
    V0, Vo = np.zeros_like(S.p), np.zeros_like(A.p)
    omega = velocities(S.p, A.p, S.Pi, S.R, P.first, P.off, T, V0, Vo)
    v0, vo, Omega = sim.velocities()
    assert not sim._compiled_read
    assert np.abs(V0 - v0).max() < 1e-15 and np.abs(Vo - vo).max() < 1e-15
    assert np.abs(np.array(omega) - Omega).max() < 1e-14
    speeds = np.array([0.2, -0.1, 0.3])
    sim.step(300, pivot_forces=PUSH, reel_speeds=speeds)
    v0, vo, Omega = sim.velocities()
    TW = sim.winches.arrays
    lengths = TW.state[:, WINCH.scalar("length")].copy()  # a step l - h v -> l at the reel speeds
    TW.target[:] = lengths
    TW.state[:, WINCH.scalar("length")] = lengths - P.h * speeds
    Td, off0 = velocity_params(S, P, T, TW, P.h, P.first)
    Td = Td._replace(rho_inertial=TW.body[1:].copy())  # (numba returns that slice's whole parent)
    Pi = np.array(flow_free_momenta(S, T, A, TW, P.h, P.first))
    omega = velocities(TW.lead.pshift, TW.fl, Pi, S.R, P.first, off0, Td, V0, Vo)
    TW.state[:, WINCH.scalar("length")] = lengths
    assert np.abs(V0 - v0).max() < 1e-11 and np.abs(Vo - vo).max() < 1e-11
    assert np.abs(np.array(omega) - Omega).max() < 1e-11


READ_OUTS = ("pivot", "pivot_velocity", "tension", "stretch", "load", "load_velocity", "Omega")
ENERGY_TERMS = ("kinetic", "potential_elastic", "potential_gravity", "energy", "pi3", "linear_momentum")


@pytest.mark.parametrize("drones", [False, True])
def test_the_compiled_read_out_is_the_python_one(drones):
    """kernels/team/readout.py's read-out (one compiled call: the velocities by the step's factors,
    the energy terms, momenta and pi3, each pivot, its velocity and its string's pull, each string's
    stretch, the load's centre and its velocity) against esp_gym/team/readout.py's in Python (LAPACK's
    solves), each to 1e-12 of its scale: the turning team of unequal strings with a fixed pivot, and a
    team of three drones. Then, reeled, the team reads out in Python (the negative control: the
    compiled read-out, which assumes the scenes' lengths, is then off by more than 1e-6)."""
    sim = TeamSimulator(team_scene(3, drones=True)) if drones else unequal_team()
    st = sim.state
    st.lead.Pi = st.lead.Pi + np.array([0.002, -0.001, 0.003])
    sim.set_state(st)
    sim.step(300, pivot_forces=None if drones else PUSH)

    def read(compiled: bool, reel=None):
        sim.compiled_reads = compiled
        observed, energies = sim.observed(), sim.diagnostics()
        assert sim._compiled_read == (compiled and reel is None)
        return [observed[k] for k in READ_OUTS] + [energies[k] for k in ENERGY_TERMS]

    for fast, slow in zip(read(True), read(False)):
        assert np.abs(np.asarray(fast) - slow).max() <= 1e-12 * max(1.0, np.abs(slow).max())
    if drones:
        return
    sim.step(100, pivot_forces=PUSH, reel_speeds=np.array([0.2, -0.1, 0.3]))
    sim.step(1, pivot_forces=PUSH)  # at rest, at the new lengths
    python = read(False, "reeled")
    assert all(np.array_equal(a, b) for a, b in zip(read(True, "reeled"), python))
    S, A, T, P = sim._S, sim._A, sim.params, sim._P
    team_read(S, P, T, A, sim._read)  # with the factors of the scenes' lengths
    assert np.abs(sim._read.out[TEAM_READ["omega"]] - python[READ_OUTS.index("Omega")]).max() > 1e-6


def flickering_team(switch: str):
    """Three unequal slack strings hanging straight down from one fixed pivot to one point of the
    load, its centre of mass below it (no torque: the load does not turn), string 0's nodes started
    at random axial speeds of up to 2 m/s: every motion is along e3 and the elements flicker
    between slack and taut, every string's through the load; h is 0.5 of the smallest bound."""
    speeds = np.zeros((9, 3))
    speeds[1:, 2] = np.random.default_rng(0).uniform(-2.0, 2.0, 8)
    lead = load_scene("drone_load", string={"length": 0.5}, body={"rho_c": [0.0, 0.0, 0.0]},
                      pivot={"kind": "fixed", "mass": None}, solver={"slack_switch": switch, **SOLVER},
                      **{"initial.direction": [0.0, 0.0, 1.0], "initial.node_velocities": speeds.tolist()})
    pivot = {"kind": "fixed", "position": tuple(lead.pivot.position)}
    others = [TeamString(string=dict(length=0.5, mass_per_length=0.08, EA=300.0, elements=5, law="slack"),
                         pivot=pivot, attachment=(0.0, 0.0, 0.0)),
              TeamString(string=dict(length=0.45, mass_per_length=0.03, EA=150.0, elements=3, law="slack"),
                         pivot=pivot, attachment=(0.0, 0.0, 0.0))]
    probe = TeamScene(scene=lead.model_copy(update={"h": 1e-6}), strings=others)
    bound = min(probe.member_scene(k).stability_bound for k in range(3))
    return TeamSimulator(TeamScene(scene=lead.model_copy(update={"h": 0.5 * bound}), strings=others))


def force_energy(sim) -> float:
    """1/2 f . A f [J]: the kinetic energy of 'momenta' equal to the team's generalised forces
    (every node's, each end's on the body with its moment, the load's weight torque), by the
    diagnostics' own inverse (esp_gym/team/velocities.py)."""
    S, A, T, P = sim._S, sim._A, sim.params, sim._P
    p0, po = S.f.copy(), A.f.copy()
    Pi = P.M * P.g * np.cross(P.rho, S.R[2])
    for j in range(len(T.first)):
        e = T.start[j + 1] - 1
        p0[-1] += po[e]
        Pi = Pi + np.cross(T.rho[j], S.R.T @ po[e])
        po[e] = 0.0
    members = []
    for k, (_, string, pivot) in enumerate(sim._members()):
        diag, off, _ = string_mass(string, pivot)
        rows = p0 if k == 0 else po[T.start[k - 1]:T.start[k]]
        members.append((diag, off, 0 if pivot.is_free else 1, rows, np.zeros(3) if k == 0 else T.rho[k - 1]))
    (v0, *rest), omega = team_velocities(members, P.M, P.rho, P.J, S.R, p0[-1], Pi)
    return 0.5 * (np.sum(p0 * v0) + np.sum(po * np.concatenate(rest)) + Pi @ omega)


def modified_energy(sim) -> float:
    """H~ = E - h^2/8 f . A f less what the switches still owe [J] (tests/test_switch.py's, with
    the team's inverse mass matrix)."""
    owed = sim._S.owed.sum() + sim._A.owed.sum()
    return sim.diagnostics()["energy"] - sim.h ** 2 / 4 * force_energy(sim) - owed


def switch_count(before, after) -> int:
    return sum(int(np.sum((np.linalg.norm(np.diff(a, axis=0), axis=1) < s.u)
                          != (np.linalg.norm(np.diff(b, axis=0), axis=1) < s.u)))
               for (a, s, _), (b, _, _) in zip(before, after))


@pytest.mark.parametrize("switch", SWITCHES)
def test_a_flickering_team_keeps_its_modified_energy_to_round_off(switch):
    """10,000 steps of three strings whose motion is 1-D (the potential piecewise quadratic along
    each step): settled, H~ stays within 1e-12 J (round-off of a 2 J energy; measured 6.4e-15);
    plain, the switches move it (measured 0.042 J)."""
    sim = flickering_team(switch)
    start, worst, switches = modified_energy(sim), 0.0, 0
    before = [(r.copy(), s, p) for r, s, p in sim._members()]
    for _ in range(500):
        sim.step(20)
        worst = max(worst, abs(modified_energy(sim) - start))
        after = [(r.copy(), s, p) for r, s, p in sim._members()]
        switches += switch_count(before, after)
        before = after
    assert np.abs(sim.state.r[:, :2]).max() == 0.0 and np.array_equal(sim.state.lead.R, np.eye(3))  # 1-D
    assert switches > 1000, switches  # it does flicker (measured 1,638 between samples)
    if switch == "settled":
        assert worst <= 1e-12, worst
    else:
        assert worst >= 1e-2, worst


def test_settling_keeps_momentum_and_pi3():
    """The unequal team on free pivots, turning, pushed at random, its strings flickering, reeling
    and at fixed lengths: the settling impulses are internal, so the linear momentum still equals
    the gravity and pivot impulses and pi3 moves by exactly the inputs' angular impulse, both to
    round-off; the settled state is not the plain one (the switches acted)."""
    runs = []
    for switch in SWITCHES:
        sim = unequal_team(switch, FREE)
        rng = np.random.default_rng(3)
        for k in range(40):
            speeds = rng.uniform(-0.3, 0.3, 3) if k % 4 else np.zeros(3)
            pushes = PUSH + [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -3.0]] + rng.uniform(-3.0, 3.0, (3, 3))
            sim.step(50, pivot_forces=pushes, reel_speeds=speeds)
        runs.append(sim)
        d = sim.diagnostics()
        scale = np.abs(d["linear_momentum"] - d["momentum_balance_residual"]).max()
        assert np.abs(d["momentum_balance_residual"]).max() <= 1e-13 * max(scale, 1.0), d["momentum_balance_residual"]
        assert abs(d["pi3_balance_residual"]) <= 1e-13, d["pi3_balance_residual"]
    assert not np.array_equal(runs[0].state.r, runs[1].state.r)


def test_the_team_energy_benchmark_runs_quick(tmp_path):
    """benchmarks/team_energy.py --quick: K = 2 transport for 1 s, settled and plain, its table's
    rows, its JSON and its figure."""
    from benchmarks.team_energy import main

    result = main(["--quick", "--out", str(tmp_path)])
    assert [(row["run"], row["switch"]) for row in result["runs"]] == [("transport K=2", s) for s in SWITCHES]
    assert all(row["t"] == pytest.approx([0.0, 0.5, 1.0]) and row["worst"] < 1e-3 for row in result["runs"])
    assert (tmp_path / "team_energy.json").exists() and (tmp_path / "team_energy.png").stat().st_size > 0


def test_a_failing_teams_balance_converges_as_h_shrinks():
    """Two point pivots under the LQR + 0.3 x noise (seed 205) fail within 10 s, and the residual's
    largest swing comes in that violent end: above 0.1 J at the default safety (0.24 J measured),
    below 0.05 J at an eighth of the bound (0.026 J): a bounded error of the step, not a gain
    (docs/physics.md, "The slack switch of a team's strings")."""
    from benchmarks.team_energy import run

    coarse, fine = (run("K=2", 2, "transport", False, "lqr", "settled", 60.0, 0.3, 205, safety=safety)
                    for safety in (0.5, 0.125))
    assert coarse["reason"] and fine["reason"] and coarse["t"][-1] < 15.0 and fine["t"][-1] < 15.0
    assert coarse["worst"] > 0.1 > 0.05 > fine["worst"], (coarse["worst"], fine["worst"])
