"""Compiled kernels (numba, ``@njit`` only): flat float64 arrays in, status codes out.

numba's on-disk cache (``cache=True``) checks only the modification time of the file that
defines a function, so a kernel that calls into an edited sibling file would load stale machine
code. The cache therefore lives in a directory named after a hash of every kernel source file:
any edit here starts a fresh cache. Its base is the first writable one of ``$NUMBA_CACHE_DIR``,
this package's ``__pycache__``, ``$XDG_CACHE_HOME/esp_gym``, ``~/.cache/esp_gym`` and the
temporary directory; with none writable the kernels compile without a cache, with a warning
(``jit.choose_cache_dir``). ``jit.kernel`` sets it for every kernel, including those compiled
later (the specialised step kernels of step/specialise.py).

The base modules here are what every kernel shares (jit.py, layout.py, rows.py, status.py,
sums.py, so3.py, stability.py, tolerance.py); the subpackages hold the string's step family
(step/), the drone's (drone/), the team's (team/) and the single environment's control step
(env/). docs/architecture.md names every module and what it holds. Importing this package compiles
nothing: each module compiles its kernels on first call (or loads them from the cache).
"""
from .jit import CACHE_DIR  # noqa: F401
