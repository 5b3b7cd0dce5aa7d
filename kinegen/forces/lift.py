"""Hydraulic lift capacity at the arm's end over a grid of lift-point heights and radii: the
hydraulic half of an ISO 10567 lift chart (the tipping half needs masses).

At each grid point (radius r from the swing axis, height h, in the boom plane at zero swing) the
inputs that place the lift point (``lift_chart.place``, e.g. boom and arm cylinders) are solved so
that the point is there (bounded least squares on the inputs, from the nearest pose of a compiled
grid sweep); the others stay at the case's start. The load hangs at the lift point on its body
(the arm: the bucket removed); the lifting cylinder works at its relief setting and the others hold
at their holding settings. The hydraulic lift capacity is the largest such load, and ISO 10567
rates 87 % of it; the tipping load (rated at 75 %) is left for when the model has masses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, minimize

from kinegen.errors import KinegenError
from kinegen.forces.statics import Statics, pose_results
from kinegen.model import Model
from kinegen.runtime import NumericSystem, Solver, SolverOptions
from kinegen.runtime.batch import sweep_grid

#: standard gravity [m/s^2]: a load's mass in kg is its weight in N / G
G = 9.80665
#: ISO 10567: the rated lift capacity is at most this share of the hydraulic lift capacity
HYDRAULIC_SHARE = 0.87


@dataclass(frozen=True)
class LiftPoint:
    """The hydraulic lift capacity at one lift-point position."""

    radius: float  #: m from the swing axis
    height: float  #: m above the ground
    capacity: float  #: [N] the hydraulic lift capacity (NaN where the point cannot be reached)
    limiting: str  #: the cylinder that limits it
    setting: str  #: "relief" or "holding"
    inputs: dict[str, float]  #: the pose's inputs

    @property
    def rated_kg(self) -> float:
        """ISO 10567's hydraulic rating: 87 % of the capacity, in kg."""
        return HYDRAULIC_SHARE * self.capacity / G


@dataclass(frozen=True)
class LiftChart:
    """The grid (heights x radii, ``None`` where the point cannot be reached) and the capacity at the
    largest radius reachable at each height."""

    point: str
    lifting: str
    heights: tuple[float, ...]
    radii: tuple[float, ...]
    grid: tuple[tuple[LiftPoint | None, ...], ...]  #: [height][radius]
    max_reach: tuple[LiftPoint | None, ...]  #: per height

    def table(self) -> str:
        """The manufacturers' layout: a row per lift-point height, per radius the rated load over the
        front and over the side, and the load at the largest radius; kg."""
        columns = [f"{r:g} m" for r in self.radii] + ["max reach"]
        lines = [
            f"rated lift capacity at {self.point} (the bucket removed), kg: 87 % of the hydraulic lift capacity (ISO 10567), "
            f"{self.lifting} lifting at its relief setting, the other cylinders holding",
            "* hydraulic limit. The tipping limit (75 % of the tipping load) needs masses and is not checked yet: over the side it "
            "usually rules, so read the side columns as an upper bound.",
            f"{'height':>7}  " + "  ".join(f"{c:^17}" for c in columns),
            f"{'m':>7}  " + "  ".join(f"{'front':>8} {'side':>8}" for _ in columns),
        ]
        for h, row, reach in zip(self.heights, self.grid, self.max_reach):
            cells = [_cell(p) for p in row] + [_cell(reach, radius=True)]
            lines.append(f"{h:>7g}  " + "  ".join(cells))
        return "\n".join(lines)


def _cell(point: LiftPoint | None, radius: bool = False) -> str:
    if point is None or not np.isfinite(point.capacity):
        return f"{'-':>8} {'-':>8}"
    value = f"*{point.rated_kg:,.0f}"
    return f"{value:>8} {value:>8}" + (f" @{point.radius:.2f}" if radius else "")


def lift_chart(system: NumericSystem, model: Model) -> LiftChart:
    """The model's ``lift_chart`` in ``system`` (a case of the model: the spec's case)."""
    spec = model.lift_chart
    if spec is None:
        raise KinegenError(f"{model.name} has no lift_chart: section")
    placer = _Placer(system, model)
    grid = tuple(tuple(placer.at(r, h) for r in spec.radii) for h in spec.heights)
    reach = tuple(placer.farthest(h) for h in spec.heights)
    return LiftChart(f"{spec.point.body}.{spec.point.name}", spec.lifting, spec.heights, spec.radii, grid, reach)


class _Placer:
    """Poses that put the lift point at a radius and height, and the capacity there."""

    def __init__(self, system: NumericSystem, model: Model) -> None:
        spec = model.lift_chart
        self.system, self.model, self.spec = system, model, spec
        self.solver = Solver(system, SolverOptions())
        self.base = system.driver_inputs(system.t0)[0].astype(float)
        self.index = [system.driver_names.index(n) for n in spec.place]
        self.low = np.array([spec.ranges[n][0] for n in spec.place])
        self.high = np.array([spec.ranges[n][1] for n in spec.place])
        axes = [np.linspace(lo, hi, 41) for lo, hi in zip(self.low, self.high)]
        q0 = self.solver.position(system.initial_q, self.base, system.t0)[0]
        corner = self._inputs(np.array([a[0] for a in axes]))
        q0 = self._continue(q0, self.base, corner)
        sweep = sweep_grid(system, corner, self.index, axes, q0)
        ok = sweep.converged.ravel()
        self.samples = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)[ok]
        self.q = sweep.q.reshape(system.n_stored, -1)[:, ok].T
        self.points = system.point_positions(self.q, [(spec.point.body, spec.point.name)])[:, 0]
        self.last: tuple[np.ndarray, np.ndarray] | None = None

    def _inputs(self, values: np.ndarray) -> np.ndarray:
        u = self.base.copy()
        u[self.index] = values
        return u

    def _continue(self, q: np.ndarray, u_from: np.ndarray, u_to: np.ndarray) -> np.ndarray:
        steps = max(1, int(np.ceil(np.abs(u_to - u_from).max() / 0.05)))
        for f in np.linspace(0, 1, steps + 1)[1:]:
            q = self.solver.position(q, u_from + f * (u_to - u_from))[0]
        return q

    def _pose(self, values: np.ndarray) -> np.ndarray:
        """q at the placing inputs ``values``, by continuation from the last pose."""
        q, u = self.last
        target = self._inputs(np.clip(values, self.low, self.high))
        q = self._continue(q, u, target)
        self.last = (q, target)
        return q

    def _point(self, values: np.ndarray) -> np.ndarray:
        q = self._pose(values)
        return self.system.point_positions(q[None], [(self.spec.point.body, self.spec.point.name)])[0, 0]

    def _start(self, k: int) -> np.ndarray:
        self.last = (self.q[k], self._inputs(self.samples[k]))
        return self.samples[k]

    def at(self, radius: float, height: float) -> LiftPoint | None:
        """The capacity with the lift point at (radius, height), or None where it cannot be there."""
        target = np.array([radius, height])
        near = int(np.argmin(np.linalg.norm(self.points[:, [0, 2]] - target, axis=1)))
        if np.linalg.norm(self.points[near, [0, 2]] - target) > 0.5:
            return None
        found = least_squares(lambda x: self._point(x)[[0, 2]] - target, self._start(near), bounds=(self.low, self.high),
                              xtol=1e-12, ftol=1e-12, gtol=1e-12)  # fmt: skip
        if np.linalg.norm(found.fun) > 1e-6:
            return None
        return self._capacity(found.x, radius, height)

    def farthest(self, height: float) -> LiftPoint | None:
        """The capacity at the largest radius the lift point reaches at ``height``."""
        level = np.abs(self.points[:, 2] - height) < 0.25
        if not level.any():
            return None
        near = int(np.flatnonzero(level)[np.argmax(self.points[level, 0])])
        found = minimize(lambda x: -self._point(x)[0], self._start(near), method="SLSQP", bounds=list(zip(self.low, self.high)),
                         constraints=[{"type": "eq", "fun": lambda x: self._point(x)[2] - height}],
                         options={"ftol": 1e-12, "maxiter": 200})  # fmt: skip
        point = self._point(found.x)
        if abs(point[2] - height) > 1e-6:
            return None
        return self._capacity(found.x, float(point[0]), height)

    def _capacity(self, values: np.ndarray, radius: float, height: float) -> LiftPoint:
        u = self._inputs(np.clip(values, self.low, self.high))
        q = self._pose(values)
        system = self.system
        statics = Statics(pose_results(system, q[None], u[None]), self.model)
        _, multipliers = statics.hold(self.spec.point.body, self.spec.point.name, np.array([[0.0, 0.0, -1.0]]))
        limits = statics.hydraulic_limits(statics.element_forces(multipliers), working=self.spec.lifting)
        limiting = min(limits, key=lambda name: limits[name][0][0])  # the first of equals, in the model's order
        setting = "relief" if limiting == self.spec.lifting else "holding"
        return LiftPoint(radius, height, float(limits[limiting][0][0]), limiting, setting, dict(zip(system.driver_names, map(float, u))))
