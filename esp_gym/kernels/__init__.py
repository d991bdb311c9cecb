"""Compiled kernels (numba, ``@njit`` only): flat float64 arrays in, status codes out.

numba's on-disk cache (``cache=True``) checks only the modification time of the file that
defines a function, so a kernel that calls into an edited sibling file would load stale machine
code. The cache therefore lives in a directory named after a hash of every kernel source file:
any edit here starts a fresh cache. Its base is ``$NUMBA_CACHE_DIR`` if set, else this package's
``__pycache__`` (or ``~/.cache/esp_gym`` where that is not writable).
"""
import hashlib
import os
from pathlib import Path

import numba

_HERE = Path(__file__).resolve().parent
_DIGEST = hashlib.sha256(b"".join(p.read_bytes() for p in sorted(_HERE.glob("*.py")))).hexdigest()[:16]


def _cache_dir() -> str:
    base = os.environ.get("NUMBA_CACHE_DIR")
    if not base:
        base = str(_HERE / "__pycache__")
        try:
            os.makedirs(base, exist_ok=True)
        except OSError:
            base = ""
        if not base or not os.access(base, os.W_OK):
            base = str(Path.home() / ".cache" / "esp_gym")
    return os.path.join(base, f"esp_gym-kernels-{_DIGEST}")


# Decorating with cache=True fixes each function's cache location, so set ours while the
# kernel modules are imported, then give numba its setting back.
_previous = numba.config.CACHE_DIR
numba.config.CACHE_DIR = _cache_dir()
try:
    from . import diagnostics, lgvi, so3, string, task  # noqa: F401,E402
finally:
    numba.config.CACHE_DIR = _previous

CACHE_DIR = _cache_dir()
