"""Modules imported at their first use, so that a command's start-up does not pay for them
(``kinegen --help`` needs neither NumPy nor SymPy): the standard library's ``LazyLoader``; and a
package's names imported when first read (:func:`exported`)."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Callable
from importlib import import_module
from types import ModuleType
from typing import Any


def lazy_import(name: str) -> ModuleType:
    """The module ``name``: already imported, or registered now and executed when one of its
    attributes is first read (an import error then surfaces at that first use)."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None:
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    loader = importlib.util.LazyLoader(spec.loader)
    spec.loader = loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    loader.exec_module(module)
    return module


def exported(package: str, where: dict[str, str]) -> Callable[[str], Any]:
    """A package's module ``__getattr__`` (PEP 562) giving each name of ``where`` (name -> the module
    that defines it) from that module, imported when the name is first read."""

    def __getattr__(name: str) -> Any:
        if name in where:
            return getattr(import_module(where[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
