"""ISO 6015 tool forces of a backhoe: the bucket cylinder tool force (bucket digging force) and the
arm cylinder tool force (arm crowd force), hydraulic limit, with the limiting circuit named.

How kinegen computes them (the standard's definitions in kinegen's words: docs/forces.md):

* The force acts at the lip, tangent to the lip's circle about the pivot of the part the working
  cylinder turns (the bucket pin for the bucket force, the boom-arm pin for the arm force), against
  the lip's motion when that cylinder extends: the resistance the cylinder works against.
* At a pose, the largest such force is the smallest of the forces at which some cylinder reaches
  its setting: the working cylinder at its relief setting, every other cylinder (holding its
  position) at its holding (port relief) setting. Per unit lip force, each cylinder's force comes
  from one solve Φ_qᵀ λ = Q (:mod:`kinegen.forces.statics`); its pressure from its side's area.
* The figure is the largest over the positions of the front ("the position giving the maximum
  force"): the working cylinder's stroke and the other inputs the working range sweeps (boom and
  arm for the bucket force, the boom for the arm force), from a coarse grid then SLSQP on
  max t subject to every cylinder's limit >= t. For the arm force the bucket is first turned to
  where the lip is farthest from the arm pivot (the longest lever) and stays there.
* The working cylinder's relief-limited force depends on its own stroke only (the linkage it
  drives): its largest value, the *ceiling*, is what the figure would be if no other circuit
  limited first.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from kinegen.errors import KinegenError
from kinegen.forces.statics import Statics, pose_results, unit_rate_velocities
from kinegen.model import Model
from kinegen.model.schema import ToolForce
from kinegen.runtime import NumericSystem, Solver, SolverOptions, kinematics

#: poses on a stroke before the maximum is refined
GRID = 41
#: the largest change of an input (m or rad) in one Newton solve when moving from pose to pose
STEP = 0.05
#: the step, relative to max(1, |u|), of the forward differences the optimum's search takes its limits' slopes by (√ε)
FD_STEP = float(np.sqrt(np.finfo(float).eps))


@dataclass(frozen=True)
class ToolForceResult:
    """One ISO 6015 tool force: the figure, where it is reached and what limits it."""

    name: str  #: "bucket" or "arm"
    force: float  #: [N] the largest tool force over the stroke
    driver: str
    stroke_value: float  #: the driver's input where it is reached
    inputs: dict[str, float]  #: every driver's input at that pose
    lip: np.ndarray  #: (3,) the lip's position there [m]
    radius: float  #: the lip's distance from the pivot [m]
    limiting: str  #: the actuator whose setting limits it
    setting: str  #: "relief" (the working cylinder) or "holding" (another one)
    pressure: float  #: [Pa] the limiting setting
    side: str  #: "cap" or "rod"
    #: the other cylinders that reach their settings at the same force (within 1e-6): (actuator, setting, pressure, side)
    also: tuple[tuple[str, str, float, str], ...]
    #: [N] the working cylinder alone at its relief setting: its largest tool force over its stroke
    #: (the figure when no other circuit limits first), and the input where it is reached
    ceiling: float
    ceiling_at: float
    stroke: np.ndarray  #: (GRID,) the searched inputs (the other inputs where the search started)
    curve: np.ndarray  #: (GRID,) the tool force at each
    capacities: dict[str, np.ndarray]  #: per hydraulic actuator, (GRID,) the tool force at which it reaches its setting
    published: float | None = None


def tool_forces(system: NumericSystem, model: Model) -> dict[str, ToolForceResult]:
    """The model's ISO 6015 tool forces (``tool_forces:``) in ``system`` (a case of the model: the
    spec's case)."""
    spec = model.tool_forces
    if spec is None:
        raise KinegenError(f"{model.name} has no tool_forces: section (what kinegen forces computes)")
    if system.case != spec.case:
        raise KinegenError(f"tool_forces are computed in case {spec.case!r}, not {system.case!r}")
    finder = _Finder(system, model)
    out = {}
    for name, item in spec.forces.items():
        base = finder.start.copy()
        if name == "arm" and "bucket" in spec.forces:  # the bucket turned to the longest lever about the arm pivot
            bucket = spec.forces["bucket"]
            k = system.driver_names.index(bucket.driver)
            lever = finder.lever(base, k, item.pivot)
            best = minimize_scalar(lambda s: -lever(s), bounds=bucket.stroke, method="bounded", options={"xatol": 1e-9})  # noqa: B023
            base[k] = float(best.x)
        swept = model.working_range.numbers(system.design) if model.working_range is not None and model.working_range.case == spec.case else {}
        held = {d.driver for d in spec.forces.values()} if name == "arm" else {item.driver}  # the bucket stays at its lever
        free = {system.driver_names.index(n): r for n, r in swept.items() if isinstance(r, tuple) and n not in held}
        out[name] = finder.tool_force(item, base, free, spec.published.get(name))
    return out


class _Finder:
    """Poses along a stroke (Newton continuation) and the tool force at each."""

    def __init__(self, system: NumericSystem, model: Model) -> None:
        self.system = system
        self.model = model
        self.solver = Solver(system, SolverOptions())
        self.start = system.driver_inputs(system.t0)[0].astype(float)
        self.q, self.u = self.solver.position(system.initial_q, self.start, system.t0)[0], self.start.copy()
        self.lip = model.tool_forces.lip
        self.hydraulic = [a for a in model.actuators if a.hydraulics is not None]

    def pose(self, u: np.ndarray) -> np.ndarray:
        """q at inputs ``u``, by continuation from the last pose in steps of at most ``STEP`` of each input."""
        steps = max(1, int(np.ceil(np.abs(u - self.u).max() / STEP)))
        for f in np.linspace(0, 1, steps + 1)[1:]:
            self.q = self.solver.position(self.q, self.u + f * (u - self.u))[0]
        self.u = u.copy()
        return self.q

    def lever(self, base: np.ndarray, k: int, pivot) -> Callable[[float], float]:
        """s -> the lip's distance from ``pivot`` with input k at s."""

        def distance(s: float) -> float:
            u = base.copy()
            u[k] = s
            q = self.pose(u)
            points = self.system.point_positions(q[None], [(self.lip.body, self.lip.name), (pivot.body, pivot.name)])[0]
            return float(np.linalg.norm(points[0] - points[1]))

        return distance

    def tool_force(self, item: ToolForce, base: np.ndarray, free: dict[int, tuple[float, float]], published: float | None) -> ToolForceResult:
        """The largest tool force of ``item``: the working cylinder's relief-limited force is
        largest at one place of its stroke (it depends on its own stroke only); there the other
        ``free`` inputs (index -> range) are searched for the pose where no other cylinder's holding
        setting limits first; if there is none, the smallest limit is maximized over all of them."""
        k = self.system.driver_names.index(item.driver)
        stroke = np.linspace(*item.stroke, GRID)
        inputs = np.repeat(base[None], GRID, axis=0)
        inputs[:, k] = stroke
        capacities, _ = self._capacities(item, inputs)
        working = capacities[item.actuator]
        best = int(np.argmax(working))
        at = base.copy()
        at[k] = stroke[best]
        if 0 < best < GRID - 1:
            found = minimize_scalar(lambda x: -self._limit(item, _with(at, {k: x}), item.actuator), method="bounded",
                                    bounds=(stroke[best - 1], stroke[best + 1]), options={"xatol": 1e-9})  # fmt: skip
            at[k] = float(found.x)
        ceiling, ceiling_at = self._limit(item, at, item.actuator), float(at[k])
        if free:
            at = self._optimum(item, at, {k: item.stroke, **free})
        caps, settings = self._capacities(item, at[None])
        figure = min(float(c[0]) for c in caps.values())
        limiting = [settings[a][0] for a in sorted(caps, key=lambda a: caps[a][0]) if caps[a][0] <= figure * (1 + 1e-6)]
        (name, setting, pressure, side), also = limiting[0], tuple(limiting[1:])
        q = self.pose(at)
        lip, pivot = self.system.point_positions(q[None], [(self.lip.body, self.lip.name), (item.pivot.body, item.pivot.name)])[0]
        return ToolForceResult(
            item.name, figure, item.driver, float(at[k]), dict(zip(self.system.driver_names, map(float, at))),
            lip, float(np.linalg.norm(lip - pivot)), name, setting, pressure, side, also, ceiling, ceiling_at, stroke, np.min(np.stack(list(capacities.values())), axis=0),
            capacities, published,
        )  # fmt: skip

    def _limit(self, item: ToolForce, u: np.ndarray, only: str | None = None) -> float:
        """The tool force at inputs ``u`` at which the first cylinder (or ``only`` that one) reaches its setting."""
        capacities, _ = self._capacities(item, u[None])
        return float(capacities[only][0]) if only else float(min(c[0] for c in capacities.values()))

    def _optimum(self, item: ToolForce, at: np.ndarray, free: dict[int, tuple[float, float]]) -> np.ndarray:
        """``at`` with the ``free`` inputs (index -> range) moved to the largest tool force: the best
        of a coarse grid (one batch), then max t subject to every cylinder's limit >= t (SLSQP)."""
        index = list(free)
        low, high = np.array([free[i][0] for i in index]), np.array([free[i][1] for i in index])
        axes = [np.linspace(lo, hi, 9 if i == index[0] else 5) for i, lo, hi in zip(index, low, high)]
        grid = _serpentine(axes)
        capacities, _ = self._capacities(item, np.stack([_with(at, dict(zip(index, x))) for x in grid]))
        limits = np.min(np.stack(list(capacities.values())), axis=0)
        start = grid[int(np.argmax(limits))] if limits.max() > self._limit(item, at) else at[index]
        cache: dict[bytes, np.ndarray] = {}

        def each(x: np.ndarray) -> np.ndarray:
            key = x.tobytes()
            if key not in cache:
                caps, _ = self._capacities(item, _with(at, dict(zip(index, np.clip(x, low, high))))[None])
                cache[key] = np.array([c[0] for c in caps.values()])
            return cache[key]

        def slopes(x: np.ndarray) -> np.ndarray:
            """d each / dx by forward differences, the shifted poses in one batch: steps of sqrt(eps)
            max(1, |x_i|), taken towards the inside of the bounds."""
            x = np.clip(x, low, high)
            size = FD_STEP * np.maximum(1.0, np.abs(x))
            shifted = x + np.diag(np.where(x + size > high, -size, size))
            caps, _ = self._capacities(item, np.stack([_with(at, dict(zip(index, row))) for row in shifted]))
            changes = np.array([c for c in caps.values()]) - each(x)[:, None]  # (actuators, variables)
            return changes / (shifted.diagonal() - x)[None, :]

        scale = float(limits.max())
        found = minimize(lambda z: -z[-1], np.r_[start, self._limit(item, _with(at, dict(zip(index, start)))) / scale], method="SLSQP",
                         jac=lambda z: np.r_[np.zeros(len(index)), -1.0],
                         constraints=[{"type": "ineq", "fun": lambda z: each(z[:-1]) / scale - z[-1],
                                       "jac": lambda z: np.c_[slopes(z[:-1]) / scale, -np.ones(len(each(z[:-1])))]}],
                         bounds=[*zip(low, high), (0, None)], options={"ftol": 1e-12, "maxiter": 200})  # fmt: skip
        best = _with(at, dict(zip(index, np.clip(found.x[:-1], low, high))))
        return best if self._limit(item, best) >= self._limit(item, _with(at, dict(zip(index, start)))) else _with(at, dict(zip(index, start)))

    def _capacities(self, item: ToolForce, inputs: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, list[tuple[str, str, float, str]]]]:
        """Per hydraulic actuator, the tool force (K,) at which it reaches its setting, at the poses of
        ``inputs`` (K, n_inputs); and per actuator, per pose, (actuator, setting, pressure, side) that applies."""
        system = self.system
        q = np.stack([self.pose(u) for u in inputs])
        results = pose_results(system, q, inputs, unit_rate_velocities(system, q, inputs, item.driver))
        motion = kinematics.point_velocity(results, self.lip.body, self.lip.name)  # the lip's velocity per unit rate of the working input
        direction = motion / np.linalg.norm(motion, axis=1)[:, None]
        statics = Statics(results, self.model)
        _, multipliers = statics.hold(self.lip.body, self.lip.name, -direction)  # 1 N resisting the lip's motion
        limits = statics.hydraulic_limits(statics.element_forces(multipliers), working=item.actuator)
        capacities = {name: limit for name, (limit, _, _) in limits.items()}
        settings = {
            name: [(name, "relief" if name == item.actuator else "holding", float(p), str(d)) for p, d in zip(pressure, side)]
            for name, (_, pressure, side) in limits.items()
        }
        return capacities, settings

def _with(u: np.ndarray, values: dict[int, float]) -> np.ndarray:
    out = u.copy()
    for i, value in values.items():
        out[i] = value
    return out


def _serpentine(axes: list[np.ndarray]) -> np.ndarray:
    """Every point of the grid of ``axes`` (N, len(axes)), ordered so that consecutive points are
    neighbours (each axis runs back and forth): continuation moves one grid step at a time."""
    if len(axes) == 1:
        return axes[0][:, None]
    rest = _serpentine(axes[1:])
    return np.concatenate([np.column_stack([np.full(len(rest), x), rest if i % 2 == 0 else rest[::-1]]) for i, x in enumerate(axes[0])])


#: what each tool force is called in a report
TITLES = {"bucket": "bucket digging force (bucket cylinder tool force)", "arm": "arm crowd force (arm cylinder tool force)"}


def document(found: dict[str, ToolForceResult], model: Model, seconds: float) -> dict:
    """The tool forces as JSON data (``kinegen forces --json``): per force its figure, the
    published one, the limiting circuit and the others at their settings, the working cylinder's
    ceiling, the pose and the curve over the stroke; SI units."""
    return {
        "model": model.name, "lip": f"{model.tool_forces.lip.body}.{model.tool_forces.lip.name}", "seconds": seconds,
        "forces": {name: {
            "force": r.force, "published": r.published, "limiting": {"actuator": r.limiting, "setting": r.setting, "pressure": r.pressure, "side": r.side},
            "also": [{"actuator": a, "setting": s, "pressure": p, "side": d} for a, s, p, d in r.also],
            "ceiling": r.ceiling, "ceiling_at": r.ceiling_at, "inputs": r.inputs, "lip": r.lip.tolist(), "radius": r.radius,
            "stroke": r.stroke.tolist(), "curve": r.curve.tolist(),
        } for name, r in found.items()},
    }  # fmt: skip


def report(found: dict[str, ToolForceResult], model: Model, seconds: float | None = None) -> str:
    """The tool forces as text: each figure beside its published value, the circuits that limit it,
    the working cylinder's ceiling, and the pose where it is reached."""
    spec = model.tool_forces
    lip = spec.lip
    timing = f"  [{seconds:.2f} s]" if seconds is not None else ""
    lines = [f"{model.name}: ISO 6015 tool forces at the lip ({lip.body}.{lip.name}), hydraulic limit{timing}"]
    for name, r in found.items():
        published = f"; published {r.published / 1e3:.0f} kN (unverified), kinegen {100 * (r.force / r.published - 1):+.1f} %" if r.published else ""
        lines.append(f"  {TITLES[name]}: {r.force / 1e3:.1f} kN{published}")
        limits = [(r.limiting, r.setting, r.pressure, r.side), *r.also]
        lines.append("    limited by " + ", ".join(f"{a} {s} {p / 1e6:.1f} MPa ({d} side)" for a, s, p, d in limits))
        working = spec.forces[name]
        lines.append(f"    {working.actuator} alone at its relief setting: {r.ceiling / 1e3:.1f} kN at {working.driver} = {r.ceiling_at:.4f}")
        pose = ", ".join(f"{k} {v:.4f}" for k, v in r.inputs.items())
        lines.append(f"    at {pose}; lip at x {r.lip[0]:.3f}, y {r.lip[1]:.3f}, z {r.lip[2]:.3f} m, {r.radius:.3f} m from "
                     f"{working.pivot.body}.{working.pivot.name}")  # fmt: skip
    return "\n".join(lines)
