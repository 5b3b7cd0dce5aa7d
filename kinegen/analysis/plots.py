"""PNG plots of solve results (matplotlib, non-interactive backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinegen.figures import legend_beside, pyplot, save
from kinegen.runtime import kinematics
from kinegen.runtime.results import Results


def _in_frame(results: Results, frame_body: str | None, points: np.ndarray) -> np.ndarray:
    """Global points (K, 3) expressed in ``frame_body``'s frame (K, 3); global if None."""
    if frame_body is None:
        return points
    rotation = kinematics.rotation_matrix(results, frame_body)
    return np.einsum("kji,kj->ki", rotation, points - kinematics.position(results, frame_body))


def tracked_point(results: Results, model=None) -> tuple[str, str] | None:
    """The point whose path a picture draws: the model's working-range point when it has one,
    else the named body point farthest from the origin at the start (a tip, usually)."""
    if model is not None and model.working_range is not None:
        return model.working_range.point.body, model.working_range.point.name
    named = [(b, p) for b, points in results.system.points.items() for p in points]
    return max(named, key=lambda ref: float(np.linalg.norm(kinematics.point_position(results, *ref)[0]))) if named else None


def best_frame(results: Results, trace: tuple[str, str] | None) -> str | None:
    """The frame a motion is best drawn in: the global one, or the first body's when the named
    points are flatter there (an excavator's upper structure: the front stays in its x-z plane
    while it swings) and the traced point still moves in it (not a single body turning in place)."""
    system = results.system
    names = [(b, p) for b, points in system.points.items() for p in points]
    if not names or not system.bodies:
        return None

    def flatness(frame: str | None) -> float:
        points = np.vstack([_in_frame(results, frame, kinematics.point_position(results, *ref)) for ref in names])
        points = points[np.isfinite(points).all(axis=1)]
        spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
        return float(spread[2] / spread[0]) if spread[0] > 0 else np.inf

    def moving(frame: str | None) -> float:
        path = _in_frame(results, frame, kinematics.point_position(results, *trace)) if trace else np.zeros((1, 3))
        path = path[np.isfinite(path).all(axis=1)]
        return float(np.ptp(path, axis=0).max()) if len(path) else 0.0

    first = next(iter(system.bodies))
    if moving(first) >= 0.05 * moving(None) and flatness(first) < flatness(None):
        return first
    return None


def drawing_plane(results: Results, frame_body: str | None) -> tuple[np.ndarray, tuple[str, str], str]:
    """The plane a mechanism is drawn in: (2, 3) unit axes, their labels and a description.
    The x-z plane of ``frame_body``'s frame when one is named; else the plane of the two
    directions in which the named points spread most over the motion (global frame) -- two of
    x, y, z when that plane is a coordinate plane (to 1e-6)."""
    if frame_body is not None:
        return (np.array([[1.0, 0, 0], [0, 0, 1.0]]), (f"x along the {frame_body} frame [m]", f"z along the {frame_body} frame [m]"),
                f"the x-z plane of the {frame_body} frame")  # fmt: skip
    points = np.vstack([kinematics.point_position(results, b, p) for b, names in results.system.points.items() for p in names])
    points = points[np.isfinite(points).all(axis=1)]
    _, _, axes = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)
    basis, labels, name = plane_axes(axes[2])
    return basis, labels, f"{name}\n(the plane of largest spread, global frame)"


def plane_axes(normal: np.ndarray) -> tuple[np.ndarray, tuple[str, str], str]:
    """Drawing axes of the plane with unit ``normal`` (global frame), in words: a coordinate plane
    (to 1e-6) is drawn in its two axes (x-y, x-z, y-z); a tilted one along its horizontal line
    (given by its heading from x toward y) and its line of steepest ascent (given by its angle
    from the vertical), so that up on the drawing is up the plane; a horizontal plane in x and
    y. Returns (2, 3) unit axes, their labels and the plane's name."""
    normal = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    k = int(np.argmax(np.abs(normal)))
    if abs(abs(normal[k]) - 1) < 1e-6:  # a coordinate plane: its two axes, in order
        kept = [i for i in range(3) if i != k]
        return (np.eye(3)[kept], (f"{'xyz'[kept[0]]}, global [m]", f"{'xyz'[kept[1]]}, global [m]"),
                f"the {'xyz'[kept[0]]}-{'xyz'[kept[1]]} plane")  # fmt: skip
    up = np.array([0.0, 0.0, 1.0]) - normal[2] * normal
    if np.linalg.norm(up) < 1e-9:
        return np.eye(3)[:2], ("x, global [m]", "y, global [m]"), "the x-y plane"
    up /= np.linalg.norm(up)
    level = np.cross(up, normal)
    if level[0] < 0 or (level[0] == 0 and level[1] < 0):
        level = -level
    heading = np.degrees(np.arctan2(level[1], level[0]))
    tilt = np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0)))
    labels = (f"horizontal, heading {heading:.0f} deg from x toward y [m]",
              f"up the plane, {tilt:.0f} deg from the vertical [m]")  # fmt: skip
    slope = "a vertical plane" if tilt < 0.5 else f"a plane tilted {tilt:.0f} deg from the vertical"
    return np.array([level, up]), labels, f"{slope}, heading {heading:.0f} deg"


def angular_rate(omega: np.ndarray, tolerance: float = 1e-6) -> tuple[np.ndarray, np.ndarray | None]:
    """A body's angular velocities (K, 3) as one curve: signed, omega . n, when they all lie
    along one fixed axis n (to ``tolerance`` of the largest; a planar motion, a hinge), n's
    sign chosen so its largest component is positive; else |omega| (and None)."""
    finite = omega[np.isfinite(omega).all(axis=1)]
    if len(finite) == 0 or not np.abs(finite).max() > 0:
        return np.linalg.norm(omega, axis=1), None
    _, sigma, vt = np.linalg.svd(finite, full_matrices=False)
    if sigma[1] > tolerance * sigma[0]:
        return np.linalg.norm(omega, axis=1), None
    axis = vt[0] * np.sign(vt[0][np.argmax(np.abs(vt[0]))])
    axis = np.where(np.abs(axis) < tolerance, 0.0, axis) + 0.0  # no -0 or 1e-16 in its label
    return omega @ axis, axis


def _readable_log_ticks(ax) -> None:
    """A log axis labelled with plain numbers (300, 400, 1000, 1e+06): every integer multiple of
    a power of ten within one decade, 1-2-5 steps within two, powers of ten beyond."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    low, high = ax.get_ylim()
    decades = np.log10(high / low) if low > 0 else np.inf
    subs = np.arange(1.0, 10.0) if decades < 1 else (1.0, 2.0, 5.0) if decades < 2 else (1.0,)
    ax.yaxis.set_major_locator(LogLocator(subs=subs))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())


def couplers(model, system) -> list[tuple[tuple[str, str], tuple[str, str]]]:
    """The distance joints of ``model`` as the two named points they hold apart (body, point) --
    a coupler drawn as a line, though no body carries it; a joint point that is no named point of
    its body (to 1e-12 at the nominal design) is left out."""
    from kinegen.model.schema import GROUND, design_value

    nominal = {d.name: float(d.nominal) for d in model.design}

    def named(body: str, local) -> tuple[str, str] | None:
        points = system.ground_points if body == GROUND else system.points.get(body, {})
        where = np.array([design_value(x, nominal) for x in local])
        return next(((body, name) for name, at in points.items() if np.abs(np.asarray(at, dtype=float) - where).max() < 1e-12), None)

    out = []
    for joint in model.joints:
        if joint.type == "distance":
            ends = named(joint.body1, joint.point1), named(joint.body2, joint.point2)
            if None not in ends:
                out.append(ends)
    return out


def twins(results: Results) -> dict[str, str]:
    """Actuators whose length follows an earlier one's at every solved time point (to 1e-9 m: the
    excavator's two boom cylinders): name -> the earlier one's. Drawn dashed over it, so both show."""
    out: dict[str, str] = {}
    names = list(results.system.actuators)
    solved = results.converged
    for i, name in enumerate(names):
        mine = kinematics.actuator_length(results, name)[solved]
        for other in names[:i]:
            if other not in out and np.abs(kinematics.actuator_length(results, other)[solved] - mine).max(initial=0.0) < 1e-9:
                out[name] = other
                break
    return out


def plot_case(
    results: Results, path: str | Path, frame_body: str | None = None, trace: tuple[str, str] | None = None, snapshots: int = 6,
    model=None,
) -> Path:  # fmt: skip
    """:func:`case_figure` written to ``path`` (PNG)."""
    return save(case_figure(results, frame_body, trace, snapshots, model), path)


def case_figure(results: Results, frame_body: str | None = None, trace: tuple[str, str] | None = None, snapshots: int = 6, model=None):
    """One figure per case: the mechanism at several instants in the plane that shows it
    (:func:`drawing_plane`) with the traced point's path (and, given the ``model``, its distance
    joints' couplers and, where it draws the ground, the ground line); beside it the actuator lengths
    against their labelled ranges and their rates (twins dashed over the one they follow; without
    actuators, every body's angular speed), and the Jacobian's condition number against time.
    Panels without data are left out."""
    plt = pyplot()
    system = results.system
    basis, labels, plane = drawing_plane(results, frame_body)
    panels = ["lengths", "rates"] if system.actuators else ["omega"]
    if results.converged.any():  # kinematics.condition_numbers(results): the exact 2-norm's, computed here
        panels.append("condition")
    fig = plt.figure(figsize=(15, 9))
    grid = fig.add_gridspec(len(panels), 2, width_ratios=[1.35, 1])
    drawing = fig.add_subplot(grid[:, 0], gid="drawing")
    axes = {name: fig.add_subplot(grid[i, 1], gid=name) for i, name in enumerate(panels)}
    solved = np.flatnonzero(results.converged)
    instants = solved[np.linspace(0, len(solved) - 1, min(snapshots, len(solved))).round().astype(int)]
    following = twins(results)
    links = couplers(model, system) if model is not None else []
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(instants)))

    def projected(body: str, point: str) -> np.ndarray:
        return _in_frame(results, frame_body, kinematics.point_position(results, body, point)) @ basis.T

    for colour, k in zip(colours, instants):
        for body, points in system.points.items():
            xy = np.array([projected(body, p)[k] for p in points])
            closed = np.vstack([xy, xy[:1]]) if len(points) > 2 else xy
            drawing.plot(closed[:, 0], closed[:, 1], "-o", color=colour, lw=1.6, ms=2.5)
        for name, ((b1, p1), (b2, p2), _) in system.actuators.items():
            ends = np.array([projected(b, p)[k] for b, p in ((b1, p1), (b2, p2))])
            if name in following:  # a twin drawn over the one it follows: dashed, narrower, so both show
                drawing.plot(ends[:, 0], ends[:, 1], "--", color="white", lw=1.2, gid=f"twin:{name}")
            else:
                drawing.plot(ends[:, 0], ends[:, 1], "-", color=colour, lw=4, alpha=0.45, solid_capstyle="round", gid=f"actuator:{name}")
        for (b1, p1), (b2, p2) in links:
            ends = np.array([projected(b, p)[k] for b, p in ((b1, p1), (b2, p2))])
            drawing.plot(ends[:, 0], ends[:, 1], "-", color=colour, lw=1.2, gid=f"coupler:{b1}.{p1}-{b2}.{p2}")
        drawing.annotate(f"t={results.times[k]:.2f}s", xy=(0.02, 0.97 - 0.035 * list(instants).index(k)), xycoords="axes fraction",
                         color=colour, fontsize=8, va="top")  # fmt: skip
    if trace:
        tip = projected(*trace)
        drawing.plot(tip[solved, 0], tip[solved, 1], "r-", lw=1.2, label=f"path of {trace[0]}.{trace[1]}", gid="path")
    if model is not None and model.ground_outline and labels[1].startswith("z"):  # the ground where the model draws one
        drawing.axhline(0, color="saddlebrown", lw=0.8, gid="ground")
    path_note = f"; red: the path of {trace[0]}.{trace[1]}" if trace else ""  # in the title: no legend on the drawing
    drawing.set(title=f"mechanism in {plane}{path_note}", xlabel=labels[0], ylabel=labels[1], aspect="equal")
    drawing.margins(0.08)
    few = len(system.actuators) <= 12
    colour_of: dict[str, str] = {}
    ranges: dict[tuple[float, float], list[str]] = {}
    for name, (_, _, limits) in system.actuators.items():
        twin = following.get(name)
        style = {"ls": (0, (4, 3)), "lw": 1.6, "color": "black", "label": f"{name} (= {twin})"} if twin else {"label": name}
        line = axes["lengths"].plot(results.times, kinematics.actuator_length(results, name), **style)[0]
        colour_of[name] = line.get_color()
        axes["rates"].plot(results.times, kinematics.actuator_rate(results, name), **style)
        if limits:
            ranges.setdefault(tuple(limits), []).append(name)
    for k, (limits, names) in enumerate(ranges.items()):  # each range once, labelled; nearby ranges' labels side by side
        for value, end in zip(limits, ("min", "max")):
            axes["lengths"].axhline(value, color=colour_of[names[0]], ls=":", lw=0.8, gid=f"range:{names[0]}:{end}")
            label = f"{end} {names[0]}" + (f" (+{len(names) - 1})" if len(names) > 1 else "")
            axes["lengths"].annotate(label, (0.99 - 0.33 * (k % 3), value), xycoords=("axes fraction", "data"), xytext=(0, 2 if end == "max" else -2),
                                     textcoords="offset points", ha="right", va="bottom" if end == "max" else "top", fontsize=6,
                                     color=colour_of[names[0]], gid=f"range-label:{names[0]}:{end}")  # fmt: skip
    if "lengths" in axes:
        axes["lengths"].set(title="actuator lengths (dotted: their ranges)", ylabel="length [m]")
        axes["rates"].set(title="extension rates", ylabel="extension rate [m/s]")
        if few:  # beside the panel: it covers no curve
            legend_beside(axes["lengths"], fontsize=7)
    if "omega" in axes:
        for body in system.bodies:
            rate, axis = angular_rate(kinematics.omega(results, body))
            about = "|omega| (its axis moves)" if axis is None else "about (" + ", ".join(f"{c:.2g}" for c in axis) + ")"
            axes["omega"].plot(results.times, rate, label=f"{body}, {about}")
        axes["omega"].set(title="angular velocity of each body (signed about a fixed axis)", ylabel="angular velocity [rad/s]")
        if len(system.bodies) <= 12:
            legend_beside(axes["omega"], fontsize=7)
    if "condition" in axes:
        axes["condition"].semilogy(results.times, kinematics.condition_numbers(results), "k-")
        axes["condition"].set(title="condition number of Phi_q: sigma_max / sigma_min (the CSV's)", ylabel="condition number")
        _readable_log_ticks(axes["condition"])
    list(axes.values())[-1].set(xlabel="time t [s]")
    for ax in (drawing, *axes.values()):
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"{system.model} / {system.case} [{system.parametrization.name}]")
    fig.tight_layout()
    return fig


