"""Sub-environment b of a batch: the row of a struct whose arrays carry a leading batch axis.

A batch holds each struct of one environment (:class:`~.layout.StateArrays`,
:class:`~esp_gym.kernels.env.arrays.EnvArrays`, ...) with every field stacked along a leading (B,) axis (the
constants of :class:`~.layout.LGVIParams` too: a scalar field becomes a (B,) array).
:func:`row_function` writes, from the struct's ``_fields``, the compiled function that takes row
b of each field and rebuilds the struct of one environment (views, and scalars where a field is
(B,)), so a field added to a struct reaches the batched step without another line.
"""
from .jit import kernel


def row_function(struct):
    """The compiled ``row(X, b) -> struct(X.f[b] for f in struct._fields)`` for the namedtuple
    class ``struct``, inlined into its callers. Generated source (not cached on its own: inlined
    before typing, it lives in its callers' cache)."""
    name = struct.__name__.lower() + "_row"
    fields = ", ".join(f"X.{field}[b]" for field in struct._fields)
    namespace = {"struct": struct}
    exec(f"def {name}(X, b):\n    return struct({fields})\n", namespace)
    row = namespace[name]
    row.__doc__ = f"Sub-environment ``b`` of a stacked :class:`{struct.__name__}` (views; scalars from (B,) fields)."
    return kernel(row, inline="always", cache=False)
