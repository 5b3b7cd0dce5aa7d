"""``--animate``: a solved motion as a GIF (or MP4) for slides -- the mechanism's stick figures
in one plane, frame by frame (matplotlib's ``FuncAnimation``).

The plane: the x-z plane of ``frame_body``'s frame when one is named (the excavator's upper
structure: its front then stays in the picture while it swings), else the plane through the
points' two directions of largest spread over the motion (global frame). Metres.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinegen.analysis.plots import _in_frame, pyplot
from kinegen.analysis.view import TRACKED, _outline, frames
from kinegen.files import atomic_path
from kinegen.model.schema import GROUND
from kinegen.runtime.results import Results

#: frames of an animation at most (Pillow writes ~7 a second)
MAX_GIF_FRAMES = 100


def animate(
    results: Results, path: str | Path, frame_body: str | None = None, track: tuple[str, str] | None = None, fps: int = 20
) -> Path:
    """Write the animation to ``path`` (.gif with Pillow; .mp4 needs ffmpeg)."""
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter

    target = Path(path)
    if target.suffix.lower() not in (".gif", ".mp4"):
        raise ValueError(f"{path}: an animation is written as .gif or .mp4")
    system = results.system
    solved, keep = frames(results, MAX_GIF_FRAMES)
    bodies = {b: list(p) for b, p in system.points.items() if b != GROUND and p}
    outlines = {b: _outline(np.array([system.points[b][p] for p in names], dtype=float)) for b, names in bodies.items()}
    world = {(b, p): _in_frame(results, frame_body, results.point_position(b, p)) for b, names in bodies.items() for p in names}
    if frame_body is None:  # the plane of largest spread
        stacked = np.vstack(list(world.values()))
        _, _, axes = np.linalg.svd(stacked - stacked.mean(axis=0), full_matrices=False)
        basis, labels = axes[:2], ("u [m]", "w [m]")
    else:
        basis, labels = np.array([[1.0, 0, 0], [0, 0, 1.0]]), (f"x of {frame_body} [m]", f"z of {frame_body} [m]")
    plane = {key: value @ basis.T for key, value in world.items()}
    path_2d = _in_frame(results, frame_body, results.point_position(*track)) @ basis.T if track else None
    everything = np.vstack(list(plane.values()))
    low, high = everything.min(axis=0), everything.max(axis=0)
    pad = 0.05 * float(np.max(high - low) or 1.0)

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 6))
    ax.set(xlim=(low[0] - pad, high[0] + pad), ylim=(low[1] - pad, high[1] + pad), aspect="equal", xlabel=labels[0], ylabel=labels[1])
    ax.grid(True, alpha=0.3)
    lines = {b: ax.plot([], [], "-o", lw=2, ms=3)[0] for b in bodies}
    if path_2d is not None:
        ax.plot(path_2d[solved, 0], path_2d[solved, 1], ":", color="green", lw=1, label=f"path of {track[0]}.{track[1]}")
        marker = ax.plot([], [], "o", color=TRACKED, ms=7)[0]
        ax.legend(loc="upper right", fontsize=8)
    title = ax.set_title("")

    def draw(k: int):
        for b, names in bodies.items():
            xy = np.array([plane[b, names[i]][k] for i in outlines[b]])
            lines[b].set_data(xy[:, 0], xy[:, 1])
        if path_2d is not None:
            marker.set_data([path_2d[k, 0]], [path_2d[k, 1]])
        title.set_text(f"{system.model} / {system.case}   t = {results.times[k]:.2f} s")
        return [*lines.values(), title]

    movie = FuncAnimation(fig, draw, frames=[int(k) for k in keep], blit=False)
    writer = PillowWriter(fps=fps) if target.suffix.lower() == ".gif" else FFMpegWriter(fps=fps)
    with atomic_path(target) as partial:  # a failed or interrupted write keeps the previous file
        movie.save(str(partial), writer=writer, dpi=80)
    plt.close(fig)
    return target
