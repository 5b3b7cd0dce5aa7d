"""Code-generation backends, one folder each (``python/``, ``c/``): a printer, file skeletons
as Jinja templates and a small config. Each exposes ``render(description, stem)`` returning
``{file name: text}`` for a :class:`kinegen.codegen.kernels.ModuleDescription`, and ``jobs(description)``:
what it prints, as (printer, group) pairs (printed ahead, shared between processes: ``Shapes.prepare``); adding a
target means adding a folder and naming it here."""

from __future__ import annotations

from collections.abc import Callable
from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from kinegen.codegen.kernels import ModuleDescription

#: target name -> module of its backend
TARGETS = {"python": "kinegen.codegen.backends.python", "c": "kinegen.codegen.backends.c"}


def get(target: str) -> Callable[[ModuleDescription, str], dict[str, str]]:
    """The ``render`` function of the backend called ``target``."""
    if target not in TARGETS:
        raise ValueError(f"unknown target {target!r} (targets: {', '.join(TARGETS)})")
    return import_module(TARGETS[target]).render


def printers(target: str) -> tuple:
    """The printers the backend called ``target`` prints every section with (a section of the
    plain-float kernels may have more: :func:`jobs` says)."""
    if target not in TARGETS:
        raise ValueError(f"unknown target {target!r} (targets: {', '.join(TARGETS)})")
    return import_module(TARGETS[target]).printers()


def jobs(target: str, description: ModuleDescription) -> list:
    """The (printer, group) pairs the backend called ``target`` prints for ``description``."""
    if target not in TARGETS:
        raise ValueError(f"unknown target {target!r} (targets: {', '.join(TARGETS)})")
    return import_module(TARGETS[target]).jobs(description)
