"""SymEngine for the heavy symbolic steps: differentiation and common-subexpression elimination.

kinegen derives and prints in SymPy; SymEngine (C++, pinned exactly as SymPy is) does the two
steps that dominate a build, and its results come back as SymPy expressions:

- :func:`gradient`: the derivatives of an expression with respect to some of its symbols;
- :func:`eliminate`: CSE of a group of expressions, temporaries ``_t0, _t1, ...`` in order;
- :class:`Bridge`: other arithmetic in SymEngine on SymPy inputs (the inertia rows).

Back in SymPy, sums, products and powers are built unevaluated from SymEngine's arguments,
which are already canonical (SymPy evaluating them again would cost more than SymEngine's
whole step), and every symbol is the caller's own (its assumptions kept). SymEngine orders
terms by its own structural hash, not Python's, so nothing here depends on ``PYTHONHASHSEED``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import symengine as se
import sympy as sp
from symengine.lib.symengine_wrapper import Boolean, Constant

#: SymEngine's version, in every generated file's header (as SymPy's): the CSE's temporaries are its.
VERSION: str = se.__version__


def gradient(expr: sp.Expr, symbols: Sequence[sp.Symbol]) -> dict[sp.Symbol, sp.Expr]:
    """The derivatives of ``expr`` with respect to those of ``symbols`` it contains (in their
    order), identically zero ones included."""
    free = expr.free_symbols
    present = [s for s in symbols if s in free]
    if not present:
        return {}
    bridge = Bridge()
    converted = bridge.to(expr)
    return {s: bridge.back(converted.diff(se.Symbol(s.name))) for s in present}


class Bridge:
    """Arithmetic in SymEngine on SymPy expressions: :meth:`to` converts (remembering each symbol),
    :meth:`back` gives a result back to SymPy with the remembered symbols (assumptions kept),
    unevaluated as :func:`to_sympy`."""

    def __init__(self) -> None:
        self.names: dict[str, sp.Symbol] = {}
        self._memo: dict[se.Basic, sp.Expr] = {}

    def to(self, value):
        """A SymPy expression (a number, a matrix: SymEngine's DenseMatrix) in SymEngine."""
        if isinstance(value, sp.MatrixBase):
            return se.Matrix(value.rows, value.cols, [self.to(x) for x in value])
        value = sp.sympify(value)
        self.names.update(_names(value.free_symbols))
        return se.sympify(value)

    def back(self, value: se.Basic) -> sp.Expr:
        """A SymEngine result in SymPy."""
        return to_sympy(value, self.names, self._memo)


def eliminate(
    expressions: Sequence[sp.Expr | se.Basic], symbols: dict[str, sp.Symbol] | None = None
) -> tuple[list[tuple[sp.Symbol, sp.Expr]], list[sp.Expr]]:
    """SymEngine's CSE of ``expressions``, irrational constants frozen to doubles first
    (:func:`freeze_numbers`): the temporaries as (``_t<k>``, value) in SymEngine's order (each
    defined before its first use), and the expressions reduced. ``expressions`` are SymPy's, or
    SymEngine's (made in SymEngine, not converted there and back) with ``symbols``: their symbols
    by name (a :class:`Bridge`'s ``names``), which the results hold."""
    names = dict(symbols or {})
    names.update(_names(s for e in expressions if isinstance(e, sp.Basic) for s in e.free_symbols))
    replacements, reduced = se.cse([freeze_numbers(e if isinstance(e, se.Basic) else se.sympify(e)) for e in expressions])
    # a condition (a Piecewise's ``h < 1e-4``) is not a number: written out where it is used, not a temporary
    conditions = {t: value for t, value in replacements if isinstance(value, Boolean)}
    replacements = [(t, value) for t, value in replacements if t not in conditions]
    for k, (temporary, _) in enumerate(replacements):  # SymEngine names them apart from every symbol given
        names[temporary.name] = sp.Symbol(f"_t{k}")
    memo: dict[se.Basic, sp.Expr] = {}
    temporaries = [(names[t.name], to_sympy(value, names, memo, conditions)) for t, value in replacements]
    return temporaries, [to_sympy(e, names, memo, conditions) for e in reduced]


def freeze_numbers(expr: se.Basic) -> se.Basic:
    """Each largest irrational constant subexpression of ``expr`` (``sqrt(2)/2``, ``cos(17/50)``,
    ``2*pi``) as the double nearest its value (evaluated by SymPy to 30 digits). Integers and
    rationals stay exact (Python folds ``89/50`` at compile time, C ``89.0/50.0``)."""
    memo: dict[se.Basic, tuple[se.Basic, bool]] = {}

    def frozen(e: se.Basic) -> tuple[se.Basic, bool]:  # (the expression frozen, whether it is a constant)
        if e in memo:
            return memo[e]
        if not e.args:
            out = (e, e.is_Number or isinstance(e, Constant))  # pi, E: constants
        else:
            parts = [frozen(a) for a in e.args]
            if all(constant for _, constant in parts) and not isinstance(e, Boolean):
                out = (e, True)
            else:
                args = [_double(a) if constant else a for a, constant in parts]
                out = (_rebuilt(e, args) if any(a is not b for a, b in zip(args, e.args)) else e, False)
        memo[e] = out
        return out

    result, constant = frozen(expr)
    return _double(result) if constant else result


def to_sympy(
    expr: se.Basic, symbols: dict[str, sp.Symbol], memo: dict[se.Basic, sp.Expr], conditions: dict[se.Basic, se.Basic] | None = None
) -> sp.Expr:
    """``expr`` as SymPy: sums, products and powers built unevaluated from SymEngine's (already
    canonical) arguments, each symbol the one of ``symbols`` of its name; ``memo`` shares
    subexpressions converted already. ``conditions``: CSE temporaries that stand for a condition,
    written out in their place (SymEngine's Piecewise holds such a temporary ``x`` as ``x == True``)."""
    if expr in memo:
        return memo[expr]
    conditions = conditions or {}
    if isinstance(expr, se.Symbol):
        out = to_sympy(conditions[expr], symbols, memo, conditions) if expr in conditions else symbols.get(expr.name) or sp.Symbol(expr.name)
    elif not expr.args:
        out = expr._sympy_()
    elif isinstance(expr, se.Equality) and se.true in expr.args and any(a in conditions for a in expr.args):
        out = to_sympy(next(a for a in expr.args if a in conditions), symbols, memo, conditions)
    else:
        args = [to_sympy(a, symbols, memo, conditions) for a in expr.args]
        # sums, products and powers as SymPy's ``evaluate=False`` constructors make them, without their
        # checks and cache (~half of the conversion): the arguments are SymPy expressions, none a matrix
        if isinstance(expr, se.Add):
            out = sp.Add._from_args(args)
        elif isinstance(expr, se.Mul):
            out = sp.Mul._from_args(args)
        elif isinstance(expr, se.Pow):
            out = sp.Expr.__new__(sp.Pow, *args)
            out.is_commutative = args[0].is_commutative and args[1].is_commutative
        elif isinstance(expr, se.Piecewise):
            out = sp.Piecewise(*zip(args[::2], args[1::2]))
        else:  # a function, a relation: SymPy's own conversion, then the caller's symbols
            converted = expr._sympy_()
            out = converted.xreplace({s: symbols[s.name] for s in converted.free_symbols if s.name in symbols})
    memo[expr] = out
    return out


def _names(symbols: Iterable[sp.Symbol]) -> dict[str, sp.Symbol]:
    return {s.name: s for s in symbols}


def _rebuilt(e: se.Basic, args: list[se.Basic]) -> se.Basic:
    """``e`` of the same kind with other ``args`` (a Piecewise's are flat: value, condition, ...)."""
    if isinstance(e, se.Piecewise):
        return se.Piecewise(*zip(args[::2], args[1::2]))
    return type(e)(*args)


def _double(e: se.Basic) -> se.Basic:
    """A constant as SymEngine's double nearest its value; an integer, rational or double as it is."""
    if e.is_Number:
        return e
    return se.RealDouble(float(sp.N(e._sympy_(), 30)))
