"""The C backend's printer: SymPy's C99 printer with the Python backend's number and power
conventions, so that the C and the plain-float Python kernels compute the same roundings
wherever they can (tested to agree to 1e-12)."""

from __future__ import annotations

import sympy as sp
from sympy.printing.c import C99CodePrinter

from kinegen.codegen.expressions import PrecedenceOnce


class CPrinter(PrecedenceOnce, C99CodePrinter):
    """Doubles only. Small rationals as ``p.0/q.0`` (folded by the compiler to the correctly
    rounded double, as Python folds ``p/q``), others as their nearest double; squares of names
    as products (``(x*x)``: exact, as the Python printer writes them); ``x**-1/2`` as
    ``1.0/sqrt(x)``; ``sign`` as a comparison (0 at 0, as NumPy)."""

    def __init__(self) -> None:
        super().__init__({"strict": True, "order": "none"})

    def _print_Float(self, expr: sp.Float) -> str:
        return repr(float(expr))

    def _print_Rational(self, expr: sp.Rational) -> str:
        if abs(expr.p) < 10**6 and expr.q < 10**6:
            return f"{expr.p}.0/{expr.q}.0"
        return repr(float(expr))

    def _print_Integer(self, expr: sp.Integer) -> str:
        return f"{expr.p}.0" if abs(expr.p) < 2**53 else repr(float(expr))

    def _print_Pow(self, expr: sp.Pow) -> str:
        if expr.exp == 2 and expr.base.is_Symbol:
            name = self._print(expr.base)
            return f"({name}*{name})"
        if expr.exp == -sp.Rational(1, 2):
            return f"1.0/sqrt({self._print(expr.base)})"
        return super()._print_Pow(expr)

    def _print_sign(self, expr: sp.Expr) -> str:
        argument = self._print(expr.args[0])
        return f"((double)(({argument}) > 0.0) - (double)(({argument}) < 0.0))"
