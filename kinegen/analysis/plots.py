"""PNG plots of solve results (matplotlib, non-interactive backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinegen.runtime.results import Results


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path: str | Path, dpi: int = 100) -> Path:
    """Lay out, write (creating the folder) and close a figure."""
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    pyplot().close(fig)
    return path


def plot_results(results: Results, path: str | Path) -> Path:
    """Paths of every named point (top view x-y and side view x-z) and |omega| of every body."""
    plt = pyplot()
    fig, (top, side, rates) = plt.subplots(1, 3, figsize=(15, 4.8))
    for body, points in results.system.points.items():
        for point in points:
            p = results.point_position(body, point)
            top.plot(p[:, 0], p[:, 1], label=f"{body}.{point}")
            side.plot(p[:, 0], p[:, 2], label=f"{body}.{point}")
        rates.plot(results.times, np.linalg.norm(results.omega(body), axis=1), label=body)
    top.set(title="point paths, top view", xlabel="x [m]", ylabel="y [m]", aspect="equal")
    side.set(title="point paths, side view", xlabel="x [m]", ylabel="z [m]", aspect="equal")
    rates.set(title="angular speed |omega|", xlabel="t [s]", ylabel="rad/s")
    for ax in (top, side, rates):
        ax.grid(True, alpha=0.3)
    top.legend(fontsize=7)
    rates.legend(fontsize=7)
    system = results.system
    fig.suptitle(f"{system.model} / {system.case} [{system.parametrization.name}]")
    return save(fig, path, dpi=110)


def _in_frame(results: Results, frame_body: str | None, points: np.ndarray) -> np.ndarray:
    """Global points (K, 3) expressed in ``frame_body``'s frame (K, 3); global if None."""
    if frame_body is None:
        return points
    rotation = results.rotation_matrix(frame_body)
    return np.einsum("kji,kj->ki", rotation, points - results.position(frame_body))


def plot_case(
    results: Results, path: str | Path, frame_body: str | None = None, trace: tuple[str, str] | None = None, snapshots: int = 6
) -> Path:
    """One PNG per case: the mechanism in a body's x-z plane at several instants with the
    traced point's path, actuator lengths against their ranges, their rates, and the
    Jacobian's condition number against time."""
    plt = pyplot()
    system = results.system
    fig = plt.figure(figsize=(15, 9))
    grid = fig.add_gridspec(3, 2, width_ratios=[1.35, 1])
    drawing = fig.add_subplot(grid[:, 0])
    lengths, rates, condition = (fig.add_subplot(grid[i, 1]) for i in range(3))
    instants = np.linspace(0, len(results.times) - 1, snapshots).round().astype(int)
    colours = plt.cm.viridis(np.linspace(0, 0.9, snapshots))
    for colour, k in zip(colours, instants):
        for body, points in system.points.items():
            if len(points) < 2:
                continue
            xyz = np.array([_in_frame(results, frame_body, results.point_position(body, p))[k] for p in points])
            closed = np.vstack([xyz, xyz[:1]]) if len(points) > 2 else xyz
            drawing.plot(closed[:, 0], closed[:, 2], "-o", color=colour, lw=1.6, ms=2.5)
        for (b1, p1), (b2, p2), _ in system.actuators.values():
            ends = np.array([_in_frame(results, frame_body, results.point_position(b, p))[k] for b, p in ((b1, p1), (b2, p2))])
            drawing.plot(ends[:, 0], ends[:, 2], "-", color=colour, lw=4, alpha=0.45, solid_capstyle="round")
        drawing.annotate(
            f"t={results.times[k]:.1f}s",
            xy=(0.02, 0.97 - 0.035 * list(instants).index(k)),
            xycoords="axes fraction",
            color=colour,
            fontsize=8,
            va="top",
        )
    if trace:
        tip = _in_frame(results, frame_body, results.point_position(*trace))
        drawing.plot(tip[:, 0], tip[:, 2], "r-", lw=1.2, label=f"path of {trace[0]}.{trace[1]}")
        drawing.legend(loc="lower left", fontsize=8)
    drawing.axhline(0, color="saddlebrown", lw=0.8)
    plane = f"{frame_body} frame" if frame_body else "global frame"
    drawing.set(title=f"mechanism in the x-z plane of the {plane}", xlabel="x [m]", ylabel="z [m]", aspect="equal")
    for name, (_, _, limits) in system.actuators.items():
        line = lengths.plot(results.times, results.actuator_length(name), label=name)[0]
        if limits:
            for value in limits:
                lengths.axhline(value, color=line.get_color(), ls=":", lw=0.8)
        rates.plot(results.times, results.actuator_rate(name), label=name)
    lengths.set(title="actuator lengths (dotted: range)", ylabel="m")
    rates.set(title="extension rates", ylabel="m/s")
    condition.semilogy(results.times, results.conditions, "k-")
    kind = {"exact": "2-norm", "estimate": "1-norm estimate"}.get(results.condition_kind, "not recorded")
    condition.set(title=f"condition number of Phi_q ({kind})", xlabel="t [s]")
    for ax in (drawing, lengths, rates, condition):
        ax.grid(True, alpha=0.3)
    if system.actuators:
        lengths.legend(fontsize=7)
    fig.suptitle(f"{system.model} / {system.case} [{system.parametrization.name}]")
    return save(fig, path)
