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
  bucket hanging teeth down, as when dumping; a constrained maximum).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from kinegen.model.schema import WorkingRange
from kinegen.runtime import NumericSystem, Solver
from kinegen.runtime.batch import sweep_grid

STAGE = 0.065  # of an input's range, per continuation stage
FIGURES = ("max_reach", "max_reach_at_ground", "max_depth", "max_cutting_height", "max_dumping_height")


@dataclass
class Envelope:
    """Sampled working range and its refined figures."""

    spec: WorkingRange
    names: list[str]  # swept input names
    samples: np.ndarray  # (N, len(names)) input values
    points: np.ndarray  # (N, 3) global positions of the point (NaN where no solve)
    pivots: np.ndarray  # (N, 3) global positions of the dump pivot (NaN if none)
    figures: dict[str, float] = field(default_factory=dict)
    arguments: dict[str, dict[str, float]] = field(default_factory=dict)  # figure -> inputs
    seconds: float = 0.0
    solves: int = 0
    grid_seconds: float = 0.0  #: time of the batched grid sweep (continuation to its corner included)
    grid_solved: int = 0  #: grid configurations solved

    def table(self) -> str:
        """The figures beside the published (unverified) values."""
        lines = [f"{'figure':<22} {'kinegen [m]':>11} {'published [m]':>14}  at inputs"]
        for name in FIGURES:
            published = self.spec.published.get(name)
            ref = f"{published:>7.2f} (unverified)" if published is not None else f"{'-':>14}"
            where = ", ".join(f"{k} {v:.4f}" for k, v in self.arguments.get(name, {}).items())
            lines.append(f"{name:<22} {self.figures.get(name, float('nan')):>11.3f} {ref}  {where}")
        return "\n".join(lines)


class _Evaluator:
    """Point position for given swept inputs, by Newton continuation from the last solve."""

    def __init__(self, system: NumericSystem, spec: WorkingRange) -> None:
        self.system = system
        self.solver = Solver(system)
        self.spec = spec
        inputs = self.inputs_spec = spec.numbers(system.design)  # at the system's design values
        self.names = [n for n in system.driver_names if isinstance(inputs[n], tuple)]
        self.base = np.array([v if not isinstance(v, tuple) else 0.5 * (v[0] + v[1]) for v in (inputs[n] for n in system.driver_names)])
        self.index = [system.driver_names.index(n) for n in self.names]
        #: largest change of each input per Newton stage: continuation never jumps branches
        self.stage = np.array([STAGE * (inputs[n][1] - inputs[n][0]) for n in self.names])
        self.tracked = [(spec.point.body, spec.point.name)]
        if spec.dump_pivot is not None:
            self.tracked.append((spec.dump_pivot.body, spec.dump_pivot.name))
        self.q = system.initial_q.copy()
        self.u = system.driver_inputs(system.t0)[0].copy()
        self.solves = 0

    def inputs(self, values: np.ndarray) -> np.ndarray:
        u = self.base.copy()
        u[self.index] = values
        return u

    def points(self, q: np.ndarray) -> np.ndarray:
        """Global positions of the tracked point (and of the dump pivot): (1 or 2, 3) for
        q of shape (n,), (K, 1 or 2, 3) for a batch (n, K)."""
        batch = q.reshape(q.shape[0], -1)
        out = []
        for body, name in self.tracked:
            origin, rotation = self.system.parametrization.pose(self.system.body_coordinates(batch.T, body))  # (K, 3), (K, 3, 3)
            out.append(origin + rotation @ np.array(self.system.points[body][name]))
        points = np.stack(out, axis=1)
        return points[0] if q.ndim == 1 else points

    def move_to(self, values: np.ndarray) -> np.ndarray:
        """Solve at the swept ``values`` by continuation from the last solve; the tracked points."""
        target = self.inputs(values)
        steps = max(1, int(np.ceil(np.max(np.abs(target[self.index] - self.u[self.index]) / self.stage))))
        q = self.q
        for s in np.linspace(0, 1, steps + 1)[1:]:
            u = self.u + s * (target - self.u)
            q, _, _ = self.solver.position(q, u)
            self.solves += 1
        self.q, self.u = q, target
        return self.points(q)


def working_range(system: NumericSystem, spec: WorkingRange, grid: tuple[int, ...] | None = None) -> Envelope:
    """Sample and refine the working range of ``spec.point`` (see the module docstring)."""
    start = time.perf_counter()
    evaluator = _Evaluator(system, spec)
    names = evaluator.names
    counts = list(grid or [21, 11, 21][: len(names)] + [11] * max(0, len(names) - 3))
    ranges = [evaluator.inputs_spec[n] for n in names]
    axes = [np.linspace(lo, hi, c) for (lo, hi), c in zip(ranges, counts)]
    corner = np.array([a[0] for a in axes])
    evaluator.move_to(corner)  # continuation from the model's pose to the grid's first corner
    swept = [system.driver_names.index(n) for n in names]
    sweep = sweep_grid(system, evaluator.inputs(corner), swept, axes, evaluator.q)
    grid_seconds = time.perf_counter() - start
    index = np.indices(counts).reshape(len(counts), -1)
    samples = np.array([axes[d][index[d]] for d in range(len(counts))]).T
    q = sweep.q.reshape(system.n_stored, -1)
    ok = sweep.converged.ravel()
    tracked = np.full((len(samples), 2, 3), np.nan)
    found = evaluator.points(q[:, ok])
    tracked[ok, : found.shape[1]] = found
    envelope = Envelope(spec, names, samples, tracked[:, 0], tracked[:, 1])
    envelope.grid_seconds = grid_seconds
    envelope.grid_solved = int(ok.sum())
    _refine(envelope, evaluator, ranges, q)
    envelope.seconds = time.perf_counter() - start
    envelope.solves = evaluator.solves + int(ok.sum())
    return envelope


def _refine(envelope: Envelope, evaluator: _Evaluator, ranges: list[tuple[float, float]], grid_q: np.ndarray) -> None:
    samples, points, pivots = envelope.samples, envelope.points, envelope.pivots
    reach = np.hypot(points[:, 0], points[:, 1])
    z = points[:, 2]
    lows = np.array([r[0] for r in ranges])
    spans = np.array([r[1] - r[0] for r in ranges])

    def run(name: str, objective, seed: int, constraint=None) -> None:
        """Minimize objective(points) over the normalized inputs from sample ``seed``."""
        x0 = (samples[seed] - lows) / spans

        def full(x: np.ndarray) -> np.ndarray:
            return lows + spans * np.clip(x, 0, 1)

        evaluator.q, evaluator.u = grid_q[:, seed].copy(), evaluator.inputs(samples[seed])  # the grid's solution

        def value(x: np.ndarray) -> np.ndarray:
            return evaluator.move_to(full(x))

        constraints = [{"type": "eq", "fun": lambda x: constraint(value(x))}] if constraint else []
        result = minimize(
            lambda x: objective(value(x)),
            x0,
            method="SLSQP",
            bounds=[(0, 1)] * len(x0),
            constraints=constraints,
            options={"ftol": 1e-12, "maxiter": 100},
        )
        best = value(result.x)
        envelope.figures[name] = abs(objective(best))
        envelope.arguments[name] = dict(zip(envelope.names, full(result.x)))

    def argbest(values: np.ndarray) -> int:
        return int(np.nanargmax(values))

    def horizontal(p: np.ndarray) -> float:
        return -float(np.hypot(p[0, 0], p[0, 1]))

    run("max_reach", horizontal, argbest(reach))
    run("max_reach_at_ground", horizontal, argbest(np.where(np.abs(z) < 0.3, reach, np.nan)), constraint=lambda p: float(p[0, 2]))
    run("max_depth", lambda p: float(p[0, 2]), argbest(-z))
    run("max_cutting_height", lambda p: -float(p[0, 2]), argbest(z))
    if envelope.spec.dump_pivot is not None:
        offset = reach - np.hypot(pivots[:, 0], pivots[:, 1])
        hanging = (np.abs(offset) < 0.15) & (z < pivots[:, 2])
        run(
            "max_dumping_height",
            lambda p: -float(p[0, 2]),
            argbest(np.where(hanging, z, np.nan)),
            constraint=lambda p: float(np.hypot(p[0, 0], p[0, 1]) - np.hypot(p[1, 0], p[1, 1])),
        )


def plot_envelope(envelope: Envelope, path: str | Path) -> Path:
    """The sampled working range in the vertical plane (horizontal reach, height) with the figures."""
    from scipy import ndimage

    from kinegen.analysis.plots import pyplot, save

    plt = pyplot()
    ok = np.isfinite(envelope.points[:, 0])
    reach = np.hypot(envelope.points[ok, 0], envelope.points[ok, 1])
    z = envelope.points[ok, 2]
    cell = 0.1
    xbins = np.arange(reach.min() - 0.5, reach.max() + 0.5, cell)
    zbins = np.arange(z.min() - 0.5, z.max() + 0.5, cell)
    hist, _, _ = np.histogram2d(reach, z, bins=[xbins, zbins])
    occupied = np.pad(hist > 0, 8)
    region = ndimage.binary_fill_holes(ndimage.binary_closing(occupied, iterations=6))
    region = ndimage.gaussian_filter(region.astype(float), 1.2)[8:-8, 8:-8]
    fig, ax = plt.subplots(figsize=(9, 8))
    ax.scatter(reach, z, s=0.5, color="0.75", label=f"{len(reach)} solved configurations")
    ax.contour(0.5 * (xbins[1:] + xbins[:-1]), 0.5 * (zbins[1:] + zbins[:-1]), region.T, levels=[0.5], colors="tab:blue")
    ax.axhline(0, color="saddlebrown", lw=1)
    figures = envelope.figures
    marks = {
        "max_reach": None,
        "max_reach_at_ground": (figures.get("max_reach_at_ground"), 0.0),
        "max_depth": None,
        "max_cutting_height": None,
        "max_dumping_height": None,
    }
    for name in marks:
        if name in figures:
            ax.annotate(
                f"{name.replace('_', ' ')} {figures[name]:.2f} m",
                xy=(0.02, 0.97 - 0.04 * list(marks).index(name)),
                xycoords="axes fraction",
                fontsize=9,
                va="top",
            )
    if "max_reach_at_ground" in figures:
        ax.plot([figures["max_reach_at_ground"]], [0], "r^")
    ax.set(
        title=f"working range of {envelope.spec.point.body}.{envelope.spec.point.name}",
        xlabel="horizontal distance from the swing axis [m]",
        ylabel="height above ground [m]",
        aspect="equal",
    )
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    return save(fig, path)
