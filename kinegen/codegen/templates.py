"""The Jinja environment every backend renders its file skeletons with (``templates/`` of its folder)."""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from pathlib import Path

import jinja2
import jinja2.bccache

from kinegen.files import cache_folder
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


class _CompiledTemplates(jinja2.FileSystemBytecodeCache):
    """Jinja's compiled templates kept in kinegen's cache (``templates/``): compiling the backends'
    templates is ~0.15 s of every build's process otherwise. Jinja keys each by the template's
    file and checks its source's checksum (and Python's version) when loading; it writes through
    a temporary file and a rename. A cache that cannot be written is not an error: the template is
    compiled again next time."""

    def dump_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        try:
            super().dump_bytecode(bucket)
        except OSError:
            pass


def _compiled_templates() -> jinja2.BytecodeCache | None:
    folder = cache_folder() / "templates"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return _CompiledTemplates(str(folder))


@cache
def environment(folder: Path) -> jinja2.Environment:
    """Templates of ``folder``: undefined names are errors, text is kept exactly as written
    (no autoescape, trailing newline kept), so output is byte-for-byte reproducible. Their compiled
    code is kept in kinegen's cache (:class:`_CompiledTemplates`)."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(folder)),
        undefined=jinja2.StrictUndefined,
        autoescape=False,
        keep_trailing_newline=True,
        bytecode_cache=_compiled_templates(),
    )
    env.filters["py"] = python_literal
    env.filters["tuple"] = as_tuple
    env.filters["comment"] = comment_text  # a user's text in a docstring or C comment
    return env
