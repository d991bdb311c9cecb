"""Agents for ElasticStringPendulum-v0: SB3 training and evaluation, classical baselines."""
