"""Ending a finished command's process without taking its heap apart object by object.

A build leaves millions of SymPy and SymEngine objects behind; Python's own shutdown frees each of
them before the process ends (0.3-0.6 s after the excavator's build, measured: docs/performance.md,
"Command start-up"). A command that is done has nothing left to free: :func:`exit_process` flushes
the standard streams, runs what was registered to run at exit (:mod:`atexit`: logging's shutdown,
the finalizers of temporary files and folders, multiprocessing's and Dask's clean-ups) and ends
the process with the command's exit code. Where that is not certainly the same as Python's own
shutdown (another thread still running, a stream that cannot be flushed, an exit status that is not
a number), it leaves the exit to Python.
"""

from __future__ import annotations

import atexit
import os
import sys
import threading
from typing import NoReturn


def exit_process(code: int | str | None) -> NoReturn:
    """End the process with ``code`` (a :class:`SystemExit`'s: None is 0) once the standard streams
    are flushed and the :mod:`atexit` functions have run; where another thread is still running
    (which Python's shutdown would wait for) or a stream cannot be flushed, ``sys.exit(code)``."""
    run_exit_functions = getattr(atexit, "_run_exitfuncs", None)  # (CPython's; elsewhere Python's own exit)
    others = [t for t in threading.enumerate() if t is not threading.main_thread() and not t.daemon and t.is_alive()]
    if not (code is None or isinstance(code, int)) or others or run_exit_functions is None:
        sys.exit(code)
    run_exit_functions()  # (they may write too: the streams are flushed after them)
    if not _flushed():
        sys.exit(code)
    os._exit(code or 0)


def _flushed() -> bool:
    """Whether standard output and error were flushed (a closed stream has nothing to flush)."""
    try:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None and not stream.closed:
                stream.flush()
    except (OSError, ValueError):  # a reader that went away (| head): Python's exit reports it as before
        return False
    return True


__all__ = ["exit_process"]
