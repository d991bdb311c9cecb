"""Agents for ElasticStringPendulum-v0: SB3 training and evaluation, classical baselines.

Run from the repository root as modules: ``python -m agents.train``, ``python -m agents.evaluate``,
``python -m agents.compare``, ``python -m agents.tune`` (``--help`` for the options of each).
"""
