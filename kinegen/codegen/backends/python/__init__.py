"""The Python backend: one importable module per model and parametrization (NumPy batch code
and plain-float code for one configuration)."""

from kinegen.codegen.backends.python.backend import jobs, printers, render

__all__ = ["jobs", "printers", "render"]
