"""The model expression parser: exact results, and hostile input rejected without running it."""

from __future__ import annotations

import pytest
import sympy as sp

from kinegen.errors import ExpressionError
from kinegen.model.expressions import T, parse


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("pi/2 + t**2", sp.pi / 2 + T**2),
        ("0.3*sin(2*pi*t)", sp.Rational(3, 10) * sp.sin(2 * sp.pi * T)),
        ("1.78", sp.Rational(89, 50)),
        ("-2 + +3", sp.Integer(1)),
        ("atan2(1, 1)", sp.pi / 4),
        ("sqrt(2)/2", sp.sqrt(2) / 2),
        (1.5, sp.Rational(3, 2)),
        (7, sp.Integer(7)),
    ],
)
def test_parses_to_exact_sympy(text, expected):
    assert sp.simplify(parse(text) - expected) == 0


def test_parameters_are_substituted():
    assert parse("2*L + t", {"L": sp.Rational(89, 50)}) == sp.Rational(89, 25) + T


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("__import__('os').system('touch /tmp/kinegen-pwned')", "not allowed"),
        ("t.real", "attribute access"),
        ("(lambda: 1)()", "not allowed"),
        ("__builtins__", "not allowed"),
        ("open('/etc/passwd')", "not allowed"),
        ("[1, 2]", "not allowed"),
        ("'text'", "not a real number"),
        ("2**10**10", "exponent"),
        ("x + 1", "unknown name 'x'"),
        ("sin(t, t)", "argument"),
        ("sin(x=t)", "keyword"),
        ("1/0", "division by zero"),
        ("1e400", "not finite"),
        ("1e300", "magnitude"),
        ("sin(" * 60 + "t" + ")" * 60, "nested"),
        ("-" * 100 + "t", "nested"),
        ("t +", "cannot parse"),
        ("import os", "cannot parse"),
        ("sin", "must be called"),
        ("atan2((0*t + 0), atan2((0*t + 0), (0*t + 0)))", "not a finite number"),
        ("atan2(0, 0)", "not a finite number"),
        ("log(0)", "not a finite number"),  # atan2(0, 0) is NaN (found by the fuzzer)
    ],
)
def test_rejects_hostile_or_malformed_text(text, message, tmp_path):
    with pytest.raises(ExpressionError, match=message):
        parse(text)
    assert not (tmp_path / "kinegen-pwned").exists()


def test_time_can_be_forbidden():
    with pytest.raises(ExpressionError, match="time"):
        parse("t + 1", allow_time=False)
