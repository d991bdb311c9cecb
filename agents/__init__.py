"""Agents for ElasticStringPendulum-v0: SB3 training and evaluation, classical baselines, and
training on a Ray cluster (the subpackage agents.distributed, the ``ray`` extra).

Run from the repository root as modules: ``python -m agents.train``, ``python -m agents.evaluate``,
``python -m agents.compare``, ``python -m agents.zoo``, ``python -m agents.baselines.gain_search``, ``python -m agents.distributed.train``,
``python -m agents.distributed.sweep`` (``--help`` for the options of each).
"""
from pathlib import Path

#: The repository root, and where the agents' configs live (light: no import of torch or SB3).
ROOT = Path(__file__).resolve().parent.parent
CONFIG_DIR = ROOT / "configs" / "agents"
