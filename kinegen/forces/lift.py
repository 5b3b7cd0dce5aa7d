"""ISO 10567 lift chart: the rated lift capacity at the arm's end over a grid of lift-point heights
and radii, over the front and over the side -- at each point the smaller of 87 % of the hydraulic
lift capacity and 75 % of the tipping load.

At each grid point (radius r from the swing axis, height h, in the boom plane at zero swing) the
inputs that place the lift point (``lift_chart.place``, e.g. boom and arm cylinders) are solved so
that the point is there (bounded least squares on the inputs, from the nearest pose of a compiled
grid sweep); the others stay at the case's start. The load hangs at the lift point on its body
(the arm: the bucket removed, ``lift_chart.without``).

* **Hydraulic lift capacity**: the largest load with the lifting cylinder at most at its relief
  setting and the others at most at their holding settings, the front's own weight (a model with
  masses) held too.
* **Tipping load** (a model with masses and a ``machine:`` section): the load whose moment about
  the tipping line equals that of every weight on the machine's side of it -- the moving bodies at
  the pose (less ``without``) and the undercarriage. kinegen's tipping lines (its own choice, where
  the standard's text could not be read): over the front, the line across the tracks at half the
  tumbler distance in front of the swing axis (the front idlers' centres); over the side, the
  centreline of the track on that side (half the gauge from the swing axis), the upper structure
  swung a quarter turn. The load tips the machine when its radius is beyond the line.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.optimize import least_squares, minimize

from kinegen.errors import KinegenError
from kinegen.forces.statics import Rows, Statics, pose_results
from kinegen.model import Model
from kinegen.model.schema import STANDARD_GRAVITY, design_value
from kinegen.runtime import NumericSystem, Solver, SolverOptions
from kinegen.runtime.batch import sweep_grid

#: standard gravity [m/s^2]: a load's mass in kg is its weight in N / G
G = -float(STANDARD_GRAVITY[2])
#: ISO 10567: the rated lift capacity is at most this share of the hydraulic lift capacity
HYDRAULIC_SHARE = 0.87
#: ISO 10567: ... and at most this share of the tipping load
TIPPING_SHARE = 0.75


@dataclass(frozen=True)
class LiftPoint:
    """The lift capacities at one lift-point position."""

    radius: float  #: m from the swing axis
    height: float  #: m above the ground
    capacity: float  #: [N] the hydraulic lift capacity (NaN where the point cannot be reached)
    limiting: str  #: the cylinder that limits it
    setting: str  #: "relief" or "holding"
    inputs: dict[str, float]  #: the pose's inputs
    #: [kg] the tipping load over the front and over the side (inf: the radius is inside the tipping
    #: line; NaN: no masses or no machine: section)
    tipping_front: float = float("nan")
    tipping_side: float = float("nan")

    @property
    def hydraulic_kg(self) -> float:
        """ISO 10567's hydraulic rating: 87 % of the hydraulic capacity, in kg."""
        return HYDRAULIC_SHARE * self.capacity / G

    def rated(self, side: bool) -> tuple[float, str]:
        """The rated lift capacity over the front (``side`` False) or the side [kg] and its limit:
        "hydraulic" or "tipping" (the hydraulic rating alone when the tipping load is unknown)."""
        tipping = TIPPING_SHARE * (self.tipping_side if side else self.tipping_front)
        if np.isnan(tipping) or self.hydraulic_kg <= tipping:
            return self.hydraulic_kg, "hydraulic"
        return tipping, "tipping"

    def document(self) -> dict:
        """The point as JSON data (``kinegen lift --json``): SI units and kg; an unknown or infinite
        tipping load is null."""
        (front, front_limit), (side, side_limit) = self.rated(False), self.rated(True)
        finite = {"tipping_front_kg": self.tipping_front, "tipping_side_kg": self.tipping_side}
        return {"radius": self.radius, "height": self.height, "capacity_n": self.capacity, "hydraulic_kg": self.hydraulic_kg,
                **{k: (None if not np.isfinite(v) else v) for k, v in finite.items()},
                "rated_front_kg": front, "front_limit": front_limit, "rated_side_kg": side, "side_limit": side_limit,
                "limiting": self.limiting, "setting": self.setting, "inputs": self.inputs}  # fmt: skip


class Held(NamedTuple):
    """A lift pose and its solves (:meth:`Placer.held`)."""

    inputs: np.ndarray  #: every driver input
    q: np.ndarray  #: stored coordinates
    statics: Statics  #: at that one pose
    matrix: Rows
    multipliers: np.ndarray  #: (1, rows): holding a unit load (1 N, downward) at the lift point
    weight: np.ndarray | None  #: (1, rows): holding the front's weight; None without masses


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

    tipping: bool = False  #: whether the tipping loads are known (masses and a machine: section)
    without: tuple[str, ...] = ()
    #: the lift point's range in the boom plane (radius, height) [m], (P, 2), closed: the placing
    #: inputs' range boundary mapped by exact poses (no fold inside it); None where it has a fold
    outline: np.ndarray | None = None

    def table(self) -> str:
        """The manufacturers' layout: a row per lift-point height, per radius the rated load over the
        front and over the side, and the load at the largest radius; kg."""
        columns = [f"{r:g} m" for r in self.radii] + ["max reach"]
        removed = f" (without {', '.join(self.without)})" if self.without else ""
        if self.tipping:
            rule = ("the smaller of 87 % of the hydraulic lift capacity and 75 % of the tipping load (ISO 10567); "
                    "* hydraulic limit, otherwise tipping")  # fmt: skip
        else:
            rule = ("87 % of the hydraulic lift capacity (ISO 10567); * hydraulic limit. The tipping limit needs masses and a "
                    "machine: section: read the side columns as an upper bound")  # fmt: skip
        lines = [
            f"rated lift capacity at {self.point}{removed}, kg: {rule}; {self.lifting} lifting at its relief setting, the "
            "other cylinders holding",
            f"{'height':>7}  " + "  ".join(f"{c:^17}" for c in columns),
            f"{'m':>7}  " + "  ".join(f"{'front':>8} {'side':>8}" for _ in columns),
        ]
        for h, row, reach in zip(self.heights, self.grid, self.max_reach):
            cells = [_cell(p) for p in row] + [_cell(reach, radius=True)]
            lines.append(f"{h:>7g}  " + "  ".join(cells))
        points = [p for row in (*self.grid, self.max_reach) for p in row]
        if any(p is None or not np.isfinite(p.capacity) for p in points):
            lines.append(UNREACHED)
        if any("tips" in _cell(p) for p in points):
            lines.append(TIPS)
        return "\n".join(lines)

    def document(self) -> dict:
        """The chart as JSON data (``kinegen lift --json``): every grid point's and the largest
        radius's :meth:`LiftPoint.document` (null where the point cannot be placed)."""
        def entry(p: LiftPoint | None) -> dict | None:
            return None if p is None else p.document()

        return {
            "point": self.point, "lifting": self.lifting, "without": self.without, "heights": self.heights,
            "radii": self.radii, "tipping": self.tipping,
            "grid": [[entry(p) for p in row] for row in self.grid], "max_reach": [entry(p) for p in self.max_reach],
        }  # fmt: skip

    def csv_text(self) -> str:
        """Every placed point as CSV (``kinegen lift --out``): a row per grid point, then per height
        the largest radius's (at_max_reach 1); SI units and kg."""
        rows = ["height_m,radius_m,at_max_reach,hydraulic_capacity_n,tipping_front_kg,tipping_side_kg,rated_front_kg,front_limit,"
                "rated_side_kg,side_limit,limiting_cylinder"]  # fmt: skip
        for row, reach in zip(self.grid, self.max_reach):
            for p, at_reach in [*((p, 0) for p in row), (reach, 1)]:
                if p is not None and np.isfinite(p.capacity):
                    (front, front_limit), (side, side_limit) = p.rated(False), p.rated(True)
                    rows.append(",".join(str(x) for x in (p.height, f"{p.radius:.6g}", at_reach, f"{p.capacity:.6g}",
                                                          f"{p.tipping_front:.6g}", f"{p.tipping_side:.6g}", f"{front:.6g}",
                                                          front_limit, f"{side:.6g}", side_limit, p.limiting)))  # fmt: skip
        return "\n".join(rows) + "\n"


#: what the chart's marks mean (the table's and the picture's notes)
UNREACHED = "-: the lift point cannot be placed at that radius and height"
TIPS = "tips: the machine tips over with no load there (its own weight's moment about the tipping line exceeds the undercarriage's)"


def rated_text(point: LiftPoint, side: bool) -> str:
    """A rated load as the chart shows it: kg, ``*`` where the hydraulic limit rules, ``tips`` where
    the machine tips unloaded (a negative tipping load: no load can be held)."""
    value, limit = point.rated(side)
    return "tips" if value < 0 else f"{'*' if limit == 'hydraulic' else ''}{value:,.0f}"


def _cell(point: LiftPoint | None, radius: bool = False) -> str:
    if point is None or not np.isfinite(point.capacity):
        return f"{'-':>8} {'-':>8}"
    texts = [rated_text(point, side) for side in (False, True)]
    return f"{texts[0]:>8} {texts[1]:>8}" + (f" @{point.radius:.2f}" if radius else "")


def lift_chart(system: NumericSystem, model: Model) -> LiftChart:
    """The model's ``lift_chart`` in ``system`` (a case of the model: the spec's case)."""
    spec = model.lift_chart
    if spec is None:
        raise KinegenError(f"{model.name} has no lift_chart: section")
    placer = Placer(system, model)
    grid = tuple(tuple(placer.at(r, h) for r in spec.radii) for h in spec.heights)
    reach = tuple(placer.farthest(h) for h in spec.heights)
    return LiftChart(f"{spec.point.body}.{spec.point.name}", spec.lifting, spec.heights, spec.radii, grid, reach,
                     model.tips, spec.without, placer.outline())  # fmt: skip


class Placer:
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

    def outline(self, per_edge: int = 81) -> np.ndarray | None:
        """The lift point's range in the boom plane (radius, height): the boundary of the placing
        inputs' rectangle, ``per_edge`` exact poses along each edge (by continuation), when the map
        from those inputs to the point has no fold inside (its Jacobian's determinant keeps one sign
        over the sampled grid: the range is then the image of the boundary); else None."""
        count = [len(np.unique(self.samples[:, d])) for d in range(2)]
        if len(self.samples) != count[0] * count[1]:
            return None  # a pose of the grid did not solve: no fold test
        plane = self.points[:, [0, 2]].reshape(count[0], count[1], 2)
        du, dv = np.diff(plane, axis=0)[:, :-1], np.diff(plane, axis=1)[:-1]
        det = du[..., 0] * dv[..., 1] - du[..., 1] * dv[..., 0]
        if not (np.all(det > 0) or np.all(det < 0)):
            return None
        (low0, low1), (high0, high1) = self.low, self.high
        along = np.linspace(0.0, 1.0, per_edge)
        corners = [(low0, low1), (high0, low1), (high0, high1), (low0, high1), (low0, low1)]
        inputs = np.vstack([np.outer(1 - along[:-1], start) + np.outer(along[:-1], end) for start, end in itertools.pairwise(corners)])
        self._start(0)  # the grid's first sample: the rectangle's corner (low, low)
        points = np.array([self._point(x)[[0, 2]] for x in inputs])
        return np.vstack([points, points[:1]])

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

    @property
    def weighed(self) -> list:
        """The massive bodies whose weight the lift carries (the model's, less ``without``)."""
        return [b for b in self.model.massive if b.name not in self.spec.without]

    def held(self, values: np.ndarray) -> Held:
        """The pose at the placing inputs ``values`` and what holds a unit load hanging at the lift
        point there, and the front's own weight (less ``without``) before it."""
        u = self._inputs(np.clip(values, self.low, self.high))
        q = self._pose(values)
        statics = Statics(pose_results(self.system, q[None], u[None]), self.model)
        matrix, multipliers = statics.hold(self.spec.point.body, self.spec.point.name, np.array([[0.0, 0.0, -1.0]]))
        weight = statics.solve(matrix, statics.weight_load(self.weighed)) if self.weighed else None
        return Held(u, q, statics, matrix, multipliers, weight)

    def _capacity(self, values: np.ndarray, radius: float, height: float) -> LiftPoint:
        system = self.system
        u, _, statics, _, multipliers, weight = self.held(values)
        carried = None if weight is None else statics.element_forces(weight)
        limits = statics.hydraulic_limits(statics.element_forces(multipliers), working=self.spec.lifting, carried=carried)
        limiting = min(limits, key=lambda name: limits[name][0][0])  # the first of equals, in the model's order
        setting = "relief" if limiting == self.spec.lifting else "holding"
        front = side = float("nan")
        if self.model.tips:
            front, side = tipping_loads(self.model, statics, self.weighed, radius)
        return LiftPoint(radius, height, float(limits[limiting][0][0]), limiting, setting, dict(zip(system.driver_names, map(float, u))),
                         front, side)  # fmt: skip


def tipping_loads(model: Model, statics: Statics, bodies: list, radius: float) -> tuple[float, float]:
    """The tipping loads [kg] over the front and over the side of a load hanging at ``radius`` from
    the swing axis, the front of the pose (one pose: ``statics``'s first) pointing along +x: per
    tipping line at distance d from the swing axis, Σ m_i (d - x_i) / (radius - d) over ``bodies``
    (x_i their centres of mass along the front) and the undercarriage (x along the tracks over the
    front; its y over the side: it does not swing); inf where the radius is inside the line."""
    front, side = (float("inf") if radius <= line else sum(m * (line - x) for m, _, x, _ in terms) / (radius - line)
                   for line, _, terms in _levers(model, statics, bodies))  # fmt: skip
    return front, side


def tipping_load_changes(model: Model, statics: Statics, changes, bodies: list, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """d/d(design parameters) (P,) of :func:`tipping_loads` [kg per unit], the pose moving as
    ``changes`` (a :class:`kinegen.forces.sensitivity.TangentChanges` along the pose's change) says
    and the load's radius held: with T = R / (r - d), R = Σ m_i (d - x_i) + m_u (d - x_u),
    dT = (Σ dm_i (d - x_i) + m_i (dd - dx_i) + dm_u (d - x_u) + m_u (dd - dx_u)) / (r - d) + T dd / (r - d);
    zero where the radius is inside the line."""
    out = []
    for line, d_line, terms in _levers(model, statics, bodies, changes):
        if radius <= line:
            out.append(np.zeros(len(statics.system.design)))
            continue
        restoring = sum(m * (line - x) for m, _, x, _ in terms)
        d_restoring = sum(dm * (line - x) + m * (d_line - dx) for m, dm, x, dx in terms)
        out.append(d_restoring / (radius - line) + restoring * d_line / (radius - line) ** 2)
    return out[0], out[1]


def _levers(model: Model, statics: Statics, bodies: list, changes=None) -> list[tuple[float, np.ndarray, list]]:
    """Per tipping line (over the front, over the side): its distance d from the swing axis, dd/dp and
    per weight (``bodies`` at the pose, then the undercarriage) (mass, d mass/dp, its centre along the
    front, that position's d/dp) -- the derivatives zero unless ``changes`` (the pose's change,
    :class:`kinegen.forces.sensitivity.TangentChanges`) is given."""
    from kinegen.model.schema import design_gradient

    machine = model.machine
    design = statics.system.design
    count = len(design)
    value = functools.partial(design_value, design=design)
    if changes is None:  # the chart's values alone: no derivatives to take

        def gradient(_) -> np.ndarray:
            return np.zeros(count)
    else:
        gradient = functools.partial(design_gradient, names=list(design), design=design)
    weights = []
    for body in bodies:
        local = statics.design_vector(body.inertia.center)
        if changes is None:
            along, d_along = statics.position(body.name, local)[0, 0], np.zeros(count)
        else:
            d_local = np.array([gradient(x) for x in body.inertia.center]).reshape(3, count)
            position, d_position, _, _ = changes.point_at(body.name, local, d_local)
            along, d_along = position[0, 0], d_position[0, 0]
        weights.append((value(body.inertia.mass), gradient(body.inertia.mass), along, d_along))
    under = (value(machine.undercarriage_mass), gradient(machine.undercarriage_mass))
    return [(value(size) / 2, gradient(size) / 2, [*weights, (*under, value(machine.undercarriage_center[axis]),
                                                               gradient(machine.undercarriage_center[axis]))])
            for size, axis in ((machine.track_length, 0), (machine.gauge, 1))]  # fmt: skip


def lift_chart_figure(chart: LiftChart, boundary=None):
    """The lift chart as an engineer reads it: on the left, the boom plane (radius from the swing axis,
    height above the ground) with the lift point's own range (:attr:`LiftChart.outline`; without it,
    the working range ``boundary`` of the tool point, so named), each grid point's ratings over the
    front (above) and over the side (below) in kg -- blue where the hydraulic limit rules, red where
    tipping does -- and the largest reach at each height as a dashed line; on the right, the table in
    the layout manufacturers print (heights as rows, radii as columns, front and side, the largest
    reach with its radius), coloured the same."""
    from kinegen.figures import pyplot

    plt = pyplot()
    fig, (ax, side) = plt.subplots(1, 2, figsize=(16.5, 8.0), gridspec_kw={"width_ratios": [1.0, 1.25]})
    if chart.outline is not None:
        ax.plot(chart.outline[:, 0], chart.outline[:, 1], color="0.35", lw=1.2, label=f"range of the lift point {chart.point}", gid="outline")
    elif boundary is not None:
        ax.plot(boundary.points[:, 0], boundary.points[:, 1], color="0.4", lw=1.0, label="working range of the tool point", gid="boundary")
    colours = {"hydraulic": "tab:blue", "tipping": "tab:red"}
    reach = [p for p in chart.max_reach if p is not None and np.isfinite(p.capacity)]
    ax.plot([p.radius for p in reach], [p.height for p in reach], "--", color="0.5", lw=0.8, marker="o", ms=3,
            label="largest reach at each height (ratings: the table)", gid="reach")  # fmt: skip
    tips = False  # whether a point shows "tips" (the note says what it means)
    for p in (p for row in chart.grid for p in row if p is not None and np.isfinite(p.capacity)):
        ax.plot(p.radius, p.height, "o", color="0.2", ms=3)
        for on_side, offset in ((False, 3), (True, -10)):
            _, limit = p.rated(on_side)
            tips = tips or p.rated(on_side)[0] < 0
            ax.annotate(rated_text(p, on_side), (p.radius, p.height), xytext=(-4, offset), textcoords="offset points", fontsize=7.5,
                        color=colours[limit], ha="right")  # fmt: skip
    for limit, colour in colours.items():
        ax.plot([], [], "s", color=colour, label=f"{limit} limit")
    ax.axhline(0.0, color="saddlebrown", lw=1.0)
    ax.set(aspect="equal", xlabel="radius: horizontal distance from the swing axis [m]", ylabel="height of the lift point above the ground [m]",
           title=f"rated lift capacity at {chart.point} [kg]: over the front (upper), over the side (lower)")  # fmt: skip
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=8, frameon=False)  # below the drawing: it covers nothing
    _table_panel(side, chart, colours)
    fig.suptitle("ISO 10567: the smaller of 87 % of the hydraulic lift capacity and 75 % of the tipping load"
                 + (f"; without {', '.join(chart.without)}" if chart.without else ""), fontsize=10)  # fmt: skip
    notes = [UNREACHED, *([TIPS] if tips else [])]
    fig.text(0.5, 0.01, "   ".join(notes), ha="center", fontsize=8)
    fig.tight_layout(rect=(0, 0.03, 1, 0.96))
    return fig


def _table_panel(side, chart: LiftChart, colours: dict[str, str]) -> None:
    """The manufacturers' table on ``side``: a row per height, per radius the front and side
    ratings, the largest reach's ratings and radius; each rating coloured by its limit."""
    side.axis("off")
    header = ["height", *(f"{r:g} m {which}" for r in chart.radii for which in ("front", "side")), "max reach front", "max reach side",
              "at radius"]  # fmt: skip
    cells, colour_rows = [], []
    for h, row, far in zip(chart.heights, chart.grid, chart.max_reach):
        texts, tints = [f"{h:g} m"], ["black"]
        for p in (*row, far):
            for on_side in (False, True):
                if p is None or not np.isfinite(p.capacity):
                    texts.append("-")
                    tints.append("0.4")
                else:
                    texts.append(rated_text(p, on_side))
                    tints.append(colours[p.rated(on_side)[1]])
        texts.append("-" if far is None or not np.isfinite(far.capacity) else f"{far.radius:.2f} m")
        tints.append("black")
        cells.append(texts)
        colour_rows.append(tints)
    table = side.table(cellText=cells, colLabels=header, loc="center", cellLoc="right")
    table.auto_set_font_size(False)
    table.set_fontsize(7.5)
    table.scale(1.0, 1.5)
    for (r, c), cell in table.get_celld().items():
        if r == 0:
            cell.set_text_props(fontweight="bold", fontsize=6.5, wrap=True)
        else:
            cell.get_text().set_color(colour_rows[r - 1][c])
        cell.set_gid(f"cell:{r}:{c}")
    side.set_title(f"rated lift capacity at {chart.point} [kg] ({chart.lifting} lifting at its relief setting, the others holding)",
                   fontsize=9)  # fmt: skip


def plot_lift_chart(chart: LiftChart, path, boundary=None):
    """PNG of :func:`lift_chart_figure`."""
    from kinegen.figures import save

    return save(lift_chart_figure(chart, boundary), path)
