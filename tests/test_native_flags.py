"""The runtime's library compiles the model's C for the machine that runs it (``-march=native`` in
:data:`kinegen.runtime.native.MODEL_FLAGS`, as the solver's object always was). At ``-O1`` under
``-std=c99`` that changes how the instructions are encoded (three-operand scalar forms), never a
result: checked here against the same C compiled without it, with the machine's ``cc``."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import kinegen.runtime.native as native
from kinegen.runtime import Solver, SolverOptions, from_module, load_module
from tests.conftest import GENERATED

pytestmark = pytest.mark.skipif((shutil.which("cc") or shutil.which("gcc")) is None, reason="no C compiler")


def _solved(stem: str, case: str, options: SolverOptions) -> tuple[str, list[np.ndarray]]:
    """The library a compiled solve of the committed module's case loaded, and what it solved."""
    system = from_module(load_module(GENERATED / f"{stem}.py"), case, compiled=True)
    results = Solver(system, options).solve()
    return system.native.library._name, [results.q, results.v, results.a, results.iterations, results.residuals, results.conditions]


def _same_bits(mine: list[np.ndarray], theirs: list[np.ndarray]) -> None:
    """Every array of one solve equal to the other's, shape and bytes."""
    assert len(mine) == len(theirs)
    for a, b in zip(mine, theirs):
        assert a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize(("stem", "case"), [("excavator_quaternion", "digging"), ("slider_crank_euler_parameters", "run")])
def test_the_models_c_for_this_machine_solves_to_the_same_bits(stem: str, case: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Certified steps along the case's own functions (the interval kernels' ``tanh`` and ``expm1`` on
    the excavator), polishing, v, a and the condition estimate: with the model's C compiled for this
    machine and without (another library in the cache: the flags are in its key), every value equal
    to the bit."""
    assert native.PORTABLE in native.MODEL_FLAGS and native.PORTABLE in native.SOLVER_FLAGS
    options = SolverOptions(condition="estimate")
    here, mine = _solved(stem, case, options)
    monkeypatch.setattr(native, "MODEL_FLAGS", tuple(f for f in native.MODEL_FLAGS if f != native.PORTABLE))
    there, theirs = _solved(stem, case, options)
    assert here != there  # two libraries, two compiles
    _same_bits(mine, theirs)


def test_a_compiler_that_refuses_both_optional_flags_still_builds_a_library_that_solves_alike(tmp_path) -> None:
    """A ``cc`` that knows neither ``-march=native`` nor ``-ffp-contract=off`` (the runtime's
    :data:`~kinegen.runtime.native.OPTIONAL_FLAGS`): each refused compile is tried again without them,
    one at a time, and the library so built (the solver's object too) solves the slider-crank to the
    bits the usual one gives -- GCC under ``-std=c99`` fuses nothing either way."""
    import os
    import subprocess
    import sys

    real = native.c_compiler()
    refused = tmp_path / "refused.txt"
    fake = tmp_path / "cc"
    fake.write_text(
        '#!/bin/sh\nbad=0\nfor a in "$@"; do case "$a" in -march=native|-ffp-contract=off)\n'
        f'  echo "$a" >> {refused}; bad=1;; esac; done\n'
        f'if [ $bad = 1 ]; then echo "cc: error: unknown option" >&2; exit 1; fi\nexec {real} "$@"\n'
    )
    fake.chmod(0o755)
    solved = tmp_path / "solved.npz"
    solve = (
        "import numpy as np\n"
        "from kinegen.runtime import Solver, SolverOptions, from_module, load_module\n"
        f"m = load_module({str(GENERATED / 'slider_crank_euler_parameters.py')!r})\n"
        "r = Solver(from_module(m, 'run', compiled=True), SolverOptions(condition='estimate')).solve()\n"
        f"np.savez({str(solved)!r}, r.q, r.v, r.a, r.iterations, r.residuals, r.conditions)\n"
    )
    env = {**os.environ, "CC": str(fake), "KINEGEN_CACHE": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", solve], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert {"-march=native", "-ffp-contract=off"} <= set(refused.read_text().split())  # each refused, then left out
    _, usual = _solved("slider_crank_euler_parameters", "run", SolverOptions(condition="estimate"))
    with np.load(solved) as theirs:
        _same_bits(usual, [theirs[f"arr_{k}"] for k in range(len(theirs.files))])
