"""A team environment's compiled control step (esp_gym/kernels/team/env.py, esp_gym/team/control.py)
against the same episode stepped in Python (``TeamCore.compiled_steps = False``: TeamSimulator.step,
then the compiled task): the states bit for bit, the observations, rewards, infos and terminations
equal, the energy balance to 1e-12 of its scale (the load force's work is summed in another order),
over episodes of strong random actions that end, for point pivots and for drones in every
actuation, with latency, noise, wind and randomised teams; a failing step and the energy watchdog
give the same termination and error; an action that is not finite changes nothing; and a force
scale moved by one part in 1e12 is seen (the negative control)."""
import numpy as np
import pytest

from esp_gym.kernels.status import ENERGY_BALANCE
from esp_gym.kernels.team.env import TD_HOVER_THRUST, TE_FORCE_SCALE
from esp_gym.team.core import TeamCore
from esp_gym.team.scene import team_scene

CONFIGS = {
    "points": dict(team=3),
    "points, track, latency": dict(team=2, task="track", action_latency=2),
    "points, hard": dict(team=3, preset="hard"),
    "drones, thrust_rates, hook": dict(team=3, actuation="thrust_rates", observation="hook"),
    "drones, thrust_torque, hard": dict(team=3, actuation="thrust_torque", preset="hard"),
    "drones, motors, track": dict(team=2, actuation="motors", task="track"),
}


def episode(options: dict, compiled: bool, steps: int = 200, amplitude: float = 0.5, seed: int = 3,
            perturb=None) -> tuple:
    """``(each step's outcome, the final TeamState, the core)`` of one seeded episode of random
    actions, stepped compiled or in Python (``perturb(core)`` after the reset)."""
    with pytest.MonkeyPatch.context() as patch:  # read where each episode's team is built
        patch.setattr(TeamCore, "compiled_steps", compiled)
        core = TeamCore(**options)
        core.reset(seed=seed)
    assert (core.control is not None) == compiled
    if perturb is not None:
        perturb(core)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(steps):
        obs, reward, terminated, _, info = core.step(rng.uniform(-amplitude, amplitude, (core.size, core.action_size)))
        out.append((obs, reward, terminated, info, core.sim.diagnostics()["energy_balance_residual"]))
        if terminated:
            break
    return out, core.sim.state, core


def assert_same_states(a, b) -> None:
    for name in ("r", "p", "R", "Pi"):
        assert np.array_equal(getattr(a.lead, name), getattr(b.lead, name)), f"lead.{name}"
    assert np.array_equal(a.r, b.r) and np.array_equal(a.p, b.p)
    for da, db in zip(a.drones, b.drones):
        for x, y in zip(da, db):
            assert np.array_equal(x, y)


def assert_same_outcomes(compiled: list, python: list, scale: float) -> None:
    assert len(compiled) == len(python)
    for (o1, r1, t1, i1, e1), (o2, r2, t2, i2, e2) in zip(compiled, python):
        assert np.array_equal(o1, o2) and r1 == r2 and t1 == t2
        assert set(i1) == set(i2)
        for key in i1:
            assert np.array_equal(np.asarray(i1[key]), np.asarray(i2[key])), key
        # the load force's work: F . dx summed in the kernel's order, NumPy's dot in Python
        assert abs(e1 - e2) <= 1e-12 * scale


@pytest.mark.parametrize("name", list(CONFIGS))
def test_the_compiled_control_step_is_the_python_one(name):
    options = CONFIGS[name]
    compiled, state, _ = episode(options, True)
    python, reference, _ = episode(options, False)
    assert_same_outcomes(compiled, python, scale=10.0)
    assert_same_states(state, reference)
    assert len(compiled) > 20  # the episode ran


def test_a_failing_step_and_the_watchdog_end_the_episode_as_in_python():
    """The energy watchdog at 1e-12 of the energy scale breaks at the first step: the same
    termination, reward and error (its message names the balance) both ways."""
    team = team_scene(3)
    solver = team.scene.solver.model_copy(update={"energy_watchdog": 1e-12})
    team = team.model_copy(update={"scene": team.scene.model_copy(update={"solver": solver})})
    runs = [episode(dict(team=team), compiled) for compiled in (True, False)]
    (compiled, state, core), (python, reference, other) = runs
    assert compiled[-1][3]["termination"] == ENERGY_BALANCE and compiled[-1][2]
    assert_same_outcomes(compiled, python, scale=10.0)
    assert_same_states(state, reference)
    assert str(core.failure) == str(other.failure) and core.failure.status == ENERGY_BALANCE


def test_an_action_that_is_not_finite_changes_nothing():
    core = TeamCore(team=3, preset="hard")
    core.reset(seed=1)
    before, draws, steps = core.sim.state, core.np_random.bit_generator.state, core.steps
    bad = np.zeros((3, 3))
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="finite"):
        core.step(bad)
    assert_same_states(core.sim.state, before)
    assert core.np_random.bit_generator.state == draws and core.steps == steps
    core = TeamCore(team=3)  # no latency nor wind: the kernel itself refuses it
    core.reset(seed=1)
    before = core.sim.state
    with pytest.raises(ValueError, match="finite"):
        core.step(bad)
    assert_same_states(core.sim.state, before)


def test_a_force_scale_moved_by_one_part_in_1e12_is_seen():
    """The negative control: the comparison above sees the smallest change of an input."""
    def nudge(core):
        core.control.arrays.params[TE_FORCE_SCALE] *= 1.0 + 1e-12

    _, moved, _ = episode(CONFIGS["points"], True, steps=30, perturb=nudge)
    _, reference, _ = episode(CONFIGS["points"], False, steps=30)
    with pytest.raises(AssertionError):
        assert_same_states(moved, reference)


@pytest.mark.parametrize("name", ["points, hard", "drones, thrust_rates, hook"])
def test_a_team_in_a_batch_is_the_team_alone(name):
    """Three teams stepped in one compiled call (esp_gym/team/batch.py) against three stepped alone,
    through resets that build new teams (the hard preset's), bit for bit; a force scale moved by one
    part in 1e12 in one team's row is seen in that team only (the negative control)."""
    from esp_gym.team.batch import TeamBatch

    options, B = CONFIGS[name], 3
    cores, alone = ([TeamCore(**options) for _ in range(B)] for _ in range(2))
    for b in range(B):
        cores[b].reset(seed=b)
        alone[b].reset(seed=b)
    batch = TeamBatch(cores)
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(120):
        actions = rng.uniform(-0.5, 0.5, (B, cores[0].size, cores[0].action_size))
        outcomes = batch.step(actions.copy(), np.ones(B, dtype=bool))
        for b in range(B):
            obs, reward, terminated, _, _ = alone[b].step(actions[b])
            assert np.array_equal(outcomes[b][0], obs) and outcomes[b][1] == reward
            assert_same_states(cores[b].sim.state, alone[b].sim.state)
            if terminated:
                ends += 1
                for core in (cores[b], alone[b]):
                    core.reset()
                batch.reset(b)
    assert ends >= 2
    if cores[0].drones:  # team 1's hover thrust, else its force scale
        batch.env.drive[1, :, TD_HOVER_THRUST] *= 1.0 + 1e-12
    else:
        batch.env.params[1, TE_FORCE_SCALE] *= 1.0 + 1e-12
    for _ in range(3):
        batch.step(np.full((B, cores[0].size, cores[0].action_size), 0.1), np.ones(B, dtype=bool))
        for b in range(B):
            alone[b].step(np.full((cores[0].size, cores[0].action_size), 0.1))
    assert_same_states(cores[0].sim.state, alone[0].sim.state)
    with pytest.raises(AssertionError):
        assert_same_states(cores[1].sim.state, alone[1].sim.state)
