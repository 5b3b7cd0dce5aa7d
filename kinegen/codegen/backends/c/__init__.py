"""The C backend: the model's kernels as C99 (``<stem>.h``/``<stem>.c``) and, as a standalone
target, the runtime ``kinegen_solver.h/.c``, a Makefile, a CMakeLists.txt and example_main.c.
(``jobs`` and ``render`` are imported when first read: the runtime reads :mod:`.config` alone.)"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinegen.codegen.backends.c.backend import jobs, render


def __getattr__(name: str) -> Any:
    if name in ("jobs", "render"):
        return getattr(import_module("kinegen.codegen.backends.c.backend"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["jobs", "render"]
