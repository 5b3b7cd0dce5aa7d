"""``--animate``: a solved motion as a GIF (or MP4) for slides -- the mechanism's stick figures
in one plane, frame by frame (a GIF: the still parts drawn once, each frame's moving artists over them).

The plane: the x-z plane of ``frame_body``'s frame when one is named (the excavator's upper
structure: its front then stays in the picture while it swings), else the plane through the
points' two directions of largest spread over the motion (global frame). Metres.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinegen.analysis.plots import _in_frame
from kinegen.analysis.view import _BARREL, _BODY, _OUT, _ROD, TRACKED, _outline, cylinder, frames
from kinegen.figures import pyplot
from kinegen.files import atomic_path
from kinegen.model.schema import GROUND
from kinegen.runtime import kinematics
from kinegen.runtime.results import Results

#: frames of an animation at most (Pillow writes ~7 a second)
MAX_GIF_FRAMES = 100


def animate(
    results: Results, path: str | Path, frame_body: str | None = None, track: tuple[str, str] | None = None, fps: int = 20, model=None
) -> Path:
    """Write the animation to ``path`` (.gif with Pillow; .mp4 needs ffmpeg)."""
    target = Path(path)
    if target.suffix.lower() not in (".gif", ".mp4"):
        raise ValueError(f"{path}: an animation is written as .gif or .mp4")
    fig, draw, keep = animation_figure(results, frame_body, track, model)
    with atomic_path(target) as partial:  # a failed or interrupted write keeps the previous file
        if target.suffix.lower() == ".gif":
            _write_gif(fig, draw, keep, partial, fps)
        else:
            from matplotlib.animation import FFMpegWriter

            writer = FFMpegWriter(fps=fps)
            with writer.saving(fig, str(partial), dpi=DPI):
                for k in keep:
                    draw(int(k))
                    writer.grab_frame()
    pyplot().close(fig)
    return target


#: the animation's resolution (dots per inch of the figure's size)
DPI = 80


def _write_gif(fig, draw, keep, path: Path, fps: int) -> None:
    """The frames as a GIF (Pillow), the still parts (axes, grid, labels, legend) drawn once and
    each frame's moving artists drawn over them: matplotlib's own writers draw the whole figure
    for every frame (FuncAnimation.save three times). Each frame is reduced to its own 256 colours
    by Pillow's fast octree (``gif_frame``)."""

    fig.set_dpi(DPI)
    canvas = fig.canvas
    for artist in draw(int(keep[0])):
        artist.set_animated(True)  # left out of the still picture
    canvas.draw()
    still = canvas.copy_from_bbox(fig.bbox)
    frames = []
    for k in keep:
        canvas.restore_region(still)
        for artist in draw(int(k)):
            fig.draw_artist(artist)
        frames.append(gif_frame(np.asarray(canvas.buffer_rgba())))
    frames[0].save(path, format="GIF", save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)


def gif_frame(rgba: np.ndarray):
    """One rendered frame (rows x columns x RGBA, 8 bits) as a GIF's 256-colour picture: Pillow's fast
    octree. Left to the GIF writer, each frame was reduced by median cut: 4.3 of the 11 s of the
    README's ``kinegen view --animate`` (86 frames of 640 x 800), against 1.1 s, and a file of
    1.3 MB against 0.7 MB; each pixel is within 14/255 of its rendered colour (tested), where the
    median cut's were within 40/255."""
    from PIL import Image

    return Image.fromarray(rgba).convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE)


def animation_figure(results: Results, frame_body: str | None = None, track: tuple[str, str] | None = None, model=None):
    """(figure, draw(k) -> the artists of time point k, the time points drawn): bodies as stick
    figures, each actuator as barrel + rod (red where out of its range), the ``model``'s distance
    joints as their couplers, the tracked point's path, a legend in a row below the axes."""
    from matplotlib.lines import Line2D

    from kinegen.analysis.plots import couplers

    system = results.system
    solved, keep = frames(results, MAX_GIF_FRAMES)
    bodies = {b: list(p) for b, p in system.points.items() if b != GROUND and p}
    outlines = {b: _outline(np.array([system.points[b][p] for p in names], dtype=float)) for b, names in bodies.items()}
    world = {(b, p): _in_frame(results, frame_body, kinematics.point_position(results, b, p)) for b, names in bodies.items() for p in names}
    from kinegen.analysis.plots import drawing_plane

    basis, labels, _ = drawing_plane(results, frame_body)  # the case plot's plane, its axes in words
    plane = {key: value @ basis.T for key, value in world.items()}
    path_2d = _in_frame(results, frame_body, kinematics.point_position(results, *track)) @ basis.T if track else None
    actuators = {name: (refs, limits) for name, (*refs, limits) in system.actuators.items()}
    ends = {name: [_in_frame(results, frame_body, kinematics.point_position(results, *ref)) @ basis.T for ref in refs] for name, (refs, _) in actuators.items()}
    lengths = {name: kinematics.actuator_length(results, name) for name in actuators}
    links = {f"{b1}.{p1}-{b2}.{p2}": [_in_frame(results, frame_body, kinematics.point_position(results, *ref)) @ basis.T for ref in ((b1, p1), (b2, p2))]
             for (b1, p1), (b2, p2) in (couplers(model, system) if model is not None else [])}  # fmt: skip
    everything = np.vstack([*plane.values(), *(e for pair in [*ends.values(), *links.values()] for e in pair)])
    low, high = everything.min(axis=0), everything.max(axis=0)
    pad = 0.04 * float(np.max(high - low) or 1.0)
    low, high = low - pad, high + pad

    plt = pyplot()
    width = 8.0  # inches; the height follows the drawing's aspect (equal axes), the legend below it
    fig, ax = plt.subplots(figsize=(width, min(10.0, max(3.0, width * (high[1] - low[1]) / (high[0] - low[0])) + 0.9)))
    ax.set(xlim=(low[0], high[0]), ylim=(low[1], high[1]), aspect="equal", xlabel=labels[0], ylabel=labels[1])
    ax.grid(True, alpha=0.3)
    lines = {b: ax.plot([], [], "-o", color=_BODY, lw=2, ms=3)[0] for b in bodies}
    barrels = {n: ax.plot([], [], "-", color=_BARREL, lw=6, solid_capstyle="butt")[0] for n in actuators}
    rods = {n: ax.plot([], [], "-", color=_ROD, lw=3, solid_capstyle="butt")[0] for n in actuators}
    drawn_links = {n: ax.plot([], [], "-", color=_BODY, lw=1.2, gid=f"coupler:{n}")[0] for n in links}
    handles = [
        Line2D([], [], color=_BODY, marker="o", lw=2, ms=3, label="bodies"),
        *([Line2D([], [], color=_BARREL, lw=6, label="cylinder barrel"), Line2D([], [], color=_ROD, lw=3, label="cylinder rod"),
           Line2D([], [], color=_OUT, lw=4, label="out of its range")] if actuators else []),
    ]  # fmt: skip
    if links:
        handles.append(Line2D([], [], color=_BODY, lw=1.2, label="coupler (distance joint)"))
    if path_2d is not None:
        handles.append(ax.plot(path_2d[solved, 0], path_2d[solved, 1], ":", color="green", lw=1, label=f"path of {track[0]}.{track[1]}")[0])
        marker = ax.plot([], [], "o", color=TRACKED, ms=7)[0]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    title = ax.set_title(f"{system.model} / {system.case}   t = {results.times[0]:.2f} s", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 1))  # the legend's row below the axes, no wide margins

    def draw(k: int):
        for b, names in bodies.items():
            xy = np.array([plane[b, names[i]][k] for i in outlines[b]])
            lines[b].set_data(xy[:, 0], xy[:, 1])
        for name, (base, eye) in ends.items():
            barrel, rod = cylinder(base[k], eye[k], actuators[name][1])
            limits = actuators[name][1]
            out = limits is not None and not limits[0] - 1e-9 <= lengths[name][k] <= limits[1] + 1e-9
            barrels[name].set_data(barrel[:, 0], barrel[:, 1])
            rods[name].set_data(rod[:, 0], rod[:, 1])
            barrels[name].set_color(_OUT if out else _BARREL)
            rods[name].set_color(_OUT if out else _ROD)
        for name, (one, other) in links.items():
            drawn_links[name].set_data([one[k, 0], other[k, 0]], [one[k, 1], other[k, 1]])
        if path_2d is not None:
            marker.set_data([path_2d[k, 0]], [path_2d[k, 1]])
        title.set_text(f"{system.model} / {system.case}   t = {results.times[k]:.2f} s")
        moved = [*lines.values(), *barrels.values(), *rods.values(), *drawn_links.values(), title]
        return moved if path_2d is None else [*moved, marker]

    return fig, draw, keep
