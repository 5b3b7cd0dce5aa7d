"""Design studies (``studies:``, ``kinegen optimize``): the section's checks, the quantities'
exact gradients against differences, both shipped excavator studies solved, their optima
checked on rebuilt models, the optimized model file, the command."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

from kinegen import rotations
from kinegen.analysis.studies import StudyProblem, optimize, relative_angle, write_optimized
from kinegen.errors import ExitCode, ModelError
from kinegen.model import load, loads
from kinegen.runtime import from_module, load_module, solve
from kinegen.runtime.sensitivity import body_blocks
from tests.conftest import GENERATED, MODELS, ROOT

EXCAVATOR = MODELS / "excavator.yaml"


@pytest.fixture(scope="module")
def excavator():
    return load(EXCAVATOR), load_module(GENERATED / "excavator_quaternion.py", EXCAVATOR)


def _with_study(study: str) -> str:
    text = EXCAVATOR.read_text()
    return text[: text.index("\nstudies:\n")] + "\nstudies:\n  s:\n" + study


@pytest.mark.parametrize(
    ("study", "entry", "problem"),
    [
        ("    parameters: [C_x, X]\n    minimize: [{working_range: max_reach}]\n", "studies.s.parameters[1]", "not a design parameter"),
        ("    parameters: [C_x]\n    minimize: [{working_range: max_reach}]\n    maximize: [{working_range: max_depth}]\n",
         "studies.s", "exactly one of minimize or maximize"),
        ("    parameters: [C_x]\n    minimize: [{working_range: max_width}]\n", "studies.s.minimize[0].working_range", "unknown figure"),
        ("    parameters: [C_x]\n    minimize: [{stroke: arm_cylinder, case: dig}]\n", "studies.s.minimize[0].case", "measured over a case"),
        ("    parameters: [C_x]\n    minimize: [{stroke: stick_cylinder, case: digging}]\n", "studies.s.minimize[0].stroke", "unknown actuator"),
        ("    parameters: [C_x]\n    maximize: [{rotation_range: bucket, relative_to: arm, case: digging}]\n",
         "studies.s.maximize[0]", "needs its axis"),
        ("    parameters: [C_x]\n    minimize: [{stroke: arm_cylinder, case: digging, target: published}]\n",
         "studies.s.minimize[0].target", "'published' needs a working-range figure"),
        ("    parameters: [C_x]\n    minimize: [{working_range: max_reach}]\n    constraints: [{toggle_margin: [bucket], case: digging}]\n",
         "studies.s.constraints[0]", "at_least and/or at_most"),
        ("    parameters: [C_x]\n    minimize: [{working_range: max_reach}]\n    constraints: [{toggle_margin: [buket], case: digging, at_least: 0.1}]\n",
         "studies.s.constraints[0].toggle_margin[0]", "unknown moving body"),
        ("    parameters: [C_x]\n    minimize: [{working_range: max_reach}]\n    constraints: [{transmission_angle: [arm.H, side_link.J], case: digging, at_least: 0.3}]\n",
         "studies.s.constraints[0].transmission_angle", "expected three points"),
        ("    parameters: [C_x]\n    minimize: [{working_range: max_reach}]\n    constraints: [{transmission_angle: [arm.H, side_link.X, bucket.K], case: digging, at_least: 0.3}]\n",
         "studies.s.constraints[0].transmission_angle[1]", "unknown point"),
    ],
)  # fmt: skip
def test_a_malformed_study_names_the_entry(study, entry, problem):
    with pytest.raises(ModelError) as error:
        loads(_with_study(study), "bad.yaml")
    assert error.value.file == "bad.yaml" and error.value.entry == entry and problem in error.value.problem


def test_the_quantities_gradients_match_central_differences(excavator):
    """Every quantity of both studies and every time point of the margins, at a design away from
    the nominal: the exact gradient (sensitivities, the envelope theorem) against central
    differences (h = 1e-4 of each parameter's range, 4e-6 m for +-2 cm: figures are refined to ~1e-12 m) of the
    measured values."""
    model, module = excavator
    for name, at in (("bucket_linkage", [0.58, 0.56, -0.31, 0.33]), ("calibration", [1.40, 1.99, -0.79, -0.37, 1.76])):
        problem = StudyProblem(model, module, model.studies[name], compiled=True)
        p = np.array(at)
        exact = problem.measure(p)
        for j, span in enumerate(problem.bounds[:, 1] - problem.bounds[:, 0]):
            h = 1e-4 * span
            plus, minus = (problem.measure(p + sign * h * np.eye(len(p))[j], gradients=False) for sign in (1, -1))
            for label in exact.values:
                difference = (plus.values[label] - minus.values[label]) / (2 * h)
                assert abs(exact.gradients[label][j] - difference) < 2e-6 * max(1.0, abs(difference)), (name, label, j)
            for label, (_, derivatives) in exact.series.items():
                difference = (plus.series[label][0] - minus.series[label][0]) / (2 * h)
                assert np.abs(derivatives[:, j] - difference).max() < 2e-6 * max(1.0, np.abs(difference).max()), (name, label, j)


def test_the_bucket_linkage_study_finds_the_same_optimum_with_exact_and_finite_difference_gradients(excavator):
    """More rotation for less margin: the toggle margin ends on its bound, and the optimum's
    rotation range and margin hold on the model rebuilt with those numbers (no design
    parameters: another code path), the margin by the SVD of its blocks of Phi_q."""
    from kinegen.codegen import generate
    from kinegen.runtime.system import module_from_source

    model, module = excavator
    problem = StudyProblem(model, module, model.studies["bucket_linkage"], compiled=True)
    exact = optimize(problem)
    fd = optimize(StudyProblem(model, module, model.studies["bucket_linkage"], compiled=True), gradients="fd")
    assert exact.success and fd.success
    assert max(abs(exact.optimum[n] - fd.optimum[n]) for n in exact.optimum) < 1e-6
    label_rotation, label_margin = (q.label for q in (model.studies["bucket_linkage"].terms[0].quantity,
                                                      model.studies["bucket_linkage"].constraints[0].quantity))  # fmt: skip
    assert exact.after[label_rotation] > exact.before[label_rotation] + 0.3  # rad
    assert abs(exact.after[label_margin] - 0.08) < 1e-8 and f"{label_margin} at least 0.08" in exact.active
    rebuilt = model.at(exact.optimum)
    source = generate(rebuilt, rotations.get("quaternion"), ("python",))["python"]["excavator_quaternion.py"]
    results = solve(from_module(module_from_source(source), "bucket_stroke", compiled=False))
    angle = relative_angle(results, "bucket", "arm", np.array([0.0, 1.0, 0.0]))
    assert abs(angle.max() - angle.min() - exact.after[label_rotation]) < 1e-9
    margin = min(
        np.linalg.svd(results.system.jacobian(q, u)[np.ix_(rows, cols)], compute_uv=False)[-1]
        for rows, cols in body_blocks(results.system, ("side_link", "bucket_link", "bucket"))
        for q, u in zip(results.q, results.inputs)
    )
    assert abs(margin - exact.after[label_margin]) < 1e-9


def test_the_calibration_study_fits_the_published_figures_and_the_written_model_is_the_optimum(excavator, tmp_path):
    """Least squares of the five figures against the published (unverified) ones: the figures
    recomputed on the model rebuilt at the optimum are the reported ones; the optimized file is
    the input with the optimum as nominal values, under a new name."""
    from kinegen.analysis.envelope import working_range
    from kinegen.codegen import generate
    from kinegen.runtime.system import module_from_source

    model, module = excavator
    result = optimize(StudyProblem(model, module, model.studies["calibration"], compiled=True))
    assert result.success and result.objective_after < 0.01 * result.objective_before
    rebuilt = model.at(result.optimum)
    source = generate(rebuilt, rotations.get("quaternion"), ("python",))["python"]["excavator_quaternion.py"]
    system = from_module(module_from_source(source), "digging", compiled=False)
    figures = working_range(system, rebuilt.working_range, grid=(9, 5, 9)).figures
    for figure, value in figures.items():
        assert abs(value - result.after[figure]) < 1e-8, figure
    written = load(write_optimized(EXCAVATOR, model, result, tmp_path / "calibrated.yaml"))
    assert written.name == "excavator_calibration"
    optimum = {d.name: float(d.nominal) for d in written.design if d.name in result.optimum}
    assert optimum == pytest.approx(result.optimum, abs=1e-12)
    assert written.at().bodies == model.at(optimum).bodies and written.at().actuators == model.at(optimum).actuators
    with pytest.raises(ValueError, match="not written over its input"):
        write_optimized(EXCAVATOR, model, result, EXCAVATOR)


def test_kinegen_optimize_prints_progress_and_the_optimum_and_writes_a_new_model(tmp_path):
    out = tmp_path / "linkage.yaml"
    done = subprocess.run(
        [sys.executable, "-m", "kinegen.cli", "optimize", str(EXCAVATOR), "--study", "bucket_linkage", "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "iteration   1:" in done.stdout and "K_x" in done.stdout and "active: toggle_margin" in done.stdout
    assert f"wrote {out}" in done.stdout and load(out).name == "excavator_bucket_linkage"
    refused = subprocess.run(
        [sys.executable, "-m", "kinegen.cli", "optimize", str(EXCAVATOR), "--study", "bucket_linkage", "--out", str(EXCAVATOR)],
        cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    assert refused.returncode == ExitCode.USAGE and "written to a new file" in refused.stderr
    unknown = subprocess.run([sys.executable, "-m", "kinegen.cli", "optimize", str(EXCAVATOR), "--study", "x"], cwd=ROOT, capture_output=True, text=True)
    assert unknown.returncode == ExitCode.USAGE and "studies: calibration, bucket_linkage" in unknown.stderr


@pytest.mark.parametrize(
    ("original", "hostile", "entry"),
    [
        ("parameters: [C_x, C_z, F_x, F_z, boom_retracted]", "parameters: [&f0 [1, 1], &f1 [*f0, *f0]]", "studies.calibration.parameters[0]"),
        ("case: digging, at_least: 0.02", "case: {a: 1}, at_least: 0.02", "studies.calibration.constraints[0].case"),
        ("actuator_margin: boom_cylinder_left", "actuator_margin: [1]", "studies.calibration.constraints[0].actuator_margin"),
        ("toggle_margin: [side_link, bucket_link, bucket]", "toggle_margin: [[1], bucket_link, bucket]", "studies.bucket_linkage.constraints[0].toggle_margin[0]"),
        ("working_range: max_reach, target", "working_range: [1], target", "studies.calibration.minimize[0].working_range"),
    ],
)
def test_a_study_naming_things_with_lists_or_mappings_is_a_model_error(original, hostile, entry):
    """Found by the fuzzer: a list where a name belongs ended in 'unhashable type' instead of a ModelError."""
    text = EXCAVATOR.read_text()
    assert original in text
    with pytest.raises(ModelError, match=re.escape(entry)):
        loads(text.replace(original, hostile, 1), "excavator.yaml")
