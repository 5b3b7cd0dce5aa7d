"""Force maps over the working range: at every pose of a grid over the working range's swept inputs
(the compiled batch sweep of :mod:`kinegen.runtime.batch`), the largest force the tool point can
exert in one direction, and the cylinder that limits it.

The direction is fixed in the boom plane -- ``pull`` (horizontal, toward the machine), ``push``
(away from it), ``up``, ``down`` -- or ``tangent``: along the lip's motion when the bucket curls
(its cylinder extends), the bucket digging direction. The tool exerts F along it, so the machine
holds the load -F; per newton of F every cylinder's force comes from one solve Φ_qᵀ λ = Q, and F is
the smallest of the loads at which a cylinder reaches its relief setting (kinegen's choice for a
map: every circuit can be commanded, the pump's relief setting bounds each). Where several poses
put the tool point in one cell of the chart, the cell holds the largest force among them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinegen.analysis.evaluator import RangeEvaluator
from kinegen.errors import KinegenError
from kinegen.forces.statics import Statics, pose_results, unit_rate_velocities
from kinegen.model import Model
from kinegen.runtime import NumericSystem
from kinegen.runtime.batch import sweep_grid

#: global directions of the fixed maps (the boom plane at zero swing is x-z)
DIRECTIONS = {"pull": (-1.0, 0.0, 0.0), "push": (1.0, 0.0, 0.0), "up": (0.0, 0.0, 1.0), "down": (0.0, 0.0, -1.0), "tangent": None}
#: what each map shows, in words
MEANING = {
    "pull": "horizontally toward the machine", "push": "horizontally away from the machine", "up": "vertically up",
    "down": "vertically down", "tangent": "along the lip's path as the bucket curls (the bucket digging direction)",
}  # fmt: skip


@dataclass
class ForceMap:
    """The largest tool force in ``direction`` at every solved pose of the grid."""

    direction: str
    point: str  #: body.point of the tool
    names: list[str]  #: every driver's name (the columns of ``inputs``)
    inputs: np.ndarray  #: (N, n_inputs)
    points: np.ndarray  #: (N, 3) the tool point, global [m]
    force: np.ndarray  #: (N,) [N]
    limiting: np.ndarray  #: (N,) the name of the cylinder that limits
    seconds: float

    def cells(self, size: float = 0.3) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cell centres x (nx,) and z (nz,) [m] of a ``size`` grid over the tool point's reach in the
        boom plane, and per cell (nz, nx) the largest force (NaN: no pose there) and its limiting
        cylinder ('' none)."""
        x, z = self.points[:, 0], self.points[:, 2]
        x0, z0 = np.floor(x.min() / size) * size, np.floor(z.min() / size) * size
        ix, iz = ((x - x0) / size).astype(int), ((z - z0) / size).astype(int)
        nx, nz = ix.max() + 1, iz.max() + 1
        best = np.full((nz, nx), np.nan)
        limiting = np.full((nz, nx), "", dtype=object)
        order = np.argsort(self.force)  # ascending: the largest written last wins
        best[iz[order], ix[order]] = self.force[order]
        limiting[iz[order], ix[order]] = self.limiting[order]
        return x0 + size * (np.arange(nx) + 0.5), z0 + size * (np.arange(nz) + 0.5), best, limiting

    def to_csv(self) -> str:
        """Every pose: its inputs, the tool point (x, y, z), the force [N] and the limiting cylinder."""
        header = ",".join([*self.names, "x", "y", "z", "force", "limiting"])
        rows = [",".join([*(repr(float(v)) for v in u), *(repr(float(c)) for c in p), repr(float(f)), str(name)])
                for u, p, f, name in zip(self.inputs, self.points, self.force, self.limiting)]  # fmt: skip
        return "\n".join([header, *rows]) + "\n"


def force_map(system: NumericSystem, model: Model, direction: str, grid: tuple[int, ...] = (25, 17, 25)) -> ForceMap:
    """The force map of ``model``'s tool point (its working range's point) in ``direction`` over a
    grid of its working range's swept inputs (``grid`` values each), in ``system`` (the working
    range's case)."""
    if direction not in DIRECTIONS:
        raise KinegenError(f"unknown direction {direction!r} (directions: {', '.join(DIRECTIONS)})")
    spec = model.working_range
    if spec is None:
        raise KinegenError(f"{model.name} has no working_range: section (the map covers its swept inputs)")
    start = time.perf_counter()
    evaluator = RangeEvaluator(system, spec)
    if len(grid) != len(evaluator.names):
        raise KinegenError(f"grid {grid}: give one count per swept input ({', '.join(evaluator.names)})")
    axes = [np.linspace(lo, hi, c) for (lo, hi), c in zip(evaluator.ranges, grid)]
    corner = np.array([a[0] for a in axes])
    evaluator.move_to(corner)
    swept = [system.driver_names.index(n) for n in evaluator.names]
    sweep = sweep_grid(system, evaluator.inputs(corner), swept, axes, evaluator.q)
    ok = sweep.converged.ravel()
    index = np.indices(grid).reshape(len(grid), -1)[:, ok]
    inputs = np.repeat(evaluator.inputs(corner)[None], int(ok.sum()), axis=0)
    for d, k in enumerate(swept):
        inputs[:, k] = axes[d][index[d]]
    q = sweep.q.reshape(system.n_stored, -1)[:, ok].T
    point = spec.point
    v = None
    if DIRECTIONS[direction] is None:  # the lip's velocity per unit rate of the bucket's input
        bucket = model.tool_forces.forces["bucket"].driver if model.tool_forces and "bucket" in model.tool_forces.forces else None
        if bucket is None:
            raise KinegenError("the tangent map needs tool_forces.bucket (the input that curls the bucket)")
        v = unit_rate_velocities(system, q, inputs, bucket)
    results = pose_results(system, q, inputs, v)
    if v is not None:
        motion = results.point_velocity(point.body, point.name)
        along = motion / np.linalg.norm(motion, axis=1)[:, None]
    else:
        along = np.broadcast_to(np.array(DIRECTIONS[direction]), (len(q), 3))
    statics = Statics(results, model)
    _, multipliers = statics.hold(point.body, point.name, -along, batch=True)  # the machine holds -F when the tool exerts F
    per_newton = statics.element_forces(multipliers)
    solved = np.isfinite(per_newton).all(axis=1)
    per_newton, inputs, q = per_newton[solved], inputs[solved], q[solved]  # a pose the actuation cannot hold: left out
    by_cylinder = statics.hydraulic_limits(per_newton, working=True)
    names = list(by_cylinder)
    limits = np.stack([by_cylinder[name][0] for name in names])
    which = np.argmin(limits, axis=0)
    positions = system.point_positions(q, [(point.body, point.name)])[:, 0]
    return ForceMap(direction, f"{point.body}.{point.name}", list(system.driver_names), inputs, positions, limits[which, np.arange(len(q))],
                    np.array([names[w] for w in which], dtype=object), time.perf_counter() - start)  # fmt: skip

def plot_force_map(found: ForceMap, path: str | Path, boundary=None, silhouette: dict[str, np.ndarray] | None = None) -> Path:
    """PNG of :func:`force_map_figure`."""
    from kinegen.analysis.plots import save

    return save(force_map_figure(found, boundary, silhouette), path)


def force_map_figure(found: ForceMap, boundary=None, silhouette: dict[str, np.ndarray] | None = None):
    """Left, the largest force per cell [kN] with contour lines, the working range's exact boundary
    and the machine; right, the cylinder that limits it. The cells and contours are drawn inside the
    boundary only (a 0.3 m cell holding poses near the boundary would reach past it)."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Polygon

    from kinegen.analysis.plots import pyplot

    plt = pyplot()
    xs, zs, best, limiting = found.cells()
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 6.8), sharey=True)
    kn = best / 1e3
    mesh = axes[0].pcolormesh(xs, zs, kn, cmap="viridis", shading="nearest")
    levels = np.linspace(np.nanmin(kn), np.nanmax(kn), 7)[1:-1]
    filled = np.where(np.isfinite(kn), kn, np.nanmin(kn) - 1)
    lines = axes[0].contour(xs, zs, filled, levels=levels, colors="white", linewidths=0.7)
    axes[0].clabel(lines, fmt="%.0f", fontsize=7)
    fig.colorbar(mesh, ax=axes[0], label="largest tool force [kN]", shrink=0.85)
    circuits = sorted({c for c in limiting.ravel() if c})
    codes = np.where(limiting == "", np.nan, np.vectorize(lambda c: circuits.index(c) if c else -1)(limiting)).astype(float)
    palette = ListedColormap(["tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"][: max(len(circuits), 1)])
    axes[1].pcolormesh(xs, zs, codes, cmap=palette, vmin=-0.5, vmax=len(circuits) - 0.5, shading="nearest")
    for k, name in enumerate(circuits):
        axes[1].fill([], [], color=palette(k), label=f"{name} at its relief setting")
    axes[1].legend(loc="upper right", fontsize=8)
    lines_kept = [lines] if hasattr(lines, "set_clip_path") else list(getattr(lines, "collections", []))
    clipped = [[mesh, *lines_kept], [axes[1].collections[0]]]
    for ax, title, artists in zip(axes, (f"largest force at {found.point},\n{MEANING[found.direction]}", "the cylinder that limits it"), clipped):
        if boundary is not None:  # the cells inside the exact boundary only: a cell's square may reach past it
            outline = Polygon(boundary.points[:, :2], closed=True, transform=ax.transData, facecolor="none", edgecolor="none")
            ax.add_patch(outline)
            for artist in artists:
                artist.set_clip_path(outline)
            ax.plot(boundary.points[:, 0], boundary.points[:, 1], color="black", lw=1.2, label=None)
            low, high = boundary.points[:, :2].min(axis=0) - 0.3, boundary.points[:, :2].max(axis=0) + 0.3
            ax.set(xlim=(low[0], high[0]), ylim=(low[1], high[1]))
        for polygon in (silhouette or {}).values():
            ax.fill(polygon[:, 0], polygon[:, 1], facecolor="0.75", edgecolor="0.3", lw=0.6)
        ax.axhline(0.0, color="saddlebrown", lw=1.2)
        ax.set(aspect="equal", xlabel="horizontal distance from the swing axis [m]", title=title)
    axes[0].set_ylabel("height above the ground [m]")
    fig.suptitle(f"{found.direction} force map: {len(found.force):,} poses of the working range, every cylinder at most at its relief setting\n"
                 f"(static, massless links, no friction; white: no pose of the grid in that 0.3 m cell)", fontsize=10)  # fmt: skip
    return fig
