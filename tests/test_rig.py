"""The rig table (esp_gym/physics/rig.py): every combination of pivot, string scheme, winch and hook, for
one string and for a team, is either a rig, run by that rig's entry points with its structs in the
one order, or refused with one message that names it and lists the environment's rigs; the docs
quote the table as it is."""
import itertools
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import esp_gym
from esp_gym.physics.rig import RIGS, STRUCTS, find_rig
from esp_gym.team.scene import TeamScene, team_scene

DOCS = Path(__file__).resolve().parent.parent / "docs" / "environment.md"
HOOK = [0.0, 0.0, -0.05]


def options(pivot: str, string: str, winch: bool, hook: bool, damped: bool = False) -> dict:
    """gym.make's arguments for one combination."""
    overrides = {"solver": {"string": string}}
    if string == "implicit":  # quadrotor_load's elements: auto takes the explicit string
        overrides["string"] = {"elements": 8}
    if hook:
        overrides["pivot"] = {"drone": {"rho_q": HOOK}}
    if damped:
        overrides["string"] = {**overrides.get("string", {}), "damping_time": 1e-3}
    return {"scene": "quadrotor_load" if pivot == "drone" else "drone_load", "task": "lift" if winch else "stabilize",
            "winch": winch, "scene_overrides": overrides, "disable_env_checker": True}


# a point pivot has no hook; a scene refuses a damped string at a drone's offset hook before any rig
# is asked (tests/test_damping.py)
COMBINATIONS = [c for c in itertools.product(("point", "drone"), ("explicit", "implicit"), (False, True), (False, True),
                                             (False, True))
                if (c[0] == "drone" or not c[3]) and not (c[3] and c[4])]


@pytest.mark.parametrize("combination", COMBINATIONS, ids=["-".join(map(str, c)) for c in COMBINATIONS])
def test_a_combination_is_its_rig_or_refused_by_the_table(combination):
    pivot, string, winch, hook, damped = combination
    rigs = [r for r in RIGS if (r.pivot, r.string, r.winch, r.hook, r.damper) == combination and not r.team]
    if not rigs:
        with pytest.raises(ValueError, match=r"no rig is .*; the rigs are point-explicit, .* \(esp_gym\.rigs\(\)\)$"):
            gym.make(esp_gym.ENV_ID, **options(*combination))
        return
    control = gym.make(esp_gym.ENV_ID, **options(*combination)).unwrapped.control
    assert control.rig is rigs[0] and find_rig(*combination[:4], damped=damped) is rigs[0]
    # its structs as the entry points take them, in STRUCTS' order
    assert list(control.rig.structs) == [s for s in STRUCTS if s in control.rig.structs]
    assert control.rig.entries.step is not None


def test_every_rig_steps_one_environment_and_a_batch_through_its_one_call_site():
    """Each rig's single step and batched step (its first sub-environment) from one seed give one
    observation, bit for bit."""
    for rig in (r for r in RIGS if not r.team):  # a team's: tests/test_team_env.py
        kwargs = options(rig.pivot, rig.string, rig.winch, rig.hook, rig.damper)
        kwargs.pop("disable_env_checker")
        env = gym.make(esp_gym.ENV_ID, disable_env_checker=True, **kwargs)
        vec = gym.make_vec(esp_gym.ENV_ID, num_envs=2, **kwargs)
        obs, _ = env.reset(seed=5)
        vobs, _ = vec.reset(seed=[5, 6])
        np.testing.assert_array_equal(vobs[0], obs)
        action = np.full(env.action_space.shape, 0.1)
        for _ in range(3):
            obs, *_ = env.step(action)
            vobs, *_ = vec.step(np.stack([action, -action]))
        np.testing.assert_array_equal(vobs[0], obs, err_msg=rig.name)
        assert not np.array_equal(vobs[1], obs)  # negative control: another action, another state


def test_the_docs_quote_the_rig_table():
    table = esp_gym.rigs()
    text = DOCS.read_text()
    assert table in text
    assert table.replace("drone-explicit-winch", "drone-implicit-winch") not in text  # the check can fail


def test_each_rigs_entry_points_are_named_after_it():
    """A rig's entry points are the module-level name of its name in its pivot's module (grep
    ``point_implicit_winch``), and every EntryPoints there is a rig's."""
    import importlib

    from esp_gym.kernels.env.step import EntryPoints
    from esp_gym.physics.rig import ENTRY_MODULES, Rig

    for kind, module in ENTRY_MODULES.items():
        found = {name for name, value in vars(importlib.import_module(module, "esp_gym")).items()
                 if isinstance(value, EntryPoints)}
        assert found == {r.name.replace("-", "_") for r in RIGS if r.compiled
                         and (r.team if kind == "team" else r.pivot == kind and not r.team)}, kind
    for rig in RIGS:
        assert rig.compiled == (rig.entries is not None)
        if rig.compiled:
            assert isinstance(rig.entries, EntryPoints) and rig.entries.step is not None and rig.entries.batch
    with pytest.raises(AttributeError, match="point_explicit_offset_hook"):  # negative control: no such rig
        Rig("point", "explicit", False, True, ("state",)).entries


def team_argument(pivot: str, string: str, hook: bool):
    """A team of two strings of ``pivot``'s kind, its lead string's scheme ``string``, its drones
    carrying their strings off their centres of mass if ``hook``, as the ``team`` argument takes it
    (the data, validated where the team is made)."""
    team = team_scene(2, drones=pivot == "drone")
    data = team.model_dump()
    data["scene"]["solver"]["string"] = string
    if hook:
        data["scene"]["pivot"]["drone"]["rho_q"] = HOOK
    return data


TEAM_COMBINATIONS = [c[:4] for c in COMBINATIONS if not c[4]]


@pytest.mark.parametrize("combination", TEAM_COMBINATIONS, ids=["-".join(map(str, c)) for c in TEAM_COMBINATIONS])
def test_a_team_combination_is_its_rig_or_refused_by_the_table(combination):
    """ElasticStringTeam-v0's rig is resolved once from the table: a compiled rig steps through
    its entry points (a control), the winch's in Python; any other combination is refused, whether
    by the team's scene or by the environment's options, with the table's one message."""
    pivot, string, winch, hook = combination
    rigs = [r for r in RIGS if (r.pivot, r.string, r.winch, r.hook) == combination and r.team]
    options = {"task": "lift" if winch else "transport", "winch": winch,
               "actuation": "thrust_rates" if pivot == "drone" else "force"}
    if not rigs:
        with pytest.raises(ValueError, match=r"ElasticStringTeam-v0: no rig is team-.*; the rigs are "
                                             r"team-point-explicit, .* \(esp_gym\.rigs\(\)\)"):
            TeamScene.model_validate(team_argument(pivot, string, hook))
            gym.make(esp_gym.TEAM_ENV_ID, team=2 if string == "explicit" and not hook else None,
                     disable_env_checker=True, **options)
        return
    core = gym.make(esp_gym.TEAM_ENV_ID, team=TeamScene.model_validate(team_argument(pivot, string, hook)),
                    disable_env_checker=True, **options).unwrapped.core
    assert core.rig is rigs[0] and find_rig(*combination, team=True) is rigs[0]
    assert (core.control is not None) == rigs[0].compiled == (rigs[0].entries is not None)
    assert list(core.rig.structs) == [s for s in STRUCTS if s in core.rig.structs]


def test_a_team_batch_steps_through_its_rigs_batch_entry_point():
    """A vector env of teams calls its rig's batch entry point; a rig without entry points has
    no batch (negative control: a winch team's vector env steps its teams one by one)."""
    vec = gym.make_vec(esp_gym.TEAM_ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", team=2)
    vec.reset(seed=1)
    vec.step(np.zeros(vec.action_space.shape))
    batch = vec.unwrapped.batch
    assert batch._entry is not None and batch.cores[0].rig.entries.batch is not None
    winched = gym.make_vec(esp_gym.TEAM_ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", team=2,
                           task="lift")
    assert winched.unwrapped.batch is None and winched.unwrapped.envs[0].core.rig.entries is None


def test_make_arrays_builds_a_rigs_structs_for_one_env_and_for_a_batch():
    """make_arrays: one environment's structs are its simulator's live arrays; a batch's are the
    same structs stacked, the constants the scene's in every row, the state zeros (set at reset);
    the names are the rig table's."""
    from esp_gym.scene.params import load_scene
    from esp_gym.physics.rig_arrays import RigArrays, make_arrays

    assert set(RigArrays._fields) - {"sim"} <= set(STRUCTS)
    scene = load_scene("quadrotor_load")
    one = make_arrays(scene)
    assert one.state is one.sim.buffers.state and one.hook is None and one.drone is one.sim.drone
    batch = make_arrays(scene, 3)
    for name in ("state", "work", "diag", "winch", "drone"):
        for single, stacked in zip(getattr(one, name), getattr(batch, name)):
            assert np.shape(stacked) == (3,) + np.shape(single), name
    for single, stacked in zip(one.params, batch.params):
        assert all(np.array_equal(stacked[b], single) for b in range(3))
    assert not np.any(batch.state.r) and np.any(one.state.r)  # a batch's state waits for its reset
    for single, stacked in zip(one.drone, batch.drone):
        assert np.array_equal(stacked[2], single)
    assert make_arrays(load_scene("drone_load")).drone is None
