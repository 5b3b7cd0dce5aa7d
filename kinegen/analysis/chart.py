"""The working-range chart in the style of a manufacturer's diagram (ISO 7135 naming).

Drawn in the chart plane of :mod:`kinegen.analysis.boundary` (horizontal distance from the swing
axis in the plane of the front, height; m): the exact boundary, the ground line z = 0, the swing
axis, the machine in its transport pose as a silhouette (each body the convex hull of its named
points, each actuator a bar between its pins), and dimension lines with letters for the figures
of :mod:`kinegen.analysis.envelope`, listed beside the drawing with their values.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinegen.analysis.boundary import Boundary
from kinegen.analysis.envelope import Envelope
from kinegen.analysis.evaluator import RangeEvaluator
from kinegen.runtime import NumericSystem

#: letter, figure, how it is drawn: "h" a horizontal dimension from the swing axis, "v" a vertical one from the ground
DIMENSIONS = (
    ("A", "max_reach", "h"),
    ("B", "max_reach_at_ground", "h"),
    ("C", "max_depth", "v"),
    ("D", "max_cutting_height", "v"),
    ("E", "max_dumping_height", "v"),
    ("F", "max_vertical_wall_depth", "v"),
    ("G", "min_front_swing_radius", "h"),
)
TITLES = {
    "max_reach": "max. reach",
    "max_reach_at_ground": "max. reach at ground level",
    "max_depth": "max. digging depth",
    "max_cutting_height": "max. cutting height",
    "max_dumping_height": "max. dumping height",
    "max_vertical_wall_depth": "max. vertical wall depth (arm vertical)",
    "min_front_swing_radius": "min. front swing radius",
}


@dataclass(frozen=True)
class Mark:
    """A figure's point in the chart plane and how its dimension line is drawn."""

    letter: str
    figure: str
    value: float
    reach: float  #: m, of the figure's point
    height: float  #: m
    kind: str  #: "h" or "v"


def figure_marks(envelope: Envelope, system: NumericSystem, direction: np.ndarray) -> list[Mark]:
    """Where each figure of ``envelope`` is, in the chart plane (reach along ``direction``)."""
    evaluator = RangeEvaluator(system, envelope.spec)
    out = []
    for letter, name, kind in DIMENSIONS:
        if name == "min_front_swing_radius":
            if envelope.front is None:
                continue
            body, point = envelope.front.farthest[0].split(".")
            p = system.point_positions(envelope.front.q[None], [(body, point)])[0, 0]
            out.append(Mark(letter, name, envelope.front.radius, envelope.front.radius, float(p[2]), kind))
            continue
        if name not in envelope.optima:
            continue
        p = evaluator.points(envelope.optima[name][1])[0]
        out.append(Mark(letter, name, envelope.figures[name], float(p[:2] @ direction), float(p[2]), kind))
    return out


def _pose_points(system: NumericSystem, q: np.ndarray, direction: np.ndarray) -> dict[str, np.ndarray]:
    """Each body's named points in the chart plane (P, 2) at the configuration q."""
    out = {}
    for body in system.bodies:
        names = list(system.points.get(body, {}))
        if not names:
            continue
        p = system.point_positions(q[None], [(body, n) for n in names])[0]
        out[body] = np.column_stack([p[:, :2] @ direction, p[:, 2]])
    return out


def _silhouette(ax, system: NumericSystem, q: np.ndarray, direction: np.ndarray, **style) -> None:
    """The machine at q: bodies as filled hulls of their points, actuators as bars."""
    from matplotlib.patches import Polygon
    from scipy.spatial import ConvexHull, QhullError

    points = _pose_points(system, q, direction)
    for xy in points.values():
        unique = np.unique(np.round(xy, 9), axis=0)
        if len(unique) >= 3:
            try:
                hull = ConvexHull(unique)
                ax.add_patch(Polygon(unique[hull.vertices], closed=True, **style))
                continue
            except QhullError:  # collinear
                pass
        if len(unique) >= 2:
            ax.plot(unique[:, 0], unique[:, 1], color=style.get("facecolor", "0.5"), lw=4, solid_capstyle="round",
                    alpha=style.get("alpha", 1.0), zorder=style.get("zorder", 2))  # fmt: skip
    for (body1, point1), (body2, point2), _ in system.actuators.values():
        ends = []
        for body, point in ((body1, point1), (body2, point2)):
            names = list(system.points.get(body, {}))
            if body in points and point in names:
                ends.append(points[body][names.index(point)])
        if len(ends) == 2:
            ends = np.array(ends)
            ax.plot(ends[:, 0], ends[:, 1], color=style.get("edgecolor", "0.3"), lw=3, alpha=style.get("alpha", 1.0),
                    solid_capstyle="butt", zorder=style.get("zorder", 2) + 0.1)  # fmt: skip


def transport_q(system: NumericSystem, envelope: Envelope) -> tuple[np.ndarray, str]:
    """The configuration the silhouette shows: the working_range section's ``transport`` inputs,
    else the pose of the minimum front swing radius; and its description."""
    evaluator = RangeEvaluator(system, envelope.spec)
    if envelope.spec.transport:
        evaluator.move_to(np.array([envelope.spec.transport[n] for n in evaluator.names]))
        return evaluator.q, "transport pose"
    if envelope.front is not None:
        return envelope.front.q, "pose of the minimum front swing radius"
    return evaluator.q, "the case's first pose"


def plot_working_range(envelope: Envelope, boundary: Boundary, system: NumericSystem, path: str | Path, direction: np.ndarray | None = None
                       ) -> Path:  # fmt: skip
    """The chart (see the module docstring) as a PNG."""
    from kinegen.analysis.plots import pyplot, save

    plt = pyplot()
    direction = np.array([1.0, 0.0]) if direction is None else direction
    marks = figure_marks(envelope, system, direction)
    fig, (ax, side) = plt.subplots(1, 2, figsize=(14, 9), gridspec_kw={"width_ratios": [3.2, 1.3]})
    region = boundary.points
    ax.fill(region[:, 0], region[:, 1], color="tab:blue", alpha=0.06, zorder=0)
    ax.plot(region[:, 0], region[:, 1], color="tab:blue", lw=1.8, zorder=3, label="working range (exact boundary)")
    corners = boundary.points[boundary.switching]
    ax.plot(corners[:, 0], corners[:, 1], "o", color="tab:blue", ms=3, zorder=4, label="switching points")
    left, right = min(region[:, 0].min(), 0.0) - 1.0, region[:, 0].max() + 1.2
    bottom, top = region[:, 1].min() - 0.8, region[:, 1].max() + 0.8
    ax.axhline(0.0, color="saddlebrown", lw=1.5, zorder=1)
    ax.fill_between([left - 5, right + 5], [0, 0], [-0.12, -0.12], color="saddlebrown", alpha=0.25, lw=0, zorder=1)
    ax.axvline(0.0, color="0.3", lw=0.8, ls="-.", zorder=1)
    ax.annotate("swing axis", (0.0, top - 0.2), xytext=(4, 0), textcoords="offset points", fontsize=8, color="0.3", va="top")
    q, pose = transport_q(system, envelope)
    _silhouette(ax, system, q, direction, facecolor="0.55", edgecolor="0.25", alpha=0.85, zorder=2)
    ax.plot([], [], color="0.55", lw=6, label=f"machine ({pose})")
    for number, mark in enumerate(marks):
        _dimension(ax, mark, right=number % 2 == 1)
    ax.set(xlim=(left, right), ylim=(bottom, top), aspect="equal", xlabel="horizontal distance from the swing axis [m]",
           ylabel="height above ground [m]")  # fmt: skip
    ax.set_xticks(np.arange(np.ceil(left), right, 1.0))
    ax.set_yticks(np.arange(np.ceil(bottom), top, 1.0))
    ax.grid(True, alpha=0.25)
    ax.legend(loc="lower right", fontsize=8)
    spec = envelope.spec
    ax.set_title(f"working range of {spec.point.body}.{spec.point.name}: {len(set(boundary.curve.tolist()))} curves with inputs at limits or folds, "
                 f"{len(boundary.switching)} switching points", fontsize=10)  # fmt: skip
    side.axis("off")
    rows = [["", "figure", "kinegen", "published"]]
    for mark in marks:
        published = spec.published.get(mark.figure)
        rows.append([mark.letter, TITLES[mark.figure], f"{mark.value:.3f} m", "-" if published is None else f"{published:.2f} m*"])
    table = side.table(cellText=rows, loc="upper center", cellLoc="left", colWidths=[0.06, 0.6, 0.17, 0.17])
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    table.scale(1, 1.5)
    lines = [
        "* as quoted, unverified",
        f"boundary: {len(boundary.points) - 1} exact points, chord error {1e3 * boundary.chord_error:.3f} mm",
        f"{boundary.refined} crossings found by Newton; {boundary.solves} solves, {boundary.seconds:.1f} s",
        "inputs: " + ", ".join(f"{n} [{lo:g}, {hi:g}]" for n, (lo, hi) in zip(envelope.names, _ranges(system, envelope))),
        *boundary.notes,
    ]
    side.text(0.0, 0.52, "\n".join(_wrap(line, 52) for line in lines), fontsize=8, va="top", transform=side.transAxes)
    return save(fig, path)


def _ranges(system: NumericSystem, envelope: Envelope) -> list[tuple[float, float]]:
    return RangeEvaluator(system, envelope.spec).ranges


def _wrap(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width)) or text


def _dimension(ax, mark: Mark, right: bool = True) -> None:
    """A dimension line with arrows at both ends and its letter; extension lines to the figure's point."""
    style = {"arrowstyle": "<|-|>", "color": "0.15", "lw": 0.8, "shrinkA": 0, "shrinkB": 0, "mutation_scale": 8}
    ax.plot([mark.reach], [mark.height], "o", ms=5, mfc="white", mec="crimson", mew=1.4, zorder=6)
    if mark.kind == "h":
        level = mark.height
        ax.annotate("", xy=(0.0, level), xytext=(mark.reach, level), arrowprops=style, zorder=5)
        ax.text(0.5 * mark.reach, level, mark.letter, ha="center", va="bottom", fontsize=10, fontweight="bold", color="crimson", zorder=6)
    else:
        ax.annotate("", xy=(mark.reach, 0.0), xytext=(mark.reach, mark.height), arrowprops=style, zorder=5)
        label = f" {mark.letter}" if right else f"{mark.letter} "
        ax.text(mark.reach, 0.5 * mark.height, label, ha="left" if right else "right", va="center", fontsize=10, fontweight="bold",
                color="crimson", zorder=6)  # fmt: skip


def plot_envelope(envelope: Envelope, system: NumericSystem, path: str | Path, boundary=None) -> Path:
    """The working-range chart (:func:`plot_working_range`) with the exact
    boundary (computed here unless given: :func:`kinegen.analysis.boundary.working_range_boundary`)."""
    from kinegen.analysis.boundary import working_range_boundary

    boundary = boundary if boundary is not None else working_range_boundary(system, envelope.spec)
    return plot_working_range(envelope, boundary, system, path, boundary.direction)
