"""The ZX200 excavator against independent references.

* pins against the closed-form planar computation of ``excavator_reference`` (law of
  cosines, no Newton) at 12 configurations spanning the cylinder ranges and 4 swing angles;
* velocities and accelerations against central differences of kinegen's own positions;
* round trip: the level cut's cylinder lengths drive the forward model back onto the path;
* every parametrization that is regular for this layout agrees; euler:zxz is singular.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinegen.errors import SingularJacobianError
from kinegen.runtime import Solver, SolverOptions, kinematics, solve
from tests.conftest import generated_system
from tests.excavator_reference import BOOM_CYLINDER_OFFSET, planar_pins, spatial

#: (swing, boom, arm, bucket cylinder lengths) spanning the ranges
#: boom 1.7352-3.0649, arm 1.8164-3.2939, bucket 1.6529-2.6613 m.
CONFIGURATIONS = [
    (0.0, 1.75, 1.83, 1.67),
    (0.0, 3.05, 3.28, 2.65),
    (0.7, 2.40, 2.55, 2.15),
    (0.7, 1.80, 3.20, 1.70),
    (-1.2, 3.00, 1.85, 2.60),
    (-1.2, 2.10, 2.90, 1.90),
    (2.5, 2.70, 2.20, 2.40),
    (2.5, 1.95, 1.95, 2.00),
    (-2.9, 2.95, 3.10, 1.75),
    (-2.9, 2.25, 2.35, 2.55),
    (1.5, 2.60, 3.25, 2.30),
    (1.5, 1.76, 2.05, 2.62),
]
PINS = {  # kinegen body.point -> planar reference pin, lateral offset
    ("upper", "A"): ("A", 0.0),
    ("upper", "B_left"): ("B", BOOM_CYLINDER_OFFSET),
    ("upper", "B_right"): ("B", -BOOM_CYLINDER_OFFSET),
    ("boom", "C_left"): ("C", BOOM_CYLINDER_OFFSET),
    ("boom", "C_right"): ("C", -BOOM_CYLINDER_OFFSET),
    ("boom", "D"): ("D", 0.0),
    ("boom", "E"): ("E", 0.0),
    ("arm", "F"): ("F", 0.0),
    ("arm", "G"): ("G", 0.0),
    ("arm", "H"): ("H", 0.0),
    ("arm", "Q"): ("Q", 0.0),
    ("side_link", "J"): ("J", 0.0),
    ("bucket_link", "J"): ("J", 0.0),
    ("bucket_link", "K"): ("K", 0.0),
    ("bucket", "K"): ("K", 0.0),
    ("bucket", "T"): ("T", 0.0),
    ("bucket_cyl_rod", "eye"): ("J", 0.0),
    ("arm_cyl_rod", "eye"): ("F", 0.0),
}


def forward_inputs_through(
    configurations: list[tuple[float, ...]], start: np.ndarray, substeps: int = 25
) -> tuple[np.ndarray, list[int]]:
    """Driver inputs (swing, boom, arm, bucket) moving linearly through the configurations."""
    path = [start]
    marks = []
    for target in np.array(configurations):
        s = np.linspace(0, 1, substeps + 1)[1:, None]
        path.extend(path[-1] + s * (target - path[-1]))
        marks.append(len(path) - 1)
    return np.array(path).T, marks


def solve_forward_at(configurations, param="quaternion"):
    system = generated_system(f"excavator_{param}", "digging")
    start = system.driver_inputs(system.t0)[0]
    u, marks = forward_inputs_through(configurations, start)
    zero = np.zeros_like(u)
    results = Solver(system).solve(np.arange(u.shape[1], dtype=float), inputs=(u, zero, zero))
    return results, marks


def test_pins_match_the_closed_form_planar_solution():
    results, marks = solve_forward_at(CONFIGURATIONS)
    worst = 0.0
    for (swing, boom, arm, bucket), k in zip(CONFIGURATIONS, marks):
        pins, _ = planar_pins(boom, arm, bucket)
        for (body, point), (pin, lateral) in PINS.items():
            expected = spatial(pins[pin], swing, lateral)
            worst = max(worst, np.abs(kinematics.point_position(results, body, point)[k] - expected).max())
        batch = results.system.point_positions(results.q[[k]], list(PINS))[0]  # what the working range reads
        worst = max(worst, max(np.abs(batch[j] - spatial(pins[pin], swing, lateral)).max() for j, (pin, lateral) in enumerate(PINS.values())))
        assert abs(kinematics.actuator_length(results, "boom_cylinder_right")[k] - boom) < 1e-9  # the passive twin
        assert abs(kinematics.actuator_length(results, "bucket_cylinder")[k] - bucket) < 1e-9
    assert worst < 1e-9, worst


def test_digging_velocities_and_accelerations_match_central_differences():
    system = generated_system("excavator_quaternion", "digging")
    solver = Solver(system, SolverOptions(tolerance=1e-13))
    h = 1e-3
    for t0 in (2.0, 7.3, 9.1, 12.0):
        times = t0 + h * np.arange(-2, 3)
        warm = solver.solve(np.linspace(system.t0, times[0], 60))
        r = solver.solve(times, q0=warm.q[-1])
        for body, point in (("bucket", "T"), ("arm", "Q"), ("side_link", "J")):
            p = kinematics.point_position(r, body, point)
            v = (4 * (p[3] - p[1]) / (2 * h) - (p[4] - p[0]) / (4 * h)) / 3
            a = (4 * (p[3] - 2 * p[2] + p[1]) / h**2 - (p[4] - 2 * p[2] + p[0]) / (4 * h**2)) / 3
            assert np.abs(kinematics.point_velocity(r, body, point)[2] - v).max() < 1e-8, (t0, body)
            assert np.abs(kinematics.point_acceleration(r, body, point)[2] - a).max() < 1e-5, (t0, body)
        for name in ("boom_cylinder_left", "bucket_cylinder"):
            length = kinematics.actuator_length(r, name)
            rate = (4 * (length[3] - length[1]) / (2 * h) - (length[4] - length[0]) / (4 * h)) / 3
            assert abs(kinematics.actuator_rate(r, name)[2] - rate) < 1e-8
            acceleration = (
                4 * (length[3] - 2 * length[2] + length[1]) / h**2 - (length[4] - 2 * length[2] + length[0]) / (4 * h**2)
            ) / 3
            assert abs(kinematics.actuator_acceleration(r, name)[2] - acceleration) < 1e-5


@pytest.mark.parametrize("case", ["level_cut", "trench_wall"])
def test_inverse_cases_follow_their_paths(case):
    results = solve(generated_system("excavator_quaternion", case))
    t = results.times
    s = 10 * (t / 4) ** 3 - 15 * (t / 4) ** 4 + 6 * (t / 4) ** 5
    tip = kinematics.point_position(results, "bucket", "T")
    if case == "level_cut":
        expected = np.c_[7.9 - 3.4 * s, 0 * t, -1.0 + 0 * t]
    else:
        expected = np.c_[6.0 + 0 * t, 0 * t, 0.5 - 3 * s]
    assert np.abs(tip - expected).max() < 1e-9
    # the bucket keeps its attitude: its x axis stays at -130 deg in the boom plane
    x_axis = kinematics.rotation_matrix(results, "bucket")[:, :, 0]
    assert np.abs(x_axis - [np.cos(np.radians(-130)), 0, np.sin(np.radians(-130))]).max() < 1e-10
    assert kinematics.range_violations(results) == []
    # pins against the closed form at the solved cylinder lengths
    for k in range(0, len(t), 25):
        pins, _ = planar_pins(*(kinematics.actuator_length(results, n)[k] for n in ("boom_cylinder_left", "arm_cylinder", "bucket_cylinder")))
        assert np.abs(kinematics.point_position(results, "bucket", "K")[k] - spatial(pins["K"], 0.0)).max() < 1e-9


def test_level_cut_lengths_fed_to_the_forward_case_reproduce_the_tip_path():
    inverse = solve(generated_system("excavator_quaternion", "level_cut"))
    names = ("boom_cylinder_left", "arm_cylinder", "bucket_cylinder")
    zero = np.zeros(len(inverse.times))
    u = np.vstack([zero, *(kinematics.actuator_length(inverse, n) for n in names)])
    ud = np.vstack([zero, *(kinematics.actuator_rate(inverse, n) for n in names)])
    udd = np.vstack([zero, *(kinematics.actuator_acceleration(inverse, n) for n in names)])
    forward_system = generated_system("excavator_quaternion", "digging")
    forward = Solver(forward_system).solve(inverse.times, q0=inverse.q[0], inputs=(u, ud, udd))
    assert np.abs(kinematics.point_position(forward, "bucket", "T") - kinematics.point_position(inverse, "bucket", "T")).max() < 1e-9
    assert np.abs(kinematics.point_velocity(forward, "bucket", "T") - kinematics.point_velocity(inverse, "bucket", "T")).max() < 1e-8
    assert np.abs(kinematics.point_acceleration(forward, "bucket", "T") - kinematics.point_acceleration(inverse, "bucket", "T")).max() < 1e-6


@pytest.mark.parametrize("case", ["digging", "level_cut", "trench_wall"])
@pytest.mark.parametrize("param", ["euler_parameters", "euler_zxy"])
def test_regular_parametrizations_agree_on_every_point(case, param):
    reference = solve(generated_system("excavator_quaternion", case))
    other = solve(generated_system(f"excavator_{param}", case))
    for body, points in reference.system.points.items():
        for point in points:
            assert np.abs(kinematics.point_position(other, body, point) - kinematics.point_position(reference, body, point)).max() < 1e-9, (body, point)
        assert np.abs(kinematics.omega(other, body) - kinematics.omega(reference, body)).max() < 1e-8, body


def test_euler_zxz_is_singular_and_names_the_upper_structure():
    with pytest.raises(SingularJacobianError) as info:
        solve(generated_system("excavator_euler_zxz", "digging"))
    assert info.value.t == 0
    assert info.value.bodies == ["upper"]
    assert info.value.null_space == ["upper.alpha - upper.gamma"]


def test_a_cylinder_leaving_its_range_is_reported():
    system = generated_system("excavator_quaternion", "digging")
    start = system.driver_inputs(system.t0)[0]
    target = start.copy()
    target[3] = 2.70  # bucket cylinder beyond its 2.6613 m limit (the linkage still closes)
    u, _ = forward_inputs_through([tuple(target)], start, substeps=20)
    zero = np.zeros_like(u)
    results = Solver(system).solve(np.linspace(0, 1, u.shape[1]), inputs=(u, zero, zero))
    violations = kinematics.range_violations(results)
    assert violations and {v[1] for v in violations} == {"bucket_cylinder"}
    t, name, value, limits = violations[-1]
    assert name == "bucket_cylinder"
    assert t == 1.0 and abs(value - 2.70) < 1e-9 and limits == (1.6529, 2.6613)


def test_chord_iterations_reach_the_same_poses_with_fewer_factorizations():
    """From previous-step starts (no predictor) the chord iterations (each step starts with
    the factorization made at the last solution) end where full Newton ends, every pose and
    the bucket tip's path to the tolerance, and factorize Phi_q less often."""
    system = generated_system("excavator_euler_parameters", "digging")
    times = np.linspace(0.0, 2.0, 101)
    runs = {}
    for chord in (False, True):
        solver = Solver(system, SolverOptions(predictor=False, chord=chord))
        factor, count = solver.linear.factor, [0]

        def counted(values, factor=factor, count=count):
            count[0] += 1
            return factor(values)

        solver.linear.factor = counted
        runs[chord] = (solver.solve(times), count[0])
    (newton, newton_factors), (chord, chord_factors) = runs[False], runs[True]
    assert chord.residuals.max() <= 1e-10
    assert np.abs(chord.q - newton.q).max() < 1e-9
    tip = [kinematics.point_position(r, "bucket", "T") for r in (newton, chord)]
    assert np.abs(tip[0] - tip[1]).max() < 1e-9
    assert chord_factors < 0.5 * newton_factors, (chord_factors, newton_factors)
