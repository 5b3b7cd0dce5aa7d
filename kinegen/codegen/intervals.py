"""Interval enclosures of time functions, target-neutral: the straight-line program that bounds
expressions in t over a time interval [t0, t1], for the backends to print.

The step certificate (:meth:`kinegen.runtime.solver.Solver._certify`, ``certify`` in
kinegen_solver.c) must hold for the case's own inputs between two time points, not only for a
path through their samples: it needs, over each step, bounds on every input, its rate and its
second derivative. :func:`interval_program` turns the expressions (the ``inputs`` kernel's: u,
du/dt, d2u/dt2 of every driver) into a program of interval operations on the time interval --
one register per distinct subexpression, so shared subexpressions are evaluated once -- and each
backend prints it with its interval helpers (Python: NumPy over many steps at once; C: one step).

Every operation returns an interval that contains the exact real result for every value in its
arguments' intervals (the natural interval extension): the helpers round outward (by
:data:`RELATIVE_WIDENING` of the bound's magnitude plus :data:`ABSOLUTE_WIDENING`, which covers
libm's and IEEE arithmetic's rounding), a bound that cannot be computed (a function outside its
domain over part of the interval, an overflow) becomes infinite, and 0 times an infinite bound
counts as 0. So the enclosure is never too narrow; it may be wider than the true range (the
dependency problem), which only makes the certificate more cautious.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from fractions import Fraction

import sympy as sp
from sympy.core.evalf import PrecisionExhausted

from kinegen.model.expressions import T

#: the outward rounding of every operation's bounds: this fraction of the bound's magnitude ...
RELATIVE_WIDENING = 2.0**-49
#: ... plus this (results at or near zero)
ABSOLUTE_WIDENING = 1e-300

#: operations with one argument whose helper has the operation's name (``sin`` -> ``iv_sin``)
UNARY = ("neg", "inv", "sqrt", "exp", "log", "sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "abs", "sign")
_FUNCTIONS = {
    sp.exp: "exp", sp.log: "log", sp.sin: "sin", sp.cos: "cos", sp.tan: "tan", sp.asin: "asin", sp.acos: "acos",
    sp.atan: "atan", sp.sinh: "sinh", sp.cosh: "cosh", sp.tanh: "tanh", sp.Abs: "abs", sp.sign: "sign",
}  # fmt: skip


@dataclass(frozen=True)
class Operation:
    """One register of an interval program: ``op`` on the registers ``args``. ``value``: a
    constant's bounds (``const``), an integer power's exponent (``powi``), the bounds of a rational
    power's exponent (``powr``: x**r moves with r as much as with x where x is far from 1)."""

    op: str
    args: tuple[int, ...] = ()
    value: tuple[float, float] | int | None = None


@dataclass(frozen=True)
class IntervalProgram:
    """Registers in order (register 0 is the time interval, ``time``) and, per expression, the
    register that holds its enclosure -- None where the expression holds an operation no
    interval helper has (its enclosure is then the whole real line)."""

    operations: tuple[Operation, ...]
    outputs: tuple[int | None, ...]

    @property
    def ops(self) -> frozenset[str]:
        """The operations the program uses (a backend prints the helpers of these)."""
        return frozenset(o.op for o in self.operations)


class _Unsupported(Exception):
    """An expression with an operation no interval helper has."""


def constant_bounds(value: sp.Expr) -> tuple[float, float]:
    """The tightest doubles around an exact real constant: the same double twice where it is
    exactly representable (integers, binary fractions), else its neighbours. ValueError or
    TypeError where it is not a finite real number; PrecisionExhausted where SymPy cannot give it
    to 40 digits (the interval program encloses such a constant through its arguments: ``_pinned``)."""
    value = sp.sympify(value)  # (not doit(): SymPy 1.14 evaluates Abs(acos(tanh(10))) to 0; evalf does not)
    if value.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
        raise ValueError(f"{value} is not a finite real number")
    if value.is_Rational:
        number = float(value)
        if Fraction(number) == Fraction(int(value.p), int(value.q)):
            return number, number
        return math.nextafter(number, -math.inf), math.nextafter(number, math.inf)
    number = float(value.evalf(40, strict=True))
    if not math.isfinite(number):
        raise ValueError(f"{value} is not a finite real number")
    return math.nextafter(number, -math.inf), math.nextafter(number, math.inf)


def interval_program(expressions: list[sp.Expr]) -> IntervalProgram:
    """The interval program of ``expressions`` (functions of the time symbol ``t`` and constants)."""
    operations: list[Operation] = [Operation("time")]
    made: dict[Operation, int] = {operations[0]: 0}  # an operation's register (each distinct one once)
    registers: dict[sp.Expr, int] = {T: 0}  # an expression's register

    def emit(operation: Operation) -> int:
        if operation not in made:
            made[operation] = len(operations)
            operations.append(operation)
        return made[operation]

    def fold(op: str, items: list[int]) -> int:
        result = items[0]
        for item in items[1:]:
            result = emit(Operation(op, (result, item)))
        return result

    def register(e: sp.Expr) -> int:
        if e in registers:
            return registers[e]
        if e.is_Symbol:
            raise _Unsupported(f"symbol {e}")
        if _constant(e):
            if e.has(sp.zoo, sp.nan, sp.oo, -sp.oo, sp.I):
                raise _Unsupported(f"constant {e}")
            # whether it is real, its value to 40 digits says, not SymPy's assumptions: SymPy 1.14 answers
            # ((2*acos(tanh(10)))**-1)**(1/3) (17.66) is_real False or raises TypeError, as its shuffled
            # queries fall (found by Hypothesis), which made the program depend on SymPy's random state
            try:
                bounds = constant_bounds(e)
            except (TypeError, ValueError):  # not a real number (log(-1) * log(-1) stays complex in double precision)
                raise _Unsupported(f"constant {e}") from None
            result = emit(Operation("const", value=bounds))
        elif e.is_Add or e.is_Mul:  # the constant terms or factors as one exact constant, first
            constant = [a for a in e.args if _constant(a)]
            rest = sorted((a for a in e.args if not _constant(a)), key=sp.default_sort_key)
            op, unit = ("add", sp.Integer(0)) if e.is_Add else ("mul", sp.Integer(1))
            value = e.func(*constant) if constant else unit
            if not _constant(value):  # pinned constants whose sum or product is not (1 - 0.999...): one by one
                rest, value = sorted(e.args, key=sp.default_sort_key), unit
            if not rest:  # every term or factor pinned, and so their exact sum or product (e itself is not: -|2| + |2|)
                result = register(value)
            else:
                result = fold(op, [register(a) for a in rest])
                if e.is_Mul and value == -1:
                    result = emit(Operation("neg", (result,)))
                elif value != unit:
                    result = emit(Operation(op, (register(value), result)))
        elif e.is_Pow:
            result = _power(e, register, emit)
        elif e.func == sp.atan2:
            result = emit(Operation("atan2", (register(e.args[0]), register(e.args[1]))))
        elif e.func in _FUNCTIONS:
            result = emit(Operation(_FUNCTIONS[e.func], (register(e.args[0]),)))
        else:
            raise _Unsupported(str(e.func))
        registers[e] = result
        return result

    outputs: list[int | None] = []
    for expression in expressions:
        try:
            outputs.append(register(sp.sympify(expression)))
        except _Unsupported:
            outputs.append(None)
    return IntervalProgram(tuple(operations), tuple(outputs))


def _constant(e: sp.Expr) -> bool:
    """Whether ``e`` is enclosed as one constant (its value to 40 digits, :func:`constant_bounds`): a
    number without ``t`` -- unless atan2 is in it. atan2 jumps by 2 pi across the negative x axis, and
    a constant on that axis (``atan2(tan(pi), -1/2)``, exactly pi) evaluates to either side of the
    jump (-pi there, found by Hypothesis): its arguments are enclosed instead, and the interval atan2
    gives [-pi, pi] where they touch the axis."""
    return e.is_number and not e.free_symbols and not e.has(sp.atan2) and _pinned(e)


@functools.lru_cache(maxsize=4096)
def _pinned(e: sp.Expr) -> bool:
    """Whether SymPy gives a constant's value to 40 significant digits. Not where it cancels to
    zero or near it: ``sin(pi)/sin(pi)`` (0/0) evaluated to 128 without that precision and was
    enclosed as [128, 128] (found by Hypothesis); such a constant is enclosed through its
    arguments, so the interval division by an enclosure of sin(pi), which holds 0, is unbounded."""
    if e.is_Rational:
        return True
    try:
        e.evalf(40, strict=True)
    except PrecisionExhausted:
        return False
    except (TypeError, ValueError):  # not a real number: refused where it is registered
        return True
    return True


def _power(e: sp.Pow, register, emit) -> int:
    base, exponent = e.args
    if exponent.is_Integer:
        n = int(exponent)
        if n == -1:
            return emit(Operation("inv", (register(base),)))
        power = emit(Operation("powi", (register(base),), abs(n))) if abs(n) != 1 else register(base)
        return emit(Operation("inv", (power,))) if n < 0 else power
    if exponent == sp.Rational(1, 2):
        return emit(Operation("sqrt", (register(base),)))
    if exponent == -sp.Rational(1, 2):
        return emit(Operation("inv", (emit(Operation("sqrt", (register(base),))),)))
    if exponent.is_Rational:  # x**(p/q) of x >= 0 (the real function's domain for even q; kinegen's time functions are real)
        return emit(Operation("powr", (register(base),), constant_bounds(exponent)))
    if base == sp.E:
        return emit(Operation("exp", (register(exponent),)))
    # a**b = exp(b log a)
    return emit(Operation("exp", (emit(Operation("mul", (register(exponent), emit(Operation("log", (register(base),)))))),)))
