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
    for a, b in zip(mine, theirs):
        assert a.shape == b.shape and a.tobytes() == b.tobytes()
