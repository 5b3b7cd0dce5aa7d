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

from kinegen.errors import KinegenError
from kinegen.forces.statics import Statics, pose_results, unit_rate_velocities
from kinegen.model import Model
from kinegen.runtime import NumericSystem, kinematics
from kinegen.runtime.batch import sweep_grid
from kinegen.runtime.continuation import RangeEvaluator

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
    cylinders: tuple[str, ...] = ()  #: the hydraulic actuators, in the order of ``limits``
    limits: np.ndarray | None = None  #: (n_cylinders, N) the load at which each reaches its relief setting [N]
    index: np.ndarray | None = None  #: (n_swept, N) each pose's place in the grid of the swept inputs
    swept: tuple[str, ...] = ()  #: the swept inputs, in the order of ``index``

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
    full_index = index
    inputs = np.repeat(evaluator.inputs(corner)[None], int(ok.sum()), axis=0)
    for d, k in enumerate(swept):
        inputs[:, k] = axes[d][index[d]]
    q = sweep.q.reshape(system.n_stored, -1)[:, ok].T
    point = spec.point
    v = None
    if DIRECTIONS[direction] is None:  # the lip's velocity per unit rate of the bucket's input
        bucket = _bucket_driver(model)
        if bucket is None:
            raise KinegenError("the tangent map needs tool_forces.bucket (the input that curls the bucket)")
        v = unit_rate_velocities(system, q, inputs, bucket)
    results = pose_results(system, q, inputs, v)
    if v is not None:
        motion = kinematics.point_velocity(results, point.body, point.name)
        along = motion / np.linalg.norm(motion, axis=1)[:, None]
    else:
        along = np.broadcast_to(np.array(DIRECTIONS[direction]), (len(q), 3))
    statics = Statics(results, model)
    _, multipliers = statics.hold(point.body, point.name, -along, batch=True)  # the machine holds -F when the tool exerts F
    per_newton = statics.element_forces(multipliers)
    solved = np.isfinite(per_newton).all(axis=1)
    per_newton, inputs, q = per_newton[solved], inputs[solved], q[solved]  # a pose the actuation cannot hold: left out
    full_index = full_index[:, solved]
    by_cylinder = statics.hydraulic_limits(per_newton, working=True)
    names = list(by_cylinder)
    limits = np.stack([by_cylinder[name][0] for name in names])
    which = np.argmin(limits, axis=0)
    positions = system.point_positions(q, [(point.body, point.name)])[:, 0]
    return ForceMap(direction, f"{point.body}.{point.name}", list(system.driver_names), inputs, positions, limits[which, np.arange(len(q))],
                    np.array([names[w] for w in which], dtype=object), time.perf_counter() - start, tuple(names), limits, full_index,
                    tuple(evaluator.names))  # fmt: skip


@dataclass
class ReachMap:
    """The largest tool force at each point of a (radius, height) raster of the boom plane: over the
    remaining freedom -- the tool's attitude -- the largest of the smallest load at which a cylinder
    reaches its relief setting (:func:`reach_map`). NaN where the tool point does not reach."""

    direction: str
    point: str
    radius: np.ndarray  #: (nx,) [m]
    height: np.ndarray  #: (nz,) [m]
    force: np.ndarray  #: (nz, nx) [N]
    limiting: np.ndarray  #: (nz, nx) the index into ``regions`` of what limits there (-1: not reached)
    attitude: np.ndarray  #: (nz, nx) the attitude input's value at the largest force
    #: (nz, nx) True where the largest sampled attitude is the last of those that reach the point (the
    #: next attitude puts a cylinder past its end of stroke there): the true largest may lie between
    #: them, the map shows that sampled attitude's value (the attitude input's own ends are sampled)
    edge: np.ndarray
    cylinders: tuple[str, ...]
    #: what can limit: each cylinder, then each pair of them -- where the largest force is at the attitude
    #: at which the two reach their relief settings together (the limit switches from one to the other there)
    regions: tuple[str, ...]
    attitude_input: str
    attitudes: int  #: the attitude input's values swept
    poses: int  #: the poses solved
    seconds: float


def reach_map(system: NumericSystem, model: Model, direction: str = "tangent", attitudes: int = 33, per_input: int = 41,
              spacing: float = 0.05) -> ReachMap:  # fmt: skip
    """The force map as a smooth function of the tool point's place: for each of ``attitudes`` values
    of the input that turns the tool (``tool_forces.bucket``'s driver: the bucket's attitude), the
    two other swept inputs' ``per_input`` x ``per_input`` grid solved exactly (:func:`force_map`), each
    cylinder's relief-limited load interpolated linearly over the grid's triangles as they lie in the
    boom plane, onto a ``spacing`` raster of (radius, height); at every raster point the largest over
    the attitudes of the smallest over the cylinders -- refined where one cylinder limits on both sides
    of the best attitude by the parabola through the three, and where the limit passes to another
    cylinder by the attitude at which the two meet (their limits linear between two attitudes) --
    and the cylinder (or the two cylinders) that limit there."""
    start = time.perf_counter()
    spec = model.working_range
    tool = _bucket_driver(model)
    names = RangeEvaluator(system, spec).names if spec is not None else []
    if tool is None or tool not in names:
        raise KinegenError("the reach map needs a working_range: section whose swept inputs include tool_forces.bucket's driver")
    if len(names) != 3:
        raise KinegenError(f"the reach map sweeps three inputs (two that place the tool point, one that turns it); {spec.case} sweeps {len(names)}")
    turn = names.index(tool)
    found = force_map(system, model, direction, tuple(attitudes if k == turn else per_input for k in range(3)))
    others = [k for k in range(3) if k != turn]
    x, z = found.points[:, 0], found.points[:, 2]
    radius = np.arange(np.floor(x.min() / spacing) * spacing, x.max() + spacing, spacing)
    height = np.arange(np.floor(z.min() / spacing) * spacing, z.max() + spacing, spacing)
    shape = (len(height), len(radius))
    per_layer = np.full((attitudes, *shape), np.nan)  # the largest force of each attitude
    limiting_of = np.full((attitudes, *shape), -1)
    each = np.full((attitudes, len(found.cylinders), *shape), np.nan)  # every cylinder's limit there (of the pose giving the largest)
    values = np.full(attitudes, np.nan)
    limits = np.where(np.isfinite(found.limits), found.limits, 1e300)
    for layer in range(attitudes):
        mine = np.flatnonzero(found.index[turn] == layer)
        if len(mine) < 3:
            continue
        values[layer] = found.inputs[mine[0], system.driver_names.index(tool)]
        triangles = _grid_triangles(found.index[others[0], mine], found.index[others[1], mine], mine, (per_input, per_input))
        per_layer[layer], limiting_of[layer], each[layer] = _largest_per_cell(shape, *_rasterize(x, z, limits, triangles, radius, height))
    reached = np.isfinite(per_layer).any(axis=0)
    best = np.argmax(np.where(np.isfinite(per_layer), per_layer, -np.inf), axis=0)
    rows, cols = np.indices(shape)
    force = np.where(reached, per_layer[best, rows, cols], np.nan)
    attitude = np.where(reached, values[best], np.nan)
    f0 = per_layer[np.clip(best - 1, 0, attitudes - 1), rows, cols]
    f1 = per_layer[np.clip(best + 1, 0, attitudes - 1), rows, cols]
    curve = f0 - 2 * force + f1
    inner = reached & (best > 0) & (best < attitudes - 1) & np.isfinite(f0) & np.isfinite(f1) & (curve < 0)
    limiting = np.where(reached, limiting_of[best, rows, cols], -1)
    before, after = limiting_of[np.clip(best - 1, 0, attitudes - 1), rows, cols], limiting_of[np.clip(best + 1, 0, attitudes - 1), rows, cols]
    step = np.nanmedian(np.diff(values))
    smooth = inner & (before == limiting) & (after == limiting)
    with np.errstate(all="ignore"):  # one cylinder limits on both sides: the top of the parabola through the three
        shift = np.where(smooth, 0.5 * (f0 - f1) / curve, 0.0)
        top = np.where(smooth, force - 0.25 * (f0 - f1) * shift, force)
        turned = attitude + shift * step
        for side, other in ((-1, before), (1, after)):  # the limit passes to another cylinder: where the two meet
            n = np.clip(best + side, 0, attitudes - 1)
            switch = reached & (n != best) & (other >= 0) & (other != limiting)
            i, j = np.clip(limiting, 0, None), np.clip(other, 0, None)
            fi_b, fj_b = each[best, i, rows, cols], each[best, j, rows, cols]
            fi_n, fj_n = each[n, i, rows, cols], each[n, j, rows, cols]
            d_b, d_n = fi_b - fj_b, fi_n - fj_n
            t = np.clip(d_b / (d_b - d_n), 0.0, 1.0)
            meet = fi_b + t * (fi_n - fi_b)
            better = switch & np.isfinite(meet) & (meet > top)
            top = np.where(better, meet, top)
            turned = np.where(better, attitude + side * t * step, turned)
    force, attitude = np.where(reached, np.maximum(top, force), force), np.where(reached, turned, attitude)
    edge = reached & (((best > 0) & ~np.isfinite(f0)) | ((best < attitudes - 1) & ~np.isfinite(f1)))  # an end of stroke is sampled
    on_a_face = np.zeros(shape, dtype=bool)
    # where the next attitude leaves the point's reach, the largest may be where a placing cylinder reaches its end of stroke:
    # the four faces of the inputs' box with one of them at an end, over (the other, the attitude), rasterized the same way
    for k in others:
        free = others[1 - others.index(k)]
        for end in (0, per_input - 1):
            face = np.flatnonzero(found.index[k] == end)
            triangles = _grid_triangles(found.index[free, face], found.index[turn, face], face, (per_input, attitudes))
            larger, which, _ = _largest_per_cell(shape, *_rasterize(x, z, limits, triangles, radius, height))
            wins = reached & (larger > force)
            force, limiting = np.where(wins, larger, force), np.where(wins, which, limiting)
            on_a_face |= wins
            edge &= ~(reached & (larger >= force - 1e-9 * np.abs(force)))  # the largest is on this face (where it wins, too)
    count = len(found.cylinders)
    pairs = [(i, j) for i in range(count) for j in range(i + 1, count)]
    # the best attitude lies where the limit passes from one cylinder to the other (not at a placing cylinder's end)
    switch = inner & ~on_a_face & (before >= 0) & (after >= 0) & (before != after)
    for k, (i, j) in enumerate(pairs):
        limiting = np.where(switch & (np.minimum(before, after) == i) & (np.maximum(before, after) == j), count + k, limiting)
    regions = (*found.cylinders, *(f"{found.cylinders[i]} and {found.cylinders[j]} together" for i, j in pairs))
    return ReachMap(direction, found.point, radius, height, force, limiting, attitude, edge, found.cylinders, regions, tool, attitudes,
                    len(found.force), time.perf_counter() - start)  # fmt: skip


def plot_force_map(found: ReachMap, path: str | Path, boundary=None, silhouette: dict[str, np.ndarray] | None = None) -> Path:
    """PNG of :func:`force_map_figure`."""
    from kinegen.figures import save

    return save(force_map_figure(found, boundary, silhouette), path)


#: the limiting cylinders' colours, in the model's order
REGION_COLOURS = ("tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:blue", "tab:pink", "tab:olive", "tab:cyan", "tab:gray")


def force_map_figure(found: ReachMap, boundary=None, silhouette: dict[str, np.ndarray] | None = None):
    """Left, the largest force [kN] over the boom plane (:func:`reach_map`: a smooth function of the
    tool point's place) as filled contours with labelled lines; right, the regions where each cylinder
    limits it, with their boundaries. Both inside the working range's exact boundary (drawn whole),
    with the machine's silhouette; the figure says how the map is made and how it differs from the
    ISO 6015 figure."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch, Polygon

    from kinegen.figures import pyplot

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(13.5, 8.6), sharey=True)
    force, limiting, fringe = _filled(found, boundary)
    kn = force / 1e3
    levels = np.linspace(np.nanmin(kn), np.nanmax(kn), 13)
    filled = axes[0].contourf(found.radius, found.height, kn, levels=levels, cmap="viridis")
    lines = axes[0].contour(found.radius, found.height, kn, levels=levels[2:-1:2], colors="white", linewidths=0.7)
    axes[0].clabel(lines, fmt="%.0f", fontsize=7)
    fig.colorbar(filled, ax=axes[0], label="largest tool force [kN]", shrink=0.85)
    used = sorted({int(c) for c in np.unique(limiting) if c >= 0})
    palette = ListedColormap([REGION_COLOURS[c % len(REGION_COLOURS)] for c in range(len(found.regions))])
    codes = np.where(limiting >= 0, limiting, np.nan).astype(float)
    regions = axes[1].contourf(found.radius, found.height, codes, levels=np.arange(len(found.regions) + 1) - 0.5, cmap=palette)
    edges = axes[1].contour(found.radius, found.height, codes, levels=np.arange(len(found.regions) - 1) + 0.5, colors="black", linewidths=0.6)
    axes[1].legend(handles=[Patch(color=palette(c), label=found.regions[c]) for c in used], loc="upper center", bbox_to_anchor=(0.5, -0.1),
                   ncol=2, fontsize=8, title="limited by (at the relief setting)", title_fontsize=8, frameon=False)  # fmt: skip
    for ax, title, artists in zip(axes, (f"largest force at {found.point},\n{MEANING[found.direction]}", "the cylinder that limits it"),
                                  ([filled, lines], [regions, edges])):  # fmt: skip
        if boundary is not None:  # inside the exact boundary only
            outline = Polygon(boundary.points[:, :2], closed=True, transform=ax.transData, facecolor="none", edgecolor="none")
            ax.add_patch(outline)
            for artist in artists:
                artist.set_clip_path(outline)
            ax.plot(boundary.points[:, 0], boundary.points[:, 1], color="black", lw=1.2, gid="boundary")
            low, high = boundary.points[:, :2].min(axis=0) - 0.3, boundary.points[:, :2].max(axis=0) + 0.3
            ax.set(xlim=(low[0], high[0]), ylim=(low[1], high[1]))
        for polygon in (silhouette or {}).values():
            ax.fill(polygon[:, 0], polygon[:, 1], facecolor="0.75", edgecolor="0.3", lw=0.6)
        ax.axhline(0.0, color="saddlebrown", lw=1.2)
        ax.set(aspect="equal", xlabel="horizontal distance from the swing axis [m]", title=title)
    axes[0].set_ylabel("height above the ground [m]")
    fig.suptitle(
        f"{found.direction} force map: at each place of the tool point, the largest force over the tool's attitude ({found.attitude_input}),\n"
        f"every cylinder at most at its relief setting; static, massless links, no friction. Made of {found.poses:,} exact poses "
        f"({found.attitudes} attitudes), linear between them,\nthe best attitude refined by a parabola{fringe}.\nNot the ISO 6015 figure (kinegen forces): there the working cylinder is at its relief "
        "setting and the others hold at their holding setting.", fontsize=9)  # fmt: skip
    fig.subplots_adjust(top=0.82, bottom=0.16)  # the four lines above, the legend below: off the panels' titles and axes
    return fig


def _filled(found: ReachMap, boundary) -> tuple[np.ndarray, np.ndarray, str]:
    """The map's force and limiting region with the raster points inside the exact ``boundary`` that
    no triangle of poses covers (a fringe along curled-in edges) given their nearest covered point's,
    and the words that say how much that is ("" when nothing is filled)."""
    if boundary is None:
        return found.force, found.limiting, ""
    from matplotlib.path import Path as Outline
    from scipy.ndimage import distance_transform_edt

    rr, hh = np.meshgrid(found.radius, found.height)
    inside = Outline(boundary.points[:, :2]).contains_points(np.column_stack([rr.ravel(), hh.ravel()])).reshape(rr.shape)
    covered = np.isfinite(found.force)
    gap = inside & ~covered
    if not gap.any():
        return found.force, found.limiting, ""
    nearest = distance_transform_edt(~covered, return_distances=False, return_indices=True)
    force = np.where(gap, found.force[nearest[0], nearest[1]], found.force)
    limiting = np.where(gap, found.limiting[nearest[0], nearest[1]], found.limiting)
    share = gap.sum() / inside.sum()
    return force, limiting, f"; the {share:.1%} of the range no sampled pose covers (along its edges) shows its nearest value"


def _bucket_driver(model: Model) -> str | None:
    """The input that curls the bucket (``tool_forces.bucket``'s driver), or None."""
    tool_forces = model.tool_forces
    return tool_forces.forces["bucket"].driver if tool_forces and "bucket" in tool_forces.forces else None


def _grid_triangles(rows: np.ndarray, cols: np.ndarray, poses: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The triangles (T, 3) of the poses ``poses`` laid out on a grid of ``shape`` at (``rows``,
    ``cols``): two per grid cell whose four corners were solved."""
    place = -np.ones(shape, dtype=int)
    place[rows, cols] = poses
    corners = np.stack([place[:-1, :-1], place[1:, :-1], place[1:, 1:], place[:-1, 1:]], axis=-1).reshape(-1, 4)
    corners = corners[(corners >= 0).all(axis=1)]
    return np.vstack([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])


def _largest_per_cell(shape: tuple[int, int], force: np.ndarray, limiting: np.ndarray, flat: np.ndarray,
                      cylinders: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Per raster cell (``shape``) the largest of the covered points' ``force`` that fall in it (``flat``:
    their cells; a point inside two overlapping triangles -- two poses reach it -- comes twice), that
    point's ``limiting`` cylinder and every cylinder's limit there (``cylinders``, (C, K)); NaN and -1
    where no point falls."""
    largest, which = np.full(shape, np.nan), np.full(shape, -1)
    each = np.full((len(cylinders), *shape), np.nan)
    order = np.argsort(force)  # ascending: the largest is written last
    largest.flat[flat[order]] = force[order]
    which.flat[flat[order]] = limiting[order]
    for c in range(len(cylinders)):
        each[c].flat[flat[order]] = cylinders[c, order]
    return largest, which, each


def _rasterize(x: np.ndarray, z: np.ndarray, limits: np.ndarray, triangles: np.ndarray, radius: np.ndarray,
               height: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Each cylinder's limit (``limits``, (C, N) at the poses' points (x, z)) interpolated linearly over
    every triangle of poses onto the raster points (``radius`` x ``height``) inside it: per covered
    raster point, the smallest over the cylinders, which cylinder that is, and the raster's flat index
    (a point inside two overlapping triangles -- a fold: two poses reach it -- comes twice), and every
    cylinder's value there (C, K)."""
    if not len(triangles):  # no grid cell with four solved corners
        return np.zeros(0), np.zeros(0, dtype=int), np.zeros(0, dtype=int), np.zeros((len(limits), 0))
    spacing = radius[1] - radius[0] if len(radius) > 1 else 1.0
    p0, p1, p2 = (np.column_stack([x[triangles[:, k]], z[triangles[:, k]]]) for k in range(3))
    e1, e2 = p1 - p0, p2 - p0
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    keep = np.abs(det) > 1e-18
    triangles, p0, e1, e2, det = triangles[keep], p0[keep], e1[keep], e2[keep], det[keep]
    corners = np.stack([p0, p0 + e1, p0 + e2])
    ix0 = np.ceil((corners[..., 0].min(axis=0) - radius[0]) / spacing - 1e-9).astype(int)
    ix1 = np.floor((corners[..., 0].max(axis=0) - radius[0]) / spacing + 1e-9).astype(int)
    iz0 = np.ceil((corners[..., 1].min(axis=0) - height[0]) / spacing - 1e-9).astype(int)
    iz1 = np.floor((corners[..., 1].max(axis=0) - height[0]) / spacing + 1e-9).astype(int)
    nx, nz = np.maximum(ix1 - ix0 + 1, 0), np.maximum(iz1 - iz0 + 1, 0)
    count = nx * nz
    which = np.repeat(np.arange(len(triangles)), count)
    offset = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    ix = ix0[which] + offset % nx[which]
    iz = iz0[which] + offset // nx[which]
    inside_raster = (ix >= 0) & (ix < len(radius)) & (iz >= 0) & (iz < len(height))
    which, ix, iz = which[inside_raster], ix[inside_raster], iz[inside_raster]
    d = np.column_stack([radius[ix], height[iz]]) - p0[which]
    a = (d[:, 0] * e2[which, 1] - d[:, 1] * e2[which, 0]) / det[which]
    b = (e1[which, 0] * d[:, 1] - e1[which, 1] * d[:, 0]) / det[which]
    inside = (a >= -1e-12) & (b >= -1e-12) & (a + b <= 1 + 1e-12)
    which, ix, iz, a, b = which[inside], ix[inside], iz[inside], a[inside], b[inside]
    vertices = triangles[which]
    values = (1 - a - b) * limits[:, vertices[:, 0]] + a * limits[:, vertices[:, 1]] + b * limits[:, vertices[:, 2]]  # (C, K)
    limiting = np.argmin(values, axis=0)
    return values[limiting, np.arange(values.shape[1])], limiting, iz * len(radius) + ix, values
