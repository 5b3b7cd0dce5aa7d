"""Property tests (Hypothesis): random rotations, random excavator time laws, random chain sizes."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from kinegen import rotations
from kinegen.bench.chain import tip_reference
from kinegen.rotations.euler_angles import SEQUENCES
from kinegen.runtime import Solver, SolverOptions, kinematics
from tests.conftest import chain_system, generated_system, model


def slow(examples: int) -> settings:
    return settings(max_examples=examples, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])


unit_quaternions = (
    st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4)
    .map(np.array)
    .filter(lambda q: np.linalg.norm(q) > 0.1)
    .map(lambda q: q / np.linalg.norm(q))
)


@settings(max_examples=200, deadline=None, database=None)
@given(q=unit_quaternions, sequence=st.sampled_from(SEQUENCES))
def test_every_parametrization_round_trips_against_scipy(q, sequence):
    """quaternion <-> matrix <-> Euler angles (12 intrinsic sequences) agree with SciPy's Rotation,
    away from the sequence's singular set (middle angle 0 or pi for z-x-z types, ±pi/2 for x-y-z types)."""
    reference = Rotation.from_quat(q, scalar_first=True)
    matrix = reference.as_matrix()
    for name in ("quaternion", "euler-parameters"):
        p = rotations.get(name)
        assert np.abs(p.to_matrix(q) - matrix).max() < 1e-13
        back = p.from_matrix(matrix)
        assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-12  # w-x-y-z, up to sign
    euler = rotations.get(f"euler:{sequence}")
    angles = euler.from_matrix(matrix)
    symmetric = sequence[0] == sequence[2]
    middle = angles[1]
    distance = abs(np.sin(middle)) if symmetric else abs(np.cos(middle))
    if distance < 1e-3:
        return  # at (or next to) this sequence's gimbal lock the angles are not unique
    assert np.abs(euler.to_matrix(angles) - matrix).max() < 1e-11
    scipy_angles = reference.as_euler(sequence.upper())
    difference = np.angle(np.exp(1j * (angles - scipy_angles)))
    assert np.abs(difference).max() < 1e-9 / distance


@slow(4)
@given(data=st.data())
def test_random_cylinder_laws_satisfy_phi_and_match_central_differences(data):
    """Random smooth laws inside the cylinder ranges (digging case inputs): Phi <= 1e-10 at every
    step; velocity and acceleration of the bucket tip = Richardson central differences."""
    system = generated_system("excavator_quaternion", "digging")
    ranges = model("excavator").working_range.numbers(system.design)
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    names = list(system.driver_names)
    centre, amplitude, omega, phase = (np.zeros(len(names)) for _ in range(4))
    for k, name in enumerate(names):
        low, high = ranges[name] if isinstance(ranges.get(name), tuple) else (-0.6, 0.6)
        margin = 0.05 * (high - low)
        centre[k] = rng.uniform(low + (high - low) / 3, high - (high - low) / 3)
        amplitude[k] = rng.uniform(0, min(centre[k] - low, high - centre[k]) - margin)
        omega[k], phase[k] = rng.uniform(0.3, 2.0), rng.uniform(0, 2 * np.pi)

    def inputs(times):
        arg = np.outer(omega, times) + phase[:, None]
        w = omega[:, None]
        return (
            centre[:, None] + amplitude[:, None] * np.sin(arg),
            amplitude[:, None] * w * np.cos(arg),
            -amplitude[:, None] * w**2 * np.sin(arg),
        )

    times = np.linspace(0, 3, 61)
    start = Solver(system).position(system.initial_q, inputs(times[:1])[0][:, 0], 0.0)[0]
    solver = Solver(system, SolverOptions(tolerance=1e-13))
    results = solver.solve(times, q0=start, inputs=inputs(times))
    assert results.complete
    for q, u in zip(results.q, results.inputs):
        assert np.abs(system.phi(q, u)).max() <= 1e-10
    h = 1e-3
    for i in rng.choice(np.arange(5, 56), size=2, replace=False):
        stencil = times[i] + h * np.arange(-2, 3)
        q0 = solver.position(results.q[i], inputs(stencil[:1])[0][:, 0], stencil[0])[0]
        r = solver.solve(stencil, q0=q0, inputs=inputs(stencil))
        p = kinematics.point_position(r, "bucket", "T")
        velocity = (4 * (p[3] - p[1]) / (2 * h) - (p[4] - p[0]) / (4 * h)) / 3
        acceleration = (4 * (p[3] - 2 * p[2] + p[1]) / h**2 - (p[4] - 2 * p[2] + p[0]) / (4 * h**2)) / 3
        assert np.abs(kinematics.point_velocity(r, "bucket", "T")[2] - velocity).max() < 1e-8
        assert np.abs(kinematics.point_acceleration(r, "bucket", "T")[2] - acceleration).max() < 1e-5


@slow(3)
@given(n=st.integers(1, 5), param=st.sampled_from(["quaternion", "euler-parameters", "euler:xyz"]))
def test_random_chain_sizes_match_the_analytic_tip(n, param):
    """chain-N (t in [0, 2], 41 steps) for random N and parametrization: tip position,
    velocity and acceleration = the analytic sums."""
    system = chain_system(n, param)
    results = Solver(system).solve()
    position, velocity, acceleration = tip_reference(n, results.times)
    assert np.abs(kinematics.point_position(results, f"link{n}", "tip") - position).max() < 1e-9
    assert np.abs(kinematics.point_velocity(results, f"link{n}", "tip") - velocity).max() < 1e-8
    assert np.abs(kinematics.point_acceleration(results, f"link{n}", "tip") - acceleration).max() < 1e-7
