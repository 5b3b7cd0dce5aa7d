"""Work in a forked child process, its result (or its error) back through a pipe.

The code generator splits a build's printing between two processes this way: the child is a
copy of this process (its description, its caches), so only the result travels.
"""

from __future__ import annotations

import gc
import multiprocessing
import threading
import weakref
from collections.abc import Callable
from typing import Any


def may_fork() -> bool:
    """Whether this process may work in a forked child: fork exists, no other thread runs (a fork
    copies only the calling thread: a lock another one holds would stay held), and it is not a
    daemonic process (which may not have children)."""
    return ("fork" in multiprocessing.get_all_start_methods() and threading.active_count() == 1
            and not multiprocessing.current_process().daemon)  # fmt: skip


class Child:
    """``function(*args)`` started in a forked child process (see :func:`may_fork`); :meth:`result`
    waits for it. A child whose result is never asked for (the parent's work failed meanwhile) is
    stopped when it is dropped: it would otherwise wait, blocked on its answer, for this process's end."""

    def __init__(self, function: Callable[..., Any], *args: Any) -> None:
        context = multiprocessing.get_context("fork")
        self._receiving, sending = context.Pipe(duplex=False)
        self._process = context.Process(target=_run, args=(function, args, sending), name="kinegen-child", daemon=True)
        self._process.start()
        sending.close()
        self._stop = weakref.finalize(self, _stop, self._process, self._receiving)

    def result(self) -> Any:
        """What the function returned; the exception it raised is raised here (its class, args and
        attributes), and a child that ended without an answer is a RuntimeError naming its exit code."""
        self._stop.detach()
        try:
            outcome, value = self._receiving.recv()
        except EOFError:
            self._process.join()
            outcome, value = "error", (RuntimeError, (f"the forked process ended without its result (exit code {self._process.exitcode})",), {})
        finally:
            self._receiving.close()
            self._process.join()
        if outcome == "error":
            raise _exception(*value)
        return value


def _stop(process: multiprocessing.Process, receiving) -> None:
    """A child nobody waits for: ended, and its pipe closed."""
    process.terminate()
    process.join()
    receiving.close()


def _run(function: Callable[..., Any], args: tuple, sending) -> None:
    """In the child: send ("result", value) or ("error", (class, args, attributes)). The objects the
    child was forked with are never collected here (``gc.freeze``): a collection would touch every one
    of them, copying the parent's memory page by page."""
    gc.freeze()
    try:
        sending.send(("result", function(*args)))
    except BaseException as exc:  # every failure goes back to the parent, as its class, args and attributes
        try:
            sending.send(("error", (type(exc), exc.args, dict(vars(exc)))))
        except Exception:  # one that does not pickle: its text
            sending.send(("error", (RuntimeError, (f"{type(exc).__name__}: {exc}",), {})))
    finally:
        sending.close()


def _exception(kind: type[BaseException], args: tuple, attributes: dict) -> BaseException:
    """An exception of ``kind`` with these ``args`` and attributes, its ``__init__`` not called
    again (kinegen's errors take other arguments than the message they keep in ``args``)."""
    exc = kind.__new__(kind)
    exc.args = args
    exc.__dict__.update(attributes)
    return exc
