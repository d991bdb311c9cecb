"""Processes that save overloads of one kernel at the same moment each load their own machine code
(kernels/jit.py, KernelCacheFile). Not a serial module: the race is ordered by marker files, not by
the clock, so another worker's load cannot change its outcome."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: A kernel with two overloads (closures of one function, as the rigs' entry points are), and
#: hooks on a cache file class that order two processes' saves through marker files: the first
#: process (0) reads the index, the second (1) reads it too, 0 writes the index, 1 writes the index
#: and its data, and 0 writes its data last. Under a lock held across a save the other process
#: cannot move, so each wait ends at its timeout (short then) and the saves simply follow each other.
RACING = '''
import os, time
from esp_gym.kernels.jit import kernel

def variant(which):
    @kernel(entry=True)
    def value():
        return which
    return value

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
print(racing.variant(which)())
'''

CHECK = '''
import sys; from numba.core import caching; import racing; from esp_gym.kernels import jit
if sys.argv[1] == "stock":
    jit.KernelCache.file_class = caching.IndexDataCacheFile
print(racing.variant(0)(), racing.variant(1)())
'''


def test_processes_compiling_one_kernels_overloads_at_once_each_load_their_own_code(tmp_path):
    """Two processes compile two overloads of one kernel and save them at the same moment; a third
    loads each. numba's own cache file reads the index, picks the first data file it does not name
    and writes both, with nothing held in between: both racers took the same data file, and the
    index named one overload's machine code for the other's key (an environment on the implicit
    string then ran the explicit string's step, and failed at its first step). kernels/jit.py's
    file saves under a lock and checks the key it loads. Negative control: the same order of
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
    assert loaded["ours"] == loaded["unlocked"] == ["0", "1"], loaded
    assert loaded["stock"] == ["0", "0"], loaded  # overload 1's key, overload 0's data file
