"""Forces in design (issue 28, part 4): the exact design sensitivities of the actuation forces and
the study quantities built on them, against central differences of the same forces at nearby
design values (the module takes the design parameters at run time; the poses re-solved at the
same inputs)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from kinegen.forces.iso6015 import tool_forces
from kinegen.forces.sensitivity import element_force_sensitivities
from kinegen.forces.statics import Statics, pose_results
from kinegen.runtime import Solver, SolverOptions, from_module, load_module
from tests.conftest import GENERATED, generated_system, model

H = 1e-6
LOAD = np.array([-30000.0, 0.0, -10000.0])  # at the tip T, global


@functools.cache
def module():
    return load_module(GENERATED / "excavator_quaternion.py")


def _nominal() -> dict[str, float]:
    return {d.name: float(d.nominal) for d in model("excavator").design}


def _poses(system, q_start: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    solver = Solver(system, SolverOptions(tolerance=1e-13))
    return np.stack([solver.position(q, u)[0] for q, u in zip(q_start, inputs)])


def _held(system, q: np.ndarray, inputs: np.ndarray):
    statics = Statics(pose_results(system, q, inputs), model("excavator"))
    force = np.broadcast_to(LOAD, (len(q), 3))
    matrix, multipliers = statics.hold("bucket", "T", force)
    return statics, matrix, multipliers, force


def test_element_force_sensitivities_equal_central_differences():
    """Four poses of the digging cycle, the load at the tip held fixed: d(cylinder and swing-motor
    forces)/dp of pins on the boom (C), the arm (F) and the bucket linkage (K, its link lengths)."""
    base = from_module(module(), "digging", compiled=False)
    inputs = base.driver_inputs(np.array([0.0, 2.0, 5.0, 11.0]))[0].T
    start = np.stack([Solver(base, SolverOptions()).position(base.initial_q, u)[0] for u in inputs])
    q = _poses(base, start, inputs)
    statics, matrix, multipliers, force = _held(base, q, inputs)
    exact = element_force_sensitivities(statics, matrix, multipliers, "bucket", "T", force)
    nominal = _nominal()
    for name in ("C_x", "F_z", "K_x", "side_link"):
        moved = []
        for sign in (1, -1):
            system = from_module(module(), "digging", compiled=False, design={**nominal, name: nominal[name] + sign * H})
            s, _, lam, _ = _held(system, _poses(system, q, inputs), inputs)
            moved.append(s.element_forces(lam))
        difference = (moved[0] - moved[1]) / (2 * H)
        k = list(nominal).index(name)
        np.testing.assert_allclose(exact[:, :, k], difference, rtol=0, atol=1e-7 * np.abs(difference).max(), err_msg=name)
        assert np.abs(difference).max() > 1e3  # each of them moves the forces (N per m)


def test_digging_force_quantity_is_the_iso_ceiling():
    """Two ways to the bucket cylinder's relief-limited tool force: virtual work by velocities over
    the bucket_stroke case (the study quantity) and Phi_q^T lambda = Q over the stroke (kinegen forces)."""
    from kinegen.analysis.studies import StudyProblem

    excavator = model("excavator")
    problem = StudyProblem(excavator, module(), excavator.studies["digging_force"], compiled=False)
    measured = problem.measure(np.array([problem.nominal_design[n] for n in problem.names]), gradients=False)
    ceiling = tool_forces(generated_system("excavator_quaternion", "digging"), excavator)["bucket"].ceiling
    # the case samples the stroke at 101 points, the ISO search refines the maximum between them
    assert measured.values["digging_force(bucket_cylinder, bucket_stroke)"] * 1e3 == pytest.approx(ceiling, rel=2e-4)
    assert measured.values["digging_force(bucket_cylinder, bucket_stroke)"] * 1e3 <= ceiling * (1 + 1e-9)


@pytest.mark.parametrize(
    ("quantity", "parameters", "compiled"),
    [
        ("{digging_force: bucket_cylinder, case: bucket_stroke}", ("side_link", "K_z"), False),
        ("{cylinder_pressure: bucket_cylinder, load: cutting, case: level_cut}", ("K_x", "bucket_link"), False),
        ("{cylinder_pressure: boom_cylinder_left, load: payload, case: digging}", ("C_x", "F_z"), None),
        ("{pin_load: arm_pin, load: cutting, case: level_cut}", ("F_x", "F_z"), False),
        ("{pin_load: boom_foot, load: payload, case: digging}", ("C_x", "C_z"), None),
        ("{lift_capacity: [6.0, 1.5], limit: hydraulic}", ("C_x", "C_z"), None),  # the boom cylinders limit: their pins matter
        ("{lift_capacity: [3.0, 0], limit: hydraulic}", ("F_x", "F_z"), None),  # the arm cylinder's holding limit: its pin matters
        ("{tool_force: bucket.T, direction: [-1, 0, 0], case: level_cut}", ("C_x", "C_z"), None),
    ],
)
def test_force_quantities_gradients_equal_central_differences(quantity, parameters, compiled):
    assert_gradients_equal_central_differences(study_problem(quantity, parameters, compiled))


def study_problem(quantity: str, parameters: tuple[str, ...], compiled: bool | None = False):
    """A study of the excavator with the one ``quantity`` (a YAML term) over ``parameters``, on the
    committed module's Python functions (``compiled`` False), or its compiled library as a user's
    study runs (None: ten to twenty times faster a measurement; the two agree to rounding)."""
    from kinegen.analysis.studies import StudyProblem
    from kinegen.model import loads

    text = (GENERATED.parent / "models" / "excavator.yaml").read_text()
    study = f"\nstudies:\n  check:\n    parameters: [{', '.join(parameters)}]\n    maximize:\n      - {quantity}\n"
    checked = loads(text.replace("\nstudies:\n", study, 1), "excavator.yaml")  # the shipped studies follow it
    return StudyProblem(checked, module(), checked.studies["check"], compiled=compiled)


def assert_gradients_equal_central_differences(problem, absolute: float = 1e-6) -> None:
    """The study's one quantity: its exact gradient at the nominal design against central differences
    (step H) by each parameter, which must move it (more than 0.1 of its unit per unit)."""
    p = np.array([problem.nominal_design[n] for n in problem.names])
    measured = problem.measure(p)
    (label,) = measured.values
    for i, name in enumerate(problem.names):
        step = H * np.eye(len(p))[i]
        difference = (problem.measure(p + step, False).values[label] - problem.measure(p - step, False).values[label]) / (2 * H)
        assert measured.gradients[label][i] == pytest.approx(difference, rel=1e-6, abs=absolute), name
        assert abs(difference) > 0.1  # kN, kN m or MPa per m (or kg): it depends on the parameter


def test_force_quantities_are_checked_when_read():
    from kinegen.errors import ModelError
    from kinegen.model import loads

    text = (GENERATED.parent / "models" / "excavator.yaml").read_text()
    for quantity, problem in (
        ("{cylinder_pressure: bucket_cylinder, load: wind, case: level_cut}", "one of the model's loads"),
        ("{digging_force: boom_cylinder_right, case: bucket_stroke}", "not an actuator with hydraulic data"),
        ("{pin_load: elbow, load: payload, case: digging}", "unknown joint 'elbow'"),
        ("{pin_load: arm_pin, case: digging}", "a pin load holds one of the model's loads"),
        ("{lift_capacity: [6.0]}", "expected \\[radius, height\\]"),
        ("{tool_force: bucket.T, case: level_cut}", "needs its direction"),
        ("{tool_force: bucket.T, direction: [0, 0, 0], case: level_cut}", "non-zero vector"),
        ("{lift_capacity: [6.0, 1.5], case: digging}", "measured in the lift_chart section's case"),
    ):
        broken = text.replace("      - {digging_force: bucket_cylinder, case: bucket_stroke}", f"      - {quantity}")
        with pytest.raises(ModelError, match=problem):
            loads(broken, "excavator.yaml")
