"""All numba options live here, so every kernel is compiled the same way.

``cache=True`` keeps the second start fast; ``error_model="numpy"`` makes a division by zero give
inf/nan (which the kernels detect and report as a status) instead of raising inside compiled code;
``fastmath`` stays off so results are reproducible bit for bit and round-off is what we analyse.
"""
from numba import njit

JIT_OPTIONS = dict(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False)


def kernel(fn=None, **extra):
    """Compile ``fn`` as an esp_gym kernel (nopython, cached); ``extra`` adds numba options."""
    if fn is None:
        return lambda f: njit(**JIT_OPTIONS, **extra)(f)
    return njit(**JIT_OPTIONS)(fn)
