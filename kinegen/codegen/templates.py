"""The Jinja environment every backend renders its file skeletons with (``templates/`` of its folder)."""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from pathlib import Path

import jinja2

from kinegen.integrity import comment_text


def python_literal(value: object) -> str:
    """``repr`` of a value, with floats (also inside tuples) as round-trip decimals."""
    if isinstance(value, float):
        return repr(float(value))
    if isinstance(value, tuple):
        return as_tuple(value)
    return repr(value)


def as_tuple(values: Sequence) -> str:
    """A Python tuple literal: ``(a, b)``, ``(a,)`` or ``()``."""
    items = ", ".join(python_literal(v) for v in values)
    return f"({items},)" if len(values) == 1 else f"({items})"


@cache
def environment(folder: Path) -> jinja2.Environment:
    """Templates of ``folder``: undefined names are errors, text is kept exactly as written
    (no autoescape, trailing newline kept), so output is byte-for-byte reproducible."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(folder)),
        undefined=jinja2.StrictUndefined,
        autoescape=False,
        keep_trailing_newline=True,
    )
    env.filters["py"] = python_literal
    env.filters["tuple"] = as_tuple
    env.filters["comment"] = comment_text  # a user's text in a docstring or C comment
    return env
