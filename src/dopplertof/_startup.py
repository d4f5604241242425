"""Ctrl-C while the ``dopplertof`` command loads (about 0.3 s of imports): one line and
exit status 130, as once it runs (:mod:`dopplertof.cli`), not a traceback. Only in the
command's own process: a program or notebook that imports the package keeps its handler."""

from __future__ import annotations

import os
import signal
import sys
import threading

COMMAND = "dopplertof"  # the console script (pyproject.toml)


def _fail(message: str, status: int):
    """``error: message`` on stderr and exit ``status`` at once (mid-import: no cleanup)."""
    os.write(2, f"error: {message}\n".encode())
    os._exit(status)


def _stop(signum, frame):
    _fail("interrupted while starting; nothing done", 128 + signum)


def guard_interrupts():
    """In the command's process, Ctrl-C ends it with one line until :func:`release`."""
    script = getattr(sys.modules.get("__main__"), "__file__", None) or ""
    if os.path.basename(script) == COMMAND and threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _stop)


def release():
    """Python's own Ctrl-C handling again (the command handles KeyboardInterrupt)."""
    if signal.getsignal(signal.SIGINT) is _stop:
        signal.signal(signal.SIGINT, signal.default_int_handler)
