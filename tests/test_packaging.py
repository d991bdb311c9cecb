"""The distribution's shape, in the checkout: a light core (the environments import and step with
every extra absent), one clear error per missing extra (esp_gym/extras.py), a package list that
holds every package of the tree, and the agents' data found where agents/__init__.py says.
tests/test_wheel.py checks the same from an installed wheel."""
import importlib
import subprocess
import sys
import tomllib
from importlib.metadata import packages_distributions
from pathlib import Path

import pytest

import agents
import esp_gym.team
from esp_gym.extras import EXTRAS, require

ROOT = Path(__file__).resolve().parent.parent
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
OPTIONAL = PYPROJECT["project"]["optional-dependencies"]


def requirement_name(requirement: str) -> str:
    """The distribution a requirement names, normalised (``rerun-sdk==0.41.0`` -> ``rerun_sdk``)."""
    for stop in "[<>=!~; ":
        requirement = requirement.split(stop)[0]
    return requirement.lower().replace("-", "_")


def blocked(monkeypatch, *modules):
    """Make ``modules`` impossible to import (as if not installed) and forget what imported them."""
    for name in list(sys.modules):
        if name.split(".")[0] in modules:
            monkeypatch.delitem(sys.modules, name)
    for name in modules:
        monkeypatch.setitem(sys.modules, name, None)


def test_require_names_the_extra_of_a_missing_module(monkeypatch):
    assert require("pettingzoo", "esp_gym.team.parallel_env").__name__ == "pettingzoo"  # negative control: present
    blocked(monkeypatch, "pettingzoo")
    with pytest.raises(ImportError) as err:
        require("pettingzoo", "esp_gym.team.parallel_env")
    assert str(err.value) == "esp_gym.team.parallel_env needs PettingZoo: pip install 'esp_gym[team]'"


def test_require_names_the_extra_of_a_missing_dependency_and_passes_other_failures_on(monkeypatch, tmp_path):
    """A module that is there but imports an extra's absent module (SB3 without torch) names that
    extra; a module that is no extra's is raised as it is."""
    (tmp_path / "uses_torch.py").write_text("import torch\n")
    monkeypatch.syspath_prepend(tmp_path)
    blocked(monkeypatch, "torch")
    with pytest.raises(ImportError, match=r"^a feature needs PyTorch: pip install 'esp_gym\[agents\]'$"):
        require("uses_torch", "a feature")
    with pytest.raises(ModuleNotFoundError, match="no_such_module"):
        require("no_such_module", "a feature")


@pytest.mark.parametrize("feature, missing, extra", [
    ("esp_gym.pendulum.sb3_vector", "stable_baselines3", "agents"),
    ("esp_gym.viz.recording", "rerun", "record"),
    ("esp_gym.team.recording", "rerun", "record"),
    ("esp_gym.viz.figures", "matplotlib", "plot"),
])
def test_a_module_of_an_extra_says_which_extra_it_needs(monkeypatch, feature, missing, extra):
    monkeypatch.delitem(sys.modules, feature, raising=False)
    blocked(monkeypatch, missing)
    with pytest.raises(ImportError, match=rf"^{feature} needs .*: pip install 'esp_gym\[{extra}\]'$"):
        importlib.import_module(feature)


def test_the_team_parallel_env_says_it_needs_the_team_extra(monkeypatch):
    monkeypatch.delitem(sys.modules, "esp_gym.team.parallel", raising=False)
    monkeypatch.delattr(esp_gym.team, "parallel", raising=False)
    blocked(monkeypatch, "pettingzoo")
    with pytest.raises(ImportError) as err:
        esp_gym.team.parallel_env(team=3)
    assert str(err.value) == "esp_gym.team.parallel_env needs PettingZoo: pip install 'esp_gym[team]'"


def test_the_environments_step_with_every_extra_absent():
    """The core: the plain env, the drone's scene and the team's Gymnasium env, in a process where
    no module of an extra can be imported (kernels from the suite's cache)."""
    code = (f"import sys\nfor m in {sorted(EXTRAS) + ['ray']!r}: sys.modules[m] = None\n"
            "import gymnasium as gym, esp_gym\n"
            "for make in ({'id': esp_gym.ENV_ID}, {'id': esp_gym.ENV_ID, 'scene': 'quadrotor_load'},"
            " {'id': esp_gym.TEAM_ENV_ID}):\n"
            "    env = gym.make(**make); env.reset(seed=0); env.step(env.action_space.sample())\n"
            "print('stepped')\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert done.returncode == 0 and done.stdout.strip() == "stepped", done.stderr[-2000:]


def test_the_core_needs_no_extras_module():
    """No distribution that an extra stands for is a core dependency, and each extra EXTRAS names
    exists (pyproject.toml)."""
    core = {requirement_name(r) for r in PYPROJECT["project"]["dependencies"]}
    of_extras = {requirement_name(d) for m in EXTRAS for d in packages_distributions().get(m, [])}
    assert of_extras and core & of_extras == set()
    assert {extra for extra, _ in EXTRAS.values()} <= set(OPTIONAL)
    # negative control: matplotlib as a core dependency would be found
    assert {requirement_name("matplotlib>=3.8")} & of_extras == {"matplotlib"}


def test_the_package_list_holds_every_package_of_the_tree():
    listed = set(PYPROJECT["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for top in ("esp_gym", "agents")
             for p in (ROOT / top).rglob("__init__.py")}
    mapped = set(PYPROJECT["tool"]["setuptools"]["package-dir"])  # data directories mapped into agents
    assert listed == found | mapped
    assert all((ROOT / directory).is_dir() for directory in PYPROJECT["tool"]["setuptools"]["package-dir"].values())


def test_the_agents_data_is_the_checkouts_in_a_checkout():
    assert not agents.INSTALLED and agents.ROOT == ROOT
    assert agents.CONFIG_DIR == ROOT / "configs" / "agents" and (agents.CONFIG_DIR / "zoo.yaml").is_file()
    assert agents.MODELS == ROOT / "models" and (agents.MODELS / "stabilize_ppo" / "model.zip").is_file()


def test_the_zoo_says_it_needs_the_agents_extra(monkeypatch):
    """esp_gym.zoo imports (it is the core's), and its first use without SB3 names the extra."""
    import esp_gym.zoo

    blocked(monkeypatch, "stable_baselines3")
    with pytest.raises(ImportError) as err:
        esp_gym.zoo.names()
    assert str(err.value) == "esp_gym.zoo needs Stable-Baselines3: pip install 'esp_gym[agents]'"
