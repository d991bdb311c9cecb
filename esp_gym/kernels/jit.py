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
import contextlib
import hashlib
import os
import re
import shutil
import sys
import tempfile
import warnings
from pathlib import Path

import numba
from llvmlite import ir
from numba import njit, types
from numba.core import caching, cgutils, event
from numba.core.registry import CPUDispatcher
from numba.extending import intrinsic

try:
    import fcntl
except ImportError:  # not POSIX: saves are not serialised, the key check below still holds
    fcntl = None

_HERE = Path(__file__).resolve().parent
#: Every kernel source, in the subpackages too, by its place in the package and its bytes.
_SOURCES = sorted(p for p in _HERE.rglob("*.py") if "__pycache__" not in p.parts)
_DIGEST = hashlib.sha256(b"".join(p.relative_to(_HERE).as_posix().encode() + b"\0" + p.read_bytes()
                                  for p in _SOURCES)).hexdigest()[:16]


def writable_dir(path: str) -> bool:
    """Whether the directory ``path`` exists or can be made, and a file can be created in it
    (``os.access`` is not enough: it says yes to root on a read-only mount)."""
    try:
        os.makedirs(path, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".esp_gym-probe-")
        os.close(fd)
        os.unlink(probe)
        return True
    except OSError:
        return False


def cache_candidates(environ=os.environ, package_dir: Path = _HERE) -> list:
    """Where the kernel cache may live, in order of preference: ``(what, base directory)``."""
    candidates = []
    if environ.get("NUMBA_CACHE_DIR"):
        candidates.append(("NUMBA_CACHE_DIR", environ["NUMBA_CACHE_DIR"]))
    candidates.append(("the package directory", str(package_dir / "__pycache__")))
    if environ.get("XDG_CACHE_HOME"):
        candidates.append(("XDG_CACHE_HOME", os.path.join(environ["XDG_CACHE_HOME"], "esp_gym")))
    home = environ.get("HOME")
    if not home:
        try:
            home = str(Path.home())
        except (RuntimeError, KeyError):  # no home directory at all
            home = None
    if home:
        candidates.append(("the home directory", os.path.join(home, ".cache", "esp_gym")))
    user = str(os.getuid()) if hasattr(os, "getuid") else "user"
    temp = environ.get("TMPDIR") or tempfile.gettempdir()
    candidates.append(("the temporary directory", os.path.join(temp, f"esp_gym-cache-{user}")))
    return candidates


#: Cache directories of other kernel sources kept beside the current one (the most recently
#: written first): enough to switch between a few checkouts without recompiling, not a pile.
KEEP_STALE = 2
_CACHE_NAME = re.compile(r"esp_gym-kernels-[0-9a-f]{16}")


def prune_stale_caches(current: str, keep: int = KEEP_STALE) -> list:
    """Remove the kernel cache directories beside ``current`` that belong to other kernel sources
    (``esp_gym-kernels-<hash>``), all but the ``keep`` most recently modified. Returns the paths
    removed; one that cannot be removed (in use, permissions) is left."""
    base, name = os.path.split(current)
    try:
        others = [e for e in os.scandir(base) if e.is_dir(follow_symlinks=False) and e.name != name
                  and _CACHE_NAME.fullmatch(e.name)]
    except OSError:
        return []
    others.sort(key=lambda e: e.stat(follow_symlinks=False).st_mtime, reverse=True)
    removed = []
    for entry in others[keep:]:
        try:
            shutil.rmtree(entry.path)
            removed.append(entry.path)
        except OSError:
            pass
    return removed


def choose_cache_dir(environ=os.environ, package_dir: Path = _HERE) -> tuple:
    """``(cache directory or None, warning or None)``: the first writable candidate of
    :func:`cache_candidates`, in a subdirectory named after the kernel sources' hash. None when
    nothing is writable: the kernels then compile without a cache (every process compiles)."""
    skipped = []
    for what, base in cache_candidates(environ, package_dir):
        path = os.path.join(base, f"esp_gym-kernels-{_DIGEST}")
        if writable_dir(path):
            warning = None
            if skipped and (skipped[0] == "NUMBA_CACHE_DIR" or what == "the temporary directory"):
                warning = (f"esp_gym: cannot write the kernel cache in {', '.join(skipped)}; using {path} "
                           f"(set NUMBA_CACHE_DIR or XDG_CACHE_HOME to a writable directory)")
            return path, warning
        skipped.append(what)
    return None, ("esp_gym: no writable directory for the kernel cache (tried " + ", ".join(skipped) +
                  "); kernels compile in every process. Set NUMBA_CACHE_DIR to a writable directory.")


def package_path(source: str) -> str:
    """The directory of the file ``source`` as a package path (``esp_gym/kernels``): its parents
    up to the first one that is not a package (no ``__init__.py``), the directory on sys.path."""
    directory = Path(source).resolve().parent
    parts = []
    while (directory / "__init__.py").is_file() and directory.parent != directory:
        parts.append(directory.name)
        directory = directory.parent
    return "/".join(reversed(parts)) or Path(source).resolve().parent.name


class PackageCacheLocator(caching.UserProvidedCacheLocator):
    """numba's locator for a cache directory it is given, with each source's subdirectory named
    after its package path instead of its place on disk. The same sources, installed elsewhere (a
    wheel in a virtual environment, another clone), then find the machine code compiled for them:
    the directory's name already holds the hash of every kernel source, and numba checks each
    file's own hash too."""

    @classmethod
    def get_suitable_cache_subpath(cls, py_file):
        package = package_path(py_file)
        return package.replace("/", "_") + "_" + hashlib.sha1(package.encode()).hexdigest()[:16]


class KernelCacheFile(caching.IndexDataCacheFile):
    """numba's cache file (an index of overloads by key, a data file per overload), safe for
    processes that save overloads of one kernel at the same moment (the two workers of
    ``esp-gym compile``, pytest's workers, a user's vector env subprocesses).

    numba's own ``save`` reads the index, takes the first data file the index does not name,
    writes the index and then the data, with nothing held in between: two processes saving two
    overloads (the entry points of two rigs are closures of one function) both took the same data
    file, and the index could name one overload's machine code for the other's key, which then
    ran another rig's physics. Here a save holds an exclusive lock on the cache directory's
    ``.lock`` file from reading the index to writing the data, and each data file holds its key,
    which a load checks: a mismatch is a miss (a compile), never another overload's code."""

    def save(self, key, data):
        with self._saving():
            super().save(key, (key, data))

    def load(self, key):
        stored = super().load(key)
        if isinstance(stored, tuple) and len(stored) == 2 and stored[0] == key:
            return stored[1]
        return None

    @contextlib.contextmanager
    def _saving(self):
        if fcntl is None:
            yield
            return
        with open(os.path.join(self._cache_path, ".lock"), "ab") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)


class KernelCache(caching.FunctionCache):
    """numba's per-function cache with :class:`KernelCacheFile` (``file_class``) as its file."""

    file_class = KernelCacheFile

    def __init__(self, py_func):
        super().__init__(py_func)
        self._cache_file = self.file_class(cache_path=self._cache_path, filename_base=self._impl.filename_base,
                                           source_stamp=self._impl.locator.get_source_stamp())


#: Where every kernel's compiled code is cached (see esp_gym/kernels/__init__.py); None: no cache.
CACHE_DIR, _CACHE_WARNING = choose_cache_dir()
if _CACHE_WARNING:
    warnings.warn(_CACHE_WARNING, RuntimeWarning, stacklevel=2)
if CACHE_DIR is not None:
    prune_stale_caches(CACHE_DIR)

JIT_OPTIONS = dict(cache=CACHE_DIR is not None, nogil=True, fastmath=False, error_model="numpy", boundscheck=False,
                   _nrt=False, no_cfunc_wrapper=True)


class InternalKernel(CPUDispatcher):
    """A kernel compiled without its CPython wrapper: only kernels call it (see :func:`kernel`).
    Called from Python it raises instead of running code that has no entry for Python."""

    def __call__(self, *args, **kwargs):
        name = f"{self.py_func.__module__}.{self.py_func.__qualname__}"
        raise TypeError(f"{name} is an internal kernel, compiled to be called from kernels only: decorate it "
                        f"with kernel(entry=True) to call it from Python, or call python_callable({name.rsplit('.', 1)[1]})"
                        f"(...) in a test")


def name_closure(f) -> None:
    """Give the closure ``f`` (a kernel a factory compiles once per configuration) a name of its
    own per configuration: ``step`` capturing ``winched=True, implicit=False`` becomes
    ``step__winched1_implicit0``, in its ``__qualname__`` and ``__name__``. numba names a compiled
    function's symbol by its qualified name, its argument types and a counter of the process that
    compiled it. Two configurations compiled in two processes (the workers of ``esp-gym compile``,
    pytest's) could therefore carry one symbol name; a process that loaded both from the cache
    then ran the first one's machine code for both (an environment on the implicit string ran the
    explicit string's step). Closures may capture only bools and ints, which the name spells out."""
    if not f.__closure__:
        return
    parts = []
    for variable, cell in zip(f.__code__.co_freevars, f.__closure__):
        value = cell.cell_contents
        if not isinstance(value, (bool, int)):
            raise TypeError(f"kernel {f.__qualname__} captures {variable}={value!r}: a compiled closure may capture "
                            f"only bools and ints (they name its configuration; pass anything else as an argument)")
        parts.append(f"{variable}{int(value)}")
    suffix = "__" + "_".join(parts)
    f.__qualname__ += suffix
    f.__name__ += suffix


def kernel(fn=None, entry: bool = False, **extra):
    """Compile ``fn`` as an esp_gym kernel (nopython, cached); ``extra`` adds or overrides
    numba options.

    ``entry``: Python calls it (an entry point of the compiled code). Every other kernel is
    compiled without numba's CPython wrapper (``no_cpython_wrapper``), the code that unboxes
    each argument from Python objects: for kernels taking the state's and parameters' named
    tuples that wrapper was a fifth of the first start's compile (docs/performance.md,
    "Start-up"). An internal kernel is an :class:`InternalKernel`, which refuses a call from
    Python (:func:`python_callable` gives a test one that accepts it). ``no_cfunc_wrapper``:
    no kernel is used as a first-class C function, so none is compiled with that wrapper."""
    options = {**JIT_OPTIONS, **extra}
    # inlined into numba's IR, a kernel is compiled on its own only when Python calls it (a test)
    internal = not entry and options.get("inline", "never") == "never"
    if internal:
        options["no_cpython_wrapper"] = True

    def compile_(f):
        name_closure(f)
        # cache=True fixes the cache location when the function is decorated: set ours (the
        # directory and its locator) for that moment, then give numba its settings back.
        previous = numba.config.CACHE_DIR, numba.config.CACHE_LOCATOR_CLASSES
        numba.config.CACHE_DIR = CACHE_DIR or previous[0]
        numba.config.CACHE_LOCATOR_CLASSES = f"{__name__}.{PackageCacheLocator.__name__}" if CACHE_DIR else previous[1]
        try:
            dispatcher = njit(**options)(f)
            if options.get("cache"):
                dispatcher._cache = KernelCache(f)
        finally:
            numba.config.CACHE_DIR, numba.config.CACHE_LOCATOR_CLASSES = previous
        if internal:
            dispatcher.__class__ = InternalKernel
        return dispatcher

    return compile_ if fn is None else compile_(fn)


def python_callable(internal):
    """A copy of the kernel ``internal`` that Python can call, compiled with its CPython wrapper
    and not cached (numba's cache does not key compiled code by that option, and the cached
    internal kernel has no wrapper). For tests: each call compiles anew."""
    if not isinstance(internal, CPUDispatcher):
        raise TypeError(f"python_callable takes a kernel, got {internal!r}")
    if not isinstance(internal, InternalKernel):
        return internal
    options = {key: value for key, value in internal.targetoptions.items() if key != "nopython"}
    options.update(no_cpython_wrapper=False, cache=False)
    return njit(**options)(internal.py_func)


# -- saying that the first start compiles ------------------------------------------------------

#: The entry points whose first compile is long enough to say so: their Python function ->
#: (what compiles, its seconds on the 2-core machine from benchmarks.cold_start).
_ANNOUNCED = {}
_SAID = set()
#: Whether the notice is printed (on standard error).
COMPILE_NOTICE = True


def bound_entry(dispatcher, *args):
    """The machine code of the kernel ``dispatcher`` for the types of ``args`` (loaded from the
    cache, or compiled, now), to be called without numba's type dispatch: its callers pass, at
    every call, arguments of exactly these types (the same arrays, or arrays of the same dtype,
    dimensions, layout and writeability; Python ints, bools and floats where these were). The
    dispatch types every array of every struct at every call: for a team's hundred arrays about
    4 us of a 25 us control step (esp_gym/team/control.py)."""
    return dispatcher.compile(tuple(dispatcher.typeof_pyval(a) for a in args))


def announce_compile(dispatcher, what: str, seconds: float):
    """Register ``dispatcher`` (a kernel) as an entry point whose first compile prints one line,
    once per process, saying what compiles and for about how long (:class:`_CompileNotice`)."""
    _ANNOUNCED[dispatcher.py_func] = (what, seconds)
    return dispatcher


class _CompileNotice(event.Listener):
    """numba's ``numba:compile`` event starts only where no cached code loads: an actual compile."""

    def on_start(self, ev):
        data = ev.data if isinstance(ev.data, dict) else {}
        entry = _ANNOUNCED.get(getattr(data.get("dispatcher"), "py_func", None))
        if entry is None or entry[0] in _SAID or not COMPILE_NOTICE:
            return
        _SAID.add(entry[0])
        where = f"cached in {CACHE_DIR}" if CACHE_DIR else "not cached: every process compiles"
        print(f"esp_gym: compiling {entry[0]} for this machine, first run only (up to about {entry[1]:.0f} s "
              f"on 2 cores; {where})", file=sys.stderr, flush=True)

    def on_end(self, ev):
        pass


event.register("numba:compile", _CompileNotice())


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
