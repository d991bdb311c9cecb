"""Recordings whose file cannot be written (esp_gym/viz/lifecycle.py): a full disk or a file-size
limit, and a file system that stops answering. The write error is raised during the rollout,
naming the file; close() returns within a bounded time; SIGTERM ends the process; what the file
holds stays readable.

Every case runs in a child process with a time limit, so a hang fails the test instead of
hanging the run. The children catch any exception, so the same tests show how an older
recorder fails (a hang, or an error only at close()).
"""
import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import warnings

import pytest
from rerun.chunk import RrdReader

FLUSH_EVERY = 20

#: Steps a rollout until writing its recording fails; prints what was raised and when, and how
#: long close() took. argv: path, then the file-size limit [bytes] (0: none).
ROLLOUT = r'''
import json, resource, signal, sys, time
import numpy as np, gymnasium as gym
from esp_gym.viz.recording import RecordRerun
path, limit = sys.argv[1], int(sys.argv[2])
env = RecordRerun(gym.make("ElasticStringPendulum-v0"), path, flush_every=%d, write_timeout=1.0)
env.reset(seed=0)
env.step(np.zeros(6))  # compiled (or loaded from the kernel cache) before any limit
if limit:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # past the limit, write() fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
out = {"raised": None}
start = time.monotonic()
for k in range(2, 3000):
    try:
        env.step(np.zeros(6))
    except Exception as e:
        out.update(raised=type(e).__name__, step=k, errno=getattr(e, "errno", None), message=str(e),
                   seconds=time.monotonic() - start, kept=env.recorder.samples_written)
        break
start = time.monotonic()
try:
    env.close()
except Exception as e:
    out["close_raised"] = f"{type(e).__name__}: {e}"
out["close_seconds"] = time.monotonic() - start
print(json.dumps(out), flush=True)
''' % FLUSH_EVERY


def run_child(code, *args, timeout=120):
    proc = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)  # kills the child when it hangs
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def signalled(code, args, ready, signals, pause=0.5):
    """Start a child running ``code``; once it prints a line for which ``ready(line)`` holds,
    send it ``signals``, ``pause`` seconds apart. Returns its return code, the seconds from the
    first signal to its end, and its stderr."""
    proc = subprocess.Popen([sys.executable, "-c", code, *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    watchdog = threading.Timer(120, proc.kill)  # a child that hangs before it is ready fails the test
    watchdog.start()
    try:
        while not ready(proc.stdout.readline()):
            assert proc.poll() is None, proc.stderr.read()
        start = time.monotonic()
        for k, signum in enumerate(signals):
            time.sleep(pause if k else 0.0)
            proc.send_signal(signum)
        proc.wait(timeout=30)
        return proc.returncode, time.monotonic() - start, proc.stderr.read()
    finally:
        watchdog.cancel()
        proc.kill()


def energy_steps(path):
    """The steps of the /diag/energy/total rows in ``path`` (a file without its footer is read
    as a stream, as a viewer would)."""
    steps = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "RRD file has no footer"
        for chunk in RrdReader(path).stream():
            if chunk.entity_path == "/diag/energy/total" and not chunk.is_static:
                steps += chunk.to_record_batch().column("step").to_pylist()
    return sorted(steps)


def check_failed_rollout(out, path, code):
    """The error came during the rollout, as a RecordingError naming the file, at most one
    flush after the last complete point; close() was quick; the file holds exactly the samples
    the recorder says it kept, readable."""
    assert out["raised"] == "RecordingError", out
    assert out["errno"] == code and str(path) in out["message"], out
    assert out["step"] <= out["kept"] + 2 * FLUSH_EVERY, out  # not only at close()
    assert out["close_seconds"] < 2.0 and "close_raised" not in out, out
    assert out["kept"] > 0 and energy_steps(path) == list(range(out["kept"]))


def test_a_file_size_limit_stops_the_recording_at_the_next_step(tmp_path):
    """RLIMIT_FSIZE makes write() fail as a full disk does (EFBIG instead of ENOSPC), with no
    privileges needed."""
    path, limit = tmp_path / "limited.rrd", 400_000  # the static part is ~190 kB; ~0.8 kB per step
    out = run_child(ROLLOUT, path, limit)
    check_failed_rollout(out, path, errno.EFBIG)
    assert path.stat().st_size <= limit


def test_a_full_disk_stops_the_recording_at_the_next_step():
    """The real thing, where the machine allows it (root, tmpfs): a 512 KiB file system."""
    mount = tempfile.mkdtemp(prefix="esp_gym-full-")
    try:
        if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=512k", "tmpfs", mount],
                                               capture_output=True).returncode:
            pytest.skip("mounting a small tmpfs needs root")
        try:
            path = os.path.join(mount, "full.rrd")
            check_failed_rollout(run_child(ROLLOUT, path, 0), path, errno.ENOSPC)
        finally:
            subprocess.run(["umount", mount], capture_output=True)
    finally:
        shutil.rmtree(mount, ignore_errors=True)


@pytest.fixture
def hung_file(tmp_path):
    """A path whose writes block for good once 64 KiB are in (a FIFO that is open for reading
    but never read, as a file system that stopped answering)."""
    path = tmp_path / "hung.rrd"
    os.mkfifo(path)
    reader = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    yield path
    os.close(reader)


def test_close_returns_when_the_file_system_hangs(hung_file):
    out = run_child(ROLLOUT, hung_file, 0)
    assert out["raised"] == "RecordingError" and out["errno"] == errno.ETIMEDOUT, out
    assert str(hung_file) in out["message"] and out["step"] <= 2 * FLUSH_EVERY, out
    assert out["seconds"] < 5.0 and out["close_seconds"] < 2.0, out  # write_timeout = 1 s


def test_sigterm_ends_a_process_whose_recording_hangs(hung_file):
    """SIGTERM while every sample is still buffered: closing has to write them and cannot; the
    process ends as SIGTERM would have, after the write timeout, and says why on stderr."""
    child = ("import sys, numpy as np, gymnasium as gym\n"
             "from esp_gym.viz.recording import RecordRerun\n"
             "env = RecordRerun(gym.make('ElasticStringPendulum-v0'), sys.argv[1], flush_every=10**6,\n"
             "                  flush_seconds=1e6, write_timeout=1.0)\n"
             "env.reset(seed=0)\n"
             "k = 0\n"
             "while True:\n"
             "    env.step(np.zeros(6))\n"
             "    k += 1\n"
             "    print(k, flush=True)\n")
    code, ended, err = signalled(child, [hung_file], lambda line: int(line or 0) >= 30, [signal.SIGTERM])
    assert code == -signal.SIGTERM, err
    assert ended < 5.0, ended  # write_timeout = 1 s
    assert "did not grow" in err and str(hung_file) in err, err


#: A process whose recording never finishes closing (a stand-in recorder, registered like one).
#: argv: lifecycle.EXIT_SECONDS.
STUCK_CLOSE = r'''
import sys, time
from esp_gym.viz import lifecycle
lifecycle.EXIT_SECONDS = float(sys.argv[1])
class Stuck:
    def flush(self, wait=True):
        pass
    def close(self):
        time.sleep(3600)
lifecycle.track(Stuck())
print("ready", flush=True)
while True:  # short sleeps: a signal the kernel hands to another thread is handled at the next
    time.sleep(0.05)  # bytecode; one long sleep would miss it (seen once in CI: a 30 s time-out)
'''


@pytest.mark.parametrize("exit_seconds, second_sigterm", [(1.0, False), (600.0, True)])
def test_sigterm_ends_the_process_even_if_closing_never_ends(exit_seconds, second_sigterm):
    """After EXIT_SECONDS, or at once on a second SIGTERM."""
    code, ended, err = signalled(STUCK_CLOSE, [exit_seconds], lambda line: line.strip() == "ready",
                                 [signal.SIGTERM] * (2 if second_sigterm else 1))
    assert code == -signal.SIGTERM, err
    assert ended < 5.0, ended
