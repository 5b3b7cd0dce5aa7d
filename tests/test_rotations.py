"""Rotation conventions against SciPy's Rotation, and angular velocity against finite differences."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

from kinegen import rotations
from kinegen.rotations import quaternion_algebra as qa
from kinegen.rotations.euler_angles import SEQUENCES

RNG = np.random.default_rng(7)
ANGLES = RNG.uniform(-2.5, 2.5, size=(20, 3))
ANGLES[:, 1] = RNG.uniform(0.3, 1.2, size=20)  # away from every sequence's singular set


def test_all_twelve_sequences_are_offered():
    assert len(SEQUENCES) == 12
    assert {"zxz", "zyz", "xyz", "zyx"} <= set(SEQUENCES)


@pytest.mark.parametrize("sequence", SEQUENCES)
def test_euler_matrices_match_scipy_intrinsic(sequence):
    p = rotations.get(f"euler:{sequence}")
    reference = Rotation.from_euler(sequence.upper(), ANGLES).as_matrix()
    assert np.allclose(p.to_matrix(ANGLES), reference, atol=1e-14)
    symbols = sp.symbols("a b c")
    symbolic = sp.lambdify(symbols, p.matrix(sp.Matrix(symbols)), "numpy")
    assert np.allclose(symbolic(*ANGLES[3]), reference[3], atol=1e-14)
    back = p.to_matrix(p.from_matrix(reference))
    assert np.allclose(back, reference, atol=1e-13)


@pytest.mark.parametrize("name", ["quaternion", "euler-parameters"])
def test_quaternion_order_is_w_x_y_z_like_scipy_scalar_first(name):
    p = rotations.get(name)
    rot = Rotation.random(20, random_state=3)
    q = rot.as_quat(scalar_first=True)
    assert np.allclose(p.to_matrix(q), rot.as_matrix(), atol=1e-14)
    symbols = sp.symbols("w x y z")
    symbolic = sp.lambdify(symbols, p.matrix(sp.Matrix(symbols)), "numpy")
    assert np.allclose(symbolic(*q[0]), rot.as_matrix()[0], atol=1e-14)
    recovered = p.from_matrix(rot.as_matrix())
    assert np.allclose(np.abs(np.sum(recovered * q, axis=1)), 1.0, atol=1e-12)


def test_quaternion_product_and_exponential_match_scipy():
    a, b = Rotation.random(2, random_state=11)
    product = qa.multiply(a.as_quat(scalar_first=True), b.as_quat(scalar_first=True))
    assert np.allclose(qa.to_matrix(product), (a * b).as_matrix(), atol=1e-14)
    vector = np.array([0.3, -1.2, 0.7])
    assert np.allclose(qa.to_matrix(qa.exp(vector)), Rotation.from_rotvec(vector).as_matrix(), atol=1e-14)
    assert np.allclose(qa.exp(np.array([1e-12, 0, 0])), [1, 5e-13, 0, 0], atol=1e-20)


@pytest.mark.parametrize("name", ["quaternion", "euler-parameters", "euler:zxz", "euler:xyz", "euler:yzy"])
def test_omega_matches_finite_differences_of_the_matrix(name):
    """omega from the parametrization vs [omega]x = dA/dt A^T by central differences."""
    p = rotations.get(name)
    rot0 = Rotation.from_euler("ZXZ", [0.4, 0.8, -0.3])
    w_true = np.array([0.7, -0.4, 1.1])  # constant global angular velocity
    h = 1e-5

    def stored(t):
        return p.from_matrix((Rotation.from_rotvec(w_true * t) * rot0).as_matrix())

    o = stored(0.0)
    o_dot = (stored(h) - stored(-h)) / (2 * h)
    o_ddot = (stored(h) - 2 * o + stored(-h)) / h**2
    if name == "quaternion":
        w, w_dot = w_true, np.zeros(3)
    else:
        w, w_dot = o_dot, o_ddot
    assert np.allclose(p.omega(o, w), w_true, atol=1e-8)
    assert np.allclose(p.omega_dot(o, w, w_dot), 0.0, atol=2e-5)


def test_quaternion_velocity_map_is_the_tangent_of_the_exponential_map():
    p = rotations.get("quaternion")
    q = Rotation.random(random_state=5).as_quat(scalar_first=True)
    symbols = sp.symbols("w x y z")
    b = np.array(sp.lambdify(symbols, p.velocity_map(sp.Matrix(symbols)), "numpy")(*q), dtype=float)
    h = 1e-7
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        derivative = (p.retract_orientation(q, step) - p.retract_orientation(q, -step)) / (2 * h)
        assert np.allclose(derivative, b[:, k], atol=1e-9)


def test_increment_is_exp_then_multiply_and_matches_scipy():
    """The component-first retraction exp(theta) ⊗ q equals SciPy's composition, batches and
    tiny angles (Taylor branch) included."""
    rng = np.random.default_rng(11)
    theta = rng.normal(size=(3, 5, 7)) * np.logspace(-12, 0.5, 7)
    q = Rotation.random(35, random_state=12).as_quat(scalar_first=True).T.reshape(4, 5, 7)
    out = qa.increment(theta, q)
    reference = Rotation.from_rotvec(theta.reshape(3, -1).T) * Rotation.from_quat(q.reshape(4, -1).T, scalar_first=True)
    expected = reference.as_quat(scalar_first=True).T.reshape(4, 5, 7)
    sign = np.sign((out * expected).sum(axis=0))  # q and -q are the same rotation
    assert np.abs(out - sign * expected).max() < 1e-15 * 4
    assert np.allclose(out, np.moveaxis(qa.multiply(qa.exp(np.moveaxis(theta, 0, -1)), np.moveaxis(q, 0, -1)), -1, 0), atol=1e-15)


def test_the_retractions_polynomials_are_the_half_angles_cosine_and_sine_to_rounding():
    """Below qa.SERIES_BELOW the quaternion increment's cos(angle/2) and sin(angle/2)/angle are
    Taylor polynomials: against mpmath at 40 digits they are within 1.5 ulp of the functions'
    exact values (the last one at the threshold itself), and the functions' doubles (NumPy's, the
    branch above) differ from them there by at most 2 ulp: the retraction has no step at its
    threshold."""
    import mpmath

    mpmath.mp.dps = 40
    squared = np.concatenate([np.logspace(-24, np.log10(qa.SERIES_BELOW), 400), [qa.SERIES_BELOW]])
    theta = np.zeros((3, squared.size))
    theta[0] = np.sqrt(squared)
    moved = qa.increment(theta, np.tile([[1.0], [0.0], [0.0], [0.0]], squared.size))  # (cos, scale * theta_x, 0, 0)
    for angle, cos_half, sine_x in zip(theta[0], moved[0], moved[1]):
        exact = mpmath.mpf(float(angle)) / 2
        assert abs(mpmath.mpf(float(cos_half)) - mpmath.cos(exact)) <= 1.5 * np.spacing(1.0) / 2
        assert abs(mpmath.mpf(float(sine_x)) - mpmath.sin(exact)) <= 1.5 * np.spacing(sine_x)
    above = qa.increment(np.nextafter(theta[:, -1:], 1.0), np.array([[1.0], [0.0], [0.0], [0.0]]))
    assert abs(above[0, 0] - moved[0, -1]) <= 2 * np.spacing(1.0) and abs(above[1, 0] - moved[1, -1]) <= 2 * np.spacing(moved[1, -1])
