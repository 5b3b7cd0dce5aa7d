"""Proving, locating and classifying singularities (issue 4).

* the boom: euler:zxz is a representation singularity (exact rank 5, factor sin(beta));
* a slider-crank at top dead centre: a mechanism singularity in every parametrization;
* a spatial four-bar with four revolute joints: 3 redundant, consistent equations;
* the excavator: euler:zxz singular in the upper structure's block (sin(upper_beta)),
  quaternion, dual-quaternion and dual-euler-parameters provably non-singular (every block
  determinant non-zero), none of them flagged by the scan of the digging cycle;
* the bucket linkage driven towards its toggle: the scan warns before the solve fails.
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import sympy as sp

from kinegen import rotations
from kinegen.analysis import inspect
from kinegen.analysis.classify import MECHANISM, REDUNDANT, REPRESENTATION, classify
from kinegen.analysis.scan import scan, warning_lines
from kinegen.codegen.inmemory import lambdify_model
from kinegen.model import loads
from kinegen.runtime import from_module, solve
from kinegen.symbolic.blocks import block_triangular
from tests.conftest import SLIDER_CRANK_DEAD_CENTRE, generated_system, model

ALL_REVOLUTE_FOUR_BAR = """\
model: four_bar_rrrr
redundant: true
ground:
  points: {A: [0, 0, 0], D: [1, 0, 0]}
  vectors: {z: [0, 0, 1]}
bodies:
  crank: {position: [0, 0, 0], orientation: {axis: [0, 0, 1], angle: 0.5}, points: {A: [0, 0, 0], B: [0.3, 0, 0]}, vectors: {z: [0, 0, 1]}}
  coupler: {position: [0.263275, 0.143828, 0], orientation: {axis: [0, 0, 1], angle: 0.665327}, points: {B: [0, 0, 0], C: [0.9, 0, 0]}, vectors: {z: [0, 0, 1]}}
  rocker: {position: [1, 0, 0], orientation: {axis: [0, 0, 1], angle: 1.611781}, points: {D: [0, 0, 0], C: [0.7, 0, 0]}, vectors: {z: [0, 0, 1]}}
joints:
  A: {type: revolute, bodies: [ground, crank], points: [A, A], axes: [z, z]}
  B: {type: revolute, bodies: [crank, coupler], points: [B, B], axes: [z, z]}
  C: {type: revolute, bodies: [coupler, rocker], points: [C, C], axes: [z, z]}
  D: {type: revolute, bodies: [ground, rocker], points: [D, D], axes: [z, z]}
cases:
  turn:
    drivers:
      crank_angle: {type: joint_angle, joint: A, function: 0.5 + 2*pi*t}
    t1: 1
    steps: 101
"""


def test_block_triangular_form_of_a_known_pattern():
    # [[x, 0, 0], [x, x, 0], [0, x, x]] is lower triangular: three 1x1 blocks in order
    rows, cols = np.array([0, 1, 1, 2, 2]), np.array([0, 0, 1, 1, 2])
    blocks = block_triangular((3, 3), rows, cols)
    assert [b.rows for b in blocks] == [(0,), (1,), (2,)]
    # [[x, x], [x, 0]] permutes to triangular form; a full 2x2 is one block
    assert [b.size for b in block_triangular((2, 2), np.array([0, 0, 1]), np.array([0, 1, 0]))] == [1, 1]
    assert [b.size for b in block_triangular((2, 2), np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1]))] == [2]
    # an empty column is structurally singular
    assert block_triangular((2, 2), np.array([0, 1]), np.array([0, 0])) is None


def test_boom_euler_singularity_is_a_representation_singularity():
    verdict = classify(model("boom"), rotations.get("euler:zxz"), "swing", 0.0)
    assert verdict.kind == REPRESENTATION
    assert any(line.startswith("quaternion: rank 6 of 6 x 6") for line in verdict.evidence)
    # the other parametrizations' systems from their generated modules (as kinegen inspect gives them): the same evidence
    asked = []
    tags = {"quaternion": "quaternion", "euler-parameters": "euler_parameters"}
    from_modules = classify(model("boom"), rotations.get("euler:zxz"), "swing", 0.0,
                            system_of=lambda name: asked.append(name) or generated_system(f"boom_{tags[name]}", "swing"))  # fmt: skip
    assert asked == ["euler-parameters"] and from_modules == verdict


def test_slider_crank_dead_centre_is_a_mechanism_singularity_in_every_parametrization():
    dead_centre = np.array(SLIDER_CRANK_DEAD_CENTRE)
    slider_crank = model("slider_crank")
    verdict = classify(
        slider_crank,
        rotations.get("quaternion"),
        "dead_centre",
        0.0,
        physical=dead_centre,
        others=("euler-parameters", "euler:xyz", "dual-quaternion", "dual-euler-parameters"),
    )
    assert verdict.kind == MECHANISM
    assert verdict.evidence[0].startswith("quaternion: rank 17 of 18 x 18")
    assert any(line.startswith("euler-parameters: rank 20 of 21 x 21") for line in verdict.evidence)
    assert any(line.startswith("euler:xyz: rank 17 of 18 x 18") for line in verdict.evidence)
    assert any(line.startswith("dual-quaternion: rank 17 of 18 x 18") for line in verdict.evidence)
    assert any(line.startswith("dual-euler-parameters: rank 23 of 24 x 24") for line in verdict.evidence)
    assert all("rank 18" in line for line in verdict.evidence if line.startswith("nearby"))  # regular a little away
    report = inspect(slider_crank, rotations.get("quaternion"), "dead_centre", "0", dead_centre)
    assert [b.bodies for b in report.singular_blocks] == [["crank", "rod"]]
    # the text report's inspection (kinegen inspect without --json, --det-file) derives only the singular
    # blocks' symbolic determinants: the same text, the same singular block, no regular block's determinant
    shown = inspect(slider_crank, rotations.get("quaternion"), "dead_centre", "0", dead_centre, every_block=False)
    assert shown.text() == report.text() and shown.singular_blocks == report.singular_blocks
    regular = [(a, b) for a, b in zip(report.blocks, shown.blocks) if not a.singular]
    assert len(regular) == 10 and all(a.determinant is not None and b.determinant is None for a, b in regular)


def test_spatial_all_revolute_four_bar_has_three_redundant_consistent_equations():
    four_bar = loads(ALL_REVOLUTE_FOUR_BAR, "four_bar_rrrr.yaml")
    quaternion = rotations.get("quaternion")
    system = from_module(lambdify_model(four_bar, quaternion))
    assert (len(system.constraint_names), system.n_velocity) == (21, 18)
    results = solve(system)  # least squares on the consistent, redundant equations
    assert results.residuals.max() <= 1e-10
    verdict = classify(four_bar, quaternion, "turn", 0.3, numeric=system)
    assert verdict.kind == REDUNDANT
    assert "3 equation(s) depend on the others" in verdict.evidence[-1]
    assert {"A.z", "B.z", "C.z", "D.z"} <= set(verdict.dependent_constraints)


def test_excavator_euler_zxz_singular_block_names_the_upper_structure():
    report = inspect(
        model("excavator"),
        rotations.get("euler:zxz"),
        "digging",
        "0",
        numeric=generated_system("excavator_quaternion", "digging"),
        every_block=False,  # (the regular blocks' symbolic determinants: the JSON report's, not asserted here)
    )
    assert report.singular
    (block,) = report.singular_blocks
    assert block.bodies == ["upper"]
    beta = sp.Symbol("upper_beta", real=True)
    assert block.vanishing_factors == [sp.sin(beta)]
    assert report.null_space == ["upper.alpha - upper.gamma"]


@pytest.mark.parametrize(("param", "size"), [("quaternion", 84), ("dual-quaternion", 84), ("dual-euler-parameters", 112)])
def test_excavator_jacobian_is_provably_non_singular_in_the_tangent_space_and_dual_forms(param, size):
    """Block by block, every determinant exactly non-zero at t = 0 (issue 4; issue 12 for the
    dual-quaternion parametrizations)."""
    report = inspect(
        model("excavator"),
        rotations.get(param),
        "digging",
        "0",
        numeric=generated_system("excavator_quaternion", "digging"),
        every_block=False,  # (the regular blocks' symbolic determinants: the JSON report's, not asserted here)
    )
    assert not report.singular and report.rank == size
    assert report.blocks and not report.singular_blocks
    assert all(b.value != 0 for b in report.blocks)


def test_scan_warns_before_the_bucket_linkage_reaches_its_toggle():
    physical = generated_system("excavator_quaternion", "bucket_toggle")
    result = scan(
        physical, {"quaternion": physical, "euler-parameters": generated_system("excavator_euler_parameters", "bucket_toggle")}
    )
    toggle_time = (2.7366037634564986 - 2.5) / 0.1  # bucket cylinder at the G-H-J toggle length
    assert result.stopped is not None  # the solve cannot pass the toggle
    assert result.ahead_time is not None and result.ahead_time < result.times[-1] < toggle_time + 0.01
    assert "bucket_cyl_barrel, bucket_cyl_rod, side_link" in result.ahead
    assert all(trace.warning is None for trace in result.traces)  # no parametrization is singular on the way
    assert warning_lines(result) == [(result.ahead_time, "mechanism singularity ahead")]  # the plot's dashed line


def test_scan_flags_only_the_euler_singularity_in_the_digging_cycle():
    physical = generated_system("excavator_quaternion", "digging")
    names = ("euler-parameters", "euler:zxz", "dual-quaternion", "dual-euler-parameters")
    systems = {name: generated_system(f"excavator_{name.replace(':', '_').replace('-', '_')}", "digging") for name in names}
    result = scan(physical, systems)
    traces = {trace.parametrization: trace for trace in result.traces}
    assert traces["euler:zxz"].warning_time == 0 and "upper" in traces["euler:zxz"].warning
    for name in ("quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters"):
        assert traces[name].warning is None, name
    assert result.ahead is None and result.stopped is None


def test_a_determinants_size_is_counted_as_sympy_counts_it_and_no_further_than_needed():
    """``operations_up_to`` gives SymPy's ``count_ops`` up to its limit (sums of every sign pattern,
    fractions, functions, all-negative sums), and above the limit some count above it -- what
    decides whether a determinant is expanded, factored or left as it is."""
    import importlib

    operations_up_to = importlib.import_module("kinegen.analysis.inspect").operations_up_to
    x, y, z = sp.symbols("x y z", real=True)
    rng = np.random.default_rng(7)
    coefficients = [-3, -1, 1, 2, sp.Rational(-1, 2), sp.Rational(5, 3)]
    factors = [x, y, x * y, 1 / x, sp.sin(z), x**2, (x - y) / z, sp.exp(-x), sp.sqrt(y + 1)]
    expressions = [-x - y, -x + y, x - y, -1 - x, -(x + y) / z - 1, sp.Rational(-1, 2) * x - sp.Rational(1, 3)]
    for _ in range(200):
        count = int(rng.integers(2, 8))
        expressions.append(sp.Add(*(coefficients[rng.integers(6)] * factors[rng.integers(9)] for _ in range(count))))
    for expression in expressions:
        exact = sp.count_ops(expression)
        assert operations_up_to(expression, 10**9) == exact, expression
        for limit in (0, 3, exact - 1, exact):
            assert (operations_up_to(expression, limit) > limit) == (exact > limit), (expression, limit)


def test_exact_numbers_are_the_simple_forms_decimals_and_rationals_they_stand_for_never_floats():
    from kinegen.analysis.inspect import exact_number

    rng = np.random.default_rng(7)
    simple = [sp.Rational(int(p), int(q)) for p, q in zip(rng.integers(-999, 1000, 40), rng.integers(1, 1000, 40))]
    simple += [sp.sqrt(int(n)) / int(m) for n, m in zip(rng.choice([2, 3, 5, 6, 7, 10, 11], 20), rng.integers(1, 31, 20))]  # (m^2 x^2 - n = 0: coefficients within 1000)
    simple += [(int(a) + int(b) * sp.pi) / int(c) for a, b, c in zip(rng.integers(-9, 10, 20), rng.integers(1, 10, 20), rng.integers(1, 13, 20))]
    simple += [sp.pi / 2, -sp.pi / 2, sp.sqrt(2) / 2, (1 + sp.sqrt(5)) / 2]
    for number in simple:  # each its own simplest form, from its double (the solver's values: within 1e-15 of it)
        assert sp.simplify(exact_number(float(number)) - number) == 0, number
        for ulps in (-2, 1, 3):  # a solved value: a few units in the last place off
            off = float(number) + ulps * np.spacing(float(number))
            assert sp.simplify(exact_number(off) - number) == 0, (number, ulps)
    for figure in ("0.22767", "1.95729", "-0.786562", "0.58502", "2.00192", "0.6891200000000008"):  # a model's decimals
        assert exact_number(float(figure)) == sp.Rational(repr(round(float(figure), 10))), figure
    for value in rng.uniform(-10, 10, 200):  # solved coordinates: no simple form, a rational within 1e-13
        found = exact_number(float(value))
        assert found.is_Rational and not found.atoms(sp.Float), value
        assert abs(found - sp.Rational(float(value))) <= 1e-13 * max(1.0, abs(value)), value
        assert found.q <= 10**13, value  # (small entries: determinants of large blocks stay fast)
    assert exact_number(9e-14) == 0 and exact_number(-3e-14) == 0


@pytest.mark.parametrize(("name", "param"), [("four_bar", "quaternion"), ("slider_crank", "quaternion"), ("four_bar", "euler:zxz"), ("rssr", "euler:zxz")])
def test_the_inspected_configuration_and_jacobian_are_exact(name, param):
    # a solved configuration's coordinates were kept as floats where SymPy's nsimplify found no simple form:
    # the "exact" rank and determinant were then computed in floating point; and a small Phi_q's entries
    # went through nsimplify, which made sin(50847386919/5000000000000) a different number equal to 15 digits
    report = inspect(model(name), rotations.get(param), None, "0")
    assert all(not sp.sympify(x).atoms(sp.Float) for x in report.q), report.q
    assert not report.jacobian.atoms(sp.Float)
    if report.jacobian.shape[1] <= 12:  # (the small ones: each entry the Jacobian's own at the exact configuration)
        values = dict(zip(report.system.coordinates.stored_symbols, report.q))
        values.update(report.system.inputs.at_time(report.t))
        direct = report.system.jacobian_matrix().xreplace(values)
        assert all(abs(sp.N(a - b, 50)) < 1e-40 for a, b in zip(direct, report.jacobian))  # (a look-alike: ~1e-16)
    q = np.array([float(x) for x in report.q])
    system = from_module(lambdify_model(model(name), rotations.get(param)))
    phi, _ = system.evaluate(q, system.driver_inputs(0.0)[0])
    assert np.abs(phi).max() <= 1e-12  # the exact configuration is the solved one, to 1e-13 per value


@pytest.mark.parametrize(("name", "param"), [("rssr", "quaternion"), ("rssr", "euler:zxz"), ("boom", "dual-euler-parameters"), ("slider_crank", "euler:zxz")])
def test_a_determinant_by_blocks_is_the_whole_matrixs(name, param):
    # det Phi_q from the block-triangular form (sign of the row order x sign of the column order x the
    # blocks' determinants) against NumPy's LU determinant of the whole matrix at random points
    from kinegen.symbolic import build_systems

    inspection = importlib.import_module("kinegen.analysis.inspect")
    subject = model(name)
    system = build_systems(subject, rotations.get(param), [next(iter(subject.cases))])[next(iter(subject.cases))]
    matrix = system.jacobian_matrix()
    blocks = inspection._block_form(system)
    assert blocks is not None and len(blocks) > 1
    det = inspection._determinant(matrix, blocks)
    symbols = sorted(matrix.free_symbols, key=str)
    rng = np.random.default_rng(3)
    for _ in range(4):
        point = dict(zip(symbols, (sp.Float(x) for x in rng.uniform(-1.0, 1.0, len(symbols)))))
        numeric = np.array(matrix.xreplace(point).evalf().tolist(), dtype=float)
        assert float(det.xreplace(point)) == pytest.approx(np.linalg.det(numeric), rel=1e-9, abs=1e-12)


def test_the_rssr_linkages_determinant_is_derived_within_the_default_budget():
    # whole, its 12 x 12 determinant in quaternions did not finish within the command's default minute
    report = inspect(model("rssr"), rotations.get("quaternion"), "turn", "0", budget=60.0)
    assert report.rank == 12 and report.unfinished is None and report.determinant is not None
    assert report.vanishing_factors == []
    whole = float(report.jacobian.det(method="berkowitz"))  # the exact Jacobian's, at the configuration
    assert whole != 0 and float(report.determinant_value) == pytest.approx(whole, rel=1e-12)
