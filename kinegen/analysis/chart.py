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
from kinegen.runtime import NumericSystem
from kinegen.runtime.continuation import RangeEvaluator

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


def outlines(model) -> dict[str, np.ndarray]:
    """The model's drawings (``outline:`` of a body or of the ground), body name -> (P, 3) in its
    coordinates (the ground's: ``"ground"``, global)."""
    out = {body.name: np.array(body.outline, dtype=float) for body in model.bodies if body.outline}
    if model.ground_outline:
        out["ground"] = np.array(model.ground_outline, dtype=float)
    return out


def _plane(positions: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Global positions (..., 3) in the chart plane (..., 2): reach along ``direction``, height."""
    return np.stack([positions[..., :2] @ direction, positions[..., 2]], axis=-1)


def _pose_points(system: NumericSystem, q: np.ndarray, direction: np.ndarray) -> dict[str, np.ndarray]:
    """Each body's named points in the chart plane (P, 2) at the configuration q."""
    out = {}
    for body in system.bodies:
        names = list(system.points.get(body, {}))
        if names:
            out[body] = _plane(system.point_positions(q[None], [(body, n) for n in names])[0], direction)
    return out


def machine_polygons(system: NumericSystem, q: np.ndarray, direction: np.ndarray, drawn: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The machine at q in the chart plane, body -> polygon (P, 2): a body's outline where the model
    draws one (``drawn``, from :func:`outlines`; the ground's fixed), else the convex hull of its
    named points (a bar of two points where they are collinear)."""
    from scipy.spatial import ConvexHull, QhullError

    out = {body: _plane(system.local_positions(q, body, local)[0], direction) for body, local in drawn.items()}
    for body, xy in _pose_points(system, q, direction).items():
        if body in out:
            continue
        unique = np.unique(np.round(xy, 9), axis=0)
        if len(unique) >= 3:
            try:
                out[body] = unique[ConvexHull(unique).vertices]
                continue
            except QhullError:  # collinear
                pass
        if len(unique) >= 2:
            out[body] = unique[[0, -1]]
    return out


def _silhouette(ax, system: NumericSystem, q: np.ndarray, direction: np.ndarray, polygons: dict[str, np.ndarray]) -> list:
    """The machine at q: bodies as filled ``polygons`` (:func:`machine_polygons`), actuators as
    bars; the artists drawn."""
    from matplotlib.patches import Polygon

    artists = []
    for body, polygon in polygons.items():
        fixed = body not in system.bodies
        if len(polygon) >= 3:
            artists.append(ax.add_patch(Polygon(polygon, closed=True, facecolor="0.4" if fixed else "0.62", edgecolor="0.2", lw=0.8,
                                                alpha=0.9, zorder=2, gid=f"machine:{body}")))  # fmt: skip
        else:
            (line,) = ax.plot(polygon[:, 0], polygon[:, 1], color="0.45", lw=4, solid_capstyle="round", zorder=2, gid=f"machine:{body}")
            artists.append(line)
    points = _pose_points(system, q, direction)
    for name, ((body1, point1), (body2, point2), _) in system.actuators.items():
        ends = []
        for body, point in ((body1, point1), (body2, point2)):
            names = list(system.points.get(body, {}))
            if body in points and point in names:
                ends.append(points[body][names.index(point)])
        if len(ends) == 2:
            ends = np.array(ends)
            (line,) = ax.plot(ends[:, 0], ends[:, 1], color="0.25", lw=3, solid_capstyle="butt", zorder=2.1, gid=f"machine:{name}")
            artists.append(line)
    return artists


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


#: how far below the ground a horizontal dimension near it is drawn (m): off the ground band
BELOW_GROUND = 0.55
#: chart height (inches); the width follows the drawing's aspect
CHART_HEIGHT = 8.0


def working_range_figure(envelope: Envelope, boundary: Boundary, system: NumericSystem, direction: np.ndarray | None = None,
                         drawn: dict[str, np.ndarray] | None = None):  # fmt: skip
    """The chart (see the module docstring) as a matplotlib figure: the drawing (axes 0), sized to
    its content, and beside it the figures' table, the legend and the notes (axes 1). Artists carry
    gids: ``boundary``, ``machine:<body or actuator>``, ``dimension:<letter>`` (the line, its data
    end points the figure's), ``label:<letter>``."""
    from kinegen.figures import pyplot

    plt = pyplot()
    direction = np.array([1.0, 0.0]) if direction is None else direction
    drawn = drawn or {}
    marks = figure_marks(envelope, system, direction)
    q, pose = transport_q(system, envelope)
    polygons = machine_polygons(system, q, direction, drawn)
    region = boundary.points
    everything = np.vstack([region, *polygons.values(), [[0.0, -BELOW_GROUND]]])
    left, right = min(everything[:, 0].min(), 0.0) - 0.6, everything[:, 0].max() + 0.6
    bottom, top = everything[:, 1].min() - 0.6, everything[:, 1].max() + 0.6
    width = CHART_HEIGHT * (right - left) / (top - bottom)
    fig, (ax, side) = plt.subplots(1, 2, figsize=(width + 5.4, CHART_HEIGHT + 0.9), gridspec_kw={"width_ratios": [width, 4.4]})
    ax.fill(region[:, 0], region[:, 1], color="tab:blue", alpha=0.06, zorder=0)
    ax.plot(region[:, 0], region[:, 1], color="tab:blue", lw=1.8, zorder=3, label="working range (exact boundary)", gid="boundary")
    corners = boundary.points[boundary.switching]
    ax.plot(corners[:, 0], corners[:, 1], "o", color="tab:blue", ms=3, zorder=4, label="switching points")
    ax.axhline(0.0, color="saddlebrown", lw=1.5, zorder=1)
    ax.fill_between([left - 5, right + 5], [0, 0], [-0.12, -0.12], color="saddlebrown", alpha=0.25, lw=0, zorder=1, label="ground")
    ax.axvline(0.0, color="0.3", lw=0.8, ls="-.", zorder=1)
    ax.annotate("swing axis", (0.0, top), xytext=(4, -4), textcoords="offset points", fontsize=8, color="0.3", va="top")
    machine = _silhouette(ax, system, q, direction, polygons)
    ax.fill([], [], facecolor="0.62", edgecolor="0.2", label=f"machine ({pose})")
    ax.set(xlim=(left, right), ylim=(bottom, top), aspect="equal", xlabel="horizontal distance from the swing axis [m]",
           ylabel="height above ground [m]")  # fmt: skip
    ax.set_xticks(np.arange(np.ceil(left), right, 1.0))
    ax.set_yticks(np.arange(np.ceil(bottom), top, 1.0))
    ax.grid(True, alpha=0.25)
    spec = envelope.spec
    ax.set_title(f"working range of {spec.point.body}.{spec.point.name}: {len(set(boundary.curve.tolist()))} curves with inputs at limits or folds, "
                 f"{len(boundary.switching)} switching points", fontsize=10)  # fmt: skip
    offsets = _offsets(marks)
    lines = [_dimension(ax, mark, offset) for mark, offset in zip(marks, offsets)]
    for mark, offset in zip(marks, offsets):  # the published figure on the same line, where it differs
        published = spec.published.get(mark.figure)
        if published is not None and abs(published - mark.value) > DIFFERS:
            at = (published, _level(mark)) if mark.kind == "h" else (mark.reach + offset, np.sign(mark.height) * published)
            ax.plot(*at, marker="D", ms=5, mfc="none", mec="0.25", mew=1.1, ls="none", zorder=6, gid=f"published:{mark.letter}")
    if any(a.get_gid() and a.get_gid().startswith("published:") for a in ax.lines):
        ax.plot([], [], marker="D", ms=5, mfc="none", mec="0.25", ls="none", label=f"published figure, where it differs by more than {DIFFERS:g} m")
    fig.tight_layout()  # the labels are placed at the size they are drawn
    _place_labels(fig, ax, marks, lines, [ax.lines[0], *machine])
    side.axis("off")
    rows = [["", "figure", "kinegen", "published"]]
    for mark in marks:
        published = spec.published.get(mark.figure)
        rows.append([mark.letter, TITLES[mark.figure], f"{mark.value:.3f} m", "-" if published is None else f"{published:.2f} m*"])
    height = 0.045 * len(rows)
    table = side.table(cellText=rows, cellLoc="left", colWidths=[0.06, 0.6, 0.17, 0.17], bbox=[0.0, 1.0 - height, 1.0, height])
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    handles, labels = ax.get_legend_handles_labels()
    side.legend(handles, labels, loc="upper left", bbox_to_anchor=(0.0, 0.97 - height), fontsize=8, frameon=False)
    notes = [
        "* as quoted, unverified",
        f"boundary: {len(boundary.points) - 1} exact points, chord error {1e3 * boundary.chord_error:.3f} mm",
        "inputs: " + ", ".join(f"{n} [{lo:g}, {hi:g}]" for n, (lo, hi) in zip(envelope.names, _ranges(system, envelope))),
        *(["machine outline: the model's drawing (outline:) where it has one, else the hull of a body's points"] if drawn else []),
        *boundary.notes,
    ]
    side.text(0.0, 0.78 - height, "\n".join(_wrap(line, 60) for line in notes), fontsize=8, va="top", transform=side.transAxes)
    return fig


def plot_working_range(envelope: Envelope, boundary: Boundary, system: NumericSystem, path: str | Path, direction: np.ndarray | None = None,
                       drawn: dict[str, np.ndarray] | None = None) -> Path:  # fmt: skip
    """The chart (:func:`working_range_figure`) as a PNG."""
    from kinegen.figures import save

    return save(working_range_figure(envelope, boundary, system, direction, drawn), path)


def _ranges(system: NumericSystem, envelope: Envelope) -> list[tuple[float, float]]:
    return RangeEvaluator(system, envelope.spec).ranges


def _wrap(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width)) or text


#: a published figure further than this (m) from kinegen's is drawn on its dimension line too
DIFFERS = 0.05
#: vertical dimension lines closer than this (m) are drawn apart: the later one moved by :data:`APART`
CLOSE = 0.45
APART = 0.6


def _offsets(marks: list[Mark]) -> list[float]:
    """How far (m, along the reach) each vertical dimension line is drawn from its point: 0, or
    :data:`APART` beyond the last line drawn within :data:`CLOSE` of it (max. digging depth and the
    vertical wall depth often sit at nearly one reach: their lines would lie on each other)."""
    drawn: list[float] = []
    out = []
    for mark in marks:
        offset = 0.0
        if mark.kind == "v":
            while any(abs(mark.reach + offset - x) < CLOSE for x in drawn):
                offset += APART
            drawn.append(mark.reach + offset)
        out.append(offset)
    return out


def _level(mark: Mark) -> float:
    """Where a horizontal dimension line is drawn: at its point's height, or :data:`BELOW_GROUND`
    below the ground when its point is near it (off the ground band)."""
    return -BELOW_GROUND if abs(mark.height) < BELOW_GROUND else mark.height


def _dimension(ax, mark: Mark, offset: float = 0.0):
    """A dimension line with arrows at both ends between the swing axis (h) or the ground (v) and
    the figure's point, with an extension line where it is drawn off that point (a horizontal one
    near the ground goes :data:`BELOW_GROUND` below it, off the ground band; a vertical one ``offset``
    along the reach, off another's); the line (Line2D)."""
    style = {"arrowstyle": "<|-|>", "color": "0.15", "lw": 0.8, "shrinkA": 0, "shrinkB": 0, "mutation_scale": 8}
    ax.plot([mark.reach], [mark.height], "o", ms=5, mfc="white", mec="crimson", mew=1.4, zorder=6)
    if mark.kind == "h":
        level = _level(mark)
        ends = np.array([[0.0, level], [mark.value, level]])
        if level != mark.height:
            ax.plot([mark.reach, mark.reach], [mark.height, level - 0.1], color="0.15", lw=0.5, zorder=5)
            ax.plot([0.0, 0.0], [0.0, level - 0.1], color="0.15", lw=0.5, zorder=5)
    else:
        x = mark.reach + offset
        ends = np.array([[x, 0.0], [x, np.sign(mark.height) * mark.value]])
        if offset:
            ax.plot([mark.reach, x + 0.1 * np.sign(offset)], [mark.height, mark.height], color="0.15", lw=0.5, zorder=5)
    ax.annotate("", xy=tuple(ends[0]), xytext=tuple(ends[1]), arrowprops=style, zorder=5)
    (line,) = ax.plot(ends[:, 0], ends[:, 1], lw=0, gid=f"dimension:{mark.letter}")  # the geometry, for tests and placement
    return line


def _place_labels(fig, ax, marks: list[Mark], lines: list, obstacles: list) -> None:
    """Each figure's letter beside its dimension line, at the first place along it (middle first)
    where it overlaps no other label, no dimension line, the boundary and no part of the machine."""
    from matplotlib.patches import Patch

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    paths = []
    for artist in [*obstacles, *lines]:
        transform = artist.get_transform()
        filled = isinstance(artist, Patch)
        paths.append((artist, transform.transform_path(artist.get_path()), filled))
    placed = []
    for mark, line in zip(marks, lines):
        ends = np.column_stack(line.get_data())
        text = ax.annotate(mark.letter, (0.0, 0.0), xytext=(0, 0), textcoords="offset points", fontsize=10, fontweight="bold",
                           color="crimson", zorder=6, gid=f"label:{mark.letter}")  # fmt: skip
        horizontal = mark.kind == "h"
        for fraction in (0.5, 0.4, 0.6, 0.3, 0.7, 0.2, 0.8, 0.12, 0.88):
            for side in (1, -1):
                text.xy = tuple(ends[0] + fraction * (ends[1] - ends[0]))
                text.set_position((0, 3 * side) if horizontal else (4 * side, 0))
                text.set_ha("center" if horizontal else ("left" if side > 0 else "right"))
                text.set_va(("bottom" if side > 0 else "top") if horizontal else "center")
                box = text.get_window_extent(renderer).expanded(1.15, 1.15)
                clear = not any(box.overlaps(other) for other in placed) and not any(
                    path.intersects_bbox(box, filled=filled) for artist, path, filled in paths if artist is not line
                )
                if clear:
                    break
            else:
                continue
            break
        placed.append(text.get_window_extent(renderer))


def plot_envelope(envelope: Envelope, system: NumericSystem, path: str | Path, boundary=None, drawn: dict[str, np.ndarray] | None = None) -> Path:
    """The working-range chart (:func:`plot_working_range`) with the exact boundary (computed here
    unless given: :func:`kinegen.analysis.boundary.working_range_boundary`) and the model's
    drawings ``drawn`` (:func:`outlines`)."""
    from kinegen.analysis.boundary import working_range_boundary

    boundary = boundary if boundary is not None else working_range_boundary(system, envelope.spec)
    return plot_working_range(envelope, boundary, system, path, boundary.direction, drawn)
