"""The optional compiled path: C translated from the generated plain-float functions gives the
same numbers, and the same trajectories, as the Python code."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from kinegen.runtime import Solver, from_module, load_module
from kinegen.runtime.compiled import attach, c_source
from tests.conftest import GENERATED

pytestmark = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path))


@pytest.mark.parametrize(
    "name,case", [("excavator_euler_parameters", "digging"), ("rssr_quaternion", None), ("boom_euler_zxz", None)]
)
def test_compiled_functions_equal_the_python_ones(name, case):
    module = load_module(GENERATED / f"{name}.py")
    system = from_module(module, case)
    fast = attach(system, module)
    rng = np.random.default_rng(3)
    for t in (system.t0, 0.5 * (system.t0 + system.t1)):
        q = system.initial_q + 0.01 * rng.normal(size=system.n_stored)
        v = rng.normal(size=system.n_velocity)
        u, ud, udd = (x[:, 0] for x in system.driver_inputs(np.array([t])))
        phi, values = system.evaluate(q, u)
        fast_phi, fast_values = fast.evaluate(q, u)
        scale = 1e-14 * max(1.0, np.abs(values).max())
        assert np.abs(fast_phi - phi).max() <= scale and np.abs(fast_values - np.asarray(values)).max() <= scale
        assert np.abs(fast.velocity_rhs(q, u, ud) - system.velocity_rhs(q, u, ud)).max() <= scale
        assert np.abs(fast.acceleration_rhs(q, v, u, ud, udd) - system.acceleration_rhs(q, v, u, ud, udd)).max() <= 1e-12


def test_compiled_trajectory_equals_the_python_one():
    module = load_module(GENERATED / "excavator_quaternion.py")
    system = from_module(module, "level_cut")
    python, compiled = Solver(system).solve(), Solver(attach(system, module)).solve()
    assert np.abs(python.q - compiled.q).max() < 1e-12
    assert np.abs(python.a - compiled.a).max() < 1e-9


def test_the_c_source_is_plain_arithmetic():
    module = load_module(GENERATED / "excavator_euler_parameters.py")
    source, sizes = c_source(module)
    assert "pow(" not in source and "#include <math.h>" in source
    assert sizes["digging"] == {"rows": 98, "entries": len(module.CASES["digging"]["jac_rows"])}


def test_cli_solve_compiled_gives_the_same_csv(tmp_path):
    from click.testing import CliRunner

    from kinegen.cli import main
    from tests.conftest import MODELS

    outputs = []
    for flags in ([], ["--compiled"]):
        out = tmp_path / f"run{len(flags)}.csv"
        result = CliRunner().invoke(main, ["solve", str(MODELS / "rssr.yaml"), "--out", str(out), *flags])
        assert result.exit_code == 0, result.output
        header = out.read_text().splitlines()[0].split(",")
        table = np.genfromtxt(out, delimiter=",", skip_header=1)
        # iteration counts differ: with cheap compiled evaluations the solver takes chord steps
        outputs.append(np.delete(table, header.index("newton_iterations"), axis=1))
    # so the poses agree to the Newton tolerance (1e-10), rates to it times cond(Phi_q) (~12)
    assert np.abs(outputs[0] - outputs[1]).max() < 1e-10 * 20 * max(1.0, np.abs(outputs[0]).max())
