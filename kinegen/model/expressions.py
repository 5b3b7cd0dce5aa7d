"""Safe parsing of model expressions into exact SymPy expressions.

Expressions are parsed with :mod:`ast` and translated node by node; nothing is ever
passed to ``eval``, ``exec`` or ``sympify``. Allowed: numbers, the time ``t``, ``pi``,
named parameters, ``+ - * / **``, unary minus and the functions in :data:`FUNCTIONS`.
Decimal literals become exact rationals (``1.78`` -> ``89/50``).
"""

from __future__ import annotations

import ast
import functools
import math
from collections.abc import Mapping

import symengine as se
import sympy as sp

from kinegen.errors import ExpressionError, shown

#: Whitelisted functions, by the name used in model files.
FUNCTIONS: dict[str, object] = {
    "sin": sp.sin,
    "cos": sp.cos,
    "tan": sp.tan,
    "asin": sp.asin,
    "acos": sp.acos,
    "atan": sp.atan,
    "atan2": sp.atan2,
    "sinh": sp.sinh,
    "cosh": sp.cosh,
    "tanh": sp.tanh,
    "exp": sp.exp,
    "log": sp.log,
    "sqrt": sp.sqrt,
    "abs": sp.Abs,
}
_ARITY = {"atan2": 2}
#: SymPy functions the code generators print: the whitelist and what their derivatives bring
#: (``sign`` from ``abs``); a time function whose derivatives hold anything else is refused.
PRINTABLE = frozenset({"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log", "Abs", "sign"})

#: Time symbol shared by every expression.
T = sp.Symbol("t", real=True)

MAX_LENGTH = 2000
MAX_DEPTH = 40
MAX_MAGNITUDE = 1e12
#: Digits of the largest exact integer (numerator or denominator) an expression may hold: nested
#: powers of allowed numbers grow without bound otherwise (``((10**12)**64)**64`` has 49,153).
MAX_DIGITS = 1000
_MAX_BITS = int(MAX_DIGITS * 3.3219280948873626) + 1
_BINARY = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.Pow: lambda a, b: a**b,
}


def number(value: float | int) -> sp.Expr:
    """An exact SymPy number for a finite ``int`` or ``float`` (floats via their shortest repr)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ExpressionError(f"expected a number, got {type(value).__name__} {shown(value)}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ExpressionError(f"number {shown(value)} is not finite")
    if abs(value) > MAX_MAGNITUDE:
        raise ExpressionError(f"number {shown(value)} exceeds the allowed magnitude {MAX_MAGNITUDE:g}")
    if isinstance(value, int):
        return sp.Integer(value)
    return sp.Rational(repr(value))


_FLOAT_FUNCTIONS = {
    sp.sin: math.sin, sp.cos: math.cos, sp.tan: math.tan, sp.asin: math.asin, sp.acos: math.acos, sp.atan: math.atan,
    sp.sinh: math.sinh, sp.cosh: math.cosh, sp.tanh: math.tanh, sp.exp: math.exp, sp.log: math.log, sp.Abs: abs,
    sp.atan2: math.atan2, sp.sign: lambda x: math.copysign(1.0, x) if x else 0.0,
}  # fmt: skip


def _bits(expr: sp.Expr) -> int:
    """Bits of the largest numerator or denominator among the exact numbers in ``expr``."""
    return max((max(r.p.bit_length(), r.q.bit_length()) for r in expr.atoms(sp.Rational)), default=0)


def _bounded(expr: sp.Expr) -> sp.Expr:
    """``expr``, refused when an exact number in it has more than :data:`MAX_DIGITS` digits."""
    if _bits(expr) > _MAX_BITS:
        raise ExpressionError(f"an exact number in this expression has more than {MAX_DIGITS} digits")
    return expr


def float_value(expr: sp.Expr) -> float:
    """A constant expression in double precision, innermost first; ExpressionError where any
    part of it is not a finite real double (``asin(2)``, ``log(0)``, ``sinh(sinh(20))``).

    It bounds the work of exact evaluation: SymPy evaluating ``sin(sinh(sinh(20)))`` to
    a few digits needs the argument to 10^8 digits and does not return for minutes."""
    try:
        value = _float(expr)
    except (ArithmeticError, ValueError, TypeError):
        value = float("nan")
    if not math.isfinite(value):
        raise ExpressionError(f"{sp.sstr(expr)[:80]} is not a finite real number (in double precision)")
    return value


def _float(e: sp.Expr) -> float:
    if not e.args:
        return float(e)  # numbers, pi, E (zoo, nan, I raise TypeError)
    args = [_float(a) for a in e.args]
    if e.is_Add:
        return math.fsum(args)
    if e.is_Mul:
        return math.prod(args)
    if e.is_Pow:
        return math.pow(*args)
    function = _FLOAT_FUNCTIONS.get(e.func)
    if function is None:
        raise ValueError(f"no double-precision evaluation of {e.func}")
    return float(function(*args))


@functools.lru_cache(maxsize=1 << 16)  # the loader's checks and the code generator ask for the same ones
def time_derivative(function: sp.Expr) -> sp.Expr:
    """d/dt of a time function, without impulses: where ``abs`` makes a kink, the second
    derivative's ``DiracDelta`` is dropped (a driver's rate jumps there; its acceleration is
    taken as the one on either side, 0 at the kink itself as ``sign(0) = 0``). A function is
    real wherever it is valid, so the real and imaginary parts SymPy keeps for the derivative
    of ``abs`` of an expression it cannot prove real are the expression and 0."""
    if _smooth(function):
        return _engine_derivative(function)
    derivative = sp.diff(function, T)
    if derivative.has(sp.DiracDelta):
        derivative = derivative.replace(sp.DiracDelta, lambda *_: sp.Integer(0))
    if derivative.has(sp.re, sp.im, sp.conjugate):  # d|f|/dt of an f SymPy cannot prove real (asin(t))
        derivative = derivative.replace(sp.re, lambda x: x).replace(sp.im, lambda x: sp.Integer(0))
        derivative = derivative.replace(sp.conjugate, lambda x: x)  # real where f is (elsewhere: nan, refused)
    return derivative


#: Functions whose derivatives SymEngine and SymPy agree on everywhere they are defined (no ``abs``, no
#: inverse functions with their domains' ``re``/``im`` parts): a time function of only these is derived by SymEngine.
_SMOOTH = (sp.sin, sp.cos, sp.tan, sp.sinh, sp.cosh, sp.tanh, sp.exp, sp.log)


def _smooth(function: sp.Expr) -> bool:
    return all(
        isinstance(node, (sp.Add, sp.Mul, sp.Pow, sp.Symbol, sp.Number, sp.NumberSymbol, *_SMOOTH)) for node in sp.preorder_traversal(function)
    )


def _engine_derivative(function: sp.Expr) -> sp.Expr:
    """d/dt of ``function`` by SymEngine (~4 times faster than SymPy's on a driver's tanh ramps: its
    assumptions), back in SymPy (evaluated, so in SymPy's canonical form) with the function's own symbols."""
    names = {s.name: s for s in function.free_symbols}
    derivative = sp.sympify(se.sympify(function).diff(se.Symbol(T.name)))
    return derivative.xreplace({s: names[s.name] for s in derivative.free_symbols if s.name in names})


def parse(
    text: str | int | float,
    parameters: Mapping[str, sp.Expr] | None = None,
    allow_time: bool = True,
) -> sp.Expr:
    """Parse ``text`` into an exact SymPy expression.

    ``parameters`` maps names to already-parsed values; ``t`` is the time symbol
    :data:`T` when ``allow_time`` is true. Raises :class:`ExpressionError` on anything
    outside the whitelist.
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return number(text)
    if not isinstance(text, str):
        raise ExpressionError(f"expected a number or an expression string, got {type(text).__name__}")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"expression longer than {MAX_LENGTH} characters")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError) as exc:
        raise ExpressionError(f"cannot parse {shown(text)}: {exc.msg if hasattr(exc, 'msg') else exc}") from None
    except RecursionError:
        raise ExpressionError("expression nested too deeply") from None
    return _Translator(parameters or {}, allow_time).visit(tree.body, 0)


class _Translator:
    def __init__(self, parameters: Mapping[str, sp.Expr], allow_time: bool) -> None:
        self.parameters = parameters
        self.allow_time = allow_time

    def visit(self, node: ast.AST, depth: int) -> sp.Expr:
        if depth > MAX_DEPTH:
            raise ExpressionError(f"expression nested deeper than {MAX_DEPTH} levels")
        if isinstance(node, ast.Constant):
            return (
                number(node.value)
                if not isinstance(node.value, (str, bytes, complex))
                else self._reject(f"constant {shown(node.value)} is not a real number")
            )
        if isinstance(node, ast.Name):
            return self._name(node.id)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            operand = self.visit(node.operand, depth + 1)
            return -operand if isinstance(node.op, ast.USub) else operand
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            left = self.visit(node.left, depth + 1)
            right = self.visit(node.right, depth + 1)
            if isinstance(node.op, ast.Div) and right == 0:
                raise ExpressionError("division by zero")
            if isinstance(node.op, ast.Pow):
                self._check_power(left, right)
            return _bounded(_BINARY[type(node.op)](left, right))
        if isinstance(node, ast.Call):
            return self._call(node, depth)
        if isinstance(node, ast.Attribute):
            return self._reject("attribute access is not allowed")
        return self._reject(f"{type(node).__name__} is not allowed (only numbers, names, + - * / ** and math functions)")

    def _name(self, name: str) -> sp.Expr:
        if name.startswith("_"):
            return self._reject(f"name {shown(name)} is not allowed")
        if name == "t":
            if not self.allow_time:
                return self._reject("time 't' is not allowed here")
            return T
        if name == "pi":
            return sp.pi
        if name in self.parameters:
            return self.parameters[name]
        if name in FUNCTIONS:
            return self._reject(f"function {shown(name)} must be called")
        return self._reject(f"unknown name {shown(name)}")

    def _call(self, node: ast.Call, depth: int) -> sp.Expr:
        if not isinstance(node.func, ast.Name):
            return self._reject("this call is not allowed: only direct calls of whitelisted functions")
        name = node.func.id
        if name not in FUNCTIONS:
            return self._reject(f"function {shown(name)} is not allowed (allowed: {', '.join(sorted(FUNCTIONS))})")
        if node.keywords:
            return self._reject(f"keyword arguments in {name}() are not allowed")
        arity = _ARITY.get(name, 1)
        if len(node.args) != arity or any(isinstance(a, ast.Starred) for a in node.args):
            return self._reject(f"{name}() takes {arity} argument(s)")
        args = [self.visit(a, depth + 1) for a in node.args]
        if any(a.has(sp.nan, sp.zoo, sp.oo, -sp.oo) for a in args):
            return self._reject(f"an argument of {name}() is not a finite number")
        try:
            value = FUNCTIONS[name](*args)
        except (TypeError, ValueError, ArithmeticError) as exc:  # SymPy refusing its own arguments
            return self._reject(f"{name}() cannot be evaluated here: {exc}")
        if value.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
            return self._reject(f"{name}() of these arguments is not a finite number")
        return value

    @staticmethod
    def _check_power(base: sp.Expr, exponent: sp.Expr) -> None:
        if not exponent.is_number:
            return
        try:
            value = complex(exponent)
        except (TypeError, ValueError):
            raise ExpressionError(f"exponent {exponent} is not a real number") from None
        if value.imag != 0 or not abs(value.real) <= 64:
            raise ExpressionError(f"exponent {exponent} is not a real number of magnitude at most 64")
        if _bits(base) * abs(value.real) > _MAX_BITS:
            raise ExpressionError(f"the exact value of this power would have more than {MAX_DIGITS} digits")

    @staticmethod
    def _reject(message: str) -> sp.Expr:
        raise ExpressionError(message)


COMPACT_DIGITS = 34


def compact(value: sp.Expr) -> sp.Expr:
    """A geometry constant in compact exact form.

    Rationals and small algebraic numbers (``sqrt(2)/2``) stay as they are; a constant
    containing transcendental functions (``cos(3726279298/10**10)``), large numbers under a
    root, or a large tree becomes
    the exact decimal rational of its first 34 significant digits, so that it is one
    number (not a tree) in every derivative, while evaluation stays exact rational.
    """
    if value.free_symbols:  # depends on design parameters: kept as an expression of them
        return value
    small = all(abs(r.p) < 10**6 and r.q < 10**6 for r in value.atoms(sp.Rational))
    if value.is_Rational or (small and not value.has(sp.Function) and sp.count_ops(value) <= 12):
        return value
    return sp.Rational(str(sp.N(value, COMPACT_DIGITS)))
