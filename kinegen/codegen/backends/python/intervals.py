"""The interval helpers a generated module's enclosure kernels call (kinegen.codegen.intervals).

The text below the line ``# ---- helpers ----`` is copied into every generated module (which
needs nothing but NumPy); this file is what the tests exercise. An interval is a pair
(lower, upper) of NumPy arrays (or floats) of one batch shape: every helper works on many
intervals at once. Each result contains the exact real result for every value in the arguments'
intervals: bounds rounded outward (``_iv_out``), a bound that cannot be computed (outside the
domain, overflow: NaN) made infinite, 0 times an infinite bound counted as 0.
"""

from __future__ import annotations

import numpy as np

# ---- helpers ----
_IV_RELATIVE = 2.0**-49  # outward rounding: this fraction of a bound's magnitude ...
_IV_ABSOLUTE = 1e-300  # ... plus this
_IV_PI = np.pi


def _iv_out(lo, hi):
    """[lo, hi] rounded outward; a NaN bound (not computable) infinite."""
    with np.errstate(all="ignore"):
        lo = lo - (np.abs(lo) * _IV_RELATIVE + _IV_ABSOLUTE)
        hi = hi + (np.abs(hi) * _IV_RELATIVE + _IV_ABSOLUTE)
    return np.where(np.isnan(lo), -np.inf, lo), np.where(np.isnan(hi), np.inf, hi)


def _iv_const(lo, hi, like):
    """The constant [lo, hi] in the batch shape of the interval ``like``."""
    shape = np.shape(like[0])
    return np.full(shape, lo), np.full(shape, hi)


def _iv_add(a, b):
    return _iv_out(a[0] + b[0], a[1] + b[1])


def _iv_neg(a):
    return -a[1], -a[0]


def _iv_mul(a, b):
    with np.errstate(all="ignore"):
        products = (a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1])
    # fmin/fmax skip the NaN of 0 * inf (the product of 0 and any real is 0); all four NaN: unbounded
    return _iv_out(np.fmin(np.fmin(products[0], products[1]), np.fmin(products[2], products[3])),
                   np.fmax(np.fmax(products[0], products[1]), np.fmax(products[2], products[3])))  # fmt: skip


def _iv_inv(a):
    apart = (a[0] > 0) | (a[1] < 0)  # zero not inside
    with np.errstate(all="ignore"):
        return _iv_out(np.where(apart, 1.0 / a[1], -np.inf), np.where(apart, 1.0 / a[0], np.inf))


def _iv_powi(a, n):
    """a**n, n a positive integer."""
    with np.errstate(all="ignore"):
        lo, hi = np.power(a[0], n), np.power(a[1], n)
    if n % 2:
        return _iv_out(lo, hi)
    inside = (a[0] < 0) & (a[1] > 0)
    return _iv_out(np.where(inside, 0.0, np.minimum(lo, hi)), np.maximum(lo, hi))


def _iv_powr(a, r):
    """a**r, r a real exponent within the bounds ``r`` = (r_lo, r_hi), a >= 0 (the real function's
    domain): monotone in a and in r, so its range is at the corners."""
    with np.errstate(all="ignore"):
        corners = [np.power(np.maximum(x, 0.0), e) for x in a for e in r]
    return _iv_out(np.fmin(np.fmin(corners[0], corners[1]), np.fmin(corners[2], corners[3])),
                   np.fmax(np.fmax(corners[0], corners[1]), np.fmax(corners[2], corners[3])))  # fmt: skip


def _iv_increasing(f):
    """The helper of a function that increases on its domain."""

    def helper(a):
        with np.errstate(all="ignore"):
            return _iv_out(f(a[0]), f(a[1]))

    return helper


_iv_exp = _iv_increasing(np.exp)
_iv_atan = _iv_increasing(np.arctan)
_iv_sinh = _iv_increasing(np.sinh)
_iv_tanh = _iv_increasing(np.tanh)


def _iv_sqrt(a):
    return _iv_out(np.sqrt(np.maximum(a[0], 0.0)), np.sqrt(np.maximum(a[1], 0.0)))


def _iv_log(a):
    with np.errstate(all="ignore"):
        return _iv_out(np.log(np.maximum(a[0], 0.0)), np.log(a[1]))


def _iv_asin(a):
    return _iv_out(np.arcsin(np.clip(a[0], -1.0, 1.0)), np.arcsin(np.clip(a[1], -1.0, 1.0)))


def _iv_acos(a):
    return _iv_out(np.arccos(np.clip(a[1], -1.0, 1.0)), np.arccos(np.clip(a[0], -1.0, 1.0)))


def _iv_sign(a):
    return np.sign(a[0]), np.sign(a[1])


def _iv_abs(a):
    inside = (a[0] < 0) & (a[1] > 0)
    lo, hi = np.abs(a[0]), np.abs(a[1])
    return np.where(inside, 0.0, np.minimum(lo, hi)), np.maximum(lo, hi)


def _iv_cosh(a):
    inside = (a[0] < 0) & (a[1] > 0)
    with np.errstate(all="ignore"):
        lo, hi = np.cosh(a[0]), np.cosh(a[1])
    return _iv_out(np.where(inside, 1.0, np.minimum(lo, hi)), np.maximum(lo, hi))


def _iv_reaches(a, phase, period):
    """Whether [a] holds a point phase + k period (with a margin: a near miss counts as a hit)."""
    with np.errstate(all="ignore"):
        first = np.ceil((a[0] - phase) / period - 1e-9) * period + phase
        return ~(first > a[1] + 1e-12 * (1.0 + np.abs(a[1])))


def _iv_periodic(f, top, bottom):
    """The helper of a 2 pi-periodic function of range [-1, 1] with maxima at ``top`` and minima at ``bottom`` (+ 2 k pi)."""

    def helper(a):
        with np.errstate(all="ignore"):
            fa, fb = f(a[0]), f(a[1])
            whole = ~(a[1] - a[0] < 2 * _IV_PI)  # a whole period, or not finite
            lo = np.where(whole | _iv_reaches(a, bottom, 2 * _IV_PI), -1.0, np.minimum(fa, fb))
            hi = np.where(whole | _iv_reaches(a, top, 2 * _IV_PI), 1.0, np.maximum(fa, fb))
        return _iv_out(lo, hi)

    return helper


_iv_sin = _iv_periodic(np.sin, _IV_PI / 2, -_IV_PI / 2)
_iv_cos = _iv_periodic(np.cos, 0.0, _IV_PI)


def _iv_tan(a):
    with np.errstate(all="ignore"):
        pole = ~(a[1] - a[0] < _IV_PI) | _iv_reaches(a, _IV_PI / 2, _IV_PI)
        return _iv_out(np.where(pole, -np.inf, np.tan(a[0])), np.where(pole, np.inf, np.tan(a[1])))


def _iv_atan2(y, x):
    """atan2(y, x) over the box y x x: its corners' range, or [-pi, pi] where the box holds the
    origin or crosses the negative x axis (where atan2 jumps)."""
    with np.errstate(all="ignore"):
        corners = [np.arctan2(b, c) for b in y for c in x]
        jump = (x[0] <= 0) & (y[0] <= 0) & (y[1] >= 0)
        lo = np.minimum(np.minimum(corners[0], corners[1]), np.minimum(corners[2], corners[3]))
        hi = np.maximum(np.maximum(corners[0], corners[1]), np.maximum(corners[2], corners[3]))
    return _iv_out(np.where(jump, -_IV_PI, lo), np.where(jump, _IV_PI, hi))


# ---- end of helpers ----


def evaluate(program, span):
    """The rows of an :class:`~kinegen.codegen.intervals.IntervalProgram` over ``span`` = (t0, t1)
    (floats or arrays): its outputs' lower bounds, then their upper bounds -- what a generated
    module's enclosure kernel computes, without printing it (the in-memory path)."""
    registers = []
    for operation in program.operations:
        if operation.op == "time":
            registers.append(tuple(np.asarray(t, dtype=float) for t in span))
        elif operation.op == "const":
            registers.append(_iv_const(*operation.value, registers[0]))
        elif operation.op in ("powi", "powr"):
            registers.append(globals()[f"_iv_{operation.op}"](registers[operation.args[0]], operation.value))
        else:
            registers.append(globals()[f"_iv_{operation.op}"](*(registers[a] for a in operation.args)))
    lower = [np.full(np.shape(registers[0][0]), -np.inf) if r is None else registers[r][0] for r in program.outputs]
    upper = [np.full(np.shape(registers[0][0]), np.inf) if r is None else registers[r][1] for r in program.outputs]
    return np.array(lower + upper).reshape((2 * len(program.outputs), *np.shape(registers[0][0])))
