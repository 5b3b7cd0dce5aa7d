"""The C backend: kernels printed from the same SymPy statements as the Python ones, kinegen's C
solver (kinegen_solver.c) driving them, the runtime's compiled path, and the standalone C
target built with nothing but a C99 compiler -- compiled for real with the machine's ``cc``."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kinegen import rotations
from kinegen.bench.callgraph import CallGraph
from kinegen.cli import main
from kinegen.codegen.backends.c import config
from kinegen.errors import KinegenError
from kinegen.runtime import Solver, SolverOptions, export, from_module, load_module
from kinegen.runtime.native import build_library, with_solver
from tests.conftest import GENERATED, MODELS, ROOT, SLIDER_CRANK_DEAD_CENTRE, cache_with_solver, chain_yaml

CC = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler")
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
# no variable-length array, and every function's stack bounded: the solver's and the example's to 2 kB, the
# generated kernels' (straight-line parts of at most config.PART_STATEMENTS statements, whose temporaries spill)
# to 4 kB; gcc's -Wstack-usage also reports an unbounded frame, as a recursion's
STACK = ["-Wvla", "-Wstack-usage=4096"]
CORE_STACK = ["-Wvla", "-Wstack-usage=2048"]


def systems(stem: str, case: str | None = None):
    """(Python, compiled) systems of a committed module's case."""
    module = load_module(GENERATED / f"{stem}.py")
    return from_module(module, case, compiled=False), from_module(module, case, compiled=True)


@pytest.mark.parametrize(
    ("stem", "case"),
    [("excavator_euler_parameters", "digging"), ("excavator_quaternion", "level_cut"), ("rssr_quaternion", None),
     ("boom_euler_zxz", None), ("four_bar_euler_parameters", None)],
)  # fmt: skip
def test_c_kernels_equal_the_python_ones(stem, case):
    """Phi, Phi_q, nu, gamma and the driver inputs at random configurations and times."""
    python, native = systems(stem, case)
    assert native.native is not None
    rng = np.random.default_rng(3)
    for t in (python.t0, 0.37 * python.t0 + 0.63 * python.t1):
        q = python.initial_q + 0.01 * rng.normal(size=python.n_stored)
        v = rng.normal(size=python.n_velocity)
        u, ud, udd = (x[:, 0] for x in python.driver_inputs(np.array([t])))
        phi, values = python.evaluate(q, u)
        c_phi, c_values = native.evaluate(q, u)
        scale = 1e-14 * max(1.0, np.abs(values).max())
        assert np.abs(c_phi - phi).max() <= scale and np.abs(c_values - np.asarray(values)).max() <= scale
        assert np.abs(native.velocity_rhs(q, u, ud) - python.velocity_rhs(q, u, ud)).max() <= scale
        gamma = python.acceleration_rhs(q, v, u, ud, udd)
        assert np.abs(native.acceleration_rhs(q, v, u, ud, udd) - gamma).max() <= 1e-14 * max(1.0, np.abs(gamma).max())


def test_the_compiled_path_is_the_default_and_matches_python():
    """The digging cycle through one call into the C loop equals the Python loop: poses to
    1e-12, rates to 1e-12 of their scale, the same Newton iterations; the 1-norm condition
    estimates (LAPACK's on the whole matrix, kinegen's on the block form) mostly to rounding."""
    module = load_module(GENERATED / "excavator_quaternion.py")
    assert from_module(module, "digging").native is not None  # compiled unless told otherwise
    python, native = systems("excavator_quaternion", "digging")
    estimate = SolverOptions(condition="estimate")  # (not by default: nothing the user sees reads it)
    a, b = Solver(python, estimate).solve(), Solver(native, estimate).solve()
    assert np.abs(a.q - b.q).max() < 1e-12
    for x, y in ((a.v, b.v), (a.a, b.a)):
        assert (np.abs(x - y).max(axis=0) <= 1e-12 * np.maximum(1.0, np.abs(x).max(axis=0))).all()
    assert (a.iterations == b.iterations).all()
    ratio = np.abs(np.log(a.conditions / b.conditions))
    assert np.median(ratio) < 1e-12 and ratio.max() < np.log(3.0)


def test_the_condition_estimate_counts_a_zero_as_lapack_does():
    """kinegen_solver.c's estimate takes a value's sign as LAPACK's xLACN2 does (+1 where it is >= 0, a
    zero of either sign too): a solve of e_j is exactly zero in the blocks before j's, with the signs of
    their pivots, and counting -0.0 as -1 (copysign) sent the iteration elsewhere than LAPACK's. On the
    level cut, C's estimates now equal the Python path's (LAPACK gecon) to 1e-12 in 85 % of the steps;
    with copysign, 72.6 %."""
    python, native = systems("excavator_quaternion", "level_cut")
    estimate = SolverOptions(condition="estimate")
    a, b = Solver(python, estimate).solve(), Solver(native, estimate).solve()
    equal = np.abs(np.log(a.conditions / b.conditions)) < 1e-12
    assert equal.mean() > 0.8, equal.mean()


def test_the_input_effects_in_c_are_the_numpy_paths_and_central_differences_of_solved_poses():
    """kinegen_input_effects (dq/du = Phi_q^-1 nu(q, u, e_j) at many configurations, what the working
    range's boundary and sweeps ask for) against the NumPy path (the Python kernels, the batched block
    solve) to 1e-13 of its scale along the digging cycle, against central differences of configurations
    solved at u -+ h e_j, and NaN where Phi_q is singular (the slider crank at its dead centre)."""
    import dataclasses

    from kinegen.runtime.sensitivity import configuration_sensitivities

    _, native = systems("excavator_quaternion", "digging")
    solved = Solver(native).solve(np.linspace(native.t0, native.t1, 41))
    q, u = solved.q.T, native.driver_inputs(solved.times)[0]
    by_c = configuration_sensitivities(native, q, u, design=False)[1]
    by_numpy = configuration_sensitivities(dataclasses.replace(native, native=None), q, u, design=False)[1]
    assert by_c.shape == (41, native.n_velocity, native.n_inputs)
    assert np.abs(by_c - by_numpy).max() <= 1e-13 * np.abs(by_numpy).max()
    newton, h = Solver(native), 1e-6
    for j in range(native.n_inputs):  # central differences of every body's origin at the cycle's middle configuration
        step = np.eye(native.n_inputs)[j] * h
        ahead, behind = (newton.position(q[:, 20], u[:, 20] + sign * step, solved.times[20])[0] for sign in (1, -1))
        for body in native.bodies:  # (its first three velocity coordinates: the origin's, in the global frame)
            moved = (native.body_coordinates(ahead, body)[:3] - native.body_coordinates(behind, body)[:3]) / (2 * h)
            assert np.abs(moved - native.body_coordinates(by_c[20, :, j], body, velocity=True)[:3]).max() <= 1e-7, (j, body)
    _, crank = systems("slider_crank_quaternion", "dead_centre")
    dead_centre = np.array(SLIDER_CRANK_DEAD_CENTRE)
    at_start = crank.driver_inputs(np.array([crank.t0]))[0][:, 0]
    away = Solver(crank).solve(np.array([crank.t0])).q[0]
    effects = crank.native.input_effects(np.column_stack([away, dead_centre]), np.column_stack([at_start, [0.8]]))
    assert np.isfinite(effects[0]).all() and np.isnan(effects[1]).all()


@pytest.mark.parametrize(
    ("stem", "case", "loads", "inertia"),
    [("excavator_quaternion", "digging", ("payload", "cutting"), False), ("excavator_dual_euler_parameters", "level_cut", ("payload",), True),
     ("excavator_euler_zxy", "level_cut", ("cutting",), False), ("excavator_quaternion", "digging", (), True),
     ("slider_crank_euler_parameters", "run", ("gas",), False), ("four_bar_dual_quaternion", None, ("rocker_torque",), False)],
)  # fmt: skip
def test_compiled_forces_equal_python(stem, case, loads, inertia):
    """kinegen_forces (the generated actuation, loads and inertia kernels in C, the force matrix's
    block plan, the transposed block solve) against the Python kernels and LAPACK: every multiplier
    and element force to 1e-12 of its column's scale, along a solved case; the actuation elements'
    (excavator) and the case drivers' (slider-crank, four-bar) forms both, statics and inverse
    dynamics (the excavator's estimated masses)."""
    from kinegen.forces.dynamics import inertial_load
    from kinegen.forces.statics import Statics

    python, native = systems(stem, case)
    model = _model_of(stem)
    results = Solver(python).solve()
    statics = Statics(results, model)
    load = sum((statics.generalized_load(model.loads[name]) for name in loads), np.zeros((len(results.times), python.n_velocity)))
    if inertia:
        load = load + inertial_load(results)
    expected = statics.solve(statics.matrix(), load)
    weights = np.array([float(name in loads) for name in python.statics.load_names])
    motion = (results.v, results.a) if inertia else None
    multipliers, force = native.native.forces(results.times, results.q, results.inputs, weights, motion)
    _same_forces(multipliers, expected, statics.row_names)
    expected_force = statics.element_forces(expected)
    assert force.shape == expected_force.shape
    _same_forces(force, expected_force, [e.name for e in statics.elements])


def _same_forces(c: np.ndarray, python: np.ndarray, names: list[str]) -> None:
    """Every column to 1e-12 of its scale: its largest value, or 1e-2 of the largest of all for a
    column that is zero but for rounding (a multiplier the geometry leaves unloaded, the bucket
    cylinder under a load at the bucket pin: both sides' rounding is that of the whole solve,
    up to 2e-15 of the largest force in the dual Euler parameters); the largest of the columns of its
    own unit: pressures [Pa], moments [N m], the others (forces and multipliers)."""
    kinds = np.array([1 if ".pressure" in n else 2 if ".moment_" in n else 0 for n in names])
    largest = {k: np.abs(python[:, kinds == k]).max() for k in set(kinds.tolist())}
    scale = np.maximum(np.abs(python).max(axis=0), 1e-2 * np.array([largest[k] for k in kinds]))
    error = np.abs(c - python).max(axis=0)
    assert (error <= 1e-12 * scale).all(), [(names[i], error[i], scale[i]) for i in np.flatnonzero(error > 1e-12 * scale)]


def _same_supply(c: np.ndarray, python: np.ndarray, names: list[str]) -> None:
    """The pump columns (flows, largest flows, pressures, powers, the engine's) to 1e-12 of each
    column's largest value -- except a pump's pressure where what it feeds stands still: there C's
    and Python's rates are rounding of either sign, and the filling side is either's."""
    moving = np.ones(len(c), dtype=bool)
    for k, name in enumerate(names):
        if name.endswith(".flow"):
            moving &= python[:, k] > 1e-9 * np.abs(python[:, k]).max()
    scale = np.maximum(np.abs(python).max(axis=0), 1e-300)
    error = np.abs(c - python)[moving].max(axis=0)
    assert (error <= 1e-12 * scale).all(), [(names[i], error[i], scale[i]) for i in np.flatnonzero(error > 1e-12 * scale)]


def _model_of(stem: str):
    from kinegen.model import load

    name = next(m.stem for m in MODELS.glob("*.yaml") if stem.startswith(m.stem + "_"))
    return load(MODELS / f"{name}.yaml")


def test_near_the_toggle_the_c_loop_halves_its_own_steps_and_the_branch_is_kept():
    """bucket_near_toggle (0.25 s steps): the C loop halves the steps it cannot certify itself
    (issue 25: no hand-over to Python for that), and every pose equals Python's."""
    python, native = systems("excavator_quaternion", "bucket_near_toggle")
    solver = Solver(native)
    calls = []
    steps = solver._native_steps

    def recorded(case_inputs):
        original = steps(case_inputs)
        run = original.run

        def counted(first, *args):
            done = run(first, *args)
            calls.append((first, done))
            return done

        original.run = counted
        return original

    solver._native_steps = recorded
    reference, compiled = Solver(python).solve(), solver.solve()
    assert compiled.converged.all() and calls == [(0, len(reference.times))]
    assert (compiled.iterations > 4).any()  # some steps were halved (their pieces' iterations add up)
    # the C loop's halvings (iterative, kinegen_step) are the Python recursion's: the same pieces
    assert (compiled.iterations == reference.iterations).all()
    assert np.abs(reference.q - compiled.q).max() < 1e-9
    unrefined = Solver(native, SolverOptions(max_refinements=0, on_failure="stop")).solve()
    assert not unrefined.converged.all()


def test_on_a_coarse_grid_the_certificates_coarse_bounds_accept_and_refuse_what_the_exact_one_does(monkeypatch):
    """The excavator's digging cycle on 41 points, its inputs moving in every step: the certificate
    first tries the inputs' coarse bounds (two solves, then two more with the curvature split:
    kinegen_solver.c's input_effect, Python's Solver._coarse_effect) and computes the exact one, column
    by column, when they decide nothing (Python's coarse bounds decided 68 of its 112 certificates here). On
    this grid all three happen (measured in C: of 101 certificates, 25 accepted by the coarse bound,
    16 refused by |W D| alone, 60 decided by the exact bound; 36 halvings). The reference is Python's
    certificate with the coarse bounds switched off: Python with them takes the same steps to the bit,
    C halves the same steps into the same pieces, and the poses agree."""
    python, native = systems("excavator_quaternion", "digging")
    times = np.linspace(native.t0, native.t1, 41)
    screened, compiled = Solver(python).solve(times), Solver(native).solve(times)
    monkeypatch.setattr(Solver, "_coarse_effect", lambda *args: None)
    reference = Solver(python).solve(times)
    assert compiled.converged.all() and reference.converged.all()
    assert (reference.iterations > 4).any()  # steps were halved (their pieces' iterations add up)
    assert np.array_equal(screened.iterations, reference.iterations) and np.array_equal(screened.q, reference.q)
    assert np.array_equal(compiled.iterations, reference.iterations)
    assert np.abs(reference.q - compiled.q).max() < 1e-9


@pytest.fixture(scope="module")
def chain14_over_10_s(tmp_path_factory) -> Path:
    """chain-14 in Euler parameters over 10 s on 101 points: its Python module (its C compiled by the
    first test that solves it compiled, once for both that use it)."""
    from kinegen.bench import chain as bench_chain

    folder = tmp_path_factory.mktemp("chain14")
    model = folder / "chain14.yaml"
    model.write_text(bench_chain.chain_yaml(14, t1=10.0, steps=101))
    return _python_module(folder, model, "euler-parameters")


def test_the_quarter_turn_cap_leaves_the_translations_out_alike_in_c_and_python(chain14_over_10_s, monkeypatch):
    """A certified step may turn no rotation coordinate by a quarter turn or more (kinegen_solver.h's
    KINEGEN_MAX_MOTION, the Python solver's MAX_MOTION); a body's translations (x, y, z; a dual quaternion's
    vx, vy, vz) repeat nothing and are not capped. chain-14 in Euler parameters on 41 points over 10 s: its
    far links move up to 9.7 m a step and its Euler parameters less than 0.8. C (which reads the
    translations off the layout's velocity names) and Python (NumericSystem.turning) take the same steps
    to the same poses, and fewer Newton iterations than Python with every coordinate capped, which
    halves the steps whose links moved more than pi/2 m (measured: 399 against 439)."""
    from kinegen.runtime.solver import MAX_MOTION
    from kinegen.runtime.system import NumericSystem

    module, times = load_module(chain14_over_10_s), np.linspace(0.0, 10.0, 41)
    python = from_module(module, "drive", compiled=False)
    assert [python.velocity_names[i].split(".")[1] for i in python.turning[:4]] == ["e0", "e1", "e2", "e3"]
    assert len(python.turning) == 14 * 4
    compiled = Solver(from_module(module, "drive", compiled=True)).solve(times)
    reference = Solver(python).solve(times)
    assert compiled.converged.all() and reference.converged.all() and len(reference.times) == 41
    translations = np.setdiff1d(np.arange(python.n_velocity), python.turning)
    moved = np.abs(np.diff(reference.q, axis=0))  # (stored = velocity coordinates in Euler parameters)
    assert moved[:, translations].max() > 4 * MAX_MOTION and moved[:, python.turning].max() < MAX_MOTION / 2
    assert np.array_equal(compiled.iterations, reference.iterations)
    assert np.abs(reference.q - compiled.q).max() < 1e-9
    monkeypatch.setattr(NumericSystem, "turning", property(lambda system: np.arange(system.n_velocity)))
    capped = Solver(from_module(module, "drive", compiled=False)).solve(times)
    assert capped.converged.all() and capped.iterations.sum() > reference.iterations.sum()
    assert np.abs(capped.q - reference.q).max() < 1e-8


def test_with_many_inputs_the_exact_columns_stop_once_the_rest_is_bounded_and_decide_as_before(chain14_over_10_s, monkeypatch):
    """chain-14 (14 inputs) over 10 s on 101 points (h = 0.1 s: steps halved up to 120 times): where
    the coarse bounds decide nothing, the C certificate solves W's exact columns four at a time in the
    inputs' order and after each group tries |W D| + the exact spread so far + the coarse bound of the
    rest's (measured: 8 certificates settled after 4 columns, 1 after 8, 2 after 12, 1 needed all 14).
    The reference is Python's certificate with the coarse bounds switched off, every column exact:
    C halves the same steps into the same pieces, and the poses agree."""
    module = load_module(chain14_over_10_s)
    compiled = Solver(from_module(module, "drive", compiled=True)).solve()
    monkeypatch.setattr(Solver, "_coarse_effect", lambda *args: None)
    reference = Solver(from_module(module, "drive", compiled=False)).solve()
    assert compiled.converged.all() and reference.converged.all() and len(reference.times) == 101
    assert reference.iterations.sum() > 2 * len(reference.times)  # steps were halved
    assert np.array_equal(compiled.iterations, reference.iterations)
    assert np.abs(reference.q - compiled.q).max() < 1e-9


def test_a_long_trajectory_runs_in_pieces_with_the_same_result(monkeypatch):
    """Long trajectories (a progress bar on a terminal) run the C loop in pieces; each piece goes
    on from the C solver's state, so every number equals the one-piece run's -- also across the
    hand-overs to Python near the bucket's toggle -- and still matches the Python solver."""
    from kinegen.runtime import solver as solver_module

    for case in ("digging", "bucket_near_toggle"):
        python, native = systems("excavator_quaternion", case)
        times = np.linspace(native.t0, native.t1, 1001 if case == "digging" else native.steps)
        estimate = SolverOptions(condition="estimate")  # its values handed on too
        whole = Solver(native, estimate).solve(times)
        with monkeypatch.context() as patch:
            patch.setattr(solver_module, "PROGRESS_STEPS", 2)
            patch.setattr(solver_module, "NATIVE_CHUNK", 3)
            pieces = Solver(native, estimate).solve(times)
        for name in ("q", "v", "a", "iterations", "residuals", "conditions"):
            assert np.array_equal(getattr(whole, name), getattr(pieces, name)), (case, name)
        assert pieces.converged.all()
        assert np.abs(pieces.q - Solver(python).solve(times).q).max() < 1e-9


def test_a_failure_is_the_same_error_at_the_same_time_compiled():
    errors = []
    for system in systems("excavator_quaternion", "bucket_toggle"):
        with pytest.raises(KinegenError) as caught:
            Solver(system).solve()
        errors.append(caught.value)
    assert type(errors[0]) is type(errors[1]) and errors[0].t == errors[1].t


def test_the_c_is_straight_line_in_short_functions_with_no_heap():
    source = (GENERATED / "excavator_euler_parameters.c").read_text()
    joints = re.search(r"void \w*compute_joints_phi\w*\([^)]*\) \{\n(.*?)\n\}", source, re.DOTALL).group(1)
    assert "pow(" not in joints and "(bucket_e0*bucket_e0)" in joints  # squares as products
    bodies = re.findall(r"\) \{\n(.*?)\n\}", source, re.DOTALL)
    module = load_module(GENERATED / "excavator_euler_parameters.py")
    reads = len(module.STORED_NAMES) + 9 * len(module.BODIES)  # the argument reads and rotation-matrix entries
    assert max(body.count(";") for body in bodies) <= config.PART_STATEMENTS + reads + 20  # a group is never cut
    # compiled whole by the standalone Makefile (test_standalone_*), in parallel parts by the runtime
    parts = config.source_parts(source)
    assert len(parts) >= 2 and parts == list(range(len(parts)))  # split in consecutive parts
    # every table of kinegen_solver.h's structs names its fields (designated initializers: two fields of one
    # type swapped cannot compile silently), and states its work sizes with kinegen_solver.h's macros
    tables = re.findall(r"^(?:static )?const kinegen_(?:model|layout|statics|design|kernel|point|actuator) \w+(?:\[\])? = \{\n(.*?)\n\};",
                        source, re.DOTALL | re.MULTILINE)  # fmt: skip
    assert len(tables) >= 4 + len(module.CASES)
    for table in tables:
        for line in table.splitlines():
            assert re.match(r"\s*(\{?\.\w+ = |/\*)", line), line
    assert re.search(r"\.work_doubles = EXCAVATOR_EULER_PARAMETERS_WORK_DOUBLES_DIGGING,", source)
    header = (GENERATED / "excavator_euler_parameters.h").read_text()
    assert "KINEGEN_WORK_DOUBLES(EXCAVATOR_EULER_PARAMETERS_N_Q" in header and "KINEGEN_FORCE_WORK_DOUBLES(" in header
    solver = (config.SOLVER / "kinegen_solver.c").read_text()
    assert not re.search(r"\b(malloc|calloc|realloc|free)\s*\(", solver)
    assert not re.search(r"^static [^(]*;", solver, re.MULTILINE)  # no global state


#: a program that sets up a solver on a copy of the four-bar's first case whose kernel table is changed
#: as each scenario says, and prints kinegen_init's status and role, then kinegen_start's and kinegen_step's
ROLES_PROGRAM = r"""
#include "four_bar_quaternion.h"
#include <stdio.h>
#include <string.h>
static four_bar_quaternion_workspace w;
static kinegen_kernel table[64];
static int sizes[8];
static void report(const char *scenario, const kinegen_model *m) {
    kinegen_solver s;
    double in[3 * FOUR_BAR_QUATERNION_MAX_INPUTS], next[3 * FOUR_BAR_QUATERNION_MAX_INPUTS], t1 = m->t0 + 0.01;
    int n = m->n_inputs, init = kinegen_init(&s, m, NULL, w.doubles, w.ints), inputs = kinegen_case_inputs(m, m->t0, in);
    kinegen_case_inputs(four_bar_quaternion_cases[0], m->t0, in); /* the case's inputs, from its table as built */
    kinegen_case_inputs(four_bar_quaternion_cases[0], t1, next);
    int start = kinegen_start(&s, m->t0, m->initial_q, in, in + n, in + 2 * n);
    int step = kinegen_step(&s, t1, next, next + n, next + 2 * n);
    printf("%s %d %s %d %d %d\n", scenario, init, s.role ? s.role : "-", inputs, start, step);
}
static kinegen_kernel *entry(kinegen_model *m, const char *name) {
    memcpy(table, four_bar_quaternion_cases[0]->kernels, sizeof(kinegen_kernel) * (size_t)m->n_kernels);
    m->kernels = table;
    for (int k = 0; k < m->n_kernels; ++k)
        if (strcmp(table[k].name, name) == 0) return &table[k];
    return NULL;
}
int main(void) {
    kinegen_model m = *four_bar_quaternion_cases[0];
    kinegen_kernel *k;
    report("as_built", &m);
    entry(&m, "phi_jac")->slots = "q,t";
    report("phi_jac_slots", &m);
    m = *four_bar_quaternion_cases[0];
    entry(&m, "phi_jac")->slots = "q,u,p";  /* a design parameter slot in a model without them */
    report("phi_jac_design", &m);
    m = *four_bar_quaternion_cases[0];
    k = entry(&m, "nu");
    memcpy(sizes, k->output_sizes, sizeof(int));
    sizes[0] += 1;
    k->output_sizes = sizes;
    report("nu_size", &m);
    m = *four_bar_quaternion_cases[0];
    entry(&m, "gamma")->name = "gamma_old";
    report("gamma_missing", &m);
    m = *four_bar_quaternion_cases[0];
    entry(&m, "inputs")->name = "inputs_old";  /* optional: a case without its own time functions */
    report("inputs_missing", &m);
    return 0;
}
"""


def _four_bar_program(folder: Path, name: str, source: str, optimization: str) -> subprocess.CompletedProcess:
    """``source`` compiled with the committed four-bar's C (quaternion) and kinegen's C solver by the
    machine's cc (strict flags, a bounded stack), then run: its completed process."""
    for suffix in (".c", ".h"):
        shutil.copy(GENERATED / f"four_bar_quaternion{suffix}", folder)
    for runtime in config.RUNTIME:
        shutil.copy(config.SOLVER / runtime, folder)
    (folder / f"{name}.c").write_text(source)
    program = folder / name
    sources = [str(folder / n) for n in (f"{name}.c", "four_bar_quaternion.c", "kinegen_solver.c")]
    done = subprocess.run([CC, *STRICT, *CORE_STACK, optimization, "-o", str(program), *sources, "-lm"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return subprocess.run([str(program)], capture_output=True, text=True, timeout=60)


SOLVE_PROGRAM = r"""
#include "four_bar_quaternion.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
static four_bar_quaternion_workspace w;
static double states[2][1001][3 * FOUR_BAR_QUATERNION_N_V + FOUR_BAR_QUATERNION_N_Q];
static double inputs[3 * 16];

/* the case's own motion, every step's q, v, a into states[k]; returns the steps solved */
static int run(const kinegen_model *m, int k) {
    kinegen_solver s;
    int n = m->n_inputs, steps = m->steps < 1000 ? m->steps : 1000, i;
    if (kinegen_init(&s, m, NULL, w.doubles, w.ints) != KINEGEN_OK) return -1;
    s.options.case_inputs = 1;
    s.options.condition = 1;
    kinegen_case_inputs(m, m->t0, inputs);
    if (kinegen_start(&s, m->t0, m->initial_q, inputs, inputs + n, inputs + 2 * n) != KINEGEN_OK) return -1;
    for (i = 0; i <= steps; ++i) {
        double t = m->t0 + (m->t1 - m->t0) * i / steps;
        if (i > 0) {
            kinegen_case_inputs(m, t, inputs);
            if (kinegen_step(&s, t, inputs, inputs + n, inputs + 2 * n) != KINEGEN_OK) return i;
        }
        memcpy(states[k][i], s.q, sizeof(double) * (size_t)m->n_q);
        memcpy(states[k][i] + m->n_q, s.v, sizeof(double) * (size_t)m->n_v);
        memcpy(states[k][i] + m->n_q + m->n_v, s.a, sizeof(double) * (size_t)m->n_v);
        states[k][i][m->n_q + 2 * m->n_v] = s.condition;
        states[k][i][m->n_q + 2 * m->n_v + 1] = i > 0 ? s.bound : 0.0; /* the certificate's alpha omega */
    }
    if (k == 0) { /* the written-out solves against Phi_q itself (s.jac_q: its values the factors are of) */
        double c[FOUR_BAR_QUATERNION_N_V], x[FOUR_BAR_QUATERNION_N_V], xt[FOUR_BAR_QUATERNION_N_V];
        double w[FOUR_BAR_QUATERNION_N_V], r[FOUR_BAR_QUATERNION_N_V] = {0}, rt[FOUR_BAR_QUATERNION_N_V] = {0};
        double big = 0.0, worst = 0.0, worst_t = 0.0;
        for (i = 0; i < m->n_v; ++i) c[i] = (i % 2 ? -1.0 : 1.0) * (1.0 + 0.01 * i);
        m->solve(s.store, s.off, s.perms, c, x, w);
        m->solve_transposed(s.store, s.off, s.perms, c, xt, w);
        for (i = 0; i < m->n_jac; ++i) {
            r[m->jac_rows[i]] += s.jac_q[i] * x[m->jac_cols[i]];
            rt[m->jac_cols[i]] += s.jac_q[i] * xt[m->jac_rows[i]];
            big = fmax(big, fabs(s.jac_q[i]) * fmax(fabs(x[m->jac_cols[i]]), fabs(xt[m->jac_rows[i]])));
        }
        for (i = 0; i < m->n_v; ++i) {
            worst = fmax(worst, fabs(r[i] - c[i]));
            worst_t = fmax(worst_t, fabs(rt[i] - c[i]));
        }
        printf("residuals %.3g %.3g\n", worst / big, worst_t / big);
    }
    return steps;
}

int main(void) {
    for (int c = 0; c < FOUR_BAR_QUATERNION_N_CASES; ++c) {
        const kinegen_model *m = four_bar_quaternion_cases[c];
        kinegen_model loop = *m; /* the same case solved by the solver's loops over the plan */
        loop.solve = NULL;
        loop.solve_transposed = NULL;
        if (m->solve == NULL || m->solve_transposed == NULL) return 2;
        int a = run(m, 0), b = run(&loop, 1);
        if (a != b || a < 2) return 3;
        printf("%s %d %s\n", m->case_name, a, memcmp(states[0], states[1], sizeof(states[0])) == 0 ? "identical" : "differ");
    }
    return 0;
}
"""


def test_the_written_out_block_solve_is_the_solvers_loop_to_the_bit(tmp_path):
    """Each case's Phi_q solves, written out straight-line by the C backend (kinegen_model.solve and
    solve_transposed, per distinct plan), do the operations of the solver's loops over the plan in the
    same order: every case of the four-bar solved both ways (the case's struct copied with both NULL),
    certified, with the condition estimate (its transposed solves), the states of every step, the
    estimates and the certificate's bounds equal to the bit; and at the last step both written-out
    solves leave residuals |Phi_q x - c| and |Phi_q^T x - c| below 1e-14 of max |Phi_q_ij x_j| against the
    Jacobian values themselves. Real C, strict flags."""
    run = _four_bar_program(tmp_path, "solve", SOLVE_PROGRAM, "-O2")
    assert run.returncode == 0, (run.returncode, run.stdout, run.stderr)
    lines = [line for line in run.stdout.splitlines() if not line.startswith("residuals ")]
    assert len(lines) == len(load_module(GENERATED / "four_bar_quaternion.py").CASES)
    assert all(line.endswith(" identical") and int(line.split()[1]) >= 2 for line in lines), lines
    residuals = [[float(x) for x in line.split()[1:]] for line in run.stdout.splitlines() if line.startswith("residuals ")]
    assert len(residuals) == len(lines) and all(max(pair) < 1e-14 for pair in residuals), residuals


SOLVE_FROM_PROGRAM = r"""
#include "chain14_euler_parameters.h"
#include <stdio.h>
#include <string.h>
static chain14_euler_parameters_workspace w;
static double states[3][42][3 * CHAIN14_EULER_PARAMETERS_N_V + CHAIN14_EULER_PARAMETERS_N_Q + 1];
static double inputs[3 * 14];

/* the certified trajectory along the case's own functions, every step's q, v, a into states[k] */
static int run(const kinegen_model *m, int k) {
    kinegen_solver s;
    int n = m->n_inputs, i;
    if (kinegen_init(&s, m, NULL, w.doubles, w.ints) != KINEGEN_OK) return -1;
    s.options.case_inputs = 1;
    kinegen_case_inputs(m, m->t0, inputs);
    if (kinegen_start(&s, m->t0, m->initial_q, inputs, inputs + n, inputs + 2 * n) != KINEGEN_OK) return -1;
    for (i = 0; i <= m->steps && i < 42; ++i) {
        double t = m->t0 + (m->t1 - m->t0) * i / m->steps;
        if (i > 0) {
            kinegen_case_inputs(m, t, inputs);
            if (kinegen_step(&s, t, inputs, inputs + n, inputs + 2 * n) != KINEGEN_OK) return -i;
        }
        memcpy(states[k][i], s.q, sizeof(double) * (size_t)m->n_q);
        memcpy(states[k][i] + m->n_q, s.v, sizeof(double) * (size_t)m->n_v);
        memcpy(states[k][i] + m->n_q + m->n_v, s.a, sizeof(double) * (size_t)m->n_v);
        states[k][i][m->n_q + 2 * m->n_v] = i > 0 ? s.bound : 0.0; /* the certificate's alpha omega */
    }
    if (k == 0) { /* each input's column from its part of the solve against the whole solve, at the last step */
        static double b[CHAIN14_EULER_PARAMETERS_N_V], x[CHAIN14_EULER_PARAMETERS_N_V], y[CHAIN14_EULER_PARAMETERS_N_V], work[CHAIN14_EULER_PARAMETERS_N_V];
        int differ = 0, first = 0;
        for (int c = 0; c < n; ++c) {
            memset(b, 0, sizeof(b));
            b[m->n_v - n + c] = 1.0 + 0.1 * c;
            m->solve(s.store, s.off, s.perms, b, x, work);
            m->solve_from(s.store, s.off, s.perms, b, y, work, m->input_pieces[c]);
            for (int j = 0; j < m->n_v; ++j) differ += x[j] != y[j]; /* (== : a zero's sign aside) */
            first = m->input_pieces[c] > first ? m->input_pieces[c] : first;
        }
        printf("columns %d differ, the last input from function %d\n", differ, first);
    }
    return i;
}

int main(void) {
    const kinegen_model *m = chain14_euler_parameters_cases[0];
    kinegen_model whole = *m, loops = *m; /* the same case, every column through the whole solve; and every solve
                                             and bound pass through the solver's loops over the plan */
    whole.solve_from = NULL;
    whole.input_pieces = NULL;
    loops.solve = NULL;
    loops.solve_transposed = NULL;
    loops.solve_from = NULL;
    loops.input_pieces = NULL;
    if (m->solve_from == NULL || m->input_pieces == NULL) return 2;
    int a = run(m, 0), b = run(&whole, 1), c = run(&loops, 2);
    if (a != b || a != c || a < 2) return 3;
    printf("%s %d %s\n", m->case_name, a, memcmp(states[0], states[1], sizeof(states[0])) == 0 ? "identical" : "differ");
    printf("loops %d %s\n", c, memcmp(states[0], states[2], sizeof(states[0])) == 0 ? "identical" : "differ");
    return 0;
}
"""


INVERSE_BOUND_PROGRAM = r"""
#include "kinegen_solver.c" /* its static solve_bound */
#include "four_bar_quaternion.h"
#include <stdio.h>
static four_bar_quaternion_workspace w;
int main(void) {
    const kinegen_model *m = four_bar_quaternion_cases[0];
    kinegen_solver s;
    double inputs[3 * 16], b[FOUR_BAR_QUATERNION_N_V], x[FOUR_BAR_QUATERNION_N_V], y[FOUR_BAR_QUATERNION_N_V];
    int n = m->n_inputs, i, j, k;
    kinegen_model loop = *m; /* the solver's bound pass over the plan, reading the factors' magnitudes */
    loop.solve = NULL;
    if (m->solve == NULL || kinegen_init(&s, m, NULL, w.doubles, w.ints) != KINEGEN_OK) return 2;
    s.options.case_inputs = 1;
    kinegen_case_inputs(m, m->t0, inputs);
    if (kinegen_start(&s, m->t0, m->initial_q, inputs, inputs + n, inputs + 2 * n) != KINEGEN_OK) return 3;
    for (k = 0; k < m->n_jac; ++k) printf("%d %d\n", m->jac_rows[k], m->jac_cols[k]);
    for (i = 1; i <= 12; ++i) {
        double t = m->t0 + (m->t1 - m->t0) * i / 12;
        kinegen_case_inputs(m, t, inputs);
        if (kinegen_step(&s, t, inputs, inputs + n, inputs + 2 * n) != KINEGEN_OK) return 4;
        printf("jac");
        for (k = 0; k < m->n_jac; ++k) printf(" %.17g", s.jac_q[k]); /* the values the factors are of */
        printf("\n");
        for (j = 0; j <= m->n_v; ++j) { /* every unit vector, then a positive one */
            for (k = 0; k < m->n_v; ++k) b[k] = j < m->n_v ? (k == j) : 0.5 + 0.25 * ((k * 7 + i) % 5);
            solve_bound(&s, b, x);
            s.model = &loop; /* the same bits as the written solve over the comparison matrices */
            solve_bound(&s, b, y);
            s.model = m;
            if (memcmp(x, y, sizeof(x)) != 0) return 5;
            printf("bound");
            for (k = 0; k < m->n_v; ++k) printf(" %.17g", b[k]);
            for (k = 0; k < m->n_v; ++k) printf(" %.17g", x[k]);
            printf("\n");
        }
    }
    return 0;
}
"""


def test_the_coarse_inverse_bound_is_never_below_the_inverse(tmp_path):
    """solve_bound (the certificate's coarse bound on |Phi_q^-1| b, b >= 0, from the factors it has) is
    at least |Phi_q^-1| b entry by entry -- what lets a step it certifies skip the exact bound. The
    four-bar (quaternion): Phi_q's blocks of 1, 2 and 4 rows and the entries below them, at 12 solved
    poses along its case, for every unit vector (each column of |Phi_q^-1|) and a positive one;
    against NumPy's inverse of the dense Phi_q. The bound is the case's written solve over the factors'
    comparison matrices, and the solver's bound pass over the plan (solve NULL) gives the same bits for
    each. Real C, strict flags."""
    for suffix in (".c", ".h"):
        shutil.copy(GENERATED / f"four_bar_quaternion{suffix}", tmp_path)
    for runtime in config.RUNTIME:
        shutil.copy(config.SOLVER / runtime, tmp_path)
    (tmp_path / "bound.c").write_text(INVERSE_BOUND_PROGRAM)
    sources = [str(tmp_path / n) for n in ("bound.c", "four_bar_quaternion.c")]
    done = subprocess.run([CC, *STRICT, *CORE_STACK, "-O1", "-o", str(tmp_path / "bound"), *sources, "-lm"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    run = subprocess.run([str(tmp_path / "bound")], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, (run.returncode, run.stderr)
    pattern = [line.split() for line in run.stdout.splitlines() if line[0].isdigit()]
    rows, cols = (np.array([int(p[k]) for p in pattern]) for k in (0, 1))
    n, checked, loose = rows.max() + 1, 0, []
    inverse = None
    for line in run.stdout.splitlines():
        if line.startswith("jac "):
            jac = np.zeros((n, n))
            jac[rows, cols] = np.array(line.split()[1:], dtype=float)
            inverse = np.abs(np.linalg.inv(jac))
        elif line.startswith("bound "):
            values = np.array(line.split()[1:], dtype=float)
            b, bound = values[:n], values[n:]
            exact = inverse @ b
            below = np.flatnonzero(bound < exact - 1e-12 * exact.max())  # (NumPy's inverse has rounding where Phi_q^-1 has zeros)
            assert np.isfinite(bound).all() and not below.size, (b.tolist(), below.tolist(), bound[below], exact[below])
            loose.append(bound.max() / exact.max())
            checked += 1
    assert checked == 12 * (n + 1)
    assert max(loose) > 1.0  # (coarse somewhere: it loses cancellations -- the exact bound is still needed)


def test_each_inputs_column_from_its_part_of_the_written_solve_changes_no_bit(tmp_path):
    """The certificate solves each moving input's column of Phi_q^-1 Phi_u from the function of the
    written solve that holds its driver's row (kinegen_model.solve_from, input_pieces): the rows before
    are zero. chain-14 (five functions, its inputs spread over all of them): every column equal to the
    whole solve's, and the certified trajectory's states equal to the bit to the one solved with both
    fields NULL. And with the written solve, the certificate's coarse bound on |Phi_q^-1| b is that solve
    over the factors' comparison matrices: the states and each step's bound alpha omega equal to the bit
    to the ones of the solver's loops over the plan (every written solve NULL), whose bound pass reads the
    factors' magnitudes itself. Real C, strict flags."""
    from kinegen.codegen import writer
    from kinegen.model import loads

    made = writer.generate(loads(chain_yaml(14), "chain14.yaml"), rotations.get("euler-parameters"), ("c-model",))["c-model"]
    for name, text in made.items():
        (tmp_path / name).write_text(text)
    for runtime in config.RUNTIME:
        shutil.copy(config.SOLVER / runtime, tmp_path)
    (tmp_path / "solve_from.c").write_text(SOLVE_FROM_PROGRAM)
    sources = [str(tmp_path / n) for n in ("solve_from.c", "chain14_euler_parameters.c", "kinegen_solver.c")]
    done = subprocess.run([CC, *STRICT, *STACK, "-O2", "-o", str(tmp_path / "solve_from"), *sources, "-lm"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    run = subprocess.run([str(tmp_path / "solve_from")], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, (run.returncode, run.stdout, run.stderr)
    columns, trajectory, loops = run.stdout.splitlines()
    assert columns.startswith("columns 0 differ") and int(columns.split()[-1]) >= 3, columns  # (functions 0-4: most skipped)
    assert trajectory.startswith("drive ") and trajectory.endswith(" identical") and int(trajectory.split()[1]) >= 41, trajectory
    assert loops == f"loops {trajectory.split()[1]} identical", loops


def test_the_c_solver_finds_its_kernels_by_role_and_refuses_a_table_that_declares_them_otherwise(tmp_path):
    """kinegen_init binds the kernels it calls by name from the case's and the layout's tables (no typed
    pointer of a kernel in any struct) and checks their slots and output sizes: a phi_jac declared with
    other slots (or a design parameter the model does not have), a nu with another output size, a missing
    gamma are KINEGEN_MODEL naming the role, and every later call refuses with it (no call through a
    kernel it did not bind); a case without its own time functions (inputs, an optional role) is set up,
    only kinegen_case_inputs says it has none. Real C, compiled with the machine's cc."""
    run = _four_bar_program(tmp_path, "roles", ROLES_PROGRAM, "-O1")
    assert run.returncode == 0, run.stderr
    rows = {line.split()[0]: line.split()[1:] for line in run.stdout.splitlines()}
    ok, model = "0", "6"  # KINEGEN_OK, KINEGEN_MODEL
    assert rows["as_built"] == [ok, "-", ok, ok, ok]
    for scenario, role in (("phi_jac_slots", "phi_jac"), ("phi_jac_design", "phi_jac"), ("nu_size", "nu"), ("gamma_missing", "gamma")):
        assert rows[scenario] == [model, role, ok, model, model], scenario
    assert rows["inputs_missing"] == [ok, "-", model, ok, ok]
    header = (config.SOLVER / "kinegen_solver.h").read_text()
    assert "KINEGEN_MODEL = 6" in header and "(*phi_jac)" not in header and "(*frames)" not in header


def test_the_runtime_binds_every_c_function_from_the_librarys_own_table():
    """kinegen_functions lists every function kinegen_solver.h declares, with its result and parameter
    types as declared (the C compiler holds the list to the prototypes); the runtime's ctypes
    signatures are made from it alone."""
    import ctypes

    from kinegen.runtime.abi import bind_functions

    header = re.sub(r"/\*.*?\*/", "", (config.SOLVER / "kinegen_solver.h").read_text(), flags=re.DOTALL)
    declared = {m.group(2): " ".join(m.group(3).split()).split(", ")
                for m in re.finditer(r"^([a-z][\w ]*?[\w*]+)\s*\*?\s*(kinegen_\w+)\(([^)]*)\);", header, re.MULTILINE)}  # fmt: skip
    library = systems("boom_quaternion")[1].native.abi.library
    bound = bind_functions(library)
    assert set(bound) == set(declared) and len(bound) >= 16
    for name, (_, argtypes) in bound.items():
        assert len(argtypes) == len(declared[name]), name
        for parameter, kind in zip(declared[name], argtypes):
            text = parameter.startswith("const char *")  # a string: bytes in, bytes out
            expected = ctypes.c_char_p if text else ctypes.c_void_p if "*" in parameter else {"double": ctypes.c_double, "int": ctypes.c_int}[parameter.split()[0]]
            assert kind is expected, (name, parameter)
    assert bound["kinegen_step"][0] is ctypes.c_int and bound["kinegen_status_text"][0] is ctypes.c_char_p
    assert bound["kinegen_init"][0] is ctypes.c_int and bound["kinegen_table_mismatch"][0] is ctypes.c_double
    assert bound["kinegen_find_kernel"][0] is ctypes.c_void_p
    assert library.kinegen_status_text(2) == b"singular Jacobian"  # called through the bound signature


def test_the_library_cache_key_covers_the_compiler(tmp_path, monkeypatch):
    wrapper = tmp_path / "wrapped-cc"
    wrapper.write_text(f'#!/bin/sh\nexec {CC} "$@"\n')
    wrapper.chmod(0o755)
    sources = {"k.c": "double kinegen_probe(void) { return 1.0; }\n"}
    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    first = build_library(sources)
    monkeypatch.setenv("CC", str(wrapper))
    second = build_library(sources)
    assert first != second and first.exists() and second.exists()
    assert build_library(sources) == second  # cached


def test_the_solver_object_is_compiled_once_for_every_model(tmp_path, monkeypatch):
    """Two models' libraries in an empty cache: the solver's object once, then one object per model (a
    model split into parts has one per part: test_the_sensitivity_kernels_compile_when_first_asked_for
    counts the excavator's -- two small models here, not a third excavator compile). The solver's object
    is started as a build starts it (native.start_solver_object): a compiler process and no thread, so
    this process may still fork while it compiles; the library built meanwhile in this process finishes
    it first (it holds the object's lock)."""
    import threading

    from kinegen.codegen.forked import may_fork
    from kinegen.runtime import native

    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    objects = tmp_path / "cache" / "objects"
    files = _model_files("four_bar_quaternion")
    assert not config.source_parts(files["four_bar_quaternion.c"])  # compiled whole
    threads = threading.active_count()
    finish = native.start_solver_object()
    (started,) = native._STARTED.values()
    assert started._process.poll() is None and threading.active_count() == threads and (threads > 1 or may_fork())
    build_library(with_solver(files))
    assert started._process.returncode == 0 and not native._STARTED and not list(objects.glob("tmp*"))
    assert len(list(objects.glob("*.o"))) == 2  # the solver and the model
    finish()  # (finished already: nothing)
    assert native.start_solver_object()() is None and not native._STARTED  # cached: nothing started
    build_library(with_solver(_model_files("boom_quaternion")))
    assert len(list(objects.glob("*.o"))) == 3  # the boom's one object; the solver's reused


def test_a_solver_compile_never_finished_is_stopped_and_leaves_nothing(tmp_path, monkeypatch):
    """What native.start_solver_object started and nobody finished (a build that failed before its
    model's C) is stopped when it is dropped: the compiler killed, no object cached, its folder gone and
    the object's lock free again."""
    import fcntl
    import gc

    from kinegen.runtime import native

    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    objects = tmp_path / "cache" / "objects"
    finish = native.start_solver_object()
    (started,) = native._STARTED.values()
    process, locks = started._process, list((objects / "locks").iterdir())
    assert process.poll() is None and list(objects.glob("tmp*")) and len(locks) == 1
    del finish, started
    gc.collect()
    assert process.returncode is not None and process.returncode < 0  # killed
    assert not native._STARTED and not list(objects.glob("*.o")) and not list(objects.glob("tmp*"))
    with locks[0].open("a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)  # (free: a held lock raises BlockingIOError)


def test_the_sensitivity_kernels_compile_when_first_asked_for(tmp_path, monkeypatch):
    """A model's C with parts that only its sensitivity kernels need (config.sensitivity_parts; the
    excavator's, about half its lines): a solve loads a library compiled without them (part 0 with
    -DKINEGEN_NO_SENSITIVITIES: no phi_p, dvel, dacc, frames_d or points_p in its kernel tables, whose
    lengths are their entries'), and the first sensitivities compile the complete one, sharing the other
    parts' objects; its results (the state's sensitivities, and the frames' through frames_d) equal the
    Python kernels' to 1e-12 of their scale. Compiled on the slider-crank with design parameters, its C split as the
    excavator's is (parts of at most 300 statements), in an empty cache: what is compiled is counted."""
    from kinegen.codegen import generate, write_files
    from kinegen.interface import SENSITIVITY_ONLY
    from kinegen.model import loads
    from kinegen.runtime import sensitivity
    from tests.test_design import design_model

    text = (GENERATED / "excavator_quaternion.c").read_text()
    assert config.sensitivity_parts(text) and 0 not in config.sensitivity_parts(text) and config.has_sensitivity_parts(text)
    assert not config.has_sensitivity_parts((GENERATED / "excavator_euler_parameters.c").read_text())  # built without them
    monkeypatch.setattr(config, "FILE_STATEMENTS", 300)
    made = generate(loads(design_model(), "slider_crank_design.yaml"), rotations.get("quaternion"))
    write_files(tmp_path, {name: content for files in made.values() for name, content in files.items()})
    text = (tmp_path / "slider_crank_quaternion.c").read_text()
    parts, deferred = config.source_parts(text), config.sensitivity_parts(text)
    assert deferred and set(deferred) < set(parts) and 0 not in deferred and config.has_sensitivity_parts(text)
    monkeypatch.setenv("KINEGEN_CACHE", str(cache_with_solver(tmp_path / "cache")))  # (the solver's object there already)
    objects = tmp_path / "cache" / "objects"
    module = load_module(tmp_path / "slider_crank_quaternion.py")
    system = from_module(module)
    assert not set(SENSITIVITY_ONLY) & set(system.native.kernels)
    assert {"frames", "points", "actuator_ranges"} <= set(system.native.kernels)
    assert len(list(objects.glob("*.o"))) == 1 + len(parts) - len(deferred)  # the solver, part 0 without them, the others
    times = np.linspace(system.t0, system.t1, 21)
    solved = Solver(system).solve(times)
    compiled = (*sensitivity.state_sensitivities(solved), sensitivity.frame_sensitivities(solved))
    assert set(SENSITIVITY_ONLY) <= set(system.native._complete.kernels)
    assert len(list(objects.glob("*.o"))) == 2 + len(parts)  # part 0 whole and the deferred parts: the rest shared
    python_solved = Solver(from_module(module, compiled=False)).solve(times)
    reference = (*sensitivity.state_sensitivities(python_solved), sensitivity.frame_sensitivities(python_solved))
    for c, p in zip(compiled, reference, strict=True):
        assert np.abs(c - p).max() <= 1e-12 * max(1.0, np.abs(p).max())
    # a case whose complete library cannot be compiled (here: the compiler is gone) computes them in Python, saying so
    other = from_module(module)
    assert not set(SENSITIVITY_ONLY) & set(other.native.kernels)
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    results = Solver(other).solve(np.linspace(other.t0, other.t1, 11))
    with pytest.warns(RuntimeWarning, match="no compiled sensitivity kernels"):
        fallback = sensitivity.state_sensitivities(results)
    python = sensitivity.state_sensitivities(Solver(from_module(module, compiled=False)).solve(results.times))
    for c, p in zip(fallback, python):
        assert np.abs(c - p).max() <= 1e-12 * max(1.0, np.abs(p).max())
    # the kernels the runtime calls over batches (kinegen.runtime.system) fall back with them
    assert other.native.sensitivity_case() is None
    values = other.sensitivity_kernels["dvel"](results.q.T, results.v.T, results.inputs.T, np.zeros_like(results.inputs.T))
    expected = module.CASES[other.case]["outputs"]["dvel"](results.q.T, results.v.T, results.inputs.T, np.zeros_like(results.inputs.T),
                                                            list(other.design.values()))  # fmt: skip
    assert np.array_equal(np.broadcast_arrays(*values), np.broadcast_arrays(*expected))


def _model_files(stem: str) -> dict[str, str]:
    return {name: (GENERATED / name).read_text() for name in (f"{stem}.c", f"{stem}.h")}


def _standalone(tmp_path: Path, model: Path, param: str, *options: str) -> Path:
    result = CliRunner().invoke(main, ["build", str(model), "--param", param, "--target", "c", "--out-dir", str(tmp_path / "c"), *options])
    assert result.exit_code == 0, result.output
    return tmp_path / "c"


def _compile(folder: Path, stem: str, flags: list[str], stack: bool = True, solver: Path | None = None) -> Path:
    """The standalone example program, strictly (``stack``: with the stack bounds, which hold at -O1 and above);
    ``solver``: kinegen's C solver as an object compiled before (the same C in every standalone directory)."""
    program = folder / f"{stem}_test"
    sources = [str(folder / name) for name in ("example_main.c", f"{stem}.c")] + [str(solver or folder / "kinegen_solver.c")]
    done = subprocess.run([CC, *STRICT, *(STACK if stack else ["-Wvla"]), *flags, "-o", str(program), *sources, "-lm"],
                          capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr
    return program


def _compare(program: Path, python_system, case: str) -> None:
    """Every row of the C program's CSV against the Python runtime (Python functions, same options)."""
    done = subprocess.run([str(program), case], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    header, *rows = done.stdout.splitlines()
    c = np.array([[float(x) for x in row.split(",")] for row in rows])
    results = Solver(python_system, SolverOptions(condition="estimate")).solve()  # the C program's column
    names, table = export.table(results)
    supplied = _supply_table(python_system, results)
    if supplied is not None:  # a model with pumps: the flows follow (the declared supply kernel's outputs)
        names, table = [*names, *supplied[0]], np.hstack([table, supplied[1]])
    # the C program writes its 1-norm estimate where kinegen solve writes the 2-norm condition number (an SVD)
    assert header.split(",") == [n if n != "jacobian_condition" else "jacobian_condition_estimate" for n in names]
    assert c.shape == table.shape
    table[:, names.index("jacobian_condition")] = results.conditions  # the Python solver's estimate, beside C's
    _same_rows(c, table, names)
    # one format: the counts and flags as integers in both (C: %d; Python's CSV the same)
    with tempfile.TemporaryDirectory() as folder:
        python_rows = export.to_csv(results, Path(folder) / "python.csv").read_text().splitlines()[1:]
    for column in ("converged", "newton_iterations"):
        k = names.index(column)
        assert all(re.fullmatch(r"\d+", row.split(",")[k]) for row in (*rows, *python_rows)), column
        assert [row.split(",")[k] for row in rows] == [row.split(",")[k] for row in python_rows], column


def _supply_table(system, results, held=None):
    """The pump columns `kinegen solve` writes for this motion (None: the model has no pumps):
    kinegen.forces.supply's numbers, beside which the C program's come from its supply kernel."""
    from kinegen.forces.supply import flows

    path = MODELS / f"{system.model}.yaml"
    if not path.exists():
        return None
    m = _model_of(f"{system.model}_x")
    return None if m.supply is None else flows(results, m, held).table()


def _same_rows(c: np.ndarray, table: np.ndarray, names: list[str]) -> None:
    """Every column to 1e-12 of its scale, except the 1-norm condition estimate: a local search
    (Hager's) that may stop at another vertex after a last-bit change, to within a factor 3."""
    estimate = ("jacobian_condition", "jacobian_condition_estimate")
    exact = [i for i, n in enumerate(names) if n not in estimate]
    scale = np.maximum(1.0, np.abs(table[:, exact]).max(axis=0))
    assert (np.abs(c[:, exact] - table[:, exact]).max(axis=0) <= 1e-12 * scale).all(), [
        names[exact[i]] for i in np.flatnonzero(np.abs(c[:, exact] - table[:, exact]).max(axis=0) > 1e-12 * scale)
    ]
    condition = next(i for i, n in enumerate(names) if n in estimate)
    assert np.abs(np.log(c[:, condition] / table[:, condition])).max() < np.log(3.0)


#: the standalone excavator's tests on one worker, so that its C (~24,000 lines, ~14 s at -O2) compiles once
EXCAVATOR_C = pytest.mark.xdist_group(name="standalone_excavator_c")


@pytest.fixture(scope="module")
def excavator_objects(tmp_path_factory) -> Path:
    """The standalone excavator (quaternion, its default build) and its model's C and the solver compiled
    to objects under the strict flags at -O2, for the tests that link their own main() against them."""
    folder = _standalone(tmp_path_factory.mktemp("excavator"), MODELS / "excavator.yaml", "quaternion")
    for name in ("excavator_quaternion", "kinegen_solver"):
        done = subprocess.run([CC, *STRICT, *STACK, "-O2", "-c", "-o", str(folder / f"{name}.o"), str(folder / f"{name}.c")],
                              capture_output=True, text=True)  # fmt: skip
        assert done.returncode == 0, done.stderr
    return folder


def _link(folder: Path, program: str, sources: list[str], flags: list[str]) -> Path:
    """``sources`` of ``folder`` compiled with ``flags`` and linked with the excavator's objects."""
    objects = [str(folder / f"{name}.o") for name in ("excavator_quaternion", "kinegen_solver")]
    done = subprocess.run([CC, *flags, "-o", str(folder / program), *(str(folder / s) for s in sources), *objects, "-lm"],
                          capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr
    return folder / program


@EXCAVATOR_C
def test_standalone_excavator_builds_strictly_and_matches_python_in_every_case(excavator_objects):
    folder = excavator_objects
    assert {p.name for p in folder.iterdir()} >= {"excavator_quaternion.c", "excavator_quaternion.h", "kinegen_solver.c",
                                                   "kinegen_solver.h", "Makefile", "CMakeLists.txt", "example_main.c"}  # fmt: skip
    program = _link(folder, "excavator_quaternion_test", ["example_main.c"], [*STRICT, *STACK, "-O2"])
    module = load_module(GENERATED / "excavator_quaternion.py")
    for case in ("digging", "level_cut", "trench_wall"):
        _compare(program, from_module(module, case, compiled=False), case)
    _compare_forces(program, from_module(module, "level_cut", compiled=False))


def _compare_forces(program: Path, system) -> None:
    """`<program> case steps load ... +inertia` appends each element's force, each cylinder's pressure
    and the limit it meets, every joint's reaction (force, moment about its point) and the multipliers
    (inverse dynamics: the loads, the bodies' weight and inertia), named as `kinegen solve --load`
    names them, equal to the Python runtime's to 1e-12 of each column's scale; an unknown load is a
    usage error naming the model's loads."""
    from kinegen.forces import forces

    done = subprocess.run([str(program), system.case, "41", "payload", "+inertia", "cutting"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    header, *rows = done.stdout.splitlines()
    names = header.split(",")
    c = np.array([[float(x) for x in row.split(",")] for row in rows])
    results = Solver(system).solve(np.linspace(system.t0, system.t1, 41))
    held = forces(results, _model_of("excavator_quaternion"), ["payload", "cutting"], inertia=True)
    force_names, table = held.table()
    wanted = [n for n in force_names if not any(part in n for part in (".joint_force_", ".joint_moment_", "energy.", "tipping_margin"))]
    pump_names, pumps = _supply_table(system, results, held)  # then the pumps' flows, pressures and power
    assert names[-len(wanted) - len(pump_names) :] == [*wanted, *pump_names]
    _same_forces(c[:, -len(wanted) - len(pump_names) : -len(pump_names)], table[:, [force_names.index(n) for n in wanted]], wanted)
    _same_supply(c[:, -len(pump_names) :], pumps, pump_names)
    unknown = subprocess.run([str(program), system.case, "41", "payload", "gravel"], capture_output=True, text=True, timeout=60)
    assert unknown.returncode == 64 and "no load 'gravel'" in unknown.stderr and "payload cutting" in unknown.stderr


def test_standalone_chain_and_boom_match_python(tmp_path):
    model = tmp_path / "chain14.yaml"
    model.write_text(chain_yaml(14))
    solver = None  # the solver's C is the same in both directories: compiled once, strictly, at -O2
    for path, param, case in ((model, "euler-parameters", "drive"), (MODELS / "boom.yaml", "quaternion", "swing")):
        folder = _standalone(tmp_path / path.stem, path, param)
        stem = next(p.stem for p in folder.glob("*.h") if p.name not in config.RUNTIME)
        if solver is None:
            solver = tmp_path / "kinegen_solver.o"
            done = subprocess.run([CC, *STRICT, *STACK, "-O2", "-c", "-o", str(solver), str(folder / "kinegen_solver.c")], capture_output=True, text=True)
            assert done.returncode == 0, done.stderr
        program = _compile(folder, stem, ["-O2"], solver=solver)
        module = load_module(next(folder.parent.glob("*.py"), None) or _python_module(tmp_path / path.stem, path, param))
        _compare(program, from_module(module, case, compiled=False), case)


def _python_module(folder: Path, model: Path, param: str) -> Path:
    result = CliRunner().invoke(main, ["build", str(model), "--param", param, "--no-compile", "--out-dir", str(folder / "py")])  # (its Python alone)
    assert result.exit_code == 0, result.output
    return next((folder / "py").glob("*.py"))


def test_standalone_runs_clean_under_address_and_undefined_behaviour_sanitizers(tmp_path):
    # the design excavator's solver without its sensitivity kernels: example_main does not call them; -O0: the
    # sanitizers instrument every access the source makes (none optimized away), and its 13,000 lines compile in
    # 15 CPU-s against 35 at -Og (the stack bounds, which hold from -O1 on, are the strict builds' to check)
    folder = _standalone(tmp_path, MODELS / "excavator.yaml", "euler-parameters", "--no-sensitivities")
    program = _compile(folder, "excavator_euler_parameters", ["-O0", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"], stack=False)
    done = subprocess.run([str(program), "digging", "101", "payload", "+inertia"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and "runtime error" not in done.stderr, done.stderr
    assert len(done.stdout.splitlines()) == 102
    # the force columns with a parametrization that has normalization rows (in each body's square map
    # of the pin reactions), against the Python runtime's
    from kinegen.forces import forces

    header, *rows = done.stdout.splitlines()
    names = header.split(",")
    system = from_module(load_module(GENERATED / "excavator_euler_parameters.py"), "digging", compiled=False)
    results = Solver(system).solve(np.linspace(system.t0, system.t1, 101))
    held = forces(results, _model_of("excavator_euler_parameters"), ["payload"], inertia=True)
    force_names, table = held.table()
    wanted = [n for n in force_names if not any(part in n for part in (".joint_force_", ".joint_moment_", "energy.", "tipping_margin"))]
    pump_names, pumps = _supply_table(system, results, held)
    assert names[-len(wanted) - len(pump_names) :] == [*wanted, *pump_names]
    c = np.array([[float(x) for x in row.split(",")[-len(wanted) - len(pump_names) :]] for row in rows])
    _same_forces(c[:, : len(wanted)], table[:, [force_names.index(n) for n in wanted]], wanted)
    _same_supply(c[:, len(wanted) :], pumps, pump_names)


def test_the_c_core_is_clean_under_the_static_analyzer_with_a_bounded_stack(tmp_path):
    """The solver (kinegen_solver.c) and the example program: no variable-length array, no
    recursion, at most 2 kB of stack a function, nothing gcc's static analyzer (-fanalyzer) finds."""
    probe = subprocess.run([CC, "-fanalyzer", "-x", "c", "-c", "-o", os.devnull, "-"], input="int f(void);\n", capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"{CC} has no -fanalyzer (gcc >= 10 has)")
    folder = _standalone(tmp_path, MODELS / "four_bar.yaml", "quaternion")
    for name in ("kinegen_solver.c", "example_main.c"):
        flags = [*STRICT, *CORE_STACK, "-O2", "-fanalyzer", "-fcallgraph-info=su", "-c"]
        done = subprocess.run([CC, *flags, "-o", str(tmp_path / f"{name}.o"), str(folder / name)], capture_output=True, text=True, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
    # the solver's call graph as gcc compiled it (the kernels, called through pointers, are straight-line
    # leaves): no cycle, so no recursion, and the deepest chain of frames from any entry point is bounded
    graph = CallGraph(tmp_path / "kinegen_solver.c.ci")
    entries = graph.functions("kinegen_")
    assert "kinegen_step" in entries and len(graph.frames) > 20
    assert max(graph.deepest(name) for name in entries) <= 4096  # (a recursion raises ValueError)


def test_a_step_is_halved_at_most_as_often_as_both_solvers_allow():
    """max_refinements is bounded alike in Python and C (KINEGEN_MAX_REFINEMENTS), and a larger
    setting is refused with what the bound is."""
    from kinegen.runtime.solver import MAX_REFINEMENTS

    header = (config.SOLVER / "kinegen_solver.h").read_text()
    assert int(re.search(r"#define KINEGEN_MAX_REFINEMENTS (\d+)", header).group(1)) == MAX_REFINEMENTS
    SolverOptions(max_refinements=MAX_REFINEMENTS)
    for wrong in (-1, MAX_REFINEMENTS + 1):
        with pytest.raises(ValueError, match=f"max_refinements = {wrong}: a step is halved 0 to {MAX_REFINEMENTS} times"):
            SolverOptions(max_refinements=wrong)


@EXCAVATOR_C
def test_standalone_reads_driver_inputs_from_stdin_and_reports_failures(excavator_objects):
    """Inputs from a CSV on stdin give the same rows as the case's own functions; the toggle
    case ends with the solver's status as the exit code. (The directory's Makefile builds the same
    program in the controller's README test.)"""
    program = _link(excavator_objects, "excavator_quaternion_stdin", ["example_main.c"], [*STRICT, *STACK, "-O2"])
    own = subprocess.run([str(program), "level_cut"], capture_output=True, text=True, check=True).stdout
    system = from_module(load_module(GENERATED / "excavator_quaternion.py"), "level_cut", compiled=False)
    times = np.linspace(system.t0, system.t1, system.steps)
    rows = np.vstack([times, *system.driver_inputs(times)]).T
    text = "t,inputs...\n" + "\n".join(",".join(repr(float(x)) for x in row) for row in rows) + "\n"
    piped = subprocess.run([str(program), "level_cut", "-"], input=text, capture_output=True, text=True, check=True).stdout
    assert piped.splitlines()[0] == own.splitlines()[0]
    a, b = (np.array([[float(x) for x in row.split(",")] for row in out.splitlines()[1:]]) for out in (own, piped))
    _same_rows(b, a, own.splitlines()[0].split(","))  # NumPy's and libm's sin differ in the last bit
    failed = subprocess.run([str(program), "bucket_toggle"], capture_output=True, text=True)
    assert failed.returncode in (1, 2, 3) and failed.stderr.startswith("error: excavator/bucket_toggle at t = ")


@EXCAVATOR_C
def test_the_readmes_controller_snippet_compiles_strictly_and_solves_its_case(excavator_objects):
    """The C block of docs/controller.md ("Using kinegen in a controller"), as printed, compiled with the
    standalone directory's files under the strict flags, called from a main(): every step of the
    level cut solved (KINEGEN_OK)."""
    readme = (ROOT / "docs" / "controller.md").read_text()
    section = readme[readme.index("## Using kinegen in a controller") :]
    snippet = section[section.index("```c\n") + 5 : section.index("```", section.index("```c\n") + 5)]
    stated = int(re.search(r"all memory of one solver: ([\d,]+) B", snippet).group(1).replace(",", ""))
    folder = excavator_objects
    (folder / "controller.c").write_text(snippet)
    (folder / "main.c").write_text('#include <stdio.h>\n#include "excavator_quaternion.h"\nint control_loop(void);\nint main(void) {\n'
                                   '    int status = control_loop();\n'
                                   '    printf("%d %zu\\n", status, sizeof(excavator_quaternion_workspace));\n    return status;\n}\n')  # fmt: skip
    program = _link(folder, "controller", ["main.c", "controller.c"], [*STRICT, "-O1"])
    ran = subprocess.run([str(program)], capture_output=True, text=True, timeout=120)
    assert (ran.returncode, ran.stdout.split()) == (0, ["0", str(stated)]), ran.stderr  # the workspace as the snippet states it
