"""kinegen.exiting: a finished command's process ends with its exit code, its output flushed and its
exit functions run, as Python's own shutdown would end it; where that is not certain, Python exits."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest


def _run(code: str, tmp_path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=60, cwd=tmp_path)


@pytest.mark.parametrize("code, status", [(None, 0), (0, 0), (3, 3), (64, 64)])
def test_output_flushed_exit_functions_run_and_the_code_kept(tmp_path: Path, code: int | None, status: int) -> None:
    done = _run(
        f"""
        import atexit, sys, tempfile, pathlib
        from kinegen.exiting import exit_process
        folder = tempfile.TemporaryDirectory(dir=".")  # its finalizer removes it at exit
        pathlib.Path(folder.name, "inside").write_text("x")
        atexit.register(lambda: pathlib.Path("ran").write_text("atexit"))
        sys.stdout.write("out " * 50_000)  # more than a pipe's buffer, none of it flushed yet
        sys.stderr.write("err")
        exit_process({code!r})
        """,
        tmp_path,
    )
    assert done.returncode == status, done.stderr
    assert done.stdout == "out " * 50_000
    assert done.stderr == "err"
    assert (tmp_path / "ran").read_text() == "atexit"
    assert [p.name for p in tmp_path.iterdir()] == ["ran"]  # the temporary folder removed by its finalizer


def test_a_running_thread_leaves_the_exit_to_python(tmp_path: Path) -> None:
    """A non-daemon thread still working: Python's shutdown waits for it, and so the process does."""
    done = _run(
        """
        import threading, time, pathlib
        from kinegen.exiting import exit_process
        def work():
            time.sleep(0.5)
            pathlib.Path("thread").write_text("finished")
        threading.Thread(target=work).start()
        exit_process(5)
        """,
        tmp_path,
    )
    assert done.returncode == 5, done.stderr
    assert (tmp_path / "thread").read_text() == "finished"


def test_a_message_as_the_code_is_python_s_exit(tmp_path: Path) -> None:
    done = _run("from kinegen.exiting import exit_process\nexit_process('stopped: why')", tmp_path)
    assert done.returncode == 1
    assert done.stderr.strip() == "stopped: why"


def test_the_command_line_exits_through_it(tmp_path: Path) -> None:
    """`python -m kinegen.cli` (as the installed `kinegen`, ``kinegen.cli:run``): its output and codes."""
    listing = subprocess.run([sys.executable, "-m", "kinegen.cli", "models"], capture_output=True, text=True, timeout=120)
    assert listing.returncode == 0 and "four_bar.yaml" in listing.stdout
    missing = subprocess.run([sys.executable, "-m", "kinegen.cli", "build", str(tmp_path / "none.yaml")], capture_output=True, text=True, timeout=120)
    assert missing.returncode == 2
    assert missing.stderr.startswith("error: ") and "none.yaml" in missing.stderr
    assert "warning" not in missing.stderr  # (the solver's compile a failed build started is stopped without a leaked pipe)
