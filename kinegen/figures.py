"""Figure files: matplotlib on its non-interactive backend, and a figure written all or nothing.
Below both kinegen.analysis and kinegen.forces, which draw with it."""

from __future__ import annotations

import io
from pathlib import Path

from kinegen.files import write_atomic


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
    image = io.BytesIO()
    try:
        fig.savefig(image, dpi=dpi, format=image_format(path))
    finally:
        pyplot().close(fig)
    write_atomic(path, image.getvalue())  # all or nothing; a full disk is an error, the previous file kept
    return path


def legend_beside(ax, **style) -> None:
    """The axes' legend to the right of them, top-aligned: it covers none of their data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **style)


def image_format(path: str | Path) -> str:
    """The image format a file name asks for (its suffix; PNG without one), ValueError if
    matplotlib cannot write it."""
    from matplotlib.backend_bases import FigureCanvasBase

    suffix = Path(path).suffix.lower().lstrip(".") or "png"
    supported = FigureCanvasBase.get_supported_filetypes()
    if suffix not in supported:
        raise ValueError(f"{Path(path).name!r}: cannot write an image of type {suffix!r} (one of {', '.join(sorted(supported))})")
    return suffix
