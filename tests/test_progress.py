"""Progress bars on long work: drawn on a terminal (a real pseudo-terminal here), never into a
pipe or a file -- for a build, `make bench` and `make fuzz`."""

from __future__ import annotations

import os
import re
import subprocess
import sys

from tests.conftest import MODELS, ROOT, on_a_terminal


def _piped(command: list[str], env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(command, capture_output=True, text=True, timeout=300, cwd=ROOT, env=env)


def test_a_build_shows_its_stages_on_a_terminal_and_nothing_in_a_pipe(tmp_path):
    """A build in a cache of its own (so that it derives: kinegen.codegen.kept), on a terminal; the
    same build again into a pipe and on the terminal (taken from the cache, and saying so there);
    then with --derive (derived, though the cache holds it). (--no-compile: a cache of its own would
    compile kinegen's C solver, which the stages do not show.)"""
    command = [sys.executable, "-m", "kinegen.cli", "build", str(MODELS / "four_bar.yaml"), "--generated-dir", str(tmp_path), "--no-compile"]
    env = dict(os.environ, KINEGEN_CACHE=str(tmp_path / "cache"))
    code, text = on_a_terminal(command, env)
    assert code == 0
    assert "build four_bar (quaternion): deriving and printing: [0/3 stages" in text
    assert "build four_bar (quaternion): checking: [1/3 stages" in text and "wrote " in text
    piped = _piped(command, env)
    assert piped.returncode == 0 and "wrote " in piped.stdout + piped.stderr and "stages," not in piped.stdout + piped.stderr
    code, text = on_a_terminal(command, env)
    assert code == 0 and "build four_bar (quaternion): kept from an earlier build: [0/3 stages" in text and "deriving" not in text
    code, text = on_a_terminal([*command, "--derive"], env)
    assert code == 0 and "build four_bar (quaternion): deriving and printing: [0/3 stages" in text


def test_the_benchmark_counts_its_runs_on_a_terminal_and_prints_only_its_table_into_a_pipe():
    """`python -m kinegen.bench` on chain-3 alone with three contenders (``--only``; no extra
    sections): the bar names each contender as it runs and counts the runs; the table's rows are
    the same either way, and only the contenders asked for run."""
    command = [sys.executable, "-m", "kinegen.bench", "--sizes", "3", "--excavator", "--quick", "--no-sweep", "--no-studies",
               "--no-explore", "--only", "own predictor", "python newton loop", "--repeats", "1"]  # fmt: skip
    piped = _piped(command, dict(os.environ, OPENBLAS_NUM_THREADS="1"))
    assert piped.returncode == 0, piped.stdout + piped.stderr
    assert "FAILED" not in piped.stdout, piped.stdout  # every contender's row ran
    assert "runs" not in piped.stderr and "\r" not in piped.stdout + piped.stderr
    rows = [line.split()[1:3] for line in piped.stdout.splitlines() if line.startswith("chain-3 ")]
    assert rows == [["kinegen", "(own"], ["kinegen", "compiled"], ["CasADi", "SX,"]]
    code, text = on_a_terminal(command, dict(os.environ, OPENBLAS_NUM_THREADS="1"))
    assert code == 0, text[-2000:]
    counts = [int(n) for n in re.findall(r"bench: chain-3, [^\[\r\n]*\[(\d+)/\d+ runs", text)]
    assert counts[0] == 0 and max(counts) == len(rows)  # one stage per row, each counted when the next starts
    assert f"bench: C target memory: [{len(rows)}/{len(rows) + 1} runs" in text
    assert all(" ".join(row) in text for row in rows)


def test_the_fuzzer_counts_its_models_on_a_terminal():
    """`make fuzz` runs pytest with -s: on a terminal the fuzzer draws a bar over its models; the
    test suite captures stderr, so there it draws nothing."""
    env = dict(os.environ, KINEGEN_FUZZ_EXAMPLES="12", OPENBLAS_NUM_THREADS="1")
    command = [sys.executable, "-m", "pytest", "-q", "-s", "-p", "no:randomly", "-p", "no:cacheprovider",
               "tests/test_fuzz.py", "-k", "test_fuzzed_models"]  # fmt: skip
    code, text = on_a_terminal(command, env)
    assert code == 0, text[-2000:]
    counts = [int(n) for n in re.findall(r"fuzz: [\w/]+ layer: \[(\d+)/12 models", text)]
    assert counts and counts[0] == 0 and max(counts) >= 11
    piped = _piped(command, env)
    assert piped.returncode == 0 and "models" not in piped.stderr and "layer[" not in piped.stdout


def test_a_long_solve_counts_its_steps_on_a_terminal(tmp_path):
    """`kinegen solve --no-compile --steps 3000` (pure Python, ~2 s here, four times the
    PROGRESS_DELAY after which the bar shows): a bar over the time steps on a terminal, nothing
    in a pipe."""
    steps = 3_000
    command = [sys.executable, "-m", "kinegen.cli", "solve", str(MODELS / "slider_crank.yaml"), "--steps", str(steps),
               "--no-compile", "--generated-dir", str(tmp_path)]  # fmt: skip
    piped = _piped(command)
    assert piped.returncode == 0 and "step/s" not in piped.stdout + piped.stderr, piped.stderr
    assert f"{steps} of {steps} time points" in piped.stdout
    code, text = on_a_terminal(command)
    assert code == 0, text[-2000:]
    assert re.search(r"solve slider_crank/run: +\d+%", text) and f"{steps} of {steps} time points" in text


def test_a_bar_shown_starts_no_thread_so_a_build_on_a_terminal_still_shares_its_printing():
    """tqdm's monitor thread would keep kinegen.codegen.forked.may_fork() False while a bar is shown
    (a fork copies only the calling thread): kinegen's bars run without it."""
    import threading

    from kinegen.progress import counter

    before = threading.active_count()
    with counter("shown", 3, show=True) as bar:
        bar.update(1)
        assert threading.active_count() == before
