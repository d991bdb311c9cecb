"""All numba options live here, so every kernel is compiled the same way.

``cache=True`` keeps the second start fast; ``error_model="numpy"`` makes a division by zero give
inf/nan (which the kernels detect and report as a status) instead of raising inside compiled code;
``fastmath`` stays off so results are reproducible bit for bit and round-off is what we analyse.

``_nrt=False`` compiles without numba's runtime. The kernels never allocate (callers pass every
array), so they do not need it, and without it numba emits no reference counting: with it, every
array taken out of a namedtuple (the state, the scratch, the parameters) was an atomic
incref/decref pair in the step loop, about half the time of a step (1.00 -> 0.53 us at N = 20).
Allocating inside a kernel (``np.empty``, slice assignment, ``.copy()``) then fails to compile
("NRT required but not enabled"), which keeps it that way.

Inlining, and what it costs to compile (docs/performance.md, "Start-up"). ``inline="always"``
splices the callee's numba IR into the caller before typing. numba deep-copies that IR, block by
block, and every block's copy re-copies the callee's whole variable table, so the cost grows with
size x blocks and is paid again at every level a big function is inlined through. The LGVI substep
(126 blocks) cost 3-5 s per level, and the env's step, four levels up, took 18-26 s to compile.
``forceinline=True`` instead compiles the callee once per signature (cached on disk like any
kernel) and marks it ``alwaysinline`` for LLVM, which inlines it into every caller: the same
machine code, bit for bit, at a fraction of the compile time. The substep is compiled that way;
small helpers keep ``inline="always"``. numba lets the callees of a ``forceinline`` function
inherit the flag.
"""
import hashlib
import os
from pathlib import Path

import numba
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

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


#: Where every kernel's compiled code is cached (see esp_gym/kernels/__init__.py).
CACHE_DIR = _cache_dir()

JIT_OPTIONS = dict(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False, _nrt=False)


def kernel(fn=None, **extra):
    """Compile ``fn`` as an esp_gym kernel (nopython, cached); ``extra`` adds or overrides
    numba options."""
    options = {**JIT_OPTIONS, **extra}

    def compile_(f):
        # cache=True fixes the cache location when the function is decorated: set ours for
        # that moment, then give numba its setting back.
        previous = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = CACHE_DIR
        try:
            return njit(**options)(f)
        finally:
            numba.config.CACHE_DIR = previous

    return compile_ if fn is None else compile_(fn)


@intrinsic
def _fma_intrinsic(typingctx, a, b, c):
    """LLVM's ``llvm.fma.f64``: ``a * b + c`` with one rounding."""
    if not all(isinstance(t, types.Float) for t in (a, b, c)):
        return None
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        x, y, z = (context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args))
        d = ir.DoubleType()
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(d, [d, d, d]), "llvm.fma.f64")
        return builder.call(fn, [x, y, z])

    return sig, codegen


@kernel(inline="always")
def fma(a, b, c):
    """``a * b + c`` rounded once (IEEE fused multiply-add; correctly rounded on every machine:
    a hardware instruction where there is one, else libm's fma). Used on the latency-bound
    recurrences (the Thomas sweeps), where it halves the dependency chain. fastmath's
    ``contract`` would do this everywhere, but where it fuses depends on the expression's shape,
    so the specialised kernels would no longer equal the general one bit for bit."""
    return _fma_intrinsic(a, b, c)
