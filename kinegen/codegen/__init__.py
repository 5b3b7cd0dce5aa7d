"""Code generation: generated Python modules (files) and the in-memory lambdify path."""

from kinegen.codegen.writer import build, generate_source, initial_q, module_name, write_atomic

__all__ = ["build", "generate_source", "initial_q", "module_name", "write_atomic"]
