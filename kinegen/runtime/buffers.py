"""Arrays a solver hands out again once nothing else holds them.

A trajectory's positions, velocities and accelerations are large arrays, new at every solve
(chain-100 over 1,000 steps: 15 MB). Memory of that size comes from the operating system each
time: glibc's allocator maps such a block and unmaps it when it is freed, or gives its heap's
top back, so a solve repeated in one process touched every page of its results afresh
(chain-14: ~620 page faults a solve, chain-100 ~2,300; ~10 % of either solve's time in a loop
that drops each result, docs/performance.md). :class:`Reusable` keeps the arrays of a solver's
last solves and hands one out again for the same shape and type once no other reference to it
is left -- the :class:`~kinegen.runtime.results.Results` that held it and every view of it are
gone, which CPython's reference count tells exactly. An array still held anywhere is never
handed out: then a new one is made. Where reference counts do not exist (another Python),
nothing is kept.
"""

from __future__ import annotations

import sys
import threading

import numpy as np

#: the most memory one :class:`Reusable` keeps (bytes), in use or not: what a dropped result
#: may hold on to for as long as its solver lives (a loop ``results = solver.solve(...)`` over
#: chain-100's 1,000 steps alternates between two sets of ~18 MB)
KEPT_BYTES = 1 << 26


def _count_of_kept() -> int | None:
    """sys.getrefcount of an array held only by a list, as :meth:`Reusable.empty` reads it."""
    if not hasattr(sys, "getrefcount"):
        return None
    kept = [np.empty(1)]
    return sys.getrefcount(kept[0])


_FREE = _count_of_kept()


class Reusable:
    """Uninitialized arrays (as :func:`numpy.empty`), each handed out again by a later call for
    the same shape and type once nothing but this object refers to it. At most
    :data:`KEPT_BYTES` are kept, the oldest let go first. Threads may share one: an array is found
    free and handed out under a lock, and its taker's reference exists before the lock is let go."""

    def __init__(self) -> None:
        self._kept: list[np.ndarray] = []  # oldest first
        self._lock = threading.Lock()

    def empty(self, shape: tuple[int, ...], dtype: type | str = float) -> np.ndarray:
        """An array of ``shape`` and ``dtype`` whose values are unspecified (stale values of an
        earlier call's user, or whatever new memory holds)."""
        shape, dtype = tuple(int(n) for n in shape), np.dtype(dtype)
        with self._lock:
            kept = self._kept
            for i in range(len(kept)):
                if kept[i].shape == shape and kept[i].dtype == dtype and sys.getrefcount(kept[i]) == _FREE:  # this list's alone
                    return kept[i]
            array = np.empty(shape, dtype=dtype)
            if _FREE is not None and array.nbytes <= KEPT_BYTES:
                held = sum(a.nbytes for a in kept)
                while held + array.nbytes > KEPT_BYTES:
                    held -= kept.pop(0).nbytes
                kept.append(array)
            return array

    def copy(self, x: np.ndarray) -> np.ndarray:
        """A C-contiguous copy of ``x``'s values (what :func:`numpy.ascontiguousarray` of a view gives),
        in an array of :meth:`empty`: a kept one when one is free."""
        out = self.empty(x.shape, x.dtype)
        np.copyto(out, x)
        return out
