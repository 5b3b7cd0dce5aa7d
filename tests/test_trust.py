"""Issue 25: never silently wrong, never runs what kinegen did not write.

* Certified steps: a motion the solver cannot follow never comes back as a result. Each class of
  fast input (one or all cylinders oscillating, a step in the inputs) is compared with a solve of
  the same inputs on a 1000x finer grid: every row equals the fine solve's (body points to 1e-9 m)
  or the solve refuses with a BranchError -- in the C loop and in the Python runtime.
* Hostile file names reach generated Python and C only as escaped text: the modules parse to the
  same AST as a harmless name's (string constants aside) and nothing in the name runs.
* A module is verified before it runs: an edited, planted or foreign-version module, an edited C
  file and a tampered cached library are refused (or rebuilt), never executed or loaded.
"""

from __future__ import annotations

import ast
import hashlib
import shutil
import subprocess

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import kinegen
from kinegen import integrity
from kinegen.api import Session
from kinegen.codegen import build, writer
from kinegen.errors import BranchError, ChangedFileError, GeneratedModuleError, KinegenError
from kinegen.integrity import c_string, comment_text
from kinegen.runtime import Solver, SolverOptions, from_module, load_module
from kinegen.runtime import native as native_module
from kinegen.runtime.solver import SamplingWarning
from tests.conftest import GENERATED, MODELS, cache_with_solver

#: the file's tests in one test process (make test distributes with --dist loadgroup): the oscillation case's fine reference solve, computed once
pytestmark = pytest.mark.xdist_group(name="trust")

CC = shutil.which("cc") or shutil.which("gcc")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler")


# ---- certified steps ---------------------------------------------------------------------------
#: both solves to max |Phi| <= 1e-12, so that their rows agree to well within 1e-9 m where both are right
TIGHT = SolverOptions(tolerance=1e-12)


@pytest.fixture(scope="module")
def excavator():
    return load_module(GENERATED / "excavator_quaternion.py", MODELS / "excavator.yaml")


def _signal(system, amplitudes, frequencies, phases):
    """Inputs (u, ud, udd) at times: the case's start values plus sines on the cylinders."""
    start = system.driver_inputs(np.array([system.t0]))[0][:, 0]

    def inputs(times):
        u = np.repeat(start[:, None], len(times), axis=1)
        ud, udd = np.zeros_like(u), np.zeros_like(u)
        for k, (amplitude, w, phase) in enumerate(zip(amplitudes, frequencies, phases), start=1):
            u[k] = u[k] + amplitude * np.sin(w * times + phase)
            ud[k] = amplitude * w * np.cos(w * times + phase)
            udd[k] = -amplitude * w * w * np.sin(w * times + phase)
        return u, ud, udd

    return inputs


def _points(system, q):
    return system.point_positions(q, [(b, p) for b, pts in system.points.items() for p in pts])


def _fine_solve(system, inputs, count):
    """The same inputs solved on a 1000x finer grid than ``count`` points (None when even that
    cannot follow them)."""
    fine_times = np.linspace(0.0, 1.0, (count - 1) * 1000 + 1)
    try:
        return Solver(system, TIGHT).solve(fine_times, inputs=inputs(fine_times))
    except KinegenError:
        return None


def _rows_equal_the_fine_solve_or_refuse(system, inputs, count, options, fine=None):
    """Solved on ``count`` points: every row's body points within 1e-9 m of a 1000x finer solve's
    (``fine``, else solved here), or a BranchError. Returns True when the coarse solve was accepted."""
    fine = fine if fine is not None else _fine_solve(system, inputs, count)
    if fine is None:
        return None  # the reference itself cannot follow: nothing to compare with
    times = np.linspace(0.0, 1.0, count)
    try:
        coarse = Solver(system, options).solve(times, inputs=inputs(times))
    except BranchError as error:
        assert "even over a step of" in str(error) and "observed" not in str(error)
        return False
    deviation = np.abs(_points(system, coarse.q) - _points(system, fine.q[::1000])).max()
    assert deviation <= 1e-9, f"a row {deviation:.3g} m from the fine solve came back as a result"
    return True


@needs_cc
@pytest.mark.parametrize(
    ("amplitudes", "frequency", "count"),
    [((0.0, 0.0, 0.05), 1000.0, 101), ((0.05, 0.05, 0.05), 1000.0, 101), ((0.0, 0.0, 0.15), 300.0, 41)],
    ids=["bucket-fast", "all-fast", "bucket-coarse"],
)
def test_fast_inputs_come_back_right_or_not_at_all(excavator, amplitudes, frequency, count):
    system = from_module(excavator, "digging")
    inputs = _signal(system, amplitudes, (frequency,) * 3, (1.0, 2.0, 3.0))
    # without the certificate the same solve returns rows on the other assembly mode (metres away)
    times = np.linspace(0.0, 1.0, count)
    fine = _fine_solve(system, inputs, count)
    try:
        blind = Solver(system, SolverOptions(keep_branch=False)).solve(times, inputs=inputs(times))
        blind_error = np.abs(_points(system, blind.q) - _points(system, fine.q[::1000])).max()
    except KinegenError:
        blind_error = np.inf
    assert blind_error > 1e-3
    assert _rows_equal_the_fine_solve_or_refuse(system, inputs, count, TIGHT, fine) is True


def test_fast_inputs_in_pure_python_match_the_fine_solve(excavator):
    system = from_module(excavator, "digging", compiled=False)
    inputs = _signal(system, (0.0, 0.0, 0.05), (1000.0,) * 3, (1.0, 2.0, 3.0))
    times = np.linspace(0.0, 1.0, 21)
    coarse = Solver(system, SolverOptions(compiled=False)).solve(times, inputs=inputs(times))
    fine_times = np.linspace(0.0, 1.0, 20_001)
    fine = Solver(from_module(excavator, "digging")).solve(fine_times, inputs=inputs(fine_times))
    assert np.abs(_points(system, coarse.q) - _points(system, fine.q[::1000])).max() <= 1e-9


@pytest.mark.parametrize("compiled", [True, False])
def test_a_jump_in_a_time_function_stops_with_an_error_naming_what_was_observed(tmp_path, compiled):
    """A crank angle that jumps by 1 rad within a microsecond: however often the step is halved,
    the inputs move too far within it -- the solve stops there (exit 3), the rows before it kept."""
    model = tmp_path / "jump.yaml"
    model.write_text((MODELS / "slider_crank.yaml").read_text().replace("0.3 + 2*pi*t + 0.5*t**2", "0.3 + 0.5*tanh(1e7*(t - 0.5))"))
    module = load_module(build(model, "quaternion", tmp_path), model)
    system = from_module(module, compiled=compiled)
    if compiled and system.native is None:
        pytest.skip("no C compiler")
    with pytest.raises(BranchError) as caught:
        Solver(system).solve()
    assert caught.value.exit_code == 3 and caught.value.t0 <= 0.5 <= caught.value.t1
    assert "continuation bound fails" in str(caught.value) and "alpha * omega" in str(caught.value)
    assert "the input crank_angle moves too much within the step" in str(caught.value)
    stopped = Solver(system, SolverOptions(on_failure="stop")).solve()
    assert stopped.converged[:-1].all() and not stopped.converged[-1] and stopped.times[-1] >= 0.5
    assert np.isnan(stopped.q[-1]).all()


@needs_cc
def test_a_motion_through_the_toggle_is_refused_naming_the_block_and_its_bodies(excavator):
    system = from_module(excavator, "bucket_toggle")
    with pytest.raises(KinegenError) as caught:
        Solver(system).solve()
    assert caught.value.exit_code == 3
    text = str(caught.value)
    if isinstance(caught.value, BranchError):
        assert "bodies" in text and "bucket" in text


@needs_cc
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    amplitudes=st.tuples(*[st.floats(0.0, 0.08)] * 3),
    cycles=st.tuples(*[st.floats(0.5, 20.0)] * 3),  # up to the 41-point grid's Nyquist rate (20 cycles)
    phases=st.tuples(*[st.floats(0.0, 6.28)] * 3),
)
def test_random_input_signals_come_back_right_or_not_at_all(excavator, amplitudes, cycles, phases):
    system = from_module(excavator, "digging")
    inputs = _signal(system, amplitudes, tuple(2 * np.pi * c for c in cycles), phases)
    _rows_equal_the_fine_solve_or_refuse(system, inputs, 41, TIGHT)


# ---- certified along the case's own time functions (issue 38) ----------------------------------
#: the oscillation case's fine grid: 200 x finer than its 211-point grids (h = 2/42000 s, 0.016 rad of phase a step)
FINE_STEPS = 42_000


@pytest.fixture(scope="module")
def oscillation_reference(excavator):
    """The oscillation case (every input at 270-330 rad/s) solved on a 2/42000 s grid: the body points."""
    system = from_module(excavator, "oscillation")
    fine = Solver(system, TIGHT).solve(np.linspace(0.0, 2.0, FINE_STEPS + 1))
    return fine.q, _points(system, fine.q)


@needs_cc
@pytest.mark.parametrize("count", [101, 106, 151, 176, 201, 421])
def test_every_input_oscillating_fast_comes_back_right_or_not_at_all(excavator, oscillation_reference, count):
    """Four inputs at 270-330 rad/s on grids of 101-421 points (1-7 rad of phase a step): kinegen
    before issue 38 returned these rows 2.8-7.8 m off the fine solve, certified. Now every row
    equals the fine solve's (1e-9 m) or the solve refuses; without the certificate they are off."""
    system = from_module(excavator, "oscillation")
    times = np.linspace(0.0, 2.0, count)
    fine = oscillation_reference[1][:: FINE_STEPS // (count - 1)]
    try:
        results = Solver(system).solve(times)
    except BranchError:
        return
    assert np.abs(_points(system, results.q) - fine).max() <= 1e-9
    try:
        blind = Solver(system, SolverOptions(keep_branch=False)).solve(times)
        assert np.abs(_points(system, blind.q) - fine).max() > 1e-3
    except KinegenError:
        pass


def test_every_input_oscillating_fast_in_pure_python(excavator, oscillation_reference):
    """The Python runtime's certificate (its own enclosures, its own halving) over the first 0.2 s on
    the 101-point grid's steps, whose rows kinegen before issue 38 returned 2.7 m off."""
    q, points = oscillation_reference
    system = from_module(excavator, "oscillation", compiled=False)
    results = Solver(system, SolverOptions(compiled=False)).solve(np.linspace(0.0, 0.2, 11), q0=q[0])
    assert np.abs(_points(system, results.q) - points[:4201:420]).max() <= 1e-9


@pytest.mark.parametrize("compiled", [True, False])
def test_an_excursion_between_two_time_points_is_not_certified(tmp_path, compiled):
    """The slider pushed to x = 0.9 m between every two time points and back to 0.6 m at each (its
    samples and rates say it stands still, the crank cannot reach past 0.8 m): the solve refuses,
    where the cubic path of the samples certified every row."""
    model = tmp_path / "excursion.yaml"
    model.write_text((MODELS / "slider_crank.yaml").read_text().replace("function: 0.8 - 0.1*t**2", "function: 0.6 + 0.3*sin(10*pi*t)**2")
                     .replace("t0: -1", "t0: 0").replace("t1: 0\n", "t1: 1\n").replace("steps: 101", "steps: 11"))  # fmt: skip
    module = load_module(build(model, "quaternion", tmp_path), model)
    system = from_module(module, "dead_centre", compiled=compiled)
    if compiled and system.native is None:
        pytest.skip("no C compiler")
    u, ud, udd = system.driver_inputs(np.linspace(0.0, 1.0, 11))
    assert np.allclose(u, 0.6) and np.allclose(ud, 0.0, atol=1e-12)
    # as a table (values, rates and accelerations of the samples) the path between them is the samples' cubic:
    # the rows come back, and the table's accelerations (2 x 0.3 x (10 pi)^2) disagree with that path: a warning
    with pytest.warns(SamplingWarning, match="slider_x"):
        tabled = Solver(system, SolverOptions(compiled=compiled)).solve(np.linspace(0.0, 1.0, 11), inputs=(u, ud, udd))
    assert tabled.converged.all()
    with pytest.raises(KinegenError) as caught:
        Solver(system, SolverOptions(compiled=compiled)).solve()
    assert caught.value.exit_code in (3, 4) and caught.value.t < 0.1


#: a module of every parametrization family, the excavator's with every driver kind (joint angle, distance)
NU_MODULES = ["excavator_quaternion", "excavator_euler_zxz", "slider_crank_dual_quaternion", "rssr_euler_parameters"]


@pytest.mark.parametrize("stem", NU_MODULES)
def test_one_nu_call_holds_every_column_of_phi_u(stem):
    """The certificates read Phi_u off one nu(q, u, 1): in every case the drivers' rows come last
    in the inputs' order, and nu(q, u, e_k) -- what the certificate took before, one call per
    input -- is zero off driver k's row and there equal to the bit to nu(q, u, 1)'s (away from a
    solution: q and u perturbed)."""
    module = load_module(GENERATED / f"{stem}.py")
    rng = np.random.default_rng(7)
    for case in module.CASES:
        system = from_module(module, case, compiled=False)
        n, first = system.n_inputs, len(system.constraint_names) - system.n_inputs
        q = system.initial_q + 0.05 * rng.standard_normal(system.n_stored)
        u = system.driver_inputs(np.array([system.t0]))[0][:, 0] + 0.1 * rng.standard_normal(n)
        together = system.velocity_rhs(q, u, np.ones(n))
        for k in range(n):
            alone = system.velocity_rhs(q, u, np.eye(n)[k])
            expected = np.zeros_like(alone)
            expected[first + k] = together[first + k]
            assert np.array_equal(alone, expected), (stem, case, system.driver_names[k])
        assert not together[:first].any()


def test_a_system_whose_drivers_are_not_last_is_refused(excavator):
    import dataclasses

    system = from_module(excavator, compiled=False)
    names = system.constraint_names
    with pytest.raises(ValueError, match="drivers' rows must come last"):
        dataclasses.replace(system, constraint_names=names[-1:] + names[:-1])


@pytest.mark.parametrize("case", ["digging", "level_cut"])
def test_the_grids_chord_deviations_are_each_steps_own_and_bound_the_inputs_between_samples(excavator, case):
    """The Python certificate takes the chord deviations of a whole grid in one pass: each step's
    equal to the bit to its own call's (what a halved step computes), and each a bound on how far
    the case's functions, sampled 200 times within the step, stray from the chord between its ends.
    Where the deviation is the curvature's, its split holds at every sample too: the error is
    -(4 sigma / h^2)(curve + delta), |delta| <= beyond, sigma = (s - t0)(t1 - s)."""
    from kinegen.runtime.solver import chord_bounds

    system = from_module(excavator, case, compiled=False)
    times = np.linspace(system.t0, system.t1, 41)
    u = system.driver_inputs(times)[0]
    ranges = np.asarray(system.input_ranges((times[:-1], times[1:])), dtype=float).reshape(-1, len(times) - 1)
    together = chord_bounds(ranges, np.diff(times), u[:, 1:], np.diff(u, axis=1))
    moving = split = 0
    for i in range(len(times) - 1):
        h = times[i + 1] - times[i]
        alone = chord_bounds(ranges[:, i], h, u[:, i + 1], u[:, i + 1] - u[:, i])
        assert np.array_equal(together[:, :, i], alone), i
        deviation, curve, beyond = alone
        fine = np.linspace(times[i], times[i + 1], 201)
        chord = u[:, [i]] + (fine - times[i]) / h * (u[:, [i + 1]] - u[:, [i]])
        error = system.driver_inputs(fine)[0] - chord
        assert np.isfinite(alone).all() and (np.abs(error).max(axis=1) <= deviation + 1e-15).all(), (i, error, deviation)
        weight = 4.0 * (fine - times[i]) * (times[i + 1] - fine) / h**2  # 4 sigma / h^2, in [0, 1]
        assert (np.abs(error + weight * curve[:, None]) <= weight * beyond[:, None] + 1e-15).all(), i
        assert (np.abs(curve) + beyond <= deviation * (1 + 1e-12)).all(), i
        moving += int((np.abs(error).max(axis=1) > 0).sum())
        split += int((curve != 0).sum())
    assert moving > 0 and split > 0  # the functions do curve between samples, and their curvature is bounded


def test_the_split_deviations_bound_is_never_above_the_deviations_own():
    """The exact bound with the curvature's split, |W D| + max(|W curve| + |W| beyond), is never above
    |W D| + max(|W| c) (the chord deviations alone), for any W: random columns, changes and splits."""
    from kinegen.runtime.solver import input_effect

    rng = np.random.default_rng(7)
    for _ in range(200):
        nv, ni = rng.integers(1, 12), rng.integers(1, 6)
        w = rng.normal(size=(nv, ni)) * 10.0 ** rng.integers(-3, 3, size=ni)
        u0, u1 = rng.normal(size=ni), rng.normal(size=ni)
        curve, beyond = rng.normal(size=ni) * 1e-3, rng.uniform(0, 1e-3, size=ni)
        c = np.abs(curve) + beyond
        start, end = (u0, np.zeros(ni)), (u1, np.zeros(ni))
        split, _ = input_effect(lambda which, w=w: w[:, which], 0.1, start, end, np.stack((c, curve, beyond)))
        whole, _ = input_effect(lambda which, w=w: w[:, which], 0.1, start, end, np.stack((c, np.zeros(ni), c)))
        assert split <= whole * (1 + 1e-12)


@needs_cc
def test_the_shipped_cases_are_never_subdivided(excavator):
    """The certificate holds for every whole step of the smooth shipped cases: no step is halved."""
    for case in ("digging", "level_cut", "trench_wall"):
        system = from_module(excavator, case)
        results = Solver(system).solve()
        plain = Solver(system, SolverOptions(max_refinements=0)).solve()
        assert np.array_equal(results.q, plain.q) and results.converged.all()


@needs_cc
def test_from_rest_along_a_smooth_path_the_c_solver_does_not_cry_wolf(excavator, tmp_path):
    """Driven from rest (zero rates at the start) along smooth paths on a 41-point grid: no step is
    refused in C or in Python, with or without refinements, and det(Phi_q) keeps its sign."""
    system = from_module(excavator, "digging")
    start = system.driver_inputs(np.array([system.t0]))[0][:, 0]
    times = np.linspace(0.0, 1.0, 41)
    rng = np.random.default_rng(7)
    for _ in range(11):
        stroke = rng.uniform(-0.25, 0.25, 3)
        u = np.repeat(start[:, None], len(times), axis=1)
        shape, rate = (1 - np.cos(np.pi * times)) / 2, np.pi * np.sin(np.pi * times) / 2
        u[1:] += stroke[:, None] * shape
        ud, udd = np.zeros_like(u), np.zeros_like(u)
        ud[1:], udd[1:] = stroke[:, None] * rate, stroke[:, None] * np.pi**2 * np.cos(np.pi * times) / 2
        for compiled in (True, False):
            results = Solver(system, SolverOptions(max_refinements=0, compiled=compiled)).solve(times, inputs=(u, ud, udd))
            assert results.converged.all()


# ---- user text never runs ----------------------------------------------------------------------
HOSTILE = [
    'x""";open("MARKER","w");"""',
    "a'''b\\\\c\\nd",
    "line\nbreak \"\"\"\nimport os",
    "end*/ int evil; /*",
    "#define phi_jac evil",
    "trigraph??/ \"quote",
    "m\u00e9canisme \u2603 \U0001f40d",
]


def _normalized(text: str) -> str:
    """The AST of a module with every string constant emptied: its structure and numbers."""
    tree = ast.parse(text)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            node.value = ""
    return ast.dump(tree)


def test_hostile_file_names_build_into_the_same_code_and_nothing_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    source = (MODELS / "slider_crank.yaml").read_text()
    harmless = tmp_path / "plain" / "slider.yaml"
    harmless.parent.mkdir()
    harmless.write_text(source)
    reference = build(harmless, "quaternion", harmless.parent)
    expected = _normalized(reference.read_text())
    c_reference = reference.with_suffix(".c").read_text()
    for index, name in enumerate(n.replace("/", "|") for n in HOSTILE):  # (no file name holds a slash)
        folder = tmp_path / f"hostile{index}"
        folder.mkdir()
        model = folder / f"{name}.yaml"
        model.write_text(source)
        module_path = build(model, "quaternion", folder)
        text = module_path.read_text()
        assert _normalized(text) == expected, name
        module = load_module(module_path, model)
        assert module.SOURCE == model.name
        c_text = module_path.with_suffix(".c").read_text()
        # the header comment ends where the harmless one does: user text cannot close it
        assert c_text.split("*/", 2)[1].count("\n") == c_reference.split("*/", 2)[1].count("\n")
        assert "??" not in c_text and not any(line.startswith("#define phi_jac") for line in c_text.splitlines())
        if CC is not None:
            system = from_module(module, compiled=True)
            assert system.native is not None
            assert Solver(system).solve().converged.all()
        assert not (tmp_path / "MARKER").exists() and not (folder / "MARKER").exists()


def test_escapes_leave_no_way_out_of_a_comment_or_a_string():
    for name in HOSTILE:
        shown = comment_text(name)
        assert shown.isascii() and not any(c in shown for c in "\"'*/?\n\r") and "\\" not in shown.replace("\\x", "").replace("\\u", "").replace("\\U", "")
        literal = c_string(name)
        assert literal.isascii() and "?" not in literal and "\n" not in literal
        body = literal[1:-1]
        assert '"' not in body.replace('\\"', "") and all(part[:3].isdigit() for part in body.split("\\")[1:])


# ---- modules and libraries are verified before they run --------------------------------------
@pytest.fixture
def built(tmp_path, tmp_path_factory, monkeypatch):
    """The four-bar built afresh, with a cache of this test process's own: the tests that use it damage
    what kinegen keeps there (a module's code, a compiled library), which no other test may load."""
    monkeypatch.setenv("KINEGEN_CACHE", str(cache_with_solver(tmp_path_factory.getbasetemp() / "kinegen-cache")))
    model = tmp_path / "four_bar.yaml"
    shutil.copy(MODELS / "four_bar.yaml", model)
    return model, build(model, "quaternion", tmp_path / "generated")


def test_an_edited_module_is_refused_before_it_runs(built, tmp_path):
    """Edited, with a seal line recomputed over the new text as the old files carried (what issue 38
    found running), or truncated: refused (exit 5) as changed since kinegen wrote it, nothing runs --
    by the Session too, which rebuilds a stale module but never one that was changed."""
    model, path = built
    text = path.read_text()
    edited = text.replace("INITIAL_Q = (", "INITIAL_Q = (1.0 + ", 1) + f"\nopen({str(tmp_path / 'RAN')!r}, 'w')\n"
    forged = f"# kinegen: sha256 of the rest of this file: {hashlib.sha256(edited.encode()).hexdigest()}\n{edited}"
    unknown = text.replace("parametrization: quaternion", "parametrization: !quaternion", 1)  # (found by the fuzzer)
    other = text.replace("parametrization: quaternion", "parametrization: euler-parameters", 1)
    for changed in (edited, forged, text[: len(text) // 2], unknown, other):
        path.write_text(changed)
        with pytest.raises(ChangedFileError, match="changed since kinegen wrote it") as caught:
            load_module(path, model)
        assert caught.value.exit_code == 5 and "kinegen build" in str(caught.value) and "nothing in it ran" in str(caught.value)
        with pytest.raises(ChangedFileError):
            Session(path.parent).module(model, "quaternion")
        assert path.read_text() == changed  # never rebuilt over
    assert not (tmp_path / "RAN").exists()


def test_a_module_from_elsewhere_is_verified_by_regenerating_it_once(built, tmp_path, monkeypatch):
    """A module kinegen wrote for another account (a fresh store): regenerated from its model to the
    same bytes, then remembered -- the second load does not regenerate."""
    model, path = built
    monkeypatch.setenv("KINEGEN_TRUST", str(tmp_path / "another-store"))
    monkeypatch.setattr(integrity, "_KNOWN", set())
    calls = []
    original = writer._regenerates
    monkeypatch.setattr(writer, "_regenerates", lambda *a: calls.append(a) or original(*a))
    assert load_module(path, model).MODEL == "four_bar"
    assert load_module(path).MODEL == "four_bar"  # its bytes now in the store: no model needed
    assert len(calls) == 1


def test_a_planted_or_foreign_version_module_is_refused(built, tmp_path):
    model, path = built
    planted = path.with_name("planted.py")
    planted.write_text(f"open({str(tmp_path / 'RAN')!r}, 'w')\nMODEL = 'x'\n")
    with pytest.raises(ChangedFileError, match="did not write these bytes"):
        load_module(planted)
    # with the model's own header, pretending to be its module
    path.write_text(path.read_text().split("\nMODEL =", 1)[0] + f"\nopen({str(tmp_path / 'RAN')!r}, 'w')\nMODEL = 'x'\n")
    with pytest.raises(ChangedFileError, match="changed since kinegen wrote it"):
        load_module(path, model)
    assert not (tmp_path / "RAN").exists()
    build(model, "quaternion", path.parent)
    path.write_text(path.read_text().replace(f"kinegen version: {kinegen.__version__}", "kinegen version: 0.0.9", 1))
    with pytest.raises(GeneratedModuleError, match=r"built by kinegen 0\.0\.9"):
        load_module(path, model)


def test_a_module_rebuilt_at_once_is_the_new_one(tmp_path):
    """No time stamps: a module replaced within the same second by one of the same size runs as written
    (its code is kept by its source's digest, never beside it in __pycache__)."""
    folder = tmp_path / "generated"
    first, second = tmp_path / "one" / "m.yaml", tmp_path / "two" / "m.yaml"
    for path, length in ((first, "0.3"), (second, "0.4")):
        path.parent.mkdir()
        path.write_text((MODELS / "slider_crank.yaml").read_text().replace("0.3", length, 1))
    module_path = build(first, "quaternion", folder)
    before = load_module(module_path, first)
    build(second, "quaternion", folder)
    after = load_module(module_path, second)
    assert before.SOURCE_SHA256 != after.SOURCE_SHA256 == hashlib.sha256(second.read_bytes()).hexdigest()
    assert not list(folder.glob("__pycache__"))


def test_a_modules_kept_code_runs_only_when_kinegen_wrote_it(built, tmp_path, monkeypatch):
    """A module's code, compiled once, is kept in the cache and loaded without compiling, under the
    module's own file name; planted code (doing something else) or truncated code in its place is
    never loaded: the verified source is compiled again and its code kept anew."""
    import marshal

    from kinegen.runtime import bytecode

    model, path = built
    load_module(path, model)  # compiled (or loaded, if kept already under this trust store)
    kept = bytecode._path(path.read_text())
    assert integrity.trusted(kept.read_bytes())
    compiled = []
    monkeypatch.setattr(bytecode, "compile", lambda *a: compiled.append(a[1]) or compile(*a), raising=False)
    module = load_module(path, model)
    assert compiled == [] and module.MODEL == "four_bar"
    assert {f.__code__.co_filename for f in vars(module).values() if callable(f) and hasattr(f, "__code__")} == {str(path)}
    planted = marshal.dumps([compile(f"open({str(tmp_path / 'RAN')!r}, 'w')\nMODEL = 'x'\n", str(path), "exec")])
    for damaged in (planted, kept.read_bytes()[:1000]):
        kept.write_bytes(damaged)
        compiled.clear()
        again = load_module(path, model)
        assert again.MODEL == "four_bar" and len(compiled) == len(bytecode.parts(path.read_text())) > 1
        assert integrity.trusted(kept.read_bytes()) and not (tmp_path / "RAN").exists()


def test_a_build_asked_for_again_is_taken_from_the_cache_only_when_kinegen_kept_it(tmp_path, monkeypatch):
    """The same build into another folder derives nothing and writes the bytes of the committed
    module and its C; a kept entry with planted code (run by the pre-write check if it were used)
    or truncated is passed by and derived anew; a changed model is another build."""
    import json

    from kinegen.codegen import kept
    from kinegen.runtime import check_source

    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    model = tmp_path / "four_bar.yaml"
    shutil.copy(MODELS / "four_bar.yaml", model)
    derived = []
    original = writer.generate
    monkeypatch.setattr(writer, "generate", lambda *a, **k: derived.append(a[1].name) or original(*a, **k))
    names = ("four_bar_quaternion.py", "four_bar_quaternion.c", "four_bar_quaternion.h")

    def built_into(folder: str) -> None:
        build(model, "quaternion", tmp_path / folder, check=check_source)
        for name in names:
            assert (tmp_path / folder / name).read_bytes() == (GENERATED / name).read_bytes(), (folder, name)

    built_into("one")
    built_into("two")
    assert derived == ["quaternion"]
    (entry,) = (tmp_path / "cache" / "builds").iterdir()
    made = json.loads(entry.read_text())
    made["python"][names[0]] += f"\nopen({str(tmp_path / 'RAN')!r}, 'w')\n"
    for damaged in (json.dumps(made), entry.read_text()[:1000]):
        entry.write_text(damaged)
        derived.clear()
        built_into("three")
        assert derived == ["quaternion"] and not (tmp_path / "RAN").exists()
        assert kept.kept(entry.stem, ("python", "c-model")) is not None  # derived anew and kept again
    text = model.read_text()
    model.write_text(text.replace("M: [0.45,", "M: [0.46,", 1))
    assert model.read_text() != text
    derived.clear()
    build(model, "quaternion", tmp_path / "four", check=check_source)
    assert derived == ["quaternion"] and len(list((tmp_path / "cache" / "builds").iterdir())) == 2


@needs_cc
def test_an_edited_c_file_is_refused_by_the_same_rule(built):
    model, path = built
    c_file = path.with_suffix(".c")
    c_file.write_text(c_file.read_text().replace("static", "static ", 1))
    with pytest.raises(ChangedFileError, match="changed since kinegen wrote it") as caught:
        from_module(load_module(path, model), compiled=True)
    assert caught.value.exit_code == 5


@needs_cc
def test_a_tampered_or_truncated_cached_library_is_rebuilt_never_loaded(built):
    model, path = built
    module = load_module(path, model)
    sources = native_module._model_sources(module)
    library = native_module.build_library(sources)
    original = library.read_bytes()
    for damaged in (original[: len(original) // 3], original[:-64] + b"\0" * 64):
        library.write_bytes(damaged)
        assert native_module.build_library(sources) == library
        assert library.read_bytes() == original
    library.write_bytes(original[:100])
    with pytest.raises(native_module.CompileError, match="not one kinegen compiled"):
        native_module._load(library)
    # a planted library with a digest written beside it, as the old record was: rebuilt, its constructor never runs
    planted = library.with_name("planted.c")
    planted.write_text(f'#include <stdio.h>\n__attribute__((constructor)) static void run(void) {{ fopen("{library.parent / "RAN"}", "w"); }}\n')
    subprocess.run([CC, "-shared", "-fPIC", "-o", str(library), str(planted)], check=True)
    library.with_name(library.name + ".sha256").write_text(hashlib.sha256(library.read_bytes()).hexdigest())
    assert native_module.build_library(sources) == library and library.read_bytes() == original
    assert not (library.parent / "RAN").exists()


def test_concurrent_builds_sharing_the_cache_all_succeed_and_compile_each_object_once(tmp_path):
    """Four processes build one model's library into one cache at once: each gets a whole library,
    no temporary is left, and each object file is compiled once -- a process that needs an object
    another is compiling waits for it (the compiler, wrapped, writes down every compile)."""
    if CC is None:
        pytest.skip("no C compiler")
    log, wrapper = tmp_path / "compiles.log", tmp_path / "logging-cc"
    wrapper.write_text(f'#!/bin/sh\ncase " $* " in *" -c "*) echo "$*" >> {log} ;; esac\nexec {CC} "$@"\n')
    wrapper.chmod(0o755)
    script = (
        "import sys; from kinegen.runtime import native, load_module;"
        f"m = load_module({str(GENERATED / 'slider_crank_quaternion.py')!r});"
        "native.build_library(native._model_sources(m)); print('ok')"
    )
    env = {**__import__("os").environ, "KINEGEN_CACHE": str(tmp_path / "shared-cache"), "CC": str(wrapper)}
    runs = [subprocess.Popen([__import__("sys").executable, "-c", script], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(4)]
    outputs = [run.communicate(timeout=300) for run in runs]
    assert all(run.returncode == 0 for run in runs), [o[1][-600:] for o in outputs]
    assert not [p for p in (tmp_path / "shared-cache").rglob("tmp*")]
    objects = list((tmp_path / "shared-cache" / "objects").glob("*.o"))
    compiled = log.read_text().splitlines()
    assert len(objects) >= 2 and len(compiled) == len(objects), compiled  # the solver's and the model's: once each


def test_a_model_read_again_is_the_kept_one_and_nothing_kinegen_did_not_keep_is_loaded(tmp_path, monkeypatch):
    """A model read once is kept (kinegen.model.kept): the same bytes under the same name read
    again give an equal model without parsing, with the warnings reading gave; a planted pickle
    (code that runs when loaded) or a truncated one in its place is never loaded: the file is read
    again and kept anew. Other bytes, or the same bytes under another name, are another model; a
    model that fails keeps nothing."""
    import pickle
    import warnings

    from kinegen.errors import ModelError
    from kinegen.model import ModelWarning, kept, loader, loads
    from tests.test_model_validation import BASE

    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    assert "{quaternion: [1, 0, 0, 0]}" in BASE and "type: revolute" in BASE
    text = BASE.replace("{quaternion: [1, 0, 0, 0]}", "{quaternion: [2, 0, 0, 0]}")  # normalized, with a ModelWarning
    reads = []
    read = loader._read
    monkeypatch.setattr(loader, "_read", lambda data, file: reads.append(file) or read(data, file))

    def load_said(name: str = "arm.yaml"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model = loads(text, name)
        return model, [str(w.message) for w in caught if issubclass(w.category, ModelWarning)]

    first, said = load_said()
    assert reads == ["arm.yaml"] and any("normalized" in message for message in said)
    stored = kept._path(text.encode(), "arm.yaml")
    assert integrity.trusted(stored.read_bytes())
    again, said_again = load_said()
    assert reads == ["arm.yaml"] and again == first and again is not first and said_again == said
    planted = pickle.dumps(ShellCommand(f"touch {tmp_path / 'RAN'}"))
    for damaged in (planted, stored.read_bytes()[:200]):
        stored.write_bytes(damaged)
        reads.clear()
        model, _ = load_said()
        assert reads == ["arm.yaml"] and model == first and not (tmp_path / "RAN").exists()
        assert integrity.trusted(stored.read_bytes())
    reads.clear()
    assert load_said("other_name.yaml")[0].file == "other_name.yaml" and reads == ["other_name.yaml"]
    broken = text.replace("type: revolute", "type: revolving", 1)
    for _ in range(2):
        with pytest.raises(ModelError, match="revolving"):
            loads(broken, "broken.yaml")
    assert not kept._path(broken.encode(), "broken.yaml").exists()


class ShellCommand:
    """An object whose unpickling runs a shell command (what a planted pickle can do)."""

    def __init__(self, command: str) -> None:
        self.command = command

    def __reduce__(self):
        import os

        return (os.system, (self.command,))
