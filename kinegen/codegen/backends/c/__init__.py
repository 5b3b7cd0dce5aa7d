"""The C backend: the model's kernels as C99 (``<stem>.h``/``<stem>.c``) and, as a standalone
target, the runtime ``kinegen_solver.h/.c``, a Makefile, a CMakeLists.txt and example_main.c."""

from kinegen.codegen.backends.c.backend import jobs, render

__all__ = ["jobs", "render"]
