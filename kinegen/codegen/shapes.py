"""Common-subexpression elimination and printing once per constraint shape, for any printers.

Rows derived through :class:`kinegen.symbolic.assembly.Templates` carry their shape (the
same equation up to the names of their bodies and inputs) and the renaming from the
shape's placeholder symbols to their own. A *group* (the rows of one joint, one driver or
one body's normalization) is eliminated once per distinct shape, in placeholder names, and
printed once per shape by each printer of a backend (Python: NumPy and plain ``math``; C:
one); every group of that shape then only renames the printed text (placeholders -> its
symbols, temporaries -> the function's next ``c<k>``). The links of a chain or the two sides
of a symmetric pin cost one CSE and one printing, however many there are.

The eliminated statements themselves (:class:`Statements`, SymPy) are target-neutral and
live in the kernel description (:mod:`kinegen.codegen.kernels`); a :class:`Printing` is one
backend's printed text of them.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field

import sympy as sp
from sympy.printing.codeprinter import CodePrinter

from kinegen.codegen.expressions import PrecedenceOnce, freeze_numbers
from kinegen.symbolic import engine
from kinegen.symbolic.assembly import GENERIC_NAME

#: Statements per generated function part: Python's compiler needs ~60 bytes of memory per
#: byte of a function it compiles, and C compilers grow faster than linearly with a
#: function's length, so the functions of large models are cut in parts.
PART_STATEMENTS = 5000


@dataclass(frozen=True)
class Statements:
    """One group's expressions after CSE, in placeholder symbols: temporaries ``_t<k>`` in
    order, then the outputs (an exact zero stays ``0``)."""

    temporaries: tuple[tuple[sp.Symbol, sp.Expr], ...]
    outputs: tuple[sp.Expr, ...]

    @property
    def used(self) -> frozenset[sp.Symbol]:
        """Placeholder (argument) symbols the statements use."""
        names = {t for t, _ in self.temporaries}
        found = set().union(*(e.free_symbols for e in self.outputs), *(v.free_symbols for _, v in self.temporaries))
        return frozenset(found - names)


def code(printer: CodePrinter, expr: sp.Expr, has_re: bool | None = None) -> str:
    """``printer.doprint(expr)``'s text, printed by the printer's own methods without what
    ``doprint`` adds around them for one expression (its conversions and its pass replacing
    ``re(...)`` nodes, ~40 % of the time on the excavator's kernels): the same text whenever the
    expression has no ``re`` node and prints as one line needing no number declarations and nothing
    unsupported. Otherwise ``doprint`` itself prints it. ``has_re``: whether ``expr`` has an ``re``
    node, when the caller knows (one search for all its printers)."""
    if isinstance(expr, sp.Basic) and not (expr.has(sp.re) if has_re is None else has_re):
        printer._not_supported, printer._number_symbols = set(), set()
        text = printer._print(expr)
        clean = not (printer._not_supported or printer._number_symbols)
        printer._not_supported, printer._number_symbols = set(), set()
        if clean and "\n" not in text and "\r" not in text and text == text.lstrip(" \t"):
            return text
    return printer.doprint(expr)


def eliminate(expressions: Sequence[sp.Expr], symbols: dict[str, sp.Symbol] | None = None) -> Statements:
    """CSE of ``expressions`` (irrational constants frozen to doubles first) by SymEngine
    (:func:`kinegen.symbolic.engine.eliminate`; ``symbols``: SymEngine expressions' symbols)."""
    temporaries, reduced = engine.eliminate(expressions, symbols)
    return Statements(tuple(temporaries), tuple(reduced))


@dataclass(frozen=True)
class Group:
    """Expressions to emit together: a key naming their shape (None: not shared), a thunk
    giving them in placeholder symbols, and the renaming placeholder -> real symbol."""

    key: tuple | None
    expressions: Callable[[], list[sp.Expr]]
    rename: dict[sp.Symbol, sp.Symbol]
    #: expressions made in SymEngine: their symbols by name (:func:`kinegen.symbolic.engine.eliminate`)
    symbols: dict[str, sp.Symbol] | None = None


@dataclass(frozen=True)
class Definitions:
    """The rotation-matrix entries ``<body>_a<ij>`` (and an origin that is not stored,
    ``<body>_o<x,y,z>``) as expressions of the stored coordinates, the same for every body up
    to its name: printed once for the generic body, renamed as text."""

    bodies: tuple[tuple[str, tuple[sp.Symbol, ...], tuple[sp.Expr, ...]], ...]  # name, symbols, expressions
    generic: tuple[sp.Expr, ...]
    generic_name: str = GENERIC_NAME


@dataclass
class Block:
    """Expressions of one generated function, as text per printer (style), and the symbols they use.

    ``offset`` is the index of the first output in the whole block when this is a part of
    one; ``groups`` the end (temporaries, outputs) and the symbols used of each group.
    """

    temporaries: list[tuple[str, ...]] = field(default_factory=list)  # (name, text per style)
    outputs: list[tuple[str, ...] | None] = field(default_factory=list)  # text per style; None: an exact zero
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
class _Printed:
    """One shape's statements printed by every printer, in placeholder names."""

    temporaries: list[tuple[str, ...]]  # text per style, temporaries named _t0, _t1, ...
    outputs: list[tuple[str, ...] | None]  # per expression; None for an exact zero
    used: frozenset[sp.Symbol]  # placeholder symbols the texts use
    pattern: re.Pattern | None  # every placeholder or temporary name in the texts (and possibly other identifiers)


#: Every identifier in a printed text (a maximal run of word characters not starting with a digit):
#: renaming a group's text replaces those that are its placeholders or temporaries, the same
#: matches as a pattern of exactly those names between word boundaries.
_IDENTIFIER = re.compile(r"\b[^\W\d]\w*\b")


@dataclass(frozen=True)
class _Naming:
    """What renaming a group's printed text needs: the placeholder symbols its statements use and
    a pattern matching every placeholder or temporary name in the texts (and possibly other
    identifiers, which renaming leaves as they are)."""

    used: frozenset[sp.Symbol]
    pattern: re.Pattern | None


#: One printer's text of a group's statements: its temporaries' (named _t0, _t1, ...) and its
#: outputs' (None for an exact zero).
Texts = tuple[list[str], list[str | None]]


def _kind(printer: CodePrinter) -> str:
    """A printer's class: printers of one class print alike (kinegen's take no settings)."""
    return f"{type(printer).__module__}.{type(printer).__qualname__}"


class Shapes:
    """Cache of eliminated statements (shared by every backend) and of their text per printer.

    A group with a key is eliminated once per shape; one without (its expressions its own) each
    time its text is asked for by another set of printers (its statements are not kept). Texts
    are kept by printer class and group (its key, or the group itself)."""

    def __init__(self) -> None:
        self._statements: dict[tuple, Statements] = {}
        self._texts: dict[tuple[str, Hashable], Texts] = {}
        self._naming: dict[Hashable, _Naming] = {}
        self._held: dict[int, Group] = {}  # the groups without a key whose texts are kept: their ids stay theirs

    def statements(self, group: Group) -> Statements:
        """The group's statements, eliminated once per shape."""
        if group.key is None:
            return eliminate(group.expressions(), group.symbols)
        if group.key not in self._statements:
            self._statements[group.key] = eliminate(group.expressions(), group.symbols)
        return self._statements[group.key]

    def printing(self, printers: Sequence[CodePrinter]) -> Printing:
        """A printing of these statements by ``printers`` (one text per printer: the styles)."""
        return Printing(self, tuple(printers))

    def texts(self, printers: Sequence[CodePrinter], group: Group) -> tuple[list[Texts], _Naming]:
        """Each printer's text of the group's statements, and their naming; printed when first asked for."""
        identity = self._identity(group)
        missing = [p for p in printers if (_kind(p), identity) not in self._texts]
        if missing:
            self._print(group, missing)
        return [self._texts[_kind(p), identity] for p in printers], self._naming[identity]

    def _print(self, group: Group, printers: Sequence[CodePrinter]) -> None:
        statements = self.statements(group)
        identity = self._identity(group)
        values = [v for _, v in statements.temporaries]
        has_re = [isinstance(e, sp.Basic) and e.has(sp.re) for e in (*values, *statements.outputs)]
        for printer in printers:
            if isinstance(printer, PrecedenceOnce):
                printer.forget()  # the precedences kept while this group is printed
            temporaries = [code(printer, v, r) for v, r in zip(values, has_re)]
            outputs = [None if e == 0 else code(printer, e, r) for e, r in zip(statements.outputs, has_re[len(values) :])]
            self._texts[_kind(printer), identity] = (temporaries, outputs)
        if identity not in self._naming:
            used = statements.used
            names = {_text(t) for t, _ in statements.temporaries}
            words = {_text(s) for s in used} | names
            if not words:
                pattern = None
            elif all(w.isidentifier() for w in words):  # (kinegen's names: no pattern of its own to compile)
                pattern = _IDENTIFIER
            else:
                pattern = re.compile(r"\b(" + "|".join(map(re.escape, sorted(words, key=len, reverse=True))) + r")\b")
            self._naming[identity] = _Naming(used, pattern)

    def prepare(self, jobs: Sequence[tuple[CodePrinter, Group]], fork: bool = False) -> None:
        """Eliminate and print ``jobs`` (printer, group) now, each group's statements once for all its
        printers; with ``fork``, every other group in a forked process (its texts come back through a
        pipe): the two cores' share of a build. What is printed already is not printed again."""
        work = self.unprinted(jobs)
        if not fork or len(work) < 2:
            for group, printers in work:
                self._print(group, printers)
            return
        from kinegen.codegen.forked import Child

        child = Child(self.printed_texts, work[1::2])
        for group, printers in work[0::2]:
            self._print(group, printers)
        self.adopt(*child.result())

    def unprinted(self, jobs: Sequence[tuple[CodePrinter, Group]]) -> list[tuple[Group, list[CodePrinter]]]:
        """``jobs`` (printer, group) not printed yet, by group (the first of those with one key) with
        its printers (one of each kind), in the order the groups first come."""
        todo: dict[Hashable, tuple[Group, list[CodePrinter]]] = {}
        for printer, group in jobs:
            identity = self._identity(group)
            if (_kind(printer), identity) in self._texts:
                continue
            _, printers = todo.setdefault(identity, (group, []))
            if all(_kind(p) != _kind(printer) for p in printers):
                printers.append(printer)
        return list(todo.values())

    def adopt(self, texts: dict, naming: dict) -> None:
        """Texts and namings another process printed (:meth:`printed_texts`), kept as this one's."""
        self._texts.update(texts)
        for identity, value in naming.items():
            self._naming.setdefault(identity, value)

    def _identity(self, group: Group) -> Hashable:
        """What a group's texts are kept under: its key, or (a group without one) the group itself,
        held here so that its id is not another's later."""
        if group.key is not None:
            return group.key
        self._held[id(group)] = group
        return ("group", id(group))

    def printed_texts(self, work: list[tuple[Group, list[CodePrinter]]]) -> tuple[dict, dict]:
        """``work`` printed here: the texts and namings made for it (what a forked process sends back)."""
        before = set(self._texts)
        for group, printers in work:
            self._print(group, printers)
        identities = {self._identity(group) for group, _ in work}
        return {k: v for k, v in self._texts.items() if k not in before}, {k: self._naming[k] for k in identities}


def _text(symbol: sp.Symbol) -> str:
    """``str(symbol)``: a plain symbol's name without SymPy's printer (made anew for every ``str``)."""
    return symbol.name if type(symbol) is sp.Symbol else str(symbol)




class Printing:
    """Printed blocks for one backend: each group's statements as every printer prints them."""

    def __init__(self, shapes: Shapes, printers: tuple[CodePrinter, ...]) -> None:
        self.shapes = shapes
        self.printers = printers
        self._generic_definitions: list[tuple[str, ...]] | None = None

    def _printed(self, group: Group) -> _Printed:
        texts, naming = self.shapes.texts(self.printers, group)
        temporaries = list(zip(*(t for t, _ in texts)))
        outputs = [None if out[0] is None else tuple(out) for out in zip(*(o for _, o in texts))]
        return _Printed(temporaries, outputs, naming.used, naming.pattern)
    def definitions(self, definitions: Definitions, used: set[sp.Symbol]) -> tuple[list[tuple[str, ...]], set[sp.Symbol]]:
        """(name, text per style) of the rotation-matrix entries among ``used``, body by body,
        and the argument symbols they need. Each text is the generic body's, printed once and renamed."""
        if self._generic_definitions is None:
            self._generic_definitions = [tuple(code(p, freeze_numbers(e)) for p in self.printers) for e in definitions.generic]
        lines, needs = [], set()
        for body, symbols, values in definitions.bodies:
            for k, (symbol, value) in enumerate(zip(symbols, values)):
                if symbol in used:
                    lines.append((_text(symbol), *(t.replace(definitions.generic_name, body) for t in self._generic_definitions[k])))
                    needs |= value.free_symbols
        return lines, needs

    def block(self, groups: Sequence[Group], prefix: str = "c") -> Block:
        """The groups' expressions in order, temporaries ``{prefix}0, ...`` numbered through the block."""
        out = Block()
        for group in groups:
            printed = self._printed(group)
            names = {_text(g): _text(group.rename.get(g, g)) for g in printed.used}
            start = len(out.temporaries)
            names.update({f"_t{k}": f"{prefix}{start + k}" for k in range(len(printed.temporaries))})

            def rename(text: str, names: dict[str, str] = names, printed: _Printed = printed) -> str:
                return printed.pattern.sub(lambda m: names.get(m.group(0), m.group(0)), text) if printed.pattern else text

            for k, texts in enumerate(printed.temporaries):
                out.temporaries.append((f"{prefix}{start + k}", *(rename(t) for t in texts)))
            out.outputs += [None if o is None else tuple(rename(t) for t in o) for o in printed.outputs]
            symbols = frozenset(group.rename.get(g, g) for g in printed.used)
            out.symbols |= symbols
            out.groups.append((len(out.temporaries), len(out.outputs), symbols))
        return out
