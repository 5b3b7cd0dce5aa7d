"""The C backend: the model's kernels as C99 (``<stem>.h``/``<stem>.c``) and, as a standalone
target, the runtime ``kinegen_solver.h/.c``, a Makefile, a CMakeLists.txt and example_main.c.
(``jobs``, ``printers`` and ``render`` are imported when first read: the runtime reads :mod:`.config` alone.)"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinegen.lazy import exported

if TYPE_CHECKING:
    from kinegen.codegen.backends.c.backend import jobs, printers, render

__getattr__ = exported(__name__, {name: "kinegen.codegen.backends.c.backend" for name in ("jobs", "printers", "render")})


__all__ = ["jobs", "printers", "render"]
