"""Hard motions: the assembly branch is kept, failures are never silent, damped fallbacks
recover from rough starts, and an unreachable target is reported as such."""

from __future__ import annotations

import numpy as np
import pytest

from kinegen.errors import BranchError, ConvergenceError, KinegenError, SingularJacobianError, UnreachableError
from kinegen.runtime import Solver, SolverOptions, kinematics
from tests.conftest import generated_system


def bucket_angle(results) -> np.ndarray:
    """Angle of the bucket about global y (the boom plane at zero swing)."""
    rotation = kinematics.rotation_matrix(results, "bucket")
    return np.arctan2(rotation[:, 2, 0], rotation[:, 0, 0])


def test_coarse_steps_near_the_bucket_toggle_keep_the_assembly_branch():
    """bucket_near_toggle: 0.25 s steps, the cylinder 1.6 mm short of the toggle and back.

    Reference: the same case on a 1 ms grid. Without branch keeping the coarse solve ends on
    the other branch of the bucket four-bar (the bucket more than 1 rad off); with it (the
    default) every coarse pose is the reference pose."""
    system = generated_system("excavator_quaternion", "bucket_near_toggle")
    assert system.steps == 9 and (system.t1 - system.t0) / (system.steps - 1) == 0.25
    fine_times = np.linspace(system.t0, system.t1, 2001)
    reference = Solver(system).solve(fine_times)
    assert reference.inputs[:, 3].max() > 2.7349  # 1.6 mm short of the toggle at 2.7366 m

    def deviation(results) -> np.ndarray:
        difference = bucket_angle(results) - np.interp(results.times, fine_times, bucket_angle(reference))
        return np.abs(np.angle(np.exp(1j * difference)))

    unprotected = Solver(system, SolverOptions(keep_branch=False)).solve()
    assert deviation(unprotected).max() > 1.0  # coarse stepping alone jumps to the other branch
    kept = Solver(system).solve()
    assert deviation(kept).max() < 1e-9
    assert np.abs(kept.q - reference.q[::250]).max() < 1e-9


@pytest.mark.parametrize("compiled", [False, True])
def test_a_failed_step_is_marked_and_stops_the_run_when_asked(compiled):
    """bucket_toggle drives the cylinder past the toggle: no silent wrong pose either way. The step
    that failed is the last row, NaN (the solver fills its arrays row by row, not beforehand)."""
    system = generated_system("excavator_quaternion", "bucket_toggle", compiled)
    with pytest.raises(KinegenError):
        Solver(system).solve()
    results = Solver(system, SolverOptions(on_failure="stop", condition="estimate")).solve()
    assert not results.complete and isinstance(results.failure, KinegenError)
    assert not results.converged[-1]
    assert all(np.isnan(x[-1]).all() for x in (results.q, results.v, results.a, results.conditions))
    assert np.isfinite(results.conditions[:-1]).all() and np.isfinite(results.v[:-1]).all()
    assert results.converged[:-1].all() and len(results.times) < system.steps
    toggle_time = (2.7366037634564986 - 2.5) / 0.1
    assert abs(results.times[-1] - toggle_time) < 0.02  # it stops where the linkage locks
    for q, u in zip(results.q[:-1], results.inputs[:-1]):
        assert np.abs(system.phi(q, u)).max() <= 1e-10


def test_a_tip_target_beyond_reach_ends_in_an_error_that_says_so():
    """level_cut with the tip asked out to 14 m (reach 9.9 m; with the bucket held at -130 deg
    at z = -1 m, about 8.4 m): the certified steps stop where the path meets the edge of the
    workspace (the front stretched out: a singular pose within the step), before any row beyond
    it -- a BranchError naming the nearly singular block; from a pose given directly, the target
    is an UnreachableError naming the driver targets that cannot be met."""
    system = generated_system("excavator_quaternion", "level_cut")
    times = np.linspace(0.0, 1.0, 11)
    u, ud, udd = system.driver_inputs(times)
    k = system.driver_names.index("tip_x")
    u[k] = np.linspace(7.9, 14.0, len(times))
    ud[k], udd[k] = (14.0 - 7.9) / 1.0, 0.0
    with pytest.raises(BranchError) as info:
        Solver(system).solve(times, inputs=(u, ud, udd))
    assert 0 < info.value.t < 0.2  # 7.9 m is reachable, 9.1 m is not
    assert "singular pose is near" in str(info.value) and "boom" in str(info.value)
    with pytest.raises(UnreachableError) as info:
        Solver(system).position(system.initial_q, u[:, 2], times[2])
    error = info.value
    assert "outside the workspace" in str(error) and "closest reachable" in str(error)
    assert error.residual > 1e-6
    assert {name for name, _ in error.worst} <= {"tip_x", "tip_z", "bucket_attitude", "swing_angle"}
    assert {name for name, _ in error.worst} & {"tip_x", "tip_z"}


def test_assembly_from_a_rough_pose_recovers_with_the_damped_fallback():
    """Full Newton steps from a pose up to 0.5 rad / 0.5 m off (every coordinate) fail; line
    search / homotopy / Levenberg-Marquardt find an assembled pose that satisfies Phi to 1e-10."""
    system = generated_system("excavator_quaternion", "digging")
    solver = Solver(system)
    rng = np.random.default_rng(0)
    u = system.driver_inputs(system.t0)[0]
    rough = solver.retract(system.initial_q, rng.uniform(-0.5, 0.5, system.n_velocity))
    with pytest.raises((ConvergenceError, SingularJacobianError)):
        Solver(system, SolverOptions(line_search=False)).position(rough, u, 0.0)
    q, iterations, residual = solver.position(rough, u, 0.0)
    assert residual <= 1e-10 and np.abs(system.phi(q, u)).max() <= 1e-10
    assert iterations > 3


def test_the_third_order_predictor_starts_newton_nearer_and_saves_iterations():
    """On a whole step after another the predictor adds the jerk term (a - a_prev) / h_prev h^3 / 6 to
    v h + a h^2 / 2 (Solver._step; the C solver's attempt, the same sums, equal iteration for iteration
    in test_c_target). Along the excavator's digging cycle, from each solved row: the predicted pose's
    max |Phi| with it against without it, and the Newton iterations the solve took against the steps."""
    system = generated_system("excavator_quaternion", "digging")
    results = Solver(system).solve()
    q, v, a, t = results.q, results.v, results.a, results.times
    u = system.driver_inputs(t)[0]
    second, third = [], []
    for i in range(2, len(t) - 1):
        h, h_prev = t[i + 1] - t[i], t[i] - t[i - 1]
        plain = v[i] * h + 0.5 * a[i] * h * h
        jerk = plain + (a[i] - a[i - 1]) / h_prev * h * h * h / 6.0
        for motion, out in ((plain, second), (jerk, third)):
            out.append(float(np.abs(system.evaluate(system.retract(q[i], motion), u[:, i + 1])[0]).max()))
    second, third = np.array(second), np.array(third)
    assert np.median(third / second) < 0.25 and (third < second).mean() > 0.9, (np.median(third / second), (third < second).mean())
    # most steps now need one Newton iteration, or none where the prediction is already within tolerance
    assert results.iterations[1:].sum() < 1.5 * (len(t) - 1), results.iterations[1:].sum()
