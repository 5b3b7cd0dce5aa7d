"""What a command costs before it starts (issue 39): ``kinegen --help``, ``kinegen models`` and
``kinegen info`` on the excavator (its first description, then the cached one), each the median of
fresh processes' wall times, beside Python's own start-up (``python -c pass``) in the same run."""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
COMMANDS = {
    "python -c pass": [sys.executable, "-c", "pass"],
    "kinegen --help": [sys.executable, "-m", "kinegen.cli", "--help"],
    "kinegen models": [sys.executable, "-m", "kinegen.cli", "models"],
    "kinegen info (cached)": [sys.executable, "-m", "kinegen.cli", "info", str(ROOT / "models" / "excavator.yaml")],
}


def _seconds(command: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run(command, env=env, check=True, capture_output=True, timeout=600)
    return time.perf_counter() - start


def startup_cost(repeats: int = 7) -> dict:
    """Median wall seconds per command (and the first, uncached ``kinegen info``) in a fresh cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, KINEGEN_CACHE=cache)
        out = {"kinegen info (first)": _seconds(COMMANDS["kinegen info (cached)"], env)}
        for name, command in COMMANDS.items():
            out[name] = statistics.median(_seconds(command, env) for _ in range(repeats))
    return out
