"""Code generation: a target-neutral kernel description (:mod:`kernels`) printed by one
backend per target (:mod:`backends`), written atomically (:mod:`writer`); and the in-memory
lambdify path (:mod:`inmemory`).

The names below are imported when first read: the runtime reads the C backend's settings
(``kinegen.codegen.backends.c.config``) without importing the generator and SymPy's printers."""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinegen.lazy import exported

if TYPE_CHECKING:
    from kinegen.codegen.kernels import describe, initial_q
    from kinegen.codegen.writer import (
        build,
        built_with_sensitivities,
        generate,
        generate_source,
        module_name,
        write_atomic,
        write_files,
    )

__getattr__ = exported(__name__, {
    "describe": "kinegen.codegen.kernels", "initial_q": "kinegen.codegen.kernels",
    "build": "kinegen.codegen.writer", "built_with_sensitivities": "kinegen.codegen.writer", "generate": "kinegen.codegen.writer",
    "generate_source": "kinegen.codegen.writer", "module_name": "kinegen.codegen.writer", "write_atomic": "kinegen.codegen.writer",
    "write_files": "kinegen.codegen.writer",
})  # fmt: skip


__all__ = ["build", "built_with_sensitivities", "describe", "generate", "generate_source", "initial_q", "module_name", "write_atomic", "write_files"]
