"""The wheel installed the way a user installs it: built from this checkout, installed into a new
virtual environment outside the repository (its pip resolving the requirements; torch from
constraints.txt), and used from a process whose working directory is outside the repository, so
nothing of the checkout is on its path. First the core only: the environments step, their scenes
and the agents' data are the installed copies, torch is absent and the extras' features say which
extra they need. Then PettingZoo's tests at the low end of the team extra's range, then the agents
extra: a shipped policy and its baseline play an episode each.

Each phase's seconds are printed (``-s``). The installed package finds its kernel cache beside its
sources (checked apart); the phases that step environments are pointed (``NUMBA_CACHE_DIR``) at
the checkout's cache, whose machine code the same sources installed elsewhere load
(esp_gym/kernels/jit.py, ``PackageCacheLocator``), instead of compiling it all again.
"""
import json
import math
import os
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from esp_gym.kernels import jit

ROOT = Path(__file__).resolve().parent.parent
#: What the wheel is built from (pyproject.toml's sources and data), copied apart first: setuptools'
#: build/ directory keeps files removed from the tree, and the checkout stays as it is.
SOURCES = ("pyproject.toml", "README.md", "esp_gym", "agents", "configs", "models")
#: The low end of the team extra's PettingZoo range (pyproject.toml).
PETTINGZOO_LOW = "1.23.0"
#: Seconds of each phase, printed at the end of each test.
TIMES = {}


#: The checkout's kernel cache, as NUMBA_CACHE_DIR: its parent (None: the checkout has none).
SHARED_CACHE = None if jit.CACHE_DIR is None else os.path.dirname(jit.CACHE_DIR)


def timed(phase: str, argv: list, cwd: Path, timeout: float = 600, shared_cache: bool = False) -> str:
    """Run ``argv`` in ``cwd`` with the checkout off the path, and with the checkout's kernel cache if
    ``shared_cache``; its stdout, or a failure with its output."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "NUMBA_CACHE_DIR")}
    if shared_cache and SHARED_CACHE is not None:
        env["NUMBA_CACHE_DIR"] = SHARED_CACHE
    start = time.perf_counter()
    done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    TIMES[phase] = round(time.perf_counter() - start, 1)
    assert done.returncode == 0, f"{phase}: {done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def report():
    print("wheel test phases [s]:", json.dumps(TIMES))


#: pip install into the new environment, torch pinned by constraints.txt; --no-compile, as the
#: Makefile: modules are byte-compiled when first imported (torch 20 -> 8 s).
PIP_INSTALL = ["-m", "pip", "install", "-q", "--no-compile", "-c", str(ROOT / "constraints.txt")]


@pytest.fixture(scope="module")
def install(tmp_path_factory):
    """``(python, wheel, work)``: the new environment's interpreter with the core installed from the
    wheel, the wheel, and a working directory outside the repository."""
    base = tmp_path_factory.mktemp("wheel")
    assert ROOT not in base.parents
    source = base / "source"
    source.mkdir()
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            shutil.copy2(ROOT / name, source / name)
    timed("build", [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(base / "dist"), str(source)], base)
    wheel, = (base / "dist").glob("esp_gym-*.whl")
    timed("venv", [sys.executable, "-m", "venv", str(base / "venv")], base)
    python = base / "venv" / "bin" / "python"
    timed("core install", [str(python), *PIP_INSTALL, str(wheel)], base)
    work = base / "work"
    work.mkdir()
    return python, wheel, work


def test_the_wheel_holds_the_packages_and_their_data(install):
    _, wheel, _ = install
    names = set(zipfile.ZipFile(wheel).namelist())
    shipped = {f"esp_gym/scenes/{p.name}" for p in (ROOT / "esp_gym" / "scenes").glob("*.yaml")}
    shipped |= {f"agents/configs/{p.name}" for p in (ROOT / "configs" / "agents").glob("*.yaml")}
    shipped |= {f"agents/models/{p.relative_to(ROOT / 'models').as_posix()}" for p in (ROOT / "models").rglob("*")
                if p.is_file()}
    sources = {p.relative_to(ROOT).as_posix() for top in ("esp_gym", "agents") for p in (ROOT / top).rglob("*.py")
               if "__pycache__" not in p.parts}
    assert shipped - names == set() and sources - names == set()
    assert {"esp_gym/scenes/quadrotor_load.yaml", "agents/configs/zoo.yaml", "agents/models/stabilize_ppo/model.zip",
            "agents/models/team3_transport_hard_rllib/checkpoint/residual.json"} <= names
    data = {n for n in names if not n.endswith(".py") and ".dist-info/" not in n}
    assert data == shipped  # nothing else: no caches, no stray files
    print(f"wheel: {len(names)} files, {wheel.stat().st_size / 1e6:.1f} MB")


CORE = """
import importlib.metadata as md, json, sys, sysconfig, time
import gymnasium as gym, numpy as np
import agents, esp_gym, esp_gym.team

site = sysconfig.get_paths()["purelib"]
out = {"esp_gym": esp_gym.__file__.startswith(site), "agents": str(agents.CONFIG_DIR).startswith(site),
       "data": (agents.CONFIG_DIR / "zoo.yaml").is_file() and (agents.MODELS / "stabilize_ppo" / "model.zip").is_file(),
       "scenes": esp_gym.available_scenes(), "installed": sorted(d.metadata["Name"].lower().replace("-", "_") for d in md.distributions()),
       "sys.path": [p for p in sys.path if p.startswith(sys.argv[1])]}
for name, make in (("plain", {"id": esp_gym.ENV_ID}), ("drone", {"id": esp_gym.ENV_ID, "scene": "quadrotor_load"}),
                   ("team", {"id": esp_gym.TEAM_ENV_ID})):
    start = time.perf_counter()
    env = gym.make(**make)
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    out[name] = {"finite": bool(np.all(np.isfinite(obs)) and np.isfinite(reward)), "seconds": time.perf_counter() - start}
try:
    esp_gym.team.parallel_env(team=3)
except ImportError as err:
    out["team extra"] = str(err)
print(json.dumps(out))
"""


CACHE_LOCATION = """
import os, sysconfig
from esp_gym.kernels import jit
print(os.path.relpath(jit.CACHE_DIR, sysconfig.get_paths()["purelib"]))
"""


def test_the_installed_package_keeps_its_kernel_cache_beside_its_sources(install):
    """Named after its sources' hash, the same as the checkout's: what lets the phases below share
    the checkout's cache."""
    python, _, work = install
    where = timed("cache location", [str(python), "-c", CACHE_LOCATION], work).split()[-1]
    assert where == os.path.join("esp_gym", "kernels", "__pycache__", os.path.basename(jit.CACHE_DIR))


def test_the_core_install_steps_the_environments_without_torch(install):
    python, _, work = install
    out = json.loads(timed("core steps", [str(python), "-c", CORE, str(ROOT)], work, shared_cache=True).splitlines()[-1])
    assert out["esp_gym"] and out["agents"] and out["data"] and out["sys.path"] == []
    assert out["scenes"] == sorted(p.stem for p in (ROOT / "esp_gym" / "scenes").glob("*.yaml"))
    assert all(out[name]["finite"] for name in ("plain", "drone", "team"))
    for first in ("plain", "drone", "team"):
        TIMES[f"core steps: {first}"] = round(out[first]["seconds"], 1)
    assert "esp_gym" in out["installed"]
    assert not {"torch", "stable_baselines3", "rerun_sdk", "pettingzoo", "matplotlib"} & set(out["installed"])
    assert out["team extra"] == "esp_gym.team.parallel_env needs PettingZoo: pip install 'esp_gym[team]'"
    report()


PETTINGZOO_TESTS = """
import importlib.metadata as md
from pettingzoo.test import parallel_api_test, parallel_seed_test
import esp_gym.team
parallel_api_test(esp_gym.team.parallel_env(team=3), num_cycles=30)
parallel_seed_test(lambda: esp_gym.team.parallel_env(team=3))
print(md.version("pettingzoo"))
"""


def test_the_team_extras_lowest_pettingzoo_passes_its_api_and_seed_tests(install):
    python, wheel, work = install
    timed("team install", [str(python), *PIP_INSTALL, f"{wheel}[team]", f"pettingzoo=={PETTINGZOO_LOW}"], work)
    assert timed("team tests", [str(python), "-c", PETTINGZOO_TESTS], work,
                 shared_cache=True).splitlines()[-1] == PETTINGZOO_LOW
    report()


AGENTS = """
import importlib.metadata as md, subprocess, sys
print(md.version("torch"))
subprocess.run([sys.executable, "-m", "agents.zoo", "--list", "--only", "stabilize"], check=True)
"""


def test_the_agents_extra_installs_torch_from_the_constraints_and_runs_the_agents(install):
    python, wheel, work = install
    timed("agents install", [str(python), *PIP_INSTALL, f"{wheel}[agents]"], work)
    lines = timed("agents zoo --list", [str(python), "-c", AGENTS], work).splitlines()
    assert lines[0] == "2.13.0+cpu" and lines[1].startswith("stabilize: python -m agents.train")
    report()


ZOO = """
import json
import esp_gym.zoo

assert "stabilize_ppo" in esp_gym.zoo.names()
env = esp_gym.zoo.make("stabilize_ppo")
returns = {}
for name, policy in (("policy", esp_gym.zoo.load("stabilize_ppo", env)), ("baseline", esp_gym.zoo.baseline("stabilize_ppo", env))):
    obs, _ = env.reset(seed=0)
    total, done = 0.0, False
    while not done:
        obs, reward, terminated, truncated, _ = env.step(policy.predict(obs, deterministic=True)[0])
        total, done = total + reward, terminated or truncated
    returns[name] = total
print(json.dumps(returns))
"""


def test_a_shipped_policy_and_its_baseline_play_an_episode_from_the_install(install):
    """From the install with the agents extra: a shipped policy by name and its base controller
    fly the documented configuration's episode; the residual is worth something (the policy's
    return is not the base's)."""
    python, _, work = install
    returns = json.loads(timed("zoo episodes", [str(python), "-c", ZOO], work, shared_cache=True).splitlines()[-1])
    assert set(returns) == {"policy", "baseline"} and all(math.isfinite(v) for v in returns.values())
    assert returns["policy"] != returns["baseline"] and returns["policy"] > 400.0
    report()
