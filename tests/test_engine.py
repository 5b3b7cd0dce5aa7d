"""SymEngine's steps of a build (kinegen.symbolic.engine), each against SymPy or Python's math."""

from __future__ import annotations

import math
import random

import symengine as se
import sympy as sp

from kinegen.symbolic import engine

x, y, t = sp.symbols("x y t", real=True)


def _value(expr: sp.Expr, point: dict) -> float:
    return float(expr.xreplace(point))


def test_irrational_constants_become_the_nearest_double_and_rationals_stay():
    expr = sp.sqrt(2) / 2 * x + sp.cos(sp.Rational(17, 50)) + 2 * sp.pi * t + sp.Rational(89, 50) * y
    frozen = engine.to_sympy(engine.freeze_numbers(se.sympify(expr)), {s.name: s for s in expr.free_symbols}, {})
    floats = {float(a) for a in frozen.atoms(sp.Float)}
    assert floats == {math.sqrt(2) / 2, math.cos(0.34), 2 * math.pi}
    assert sp.Rational(89, 50) in frozen.atoms(sp.Rational)
    assert frozen.free_symbols == {x, y, t} and all(s.is_real for s in frozen.free_symbols)  # the caller's own symbols


def test_the_gradient_is_sympys():
    expr = x**3 * y - sp.sin(x * t) * sp.sqrt(y**2 + 1) + sp.Rational(3, 7) * x * y * t
    found = engine.gradient(expr, [t, x, sp.Symbol("absent"), y])
    assert list(found) == [t, x, y]
    rng = random.Random(4)
    for _ in range(5):
        point = {s: rng.uniform(-2, 2) for s in (x, y, t)}
        for symbol, derivative in found.items():
            assert math.isclose(_value(derivative, point), _value(sp.diff(expr, symbol), point), rel_tol=1e-13, abs_tol=1e-13)


def test_eliminated_statements_give_the_expressions_back():
    h = sp.sqrt(x**2 + y**2)
    rows = [
        sp.Piecewise((1 - h**2 / 6, h < sp.Float(1e-4)), (sp.sin(h) / h, True)),
        sp.sin(h) * sp.cos(h) + h**2 * t,
        (sp.sin(h) + x * y) ** 2,
    ]
    temporaries, reduced = engine.eliminate(rows)
    assert [str(name) for name, _ in temporaries] == [f"_t{k}" for k in range(len(temporaries))]
    defined: set = set()
    for name, value in temporaries:  # each defined before it is used, and none is a condition
        assert value.free_symbols - {x, y, t} <= defined and not isinstance(value, sp.logic.boolalg.Boolean)
        defined.add(name)
    assert any(isinstance(r, sp.Piecewise) and r.args[0].cond.has(sp.StrictLessThan) for r in reduced)
    rng = random.Random(7)
    for _ in range(5):
        point = {s: rng.uniform(-2, 2) for s in (x, y, t)}
        values = dict(point)
        for name, value in temporaries:
            values[name] = _value(value, values)
        for row, again in zip(rows, reduced):
            assert math.isclose(_value(again, values), _value(row, point), rel_tol=1e-13)
