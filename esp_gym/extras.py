"""The optional parts of esp_gym and the extra that installs each (pyproject.toml,
``[project.optional-dependencies]``). The core (the environments, their scenes and the compiled
physics) needs none of them; a feature that needs one imports it through :func:`require`, which
turns its absence into one ImportError naming the feature and the ``pip install`` that brings it.
"""
from __future__ import annotations

import importlib
from types import ModuleType

#: Top-level module -> (the extra that installs it, its name in the message).
EXTRAS = {
    "matplotlib": ("plot", "Matplotlib"),
    "mpl_toolkits": ("plot", "Matplotlib"),
    "rerun": ("record", "the Rerun SDK"),
    "pyarrow": ("record", "the Rerun SDK"),
    "stable_baselines3": ("agents", "Stable-Baselines3"),
    "torch": ("agents", "PyTorch"),
    "threadpoolctl": ("agents", "threadpoolctl"),
    "pettingzoo": ("team", "PettingZoo"),
    "mujoco": ("bench", "MuJoCo"),
    "moordyn": ("bench", "MoorDyn"),
}


def require(module: str, feature: str) -> ModuleType:
    """``import module`` for ``feature`` (as the message names it, e.g. ``"esp_gym.pendulum.sb3_vector"``).

    A module of an extra that is not installed, ``module`` itself or one it imports (SB3 without
    torch), raises ``ImportError("FEATURE needs NAME: pip install 'esp_gym[EXTRA]'")`` for that
    module's extra; any other failure to import is raised as it is (a broken install is not a
    missing extra).
    """
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as err:
        absent = (err.name or "").partition(".")[0]
        if absent not in EXTRAS:
            raise
        extra, name = EXTRAS[absent]
        raise ImportError(f"{feature} needs {name}: pip install 'esp_gym[{extra}]'") from err
