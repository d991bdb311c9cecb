"""Compiling code outside the package as the environment's kernels are compiled (no fastmath, the
same error model) and cached beside them: :func:`kernel` is esp_gym/kernels/jit.py's decorator, for
the agents' compiled policy network (agents/mlp.py)."""
from .kernels.jit import kernel

__all__ = ["kernel"]
