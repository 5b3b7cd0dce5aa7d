"""Text a command computes once per model version, kept in kinegen's cache (``kinegen info``).

A model file's description takes SymPy to compute (seconds for the excavator, most of it SymPy's
import); the same bytes described by the same kinegen give the same text. The text is stored
under a key over the model file's bytes, what was asked, kinegen's version and its own code
(every source file of the package), with the warnings loading the model gave, which are given
again on a hit. This module imports nothing heavy: a hit costs a hash of the package's sources.
"""

from __future__ import annotations

import functools
import hashlib
import json
import warnings
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import TypeVar

import kinegen
from kinegen.files import cache_folder, write_atomic

T = TypeVar("T")


@functools.cache
def code_fingerprint(suffixes: tuple[str, ...] = (".py",)) -> str:
    """SHA-256 over kinegen's version, SymPy's and SymEngine's installed versions and the package's files ending in
    ``suffixes`` (the code generator's fingerprint adds its templates and C: ``.jinja``, ``.c``, ``.h``)."""
    root = Path(kinegen.__file__).resolve().parent
    versions = []
    for package in ("sympy", "symengine"):
        try:
            versions.append(metadata.version(package))
        except metadata.PackageNotFoundError:
            versions.append("?")
    key = hashlib.sha256("\n".join([kinegen.__version__, *versions]).encode())
    for file in sorted(p for p in root.rglob("*") if p.suffix in suffixes and "__pycache__" not in p.parts):
        key.update(f"\n{file.relative_to(root).as_posix()}\n".encode() + file.read_bytes())
    return key.hexdigest()


def cached_text(kind: str, source: bytes, question: str, compute: Callable[[], str]) -> str:
    """``compute()``'s text for the model bytes ``source`` and ``question`` (e.g. the parametrizations
    asked for), from the cache when this kinegen computed it before; the warnings it raised then
    are raised again (as :class:`UserWarning` subclasses are shown: through ``warnings``). A cache
    that cannot be read or written is passed by: the text is computed."""
    key = hashlib.sha256(b"\0".join([kind.encode(), source, question.encode(), code_fingerprint().encode()])).hexdigest()
    path = cache_folder() / kind / f"{key}.json"
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
        text, said = stored["text"], stored["warnings"]
        if isinstance(text, str) and isinstance(said, list) and all(isinstance(w, str) for w in said):
            for message in said:
                warnings.warn(message, UserWarning, stacklevel=2)
            return text
    except (OSError, ValueError, KeyError, TypeError):
        pass
    text, caught = given_and_recorded(compute)
    try:
        write_atomic(path, json.dumps({"text": text, "warnings": [str(w.message) for w in caught]}))
    except OSError:
        pass
    return text


def given_and_recorded(compute: Callable[[], T]) -> tuple[T, list[warnings.WarningMessage]]:
    """``compute()``'s value and the warnings it raised, each recorded (to be given again when a
    kept value is used) and given as it would have been (through ``warnings``, every one)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = compute()
    for warning in caught:
        warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)
    return value, caught
