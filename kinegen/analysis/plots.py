"""PNG plots of solve results (matplotlib, non-interactive backend)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinegen.runtime.results import Results


def plot_results(results: Results, path: str | Path) -> Path:
    """Paths of every named point (top view x-y and side view x-z) and |omega| of every body."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
