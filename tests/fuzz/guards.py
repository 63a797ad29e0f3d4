"""What every fuzz test of a file surface watches besides the outcome: the files opened
(through Python's audit hook on ``open``, so a read outside the allowed folders is seen
whatever code path made it) and the time taken (an alarm, so a hang fails the example
instead of the run)."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

_WATCHING = threading.local()


def _audit(event, args):
    opened = getattr(_WATCHING, "opened", None)
    if opened is not None and event == "open" and args and isinstance(args[0], (str, bytes)):
        opened.append(os.fsdecode(args[0]))


sys.addaudithook(_audit)


@contextlib.contextmanager
def watch_opens():
    """Collects the paths this thread opens inside the block into the list it yields."""
    _WATCHING.opened = opened = []
    try:
        yield opened
    finally:
        _WATCHING.opened = None


def touched(opened, forbidden) -> list:
    """The opened paths that lie (once links are resolved, or as written) under one of the
    ``forbidden`` paths (folders or files)."""
    roots = [os.path.realpath(f) for f in forbidden] + [os.path.abspath(f) for f in forbidden]
    bad = []
    for path in opened:
        for real in {os.path.realpath(path), os.path.abspath(path)}:
            if any(real == r or real.startswith(r + os.sep) for r in roots):
                bad.append(path)
                break
    return bad


class Hang(Exception):
    """An example ran past its time limit."""


@contextlib.contextmanager
def time_limit(seconds: float):
    """Raise :class:`Hang` in the main thread after ``seconds`` (no-op off the main
    thread, where signals cannot be delivered)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def ring(signum, frame):
        raise Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
