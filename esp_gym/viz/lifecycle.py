"""The open recordings of the process, and what happens to them at exit and on signals.

A recorder registers with :func:`track` when it opens and leaves with :func:`untrack` when it
closes; it needs two methods, ``flush(wait=True)`` and ``close()``. :func:`track` installs,
once per process, the handlers:

* ``atexit``: close every open recording;
* SIGTERM: close every open recording (the file gets its footer), then end the process as
  SIGTERM would have, or call the previously installed Python handler;
* SIGINT: write every open recording's buffers, then call the previous handler (Python's
  default raises KeyboardInterrupt; ``atexit`` closes the recordings later).

Handlers are chained to the previous ones and installed from the main thread only (elsewhere
signals are left alone). A signal arriving while a flush is in progress
(:func:`holding_signals`) is handled when the flush ends, so a record batch is never cut in
half.
"""
from __future__ import annotations

import atexit
import os
import signal
import threading
from contextlib import contextmanager

#: Recorders not yet closed (strong references: buffered samples are written at exit even if
#: a recorder was dropped without close).
_open: set = set()
_state = {"busy": 0, "pending": [], "installed": False}
_previous: dict = {}


def track(recorder) -> None:
    """Register an open recorder (closed at exit and on SIGTERM, flushed on SIGINT) and install
    the handlers (:func:`install_handlers`)."""
    _open.add(recorder)
    install_handlers()


def untrack(recorder) -> None:
    """Forget a closed recorder."""
    _open.discard(recorder)


def close_all() -> None:
    """Close every open recorder."""
    for rec in list(_open):
        rec.close()


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
    if signum == signal.SIGINT:
        for rec in list(_open):
            rec.flush(wait=True)
    else:
        close_all()
    prev = _previous.get(signum, signal.SIG_DFL)
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
