"""Working range ("envelope") of a point of a mechanism, by sweeping driver inputs.

The forward case named in the model's ``working_range`` section is driven over the box
of its input ranges: a grid solved in batches (:func:`kinegen.runtime.batch.sweep_grid`:
continuation on every other grid line, then the lines between from interpolated starts,
each batch one vectorized Newton) gives the sampled reachable set; each working-range figure is then
refined by SLSQP over the inputs from the best grid sample, every evaluation a solver call. The standard figures (ISO 7135 style, from the swing axis
and the ground plane z = 0):

* max_reach: largest horizontal distance of the point from the z axis;
* max_reach_at_ground: the same, on z = 0 (a constrained maximum);
* max_depth: largest depth below z = 0; max_cutting_height: largest height;
* max_dumping_height: largest height of the point directly below ``dump_pivot`` (the
  bucket hanging teeth down, as when dumping; a constrained maximum);
* max_vertical_wall_depth: largest depth below z = 0 with the arm vertical, ``arm_pivot``
  directly above ``dump_pivot`` (kinegen's reading of the brochures' "vertical wall digging
  depth"; a constrained maximum, with ``arm_pivot`` only);
* min_front_swing_radius: the smallest radius, over the inputs, of the circle the front
  swings through -- the largest horizontal distance from the swing axis of any named point of
  the bodies the swept inputs move (a min-max: :func:`front_swing_radius`).

The first four lie on the working range's boundary (:mod:`kinegen.analysis.boundary`); the
dumping height and the vertical-wall depth are inside it by their definitions.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from kinegen.model.schema import WORKING_RANGE_FIGURES, WorkingRange, design_gradient
from kinegen.runtime import NumericSystem
from kinegen.runtime.batch import sweep_grid
from kinegen.runtime.continuation import RangeEvaluator

POLISH_STEPS = 8  # Newton steps on the optimality conditions after SLSQP, at most
FIGURES = WORKING_RANGE_FIGURES  # (the schema's list: the loader checks published figures against the same)


@dataclass(frozen=True)
class Figure:
    """A working-range figure as an optimization over the swept inputs: minimize ``objective``
    of the tracked points (the point, the dump pivot, the arm pivot: (P, 3) global positions), subject to
    ``constraint`` = 0 when there is one; the figure is ``-objective`` at the optimum. The
    gradients are in the tracked points' coordinates ((P, 3)), for the envelope theorem."""

    name: str
    objective: Callable[[np.ndarray], float]
    gradient: Callable[[np.ndarray], np.ndarray]
    constraint: Callable[[np.ndarray], float] | None = None
    constraint_gradient: Callable[[np.ndarray], np.ndarray] | None = None


def _horizontal(p: np.ndarray, k: int = 0) -> float:
    return float(np.hypot(p[k, 0], p[k, 1]))


def _horizontal_gradient(p: np.ndarray, k: int = 0) -> np.ndarray:
    out = np.zeros_like(p)
    out[k, :2] = p[k, :2] / _horizontal(p, k)
    return out


def _height_gradient(p: np.ndarray) -> np.ndarray:
    out = np.zeros_like(p)
    out[0, 2] = 1.0
    return out


FIGURE_TABLE = {
    figure.name: figure
    for figure in (
        Figure("max_reach", lambda p: -_horizontal(p), lambda p: -_horizontal_gradient(p)),
        Figure("max_reach_at_ground", lambda p: -_horizontal(p), lambda p: -_horizontal_gradient(p), lambda p: float(p[0, 2]), _height_gradient),
        Figure("max_depth", lambda p: float(p[0, 2]), _height_gradient),
        Figure("max_cutting_height", lambda p: -float(p[0, 2]), lambda p: -_height_gradient(p)),
        Figure(
            "max_dumping_height", lambda p: -float(p[0, 2]), lambda p: -_height_gradient(p),
            lambda p: _horizontal(p, 0) - _horizontal(p, 1), lambda p: _horizontal_gradient(p, 0) - _horizontal_gradient(p, 1),
        ),
        Figure(
            "max_vertical_wall_depth", lambda p: float(p[0, 2]), _height_gradient,
            lambda p: _horizontal(p, 2) - _horizontal(p, 1), lambda p: _horizontal_gradient(p, 2) - _horizontal_gradient(p, 1),
        ),
    )
}  # fmt: skip


@dataclass
class Envelope:
    """Sampled working range and its refined figures."""

    spec: WorkingRange
    names: list[str]  # swept input names
    samples: np.ndarray  # (N, len(names)) input values
    points: np.ndarray  # (N, 3) global positions of the point (NaN where no solve)
    pivots: np.ndarray  # (N, 3) global positions of the dump pivot (NaN if none)
    arm_pivots: np.ndarray | None = None  # (N, 3) global positions of the arm pivot (NaN if none)
    figures: dict[str, float] = field(default_factory=dict)
    arguments: dict[str, dict[str, float]] = field(default_factory=dict)  # figure -> inputs
    seconds: float = 0.0
    solves: int = 0
    grid_seconds: float = 0.0  #: time of the batched grid sweep (continuation to its corner included)
    grid_solved: int = 0  #: grid configurations solved
    #: figure -> (every driver input, the stored coordinates) at its refined optimum
    optima: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    design: dict[str, float] = field(default_factory=dict)  #: the design values it was computed at
    front: FrontSwing | None = None  #: the minimum front swing radius (with a grid only)

    def table(self) -> str:
        """The figures beside the published (unverified) values."""
        lines = [f"{'figure':<24} {'kinegen [m]':>11} {'published [m]':>14}  at inputs"]
        rows = [(name, self.figures[name], self.arguments.get(name, {})) for name in FIGURES if name in self.figures]
        if self.front is not None:
            rows.append(("min_front_swing_radius", self.front.radius, self.front.arguments))
        for name, value, arguments in rows:
            published = self.spec.published.get(name)
            ref = f"{published:>7.2f} (unverified)" if published is not None else f"{'-':>14}"
            where = ", ".join(f"{k} {v:.4f}" for k, v in arguments.items())
            lines.append(f"{name:<24} {value:>11.3f} {ref}  {where}")
        return "\n".join(lines)


@dataclass
class FrontSwing:
    """The minimum front swing radius: min over the swept inputs of the largest horizontal distance
    from the swing axis of the front's named points (every point of a body the swept inputs move)."""

    radius: float  #: m
    arguments: dict[str, float]  #: swept inputs at the minimum
    q: np.ndarray  #: stored coordinates there
    farthest: list[str]  #: "body.point" at the radius there (several at a min-max)


def working_range(system: NumericSystem, spec: WorkingRange, grid: tuple[int, ...] | None = None) -> Envelope:
    """Sample and refine the working range of ``spec.point`` (see the module docstring), at the
    system's design values."""
    start = time.perf_counter()
    evaluator = RangeEvaluator(system, spec)
    names = evaluator.names
    counts = list(grid or [21, 11, 21][: len(names)] + [11] * max(0, len(names) - 3))
    if len(counts) != len(names) or any(c < 2 for c in counts):
        raise ValueError(f"grid {tuple(counts)}: give one count >= 2 per swept input ({', '.join(names)})")
    axes = [np.linspace(lo, hi, c) for (lo, hi), c in zip(evaluator.ranges, counts)]
    corner = np.array([a[0] for a in axes])
    evaluator.move_to(corner)  # continuation from the model's pose to the grid's first corner
    swept = [system.driver_names.index(n) for n in names]
    sweep = sweep_grid(system, evaluator.inputs(corner), swept, axes, evaluator.q)
    grid_seconds = time.perf_counter() - start
    index = np.indices(counts).reshape(len(counts), -1)
    samples = np.array([axes[d][index[d]] for d in range(len(counts))]).T
    q = sweep.q.reshape(system.n_stored, -1)
    ok = sweep.converged.ravel()
    tracked = np.full((len(samples), 3, 3), np.nan)
    found = evaluator.points(q[:, ok])
    tracked[ok, : found.shape[1]] = found
    envelope = Envelope(spec, names, samples, tracked[:, 0], tracked[:, 1], tracked[:, 2], design=dict(system.design))
    envelope.grid_seconds = grid_seconds
    envelope.grid_solved = int(ok.sum())
    starts = {name: (samples[k], q[:, k]) for name, k in _grid_seeds(envelope).items()}
    _refine(envelope, evaluator, starts, bar=True)
    envelope.front = front_swing_radius(system, evaluator, samples[ok], q[:, ok])
    envelope.seconds = time.perf_counter() - start
    envelope.solves = evaluator.solves + int(ok.sum())
    return envelope


def _front_points(system: NumericSystem, evaluator: RangeEvaluator, q: np.ndarray) -> list[tuple[str, str]]:
    """Every named point of the bodies the swept inputs move (checked at the configuration q)."""
    from kinegen.runtime.sensitivity import point_position_sensitivities

    names = [(body, point) for body in system.bodies for point in system.points.get(body, {})]
    _, _, by_input = point_position_sensitivities(system, q[:, None], evaluator.u[:, None], names, design=False)
    moved = np.abs(by_input[0][:, :, evaluator.index]).max(axis=(1, 2))
    return [name for name, change in zip(names, moved) if change > 1e-9]


def front_swing_radius(system: NumericSystem, evaluator: RangeEvaluator, samples: np.ndarray, q: np.ndarray) -> FrontSwing | None:
    """The minimum front swing radius (:class:`FrontSwing`): the best of the solved grid samples
    (swept inputs (N, d), q (n, N)), then SLSQP on min t subject to t >= r_i(u) for every front
    point i (r_i its horizontal distance from the z axis, exact gradients by the inputs)."""
    from kinegen.runtime.sensitivity import point_position_sensitivities

    if not len(samples):
        return None
    evaluator.move_to(samples[0])
    front = _front_points(system, evaluator, evaluator.q)
    if not front:
        return None
    u = np.repeat(evaluator.base[:, None], len(samples), axis=1)
    u[evaluator.index] = samples.T
    positions = system.point_positions(q.T, front)  # every sample's front points (N, P, 3)
    radii = np.hypot(positions[..., 0], positions[..., 1])
    best = int(radii.max(axis=1).argmin())
    lows = np.array([r[0] for r in evaluator.ranges])
    spans = np.array([r[1] - r[0] for r in evaluator.ranges])
    evaluator.q, evaluator.u = q[:, best].copy(), u[:, best].copy()
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def at(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Radii (P,) and their derivatives by the normalized inputs (P, d) at x = (inputs, t)."""
        key = x[:-1].tobytes()
        if key not in cache:
            cache.clear()
            evaluator.move_to(lows + spans * np.clip(x[:-1], 0, 1))
            positions, _, by_input = point_position_sensitivities(system, evaluator.q[:, None], evaluator.u[:, None], front, design=False)
            p, dp = positions[0], by_input[0][:, :, evaluator.index] * spans  # (P, 3), (P, 3, d)
            r = np.hypot(p[:, 0], p[:, 1])
            cache[key] = r, (p[:, 0, None] * dp[:, 0] + p[:, 1, None] * dp[:, 1]) / r[:, None]
        return cache[key]

    x0 = np.append((samples[best] - lows) / spans, radii[best].max())
    result = minimize(
        lambda x: x[-1], x0, jac=lambda x: np.eye(len(x))[-1], method="SLSQP",
        bounds=[(0, 1)] * (len(x0) - 1) + [(0, None)],
        constraints=[{"type": "ineq", "fun": lambda x: x[-1] - at(x)[0],
                      "jac": lambda x: np.hstack([-at(x)[1], np.ones((len(front), 1))])}],
        options={"ftol": 1e-14, "maxiter": 200},
    )  # fmt: skip
    x = np.clip(result.x[:-1], 0, 1)
    radii_at, _ = at(np.append(x, 0.0))
    radius = float(radii_at.max())
    farthest = [f"{b}.{p}" for (b, p), r in zip(front, radii_at) if r >= radius - 1e-6]
    return FrontSwing(radius, dict(zip(evaluator.names, lows + spans * x)), evaluator.q.copy(), farthest)


def refine_from(system: NumericSystem, previous: Envelope) -> Envelope:
    """The working-range figures at the system's design values, each refined from its optimum in
    ``previous`` (computed at another, nearby design) instead of from a new grid: what a design
    study re-evaluates at every design. The result has no samples."""
    start = time.perf_counter()
    evaluator = RangeEvaluator(system, previous.spec)
    envelope = Envelope(previous.spec, evaluator.names, np.empty((0, len(evaluator.names))), np.empty((0, 3)), np.empty((0, 3)),
                        design=dict(system.design))  # fmt: skip
    index = evaluator.index
    _refine(envelope, evaluator, {name: (u[index], q) for name, (u, q) in previous.optima.items()})
    envelope.seconds = time.perf_counter() - start
    envelope.solves = evaluator.solves
    return envelope


def _grid_seeds(envelope: Envelope) -> dict[str, int]:
    """Per figure, the grid sample it is refined from."""
    points, pivots = envelope.points, envelope.pivots
    reach = np.hypot(points[:, 0], points[:, 1])
    z = points[:, 2]

    def argbest(values: np.ndarray) -> int:
        return int(np.nanargmax(values))

    seeds = {
        "max_reach": argbest(reach),
        "max_reach_at_ground": argbest(np.where(np.abs(z) < 0.3, reach, np.nan)),
        "max_depth": argbest(-z),
        "max_cutting_height": argbest(z),
    }
    if envelope.spec.dump_pivot is not None:
        offset = reach - np.hypot(pivots[:, 0], pivots[:, 1])
        hanging = (np.abs(offset) < 0.15) & (z < pivots[:, 2])
        seeds["max_dumping_height"] = argbest(np.where(hanging, z, np.nan))
    if envelope.spec.arm_pivot is not None:
        arm = envelope.arm_pivots
        vertical = (np.abs(np.hypot(arm[:, 0], arm[:, 1]) - np.hypot(pivots[:, 0], pivots[:, 1])) < 0.15) & (arm[:, 2] > pivots[:, 2])
        if vertical.any():
            seeds["max_vertical_wall_depth"] = argbest(np.where(vertical, -z, np.nan))
    return seeds


def _refine(envelope: Envelope, evaluator: RangeEvaluator, starts: dict[str, tuple[np.ndarray, np.ndarray]], bar: bool = False) -> None:
    """Each figure of ``starts`` (name -> (swept inputs, q solved there)) refined by SLSQP over the
    normalized inputs, every evaluation a solve by continuation."""
    lows = np.array([r[0] for r in evaluator.ranges])
    spans = np.array([r[1] - r[0] for r in evaluator.ranges])

    def full(x: np.ndarray) -> np.ndarray:
        return lows + spans * np.clip(x, 0, 1)

    solved: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def value(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tracked points at the normalized inputs x and their derivatives by x (solved once per x)."""
        key = np.asarray(x, dtype=float).tobytes()
        if key not in solved:
            solved.clear()
            evaluator.move_to(full(x))
            positions, by_input = evaluator.derivatives()
            solved[key] = positions, by_input * np.where((x >= 0) & (x <= 1), spans, 0.0)  # d/dx (zero outside: clipped)
        return solved[key]

    def chained(function, gradient):
        return lambda x: np.einsum("pi,pik->k", gradient(value(x)[0]), value(x)[1])

    from kinegen.progress import progress

    names = [f for f in FIGURES if f in starts]
    for name in progress(names, "working range: refining figures", unit="figure") if bar else names:
        figure = FIGURE_TABLE[name]
        inputs, q = starts[name]
        x0 = np.clip((inputs - lows) / spans, 0, 1)
        evaluator.q, evaluator.u = q.copy(), evaluator.inputs(inputs)  # where the start was solved
        solved.clear()
        constraints = []
        if figure.constraint:
            constraints = [{"type": "eq", "fun": lambda x, figure=figure: figure.constraint(value(x)[0]),
                            "jac": chained(figure.constraint, figure.constraint_gradient)}]  # fmt: skip
        result = minimize(
            lambda x, figure=figure: figure.objective(value(x)[0]),
            x0,
            jac=chained(figure.objective, figure.gradient),
            method="SLSQP",
            bounds=[(0, 1)] * len(x0),
            constraints=constraints,
            options={"ftol": 1e-14, "maxiter": 100},
        )
        x0 = _polish(figure, value, np.clip(result.x, 0, 1))
        best = value(x0)[0]
        envelope.figures[name] = -figure.objective(best)
        envelope.arguments[name] = dict(zip(envelope.names, full(x0)))
        envelope.optima[name] = (evaluator.u.copy(), evaluator.q.copy())


def _polish(figure: Figure, value: Callable, x: np.ndarray) -> np.ndarray:
    """SLSQP's optimum ``x`` (normalized inputs) made exact: Newton on the optimality conditions in
    the inputs not at a bound (F), ∇_F g + λ ∇_F h = 0 and h = 0 (without a constraint ∇_F g = 0),
    the gradients exact (``value(x)``: tracked points and their derivatives by x), their
    derivatives by differences of them. SLSQP may stop short of an equality constraint (by 1e-5 m
    where the constraint alone fixes the one free input); this takes it to rounding. A step that
    leaves the bounds or does not reduce the residual ends the polish, keeping the best x."""
    free = np.flatnonzero((x > 1e-9) & (x < 1 - 1e-9))
    if free.size == 0:
        return x

    def conditions(x: np.ndarray, multiplier: float) -> tuple[np.ndarray, np.ndarray, float]:
        positions, by_x = value(x)
        g = np.einsum("pi,pik->k", figure.gradient(positions), by_x)[free]
        if figure.constraint is None:
            return g, g, multiplier
        h = np.einsum("pi,pik->k", figure.constraint_gradient(positions), by_x)[free]
        if np.isnan(multiplier):
            multiplier = -float(h @ g) / float(h @ h) if h @ h > 0 else 0.0
        return np.append(g + multiplier * h, figure.constraint(positions)), h, multiplier

    residual, along, multiplier = conditions(x, np.nan)
    for _ in range(POLISH_STEPS):
        if np.max(np.abs(residual)) < 1e-14:
            break
        step_size = 1e-7
        hessian = np.empty((free.size, free.size))
        for j, k in enumerate(free):
            moved = x.copy()
            moved[k] += step_size if x[k] + step_size <= 1 else -step_size
            hessian[:, j] = (conditions(moved, multiplier)[0][: free.size] - residual[: free.size]) / (moved[k] - x[k])
        if figure.constraint is None:
            system, unknowns = hessian, free.size
        else:
            system = np.block([[hessian, along[:, None]], [along[None, :], np.zeros((1, 1))]])
            unknowns = free.size + 1
        try:
            delta = np.linalg.solve(system, -residual[:unknowns])
        except np.linalg.LinAlgError:
            break
        trial = x.copy()
        trial[free] += delta[: free.size]
        if np.any(trial < 0) or np.any(trial > 1):
            break
        trial_multiplier = multiplier + (delta[-1] if figure.constraint is not None else 0.0)
        trial_residual, trial_along, trial_multiplier = conditions(trial, trial_multiplier)
        if not np.max(np.abs(trial_residual)) < np.max(np.abs(residual)):
            break
        x, residual, along, multiplier = trial, trial_residual, trial_along, trial_multiplier
    return x


def figure_sensitivities(envelope: Envelope, system: NumericSystem) -> dict[str, np.ndarray]:
    """The exact derivative of every refined figure by the design parameters (n_design each), at
    the design the envelope was computed at (``system``: the same case at that design, from a
    module with sensitivity kernels), by the envelope theorem: with the figure's optimum u* over
    the swept inputs, the bounds active there A (which may move with p: a cylinder's retracted
    length) and an equality constraint h with multiplier λ (from the stationarity in the free
    inputs), df/dp = ∂g/∂p + Σ_A ∂g/∂u_j db_j/dp + λ (∂h/∂p + Σ_A ∂h/∂u_j db_j/dp), the partial
    derivatives those of the tracked points at fixed inputs and fixed p
    (:func:`kinegen.runtime.sensitivity.point_position_sensitivities`)."""
    from kinegen.runtime.sensitivity import point_position_sensitivities

    evaluator = RangeEvaluator(system, envelope.spec)
    lows, highs = (np.array([r[k] for r in evaluator.ranges]) for k in (0, 1))
    moving = _bound_derivatives(envelope.spec, evaluator.names, system.design)  # (n_swept, 2, n_design)
    out = {}
    for name, (u, q) in envelope.optima.items():
        figure = FIGURE_TABLE[name]
        positions, by_design, by_input = (x[0] for x in point_position_sensitivities(system, q[:, None], u[:, None], evaluator.tracked))
        swept = u[evaluator.index]
        tolerance = 1e-9 * (highs - lows)
        at_low, at_high = swept <= lows + tolerance, swept >= highs - tolerance
        bound_change = np.where(at_low[:, None], moving[:, 0], 0.0) + np.where(at_high[:, None], moving[:, 1], 0.0)
        free = ~(at_low | at_high)

        def total(gradient: np.ndarray, by_design=by_design, by_input=by_input, bound_change=bound_change) -> tuple[np.ndarray, np.ndarray]:
            """(d/dp with the active bounds moving, d/du of the swept inputs) of a function of the tracked points."""
            d_input = np.einsum("pi,pik->k", gradient, by_input)[evaluator.index]
            return np.einsum("pi,pik->k", gradient, by_design) + d_input @ bound_change, d_input

        d_objective, objective_inputs = total(figure.gradient(positions))
        if figure.constraint_gradient is not None:
            d_constraint, constraint_inputs = total(figure.constraint_gradient(positions))
            along = constraint_inputs[free]
            multiplier = -float(along @ objective_inputs[free]) / float(along @ along) if along @ along > 0 else 0.0
            d_objective = d_objective + multiplier * d_constraint
        out[name] = -d_objective
    return out


def _bound_derivatives(spec: WorkingRange, names: list[str], design: dict[str, float]) -> np.ndarray:
    """d(low, high)/dp of each swept input's range (exact expressions, at ``design``): (n_swept, 2, n_design)."""
    return np.array([[design_gradient(bound, list(design), design) for bound in spec.inputs[name]] for name in names]).reshape(
        len(names), 2, len(design)
    )
