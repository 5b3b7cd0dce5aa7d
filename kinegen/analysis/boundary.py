"""The exact boundary of a working range in its chart plane, by continuation along its curves.

The chart plane of a working range is (horizontal distance of the tracked point from the swing
axis = the global z axis, height z), in m. The swept inputs u (the ``working_range`` section's
[min, max] inputs, a box) map to that plane, c(u) = (hypot(x, y), z). A boundary point of the
image of the box is the image of a point where the inputs not at a limit cannot move c in every
direction: on a face of the box where the free inputs F are the ones not at a limit, the 2 x |F|
Jacobian dc/du_F has rank below 2 (Lagrange's condition). So the boundary is made of

* **edge curves**: all but one input at a limit (|F| = 1), e.g. the arc the tip draws with the
  boom and arm cylinders at their ends while the bucket cylinder strokes;
* **fold curves**: all but two inputs at a limit and det(dc/du_F) = 0 (|F| = 2), e.g. the
  bucket's tip in line with its pivot as seen from the arm's (the maximum reach);

(and, with more than three swept inputs, rank-deficient curves of faces of three or more free
inputs, which are not traced here: :func:`working_range_boundary` says so when it finds such a
face close to rank-deficient). Every curve is computed as exact solves: an edge by a batched
continuation along its free input; a fold by the zero contour of det(dc/du_F) over a grid of its
face (``contourpy``), each contour vertex then moved onto det = 0 by a bracketed root search
along its grid edge (every evaluation a Newton solve and exact sensitivities), a fold ending on a
box edge inserted into that edge. The outer boundary of all the curves is found by noding them
and polygonizing (``shapely``); where it switches from one curve to another at a crossing, the
switching point is found by Newton on "the two curves meet" in their free inputs (det = 0 kept on
a fold), not by interpolation. The drawn boundary is the polyline through these exact points;
:attr:`Boundary.chord_error` measures how far it strays from the curves between them.

Inputs that do not move the chart point (a swing) are held at their lower limit.
"""

from __future__ import annotations

import csv
import io
import itertools
import time
from dataclasses import dataclass, field

import numpy as np

from kinegen.errors import KinegenError
from kinegen.runtime import NumericSystem
from kinegen.runtime.batch import solve_batch, sweep_grid
from kinegen.runtime.continuation import RangeEvaluator

#: samples per free input of a face's det grid (the fold curves' vertices lie on its lines)
FACE_GRID = 61
#: samples along an edge curve
EDGE_SAMPLES = 101
#: largest distance (m) between neighbouring points of a curve in the chart (chord error ~ spacing^2 / 8 R)
SPACING = 0.02
#: Newton tolerance of the boundary's solves (max |Phi|), as the envelope's refinement
TOLERANCE = 1e-13


@dataclass
class Curve:
    """One candidate curve: exact solves along it, in order."""

    label: str  #: which inputs are at which limit, e.g. "boom_length max, arm_length min"
    kind: str  #: "edge" or "fold"
    free: tuple[int, ...]  #: indices (in the swept inputs) of the inputs not at a limit
    inputs: np.ndarray  #: (M, d) swept inputs
    points: np.ndarray  #: (M, 2) chart coordinates (reach, height), m
    q: np.ndarray  #: (M, n) stored coordinates


@dataclass
class Boundary:
    """The outer boundary of a working range: a closed polyline (counter-clockwise) through exact
    points of its curves, first point repeated last."""

    names: list[str]  #: swept input names
    points: np.ndarray  #: (N, 2) (reach, height), m
    inputs: np.ndarray  #: (N, d) swept inputs at each point
    curve: np.ndarray  #: (N,) index into ``curves`` of the curve from each point to the next
    switching: np.ndarray  #: indices of the points where the boundary changes curve
    refined: int  #: switching points found by Newton on two curves (the others are curve ends)
    unrefined: int  #: crossings left where noding put them (Newton did not converge; see ``chord_error``)
    curves: list[Curve]  #: every candidate curve traced (edges and folds)
    direction: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0]))  #: horizontal unit vector of the reach axis
    chord_error: float = float("nan")  #: largest distance of the exact curve from the polyline between two points, m
    seconds: float = 0.0
    solves: int = 0
    notes: list[str] = field(default_factory=list)

    def on_boundary(self, reach: float, height: float) -> float:
        """Distance (m) of the chart point (reach, height) from the drawn boundary."""
        from shapely import LineString, Point

        return float(LineString(self.points).distance(Point(reach, height)))

    def contains(self, reach: np.ndarray, height: np.ndarray) -> np.ndarray:
        """Signed distance of chart points from the boundary, negative inside (m)."""
        from shapely import LineString, Polygon, points

        ring, region = LineString(self.points), Polygon(self.points)
        cloud = points(np.column_stack([reach, height]))
        distance = ring.distance(cloud)
        return np.where(region.contains(cloud), -distance, distance)

    def rows(self) -> list[dict[str, object]]:
        """The boundary as records: reach, height, the curve it lies on, switching or not, the inputs."""
        out = []
        switching = set(self.switching.tolist())
        for k, (point, inputs, curve) in enumerate(zip(self.points, self.inputs, self.curve)):
            row: dict[str, object] = {"reach_m": float(point[0]), "height_m": float(point[1]), "curve": self.curves[curve].label,
                                      "kind": self.curves[curve].kind, "switching": k in switching}  # fmt: skip
            row.update({name: float(v) for name, v in zip(self.names, inputs)})
            out.append(row)
        return out

    def document(self) -> dict:
        """The boundary as JSON data (``kinegen envelope --json``, ``--boundary *.json``): the chart
        plane (reach along ``direction``, height; m), :meth:`rows`, the switching points' indices,
        the chord error [m] and the notes."""
        return {
            "plane": {"reach_direction": self.direction.tolist(), "units": "m"},
            "points": self.rows(),
            "switching": self.switching.tolist(),
            "chord_error_m": self.chord_error,
            "notes": self.notes,
        }

    def to_csv(self) -> str:
        """:meth:`rows` as CSV text (header first)."""
        rows = self.rows()
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
        return buffer.getvalue()


class _Chart:
    """Solves and chart coordinates (with their exact derivatives by the swept inputs) of one system."""

    def __init__(self, system: NumericSystem, evaluator) -> None:
        from kinegen.runtime import Solver, SolverOptions

        self.system, self.evaluator = system, evaluator
        self.solver = Solver(system, SolverOptions(tolerance=TOLERANCE))
        self.solves = 0
        self.direction = np.array([1.0, 0.0])  #: horizontal unit vector of the chart's reach axis

    def inputs(self, swept: np.ndarray) -> np.ndarray:
        """Every driver input (n_inputs, K) for swept inputs (K, d)."""
        u = np.repeat(self.evaluator.base[:, None], len(swept), axis=1)
        u[self.evaluator.index] = swept.T
        return u

    def solve(self, swept: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Batched Newton at swept inputs (K, d) from q0 (n, K): (q, converged)."""
        done = solve_batch(self.system, self.inputs(swept), q0, TOLERANCE)
        self.solves += len(swept)
        return done.q, done.converged

    def chart(self, swept: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Chart points (K, 2) and d(chart)/d(swept) (K, 2, d) at solved q (n, K)."""
        from kinegen.runtime.sensitivity import point_position_sensitivities

        u = self.inputs(swept)
        spec = self.evaluator.tracked[:1]
        positions, _, by_input = point_position_sensitivities(self.system, q, u, spec, design=False)
        p, dp = positions[:, 0], by_input[:, 0][:, :, self.evaluator.index]  # (K, 3), (K, 3, d)
        e = self.direction
        return np.column_stack([p[:, :2] @ e, p[:, 2]]), np.stack([np.einsum("kid,i->kd", dp[:, :2], e), dp[:, 2]], axis=1)


def working_range_boundary(
    system: NumericSystem, spec, face_grid: int = FACE_GRID, edge_samples: int = EDGE_SAMPLES, spacing: float = SPACING
) -> Boundary:
    """The exact outer boundary of ``spec``'s working range (see the module docstring) at the
    system's design values (``system``: the spec's forward case)."""
    start = time.perf_counter()
    evaluator = RangeEvaluator(system, spec)
    chart = _Chart(system, evaluator)
    names = evaluator.names
    lows = np.array([r[0] for r in evaluator.ranges])
    highs = np.array([r[1] for r in evaluator.ranges])
    notes: list[str] = []
    # inputs that do not move the chart point are held at their lower limit
    centre = 0.5 * (lows + highs)
    evaluator.move_to(centre)
    tip = evaluator.points(evaluator.q)[0]
    if np.hypot(tip[0], tip[1]) > 1e-9:
        chart.direction = tip[:2] / np.hypot(tip[0], tip[1])
    _, jac = chart.chart(centre[None], evaluator.q[:, None])
    scale = np.abs(jac[0]).max()
    active = [k for k in range(len(names)) if np.abs(jac[0][:, k]).max() > 1e-9 * scale]
    for k in set(range(len(names))) - set(active):
        highs[k] = lows[k]
        notes.append(f"{names[k]} does not move the point in the chart plane: held at {lows[k]:g}")
    if len(active) < 2:
        raise KinegenError(f"{system.model}: fewer than two swept inputs move {spec.point.body}.{spec.point.name} in the chart plane")
    corners = _corners(evaluator, lows, highs, active)
    edges = _edges(chart, corners, lows, highs, active, names, edge_samples)
    folds = []
    for free in itertools.combinations(active, 2):
        others = [k for k in active if k not in free]
        for limits in itertools.product((0, 1), repeat=len(others)):
            folds += _folds(chart, corners, edges, lows, highs, free, dict(zip(others, limits)), names, face_grid)
    if len(active) > 2:
        _check_interior(chart, corners, lows, highs, active, notes)
    curves = [e for e in edges.values()] + folds
    used = sorted(set(_outer(chart, curves, names, [], refine=False).curve.tolist()))  # the curves the boundary is made of
    for k in used:
        _densify(chart, curves[k], spacing)
    boundary = _outer(chart, curves, names, notes)
    boundary.direction = chart.direction
    boundary.chord_error = _chord_error(chart, [curves[k] for k in sorted(set(boundary.curve.tolist()))])
    boundary.seconds = time.perf_counter() - start
    boundary.solves = chart.solves + evaluator.solves
    return boundary


def _label(names: list[str], fixed: dict[int, int]) -> str:
    return ", ".join(f"{names[k]} {'max' if side else 'min'}" for k, side in sorted(fixed.items()))


def _corners(evaluator, lows: np.ndarray, highs: np.ndarray, active: list[int]) -> dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]]:
    """Every corner of the box (the active inputs at (0: low, 1: high)), solved by continuation
    from the model's pose: corner -> (swept inputs, q)."""
    out = {}
    for sides in itertools.product((0, 1), repeat=len(active)):
        values = lows.copy()
        for k, side in zip(active, sides):
            values[k] = highs[k] if side else lows[k]
        evaluator.move_to(values)
        out[sides] = (values, evaluator.q.copy())
    return out


def _edges(chart: _Chart, corners, lows, highs, active, names, samples) -> dict[tuple[int, tuple[int, ...]], Curve]:
    """Every edge curve, keyed by (free input, the others' sides in ``active`` order without it)."""
    out = {}
    for free in active:
        others = [k for k in active if k != free]
        for sides in itertools.product((0, 1), repeat=len(others)):
            fixed = dict(zip(others, sides))
            first = tuple(fixed.get(k, 0) for k in active)
            last = tuple(fixed.get(k, 1) for k in active)
            inputs0, q0 = corners[first]
            axis = np.linspace(lows[free], highs[free], samples)
            swept = [chart.system.driver_names.index(chart.evaluator.names[free])]
            result = sweep_grid(chart.system, chart.inputs(inputs0[None])[:, 0], swept, [axis], q0, TOLERANCE)
            chart.solves += samples
            if not result.converged.all():
                raise KinegenError(f"{chart.system.model}: the edge '{_label(names, fixed)}' did not solve at "
                                   f"{names[free]} = {axis[~result.converged][0]:.6g}")  # fmt: skip
            inputs = np.repeat(inputs0[None], samples, axis=0)
            inputs[:, free] = axis
            q = result.q.reshape(len(q0), samples)
            q[:, -1] = corners[last][1]  # the shared corner: bit-identical in every curve that ends there
            points, _ = chart.chart(inputs, q)
            out[free, sides] = Curve(_label(names, fixed), "edge", (free,), inputs, points, q.T.copy())
    return out


def _det(chart: _Chart, swept: np.ndarray, q: np.ndarray, free: tuple[int, int]) -> np.ndarray:
    _, jac = chart.chart(swept, q)
    a, b = jac[:, :, free[0]], jac[:, :, free[1]]
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def _folds(chart: _Chart, corners, edges, lows, highs, free: tuple[int, int], fixed: dict[int, int], names, count: int) -> list[Curve]:
    """The fold curves of one face (inputs ``free`` not at a limit, ``fixed`` at theirs)."""
    import contourpy

    active = sorted([*free, *fixed])
    corner = tuple(fixed.get(k, 0) for k in active)
    inputs0, q0 = corners[corner]
    axes = [np.linspace(lows[k], highs[k], count) for k in free]
    swept = [chart.system.driver_names.index(chart.evaluator.names[k]) for k in free]
    grid = sweep_grid(chart.system, chart.inputs(inputs0[None])[:, 0], swept, axes, q0, TOLERANCE)
    chart.solves += count * count
    mesh = np.meshgrid(*axes, indexing="ij")
    inputs = np.repeat(inputs0[None], count * count, axis=0)
    inputs[:, free[0]], inputs[:, free[1]] = mesh[0].ravel(), mesh[1].ravel()
    q = grid.q.reshape(-1, count * count)
    ok = grid.converged.ravel()
    if not ok.all():
        raise KinegenError(f"{chart.system.model}: the face '{_label(names, fixed)}' did not solve everywhere on a {count} x {count} grid")
    det = _det(chart, inputs, q, free).reshape(count, count)
    lines = contourpy.contour_generator(x=axes[1], y=axes[0], z=det, line_type="Separate").lines(0.0)
    out = []
    for number, line in enumerate(lines):
        vertices = np.asarray(line)[:, ::-1]  # (u_free0, u_free1)
        exact_inputs, exact_q = _onto_fold(chart, vertices, axes, q.reshape(-1, count, count), inputs0, free)
        points, _ = chart.chart(exact_inputs, exact_q.T)
        label = f"fold of {names[free[0]]} x {names[free[1]]}" + (f" ({_label(names, fixed)})" if fixed else "")
        curve = Curve(label + (f" #{number + 1}" if len(lines) > 1 else ""), "fold", free, exact_inputs, points, exact_q)
        for end in (0, -1):  # a fold ending on a box edge: that point is also the edge's
            _insert_into_edge(edges, curve, end, lows, highs, active)
        out.append(curve)
    return out


def _onto_fold(chart: _Chart, vertices: np.ndarray, axes: list[np.ndarray], q_grid: np.ndarray, inputs0: np.ndarray,
               free: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Contour vertices (M, 2) of det = 0, each on a grid edge of the face, moved onto det = 0
    along that edge (:func:`_roots`). Returns the swept inputs (M, d) and q (M, n)."""
    m = len(vertices)
    ends = np.empty((m, 2, 2))  # the grid edge's two nodes, in the face's free inputs
    nodes = np.empty((m, 2, 2), dtype=int)  # their grid indices
    for k, (a, b) in enumerate(vertices):
        ia, ib = int(np.argmin(np.abs(axes[0] - a))), int(np.argmin(np.abs(axes[1] - b)))
        off_a = abs(axes[0][ia] - a) / (axes[0][1] - axes[0][0])
        off_b = abs(axes[1][ib] - b) / (axes[1][1] - axes[1][0])
        if off_a <= off_b:  # on a grid line of the first input: the second varies along the edge
            ib = int(np.clip(np.searchsorted(axes[1], b) - 1, 0, len(axes[1]) - 2))
            nodes[k] = [[ia, ib], [ia, ib + 1]]
        else:
            ia = int(np.clip(np.searchsorted(axes[0], a) - 1, 0, len(axes[0]) - 2))
            nodes[k] = [[ia, ib], [ia + 1, ib]]
        ends[k] = [[axes[0][i], axes[1][j]] for i, j in nodes[k]]
    q_ends = [q_grid[:, nodes[:, j, 0], nodes[:, j, 1]] for j in (0, 1)]  # (n, M) each
    inputs, q = _roots(chart, ends, q_ends, inputs0, free)
    if not np.isfinite(inputs).all():
        raise KinegenError(f"{chart.system.model}: a point of a fold curve did not solve")
    return inputs, q


def _roots(chart: _Chart, ends: np.ndarray, q_ends: list[np.ndarray], inputs0: np.ndarray, free: tuple[int, int]
           ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """det(dc/du_free) = 0 on each segment ends[k, 0] -> ends[k, 1] (face inputs, (M, 2, 2), a sign
    change between them), started from q_ends (two (n, M)): Illinois regula falsi in the segment's
    fraction, batched, every evaluation a solve and exact sensitivities. The other inputs stay at
    ``inputs0``. Returns the swept inputs (M, d) and q (M, n)."""
    m = len(ends)
    everything = np.arange(m)

    def at(which: np.ndarray, fraction: np.ndarray, q_start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        swept = np.repeat(inputs0[None], len(which), axis=0)
        face = ends[which, 0] + fraction[:, None] * (ends[which, 1] - ends[which, 0])
        swept[:, free[0]], swept[:, free[1]] = face[:, 0], face[:, 1]
        q, converged = chart.solve(swept, chart.system.project(q_start))
        return swept, q, np.where(converged, _det(chart, swept, q, free), np.nan)

    low, high = np.zeros(m), np.ones(m)
    swept_low, q_low, f_low = at(everything, low, q_ends[0])
    swept_high, q_high, f_high = at(everything, high, q_ends[1])
    scale = np.nanmax(np.abs(np.concatenate([f_low, f_high])))
    # the answer so far: the end with the smaller |det|
    nearer = np.abs(f_low) <= np.abs(f_high)
    swept, q, f = np.where(nearer[:, None], swept_low, swept_high), np.where(nearer, q_low, q_high), np.where(nearer, f_low, f_high)
    active = np.flatnonzero((np.sign(f_low) * np.sign(f_high) < 0) & (np.abs(f) > 1e-14 * scale))
    side = np.zeros(m, dtype=int)
    for _ in range(60):
        if not len(active):
            break
        a = active
        x = np.where(f_high[a] != f_low[a], (low[a] * f_high[a] - high[a] * f_low[a]) / (f_high[a] - f_low[a]), 0.5 * (low[a] + high[a]))
        x = np.where((x > low[a]) & (x < high[a]), x, 0.5 * (low[a] + high[a]))
        start = np.where(np.abs(x - low[a]) < np.abs(x - high[a]), q_low[:, a], q_high[:, a])
        swept[a], q[:, a], f[a] = at(a, x, start)
        left = np.sign(f[a]) == np.sign(f_low[a])
        # Illinois: the value kept at the end that stays twice on the same side is halved
        f_high[a] = np.where(left, np.where(side[a] == 1, 0.5 * f_high[a], f_high[a]), f[a])
        f_low[a] = np.where(left, f[a], np.where(side[a] == -1, 0.5 * f_low[a], f_low[a]))
        low[a], q_low[:, a] = np.where(left, x, low[a]), np.where(left, q[:, a], q_low[:, a])
        high[a], q_high[:, a] = np.where(left, high[a], x), np.where(left, q_high[:, a], q[:, a])
        side[a] = np.where(left, 1, -1)
        active = a[np.isfinite(f[a]) & (np.abs(f[a]) > 1e-14 * scale) & (high[a] - low[a] > 1e-14)]
    found = np.isfinite(f) & (np.sign(f_low) * np.sign(f_high) <= 0)  # no sign change: no root
    return np.where(found[:, None], swept, np.nan), q.T.copy()


def _midpoints(chart: _Chart, curve: Curve, gaps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exact points of ``curve`` between its points ``gaps`` and ``gaps + 1``: an edge's at the
    middle of its free input; a fold's where det = 0 on the segment through the middle of the two
    (face inputs, normalized) across the line joining them. Returns the gaps where one was found,
    their inputs (G, d), q (n, G) and chart points (G, 2)."""
    a, b = curve.inputs[gaps], curve.inputs[gaps + 1]
    q_start = 0.5 * (curve.q[gaps] + curve.q[gaps + 1]).T
    if curve.kind == "edge":
        inputs = 0.5 * (a + b)
        q, converged = chart.solve(inputs, chart.system.project(q_start))
        if not converged.all():
            raise KinegenError(f"{chart.system.model}: a point of the edge '{curve.label}' did not solve")
    else:
        free = list(curve.free)
        span = np.array([chart.evaluator.ranges[k][1] - chart.evaluator.ranges[k][0] for k in free])
        middle, chord = 0.5 * (a + b)[:, free] / span, (b - a)[:, free] / span
        across = np.column_stack([-chord[:, 1], chord[:, 0]])
        ends = np.stack([middle - across, middle + across], axis=1) * span
        inputs, q_t = _roots(chart, ends, [q_start, q_start], a[0], curve.free)
        found = np.isfinite(inputs).all(axis=1)
        gaps, inputs, q = gaps[found], inputs[found], q_t[found].T
    points, _ = chart.chart(inputs, q) if len(gaps) else (np.empty((0, 2)), None)
    return gaps, inputs, q, points


def _densify(chart: _Chart, curve: Curve, spacing: float) -> None:
    """Exact points (:func:`_midpoints`) added between neighbours of ``curve`` farther apart than
    ``spacing`` (m) in the chart, until none is."""
    for _ in range(10):
        gaps = np.flatnonzero(np.linalg.norm(np.diff(curve.points, axis=0), axis=1) > spacing)
        if not len(gaps):
            return
        gaps, inputs, q, points = _midpoints(chart, curve, gaps)
        if not len(gaps):
            return
        order = np.argsort(np.concatenate([np.arange(len(curve.points)), gaps + 0.5]), kind="stable")
        curve.inputs = np.concatenate([curve.inputs, inputs])[order]
        curve.points = np.concatenate([curve.points, points])[order]
        curve.q = np.concatenate([curve.q, q.T])[order]


def _chord_error(chart: _Chart, curves: list[Curve]) -> float:
    """Largest distance (m) of a curve's exact middle point (:func:`_midpoints`) from the chord
    between its neighbours, over every pair of neighbours of ``curves``."""
    worst = 0.0
    for curve in curves:
        gaps, _, _, points = _midpoints(chart, curve, np.arange(len(curve.points) - 1))
        _, distance = _project(curve.points[gaps], curve.points[gaps + 1], points)
        worst = max(worst, float(distance.max(initial=0.0)))
    return worst


def _project(a: np.ndarray, b: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each ``points[i]`` projected onto the segment ``a[i]``-``b[i]`` (rows broadcast: one point
    onto many segments works too): the fraction along the segment in [0, 1], the distance (m)."""
    ab = b - a
    fraction = np.clip(np.einsum("ij,ij->i", points - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0, 1)
    return fraction, np.linalg.norm(a + fraction[:, None] * ab - points, axis=1)


def _insert_into_edge(edges, curve: Curve, end: int, lows, highs, active) -> None:
    """If the fold ``curve`` ends (``end`` 0 or -1) on a box edge, put that exact point into the
    edge curve (in order of its free input) and give the fold the edge's coordinates there."""
    inputs = curve.inputs[end]
    span = highs - lows
    at_low = np.abs(inputs - lows) <= 1e-12 * span
    at_high = np.abs(inputs - highs) <= 1e-12 * span
    free = [k for k in active if not (at_low[k] or at_high[k])]
    if len(free) != 1:
        return
    others = [k for k in active if k != free[0]]
    edge = edges[free[0], tuple(int(at_high[k]) for k in others)]
    value = inputs[free[0]]
    position = int(np.searchsorted(edge.inputs[:, free[0]], value))
    edge.inputs = np.insert(edge.inputs, position, inputs, axis=0)
    edge.points = np.insert(edge.points, position, curve.points[end], axis=0)
    edge.q = np.insert(edge.q, position, curve.q[end], axis=0)


def _check_interior(chart: _Chart, corners, lows, highs, active, notes: list[str]) -> None:
    """Faces of three or more free inputs are not traced: say so if the chart Jacobian comes
    close to rank 1 on a coarse interior grid (smallest/largest singular value below 1e-3)."""
    axes = [np.linspace(lows[k], highs[k], 9)[1:-1] for k in active]
    inputs0, q0 = corners[tuple(0 for _ in active)]
    swept = [chart.system.driver_names.index(chart.evaluator.names[k]) for k in active]
    grid = sweep_grid(chart.system, chart.inputs(inputs0[None])[:, 0], swept, axes, chart.evaluator.q, TOLERANCE)
    ok = grid.converged.ravel()
    mesh = np.meshgrid(*axes, indexing="ij")
    inputs = np.repeat(inputs0[None], ok.size, axis=0)
    for j, k in enumerate(active):
        inputs[:, k] = mesh[j].ravel()
    _, jac = chart.chart(inputs[ok], grid.q.reshape(len(q0), -1)[:, ok])
    chart.solves += int(ok.sum())
    sigma = np.linalg.svd(jac[:, :, active], compute_uv=False)
    ratio = float((sigma[:, -1] / sigma[:, 0]).min())
    if ratio < 1e-3:
        notes.append(f"inside the box the chart Jacobian comes close to rank 1 (smallest singular value ratio {ratio:.1e}): "
                     "curves of that kind are not traced, the boundary may miss some")  # fmt: skip


def _outer(chart: _Chart, curves: list[Curve], names: list[str], notes: list[str], refine: bool = True) -> Boundary:
    """The outer boundary of the curves' union: noded and polygonized (shapely), each crossing
    where it changes curve refined by Newton."""
    import shapely
    from shapely.geometry.polygon import orient

    lines = [shapely.LineString(c.points) for c in curves]
    noded = shapely.unary_union(shapely.MultiLineString([np.asarray(line.coords) for line in lines]))
    polygons = list(shapely.get_parts(shapely.polygonize(shapely.get_parts(noded))))
    if not polygons:
        raise KinegenError(f"{chart.system.model}: the working range's curves enclose no region")
    region = shapely.unary_union(polygons)
    if region.geom_type == "MultiPolygon":
        parts = sorted(shapely.get_parts(region), key=lambda p: -p.area)
        notes.append(f"the curves enclose {len(parts)} separate regions: the largest is drawn")
        region = parts[0]
    region = orient(region, 1.0)
    if region.interiors:
        notes.append(f"the working range has {len(region.interiors)} hole(s): only its outer boundary is drawn")
    ring = np.asarray(region.exterior.coords)[:-1]
    # the curve of each segment: the one nearest its midpoint
    middles = shapely.points(0.5 * (ring + np.roll(ring, -1, axis=0)))
    distances = np.array([line.distance(middles) for line in lines])  # (curves, N)
    segment_curve = distances.argmin(axis=0)
    # every ring vertex: an exact curve vertex, or a crossing to refine
    from scipy.spatial import cKDTree

    owners = np.concatenate([np.full(len(c.points), i) for i, c in enumerate(curves)])
    indices = np.concatenate([np.arange(len(c.points)) for c in curves])
    tree = cKDTree(np.concatenate([c.points for c in curves]))
    gap, nearest = tree.query(ring)
    n = len(ring)
    points, inputs = ring.copy(), np.empty((n, len(names)))
    switching, refined, unrefined = [], 0, 0
    for k in range(n):
        before, after = segment_curve[k - 1], segment_curve[k]
        if before != after:
            switching.append(k)
        if gap[k] <= 1e-9:
            curve = curves[owners[nearest[k]]]
            inputs[k] = curve.inputs[indices[nearest[k]]]
            continue
        if before == after:  # a crossing the curve passes (another curve touching it): on the curve, interpolated
            curve = curves[after]
            inputs[k] = _interpolate(curve, ring[k])[0]
            continue
        found = _crossing(chart, curves[before], curves[after], ring[k]) if refine else None
        if found is None:
            unrefined += 1
            inputs[k] = _interpolate(curves[after], ring[k])[0]
        else:
            refined += 1
            points[k], inputs[k] = found
    closed = np.vstack([points, points[:1]])
    return Boundary(names, closed, np.vstack([inputs, inputs[:1]]), np.append(segment_curve, segment_curve[0]), np.array(switching, dtype=int),
                    refined, unrefined, curves, notes=notes)  # fmt: skip


def _interpolate(curve: Curve, point: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, float]:
    """The curve's segment nearest ``point``: (inputs, q) interpolated there, the segment index, the fraction."""
    fraction, distance = _project(curve.points[:-1], curve.points[1:], point)
    j = int(distance.argmin())
    s = float(fraction[j])
    return (1 - s) * curve.inputs[j] + s * curve.inputs[j + 1], (1 - s) * curve.q[j] + s * curve.q[j + 1], j, s


def _crossing(chart: _Chart, first: Curve, second: Curve, guess: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Where ``first`` and ``second`` meet near ``guess``: Newton in both curves' free inputs on
    c(u_1) = c(u_2) (and det = 0 on a fold), exact chart derivatives, det's by differences.
    (chart point, inputs) or None when it does not converge to 1e-12 m."""
    starts = [_interpolate(curve, guess) for curve in (first, second)]
    x = [s[0].copy() for s in starts]
    qs = [chart.system.project(s[1][:, None])[:, 0] for s in starts]  # interpolated: back onto unit quaternions

    def evaluate(k: int, inputs: np.ndarray, q_start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
        q, converged = chart.solve(inputs[None], q_start[:, None])
        if not converged[0]:
            raise KinegenError("no solve")
        point, jac = chart.chart(inputs[None], q)
        curve = (first, second)[k]
        det = 0.0
        grad = np.zeros(len(curve.free))
        if curve.kind == "fold":
            det = float(_det(chart, inputs[None], q, curve.free)[0])
            for j, index in enumerate(curve.free):
                step = 1e-7 * (chart.evaluator.ranges[index][1] - chart.evaluator.ranges[index][0])
                moved = inputs.copy()
                moved[index] += step
                q_moved, ok = chart.solve(moved[None], q)
                grad[j] = (float(_det(chart, moved[None], q_moved, curve.free)[0]) - det) / step if ok[0] else np.nan
        return q[:, 0], point[0], jac[0][:, list(curve.free)], det, grad

    try:
        for _ in range(25):
            parts = [evaluate(k, x[k], qs[k]) for k in (0, 1)]
            qs = [parts[0][0], parts[1][0]]
            residual = [parts[0][1] - parts[1][1]]
            rows = [np.hstack([parts[0][2], -parts[1][2]])]
            sizes = [len(first.free), len(second.free)]
            for k in (0, 1):
                if (first, second)[k].kind == "fold":
                    residual.append(np.array([parts[k][3]]))
                    row = np.zeros(sum(sizes))
                    offset = 0 if k == 0 else sizes[0]
                    row[offset : offset + sizes[k]] = parts[k][4]
                    rows.append(row[None])
            r = np.concatenate(residual)
            if np.max(np.abs(r[:2])) < 1e-12 and (len(r) == 2 or np.max(np.abs(r[2:])) < 1e-12 * max(1.0, np.abs(parts[0][2]).max() ** 2)):
                point = parts[0][1]
                if np.linalg.norm(point - guess) > 0.05:  # converged to another crossing
                    return None
                return point, x[1]
            step = np.linalg.solve(np.vstack(rows), -r)
            x[0][list(first.free)] += step[: sizes[0]]
            x[1][list(second.free)] += step[sizes[0] :]
            for k, curve in enumerate((first, second)):
                lo = np.array([chart.evaluator.ranges[i][0] for i in curve.free])
                hi = np.array([chart.evaluator.ranges[i][1] for i in curve.free])
                if np.any(x[k][list(curve.free)] < lo - 1e-12) or np.any(x[k][list(curve.free)] > hi + 1e-12):
                    return None
    except (KinegenError, np.linalg.LinAlgError):
        return None
    return None
