"""Dual quaternions: conventions against independent references (4x4 homogeneous matrices
built with SciPy's ``Rotation`` and ``expm``), and both dual-quaternion parametrizations on
the excavator against the quaternion run."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from kinegen import rotations
from kinegen.rotations import dual_quaternion_algebra as dq
from kinegen.runtime import Solver, kinematics
from tests.conftest import generated_system

finite = st.floats(-3.0, 3.0, allow_nan=False, allow_infinity=False)
twists = arrays(np.float64, 6, elements=finite)
vectors = arrays(np.float64, 3, elements=finite)
quaternions = arrays(np.float64, 4, elements=st.floats(-1.0, 1.0)).filter(lambda q: np.linalg.norm(q) > 0.1)


def homogeneous(rotation: Rotation, position: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rotation.as_matrix(), position
    return out


def pose(q: np.ndarray, position: np.ndarray) -> tuple[np.ndarray, Rotation]:
    """σ of a frame from SciPy (its quaternions are x-y-z-w; kinegen's w-x-y-z)."""
    rotation = Rotation.from_quat(q[[1, 2, 3, 0]])
    w_first = rotation.as_quat()[[3, 0, 1, 2]]
    return dq.from_pose(position, w_first), rotation


def twist_matrix(twist: np.ndarray) -> np.ndarray:
    """[ξ] = [[ω]x, v; 0, 0] (spatial twist, angular then linear)."""
    (wx, wy, wz), v = twist[:3], twist[3:]
    out = np.zeros((4, 4))
    out[:3, :3] = [[0.0, -wz, wy], [wz, 0.0, -wx], [-wy, wx, 0.0]]
    out[:3, 3] = v
    return out


@settings(max_examples=200, deadline=None)
@given(twists)
def test_the_exponential_is_the_matrix_exponential_of_the_twist(twist):
    assert np.abs(dq.to_homogeneous(dq.exp(twist)) - expm(twist_matrix(twist))).max() < 1e-12


def test_the_exponential_near_zero_uses_its_series_without_a_jump():
    direction = np.array([0.3, -0.5, 0.8, 1.0, 2.0, -1.0])
    at_threshold = 2 * np.sqrt(dq.SERIES_BELOW) / np.linalg.norm(direction[:3])  # |omega|/2 = h, h^2 = SERIES_BELOW
    for scale in (1e-9, 1e-6, 1.99e-4, 2.01e-4, 1e-3, at_threshold * (1 - 1e-9), at_threshold * (1 + 1e-9), 0.05):
        twist = scale * direction
        assert np.abs(dq.to_homogeneous(dq.exp(twist)) - expm(twist_matrix(twist))).max() < 1e-15


def test_the_exponentials_polynomials_are_its_coefficients_to_rounding():
    """Where h^2 <= dq.SERIES_BELOW, cos h, sin(h)/h and (cos h - sin h/h)/h^2 are Taylor polynomials
    in h^2: within 1 ulp of mpmath's values at 40 digits, from 1e-12 rad to the threshold itself."""
    import mpmath

    mpmath.mp.dps = 40
    squared = np.concatenate([np.logspace(-24, np.log10(dq.SERIES_BELOW), 300), [dq.SERIES_BELOW]])
    for values in zip(squared, *dq._coefficients(np.sqrt(squared), squared)):
        h = mpmath.sqrt(mpmath.mpf(float(values[0])))
        exact = (mpmath.cos(h), mpmath.sin(h) / h, (mpmath.cos(h) - mpmath.sin(h) / h) / h**2)
        for value, reference in zip(values[1:], exact):
            assert abs(mpmath.mpf(float(value)) - reference) <= np.spacing(abs(float(reference)))


@settings(max_examples=200, deadline=None)
@given(quaternions, vectors, quaternions, vectors)
def test_composition_and_point_transformation_follow_the_homogeneous_matrices(q1, r1, q2, r2):
    s1, rot1 = pose(q1, r1)
    s2, rot2 = pose(q2, r2)
    product = homogeneous(rot1, r1) @ homogeneous(rot2, r2)
    assert np.abs(dq.to_homogeneous(dq.multiply(s1, s2)) - product).max() < 1e-12
    point = np.array([0.7, -1.3, 2.1])
    assert np.abs(dq.transform_point(s1, point) - (rot1.apply(point) + r1)).max() < 1e-12
    inverse = dq.conjugate(s1)
    assert np.abs(dq.to_homogeneous(inverse) @ homogeneous(rot1, r1) - np.eye(4)).max() < 1e-12


@settings(max_examples=200, deadline=None)
@given(quaternions, vectors)
def test_round_trips_between_dual_quaternion_pose_and_quaternion(q, r):
    s, rotation = pose(q, r)
    assert abs(np.linalg.norm(s[:4]) - 1.0) < 1e-15 and abs(s[:4] @ s[4:]) < 1e-15
    assert np.abs(dq.translation(s) - r).max() < 1e-14
    for param in (rotations.get("dual-quaternion"), rotations.get("dual-euler-parameters")):
        origin, matrix = param.pose(s)
        assert np.abs(origin - r).max() < 1e-14 and np.abs(matrix - rotation.as_matrix()).max() < 1e-15
        again = param.from_pose(origin, matrix)
        assert min(np.abs(again - s).max(), np.abs(again + s).max()) < 1e-14  # σ and -σ are one pose


@settings(max_examples=200, deadline=None)
@given(twists.filter(lambda x: np.linalg.norm(x[:3]) < 0.99 * 2 * np.pi))
def test_log_inverts_exp(twist):
    angle = np.linalg.norm(twist[:3])
    if angle > np.pi:  # the same motion by the shorter turn: ω' = ω (1 - 2π/|ω|), same screw
        return
    assert np.abs(dq.log(dq.exp(twist)) - twist).max() < 1e-9


def test_the_velocity_map_and_frame_rates_are_the_derivatives_of_the_exponential_motion():
    """A step ξ = (δθ, δr) is σ <- exp(ξ₀) ⊗ σ with ξ₀ = (δθ, δr + (r + ½ δr) × δθ) (against the
    4x4 matrix exponential of SciPy) and moves the origin by δr to second order; σ̇(0) = B(σ0) ξ
    (the symbolic map), and the frame's origin velocity and ω from the parametrization equal
    central differences of its pose."""
    param = rotations.get("dual-quaternion")
    sigma0, _ = pose(np.array([0.9, 0.2, -0.3, 0.25]), np.array([1.5, -0.4, 2.0]))
    twist = np.array([0.4, -0.2, 0.7, 0.3, 1.1, -0.5])
    origin = dq.translation(sigma0)
    for h in (0.3, 1e-3):
        step = h * twist
        at_global_origin = np.concatenate([step[:3], step[3:] + np.cross(origin + 0.5 * step[3:], step[:3])])
        expected = expm(twist_matrix(at_global_origin)) @ dq.to_homogeneous(sigma0)
        moved = param.retract(sigma0, step)
        assert np.abs(dq.to_homogeneous(moved) - expected).max() < 1e-12
        assert np.abs(dq.translation(moved) - origin - step[3:]).max() < 2 * h**3  # O(|δθ|² |δr|)
    symbols = sp.Matrix(sp.symbols("s0:8", real=True))
    velocity_map = sp.lambdify(list(symbols), param.body_velocity_map(symbols))(*sigma0)
    h = 1e-6
    ahead, behind = (param.retract(sigma0, sign * h * twist) for sign in (1.0, -1.0))
    assert np.abs((ahead - behind) / (2 * h) - np.asarray(velocity_map) @ twist).max() < 1e-9
    velocity, omega = param.frame_velocity(sigma0, twist)
    (o1, a1), (o0, a0) = param.pose(ahead), param.pose(behind)
    assert np.abs((o1 - o0) / (2 * h) - velocity).max() < 1e-9
    spin = (a1 - a0) / (2 * h) @ param.pose(sigma0)[1].T
    assert np.abs(np.array([spin[2, 1], spin[0, 2], spin[1, 0]]) - omega).max() < 1e-9


def test_the_retraction_keeps_the_dual_quaternion_unit_without_renormalizing():
    param = rotations.get("dual-quaternion")
    sigma, _ = pose(np.array([0.5, 0.5, -0.5, 0.5]), np.array([3.0, 1.0, -2.0]))
    rng = np.random.default_rng(7)
    for _ in range(10_000):
        sigma = param.retract(sigma, rng.normal(scale=0.1, size=6))
    assert abs(np.linalg.norm(sigma[:4]) - 1.0) < 1e-12 and abs(sigma[:4] @ sigma[4:]) < 1e-12


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("param", ["dual_quaternion", "dual_euler_parameters"])
@pytest.mark.parametrize("case", ["digging", "level_cut", "trench_wall"])
def test_every_excavator_point_agrees_with_the_quaternion_run(case, param, compiled):
    reference = Solver(generated_system("excavator_quaternion", case)).solve()
    results = Solver(generated_system(f"excavator_{param}", case, compiled=compiled)).solve()
    assert results.converged.all()
    points = [(body, name) for body, named in results.system.points.items() for name in named]
    assert len(points) == 29  # every named point of the excavator
    for body, name in points:
        assert np.abs(kinematics.point_position(results, body, name) - kinematics.point_position(reference, body, name)).max() < 1e-12, (body, name)


@settings(max_examples=100, deadline=None)
@given(twists, quaternions, vectors)
def test_the_componentwise_increment_is_exp_times_sigma(twist, q, r):
    sigma, _ = pose(q, r)
    for scale in (1.0, 1e-5):  # both branches of the series switch
        expected = dq.multiply(dq.exp(scale * twist), sigma)
        assert np.abs(dq.increment(scale * twist, sigma) - expected).max() < 1e-14


def test_the_boom_jacobian_is_regular_and_its_determinant_is_the_quaternions_up_to_sign():
    """The analogue of the paper's eq. (19): exact Jacobian at t = 0, exact rank, det proven
    non-zero; in the tangent-space form, on the set of valid poses (q_d = ½ (0, r) ⊗ q_r), the
    factored determinant is exactly minus the quaternion parametrization's."""
    from kinegen.analysis import inspect
    from tests.conftest import model

    boom = model("boom")
    quaternion = inspect(boom, rotations.get("quaternion"), "swing", 0)
    dual = inspect(boom, rotations.get("dual-quaternion"), "swing", 0)
    assert dual.rank == 6 and dual.determinant_value == -1
    names = {sp.Symbol(f"boom_q{c}", real=True): sp.Symbol(f"boom_r{c}", real=True) for c in "wxyz"}
    assert sp.expand(dual.determinant + quaternion.determinant.xreplace(names)) == 0
    algebraic = inspect(boom, rotations.get("dual-euler-parameters"), "swing", 0)
    assert algebraic.rank == 8 and algebraic.determinant_value != 0
    assert algebraic.q[5] == 89 * sp.sqrt(2) / 200  # q_d exact from the exact pose


def _dual_vector(vector: np.ndarray, moment: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], vector, [0.0], moment])


def test_joint_rows_move_points_and_lines_by_the_dual_quaternion_sandwich():
    """What the joint equations of the dual-quaternion parametrizations see: a body point is
    σ ⊗ (1 + ε p) ⊗ σ̄*, a body line (h, p × h) is σ ⊗ L ⊗ σ*, and the dual part of two lines'
    dual scalar product is l1·m2 + m1·l2 (all products numeric, from ``multiply``), at 50
    random pairs of poses."""
    from kinegen.symbolic.assembly import coordinates
    from tests.conftest import model

    coords = coordinates(model("four_bar"), rotations.get("dual-quaternion"))
    b1, b2 = coords.bodies[:2]
    p_symbols, h_symbols = sp.Matrix(sp.symbols("p0:3", real=True)), sp.Matrix(sp.symbols("h0:3", real=True))
    lines = [b.frame.line(p_symbols, h_symbols) for b in (b1, b2)]
    real, dual = lines[0].dual_dot(lines[1])
    outputs = [b1.frame.point(p_symbols), *(x for line in lines for x in (line.direction, line.moment)), real, dual]
    arguments = [*b1.stored, *b2.stored, *p_symbols, *h_symbols]
    evaluate = sp.lambdify(arguments, [sp.Matrix([o]).xreplace(coords.frame_definitions) for o in outputs])

    def sandwich(sigma, x, bar):
        conjugate = dq.conjugate(sigma) * (np.r_[np.ones(4), -np.ones(4)] if bar else 1.0)
        return dq.multiply(dq.multiply(sigma, x), conjugate)

    rng = np.random.default_rng(12)
    for _ in range(50):
        sigmas = [pose(rng.normal(size=4), rng.normal(scale=5.0, size=3))[0] for _ in range(2)]
        p, h = rng.normal(scale=2.0, size=3), rng.normal(size=3)
        h /= np.linalg.norm(h)
        point, d1, m1, d2, m2, dot_real, dot_dual = (np.asarray(x, dtype=float).ravel() for x in evaluate(*sigmas[0], *sigmas[1], *p, *h))
        assert np.abs(point - sandwich(sigmas[0], np.r_[1.0, 0, 0, 0, 0, p], bar=True)[5:]).max() < 1e-12
        moved = [sandwich(s, np.r_[0.0, h, 0.0, np.cross(p, h)], bar=False) for s in sigmas]
        assert np.abs(np.r_[d1, m1] - np.r_[moved[0][1:4], moved[0][5:]]).max() < 1e-12
        assert np.abs(np.r_[d2, m2] - np.r_[moved[1][1:4], moved[1][5:]]).max() < 1e-12
        (l1, n1), (l2, n2) = ((e[1:4], e[5:]) for e in moved)
        assert abs(dot_real[0] - l1 @ l2) < 1e-12 and abs(dot_dual[0] - (l1 @ n2 + n1 @ l2)) < 1e-11
