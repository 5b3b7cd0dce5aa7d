"""The optional compiled path: C translated from the generated plain-float functions gives the
same numbers, and the same trajectories, as the Python code."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from kinegen.errors import KinegenError
from kinegen.runtime import Solver, SolverOptions, from_module, load_module
from kinegen.runtime.compiled import PART, attach, c_source
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
    # no C function longer than PART statements: compile time stays linear in the model's size
    bodies = [block.split("}")[0] for block in source.split(") {")[1:]]
    assert max(body.count(";") for body in bodies) <= PART + 1


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


def _handovers(solver: Solver) -> list[tuple[int, int]]:
    """Record the (first, returned) steps of every call into the C loop of ``solver``."""
    calls: list[tuple[int, int]] = []
    steps = solver._compiled_steps()
    run = steps.run

    def recorded(first, *args):
        done = run(first, *args)
        calls.append((first, done))
        return done

    steps.run = recorded
    return calls


@pytest.mark.parametrize("name", ["excavator_euler_parameters", "excavator_quaternion"])
def test_the_c_step_loop_takes_every_usual_step_and_matches_python(name):
    """The digging cycle: after the first (assembly) step, one call into the C loop solves all
    the rest; poses, rates and iteration counts equal the Python loop with the same options."""
    module = load_module(GENERATED / f"{name}.py")
    system = from_module(module, "digging")
    options = SolverOptions(chord=True)
    python = Solver(system, options).solve()
    solver = Solver(attach(system, module), options)
    calls = _handovers(solver)
    compiled = solver.solve()
    assert calls == [(1, len(python.times))]
    assert np.abs(python.q - compiled.q).max() < 1e-12
    assert np.abs(python.v - compiled.v).max() < 1e-9 and np.abs(python.a - compiled.a).max() < 1e-8
    # LAPACK's 1-norm estimate is a local search: poses 1e-13 apart may give estimates ~2x apart
    assert np.abs(np.log(python.conditions / compiled.conditions)).max() < np.log(3.0)
    assert (python.iterations[2:] == compiled.iterations[2:]).all()  # step 1: C starts without chord factors


def test_near_the_toggle_the_c_loop_hands_over_and_the_branch_is_kept():
    """bucket_near_toggle (0.25 s steps): the C loop returns at the step that needs halving;
    Python refines it and hands back; every pose equals the Python solution."""
    module = load_module(GENERATED / "excavator_quaternion.py")
    system = from_module(module, "bucket_near_toggle")
    python = Solver(system).solve()
    solver = Solver(attach(system, module))
    calls = _handovers(solver)
    compiled = solver.solve()
    assert any(done < len(python.times) for _, done in calls) and len(calls) >= 2
    assert compiled.converged.all()
    assert np.abs(python.q - compiled.q).max() < 1e-9


def test_a_failure_is_the_same_error_at_the_same_time_with_the_c_loop():
    module = load_module(GENERATED / "excavator_quaternion.py")
    system = from_module(module, "bucket_toggle")
    errors = []
    for candidate in (system, attach(system, module)):
        with pytest.raises(KinegenError) as caught:
            Solver(candidate).solve()
        errors.append(caught.value)
    assert type(errors[0]) is type(errors[1]) and errors[0].t == errors[1].t
