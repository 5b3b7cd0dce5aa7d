"""Building a model into a generated module file, written atomically."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import sympy as sp

from kinegen.codegen.python_module import render
from kinegen.model import Model, load
from kinegen.rotations import Parametrization, get
from kinegen.symbolic import build_systems


def initial_q(model: Model, parametrization: Parametrization) -> np.ndarray:
    """Stored coordinates of the model's initial pose in ``parametrization``."""
    values: list[float] = []
    for body in model.bodies:
        rotation = np.array(body.rotation.evalf(30), dtype=float)
        values += [float(sp.N(x, 30)) for x in body.position]
        values += [float(x) for x in parametrization.from_matrix(rotation)]
    return np.array(values)


def module_name(model: Model, parametrization: Parametrization) -> str:
    """File stem of the generated module, e.g. ``boom_quaternion``."""
    return f"{model.name}_{parametrization.file_tag}"


def generate_source(model: Model, parametrization: Parametrization) -> str:
    """Source of the generated module for ``model`` (all cases) in ``parametrization``."""
    systems = build_systems(model, parametrization)
    return render(systems, initial_q(model, parametrization), Path(model.file).name)


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file and ``os.replace``: all or nothing."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def build(
    model_path: str | Path,
    parametrization: str,
    out_dir: str | Path = "generated",
    check: Callable[[str, str | Path], list[str]] | None = None,
) -> Path:
    """Build ``model_path`` in ``parametrization`` and write ``<out_dir>/<model>_<param>.py``.

    ``check(source, model_path)`` (e.g. :func:`kinegen.runtime.check_source`) runs on the
    new module's text before it is written; if it raises, nothing is written. Everything
    that can fail happens before the (atomic) write.
    """
    model = load(model_path)
    param = get(parametrization)
    source = generate_source(model, param)
    if check is not None:
        check(source, model_path)
    path = Path(out_dir) / f"{module_name(model, param)}.py"
    write_atomic(path, source)
    return path
