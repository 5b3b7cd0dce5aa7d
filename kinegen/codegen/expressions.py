"""Target-neutral preparation of expressions for printing."""

from __future__ import annotations

import sympy as sp


def freeze_numbers(expr: sp.Expr) -> sp.Expr:
    """Replace irrational numeric subexpressions (``sqrt(2)/2``, ``cos(17/50)``, ``2*pi``) by floats.

    Integers and rationals stay exact (Python folds ``89/50`` at compile time, C ``89.0/50.0``).
    """

    def is_constant(e: sp.Basic) -> bool:
        return isinstance(e, sp.Expr) and e.is_number and not e.is_Rational and not e.is_Float

    return expr.replace(is_constant, lambda e: sp.Float(float(sp.N(e, 30))))
