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

from dataclasses import dataclass

import numpy as np

from kinegen.errors import KinegenError

#: bisection steps for the highest x the power limit allows (relative precision 2**-60)
BISECTIONS = 60


@dataclass(frozen=True)
class PowerLimit:
    """``sqrt(x) * Σ_p flow_p * max(0, max_(e of p) (rest_e + per_u_e u + per_x_e x)) <= power`` at each
    point: ``pump_of`` (n_e,) the pump of each (element, pump) entry, ``flow`` (N+1, n_pumps) the pumps'
    flows per unit path speed, rest/per_u/per_x (N+1, n_e) the filling pressures' affine parts."""

    power: float
    pump_of: np.ndarray
    flow: np.ndarray
    rest: np.ndarray
    per_u: np.ndarray
    per_x: np.ndarray

    def need(self, i: int, u: float, x: float) -> float:
        """The power [W] the pumps need at point i with s̈ = u, ṡ² = x."""
        pressure = np.maximum(self.rest[i] + self.per_u[i] * u + self.per_x[i] * x, 0.0)
        pumps = np.zeros(self.flow.shape[1])
        np.maximum.at(pumps, self.pump_of, pressure)
        return float(np.sqrt(max(x, 0.0)) * (self.flow[i] @ pumps))

    def interval(self, i: int, x: float) -> tuple[float, float]:
        """The s̈ at point i, ṡ² = x, whose power is within the limit: [low, high] (low > high: none)."""
        if x <= 0:
            return -np.inf, np.inf
        budget = self.power / np.sqrt(x)
        slopes = self.per_u[i]
        offsets = self.rest[i] + self.per_x[i] * x
        # h(u) = Σ_p flow_p max(0, max_e(offset_e + slope_e u)): convex, piecewise linear; its corners are where
        # two lines of one pump cross or a line crosses zero
        corners = [-offsets[e] / slopes[e] for e in range(len(slopes)) if slopes[e] != 0]
        for p in range(self.flow.shape[1]):
            members = np.flatnonzero(self.pump_of == p)
            for j, e in enumerate(members):
                for f in members[j + 1 :]:
                    if slopes[e] != slopes[f]:
                        corners.append((offsets[f] - offsets[e]) / (slopes[e] - slopes[f]))
        corners = np.unique(np.asarray(corners, dtype=float))
        corners = corners[np.isfinite(corners)]

        def h(u: np.ndarray) -> np.ndarray:
            pressure = np.maximum(offsets[:, None] + slopes[:, None] * u[None], 0.0)
            pumps = np.zeros((self.flow.shape[1], len(u)))
            np.maximum.at(pumps, self.pump_of, pressure)
            return self.flow[i] @ pumps

        if len(corners) == 0:
            value = float(h(np.zeros(1))[0])
            return (-np.inf, np.inf) if value <= budget else (np.inf, -np.inf)
        values = h(corners)
        lowest = int(np.argmin(values))
        if values[lowest] > budget:
            return np.inf, -np.inf
        # beyond the last corner on each side h is linear: extend with its slope
        span = max(1.0, float(np.abs(corners).max()))
        outer = np.array([corners[0] - span, corners[-1] + span])
        left_value, right_value = h(outer)

        def crossing(a: float, fa: float, b: float, fb: float) -> float:
            return a + (budget - fa) * (b - a) / (fb - fa) if fb != fa else b

        high = np.inf
        points, heights = np.append(corners, outer[1]), np.append(values, right_value)
        for k in range(lowest, len(points) - 1):
            if heights[k + 1] > budget:
                high = crossing(points[k], heights[k], points[k + 1], heights[k + 1])
                break
        else:
            if right_value > values[-1]:  # rising beyond the last corner: where it meets the budget
                high = crossing(corners[-1], values[-1], outer[1], right_value)
        low = -np.inf
        points, heights = np.insert(corners, 0, outer[0]), np.insert(values, 0, left_value)
        for k in range(lowest + 1, 0, -1):
            if heights[k - 1] > budget:
                low = crossing(points[k], heights[k], points[k - 1], heights[k - 1])
                break
        else:
            if left_value > values[0]:
                low = crossing(corners[0], values[0], outer[0], left_value)
        return low, high


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
        """The s̈ the rows (and the power limit) allow at point i with ṡ² = x: [low, high]."""
        a, room = self.rows_u[i], self.rows_bound[i] - self.rows_x[i] * x
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = room / a
        if np.any((a == 0) & (room < 0)):
            return np.inf, -np.inf
        high = float(ratio[a > 0].min(initial=np.inf))
        low = float(ratio[a < 0].max(initial=-np.inf))
        if self.power is not None and low <= high:
            p_low, p_high = self.power.interval(i, x)
            low, high = max(low, p_low), min(high, p_high)
        return low, high

    def _linear_x(self, i: int, next_low: float, next_high: float, delta: float) -> tuple[float, float]:
        """The x at point i for which some s̈ meets the rows, and lands in [next_low, next_high] at
        i+1 (``delta`` = Δs_i; at the last point: no landing): [low, high] exactly, from every pair
        of an upper and a lower bound on s̈ as affine functions of x."""
        a, ax, b = self.rows_u[i], self.rows_x[i], self.rows_bound[i]
        # s̈ <= (b - ax x)/a for a > 0, s̈ >= (b - ax x)/a for a < 0; a == 0: ax x <= b
        up = [(b[k] / a[k], -ax[k] / a[k]) for k in np.flatnonzero(a > 0)]
        down = [(b[k] / a[k], -ax[k] / a[k]) for k in np.flatnonzero(a < 0)]
        low, high = 0.0, float(self.x_max[i])
        for k in np.flatnonzero(a == 0):
            if ax[k] > 0:
                high = min(high, b[k] / ax[k])
            elif ax[k] < 0:
                low = max(low, b[k] / ax[k])
            elif b[k] < 0:
                return np.inf, -np.inf
        if delta > 0:
            up.append((next_high / (2 * delta), -1 / (2 * delta)))
            down.append((next_low / (2 * delta), -1 / (2 * delta)))
        for g, d in up:  # every lower <= every upper: (beta - delta) x <= gamma - alpha
            for al, be in down:
                slope, rhs = be - d, g - al
                if slope > 0:
                    high = min(high, rhs / slope)
                elif slope < 0:
                    low = max(low, rhs / slope)
                elif rhs < 0:
                    return np.inf, -np.inf
        return low, high

    def _feasible(self, i: int, x: float, next_low: float, next_high: float) -> bool:
        low, high = self.u_interval(i, x)
        if i < len(self.deltas):
            d = self.deltas[i]
            low, high = max(low, (next_low - x) / (2 * d)), min(high, (next_high - x) / (2 * d))
        return low <= high

    def controllable_sets(self) -> np.ndarray:
        """K (N+1, 2): at each point the lowest and highest ṡ² from which the path can be followed to rest."""
        count = len(self.s)
        sets = np.zeros((count, 2))
        sets[-1] = 0.0, 0.0
        if np.any(self.rows_bound[-1] < 0):  # standing at the end (s̈ = ṡ = 0) must itself be within the limits
            sets[:] = np.nan
            return sets
        for i in range(count - 2, -1, -1):
            low, high = self._linear_x(i, *sets[i + 1], self.deltas[i])
            if low > high * (1 + 1e-12) + 1e-300:
                sets[: i + 1] = np.nan
                return sets
            high = max(high, low)
            if self.power is not None and not self._feasible(i, high, *sets[i + 1]):
                bottom, top = low, high
                for _ in range(BISECTIONS):
                    middle = 0.5 * (bottom + top)
                    if self._feasible(i, middle, *sets[i + 1]):
                        bottom = middle
                    else:
                        top = middle
                high = bottom
            sets[i] = low, high
        return sets

    def solve(self) -> Profile:
        """The fastest profile from rest (ṡ = 0 at s_0) to rest (at s_N)."""
        sets = self.controllable_sets()
        if np.isnan(sets).any() or sets[0, 0] > 0:
            bad = int(np.flatnonzero(np.isnan(sets[:, 0]))[-1]) if np.isnan(sets).any() else 0
            raise KinegenError(f"no timing of the path meets the limits from rest to rest: at s = {self.s[bad]:g} s no path speed "
                               "keeps every limit (the weight and loads alone exceed one there)")  # fmt: skip
        count = len(self.s)
        x, u = np.zeros(count), np.zeros(count - 1)
        for i in range(count - 1):
            d = self.deltas[i]
            high = self.u_interval(i, x[i])[1]
            landing = (sets[i + 1, 1] - x[i]) / (2 * d)
            u[i] = min(high, landing) if high >= (sets[i + 1, 0] - x[i]) / (2 * d) else landing
            x[i + 1] = max(x[i] + 2 * d * u[i], 0.0)
        x[-1] = 0.0
        u[-1] = -x[-2] / (2 * self.deltas[-1])
        return Profile(np.sqrt(x), u, sets)
