"""Masses in design (issue 29, part 5): the study quantities built on the masses -- the rated lift
capacity with its tipping half, the tipping margin along a case, the peak pressure at speed -- and
their exact design sensitivities, against central differences of the same quantities at nearby
design values (the module takes the design parameters at run time; every pose re-solved)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
import sympy as sp

from kinegen.forces.dynamics import inertial_load, tipping_margin
from kinegen.runtime import SolverOptions, from_module, kinematics, load_module
from kinegen.runtime.sensitivity import state_sensitivities
from kinegen.runtime.solver import solve
from tests.conftest import GENERATED, model
from tests.test_force_design import assert_gradients_equal_central_differences, study_problem

H = 1e-6


@functools.cache
def module():
    return load_module(GENERATED / "excavator_quaternion.py")


def _nominal() -> dict[str, float]:
    return {d.name: float(d.nominal) for d in model("excavator").design}


def _solved(design: dict[str, float], points: int = 61):
    system = from_module(module(), "digging", compiled=False, design=design)
    return solve(system, np.linspace(system.t0, system.t1, points), SolverOptions(tolerance=1e-13))


@pytest.mark.parametrize(
    ("quantity", "parameters", "compiled"),
    [
        ("{peak_pressure: boom_cylinder_left, case: digging}", ("C_x", "F_z"), None),
        ("{peak_pressure: arm_cylinder, load: payload, case: digging}", ("F_x", "C_z"), False),
        ("{tipping_margin: dynamic, load: payload, case: digging}", ("C_x", "F_z"), None),
        ("{tipping_margin: static, case: digging}", ("C_x", "F_x"), False),
        ("{lift_capacity: [6.0, 1.5]}", ("C_x", "F_z"), None),  # rated over the front: tipping rules there
        ("{lift_capacity: [6.0, 1.5], over: side, limit: tipping}", ("C_x", "F_z"), None),
        ("{lift_capacity: [4.5, 4.5]}", ("C_x", "C_z"), None),  # rated over the front: the boom's relief rules there
    ],
)
def test_mass_quantities_gradients_equal_central_differences(quantity, parameters, compiled):
    """Pure Python (compiled False) for one quantity of each kind measured along a case, the rest
    through the compiled library (test_force_design.study_problem)."""
    assert_gradients_equal_central_differences(study_problem(quantity, parameters, compiled), absolute=1e-5)


def test_rated_lift_capacity_is_the_charts():
    """The quantity's rated value is the lift chart's cell (kg x g), each side, with the limit that rules."""
    from kinegen.forces.lift import G, lift_chart

    excavator = model("excavator")
    chart = lift_chart(from_module(module(), excavator.lift_chart.case, compiled=False), excavator)
    cell = chart.grid[list(chart.heights).index(1.5)][list(chart.radii).index(6.0)]
    for over in ("front", "side"):
        problem = study_problem(f"{{lift_capacity: [6.0, 1.5], over: {over}}}", ("C_x",))
        (value,) = problem.measure(np.array([problem.nominal_design["C_x"]]), gradients=False).values.values()
        assert value * 1e3 == pytest.approx(cell.rated(over == "side")[0] * G, rel=1e-9)
        assert cell.rated(over == "side")[1] == "tipping"


def _massive_design(excavator):
    """The excavator with design parameters in its masses, centres, inertias and undercarriage: each
    stays at its nominal value at the nominal design, and moves with C_x and F_z (which also move the
    pose) -- so that the design's own share of the derivatives is checked too."""
    symbols = {d.name: d.symbol for d in excavator.design}
    nominal = _nominal()
    cx, fz = (symbols[n] - nominal[n] for n in ("C_x", "F_z"))
    bodies = []
    for body in excavator.bodies:
        if body.inertia is not None and body.name in ("upper", "arm", "bucket"):
            inertia = body.inertia
            center = sp.ImmutableMatrix([inertia.center[0] + 3 * cx, inertia.center[1], inertia.center[2] - 2 * fz])
            tensor = sp.ImmutableMatrix(inertia.tensor + sp.diag(400 * cx, 300 * fz, 500 * cx))
            inertia = dataclasses.replace(inertia, mass=inertia.mass * (1 + 2 * cx - fz), center=center, tensor=tensor)
            body = dataclasses.replace(body, inertia=inertia)
        bodies.append(body)
    machine = excavator.machine
    machine = dataclasses.replace(machine, undercarriage_mass=machine.undercarriage_mass + 5000 * fz,
                                  track_length=machine.track_length + 2 * cx, gauge=machine.gauge - 3 * fz)  # fmt: skip
    return dataclasses.replace(excavator, bodies=tuple(bodies), machine=machine)


def test_tipping_margin_changes_with_design_in_the_masses():
    """Every line's margin at every time point of the digging cycle with the payload, its derivative
    by the design parameters against central differences, the masses, centres, inertias and the
    undercarriage moving with the design as well as the pose."""
    changed = _massive_design(model("excavator"))
    nominal = _nominal()
    exact = tipping_margin(_solved(nominal), changed, ("payload",), changes=True)
    pose_only = tipping_margin(_solved(nominal), model("excavator"), ("payload",), changes=True)
    assert all(np.abs(exact.changes[line] - pose_only.changes[line]).max() > 1e5 for line in exact.margins)  # the masses' share
    for name in ("C_x", "F_z", "K_x"):
        moved = [tipping_margin(_solved({**nominal, name: nominal[name] + sign * H}), changed, ("payload",)) for sign in (1, -1)]
        k = list(nominal).index(name)
        for line, margin in exact.margins.items():
            difference = (moved[0].margins[line] - moved[1].margins[line]) / (2 * H)
            np.testing.assert_allclose(exact.changes[line][:, k], difference, rtol=0, atol=1e-7 * np.abs(margin).max(), err_msg=f"{name} {line}")
            assert np.abs(difference).max() > 1e3  # N m per m


def test_lift_tipping_load_changes_with_design_in_the_masses():
    """The tipping half of the lift capacity over both sides, the masses and the tracks moving with
    the design."""
    changed = _massive_design(model("excavator"))
    for over in ("front", "side"):
        problem = study_problem(f"{{lift_capacity: [6.0, 1.5], over: {over}, limit: tipping}}", ("C_x", "F_z"))
        problem.model = dataclasses.replace(changed, studies=problem.model.studies)
        p = np.array([problem.nominal_design[n] for n in problem.names])
        measured = problem.measure(p)
        (label,) = measured.values
        for i, name in enumerate(problem.names):
            step = H * np.eye(len(p))[i]
            difference = (problem.measure(p + step, False).values[label] - problem.measure(p - step, False).values[label]) / (2 * H)
            assert measured.gradients[label][i] == pytest.approx(difference, rel=1e-6), f"{over} {name}"


def _numeric_inertial_load(results, excavator):
    """Q_inertia (K, n_v) summed body by body from the solved frames: J_Cᵀ m (g - a_C) + T_ωᵀ (-(J ω̇ + ω × J ω))."""
    from kinegen.forces.dynamics import inertia_numbers
    from kinegen.forces.statics import Statics

    statics = Statics(results, excavator)
    gravity = statics.design_vector(excavator.gravity)
    out = np.zeros((len(results.times), statics.n_v))
    for body in excavator.massive:
        mass, local, body_tensor = inertia_numbers(body.inertia, results.system.design)
        name = body.name
        rotation = kinematics.rotation_matrix(results, name)
        arm = rotation @ local
        omega, omega_dot = kinematics.omega(results, name), kinematics.omega_dot(results, name)
        acceleration = kinematics.acceleration(results, name) + np.cross(omega_dot, arm) + np.cross(omega, np.cross(omega, arm))
        tensor = rotation @ body_tensor @ rotation.swapaxes(1, 2)
        moment = -(np.einsum("kij,kj->ki", tensor, omega_dot) + np.cross(omega, np.einsum("kij,kj->ki", tensor, omega)))
        jacobian = statics.point_jacobian(name, kinematics.position(results, name) + arm)
        out[:, statics.columns(name)] += np.einsum("kic,ki->kc", jacobian, mass * (gravity - acceleration))
        out[:, statics.columns(name)] += np.einsum("kic,ki->kc", statics.tangents[name][1], moment)
    return out


def test_inertial_load_changes_equal_central_differences():
    """dQ_inertia/dp (the peak pressure's load change): Q summed from the frames equals the generated
    ``inertia`` kernel (the nominal masses), and its derivative equals central differences of it with
    the masses moving with the design too (:func:`_massive_design`)."""
    from kinegen.forces.sensitivity import TangentChanges, inertial_load_changes
    from kinegen.forces.statics import Statics

    excavator, nominal = model("excavator"), _nominal()
    results = _solved(nominal, points=21)
    reference = _numeric_inertial_load(results, excavator)
    np.testing.assert_allclose(inertial_load(results), reference, rtol=0, atol=1e-11 * np.abs(reference).max())
    changed = _massive_design(excavator)
    statics = Statics(results, changed)
    exact = inertial_load_changes(statics, TangentChanges(statics, state_sensitivities(results)[0]))
    nominal_masses = Statics(results, excavator)
    pose_only = inertial_load_changes(nominal_masses, TangentChanges(nominal_masses, state_sensitivities(results)[0]))
    assert np.abs(exact - pose_only).max() > 1e5  # the masses' share (N per m)
    for name in ("C_x", "F_z"):
        moved = [_numeric_inertial_load(_solved({**nominal, name: nominal[name] + sign * H}, points=21), changed) for sign in (1, -1)]
        difference = (moved[0] - moved[1]) / (2 * H)
        np.testing.assert_allclose(exact[:, :, list(nominal).index(name)], difference, rtol=0, atol=1e-7 * np.abs(reference).max(), err_msg=name)


@pytest.mark.parametrize(
    ("quantity", "problem"),
    [
        ("{tipping_margin: sometimes, case: digging}", "expected one of dynamic, static"),
        ("{tipping_margin: dynamic, case: digging, load: wind}", "one of the model's loads"),
        ("{peak_pressure: swing_motor, case: digging}", "not an actuator with hydraulic data"),
        ("{lift_capacity: [6.0, 1.5], over: back}", "expected one of front, side, got 'back'"),
        ("{lift_capacity: [6.0, 1.5], limit: weight}", "expected one of rated, hydraulic, tipping"),
        ("{stroke: bucket_cylinder, case: digging, over: side}", "not used by stroke"),
        ("{mass: machine, case: digging}", "a mass is the design's, not a case's"),
        ("{mass: tracks}", "expected machine or a body with a mass"),
    ],
)
def test_mass_quantities_are_checked_when_read(quantity, problem):
    from kinegen.errors import ModelError
    from kinegen.model import loads

    text = (GENERATED.parent / "models" / "excavator.yaml").read_text()
    broken = text.replace("      - {digging_force: bucket_cylinder, case: bucket_stroke}", f"      - {quantity}")
    with pytest.raises(ModelError, match=problem):
        loads(broken, "excavator.yaml")


def test_mass_quantities_need_masses_and_the_machine():
    from kinegen.errors import ModelError
    from kinegen.model import loads

    text = (GENERATED.parent / "models" / "excavator.yaml").read_text()
    without_machine = text[: text.index("\nmachine:")] + "\n"
    study = "\nstudies:\n  check:\n    parameters: [C_x]\n    maximize:\n      - {quantity}\n"
    for quantity, problem in (
        ("{tipping_margin: dynamic, case: digging}", "needs the bodies' masses and a machine: section"),
        ("{lift_capacity: [6.0, 1.5], limit: tipping}", "needs the bodies' masses and a machine: section"),
        ("{mass: machine}", "needs the bodies' masses and a machine: section"),
    ):
        with pytest.raises(ModelError, match=problem):
            loads(without_machine.replace("\nstudies:\n", study.replace("{quantity}", quantity), 1), "excavator.yaml")


def test_the_counterweight_study_rates_its_target_by_the_lever_rule():
    """The least counterweight that rates 3,000 kg over the side at 6 m, 1.5 m: the optimum puts its
    centre at the rear bound and adds just enough mass -- which the lever rule confirms, the upper
    structure's centre of mass composed by hand from its rest (5,020 kg) and the counterweight."""
    from kinegen.analysis.studies import StudyProblem, optimize
    from kinegen.forces.lift import TIPPING_SHARE, Placer
    from tests.test_lift import _centers, _masses

    excavator = model("excavator")
    result = optimize(StudyProblem(excavator, module(), excavator.studies["counterweight"], compiled=False))
    mass, x = result.optimum["counterweight"], result.optimum["counterweight_x"]
    assert result.success and x == pytest.approx(-2.45, abs=1e-9) and 4000 < mass < 5500
    assert result.after["mass(machine)"] == pytest.approx(20.0 + (mass - 4000) / 1e3, rel=1e-12)
    placed = Placer(from_module(module(), "digging", compiled=False), excavator).at(6.0, 1.5)
    centers, masses = _centers(placed.inputs["boom_length"], placed.inputs["arm_length"]), _masses()
    upper = (5020 * 1533 / 5020 + mass * x) / (5020 + mass)  # the rest's and the counterweight's centres along x
    line = 2.2 / 2  # over the side: the track's centreline, the front swung over it
    restoring = sum(m * (line - centers[n][0]) for n, (m, _) in masses.items() if n not in ("bucket", "upper"))
    restoring += (5020 + mass) * (line - upper) + 7300 * line
    assert TIPPING_SHARE * restoring / (6.0 - line) == pytest.approx(3000.0, rel=1e-6)
