"""Compiled kernels (numba, ``@njit`` only): flat float64 arrays in, status codes out.

numba's on-disk cache (``cache=True``) checks only the modification time of the file that
defines a function, so a kernel that calls into an edited sibling file would load stale machine
code. The cache therefore lives in a directory named after a hash of every kernel source file:
any edit here starts a fresh cache. Its base is ``$NUMBA_CACHE_DIR`` if set, else this package's
``__pycache__`` (or ``~/.cache/esp_gym`` where that is not writable). ``_jit.kernel`` sets it for
every kernel, including those compiled later (the specialised step kernels of lgvi.py).
"""
from ._jit import CACHE_DIR  # noqa: F401
from . import diagnostics, lgvi, ode, so3, string, task  # noqa: F401,E402
