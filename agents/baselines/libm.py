"""Elementwise functions of the C library, for the baselines' arrays.

NumPy's transcendental ufuncs take processor-specific code paths: on an AVX-512 processor
``np.sin``, ``np.exp``, ``np.tan`` and their kin run Intel's SVML (within a few ulp of the C
library, not its bits), elsewhere the C library. A chaotic closed-loop episode grows that last
bit into another return, so a baseline's documented episodes (docs/compare) would hold on one
kind of processor only. These apply Python's ``math`` functions (the C library's, as the compiled
kernels call them) element by element: the same bits on every x86-64 processor. The arrays are
small (a reference's preview, a shaper's impulses), so the Python loop costs microseconds.
"""
from __future__ import annotations

import math

import numpy as np


def _elementwise(f):
    ufunc = np.frompyfunc(f, 1, 1)

    def apply(x) -> np.ndarray:
        return np.asarray(ufunc(np.asarray(x, dtype=np.float64)), dtype=np.float64)

    apply.__name__ = f.__name__
    apply.__doc__ = f"math.{f.__name__} of every element of x, as a float64 array of x's shape."
    return apply


cos = _elementwise(math.cos)
sin = _elementwise(math.sin)
exp = _elementwise(math.exp)
