"""Time-optimal path parametrization by reachability analysis, with a power limit.

The path's grid points s_0 < ... < s_N; at each the unknowns are u = s̈ (constant from s_i to
s_(i+1)) and x = ṡ², with x_(i+1) = x_i + 2 Δs_i u_i. At every point:

* linear rows ``A_u u + A_x x <= b`` (forces, pressures, tipping: toppra's canonical linear
  constraints, collocated at the point);
* a path-speed bound ``x <= x_max`` (flows, speed limits);
* optionally a power limit ``sqrt(x) h(u, x) <= P`` with ``h`` a sum over pumps of the pump's flow
  per unit path speed times its pressure, the largest of its elements' filling pressures
  ``max(0, a_e + b_e u + c_e x)`` -- convex and piecewise linear in u at a given x, not linear in
  (u, x), which is why this module exists beside toppra (toppra takes linear and conic constraints
  only; the tests check this module against toppra's controllable sets where the rows are linear).

The backward pass computes the controllable sets K_i = [lowest, highest] x from which the rest of
the path can be followed to rest; the forward pass from rest takes at every point the largest s̈
that keeps x_(i+1) in K_(i+1), exactly: x_(i+1) = x_i + 2 Δs_i u_i with no shaving. Where the power
limit binds, the highest controllable x is found by bisection, assuming the power a point needs
grows with its path speed (it does: flows grow with ṡ, pressures with ṡ² and s̈ at fixed room).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq

from kinegen.errors import KinegenError

#: the relative precision of the highest ṡ² the power limit allows at a point (Brent's method)
POWER_XTOL = 1e-10
#: samples of the range of ṡ² the linear rows allow at a point, where the power limit is looked for
POWER_SAMPLES = 8
#: forward passes that may find the power exceeded below a controllable set's top before every point is sampled
POWER_ROUNDS = 6


@dataclass(frozen=True)
class PowerLimit:
    """``sqrt(x) * Σ_p flow_p * max(0, max_(e of p) (rest_e + per_u_e u + per_x_e x)) <= power`` at each
    point: ``pump_of`` (n_e,) the pump of each (element, pump) entry, ``flow`` (N+1, n_pumps) the pumps'
    flows per unit path speed, rest/per_u/per_x (N+1, n_e) the filling pressures' affine parts (rest
    -inf where the element takes no oil).

    At a given x the need is convex and piecewise linear in u: the largest of affine functions per
    pump, summed with positive weights. Its corners (where two lines of one pump cross, or one crosses
    zero) are where its minimum over an interval and its crossings with the budget are found exactly."""

    power: float
    pump_of: np.ndarray
    flow: np.ndarray
    rest: np.ndarray
    per_u: np.ndarray
    per_x: np.ndarray
    #: with changes: power (P,), flow (N+1, n_pumps, P), rest/per_u/per_x (N+1, n_e, P) -- their design derivatives
    changes: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        groups = []  # per point: per pump (flow, [(rest, per_u, per_x), ...]) of the entries that take oil, as floats
        for i in range(len(self.flow)):
            point = []
            for p in range(self.flow.shape[1]):
                lines = [(float(self.rest[i, e]), float(self.per_u[i, e]), float(self.per_x[i, e]))
                         for e in np.flatnonzero(self.pump_of == p) if np.isfinite(self.rest[i, e])]  # fmt: skip
                if lines and self.flow[i, p] > 0:
                    point.append((float(self.flow[i, p]), lines))
            groups.append(point)
        object.__setattr__(self, "_groups", groups)

    def need(self, i: int, u: float, x: float) -> float:
        """The power [W] the pumps need at point i with s̈ = u, ṡ² = x."""
        return float(np.sqrt(max(x, 0.0))) * self._per_speed(i, u, x)

    def _per_speed(self, i: int, u: float, x: float) -> float:
        total = 0.0
        for flow, lines in self._groups[i]:
            total += flow * max(0.0, max(r + a * u + b * x for r, a, b in lines))
        return total

    def _corners(self, i: int, x: float) -> list[float]:
        out = []
        for _, lines in self._groups[i]:
            for k, (r, a, b) in enumerate(lines):
                if a != 0:
                    out.append(-(r + b * x) / a)
                for r2, a2, b2 in lines[k + 1 :]:
                    if a != a2:
                        out.append(((r2 + b2 * x) - (r + b * x)) / (a - a2))
        return sorted(out)

    def lowest(self, i: int, x: float, low: float, high: float) -> tuple[float, float]:
        """(u, need per unit path speed) where the need is least over s̈ in [low, high] (finite)."""
        candidates = [low, high] + [c for c in self._corners(i, x) if low < c < high]
        values = [self._per_speed(i, u, x) for u in candidates]
        k = int(np.argmin(values))
        return candidates[k], values[k]

    def highest_within(self, i: int, x: float, low: float, high: float) -> float | None:
        """The largest s̈ in [low, high] whose power is within the limit (None: none is)."""
        if x <= 0 or not self._groups[i]:
            return high
        budget = self.power / np.sqrt(x)
        top = high if np.isfinite(high) else max([low + 1.0, *self._corners(i, x)]) + 1.0
        if self._per_speed(i, top, x) <= budget:
            return high
        bottom = low if np.isfinite(low) else min([top - 1.0, *self._corners(i, x)]) - 1.0
        u, value = self.lowest(i, x, bottom, top)
        if value > budget:
            return None
        points = [u] + [c for c in self._corners(i, x) if u < c < top] + [top]
        heights = [self._per_speed(i, v, x) for v in points]
        for k in range(len(points) - 1):  # convex: it rises from u to top; the segment where it crosses the budget
            if heights[k + 1] > budget:
                a, b, fa, fb = points[k], points[k + 1], heights[k], heights[k + 1]
                return a + (budget - fa) * (b - a) / (fb - fa)
        return top


@dataclass(frozen=True)
class Profile:
    """The time-optimal path speed: ṡ (N+1,) at the points, s̈ (N,) between them, the controllable
    sets K (N+1, 2) of ṡ²."""

    speed: np.ndarray
    acceleration: np.ndarray
    controllable: np.ndarray


class Reachability:
    """The time-optimal profile from rest to rest along grid points ``s`` under linear rows
    (``rows_u``, ``rows_x``, ``rows_bound``, each (N+1, m)), path-speed bounds ``x_max`` (N+1,)
    and an optional :class:`PowerLimit`."""

    def __init__(self, s: np.ndarray, rows_u: np.ndarray, rows_x: np.ndarray, rows_bound: np.ndarray, x_max: np.ndarray,
                 power: PowerLimit | None = None) -> None:  # fmt: skip
        self.s, self.deltas = s, np.diff(s)
        self.rows_u, self.rows_x, self.rows_bound = rows_u, rows_x, rows_bound
        self.x_max, self.power = np.minimum(x_max, 1e300), power

    def u_interval(self, i: int, x: float) -> tuple[float, float]:
        """The s̈ the linear rows allow at point i with ṡ² = x: [low, high]."""
        a, room = self.rows_u[i], self.rows_bound[i] - self.rows_x[i] * x
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = room / a
        if np.any((a == 0) & (room < 0)):
            return np.inf, -np.inf
        high = float(ratio[a > 0].min(initial=np.inf))
        low = float(ratio[a < 0].max(initial=-np.inf))
        return low, high

    def _bounds(self, i: int, next_low: float, next_high: float) -> tuple[list, list, list]:
        """The bounds on s̈ at point i as affine functions of x, each (g, d, source): upper ones
        s̈ <= g + d x, lower ones s̈ >= g + d x, and the rows free of s̈ (k); a source is ("row", k),
        ("landing_high",) or ("landing_low",) (the landing in [next_low, next_high] at i+1)."""
        a, ax, b = self.rows_u[i], self.rows_x[i], self.rows_bound[i]
        up = [(b[k] / a[k], -ax[k] / a[k], ("row", int(k))) for k in np.flatnonzero(a > 0)]
        down = [(b[k] / a[k], -ax[k] / a[k], ("row", int(k))) for k in np.flatnonzero(a < 0)]
        if i < len(self.deltas):
            delta = self.deltas[i]
            up.append((next_high / (2 * delta), -1 / (2 * delta), ("landing_high",)))
            down.append((next_low / (2 * delta), -1 / (2 * delta), ("landing_low",)))
        return up, down, [int(k) for k in np.flatnonzero(a == 0)]

    def _linear_x(self, i: int, next_low: float, next_high: float) -> tuple[float, float, tuple]:
        """The x at point i for which some s̈ meets the rows and lands in [next_low, next_high] at
        i+1: [low, high] exactly, from every pair of an upper and a lower bound on s̈ as affine
        functions of x; and what sets high (("x_max",), ("zero", k) or ("pair", upper source, lower source))."""
        ax, b = self.rows_x[i], self.rows_bound[i]
        up, down, free = self._bounds(i, next_low, next_high)
        low, high, why = 0.0, float(self.x_max[i]), ("x_max",)
        for k in free:
            if ax[k] > 0 and b[k] / ax[k] < high:
                high, why = b[k] / ax[k], ("zero", k)
            elif ax[k] < 0:
                low = max(low, b[k] / ax[k])
            elif ax[k] == 0 and b[k] < 0:
                return np.inf, -np.inf, why
        for g, d, upper in up:  # every lower <= every upper: (beta - delta) x <= gamma - alpha
            for al, be, lower in down:
                slope, rhs = be - d, g - al
                if slope > 0:
                    if rhs / slope < high:
                        high, why = rhs / slope, ("pair", upper, lower)
                elif slope < 0:
                    low = max(low, rhs / slope)
                elif rhs < 0:
                    return np.inf, -np.inf, why
        return low, high, why

    def _excess(self, i: int, x: float, next_low: float, next_high: float) -> float:
        """How far the least power any allowed s̈ needs at point i, ṡ² = x, lies above the limit [W]
        (<= 0: within), for x within the range the linear rows and the landing in [next_low, next_high]
        allow (:meth:`_linear_x`)."""
        low, high = self.u_interval(i, x)
        d = self.deltas[i]
        low, high = max(low, (next_low - x) / (2 * d)), min(high, (next_high - x) / (2 * d))
        if low > high:  # x is within the linear rows' range (the caller's): an empty interval here is rounding
            low = high = 0.5 * (low + high)
        return float(np.sqrt(x)) * self.power.lowest(i, x, low, high)[1] - self.power.power

    def _power_top(self, i: int, low: float, high: float, why: tuple, following: np.ndarray) -> tuple[float, tuple, bool]:
        """The highest ṡ² at point i below which every ṡ² from ``low`` is within the power limit too:
        the need is not monotone in ṡ everywhere (a faster point must brake harder, and braking
        takes no pressure). At the points of ``self.sampled`` (where a forward pass found the limit
        exceeded below the top) the range the linear rows allow is sampled from below
        (:data:`POWER_SAMPLES`), elsewhere only its top is checked; the range is cut at the first
        sample beyond the limit, at the root between it and the one before (Brent's method).
        (top, what sets it, whether ``low`` itself is within the limit)."""
        excess = lambda x: self._excess(i, x, *following)  # noqa: E731
        if excess(low) > 0:
            return high, why, False
        below = low
        samples = low + (high - low) * np.arange(1, POWER_SAMPLES + 1) / POWER_SAMPLES if i in self.sampled else [high]
        for x in samples:
            if excess(x) > 0:
                top = brentq(excess, below, x, xtol=1e-300, rtol=POWER_XTOL)
                if excess(top) > 0:  # the root's own side: within the limit
                    top = max(low, top * (1 - 4 * POWER_XTOL))
                return top, ("power", top), True
            below = x
        return high, why, True

    def controllable_sets(self) -> np.ndarray:
        """K (N+1, 2): at each point the lowest and highest ṡ² from which the path can be followed to
        rest; what sets each highest is kept (``self.backward``) for :meth:`tangent`."""
        count = len(self.s)
        sets = np.zeros((count, 2))
        self.backward: list = [None] * count
        if np.any(self.rows_bound[-1] < 0):  # standing at the end (s̈ = ṡ = 0) must itself be within the limits
            sets[:] = np.nan
            return sets
        for i in range(count - 2, -1, -1):
            low, high, why = self._linear_x(i, *sets[i + 1])
            if low > high * (1 + 1e-12) + 1e-300:
                sets[: i + 1] = np.nan
                return sets
            if high < low:
                high, why = low, ("low",)
            if self.power is not None:
                high, why, feasible = self._power_top(i, low, high, why, sets[i + 1])
                if not feasible:
                    sets[: i + 1] = np.nan
                    return sets
            sets[i] = low, high
            self.backward[i] = why
        return sets

    def solve(self) -> Profile:
        """The fastest profile from rest (ṡ = 0 at s_0) to rest (at s_N); what sets each s̈ is kept
        (``self.forward``) for :meth:`tangent`."""
        self.sampled: set[int] = set()
        for _ in range(POWER_ROUNDS):
            sets = self.controllable_sets()
            if np.isnan(sets).any() or sets[0, 0] > 0 or self.power is None:
                break
            beyond = self._forward(sets)[2]
            if not beyond:
                break
            self.sampled |= {j for i in beyond for j in (i - 1, i, i + 1)}
        else:
            self.sampled = set(range(len(self.s)))
            sets = self.controllable_sets()
        if np.isnan(sets).any() or sets[0, 0] > 0:
            bad = int(np.flatnonzero(np.isnan(sets[:, 0]))[-1]) if np.isnan(sets).any() else 0
            raise KinegenError(f"no timing of the path meets the limits from rest to rest: at s = {self.s[bad]:g} s no path speed "
                               "keeps every limit (the weight and loads alone exceed one there)")  # fmt: skip
        x, u, beyond = self._forward(sets)
        if beyond:
            raise KinegenError(f"no timing of the path keeps the engine's power at s = {self.s[beyond[0]]:g} s (the power "
                               "a point needs is not monotone in its speed there)")  # fmt: skip
        self.profile = Profile(np.sqrt(x), u, sets)
        return self.profile

    def _forward(self, sets: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """The forward pass from rest: at each point the largest s̈ that keeps the next ṡ² within
        its controllable set (and the power within the limit); (ṡ², s̈, the points where no s̈ keeps
        the power within it); what sets each s̈ is kept (``self.forward``)."""
        count = len(self.s)
        x, u = np.zeros(count), np.zeros(count - 1)
        self.forward: list = [None] * (count - 1)
        beyond = []
        for i in range(count - 1):
            d = self.deltas[i]
            up, down, _ = self._bounds(i, *sets[i + 1])
            g, dd, why = min(up, key=lambda bound: bound[0] + bound[1] * x[i])
            high = g + dd * x[i]
            if self.power is not None:
                low = max(bound[0] + bound[1] * x[i] for bound in down)
                allowed = self.power.highest_within(i, x[i], low, high)
                if allowed is None:
                    beyond.append(i)
                elif allowed < high:
                    high, why = allowed, ("power",)
            u[i] = high
            self.forward[i] = why
            x[i + 1] = max(x[i] + 2 * d * u[i], 0.0)
        x[-1] = 0.0
        u[-1] = -x[-2] / (2 * self.deltas[-1])
        return x, u, beyond


class Dual:
    """A number with its gradient (forward-mode differentiation): ``value`` and ``grad`` (n,)."""

    __slots__ = ("grad", "value")

    def __init__(self, value: float, grad: np.ndarray) -> None:
        self.value, self.grad = float(value), grad

    @staticmethod
    def of(x, n: int) -> Dual:
        return x if isinstance(x, Dual) else Dual(x, np.zeros(n))

    def __add__(self, other):
        if isinstance(other, Dual):
            return Dual(self.value + other.value, self.grad + other.grad)
        return Dual(self.value + other, self.grad)

    __radd__ = __add__

    def __neg__(self):
        return Dual(-self.value, -self.grad)

    def __sub__(self, other):
        return self + (-other)

    def __rsub__(self, other):
        return (-self) + other

    def __mul__(self, other):
        if isinstance(other, Dual):
            return Dual(self.value * other.value, self.grad * other.value + other.grad * self.value)
        return Dual(self.value * other, self.grad * other)

    __rmul__ = __mul__

    def __truediv__(self, other):
        if isinstance(other, Dual):
            return Dual(self.value / other.value, (self.grad - other.grad * (self.value / other.value)) / other.value)
        return Dual(self.value / other, self.grad / other)

    def __rtruediv__(self, other):
        return Dual.of(other, len(self.grad)) / self

    def sqrt(self) -> Dual:
        root = np.sqrt(self.value)
        return Dual(root, self.grad / (2 * root) if root > 0 else np.zeros_like(self.grad))


def tangent_profile(reach: Reachability, changes: dict, power_changes: dict | None, x_max_changes: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """The exact derivative of the fastest profile (``reach`` solved) by the parameters its
    coefficients depend on: ``changes`` rows_u, rows_x, rows_bound (N+1, m, P), ``x_max_changes``
    (N+1, P), ``power_changes`` (:class:`PowerLimit`'s). It replays the decisions of
    :meth:`Reachability.controllable_sets` and :meth:`Reachability.solve` -- which bound sets each
    controllable set's top, each s̈ -- with :class:`Dual` numbers: the derivative of the discretized
    problem along its active constraints (the power limit's roots by implicit differentiation).
    Returns (ṡ² (N+1,), the cycle time, its gradient (P,))."""
    n = x_max_changes.shape[1]
    count = len(reach.s)
    profile = reach.profile
    sets = profile.controllable
    zero = np.zeros(n)

    def coefficient(name: str, i: int, k: int) -> Dual:
        return Dual(getattr(reach, name)[i, k], changes[name][i, k])

    def bound(i: int, source: tuple, tops: list, size: int = n) -> tuple[Dual, Dual]:
        """(g, d) of a bound s̈ <= or >= g + d x as duals of ``size`` (the parameters, maybe one more)."""
        pad = (lambda g: np.pad(g, (0, size - n))) if size > n else (lambda g: g)
        if source[0] == "row":
            k = source[1]
            a, ax, b = (Dual(getattr(reach, f)[i, k], pad(changes[f][i, k])) for f in ("rows_u", "rows_x", "rows_bound"))
            return b / a, -ax / a
        delta = reach.deltas[i]
        if source[0] == "landing_high":
            top = tops[i + 1]
            return Dual(top.value, pad(top.grad)) / (2 * delta), Dual(-1 / (2 * delta), np.zeros(size))
        return Dual(sets[i + 1, 0] / (2 * delta), np.zeros(size)), Dual(-1 / (2 * delta), np.zeros(size))

    tops: list = [None] * count
    tops[-1] = Dual(0.0, zero)
    for i in range(count - 2, -1, -1):
        why = reach.backward[i]
        if why[0] == "x_max":
            tops[i] = Dual(reach.x_max[i], x_max_changes[i])
        elif why[0] == "zero":
            k = why[1]
            tops[i] = coefficient("rows_bound", i, k) / coefficient("rows_x", i, k)
        elif why[0] == "pair":
            g, d = bound(i, why[1], tops)
            al, be = bound(i, why[2], tops)
            tops[i] = (g - al) / (be - d)
        elif why[0] == "low":
            tops[i] = Dual(sets[i, 1], zero)
        else:  # the power limit's root: excess(x, p) = 0, implicitly
            excess = _excess_dual(reach, i, sets[i, 1], tops, power_changes, bound, n)
            tops[i] = Dual(sets[i, 1], -excess.grad[:n] / excess.grad[n])
    x = [Dual(0.0, zero)]
    for i in range(count - 1):
        why = reach.forward[i]
        delta = reach.deltas[i]
        if why[0] == "power":
            u = _power_crossing_dual(reach, i, x[i], power_changes, n)
        else:
            g, d = bound(i, why, tops)
            u = g + d * x[i]
        following = x[i] + 2 * delta * u
        x.append(following if following.value > 0 else Dual(0.0, zero))
    x[-1] = Dual(0.0, zero)
    speeds = [xi.sqrt() for xi in x]
    total = Dual(0.0, zero)
    for i in range(count - 1):
        total = total + 2 * reach.deltas[i] / (speeds[i] + speeds[i + 1])
    return np.array([xi.value for xi in x]), total.value, total.grad


def _lines_dual(power: PowerLimit, changes: dict, i: int, u: float, x: float, size: int, n: int, side: float) -> list:
    """Per pump with oil taken, (flow, its active line (r, a, b) or None) as duals, the line active just
    ``side`` (-1 left, +1 right) of s̈ = u at ṡ² = x."""
    pad = (lambda g: np.pad(g, (0, size - n))) if size > n else (lambda g: g)
    probe = u + side * 1e-9 * max(1.0, abs(u))
    out = []
    for p in range(power.flow.shape[1]):
        members = [e for e in np.flatnonzero(power.pump_of == p) if np.isfinite(power.rest[i, e])]
        if not members or power.flow[i, p] <= 0:
            continue
        values = [power.rest[i, e] + power.per_u[i, e] * probe + power.per_x[i, e] * x for e in members]
        best = int(np.argmax(values))
        flow = Dual(power.flow[i, p], pad(changes["flow"][i, p]))
        if values[best] <= 0:
            out.append((flow, None))
            continue
        e = members[best]
        out.append((flow, tuple(Dual(getattr(power, f)[i, e], pad(changes[f][i, e])) for f in ("rest", "per_u", "per_x"))))
    return out


def _need_dual(lines: list, u, x) -> Dual:
    total = 0.0
    for flow, line in lines:
        if line is not None:
            r, a, b = line
            total = total + flow * (r + a * u + b * x)
    return total


def _power_crossing_dual(reach: Reachability, i: int, x: Dual, changes: dict, n: int) -> Dual:
    """s̈ where the pumps' power reaches the engine's at point i (the forward pass's power bound):
    sqrt(x) Σ_p f_p (r_p + a_p u + b_p x) = P with the lines active just left of it."""
    power = reach.power
    u0 = reach.profile.acceleration[i]
    lines = _lines_dual(power, changes, i, u0, x.value, n, n, -1.0)
    budget = Dual(power.power, changes["power"]) / x.sqrt()
    slope = _need_dual(lines, 1.0, 0.0) - _need_dual(lines, 0.0, 0.0)  # Σ f a (the u-coefficient)
    rest = _need_dual(lines, 0.0, x)
    return (budget - rest) / slope


def _excess_dual(reach: Reachability, i: int, x0: float, tops: list, changes: dict, bound, n: int) -> Dual:
    """The power excess at point i, ṡ² = x0 (its root), as a dual over the parameters and x (the last
    slot): sqrt(x) min over the allowed s̈ of the pumps' need per unit speed, minus the engine's power.
    The least need is at an end of the allowed s̈ (a bound's g + d x) or at a corner of the need (where
    one pump's active line changes, or crosses zero)."""
    power = reach.power
    size = n + 1
    X = Dual(x0, np.eye(size)[n])
    up, down, _ = reach._bounds(i, *reach.profile.controllable[i + 1])
    high_bound = min(up, key=lambda b: b[0] + b[1] * x0)
    low_bound = max(down, key=lambda b: b[0] + b[1] * x0)
    low, high = low_bound[0] + low_bound[1] * x0, high_bound[0] + high_bound[1] * x0
    if low > high:
        low = high = 0.5 * (low + high)
    u_star, _ = power.lowest(i, x0, low, high)
    if u_star == low or u_star == high:
        source = low_bound[2] if u_star == low else high_bound[2]
        g, d = bound(i, source, tops, size)
        U = g + d * X
        lines = _lines_dual(power, changes, i, u_star, x0, size, n, 1.0 if u_star == low else -1.0)
    else:  # a corner: the pump whose active line changes there
        left = _lines_dual(power, changes, i, u_star, x0, size, n, -1.0)
        right = _lines_dual(power, changes, i, u_star, x0, size, n, 1.0)
        U = None
        for (_, a_line), (_, b_line) in zip(left, right):
            if (a_line is None) != (b_line is None) or (a_line is not None and a_line[0].value != b_line[0].value):
                zero_line = (Dual(0.0, np.zeros(size)),) * 3
                ra, aa, ba = a_line or zero_line
                rb, ab, bb = b_line or zero_line
                U = -((ra - rb) + (ba - bb) * X) / (aa - ab)
                break
        if U is None:
            raise KinegenError(f"the power limit's least need at s = {reach.s[i]:g} s lies at no corner found again")
        lines = left
    need = _need_dual(lines, U, X)
    return X.sqrt() * need - Dual(power.power, np.pad(changes["power"], (0, 1)))
