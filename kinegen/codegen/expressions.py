"""Target-neutral preparation of expressions for printing."""

from __future__ import annotations

import sympy as sp
from sympy.printing.precedence import precedence


def freeze_numbers(expr: sp.Expr) -> sp.Expr:
    """Replace irrational numeric subexpressions (``sqrt(2)/2``, ``cos(17/50)``, ``2*pi``) by floats.

    Integers and rationals stay exact (Python folds ``89/50`` at compile time, C ``89.0/50.0``).
    """

    def is_constant(e: sp.Basic) -> bool:
        return isinstance(e, sp.Expr) and e.is_number and not e.is_Rational and not e.is_Float

    return expr.replace(is_constant, lambda e: sp.Float(float(sp.N(e, 30))))


class PrecedenceOnce:
    """A printer mixin: SymPy's ``parenthesize`` with each expression's precedence computed once and
    kept until :meth:`forget` (SymPy's asks for it up to twice per call, a product's each time
    through ``could_extract_minus_sign``: ~a quarter of printing the excavator's kernels). The same
    text: the precedence of an expression is a function of the expression. ``doprint`` forgets
    first, and so does :class:`kinegen.codegen.shapes.Shapes` before each group's statements: a
    printer kept for the process does not keep every expression it printed alive."""

    def forget(self) -> None:
        self.__dict__["_precedences"] = {}

    def doprint(self, expr: sp.Basic, assign_to: object = None) -> str:
        self.forget()
        return super().doprint(expr, assign_to)

    def parenthesize(self, item: sp.Basic, level: int, strict: bool = False) -> str:
        known = self.__dict__.setdefault("_precedences", {})
        value = known.get(item)
        if value is None:
            value = known[item] = precedence(item)
        if value < level or (not strict and value <= level):
            return f"({self._print(item)})"
        return self._print(item)
