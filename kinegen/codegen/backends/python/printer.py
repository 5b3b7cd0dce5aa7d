"""The Python backend's printers: NumPy code (batches) and plain ``math`` code (one configuration)."""

from __future__ import annotations

import re

import sympy as sp
from sympy.printing.numpy import NumPyPrinter
from sympy.printing.pycode import PythonCodePrinter

from kinegen.codegen.expressions import PrecedenceOnce

#: NumPy names a generated module may import (scalars and arrays alike).
NUMPY_NAMES = (
    "abs", "arccos", "arcsin", "arctan", "arctan2", "cos", "cosh", "exp", "log",
    "pi", "sign", "sin", "sinh", "sqrt", "tan", "tanh",
)  # fmt: skip


class ModulePrinter(PrecedenceOnce, NumPyPrinter):
    """NumPy printer with bare function names and round-trip float literals."""

    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": False, "inline": True, "order": "none"})

    def _print_Float(self, expr: sp.Float) -> str:
        return _float(expr)

    def _print_Rational(self, expr: sp.Rational) -> str:
        return _rational(self, expr, NumPyPrinter)


class ScalarPrinter(PrecedenceOnce, PythonCodePrinter):
    """Plain Python with ``math.<function>`` and round-trip float literals (one configuration).

    Integer coefficients are printed as floats (``2.0*x``: CPython multiplies two floats
    faster than an int and a float) and squares of names as products (``(x*x)``: faster than
    ``x**2``, and the exactly rounded product); the values are the same. The generated
    plain-float functions run ~20 % faster for it.
    """

    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": True, "inline": True, "order": "none"})

    def _print_Integer(self, expr: sp.Integer) -> str:
        return repr(float(expr)) if abs(expr.p) < 2**53 else str(expr.p)

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        if expr.exp == 2 and expr.base.is_Symbol:
            name = self._print(expr.base)
            return f"({name}*{name})"
        return super()._print_Pow(expr, rational=rational)

    def _print_Float(self, expr: sp.Float) -> str:
        return _float(expr)

    def _print_Rational(self, expr: sp.Rational) -> str:
        return _rational(self, expr, PythonCodePrinter)


def _float(expr: sp.Float) -> str:
    return repr(float(expr))


def _rational(printer: PythonCodePrinter, expr: sp.Rational, base: type) -> str:
    """Small rationals as ``p/q`` (folded by Python at compile time), others as the nearest double."""
    if abs(expr.p) < 10**6 and expr.q < 10**6:
        return base._print_Rational(printer, expr)
    return repr(float(expr))  # a compacted geometry constant


def used_numpy_names(source: str) -> list[str]:
    """The NumPy names that ``source`` uses, sorted."""
    found = set(_NUMPY_NAME.findall(source))
    return [n for n in NUMPY_NAMES if n in found]


_NUMPY_NAME = re.compile(rf"(?<![\w.])({'|'.join(NUMPY_NAMES)})\b")
