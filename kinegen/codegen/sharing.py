"""One generated function per text: what both backends do with sections that print alike.

Seven of the excavator's nine cases drive the same cylinders and swing with other time functions
(the inputs are a slot, not a case's own symbols), so their driver sections print word for word
alike. A backend makes each such text once and has the other cases' kernels call it; the kept
functions' docs name the sections they also serve.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Protocol, TypeVar


class Documented(Protocol):
    doc: str


F = TypeVar("F", bound=Documented)


class SharedTexts:
    """The functions kept per text of one generated file."""

    def __init__(self) -> None:
        self._kept: dict[Hashable, list] = {}
        self._also: dict[int, tuple[str, list[str]]] = {}  # id of a kept function -> its own doc, the sections it also serves

    def share(self, text: Hashable, made: list[F], section: str) -> list[F]:
        """The functions to call for ``section``, whose functions would be ``made`` (``text``: theirs
        but for their names): ``made`` itself the first time, else the ones kept for the same text,
        each of whose docs then names ``section`` too (the caller drops ``made``)."""
        kept = self._kept.setdefault(text, made)
        if kept is not made:
            for function in kept:
                doc, others = self._also.setdefault(id(function), (function.doc, []))
                others.append(section)
                function.doc = f"{doc} The same function serves {', '.join(others)} (the same text)."
        return kept
