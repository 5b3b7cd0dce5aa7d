"""Common-subexpression elimination and printing once per constraint shape.

Rows derived through :class:`kinegen.symbolic.assembly.Templates` carry their shape (the
same equation up to the names of their bodies and inputs) and the renaming from the
shape's placeholder symbols to their own. A *group* (the rows of one joint, one driver or
one body's normalization) is eliminated and printed once per distinct shape, in
placeholder names, by both printers (NumPy and plain ``math``); every group of that
shape then only renames the printed text (placeholders -> its symbols, temporaries ->
the function's next ``c<k>``). The links of a chain or the two sides of a symmetric pin
cost one CSE and one printing, however many there are.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import sympy as sp
from sympy.printing.codeprinter import CodePrinter

from kinegen.codegen.printer import freeze_numbers

Kind = str  # "phi", "jac", "nu", "gamma", ...

#: Statements per generated function part: Python's compiler needs ~60 bytes of memory per
#: byte of a function it compiles, so the functions of very large models are cut in parts.
PART_STATEMENTS = 5000


@dataclass(frozen=True)
class _Printed:
    """One shape after CSE, printed by both printers in placeholder names."""

    temporaries: list[tuple[str, str]]  # (array text, scalar text), temporaries named _t0, _t1, ...
    outputs: list[tuple[str, str] | None]  # per expression; None for an exact zero
    used: frozenset[sp.Symbol]  # placeholder symbols the texts use
    pattern: re.Pattern | None  # every placeholder or temporary name in the texts


@dataclass
class Block:
    """Expressions of one generated function, as text for both styles, and the symbols they use.

    ``offset`` is the index of the first output in the whole block when this is a part of
    one; ``groups`` the end (temporaries, outputs) and the symbols used of each group.
    """

    temporaries: list[tuple[str, str, str]] = field(default_factory=list)  # (name, array text, scalar text)
    outputs: list[tuple[str, str] | None] = field(default_factory=list)
    symbols: set[sp.Symbol] = field(default_factory=set)
    offset: int = 0
    groups: list[tuple[int, int, frozenset[sp.Symbol]]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.outputs)

    def parts(self, limit: int = PART_STATEMENTS) -> list[Block]:
        """The block cut at group boundaries into parts of at most about ``limit`` statements
        (one group is never cut: its temporaries are its own). A part's outputs keep their
        indices through ``offset``. A block within the limit is its own only part."""
        if len(self.temporaries) + len(self.outputs) <= limit or len(self.groups) < 2:
            return [self]
        parts: list[Block] = []
        t0 = o0 = 0
        current = Block(offset=0)
        for t1, o1, symbols in self.groups:
            size = len(current.temporaries) + len(current.outputs)
            if size and size + (t1 - t0) + (o1 - o0) > limit:
                parts.append(current)
                current = Block(offset=o0)
            current.temporaries += self.temporaries[t0:t1]
            current.outputs += self.outputs[o0:o1]
            current.symbols |= symbols
            current.groups.append((len(current.temporaries), len(current.outputs), symbols))
            t0, o0 = t1, o1
        parts.append(current)
        return parts


@dataclass(frozen=True)
class Group:
    """Expressions to emit together: a key naming their shape (None: not shared), a thunk
    giving them in placeholder symbols, and the renaming placeholder -> real symbol."""

    key: tuple | None
    expressions: Callable[[], list[sp.Expr]]
    rename: dict[sp.Symbol, sp.Symbol]


class Shapes:
    """Cache of eliminated and printed shapes for one generated module."""

    def __init__(self, array_printer: CodePrinter, scalar_printer: CodePrinter) -> None:
        self.printers = (array_printer, scalar_printer)
        self._printed: dict[tuple, _Printed] = {}

    def _print(self, expressions: list[sp.Expr]) -> _Printed:
        frozen = [freeze_numbers(e) for e in expressions]
        replacements, reduced = sp.cse(frozen, symbols=sp.numbered_symbols("_t"), order="canonical")
        array, scalar = self.printers
        temporaries = [(array.doprint(v), scalar.doprint(v)) for _, v in replacements]
        outputs = [None if e == 0 else (array.doprint(e), scalar.doprint(e)) for e in reduced]
        names = {t for t, _ in replacements}
        used = frozenset(
            set().union(*(e.free_symbols for e in reduced), *(v.free_symbols for _, v in replacements)) - names
        )
        words = sorted({str(s) for s in used} | {str(t) for t in names}, key=len, reverse=True)
        pattern = re.compile(r"\b(" + "|".join(map(re.escape, words)) + r")\b") if words else None
        return _Printed(temporaries, outputs, used, pattern)

    def block(self, groups: Sequence[Group], prefix: str = "c") -> Block:
        """The groups' expressions in order, temporaries ``{prefix}0, ...`` numbered through the block."""
        out = Block()
        for group in groups:
            printed = self._printed.get(group.key) if group.key is not None else None
            if printed is None:
                printed = self._print(group.expressions())
                if group.key is not None:
                    self._printed[group.key] = printed
            names = {str(g): str(group.rename.get(g, g)) for g in printed.used}
            start = len(out.temporaries)
            names.update({f"_t{k}": f"{prefix}{start + k}" for k in range(len(printed.temporaries))})

            def rename(text: str, names: dict[str, str] = names, printed: _Printed = printed) -> str:
                return printed.pattern.sub(lambda m: names[m.group(0)], text) if printed.pattern else text

            for k, (array_text, scalar_text) in enumerate(printed.temporaries):
                out.temporaries.append((f"{prefix}{start + k}", rename(array_text), rename(scalar_text)))
            out.outputs += [None if o is None else (rename(o[0]), rename(o[1])) for o in printed.outputs]
            symbols = frozenset(group.rename.get(g, g) for g in printed.used)
            out.symbols |= symbols
            out.groups.append((len(out.temporaries), len(out.outputs), symbols))
        return out
