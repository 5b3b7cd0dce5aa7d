"""``kinegen view``: a solved motion in 3-D, as one self-contained HTML file.

Plotly draws it (its JavaScript, ~4.7 MB, is written into the file: the page opens with no
network). Plotly rather than three.js because its Python package carries the library, and
because its 3-D scenes come with orbit, zoom and pan by mouse, and its animation frames with a
time slider and play/pause, with no JavaScript of ours to keep.

What the page shows, frame by frame (at most :data:`MAX_FRAMES` of the solved time points):

* each body as a stick figure through its named points (a closed outline around them in the
  body's own plane; a segment for two points), the ground's points as grey markers;
* the joints as black diamonds (each joint's point on its first body);
* each actuator as barrel + rod: the barrel from the base as long as the retracted length, the
  rod back from the eye as long as the stroke -- red at a frame where it is out of its range;
* the tracked point's whole path, and where it is now;
* the time, every actuator's length and the Jacobian's condition number in the title, the
  bodies drawn orange where the condition exceeds ``condition_warning``.

Conventions: global frame, metres, z up; the camera looks along the direction in which the
mechanism moves least (the normal of its points' best-fit plane), from slightly above.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinegen.model.schema import GROUND, Model, design_value
from kinegen.runtime import kinematics
from kinegen.runtime.results import Results

#: frames written at most (a 341-point case is thinned to every second point, ...)
MAX_FRAMES = 180
#: default: warn where cond(Phi_q) exceeds this
CONDITION_WARNING = 1e6

#: the tracked point's marker (a colour used nowhere else: the browser test finds it by it)
TRACKED = "#e020e0"
_BODY = "#1f77b4"
_WARN = "#ff7f0e"
_BARREL, _ROD, _OUT = "#555555", "#bbbbbb", "#d62728"


def _outline(points: np.ndarray) -> list[int]:
    """Indices of ``points`` (m, 3) in order around their centroid in their best-fit plane, closed."""
    m = len(points)
    if m <= 2:
        return list(range(m))
    centred = points - points.mean(axis=0)
    _, _, axes = np.linalg.svd(centred)
    angles = np.arctan2(centred @ axes[1], centred @ axes[0])
    order = list(np.argsort(angles))
    return [*order, order[0]]


def frames(results: Results, most: int) -> tuple[np.ndarray, np.ndarray]:
    """The solved time points, and at most ``most`` of them evenly taken (the first included)."""
    solved = np.flatnonzero(results.converged)
    return solved, solved[:: max(1, -(-len(solved) // most))]


def cylinder(base: np.ndarray, eye: np.ndarray, limits: tuple[float, float] | None) -> tuple[np.ndarray, np.ndarray]:
    """An actuator drawn as a hydraulic cylinder: the barrel from the base as long as the retracted
    length, the rod back from the eye as long as the stroke (halves without a range), each (2, dim)."""
    length = float(np.linalg.norm(eye - base))
    direction = (eye - base) / max(length, 1e-12)
    barrel_length = limits[0] if limits else 0.5 * length
    rod_length = (limits[1] - limits[0]) if limits else 0.5 * length
    return (np.array([base, base + direction * min(barrel_length, length)]),
            np.array([eye - direction * min(rod_length, length), eye]))  # fmt: skip


def _segments(polylines: list[np.ndarray]) -> np.ndarray:
    """Polylines joined into one trace's coordinates, separated by NaN (Plotly breaks lines there)."""
    parts = []
    for line in polylines:
        parts.append(line)
        parts.append(np.full((1, 3), np.nan))
    return np.vstack(parts) if parts else np.zeros((0, 3))


class _Scene:
    """Every drawn coordinate at every time point, computed once."""

    def __init__(self, results: Results, model: Model, track: tuple[str, str] | None, condition_warning: float) -> None:
        system = results.system
        self.results, self.times = results, results.times
        self.bodies = {body: list(points) for body, points in system.points.items() if body != GROUND and points}
        self.positions = {(b, p): kinematics.point_position(results, b, p) for b, names in self.bodies.items() for p in names}
        self.outlines = {b: _outline(np.array([system.points[b][p] for p in names], dtype=float)) for b, names in self.bodies.items()}
        self.ground = np.array(list(system.ground_points.values()), dtype=float).reshape(-1, 3)
        self.joints = [self._joint_point(results, j.body1, [design_value(x, system.design) for x in j.point1])
                       for j in model.joints if j.point1 is not None]  # fmt: skip
        self.couplers = [(self._joint_point(results, j.body1, [design_value(x, system.design) for x in j.point1]),
                          self._joint_point(results, j.body2, [design_value(x, system.design) for x in j.point2]))
                         for j in model.joints if j.type == "distance"]  # fmt: skip
        self.actuators = {name: (refs, limits) for name, (*refs, limits) in system.actuators.items()}
        self.lengths = {name: kinematics.actuator_length(results, name) for name in self.actuators}
        self.track = track
        self.path = kinematics.point_position(results, *track) if track else None
        self.conditions = kinematics.condition_numbers(results)  # kinegen's condition number: the CSV's and the plot's
        self.warn = np.isfinite(self.conditions) & (self.conditions > condition_warning)

    @staticmethod
    def _joint_point(results: Results, body: str, local) -> np.ndarray:
        local = np.array(local, dtype=float)
        if body == GROUND:
            return np.tile(local, (len(results.times), 1))
        return kinematics.position(results, body) + np.einsum("kij,j->ki", kinematics.rotation_matrix(results, body), local)

    def out_of_range(self, name: str, k: int) -> bool:
        limits = self.actuators[name][1]
        return limits is not None and not limits[0] - 1e-9 <= self.lengths[name][k] <= limits[1] + 1e-9

    def traces(self, k: int) -> list:
        """The frame's moving traces (plotly's scatter3d traces as plain dicts: a page's ~100 frames of them
        are written unvalidated), in a fixed order: bodies, joints, the couplers of distance joints (if any),
        each actuator's barrel and rod, the tracked point."""
        out = []
        lines = [np.array([self.positions[b, names[i]][k] for i in self.outlines[b]]) for b, names in self.bodies.items()]
        xyz = _segments(lines)
        colour = _WARN if self.warn[k] else _BODY
        out.append(_scatter3d(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2], mode="lines+markers", line={"color": colour, "width": 5},
                                marker={"size": 2.5, "color": colour}, name="bodies", hoverinfo="skip"))  # fmt: skip
        joints = np.array([j[k] for j in self.joints]).reshape(-1, 3)
        out.append(_scatter3d(x=joints[:, 0], y=joints[:, 1], z=joints[:, 2], mode="markers", name="joints",
                                marker={"symbol": "diamond", "size": 4, "color": "black"}, hoverinfo="skip"))  # fmt: skip
        if self.couplers:  # the distance joints' couplers: lines no body carries
            xyz = _segments([np.array([one[k], other[k]]) for one, other in self.couplers])
            out.append(_scatter3d(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2], mode="lines", name="couplers (distance joints)",
                                    line={"color": _BODY, "width": 3}, hoverinfo="skip"))  # fmt: skip
        for name, ((b1, p1), (b2, p2)), in ((n, refs) for n, (refs, _) in self.actuators.items()):
            base, eye = kinematics.point_position(self.results, b1, p1)[k], kinematics.point_position(self.results, b2, p2)[k]
            barrel, rod = self._cylinder(name, base, eye)
            out_of_range = self.out_of_range(name, k)
            for part, colour, width, label in ((barrel, _BARREL, 10, "barrel"), (rod, _ROD, 5, "rod")):
                out.append(_scatter3d(x=part[:, 0], y=part[:, 1], z=part[:, 2], mode="lines", name=f"{name} {label}",
                                        line={"color": _OUT if out_of_range else colour, "width": width}, showlegend=False,
                                        hovertext=f"{name}: {self.lengths[name][k]:.4f} m", hoverinfo="text"))  # fmt: skip
        if self.path is not None:
            here = self.path[k]
            out.append(_scatter3d(x=[here[0]], y=[here[1]], z=[here[2]], mode="markers", name=f"{self.track[0]}.{self.track[1]}",
                                    marker={"size": 6, "color": TRACKED}))  # fmt: skip
        return out

    def _cylinder(self, name: str, base: np.ndarray, eye: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return cylinder(base, eye, self.actuators[name][1])

    def title(self, k: int) -> str:
        lengths = ", ".join(
            f"{n} {self.lengths[n][k]:.3f} m" + (" OUT OF RANGE" if self.out_of_range(n, k) else "") for n in self.actuators
        )
        condition = f"cond(Φ_q) {self.conditions[k]:.3g}" + (" HIGH" if self.warn[k] else "") if np.isfinite(self.conditions[k]) else ""
        return f"t = {self.times[k]:.3f} s   {condition}<br><sub>{lengths}</sub>"


def _scatter3d(**trace) -> dict:
    """A plotly scatter3d trace as a plain dict (its arrays as lists of floats)."""
    return {"type": "scatter3d", **{k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in trace.items()}}


def motion_view(
    results: Results,
    model: Model,
    path: str | Path,
    title: str = "",
    track: tuple[str, str] | None = None,
    condition_warning: float = CONDITION_WARNING,
) -> Path:
    """Write the solved motion as a self-contained HTML page (see the module docstring).
    ``track``: (body, point) whose path is drawn (default: :func:`kinegen.analysis.plots.tracked_point`)."""
    import plotly.graph_objects as go
    import plotly.io as pio

    if track is None:
        from kinegen.analysis.plots import tracked_point

        track = tracked_point(results, model)
    scene = _Scene(results, model, track, condition_warning)
    solved, keep = frames(results, MAX_FRAMES)
    static = []
    if len(scene.ground):
        static.append(go.Scatter3d(x=scene.ground[:, 0], y=scene.ground[:, 1], z=scene.ground[:, 2], mode="markers", name="ground points",
                                   marker={"size": 4, "color": "grey", "symbol": "square"}))  # fmt: skip
    if scene.path is not None:
        p = scene.path[solved]
        static.append(go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="lines", name=f"path of {track[0]}.{track[1]}",
                                   line={"color": "#2ca02c", "width": 2, "dash": "dot"}))  # fmt: skip
    first = scene.traces(int(keep[0]))
    moving = list(range(len(static), len(static) + len(first)))
    animation = [{"data": scene.traces(int(k)), "traces": moving, "name": str(i), "layout": {"title": {"text": f"{title}   {scene.title(int(k))}"}}}
              for i, k in enumerate(keep)]  # fmt: skip
    everything = np.vstack([*(scene.positions.values()), scene.ground] + ([scene.path] if scene.path is not None else []))
    everything = everything[np.isfinite(everything).all(axis=1)]
    low, high = everything.min(axis=0), everything.max(axis=0)
    largest = float(np.max(high - low) or 1.0)
    centre, half = (low + high) / 2, np.maximum(high - low, 0.25 * largest) / 2 + 0.05 * largest  # no axis squashed flat
    low, high = centre - half, centre + half
    # the camera looks along the direction in which the mechanism moves least (its plane's normal), from slightly above
    _, _, axes = np.linalg.svd(everything - everything.mean(axis=0), full_matrices=False)
    normal = axes[2] if axes[2][1] <= 0 else -axes[2]
    eye = 2.0 * normal + np.array([0.3, 0.0, 0.6])
    jump = {"frame": {"duration": 0, "redraw": True}, "mode": "immediate", "transition": {"duration": 0}}
    steps = [{"label": f"{results.times[k]:.2f} s", "method": "animate", "args": [[str(i)], jump]} for i, k in enumerate(keep)]
    # the steps' own labels would crowd the slider: hidden, the current one shown above it
    slider = {"active": 0, "currentvalue": {"prefix": "t = ", "font": {"color": "#333"}}, "pad": {"t": 10, "l": 160},
              "font": {"color": "rgba(0,0,0,0)"}, "steps": steps}  # fmt: skip
    play = {
        "type": "buttons",
        "showactive": False,
        "x": 0.0,
        "y": 0.0,
        "xanchor": "left",
        "yanchor": "top",
        "pad": {"t": 25},
        "direction": "left",
        "buttons": [
            {"label": "▶ play", "method": "animate",
             "args": [None, {"frame": {"duration": 40, "redraw": True}, "fromcurrent": True, "transition": {"duration": 0}}]},
            {"label": "❚❚ pause", "method": "animate",
             "args": [[None], {"frame": {"duration": 0, "redraw": False}, "mode": "immediate", "transition": {"duration": 0}}]},
        ],
    }  # fmt: skip
    figure = go.Figure(
        data=static + first,
        layout=go.Layout(
            title={"text": f"{title}   {scene.title(int(keep[0]))}"},
            scene={
                "aspectmode": "data",
                "xaxis": {"title": "x [m]", "range": [low[0], high[0]]},
                "yaxis": {"title": "y [m]", "range": [low[1], high[1]]},
                "zaxis": {"title": "z [m]", "range": [low[2], high[2]]},
                "camera": {"eye": dict(zip("xyz", eye.tolist())), "up": {"x": 0, "y": 0, "z": 1}},
            },
            updatemenus=[play],
            sliders=[slider],
            margin={"l": 0, "r": 0, "t": 70, "b": 0},
            legend={"x": 0.0, "y": 1.0},
        ),
    )
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    # the frames as they are: plotly validating them took about half the page's time (5,669 traces for the excavator)
    html = pio.to_html({**figure.to_dict(), "frames": animation}, validate=False, include_plotlyjs=True, full_html=True,
                       auto_play=False, div_id="kinegen-view", post_script=_POST_SCRIPT)  # fmt: skip
    from kinegen.files import write_atomic

    write_atomic(target, html)
    return target


#: After the plot is drawn: go to the frame named in the address (``view.html#frame=12``: for
#: tests and links) and mark the page ready; any error is written into the page.
_POST_SCRIPT = """
window.addEventListener('error', function (e) { document.body.setAttribute('data-kinegen-error', String(e.message)); });
(function () {
  var gd = document.getElementById('{plot_id}');
  var match = /frame=(\\d+)/.exec(window.location.hash);
  var done = function () { document.body.setAttribute('data-kinegen', 'ready'); };
  if (match) {
    Plotly.animate(gd, [match[1]], {frame: {duration: 0, redraw: true}, mode: 'immediate', transition: {duration: 0}}).then(done);
  } else { done(); }
})();
"""
