"""Compensated sums: every balance and every increment of the state that must not accumulate
round-off over millions of steps goes through :func:`kahan_add` (docs/integrator.md)."""
from .jit import kernel


@kernel
def kahan_add(x, c, i, dx):
    """x[i] += dx with Kahan compensation, the remainder kept in c[i]."""
    y = dx + c[i]
    t = x[i] + y
    c[i] = (x[i] - t) + y
    x[i] = t
