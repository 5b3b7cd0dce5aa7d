"""Exact inspection of Phi_q at one configuration: rank, null spaces, determinant.

The configuration is taken exactly: numeric coordinates are converted back to exact
numbers (``1.78`` -> ``89/50``, ``0.7071...`` -> ``sqrt(2)/2``, ``1.5707...`` -> ``pi/2``)
and the symbolic Jacobian is evaluated in exact arithmetic, so a rank deficiency is a
proof, not a floating-point guess.
"""

from __future__ import annotations

import functools
import json
import math
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp
import sympy.core.random as sympy_random

from kinegen.codegen.inmemory import lambdify_model
from kinegen.collector import collector_paused
from kinegen.errors import KinegenError
from kinegen.model import Model
from kinegen.rotations import Parametrization
from kinegen.runtime import Solver, from_module
from kinegen.symbolic import System, build_systems

#: Largest Phi_q analysed as one matrix (exact rank, null spaces, determinant).
MAX_DIRECT = 12
#: Largest diagonal block whose determinant is expanded symbolically even when non-zero
#: (a vanishing block is always expanded).
MAX_SYMBOLIC_BLOCK = 2
#: Digits for values that are not rational or algebraic (trigonometric functions of decimals).
DIGITS = 60


#: Magnitudes below this are rounding noise of an exact zero (the solver stops at 1e-10).
ZERO = 1e-13
#: Longest symbolic determinant printed in full by :meth:`Inspection.text` (longer ones are summarised)
MAX_SHOWN = 600


class InspectionBudgetError(KinegenError):
    """The exact analysis did not finish within its time budget."""


class _Expired(Exception):
    """Raised by the budget's alarm inside SymPy's work."""


#: seconds between repeated alarms once a budget has run out: Python ignores an exception raised
#: where it cannot propagate (a garbage collector's callback, a ``__del__``), so an alarm landing
#: there would otherwise leave the work unbounded (it ran 846 s of a 6 s budget once)
REPEAT = 0.25


class Budget:
    """Seconds of symbolic work allowed to one inspection, enforced by ``SIGALRM`` (in the main
    thread of a Unix process; elsewhere, or with ``seconds=None``, unbounded). SymPy's work is
    Python code, interrupted between bytecodes when the alarm fires; the alarm repeats every
    :data:`REPEAT` seconds until the code that caught :class:`_Expired` calls :meth:`stop`."""

    def __init__(self, seconds: float | None) -> None:
        if seconds is not None and not (math.isfinite(seconds) and seconds > 0):
            raise ValueError(f"a budget is a positive, finite number of seconds (or None: unbounded), not {seconds!r}")
        self.seconds = seconds
        self.start = time.monotonic()
        self.stopped = False

    def remaining(self) -> float | None:
        return None if self.seconds is None else self.seconds - (time.monotonic() - self.start)

    @property
    def exhausted(self) -> str:
        """What a report says of work this budget cut short."""
        return f"not finished within the budget of {self.seconds:g} s (--budget SECONDS)"

    @contextmanager
    def limit(self) -> Iterator[None]:
        """Raise :class:`_Expired` in the block when the budget runs out."""
        left = self.remaining()
        armed = left is not None and hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
        if left is not None and left <= 0:
            raise _Expired
        if not armed:
            yield
            return

        def expire(_signum, _frame):
            if not self.stopped:  # (an alarm already on its way when stop() disarmed the timer is let pass)
                raise _Expired

        self.stopped = False
        previous = signal.signal(signal.SIGALRM, expire)
        signal.setitimer(signal.ITIMER_REAL, min(max(left, 1e-3), 1e7), REPEAT)  # (the timer's range is finite)
        try:
            yield
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)

    def stop(self) -> None:
        """No more alarms in this :meth:`limit` block: called where :class:`_Expired` was caught
        and the work after it goes on unbounded (the exact values the report still needs)."""
        self.stopped = True
        if hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread():
            signal.setitimer(signal.ITIMER_REAL, 0)


def summary(expr: sp.Expr) -> str:
    """A determinant too long to print, described: its factors, terms, degree (where it is a
    polynomial in the coordinates) and length."""
    factors = sp.Mul.make_args(expr)
    terms, degree, polynomial = 0, 0, True
    for factor in factors:
        base, exponent = factor.as_base_exp()
        terms += len(sp.Add.make_args(base))
        symbols = sorted(base.free_symbols, key=str)
        if polynomial and symbols and base.is_polynomial(*symbols) and exponent.is_Integer:
            degree += sp.Poly(base, *symbols).total_degree() * int(exponent)
        elif symbols:
            polynomial = False
    kind = f"total degree {degree}" if polynomial else "trigonometric"
    return (
        f"{len(factors)} factor(s), {terms:,} terms, {kind} in {len(expr.free_symbols)} symbols, "
        f"{len(sp.sstr(expr)):,} characters"
    )


@functools.lru_cache(maxsize=4096)  # (~3 ms a value; the parametrizations of one pose share most values)
def exact_number(value: float) -> sp.Expr:
    """An exact number (never a float) equal to ``value`` to 1e-13 (relative, at least absolute):
    the first of

    - 0, for values smaller than :data:`ZERO` in magnitude;
    - a simple form (:func:`simple_form`): a rational, a quadratic surd, or a rational combination
      of 1 and pi, with integer coefficients up to 1000 (``8/25``, ``sqrt(3)/2``, ``-pi/2``);
    - the shortest decimal of at most 13 significant digits (``0.22767`` -> ``22767/100000``: a
      model's own figure, not the rational nearest its binary double);
    - the nearest rational with a denominator of at most 1e13.

    The configuration inspected is as close to the solved one, and its exact entries stay small (the
    full binary expansion of a solved coordinate made determinants of large blocks several times
    slower).
    """
    if abs(value) < ZERO:
        return sp.Integer(0)
    simple = simple_form(value)
    if simple is not None:
        return simple
    close = 1e-13 * max(1.0, abs(value))
    for digits in range(1, 14):
        decimal = sp.Rational(f"{value:.{digits - 1}e}")
        if abs(float(decimal) - value) <= close:
            return decimal
    return sp.Rational(float(value)).limit_denominator(10**13)


#: The largest integer coefficient :func:`simple_form` looks for (mpmath.identify's default).
MAX_COEFFICIENT = 1000


def simple_form(value: float) -> sp.Expr | None:
    """``value`` as a simple exact number if it is one to 1e-13 (relative, at least absolute), else None:
    p/q with q up to :data:`MAX_COEFFICIENT` (the nearest such fraction, by continued fractions), a
    root of a + b x + c x^2 = 0, or (a + b pi)/c, integers up to :data:`MAX_COEFFICIENT` in magnitude
    (integer relations found by mpmath's PSLQ at 30 digits), tried in that order. These are the forms
    SymPy's ``nsimplify`` finds first (through ``mpmath.identify``), in two PSLQ runs instead of its
    ~60 transformations of the value, which run in full (~0.3 s) for every number without a simple
    form: the solved coordinates of a mechanism."""
    import mpmath

    close = 1e-13 * max(1.0, abs(value))
    found: list[sp.Expr] = [sp.Rational(Fraction(value).limit_denominator(MAX_COEFFICIENT))]
    with mpmath.workdps(30):
        x = mpmath.mpf(value)
        tolerance = mpmath.mpf(1e-13)
        quadratic = mpmath.pslq([1, x, x * x], tolerance, MAX_COEFFICIENT)
        if quadratic is not None and quadratic[2]:
            a, b, c = (int(k) for k in quadratic)
            discriminant = b * b - 4 * a * c
            if discriminant >= 0:
                roots = [(-b + sign * sp.sqrt(discriminant)) / (2 * c) for sign in (1, -1)]
                found.append(min(roots, key=lambda r: abs(float(r) - value)))
        with_pi = mpmath.pslq([x, 1, mpmath.pi], tolerance, MAX_COEFFICIENT)
        if with_pi is not None and with_pi[0]:
            found.append(-(sp.Integer(int(with_pi[1])) + int(with_pi[2]) * sp.pi) / int(with_pi[0]))
    for guess in found:
        if abs(float(guess) - value) <= close and sp.count_ops(guess) <= 8 and _small(guess):
            return guess
    return None


def _small(expr: sp.Expr) -> bool:
    """No rational in it with more than 13 digits in its numerator or denominator."""
    return all(len(str(abs(r.p))) <= 13 and len(str(r.q)) <= 13 for r in expr.atoms(sp.Rational))


def convert(q: np.ndarray, source: Parametrization, target: Parametrization, bodies: int) -> np.ndarray:
    """The same physical configuration in another parametrization (via rotation matrices)."""
    poses = source.pose(np.asarray(q, dtype=float).reshape(bodies, source.nq))
    return np.concatenate([target.from_pose(r, a) for r, a in zip(*poses)])


def configuration_at(model: Model, parametrization: Parametrization, case: str, t: float, numeric=None) -> np.ndarray:
    """Stored coordinates at time ``t`` in ``parametrization``.

    The physical configuration is the initial pose if it satisfies Phi at ``t``, else it
    is solved with the quaternion parametrization (regular for every orientation) and
    converted, so that a singular parametrization can still be inspected.
    """
    from kinegen.rotations import REFERENCE, get

    quaternion = get(REFERENCE)
    system = numeric if numeric is not None else from_module(lambdify_model(model, quaternion), case)
    q = system.initial_q
    if np.max(np.abs(system.phi(q, system.driver_inputs(t)[0]))) > 1e-10:
        steps = max(2, int(abs(t - system.t0) / max(system.t1 - system.t0, 1e-12) * (system.steps - 1)) + 1)
        q = Solver(system).solve(np.linspace(system.t0, t, steps)).q[-1]
    return convert(q, quaternion, parametrization, len(model.bodies))


def _combination(vector: sp.Matrix, names: list[str]) -> str:
    pivot = next(x for x in vector if x != 0)
    terms = [_exactly_simplified(c / pivot) * sp.Symbol(n) for c, n in zip(vector, names) if c != 0]
    return sp.sstr(sp.Add(*terms))


def _is_zero(value: sp.Expr) -> bool:
    """Zero test: a value clearly non-zero at 30 digits is non-zero; otherwise it is simplified
    exactly, and values with transcendental parts left are decided to DIGITS digits."""
    if value.is_Number:
        return value == 0
    if abs(sp.N(value, 30)) > 1e-20:
        return False
    value = sp.simplify(value)
    if value.is_Number:
        return value == 0
    return abs(sp.N(value, DIGITS)) < sp.Float(10) ** (-(DIGITS - 10))


def _with_decimal(value: sp.Expr) -> str:
    """An exact number as text, with its decimal value beside it when it is not an integer
    (89/50 (1.78), pi/2 (1.5708)), as the paper writes them."""
    text = sp.sstr(value)
    if value.is_number and not value.is_Integer:
        return f"{text} ({float(sp.N(value, 17)):.6g})"
    return text


#: Determinants with more operations than this are reported unfactored.
MAX_FACTOR_OPS = 1500
#: ... and with more than this not expanded or reported at all (dual Euler parameters' 8 x 8
#: boom determinant: ~10^6 operations before expansion).
MAX_EXPAND_OPS = 50_000


def _factored_determinant(matrix: sp.Matrix, simplify: bool = True, blocks: list | None = None) -> sp.Expr | None:
    """det, factored: polynomial determinants (quaternion, Euler parameters) by ``factor``;
    trigonometric ones (Euler angles) simplified with sums and multiples expanded first.
    None when the expression is too large to expand (the value at the configuration is then
    the exact matrix's determinant). ``blocks``: the matrix's block-triangular form, if known
    (:func:`_determinant`)."""
    # SymPy's multivariate factoring (Wang's algorithm) draws random evaluation points; from a fixed
    # seed its work -- and so its time -- is the same in every process (from an unlucky state the
    # slider crank's dead-centre block, 5 s otherwise, took minutes in a full test run)
    sympy_random.seed(0)
    det = _determinant(matrix, blocks)
    if det.has(sp.sin, sp.cos, sp.tan):
        det = sp.expand_trig(sp.simplify(det) if simplify and matrix.shape[0] <= 3 else det)
    ops = operations_up_to(det, MAX_EXPAND_OPS)
    if ops > MAX_EXPAND_OPS:
        return None
    if ops > MAX_FACTOR_OPS:
        det = sp.expand(det)  # products of long sums often cancel when multiplied out
        if operations_up_to(det, MAX_FACTOR_OPS) > MAX_FACTOR_OPS:
            return det
    return _trig_simplified(sp.factor(det))


def _determinant(matrix: sp.Matrix, blocks: list | None = None) -> sp.Expr:
    """det ``matrix`` by Berkowitz's algorithm; with its block-triangular form (``blocks`` in order, as
    :func:`_block_form` gives them), the product of its diagonal blocks' determinants and of the
    signs of the two orders they put the rows and columns in: the same polynomial, derived block by
    block (the RSSR linkage's 12 x 12 determinant in quaternions did not finish within a minute whole;
    by its ten blocks it takes a fraction of a second)."""
    if not blocks or len(blocks) == 1:
        return matrix.det(method="berkowitz")
    from sympy.combinatorics import Permutation

    rows = Permutation([i for block in blocks for i in block.rows])
    cols = Permutation([j for block in blocks for j in block.cols])
    product = sp.Mul(*(matrix.extract(list(block.rows), list(block.cols)).det(method="berkowitz") for block in blocks))
    return rows.signature() * cols.signature() * product


def operations_up_to(expr: sp.Expr, limit: int) -> int:
    """``sp.count_ops(expr)`` where it is at most ``limit``; above it, some count above ``limit``.

    A sum is counted term by term as SymPy counts it -- each term with a negative coefficient
    negated (its minus is the SUB between terms), one ADD or SUB between terms, one NEG when every
    term is negative -- and the count stops once past ``limit``: the dual Euler parameters' 8 x 8
    boom determinant (~10^6 operations) took 22 s to count in full, only to be found too large."""
    if not expr.is_Add:
        return sp.count_ops(expr)
    total = negatives = 0
    for i, term in enumerate(expr.args):
        negative = _leading_coefficient_negative(term)
        negatives += negative
        total += sp.count_ops(-term if negative else term) + (i > 0)
        if total > limit:
            return total
    return total + (negatives == len(expr.args))


def _leading_coefficient_negative(term: sp.Expr) -> bool:
    """True when a term's numeric leading factor is negative (how SymPy's ``count_ops`` tells a SUB)."""
    first = term.args[0] if term.is_Mul else term
    return bool(first.is_Number and first.is_extended_negative)


#: factors of a determinant with at most this many operations are simplified with ``trigsimp``
MAX_TRIGSIMP_OPS = 60


def _trig_simplified(det: sp.Expr) -> sp.Expr:
    """The factored determinant with each small trigonometric factor simplified: identities such
    as sin(x)**2 + cos(x)**2 = 1 do not survive ``factor``, and sums of products of sines and
    cosines fold into sines and cosines of sums."""
    if not det.has(sp.sin, sp.cos):
        return det
    return sp.Mul(*(sp.trigsimp(f) if f.has(sp.sin, sp.cos) and sp.count_ops(f) <= MAX_TRIGSIMP_OPS else f for f in sp.Mul.make_args(det)))


@dataclass
class BlockReport:
    """One diagonal block of the block-triangular form of Phi_q."""

    constraints: list[str]
    coordinates: list[str]
    value: sp.Expr  # det of the block at the configuration
    determinant: sp.Expr | None = None  # symbolic, factored
    vanishing_factors: list[sp.Expr] = field(default_factory=list)
    null_space: list[str] = field(default_factory=list)

    @property
    def size(self) -> int:
        return len(self.coordinates)

    @property
    def bodies(self) -> list[str]:
        return sorted({c.split(".")[0] for c in self.coordinates})

    @property
    def singular(self) -> bool:
        return _is_zero(self.value)


@dataclass
class Inspection:
    """What ``kinegen inspect`` found."""

    system: System
    t: sp.Expr
    q: list[sp.Expr]
    jacobian: sp.Matrix  # exact, at the configuration
    rank: int
    null_space: list[str]
    dependent_constraints: list[str]
    determinant: sp.Expr | None = None  # symbolic, simplified and factored
    determinant_value: sp.Expr | None = None
    vanishing_factors: list[sp.Expr] = field(default_factory=list)
    blocks: list[BlockReport] = field(default_factory=list)
    rank_method: str = "exact"
    unfinished: str | None = None  #: why a symbolic determinant is missing (its budget ran out)

    @property
    def velocity_names(self) -> list[str]:
        return self.system.coordinates.velocity_names

    @property
    def singular(self) -> bool:
        return self.rank < min(self.jacobian.shape) or self.rank < self.jacobian.shape[0]

    @property
    def singular_blocks(self) -> list[BlockReport]:
        return [b for b in self.blocks if b.singular]

    def text(self, full: bool = False) -> str:
        """Readable report; the matrix is printed in full when it is small, a determinant longer
        than :data:`MAX_SHOWN` characters summarised (:func:`summary`) unless ``full``."""

        def shown(expr: sp.Expr) -> str:
            text = sp.sstr(expr)
            return text if full or len(text) <= MAX_SHOWN else f"[{summary(expr)}; --full prints it, --det-file FILE writes it]"

        coords, names = self.system.coordinates, self.system.constraint_names
        m, n = self.jacobian.shape
        lines = [
            f"model {self.system.model.name}, case {self.system.case.name}, "
            f"parametrization {coords.parametrization.name}, t = {sp.sstr(self.t)}",
        ]
        if n <= 16:
            lines.append(
                "configuration (exact): " + ", ".join(f"{k} = {_with_decimal(v)}" for k, v in zip(coords.stored_names, self.q))
            )
        verdict = "singular" if self.singular else "full rank"
        if self.rank_method == "exact":
            lines.append(f"Phi_q: {m} x {n}, exact rank {self.rank} ({verdict})")
        else:
            lines.append(f"Phi_q: {m} x {n}, rank {self.rank} ({verdict}; {self.rank_method})")
        if n <= 16:
            cells = [[sp.sstr(self.jacobian[i, j]) for j in range(n)] for i in range(m)]
            width = [max(len(self.velocity_names[j]), *(len(cells[i][j]) for i in range(m))) for j in range(n)]
            label = max(len(x) for x in names)
            lines.append(" " * (label + 2) + "  ".join(h.rjust(w) for h, w in zip(self.velocity_names, width)))
            for i in range(m):
                lines.append(f"{names[i].ljust(label)}  " + "  ".join(c.rjust(w) for c, w in zip(cells[i], width)))
        if self.unfinished:
            lines.append(f"det Phi_q (symbolic): {self.unfinished}")
        if self.determinant is None and self.determinant_value is not None:
            lines.append("det Phi_q (symbolic): too large to expand and factor here")
            lines.append(f"det Phi_q at this configuration (exact) = {shown(self.determinant_value)}")
        if self.determinant is not None:
            lines.append(f"det Phi_q (symbolic, factored) = {shown(self.determinant)}")
            lines.append(f"det Phi_q at this configuration = {shown(self.determinant_value)}")
            for factor in self.vanishing_factors:
                lines.append(f"vanishing factor: {shown(factor)}")
        if self.blocks:
            sizes = sorted((b.size for b in self.blocks), reverse=True)
            lines.append(
                f"block-triangular form: {len(self.blocks)} diagonal blocks (largest {sizes[0]}x{sizes[0]}); "
                "det Phi_q = +-product of the block determinants"
            )
            if not self.singular_blocks:
                lines.append("every block determinant is non-zero at this configuration: det Phi_q != 0")
            for block in self.singular_blocks:
                lines.append(f"singular block {block.size}x{block.size}: bodies {', '.join(block.bodies)}")
                lines.append(f"  coordinates: {', '.join(block.coordinates)}")
                lines.append(f"  constraints: {', '.join(block.constraints)}")
                if block.determinant is not None:
                    lines.append(f"  det (symbolic, factored) = {shown(block.determinant)}")
                for factor in block.vanishing_factors:
                    lines.append(f"  vanishing factor: {shown(factor)}")
                if block.null_space:
                    lines.append(f"  null space of the block: {'; '.join(block.null_space)}")
        if self.singular and self.null_space:
            lines.append("null space (coordinate combinations Phi_q cannot see): " + "; ".join(self.null_space))
        if self.singular and self.dependent_constraints:
            lines.append("dependent constraints (left null space): " + ", ".join(self.dependent_constraints))
        return "\n".join(lines)

    def determinants(self) -> str:
        """Every symbolic determinant in full (for ``--det-file``): the whole one, or the blocks'."""
        lines = []
        if self.determinant is not None:
            lines.append(f"det Phi_q = {sp.sstr(self.determinant)}")
        for k, block in enumerate(self.blocks):
            if block.determinant is not None:
                lines.append(f"block {k} ({', '.join(block.bodies)}; {block.size}x{block.size}): det = {sp.sstr(block.determinant)}")
        return "\n".join(lines) + "\n"

    def latex(self) -> str:
        """LaTeX of the determinant (or of the vanishing block determinants)."""
        if self.determinant is not None:
            return r"\det \Phi_q = " + sp.latex(self.determinant)
        parts = [sp.latex(b.determinant) for b in self.singular_blocks if b.determinant is not None]
        if parts:
            return r"\det \Phi_q = \pm " + r" \cdot ".join(f"\\left({p}\\right)" for p in parts) + r" \cdot \ldots"
        return r"\det \Phi_q \neq 0"

    def to_json(self) -> dict[str, Any]:
        """Machine-readable report (expressions as SymPy strings)."""
        small = self.jacobian.shape[1] <= 16
        return {
            "model": self.system.model.name,
            "case": self.system.case.name,
            "parametrization": self.system.coordinates.parametrization.name,
            "t": sp.sstr(self.t),
            "configuration": dict(zip(self.system.coordinates.stored_names, map(sp.sstr, self.q))),
            "constraints": self.system.constraint_names,
            "coordinates": self.velocity_names,
            "jacobian": [[sp.sstr(x) for x in row] for row in self.jacobian.tolist()] if small else None,
            "rank": self.rank,
            "rank_method": self.rank_method,
            "singular": self.singular,
            "null_space": self.null_space,
            "dependent_constraints": self.dependent_constraints,
            "determinant": None if self.determinant is None else sp.sstr(self.determinant),
            "determinant_value": None if self.determinant_value is None else sp.sstr(self.determinant_value),
            "vanishing_factors": [sp.sstr(f) for f in self.vanishing_factors],
            "blocks": [
                {
                    "size": b.size,
                    "bodies": b.bodies,
                    "coordinates": b.coordinates,
                    "constraints": b.constraints,
                    "singular": b.singular,
                    "determinant": None if b.determinant is None else sp.sstr(b.determinant),
                    "vanishing_factors": [sp.sstr(f) for f in b.vanishing_factors],
                    "null_space": b.null_space,
                }
                for b in self.blocks
            ],
        }

    def json_text(self) -> str:
        return json.dumps(self.to_json(), indent=2)


def _exact_values(system: System, q: np.ndarray, t_exact: sp.Expr) -> dict[sp.Symbol, sp.Expr]:
    values: dict[sp.Symbol, sp.Expr] = dict(zip(system.coordinates.stored_symbols, (exact_number(float(x)) for x in q)))
    param = system.coordinates.parametrization
    for body in system.coordinates.bodies:  # stored values that are functions of the pose: from the exact pose
        if body.origin_symbols:
            stored = sp.Matrix(body.stored)
            origin = [float(sp.N(e.xreplace(values))) for e in body.origin]
            exact_origin = sp.Matrix([exact_number(x) for x in origin])
            for symbol, expr in param.pose_substitution(stored, exact_origin).items():
                values[symbol] = _exactly_simplified(sp.expand(expr.xreplace(values)))
    values.update(system.inputs.at_time(t_exact))
    return values


@collector_paused()
def inspect(
    model: Model,
    parametrization: Parametrization,
    case: str | None = None,
    t: str | float = 0,
    q: np.ndarray | None = None,
    numeric=None,
    budget: float | None = None,
    every_block: bool = True,
) -> Inspection:
    """Inspect Phi_q of ``model`` at time ``t`` (exact expression) or at the given coordinates ``q``.

    ``numeric`` is an optional quaternion :class:`NumericSystem` of the case (e.g. from a
    generated module) used to solve for the configuration; by default one is compiled. A model
    with design parameters is inspected at their nominal values (``model.at(values)`` for others).

    ``budget``: seconds of exact work (None: unbounded). When it runs out in the symbolic
    determinant, the report says so and keeps the rest; before the exact rank is known, an
    :class:`InspectionBudgetError` names the block structure of Phi_q.

    ``every_block``: in a large Phi_q's block-triangular form, the symbolic determinant of every
    small block (up to :data:`MAX_SYMBOLIC_BLOCK`) is derived, as the JSON report and ``--det-file``
    give them; False: only the singular blocks', the ones the text report shows (the excavator in
    Euler angles: 4.4 s of its 11.8 s).

    Python's cyclic garbage collector is paused meanwhile (:mod:`kinegen.collector`): its passes over
    SymPy's objects found next to nothing (``kinegen inspect`` of the excavator in Euler angles: 0.95×
    the time with them, median of 8 alternating pairs).
    """
    from kinegen.model.expressions import parse

    model = model.at() if model.design else model
    case = case or next(iter(model.cases))
    system = build_systems(model, parametrization, [case])[case]
    t_exact = parse(t, allow_time=False) if isinstance(t, str) else exact_number(float(t))
    if q is None:
        q = configuration_at(model, parametrization, case, float(t_exact), numeric)
    values = _exact_values(system, q, t_exact)
    named = {u: sp.Symbol(name, real=True) for u, name in zip(system.inputs.u, system.inputs.names)}
    values.update({named[u]: values[u] for u in system.inputs.u})
    symbolic = system.jacobian_matrix().xreplace(named)
    q_exact = [values[s] for s in system.coordinates.stored_symbols]
    on_poses, origins = _pose_substitution(system)
    values.update({r: _exactly_simplified(e.xreplace(values)) for r, e in origins.items()})
    allowed = Budget(budget)
    try:
        with allowed.limit():
            if symbolic.shape[1] <= MAX_DIRECT:
                exact = symbolic.xreplace(values).applyfunc(_exactly_simplified)
                return _direct(system, t_exact, q_exact, exact, on_poses(symbolic), values, allowed)
            exact = symbolic.xreplace(values).applyfunc(_entry)
            return _by_blocks(system, t_exact, q_exact, exact, symbolic, on_poses, values, allowed, every_block)
    except _Expired:
        raise InspectionBudgetError(
            f"the exact analysis of Phi_q ({symbolic.shape[0]} x {symbolic.shape[1]}) did not finish within its budget of "
            f"{budget:g} s; {_structure(system)}. Give it more time (--budget SECONDS), or inspect a parametrization "
            "without trigonometric entries (quaternion, euler-parameters)"
        ) from None


def _block_form(system: System):
    """The diagonal blocks of Phi_q's block-triangular form, from its sparsity pattern (None: not
    square, or structurally singular)."""
    from kinegen.symbolic.blocks import block_triangular

    rows, cols = zip(*[(i, j) for i, j, _ in system.jacobian_entries])
    shape = (len(system.constraint_names), len(system.coordinates.velocity_names))
    return block_triangular(shape, np.array(rows), np.array(cols))


def _structure(system: System) -> str:
    """Phi_q's block-triangular structure in words (from its sparsity pattern: no symbolic work)."""
    blocks = _block_form(system)
    if not blocks:
        return "Phi_q has no block-triangular form (not square, or structurally singular)"
    names = system.coordinates.velocity_names
    parts = [f"{b.size}x{b.size} ({', '.join(sorted({names[j].split('.')[0] for j in b.cols}))})" for b in blocks]
    return f"its block-triangular form has {len(blocks)} diagonal block(s): {'; '.join(parts)}"


def _pose_substitution(system: System):
    """(matrix -> the matrix on the set of valid poses, origin symbol -> its expression): where
    the stored values are functions of the pose (dual quaternions: q_d = ½ (0, r) ⊗ q_r), the
    determinants are written in the origin r and q_r, which makes them factor."""
    substitution: dict[sp.Symbol, sp.Expr] = {}
    origins: dict[sp.Symbol, sp.Expr] = {}
    param = system.coordinates.parametrization
    for body in system.coordinates.bodies:
        if not body.origin_symbols:
            continue
        found = param.pose_substitution(sp.Matrix(body.stored), sp.Matrix(body.origin_symbols))
        substitution.update(found)
        if found:
            origins.update(zip(body.origin_symbols, body.origin))
    if not substitution:
        return (lambda matrix: matrix), origins
    return (lambda matrix: matrix.xreplace(substitution).applyfunc(sp.expand)), origins


def _exactly_simplified(value: sp.Expr) -> sp.Expr:
    """A number computed from the configuration's exact values (:func:`exact_number`), simplified: a
    small Phi_q's entry, a dual quaternion's stored dual part, a null space's coefficient. It is an
    exact number already, and ``sin(8/25)`` stays itself: SymPy's ``nsimplify``, applied to these
    before, turned such a number into a look-alike equal to 15 digits (``sin(50847386919/5000000000000)``
    into ``2821109907456*2**(4/7)*3**(1/14)*...``) after up to 0.3 s of PSLQ. A value with a float in
    it (none from kinegen's values) is still given to ``nsimplify``."""
    simplified = sp.simplify(value)
    return sp.nsimplify(simplified) if simplified.has(sp.Float) else simplified


def _entry(value: sp.Expr) -> sp.Expr:
    """An entry of a large Phi_q: exact if rational or a small surd, else a DIGITS-digit rational."""
    value = sp.expand(value)
    if value.is_Rational or (not value.has(sp.Function) and sp.count_ops(value) <= 8):
        return value
    return sp.Rational(str(sp.N(value, DIGITS)))


def _direct(system: System, t_exact, q_exact, exact: sp.Matrix, symbolic: sp.Matrix, values, budget: Budget) -> Inspection:
    """Exact rank, null spaces and the factored determinant of the whole (small) matrix."""
    rank = exact.rank(simplify=True)
    null = [_combination(v, system.coordinates.velocity_names) for v in exact.nullspace(simplify=True)]
    dependent: list[str] = []
    for v in exact.T.nullspace(simplify=True):
        dependent += [n for x, n in zip(v, system.constraint_names) if x != 0 and n not in dependent]
    report = Inspection(system, t_exact, q_exact, exact, rank, null, dependent)
    m, n = exact.shape
    if m == n:
        try:  # (what is derived from the determinant too: a budget that runs out there leaves the rank proven)
            det = _factored_determinant(symbolic, blocks=_block_form(system))
            if det is None:
                value, vanishing = sp.nsimplify(sp.simplify(exact.det(method="berkowitz"))), []
            else:
                value = sp.simplify(det.xreplace(values))
                _, factors = sp.factor_list(det)
                vanishing = [f for f, _ in factors if _is_zero(f.xreplace(values))]
        except _Expired:  # the rank is proven; the symbolic form is what ran out of time
            budget.stop()
            report.unfinished = budget.exhausted
            return report
        report.determinant, report.determinant_value, report.vanishing_factors = det, value, vanishing
    return report


def _by_blocks(system: System, t_exact, q_exact, exact: sp.Matrix, symbolic: sp.Matrix, on_poses, values, budget: Budget,
               every_block: bool = True) -> Inspection:  # fmt: skip
    """Large systems: block-triangular form, determinants block by block (a regular block's
    symbolic one only when ``every_block``); ``on_poses`` (:func:`_pose_substitution`) applied to
    the blocks whose determinant is derived, not to the whole matrix (the excavator in dual
    quaternions: ~7 s of expansion otherwise)."""
    blocks = _block_form(system)
    coordinate_names, constraint_names = system.coordinates.velocity_names, system.constraint_names
    reports: list[BlockReport] = []
    unfinished: str | None = None
    for block in blocks or []:
        sub_exact = exact.extract(list(block.rows), list(block.cols))
        report = BlockReport(
            [constraint_names[i] for i in block.rows],
            [coordinate_names[j] for j in block.cols],
            sub_exact.det(method="berkowitz"),
        )
        if (report.singular or (every_block and block.size <= MAX_SYMBOLIC_BLOCK)) and not unfinished:
            try:
                det = _factored_determinant(on_poses(symbolic.extract(list(block.rows), list(block.cols))), simplify=report.singular)
            except _Expired:  # the block's exact value is known; its symbolic form ran out of time
                budget.stop()
                det, unfinished = None, budget.exhausted
            report.determinant = det
            if det is not None:
                _, factors = sp.factor_list(det)
                report.vanishing_factors = [f for f, _ in factors if _is_zero(f.xreplace(values))]
        if report.singular:
            names = [coordinate_names[j] for j in block.cols]
            report.null_space = [_combination(v, names) for v in sub_exact.nullspace(simplify=True)]
        reports.append(report)
    if blocks is not None and not any(r.singular for r in reports):
        # det = +-product of non-zero block determinants: full rank, exactly
        return Inspection(
            system,
            t_exact,
            q_exact,
            exact,
            exact.shape[1],
            [],
            [],
            blocks=reports,
            rank_method="every block determinant non-zero",
            unfinished=unfinished,
        )
    # singular (or no block form): rank and null spaces named from an SVD of the exact entries
    matrix = np.array(exact.evalf(20).tolist(), dtype=float)
    u, sigma, vt = np.linalg.svd(matrix)
    rank = int(np.sum(sigma > 1e-10 * sigma[0]))
    null = [_float_combination(list(vt[k]), coordinate_names) for k in range(rank, matrix.shape[1])]
    dependent: list[str] = []
    for k in range(rank, matrix.shape[0]):
        dependent += [constraint_names[i] for i in np.flatnonzero(np.abs(u[:, k]) > 1e-6) if constraint_names[i] not in dependent]
    method = "double-precision SVD of the exact entries (the exact proof is the vanishing block determinant)"
    return Inspection(system, t_exact, q_exact, exact, rank, null, dependent, blocks=reports, rank_method=method, unfinished=unfinished)


def _float_combination(vector: list[float], names: list[str]) -> str:
    from kinegen.runtime.solver import describe_combination

    return describe_combination(np.array(vector), names)
