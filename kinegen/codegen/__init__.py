"""Code generation: a target-neutral kernel description (:mod:`kernels`) printed by one
backend per target (:mod:`backends`), written atomically (:mod:`writer`); and the in-memory
lambdify path (:mod:`inmemory`)."""

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

__all__ = ["build", "built_with_sensitivities", "describe", "generate", "generate_source", "initial_q", "module_name", "write_atomic", "write_files"]
