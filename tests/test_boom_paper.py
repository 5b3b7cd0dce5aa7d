"""The paper's boom (Fig. 3), reproduced: singular with Euler z-x-z, eq. (19) with quaternions."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from kinegen import rotations
from kinegen.analysis import inspect
from kinegen.errors import SingularJacobianError
from kinegen.runtime import kinematics, solve
from tests.conftest import generated_system, model

#: The paper's eq. (19), the quaternion-formulation Jacobian at t = 0.
EQ_19 = sp.Matrix(
    [
        [-1, 0, 0, 0, 0, -sp.Rational(178, 100)],
        [0, -1, 0, 0, 0, 0],
        [0, 0, -1, sp.Rational(178, 100), 0, 0],
        [0, 0, 0, 1, 0, 0],
        [0, 0, 0, 0, 1, 0],
        [0, 0, 0, 0, 0, -1],
    ]
)


def test_euler_zxz_jacobian_is_provably_singular_at_t0():
    report = inspect(model("boom"), rotations.get("euler:zxz"), t="0")
    assert report.jacobian.shape == (6, 6)
    assert report.rank == 5
    assert report.null_space == ["boom.alpha - boom.gamma"]
    # the alpha and gamma columns coincide
    names = report.velocity_names
    assert report.jacobian[:, names.index("boom.alpha")] == report.jacobian[:, names.index("boom.gamma")]
    beta = sp.Symbol("boom_beta", real=True)
    assert report.determinant_value == 0
    assert any(sp.simplify(f - sp.sin(beta)) == 0 for f in report.vanishing_factors)
    assert sp.simplify(report.determinant.subs(beta, 0)) == 0
    assert not any(f.is_Add and sp.trigsimp(f).is_number for f in sp.Mul.make_args(report.determinant))  # no sin^2 + cos^2


def test_trigonometric_simplification_of_a_determinant_keeps_its_value():
    """The boom's factored Euler z-x-z determinant as ``factor`` leaves it, simplified: the
    identity factor gone, the value the same at random angles."""
    from kinegen.analysis.inspect import _trig_simplified

    a, b, g, p = sp.symbols("boom_alpha boom_beta boom_gamma phi1", real=True)
    factored = -(sp.sin(g) ** 2 + sp.cos(g) ** 2) * (
        -sp.sin(a) * sp.sin(g) * sp.cos(b) * sp.cos(p) + sp.sin(a) * sp.sin(p) * sp.cos(g)
        + sp.sin(g) * sp.sin(p) * sp.cos(a) * sp.cos(b) + sp.cos(a) * sp.cos(g) * sp.cos(p)
    ) * sp.sin(b) * sp.cos(b)  # fmt: skip
    simplified = _trig_simplified(factored)
    assert sp.sin(g) ** 2 + sp.cos(g) ** 2 not in sp.Mul.make_args(simplified) and sp.sin(b) in sp.Mul.make_args(simplified)
    assert sp.count_ops(simplified) < sp.count_ops(factored)
    rng = np.random.default_rng(5)
    for values in rng.uniform(-3, 3, (5, 4)):
        point = dict(zip((a, b, g, p), values))
        assert float(simplified.xreplace(point)) == pytest.approx(float(factored.xreplace(point)), abs=1e-13)


def test_quaternion_jacobian_is_the_papers_eq_19_up_to_row_signs():
    report = inspect(model("boom"), rotations.get("quaternion"), t="0")
    assert report.rank == 6
    for i in range(6):
        row = report.jacobian.row(i)
        assert row == EQ_19.row(i) or row == -EQ_19.row(i), i
    assert abs(report.determinant_value) == 1
    assert report.vanishing_factors == []


def test_euler_parameters_jacobian_is_7x7_and_non_singular():
    report = inspect(model("boom"), rotations.get("euler-parameters"), t="0")
    assert report.jacobian.shape == (7, 7)
    assert report.rank == 7
    assert report.determinant_value != 0


def test_solving_with_euler_zxz_stops_at_t0():
    with pytest.raises(SingularJacobianError) as info:
        solve(generated_system("boom_euler_zxz"))
    error = info.value
    assert error.t == 0 and error.rank == 5
    assert error.null_space == ["boom.alpha - boom.gamma"]
    assert error.dependent_constraints  # names the dependent joint equation
    assert "singular Jacobian at t = 0" in str(error)


@pytest.mark.parametrize("param", ["quaternion", "euler_parameters"])
def test_boom_motion_matches_closed_form(param):
    results = solve(generated_system(f"boom_{param}"))
    t = results.times
    assert t[0] == 0 and t[-1] == 2
    angle = np.pi / 2 + t**2
    zero = np.zeros_like(t)
    assert np.abs(kinematics.omega(results, "boom") - np.c_[zero, zero, 2 * t]).max() < 1e-10
    assert np.abs(kinematics.omega_dot(results, "boom") - np.c_[zero, zero, zero + 2]).max() < 1e-10
    frame_origin = 1.78 * np.c_[np.cos(angle), np.sin(angle), zero]
    assert np.abs(kinematics.position(results, "boom") - frame_origin).max() < 1e-10
    assert np.abs(kinematics.point_position(results, "boom", "O")).max() < 1e-10  # the pivot stays put
    yaw = np.unwrap(kinematics.euler_angles(results, "boom", "zyx")[:, 0])
    assert np.abs(yaw - angle).max() < 1e-10
