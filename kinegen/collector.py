"""Python's cyclic garbage collector paused for work that makes many objects and few reference cycles.

A derivation allocates millions of SymPy and SymEngine objects, few of them in reference cycles, and
keeps most of them (SymPy's caches) to its end. Each of the collector's passes over them finds next
to nothing: the excavator's build spent 0.24-0.29 s of 2.1-2.6 s in 390 collections. Paused, the
objects are freed by reference counting as before, and whatever cycles the work leaves are
collected by the first pass after it (the excavator's build: 8 MB more at its peak). Paused for:
generating a module (:func:`kinegen.codegen.writer.generate`), a kernel description
(:func:`kinegen.codegen.kernels.describe`), an exact inspection (:func:`kinegen.analysis.inspect.inspect`)
and the Python solver's loop (:meth:`kinegen.runtime.solver.Solver.solve`). The collector's state is
the process's: another thread allocating meanwhile is not collected either, for that time.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_paused() -> Iterator[None]:
    """The block run with the cyclic garbage collector disabled; it is enabled again after the block
    if it was before (a nested pause leaves that to the outermost). As a decorator
    (``@collector_paused()``), every call of the function is such a block."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
