"""Winches on a team's strings (docs/physics.md, "Winches on a team's strings";
esp_gym/kernels/team/winch.py): one string reels as the single winch, bit for bit; the energy
balance with the winches' work closes at order 2; momentum and pi3 balance to round-off; a
symmetric team reeling together stays symmetric; reversing the momenta and the reels retraces
the steps; each winch stops on the ends of its range; bad commands change nothing."""
import numpy as np
import pytest

from esp_gym.physics.simulator import Simulator
from esp_gym.team import TeamSimulator, symmetric_team
from esp_gym.team.scene import team_scene
from esp_gym.team.simulator import TeamState

FREE = {"kind": "free", "mass": 0.5}
FORCES = np.array([[0.3, -0.2, -4.0], [0.1, 0.2, -4.5], [-0.2, 0.0, -5.0]])


def test_one_string_reels_as_the_single_winch_bit_for_bit():
    """K = 1: the team's reeling step is the single string's (kernels/step/winch.py), states equal to
    the bit through a reel out, a stop and a reel in with a pushed free pivot; the energy too,
    and the winch work to the rounding of H's jumps (Python's sum against the kernel's). A reel
    speed 1e-9 m/s off moves the state (negative control)."""
    team = symmetric_team(1, elements=8, stretch=1.01, pivot=FREE, h=1e-4)
    single, same, other = (Simulator(team.scene, specialise=False), TeamSimulator(team), TeamSimulator(team))
    for v in (0.2, 0.0, -0.3):
        single.step(300, pivot_force=FORCES[0], reel_speed=v)
        same.step(300, pivot_forces=FORCES[:1], reel_speeds=[v])
        other.step(300, pivot_forces=FORCES[:1], reel_speeds=[v + 1e-9])
    a, b = single.state, same.state.lead
    assert all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("r", "p", "R", "Pi"))
    assert not np.array_equal(a.r, other.state.lead.r)
    d1, d2 = single.diagnostics(), same.diagnostics()
    assert d1["energy"] == d2["energy"]
    assert d2["winch_work"] == pytest.approx(d1["winch_work"], abs=1e-12)
    assert d2["unstretched_lengths"][0] == d1["unstretched_length"]


def reel_out_stop_in(h, pivot=FREE, speeds=(0.2, -0.1, 0.3), seconds=0.03):
    """Three strings on free pivots pushed by FORCES: reel at ``speeds``, stop, reel back, each
    for ``seconds``; returns the simulator and its diagnostics after each stage."""
    sim = TeamSimulator(symmetric_team(3, elements=6, stretch=1.01, pivot=pivot, h=h))
    n = int(round(seconds / h))
    out = []
    for v in (speeds, (0.0, 0.0, 0.0), tuple(-x for x in speeds)):
        sim.step(n, pivot_forces=FORCES if pivot else None, reel_speeds=v)
        out.append(sim.diagnostics())
    return sim, out


def test_the_energy_balance_with_the_winches_is_second_order():
    """E - E0 - W - W_winch over a reel out, a stop and a reel in of three strings at different
    speeds falls 4x per halving of h (measured 1.1e-5, 2.7e-6, 6.8e-7 J at the stop, 100/50/25 us),
    against a winch work of 0.12 J; without the winch work the balance misses by 0.1 J (the
    negative control)."""
    residual = []
    for h in (1e-4, 5e-5, 2.5e-5):
        _, stages = reel_out_stop_in(h)
        residual.append(max(abs(d["energy_balance_residual"]) for d in stages))
    d = stages[-1]
    ratios = [residual[i] / residual[i + 1] for i in range(2)]
    assert all(3.6 < q < 4.4 for q in ratios), (residual, ratios)
    assert residual[0] < 2e-5 and abs(d["winch_work"]) > 0.1
    assert abs(d["energy_balance_residual"] + d["winch_work"]) > 1e4 * residual[-1]


def test_momentum_and_pi3_balance_to_round_off_while_reeling():
    """Free pivots pushed, the winches reeling: the total momentum changes by gravity's and the
    pushes' impulses (the reeled material's momentum comes from the pivots), pi3 by the pushes'
    angular impulse, both to round-off."""
    _, stages = reel_out_stop_in(1e-4)
    for d in stages:
        assert np.abs(d["momentum_balance_residual"]).max() < 1e-12
        assert abs(d["pi3_balance_residual"]) < 1e-12


def turned(r, angle):
    c, s = np.cos(angle), np.sin(angle)
    return r @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T


def test_a_symmetric_team_reeling_together_stays_symmetric():
    """Three equal strings on fixed pivots, reeling in together: each string is the next one
    turned by 120 degrees to 1e-12 m after 2,000 steps and the load stays on the axis; a
    1 mm/s difference between the reels breaks it (negative control)."""
    def run(speeds):
        sim = TeamSimulator(symmetric_team(3, elements=6, stretch=1.01, h=1e-4))
        sim.step(2000, reel_speeds=speeds)
        return sim
    sim = run([-0.2, -0.2, -0.2])
    (r0, _), (r1, _), (r2, _) = sim.strings()
    gap = max(np.abs(turned(r0, 2 * np.pi / 3) - r1).max(), np.abs(turned(r1, 2 * np.pi / 3) - r2).max())
    assert gap < 1e-12 and np.abs(sim.load_position()[:2]).max() < 1e-12
    assert sim.winches.lengths == pytest.approx([0.96] * 3, abs=1e-12)
    (q0, _), (q1, _), _ = run([-0.2, -0.2, -0.201]).strings()
    assert np.abs(turned(q0, 2 * np.pi / 3) - q1).max() > 1e-6


def test_reversing_the_momenta_and_the_reels_retraces_the_steps():
    """Reel three strings at different speeds for 600 steps, reverse every momentum and reel,
    reel 600 steps back: the positions, the lengths and the reversed momenta return to 1e-11."""
    sim = TeamSimulator(symmetric_team(3, elements=6, stretch=1.01, pivot=FREE, h=1e-4))
    start = sim.state
    speeds = np.array([0.3, -0.2, 0.1])
    sim.set_state(TeamState(start.lead, start.r, start.p, lengths=start.lengths, reel_speeds=speeds))
    sim.step(600, reel_speeds=speeds)
    s = sim.state
    lead = s.lead
    lead.p, lead.Pi = -lead.p, -lead.Pi
    sim.set_state(TeamState(lead, s.r, -s.p, lengths=s.lengths, reel_speeds=-speeds))
    sim.step(600, reel_speeds=-speeds)
    back = sim.state
    assert np.abs(back.lead.r - start.lead.r).max() < 1e-11 and np.abs(back.r - start.r).max() < 1e-11
    assert np.abs(back.lead.p + start.lead.p).max() < 1e-11 and np.abs(back.p + start.p).max() < 1e-11
    assert np.abs(back.lead.R - start.lead.R).max() < 1e-11
    assert back.lengths == pytest.approx(start.lengths, abs=1e-12)


def ranged_team(h):
    team = symmetric_team(2, elements=6, stretch=1.01, h=h)
    data = team.model_dump()
    data["scene"]["winch"] = {"min_length": 0.8, "max_length": 1.1, "max_speed": 2.0}
    return type(team).model_validate(data)


def test_each_winch_stops_on_the_ends_of_its_range_and_the_balance_closes():
    """String 0 reels at 2 m/s across both ends of its range [0.8, 1.1] m while string 1 reels at
    0.2 m/s: string 0 stops on each end exactly (its last step cut to land there, its reel then
    at rest), string 1 goes on, and the energy balance across the stops closes (measured 3.5e-4
    and 1.8e-4 of the winch work at 100 and 50 us). The stops at 2 m/s ring the strings' axial
    modes and the residual is not yet in its asymptotic order at these steps: one string, the
    single winch bit for bit, falls 7.5x then 5.2x then 2.7x per halving from 50 us in the same
    protocol; the smooth reels above show order 2."""
    residual = []
    for h in (1e-4, 5e-5):
        sim = TeamSimulator(ranged_team(h))
        steps = int(round(0.1 / h))
        sim.step(steps, reel_speeds=[2.0, 0.2])
        d = sim.diagnostics()
        assert (d["unstretched_lengths"][0], d["reel_speeds"][0]) == (1.1, 0.0)
        assert d["unstretched_lengths"][1] == pytest.approx(1.02, abs=1e-12) and d["reel_speeds"][1] == 0.2
        sim.step(2 * steps, reel_speeds=[-2.0, -0.2])
        d = sim.diagnostics()
        assert (d["unstretched_lengths"][0], d["reel_speeds"][0]) == (0.8, 0.0)
        residual.append(abs(d["energy_balance_residual"]) / abs(d["winch_work"]))
        assert sim.step_count == 3 * steps
    assert residual[0] < 1e-3 and residual[1] < residual[0] / 1.5, residual


@pytest.mark.parametrize("bad, message", [
    ([0.1, float("nan")], r"reel_speeds\[1\].*finite"), ([0.1, 3.0], r"reel_speeds\[1\].*max_speed"),
    ([0.1], "2 numbers"), (0.1, "2 numbers"), ([0.1, "fast"], r"reel_speeds\[1\]")])
def test_a_bad_reel_command_raises_and_changes_nothing(bad, message):
    sim = TeamSimulator(ranged_team(1e-4))
    sim.step(50, reel_speeds=[0.3, 0.1])
    before = sim.state
    with pytest.raises(ValueError, match=message):
        sim.step(10, reel_speeds=bad)
    after = sim.state
    assert np.array_equal(after.lead.r, before.lead.r) and np.array_equal(after.lengths, before.lengths)
    assert sim.step_count == 50


def test_what_cannot_reel_says_why():
    """h above a string's bound at its winch's shortest length, and drones, are refused by name."""
    bound = symmetric_team(2, elements=6, stretch=1.01).scene.stability_bound
    team = symmetric_team(2, elements=6, stretch=1.01, h=0.9 * bound)  # stable at 1 m, not at 0.5 m
    with pytest.raises(ValueError, match=r"string 0.*scene.winch.min_length"):
        TeamSimulator(team).step(1, reel_speeds=[0.1, 0.0])
    with pytest.raises(ValueError, match="drones do not reel"):
        TeamSimulator(team_scene(2, drones=True)).step(1, reel_speeds=[0.1, 0.0])


def test_a_team_state_carries_its_lengths_and_reel_speeds():
    """The state after reeling, set again, steps as the simulator that went on (to the rounding
    its remainders, which a state does not carry, would have saved: 1e-12 m) and set in a second
    simulator it steps to the same bits; without its lengths it is another state (negative
    control); lengths outside a range are refused by name."""
    team = ranged_team(1e-4)
    sim = TeamSimulator(team)
    sim.step(100, reel_speeds=[0.5, -0.3])
    saved = sim.state
    sim.step(50, reel_speeds=[0.5, -0.3])
    ahead = sim.state
    sim.set_state(saved)
    sim.step(50, reel_speeds=[0.5, -0.3])
    again = TeamSimulator(team)
    again.set_state(saved)
    again.step(50, reel_speeds=[0.5, -0.3])
    assert np.array_equal(sim.state.lead.r, again.state.lead.r) and np.array_equal(sim.state.r, again.state.r)
    assert np.abs(sim.state.lead.r - ahead.lead.r).max() < 1e-12
    assert np.array_equal(sim.state.lengths, ahead.lengths)
    forgot = TeamSimulator(team)
    forgot.set_state(TeamState(saved.lead, saved.r, saved.p, reel_speeds=saved.reel_speeds))
    forgot.step(50, reel_speeds=[0.5, -0.3])
    assert np.abs(forgot.state.lead.r - ahead.lead.r).max() > 1e-6
    with pytest.raises(ValueError, match=r"lengths\[0\].*winch range"):
        sim.set_state(TeamState(saved.lead, saved.r, saved.p, lengths=np.array([2.0, 1.0])))
