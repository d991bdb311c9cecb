"""Agents for ElasticStringPendulum-v0 and the team environments: SB3 training and evaluation,
classical baselines (the subpackage agents.baselines, a team's in agents.baselines.team), training
on a Ray cluster (agents.distributed, the ``ray`` extra) and the teams' agents (agents.team).

Installed with the ``agents`` extra (``pip install 'esp_gym[agents]'``) or run from a checkout, as
modules: ``python -m agents.train``, ``python -m agents.evaluate``, ``python -m agents.compare``,
``python -m agents.zoo``, ``python -m agents.baselines.gain_search``, ``python -m agents.distributed.train``,
``python -m agents.distributed.sweep``, ``python -m agents.team.train``, ``python -m agents.team.sweep``
(``--help`` for the options of each).

The shipped data, the agents' configs and the trained models, is read from the names below and
nowhere else: in a wheel they are package data beside this file (``agents/configs``,
``agents/models``, mapped from the repository's ``configs/agents`` and ``models`` by
pyproject.toml), in a checkout the repository's own directories.
"""
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
#: True when installed from a wheel (the data beside the modules), False in a checkout.
INSTALLED = (PACKAGE / "configs").is_dir()
#: The checkout's root, or the current directory when installed: where the commands write by
#: default (runs/, sweeps/), never into site-packages.
ROOT = Path() if INSTALLED else PACKAGE.parent
#: The agents' configs (ALGO.yaml, zoo.yaml) and the shipped models (NAME_ppo, team3_*_rllib); light:
#: no import of torch or SB3.
CONFIG_DIR = PACKAGE / "configs" if INSTALLED else ROOT / "configs" / "agents"
MODELS = PACKAGE / "models" if INSTALLED else ROOT / "models"
#: The model zoo's file: its recipe and configurations (agents/zoo.py).
ZOO_FILE = CONFIG_DIR / "zoo.yaml"


def zoo_configuration_names(path: Path = ZOO_FILE) -> list:
    """The zoo's configuration names in the file's order, read without checking them (agents/zoo.py
    checks them; benchmarks/quote.py reads them here, so it does not import the zoo's command)."""
    import yaml

    return list(yaml.safe_load(Path(path).read_text())["configurations"])
