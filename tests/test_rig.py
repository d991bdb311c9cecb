"""The rig table (esp_gym/rig.py): every combination of pivot, string scheme, winch and hook is
either a rig, run by that rig's entry points with its structs in the one order, or refused with one
message that names it and lists the rigs; the docs quote the table as it is."""
import itertools
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import esp_gym
from esp_gym.rig import RIGS, STRUCTS, find_rig

DOCS = Path(__file__).resolve().parent.parent / "docs" / "environment.md"
HOOK = [0.0, 0.0, -0.05]


def options(pivot: str, string: str, winch: bool, hook: bool) -> dict:
    """gym.make's arguments for one combination."""
    overrides = {"solver": {"string": string}}
    if hook:
        overrides["pivot"] = {"drone": {"rho_q": HOOK}}
    return {"scene": "quadrotor_load" if pivot == "drone" else "drone_load", "task": "lift" if winch else "stabilize",
            "winch": winch, "scene_overrides": overrides, "disable_env_checker": True}


COMBINATIONS = [c for c in itertools.product(("point", "drone"), ("explicit", "implicit"), (False, True), (False, True))
                if c[0] == "drone" or not c[3]]  # a point pivot has no hook


@pytest.mark.parametrize("combination", COMBINATIONS, ids=["-".join(map(str, c)) for c in COMBINATIONS])
def test_a_combination_is_its_rig_or_refused_by_the_table(combination):
    pivot, string, winch, hook = combination
    rigs = [r for r in RIGS if (r.pivot, r.string, r.winch, r.hook) == combination]
    if not rigs:
        with pytest.raises(ValueError, match=r"no rig is .*; the rigs are point-explicit, .* \(esp_gym\.rigs\(\)\)$"):
            gym.make(esp_gym.ENV_ID, **options(*combination))
        return
    control = gym.make(esp_gym.ENV_ID, **options(*combination)).unwrapped.control
    assert control.rig is rigs[0] and find_rig(*combination) is rigs[0]
    # its structs as the entry points take them, in STRUCTS' order
    assert list(control.rig.structs) == [s for s in STRUCTS if s in control.rig.structs]
    assert control.rig.entries.step is not None


def test_every_rig_steps_one_environment_and_a_batch_through_its_one_call_site():
    """Each rig's single step and batched step (its first sub-environment) from one seed give one
    observation, bit for bit."""
    for rig in RIGS:
        kwargs = options(rig.pivot, rig.string, rig.winch, rig.hook)
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

    from esp_gym.kernels.env_step import EntryPoints
    from esp_gym.rig import ENTRY_MODULES, Rig

    for pivot, module in ENTRY_MODULES.items():
        found = {name for name, value in vars(importlib.import_module(module, "esp_gym")).items()
                 if isinstance(value, EntryPoints)}
        assert found == {r.name.replace("-", "_") for r in RIGS if r.pivot == pivot}, pivot
    for rig in RIGS:
        assert isinstance(rig.entries, EntryPoints) and rig.entries.step is not None
    with pytest.raises(AttributeError, match="point_explicit_offset_hook"):  # negative control: no such rig
        Rig("point", "explicit", False, True, ()).entries
