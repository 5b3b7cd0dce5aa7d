"""kinegen view in a real browser: the page opened in headless Chromium (Debian's chromium
package), no JavaScript error, and screenshots at two frames of the bucket stroke that differ
where the bucket moved and agree elsewhere."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kinegen.analysis.view import TRACKED
from kinegen.cli import main
from tests.conftest import MODELS

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: the file's tests in one test process (make test distributes with --dist loadgroup): the page and its animation, drawn once
pytestmark = [
    pytest.mark.skipif(CHROMIUM is None, reason="no chromium on this machine (Debian: apt-get install chromium; .ci/run installs it)"),
    pytest.mark.xdist_group(name="view"),
]
#: headless, software WebGL, no network use of its own (this machine's network is closed)
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--hide-scrollbars",
         "--window-size=1100,800", "--virtual-time-budget=20000"]  # fmt: skip
PLOT_ROWS = slice(100, 590)  # below the title, above the slider


@pytest.fixture(scope="module")
def page(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("view") / "bucket_stroke.html"
    gif = out.with_suffix(".gif")
    result = CliRunner().invoke(main, ["view", str(MODELS / "excavator.yaml"), "--case", "bucket_stroke", "--out", str(out),
                                       "--animate", str(gif), "--frame", "upper"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert gif.stat().st_size > 10_000
    return out


def browse(page: Path, frame: int, profile: Path, *options: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *options, f"{page.as_uri()}#frame={frame}"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip


def test_the_page_is_self_contained_and_runs_without_javascript_errors(page: Path, tmp_path: Path) -> None:
    html = page.read_text(encoding="utf-8")
    assert not re.search(r"<script[^>]+src=", html), "the page fetches a script"
    assert "plotly" in html.lower() and len(html) > 3_000_000  # the library is in the file
    done = browse(page, 50, tmp_path / "profile", "--dump-dom", "--enable-logging=stderr", "--v=0")
    assert done.returncode == 0, done.stderr[-2000:]
    body = re.search(r"<body[^>]*>", done.stdout).group(0)
    assert 'data-kinegen="ready"' in body  # the script after the plot ran to its end, frame 50 shown
    assert "data-kinegen-error" not in body
    console = [line for line in done.stderr.splitlines() if "CONSOLE" in line]
    assert not [line for line in console if re.search(r"error|uncaught", line, re.IGNORECASE)], console


def _screenshot(page: Path, frame: int, folder: Path) -> np.ndarray:
    import matplotlib.image

    shot = folder / f"frame{frame}.png"
    done = browse(page, frame, folder / f"profile{frame}", f"--screenshot={shot}")
    assert done.returncode == 0 and shot.exists(), done.stderr[-2000:]
    return matplotlib.image.imread(shot)[..., :3]


def _marker(image: np.ndarray) -> np.ndarray:
    """(row, column) of the tracked point's marker (its colour, outside the legend)."""
    colour = np.array([int(TRACKED[i : i + 2], 16) for i in (1, 3, 5)]) / 255
    found = np.abs(image - colour).max(axis=2) < 0.08
    found[:190, :150] = False  # the legend's sample of it
    rows, columns = np.nonzero(found)
    assert len(rows) > 10, "the tracked point's marker is not drawn"
    return np.array([rows.mean(), columns.mean()])


def test_two_frames_differ_where_the_bucket_moved_and_agree_elsewhere(page: Path, tmp_path: Path) -> None:
    """bucket_stroke moves only the bucket cylinder's rod, the links and the bucket: between its
    first and last frame the pixels change around the bucket tip's two positions, and nowhere
    far from them (the upper structure, the boom and its cylinders, drawn, are the same)."""
    first, last = _screenshot(page, 0, tmp_path), _screenshot(page, 100, tmp_path)
    assert first.shape == last.shape == (800, 1100, 3)
    changed = np.abs(first - last).max(axis=2) > 0.02
    changed[: PLOT_ROWS.start], changed[PLOT_ROWS.stop :] = False, False  # the title and slider say the time: not the scene
    tip_first, tip_last = _marker(first), _marker(last)
    assert np.linalg.norm(tip_first - tip_last) > 20  # the bucket tip moved on the screen
    rows, columns = np.nonzero(changed)
    assert len(rows) > 500
    for tip in (tip_first, tip_last):  # the picture changed where the tip was and where it is
        near = (np.abs(rows - tip[0]) < 15) & (np.abs(columns - tip[1]) < 15)
        assert near.sum() > 20
    reach = 0.35 * first.shape[1]
    low, high = np.minimum(tip_first, tip_last) - reach, np.maximum(tip_first, tip_last) + reach
    far = np.ones(changed.shape, dtype=bool)
    far[int(max(low[0], 0)) : int(high[0]), int(max(low[1], 0)) : int(high[1])] = False
    far[: PLOT_ROWS.start], far[PLOT_ROWS.stop :] = False, False
    assert not (changed & far).any()  # nothing changed far from the bucket
    blue = np.abs(first - np.array([0x1F, 0x77, 0xB4]) / 255).max(axis=2) < 0.08
    assert (blue & far).sum() > 200  # ... where the mechanism is drawn (the upper structure and the boom)
