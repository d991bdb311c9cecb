"""Where the compiled kernels are cached, and what happens when nowhere is writable."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from esp_gym.kernels.jit import choose_cache_dir

ROOT = Path(__file__).resolve().parent.parent
#: Nothing can be created under /proc, not even by root (for whom permission bits do not count).
UNWRITABLE = "/proc/esp_gym-unwritable"


def _environ(**extra):
    return {"HOME": UNWRITABLE + "/home", "TMPDIR": UNWRITABLE + "/tmp", **extra}


def test_an_unwritable_numba_cache_dir_falls_back_with_a_warning(tmp_path):
    path, warning = choose_cache_dir(_environ(NUMBA_CACHE_DIR=UNWRITABLE), package_dir=tmp_path)
    assert path.startswith(str(tmp_path / "__pycache__"))
    assert "NUMBA_CACHE_DIR" in warning


def test_the_temporary_directory_is_the_last_resort(tmp_path):
    path, warning = choose_cache_dir(_environ(TMPDIR=str(tmp_path)), package_dir=Path(UNWRITABLE))
    assert path.startswith(str(tmp_path)) and "using" in warning


def test_with_nothing_writable_the_kernels_run_uncached():
    path, warning = choose_cache_dir(_environ(XDG_CACHE_HOME=UNWRITABLE), package_dir=Path(UNWRITABLE))
    assert path is None
    assert "compile in every process" in warning and "NUMBA_CACHE_DIR" in warning


def test_a_writable_package_directory_needs_no_warning(tmp_path):
    assert choose_cache_dir({}, package_dir=tmp_path)[1] is None


def test_a_kernel_runs_when_numba_cache_dir_is_unwritable():
    """End to end: before the fallback this raised numba's "cannot cache function ... no locator
    available" at the first compiled call."""
    code = ("import numpy as np; from esp_gym.kernels.env.step import actions_finite; "
            "print(actions_finite(np.array([[0.5, -1.0]])))")
    env = {**os.environ, "NUMBA_CACHE_DIR": UNWRITABLE}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "True"
    assert "cannot write the kernel cache in NUMBA_CACHE_DIR" in done.stderr


def _mount_read_only(source: Path, target: Path) -> bool:
    target.mkdir()
    for args in (["mount", "--bind", str(source), str(target)], ["mount", "-o", "remount,bind,ro", str(target)]):
        if subprocess.run(args, capture_output=True).returncode != 0:
            subprocess.run(["umount", str(target)], capture_output=True)
            return False
    return True


def test_a_read_only_package_without_a_home_still_runs(tmp_path):
    """The defect as found: the package on a read-only mount, HOME unwritable, no
    NUMBA_CACHE_DIR. Before the fallback the first compiled call raised "cannot cache function
    ... no locator available"; now the cache goes to the temporary directory, with a warning."""
    source = tmp_path / "source"
    shutil.copytree(ROOT / "esp_gym", source / "esp_gym", ignore=shutil.ignore_patterns("__pycache__"))
    mounted = tmp_path / "mounted"
    if not _mount_read_only(source, mounted):
        pytest.skip("cannot make a read-only bind mount here (needs root)")
    try:
        code = ("import numpy as np; from esp_gym.kernels.env.step import actions_finite; "
                "print(actions_finite(np.array([[0.5, -1.0]])))")
        env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
        env.update(HOME=UNWRITABLE, PYTHONPATH=str(mounted), TMPDIR=str(tmp_path))
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd="/", env=env,
                              timeout=600)
    finally:
        subprocess.run(["umount", str(mounted)], capture_output=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "True"
    assert f"using {tmp_path}" in done.stderr


def test_stale_cache_directories_are_pruned_to_the_most_recent(tmp_path):
    """Beside the current cache, other kernel sources' directories beyond the KEEP_STALE most
    recently written are removed; anything not named like a kernel cache stays. Negative control:
    with room to keep them all, nothing goes."""
    from esp_gym.kernels.jit import KEEP_STALE, prune_stale_caches
    current = tmp_path / "esp_gym-kernels-0000000000000000"
    current.mkdir()
    stale = []
    for age in range(5):  # the first is the newest
        path = tmp_path / f"esp_gym-kernels-{age + 1:016x}"
        path.mkdir()
        (path / "kernel.nbi").write_bytes(b"x")
        os.utime(path, (1e9 - age * 1e5, 1e9 - age * 1e5))
        stale.append(path)
    unrelated = [tmp_path / "esp_gym-kernels-notahash", tmp_path / "mine"]
    for path in unrelated:
        path.mkdir()
    assert prune_stale_caches(str(current), keep=10) == []
    removed = prune_stale_caches(str(current))
    assert sorted(removed) == sorted(str(p) for p in stale[KEEP_STALE:])
    assert current.is_dir() and all(p.is_dir() for p in stale[:KEEP_STALE] + unrelated)
    assert not any(p.exists() for p in stale[KEEP_STALE:])


def test_a_first_compile_says_so_once_and_a_cached_start_says_nothing(tmp_path):
    """The notice of kernels/jit.py: an announced kernel compiling on an empty cache prints one
    line on standard error, once per process however many signatures compile; a second process
    loads it from the cache and prints nothing."""
    (tmp_path / "announced_kernel.py").write_text(
        "from esp_gym.kernels.jit import announce_compile, kernel\n"
        "@kernel(entry=True)\n"
        "def double(x):\n"
        "    return 2 * x\n"
        "announce_compile(double, 'a test kernel', 3)\n")
    code = "from announced_kernel import double; print(double(2), double(2.5))"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env,
                           timeout=600) for _ in range(2)]
    assert all(run.returncode == 0 and run.stdout.split() == ["4", "5.0"] for run in runs), runs
    notice = [line for line in runs[0].stderr.splitlines() if line.startswith("esp_gym: compiling")]
    assert len(notice) == 1 and notice[0].startswith(
        f"esp_gym: compiling a test kernel for this machine, first run only (up to about 3 s on 2 cores; cached in "
        f"{tmp_path / 'cache'}{os.sep}esp_gym-kernels-"), runs[0].stderr
    assert "esp_gym: compiling" not in runs[1].stderr


def test_an_internal_kernel_refuses_python_and_its_callable_copy_runs():
    """A kernel compiled without numba's Python wrapper (esp_gym/kernels/jit.py) would crash the
    interpreter if Python called it: it raises a TypeError naming itself instead, and
    python_callable gives a copy that runs. Negative control: an entry point is its own callable."""
    from esp_gym.kernels.env.step import actions_finite
    from esp_gym.kernels.jit import InternalKernel, python_callable
    from esp_gym.kernels.sums import kahan_add

    x, c = np.zeros(1), np.zeros(1)
    assert isinstance(kahan_add, InternalKernel)
    with pytest.raises(TypeError, match="esp_gym.kernels.sums.kahan_add is an internal kernel"):
        kahan_add(x, c, 0, 0.5)
    python_callable(kahan_add)(x, c, 0, 0.5)
    assert x[0] == 0.5
    assert not isinstance(actions_finite, InternalKernel)
    assert python_callable(actions_finite) is actions_finite
    with pytest.raises(TypeError, match="python_callable takes a kernel"):
        python_callable(len)


def test_the_same_sources_installed_elsewhere_load_the_machine_code_compiled_for_them(tmp_path):
    """The cache's subdirectories are named by package path (kernels/jit.py, PackageCacheLocator),
    not by place on disk: a copy of a package in another directory (a wheel in a virtual
    environment, another clone) loads what the first compiled. Negative control: the copy with its
    source changed compiles anew (numba checks each file's hash)."""
    source = ("from esp_gym.kernels.jit import announce_compile, kernel\n"
              "@kernel(entry=True)\n"
              "def double(x):\n"
              "    return 2 * x\n"
              "announce_compile(double, 'a test kernel', 3)\n")

    def run(root: Path, text: str) -> subprocess.CompletedProcess:
        (root / "copied").mkdir(parents=True, exist_ok=True)
        (root / "copied" / "__init__.py").write_text("")
        (root / "copied" / "kernels.py").write_text(text)
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
               "PYTHONPATH": os.pathsep.join([str(root), str(ROOT)])}
        done = subprocess.run([sys.executable, "-c", "from copied.kernels import double; print(double(2))"],
                              capture_output=True, text=True, cwd=root, env=env, timeout=600)
        assert done.returncode == 0 and done.stdout.split() == ["4"], done
        return done

    assert "esp_gym: compiling" in run(tmp_path / "first", source).stderr
    assert "esp_gym: compiling" not in run(tmp_path / "second", source).stderr
    assert "esp_gym: compiling" in run(tmp_path / "third", source.replace("2 * x", "x + x")).stderr

