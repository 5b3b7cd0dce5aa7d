"""Building a model into generated code: the work behind ``kinegen build``.

One call builds one parametrization: the importable Python module and the model's C (the
runtime's library compiled from it meanwhile, into the cache), or a standalone C directory.
Before anything is written, every case's time functions are checked on its time grid and its
initial pose is checked (assembled if needed): a build that fails either check writes nothing.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class BuildReport:
    """What a build wrote (``path``: the Python module, or the standalone C directory), in which
    parametrization, its wall time [s] (with the library's compilation it waited for), one line per
    case from the pre-write check, and for a standalone C directory the name of its example program."""

    path: Path
    parametrization: str
    seconds: float
    checks: list[str]
    program: str | None = None


def build(model_file: str | Path, parametrization: str, target: str = "python", out_dir: str | Path | None = None,
          sensitivities: bool = True, reuse: bool = True, compile_library: bool = True) -> BuildReport:  # fmt: skip
    """Build ``model_file`` in ``parametrization`` (a canonical name): ``target`` "python" into
    ``out_dir`` (default generated/), waiting for the runtime's library of its C (``compile_library`` False:
    not compiled now; a compiled solve compiles it when first needed); "c" a standalone C directory
    (default ``<model>_<param>_c``). ``sensitivities``: as ``kinegen build --no-sensitivities`` says.
    ``reuse``: the same build asked for again is taken from kinegen's cache (:mod:`kinegen.codegen.kept`)."""
    from kinegen.codegen import build as build_module
    from kinegen.codegen import module_name
    from kinegen.model import load
    from kinegen.rotations import get
    from kinegen.runtime import check_source

    start = time.perf_counter()
    checks: list[str] = []

    def check(source: str, model: str) -> None:
        checks.extend(check_source(source, model))

    solver_object = None
    if target != "c" and compile_library:  # kinegen's C solver does not depend on the model: compiled (once, cached) while the model is derived
        from kinegen.runtime.native import start_solver_object

        solver_object = start_solver_object()
    model = load(model_file)
    stem = module_name(model, get(parametrization))
    if target == "c":
        path = build_module(model_file, parametrization, out_dir or f"{stem}_c", check=check, targets=("c",),
                            sensitivities=sensitivities, model=model, keep=reuse)  # fmt: skip
        return BuildReport(path, parametrization, time.perf_counter() - start, checks, f"{stem}_example")
    compiling: list = []  # the model's C compiles for the runtime (cached) while the Python is printed and checked

    def ready(made: str, files: dict[str, str]) -> None:
        if made == "c-model" and compile_library:
            from kinegen.runtime.native import compile_in_background

            compiling.append(compile_in_background(files, first=solver_object))

    path = build_module(model_file, parametrization, out_dir or "generated", check=check, ready=ready, sensitivities=sensitivities,
                        model=model, keep=reuse)  # fmt: skip
    for thread in compiling:
        thread.join()
    if solver_object is not None:  # (a model without C: the solver's object is still cached for later)
        solver_object()
    return BuildReport(path, parametrization, time.perf_counter() - start, checks)


__all__ = ["BuildReport", "build"]
