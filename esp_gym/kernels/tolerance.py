"""Reward shaping: a bounded tolerance of an error (docs/environment.md, "Reward").

Each reward term is a weight times :func:`tolerance` of an error: 1 where the error is 0, 1/2
where it equals the term's scale, falling off as (scale/x)^2 past it, so no term can dominate
the sum however far the state strays and none is ever flat (dm_control's ``rewards.tolerance``
with a Cauchy-shaped sigmoid and no tolerance band).
"""
from .jit import kernel


@kernel
def tolerance(x, scale):
    """1 / (1 + (x / scale)^2), in (0, 1] [-], for an error ``x`` >= 0 and its ``scale`` > 0 (same unit)."""
    q = x / scale
    return 1.0 / (1.0 + q * q)
