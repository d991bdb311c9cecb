"""Processes that save overloads of one kernel at the same moment each load their own machine code
(kernels/jit.py, KernelCacheFile). Not a serial module: the race is ordered by marker files, not by
the clock, so another worker's load cannot change its outcome."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

#: A kernel with two overloads (for float64 and float32 arrays: its itemsize, 8 or 4), and
#: hooks on a cache file class that order two processes' saves through marker files: the first
#: process (0) reads the index, the second (1) reads it too, 0 writes the index, 1 writes the index
#: and its data, and 0 writes its data last. Under a lock held across a save the other process
#: cannot move, so each wait ends at its timeout (short then) and the saves simply follow each other.
RACING = '''
import os, time
import numpy as np
from esp_gym.kernels.jit import kernel

def call(which):
    # decorated here, after the caller chose the cache file class
    @kernel(entry=True)
    def itemsize(x):
        return x.itemsize
    return itemsize(np.zeros(1, np.float64 if which == 0 else np.float32))

def order(cls, which, folder, timeout):
    def wait(name):
        deadline = time.monotonic() + timeout
        while not os.path.exists(os.path.join(folder, name)) and time.monotonic() < deadline:
            time.sleep(0.01)
    def mark(name):
        open(os.path.join(folder, name), "w").close()
    save_index, save_data = cls._save_index, cls._save_data
    def index(self, overloads):
        if which == 0:
            wait("1-read-the-index")
            save_index(self, overloads)
            mark("0-wrote-the-index")
        else:
            mark("1-read-the-index")
            wait("0-wrote-the-index")
            save_index(self, overloads)
    def data(self, name, payload):
        if which == 0:
            wait("1-wrote-its-data")
        save_data(self, name, payload)
        if which == 1:
            mark("1-wrote-its-data")
    cls._save_index, cls._save_data = index, data
'''

RACE = '''
import contextlib, sys; from numba.core import caching; import racing; from esp_gym.kernels import jit
which, mode, folder = int(sys.argv[1]), sys.argv[2], sys.argv[3]
if mode == "stock":
    jit.KernelCache.file_class = caching.IndexDataCacheFile
if mode == "unlocked":
    jit.KernelCacheFile._saving = lambda self: contextlib.nullcontext()
racing.order(jit.KernelCache.file_class, which, folder, 1.0 if mode == "ours" else 120.0)
print(racing.call(which))
'''

CHECK = '''
import sys; from numba.core import caching; import racing; from esp_gym.kernels import jit
if sys.argv[1] == "stock":
    jit.KernelCache.file_class = caching.IndexDataCacheFile
def loaded(which):
    try:
        return str(racing.call(which))
    except TypeError:  # another overload's machine code: its wrapper refuses this array
        return "TypeError"
print(loaded(0), loaded(1))
'''


def test_processes_compiling_one_kernels_overloads_at_once_each_load_their_own_code(tmp_path):
    """Two processes compile two overloads of one kernel (two signatures) and save them at the same
    moment; a third loads each. numba's own cache file reads the index, picks the first data file it does not name
    and writes both, with nothing held in between: both racers took the same data file, and the
    index named one overload's machine code for the other's key. kernels/jit.py's file saves under
    a lock and checks the key it loads. Negative control: the same order of
    events with numba's file gives the reader another overload's code; without the lock, the key
    check alone turns that into a compile."""
    (tmp_path / "racing.py").write_text(RACING)

    def environ(mode: str) -> dict:
        return {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / mode / "cache"),
                "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}

    racers = []
    for mode in ("ours", "stock", "unlocked"):
        (tmp_path / mode / "markers").mkdir(parents=True)
        racers += [subprocess.Popen([sys.executable, "-c", RACE, str(which), mode, str(tmp_path / mode / "markers")],
                                    env=environ(mode), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                   for which in (0, 1)]
    for racer in racers:
        out, err = racer.communicate(timeout=600)
        assert racer.returncode == 0, err[-2000:]
    loaded = {}
    for mode in ("ours", "stock", "unlocked"):
        done = subprocess.run([sys.executable, "-c", CHECK, mode], capture_output=True, text=True,
                              env=environ(mode), timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        loaded[mode] = done.stdout.split()
    assert loaded["ours"] == loaded["unlocked"] == ["8", "4"], loaded
    assert loaded["stock"] == ["8", "TypeError"], loaded  # the float32 overload's key, the float64 one's code



def _configured(decorate: str, entry: str) -> str:
    """A module with a closure kernel ``inner`` made for two configurations (``which`` 0 and 1,
    as loops.py makes the string's loops for the explicit and the implicit string) and an entry
    point ``outer<which>`` calling each, compiled by ``decorate`` (``entry`` for the entry points).
    ``inner`` is long enough that LLVM keeps it a function of its own, called by its symbol."""
    terms = "\n".join(f"            acc = acc * 0.{k % 9 + 1} + x[(i * {k + 1}) % x.shape[0]] * (i + {k})"
                      f" - (acc * acc) / ({k}.5 + acc * acc)" for k in range(60))
    return f'''import numba
from esp_gym.kernels.jit import kernel

def make_inner(which):
    @{decorate}
    def inner(x, n):
        acc = 0.0
        for i in range(n):
{terms}
        return acc * 0 + which
    return inner

inner0, inner1 = make_inner(0), make_inner(1)

@{entry}
def outer0(x, n):
    return inner0(x, n) + inner0(x, n + 1)

@{entry}
def outer1(x, n):
    return inner1(x, n) + inner1(x, n + 1)
'''


def test_configurations_compiled_in_two_processes_each_run_their_own_code_in_a_third(tmp_path):
    """Two processes compile a closure kernel for one configuration each (as the two workers of
    ``esp-gym compile`` compiled the environment's string loops); a third loads both from the cache.
    numba names a compiled function's symbol by its qualified name, its argument types and a counter
    of the process that compiled it, equal in two processes that compiled alike, and a process
    links a symbol to the first definition it loaded: the third process ran the first-loaded
    configuration's code for both (the implicit string's environment ran the explicit string's
    loop). kernels/jit.py names each configuration (``inner__which0``, ``inner__which1``).
    Negative control: numba's own closures."""
    modules = {"ours": _configured("kernel", "kernel(entry=True)"),
               "stock": _configured("numba.njit(cache=True)", "numba.njit(cache=True)")}
    code = "import numpy as np, configured as c; x = np.ones(3); print({})"

    def start(mode: str, calls: str) -> subprocess.Popen:
        (tmp_path / mode).mkdir(exist_ok=True)
        (tmp_path / mode / "configured.py").write_text(modules[mode])
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / mode / "cache"),
               "PYTHONPATH": os.pathsep.join([str(tmp_path / mode), str(ROOT)])}
        return subprocess.Popen([sys.executable, "-c", code.format(calls)], env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)

    def results(processes) -> list:
        out = []
        for process in processes:
            stdout, stderr = process.communicate(timeout=600)
            assert process.returncode == 0, stderr[-2000:]
            out.append(stdout.split())
        return out

    compiled = results([start(mode, f"c.outer{which}(x, 5)") for mode in modules for which in (0, 1)])
    assert compiled == [["0.0"], ["2.0"]] * 2
    ours, stock = results([start(mode, "c.outer0(x, 5), c.outer1(x, 5)") for mode in modules])
    assert ours == ["0.0", "2.0"]
    assert stock == ["0.0", "0.0"]


def test_a_compiled_closure_captures_only_bools_and_ints():
    from esp_gym.kernels.jit import kernel
    scale = 2.5

    def scaled(x):
        return scale * x

    with pytest.raises(TypeError, match="captures scale=2.5"):
        kernel(scaled)
