"""The open recordings of the process: the file each one writes (:class:`RrdFile`), and what
happens to them at exit and on signals.

**The file.** Rerun's file sink does not write the ``.rrd`` itself: it writes the encoded
stream into a pipe, and a thread of ours copies the pipe to the file, checking every write.
Rerun's own writer (0.41) reports a failed write only at the next flush, and a flush can then
wait forever for its writer thread, which has died, with the main thread inside Rerun, where no
signal handler runs. Through the pipe, Rerun never meets a disk error: after a failed write our
thread keeps reading the pipe and drops what it reads, so Rerun's writer never blocks, and the
error is kept (:attr:`RrdFile.error`) for the recorder to raise as :class:`RecordingError` at
its next sample. Every wait has a time limit.

A reader rejects a file that ends inside a message. After every Rerun flush that has come
through (:meth:`RrdFile.sync`), the file ends on a whole message, and its size is kept as the
last complete point; after a failed write the file is cut back to it, so what it holds stays
readable (``RrdReader(path).stream()``; without the footer, ``.store()`` refuses it).

**Exit and signals.** A recorder registers with :func:`track` when it opens and leaves with
:func:`untrack` when it closes; it needs two methods, ``flush(wait=True)`` and ``close()``.
:func:`track` installs, once per process, the handlers:

* ``atexit``: close every open recording;
* SIGTERM: close every open recording (the file gets its footer), then end the process as
  SIGTERM would have, or call the previously installed Python handler. Under the default
  action, SIGTERM is back at the default while the recordings close, so a second SIGTERM ends
  the process at once, and the process ends anyway :data:`EXIT_SECONDS` after the first;
* SIGINT: write every open recording's buffers, then call the previous handler (Python's
  default raises KeyboardInterrupt; ``atexit`` closes the recordings later).

Write errors met by these handlers are printed to stderr (they cannot be raised anywhere
useful). Handlers are chained to the previous ones and installed from the main thread only
(elsewhere signals are left alone). A signal arriving while a flush is in progress
(:func:`holding_signals`) is handled when the flush ends (a flush gives up once the file has
not grown for the recorder's ``write_timeout``), so a record batch is never cut in half.
"""
from __future__ import annotations

import atexit
import errno
import os
import select
import signal
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

#: Recorders not yet closed (strong references: buffered samples are written at exit even if
#: a recorder was dropped without close).
_open: set = set()
_state = {"busy": 0, "pending": [], "installed": False}
_previous: dict = {}

#: After a SIGTERM under the default action, the process ends at the latest this many seconds
#: later, even if closing the recordings has not finished.
EXIT_SECONDS = 30.0
#: Size asked for the pipe between Rerun and the file (Linux; elsewhere the system's default),
#: and the most read from it at once.
PIPE_BYTES, READ_BYTES = 1 << 20, 1 << 16
#: Longest single wait [s] inside the waits that watch the file for progress.
SLICE = 0.1


class RecordingError(OSError):
    """Writing a recording failed (``errno`` and the message say why; ``path`` is the file) or
    did not finish in time (``errno.ETIMEDOUT``)."""

    def __init__(self, code: int, message: str, path):
        super().__init__(code, message)
        self.path = str(path)


class RrdFile:
    """The file of one recording, written by a thread of ours from the pipe Rerun's file sink
    writes into (see the module docstring).

    :meth:`attach` makes a Rerun stream save to it, :meth:`sync` flushes the stream into the
    file and marks a complete point, :meth:`finish` ends the stream and closes the file. Each
    waits at most ``timeout`` seconds; past that the file is given up (:meth:`abandon`). The
    first failed write is kept in :attr:`error` (an ``OSError``); the file is then cut back to
    its last complete point and nothing more is written (:meth:`raise_error`). POSIX only (a
    pipe opened as ``/dev/fd/N``)."""

    def __init__(self, path, timeout: float):
        self.path = Path(path)
        self.timeout = float(timeout)
        try:  # not blocking: a FIFO without a reader fails here instead of hanging
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NONBLOCK, 0o644)
        except OSError as e:
            raise RecordingError(e.errno, f"cannot open the recording {self.path}: {e.strerror}", self.path) from e
        os.set_blocking(self._fd, True)
        self._r, self._w = os.pipe()
        try:
            import fcntl
            fcntl.fcntl(self._r, fcntl.F_SETPIPE_SZ, PIPE_BYTES)
        except (ImportError, AttributeError, OSError):
            pass
        os.set_blocking(self._r, False)
        self.error = None  #: the first failed write (OSError), or a time-out
        self.written = 0  #: bytes written to the file
        self.complete = 0  #: the file's size at its last complete point (it ends on a whole message)
        self._eof = False
        self._discarder = None  # the thread dropping the pipe's bytes after abandon()
        self._lock = threading.Lock()  # held while bytes read from the pipe are not yet written
        self._thread = threading.Thread(target=self._drain, name=f"rrd writer ({self.path.name})", daemon=True)
        self._thread.start()

    def attach(self, stream, blueprint) -> None:
        """Make the Rerun ``stream`` save to this file, through the pipe, with its default
        ``blueprint``."""
        try:
            stream.save(f"/dev/fd/{self._w}", default_blueprint=blueprint)
        finally:
            os.close(self._w)  # Rerun opened its own descriptor: the pipe ends when Rerun closes it

    # -- the writer thread --------------------------------------------------------------------
    def _drain(self) -> None:
        r = self._r
        while True:
            _readable(r, None)
            with self._lock:
                try:
                    data = os.read(r, READ_BYTES)
                except BlockingIOError:  # taken by the discarding thread (abandon)
                    continue
                if not data:
                    self._eof = True
                    return
                if self.error is None:
                    self._write(data)

    def _write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            if self.error is not None:  # abandoned while a write hung
                self._cut()
                return
            try:
                n = os.write(self._fd, view)
            except OSError as e:
                self.error = e
                self._cut()
                return
            view = view[n:]
            self.written += n

    def _cut(self) -> None:
        """Cut the file back to its last complete point."""
        try:
            os.ftruncate(self._fd, self.complete)
        except OSError:  # not a regular file (e.g. /dev/full)
            pass

    # -- the recorder's side ------------------------------------------------------------------
    def sync(self, stream) -> None:
        """Flush the Rerun ``stream`` and wait until the file holds everything it wrote: the
        file then ends on a whole message, and its size is marked complete. Gives the file up
        if it stops growing for ``timeout`` seconds before that."""
        if self._waited(lambda: _flushed(stream, SLICE)) and self._waited(self._caught_up):
            self.complete = self.written

    def _caught_up(self) -> bool:
        """Whether the pipe is empty and everything read from it is written (waits up to a
        slice for the writer thread)."""
        if not self._lock.acquire(timeout=SLICE):
            return False
        try:
            return self._eof or not _readable(self._r, 0)
        finally:
            self._lock.release()

    def _waited(self, done) -> bool:
        """Call ``done()`` (it may block for a slice) until it holds: True. False, after giving
        the file up (:meth:`abandon`), once the file has not grown for ``timeout`` seconds; at
        once after a write error."""
        last, deadline = self.written, time.monotonic() + self.timeout
        while self.error is None:
            if done():
                return self.error is None
            if self.written != last:
                last, deadline = self.written, time.monotonic() + self.timeout
            elif time.monotonic() >= deadline:
                self.abandon()
            else:
                time.sleep(0.0005)
        return False

    def abandon(self) -> None:
        """The file has not grown for ``timeout`` seconds while there was more to write (the
        writer thread is stuck in a write: a hung file system): record a time-out as the error,
        and drop from now on what comes down the pipe, from a second thread, so that Rerun's
        writer never blocks. The stuck thread stops writing if its write returns."""
        if self.error is None:
            self.error = TimeoutError(errno.ETIMEDOUT, f"the file did not grow for {self.timeout:g} s "
                                                       "(write_timeout) with more to write")
        if self._discarder is None:
            self._discarder = threading.Thread(target=self._discard, name=f"rrd discard ({self.path.name})",
                                               daemon=True)
            self._discarder.start()

    def _discard(self) -> None:
        while True:
            _readable(self._r, None)
            try:
                if not os.read(self._r, READ_BYTES):
                    return
            except BlockingIOError:
                continue

    def finish(self, stream) -> bool:
        """End the Rerun ``stream`` (its footer goes down the pipe; this does not block, as the
        pipe is always read) and close the file once the writer thread has written the rest.
        Whether the file is complete: closed in time without an error."""
        stream.disconnect()
        if self._discarder is None:  # not given up: the thread reads the pipe to its end
            self._waited(lambda: _joined(self._thread, SLICE))  # (while the file grows)
        if self._discarder is None:
            self._thread.join(self.timeout)  # after a write error it only drops the rest
        if self._thread.is_alive():  # stuck in a write: the file stays open
            self.abandon()
            return False
        if self._discarder is not None:
            self._discarder.join(self.timeout)  # at the pipe's end too: then the pipe can be closed
        if self.error is None:
            self.complete = self.written
        for fd in (self._r, self._fd):
            try:
                os.close(fd)
            except OSError as e:  # a delayed write error (e.g. NFS)
                if self.error is None:
                    self.error = e
        return self.error is None

    def raise_error(self, kept: str) -> None:
        """Raise :class:`RecordingError` for :attr:`error`, naming the file, and saying what
        it ``kept``."""
        e = self.error
        raise RecordingError(getattr(e, "errno", None) or errno.EIO,
                             f"writing the recording {self.path} failed: {getattr(e, 'strerror', None) or e}. "
                             f"Recording stopped; {kept}", self.path) from e


def _flushed(stream, timeout: float) -> bool:
    """Flush the Rerun ``stream``; whether that finished within ``timeout`` seconds."""
    try:
        stream.flush(timeout_sec=timeout)
        return True
    except RuntimeError:  # timed out (or failed): the caller watches the file for progress
        return False


def _joined(thread, timeout: float) -> bool:
    thread.join(timeout)
    return not thread.is_alive()


def _readable(fd: int, timeout) -> bool:
    """Wait until ``fd`` has something to read or is at its end (``timeout`` [s], None: no
    limit); whether it has."""
    poll = select.poll()
    poll.register(fd, select.POLLIN)
    return bool(poll.poll(None if timeout is None else 1000.0 * timeout))


def track(recorder) -> None:
    """Register an open recorder (closed at exit and on SIGTERM, flushed on SIGINT) and install
    the handlers (:func:`install_handlers`)."""
    _open.add(recorder)
    install_handlers()


def untrack(recorder) -> None:
    """Forget a closed recorder."""
    _open.discard(recorder)


def _each_open(action: str) -> None:
    """Call ``action`` (``"close"`` or ``"flush"``) on every open recorder; a
    :class:`RecordingError` is printed to stderr and the others go on."""
    for rec in list(_open):
        try:
            rec.close() if action == "close" else rec.flush(wait=True)
        except RecordingError as e:
            print(f"esp_gym: {e}", file=sys.stderr, flush=True)


def close_all() -> None:
    """Close every open recorder (write errors go to stderr)."""
    _each_open("close")


def flushing() -> bool:
    """Whether a flush is in progress (inside :func:`holding_signals`)."""
    return _state["busy"] > 0


@contextmanager
def holding_signals():
    """A flush is in progress: SIGTERM and SIGINT arriving meanwhile are handled when the
    outermost such block ends (the first of them; the rest are dropped)."""
    _state["busy"] += 1
    try:
        yield
    finally:
        _state["busy"] -= 1
        if not _state["busy"] and _state["pending"]:
            signum = _state["pending"].pop(0)
            _state["pending"].clear()
            _dispatch(signum, None)


def _dispatch(signum, frame) -> None:
    prev = _previous.get(signum, signal.SIG_DFL)
    if signum == signal.SIGINT:
        _each_open("flush")
    else:
        if prev == signal.SIG_DFL:
            # from here on SIGTERM kills at once, and this timer sends one if closing hangs
            signal.signal(signum, signal.SIG_DFL)
            timer = threading.Timer(EXIT_SECONDS, os.kill, (os.getpid(), signum))
            timer.daemon = True
            timer.start()
        close_all()
    if callable(prev):
        prev(signum, frame)  # e.g. default_int_handler raises KeyboardInterrupt
    elif prev == signal.SIG_DFL:
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)  # end the process as the signal would have


def _on_signal(signum, frame) -> None:
    if _state["busy"]:  # in the middle of a flush: finish it first (holding_signals)
        _state["pending"].append(signum)
        return
    _dispatch(signum, frame)


def install_handlers() -> None:
    """Once per process: ``atexit`` closing of open recordings, and SIGTERM/SIGINT handlers
    chaining to the previous ones (main thread only; elsewhere signals are left alone). A
    signal set to be ignored stays ignored."""
    if _state["installed"]:
        return
    _state["installed"] = True
    atexit.register(close_all)
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in (signal.SIGTERM, signal.SIGINT):
        prev = signal.getsignal(sig)
        if prev in (signal.SIG_IGN, None):
            continue
        _previous[sig] = prev
        signal.signal(sig, _on_signal)
