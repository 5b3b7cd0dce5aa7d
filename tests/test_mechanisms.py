"""Solved motion against independent references.

* slider-crank and four-bar: closed-form planar positions, differentiated exactly (SymPy);
* RSSR (spatial): velocities and accelerations against Richardson-extrapolated central
  differences of kinegen's own positions;
* chain of N revolute links with parallel z axes: closed-form tip;
* omega and omega_dot agree across every regular parametrization.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from kinegen.bench.chain import tip_reference
from kinegen.errors import SingularJacobianError
from kinegen.runtime import Solver, SolverOptions, kinematics, solve
from tests.conftest import chain_system, generated_system

PARAMS = ["quaternion", "euler_parameters", "dual_quaternion", "dual_euler_parameters"]
t = sp.Symbol("t")


def closed_form(expressions: list[sp.Expr], times: np.ndarray) -> list[np.ndarray]:
    """Values, first and second time derivatives of each expression on ``times`` (the second the
    first's derivative, each order lambdified with its common subexpressions: the four-bar's took
    7 s as sp.diff(e, t, order) printed whole, 1.5 s so; the values agree to 3e-14)."""
    out = []
    for order in range(3):
        if order:
            expressions = [e.diff(t) for e in expressions]
        f = sp.lambdify(t, expressions, "numpy", cse=True)
        out.append(np.array([np.broadcast_to(v, times.shape) for v in f(times)]).T)
    return out


@pytest.mark.parametrize("param", PARAMS)
def test_slider_crank_matches_closed_form(param):
    results = solve(generated_system(f"slider_crank_{param}"))
    r, rod_length = sp.Rational(1, 5), sp.Rational(3, 5)
    theta = sp.Rational(3, 10) + 2 * sp.pi * t + t**2 / 2
    slider_x = r * sp.cos(theta) + sp.sqrt(rod_length**2 - r**2 * sp.sin(theta) ** 2)
    rod_angle = sp.atan2(-r * sp.sin(theta), slider_x - r * sp.cos(theta))
    (x, _), (xd, rodd), (xdd, roddd) = (np.array(a).T for a in closed_form([slider_x, rod_angle], results.times))
    zero = np.zeros_like(x)
    assert np.abs(kinematics.point_position(results, "slider", "C") - np.c_[x, zero, zero]).max() < 1e-10
    assert np.abs(kinematics.point_velocity(results, "slider", "C") - np.c_[xd, zero, zero]).max() < 1e-9
    assert np.abs(kinematics.point_acceleration(results, "slider", "C") - np.c_[xdd, zero, zero]).max() < 1e-8
    assert np.abs(kinematics.omega(results, "rod") - np.c_[zero, zero, rodd]).max() < 1e-9
    assert np.abs(kinematics.omega_dot(results, "rod") - np.c_[zero, zero, roddd]).max() < 1e-8
    crank_rate = 2 * np.pi + results.times
    assert np.abs(kinematics.omega(results, "crank")[:, 2] - crank_rate).max() < 1e-9
    # the crank turns more than once: the angle driver holds over the full circle
    angle = np.unwrap(kinematics.euler_angles(results, "crank", "zyx")[:, 0])
    assert angle[-1] - angle[0] > 2 * np.pi
    assert np.abs(angle - (0.3 + 2 * np.pi * results.times + 0.5 * results.times**2)).max() < 1e-10


@pytest.mark.parametrize("param", PARAMS)
def test_four_bar_matches_closed_form(param):
    results = solve(generated_system(f"four_bar_{param}"))
    a, b, c, d = sp.Rational(3, 10), sp.Rational(9, 10), sp.Rational(7, 10), sp.Integer(1)
    theta = sp.Rational(1, 2) + 2 * sp.pi * t + sp.Rational(3, 10) * sp.sin(2 * sp.pi * t)
    bx, by = a * sp.cos(theta), a * sp.sin(theta)
    ux, uy = d - bx, -by
    dist = sp.sqrt(ux**2 + uy**2)
    along = (b**2 - c**2 + dist**2) / (2 * dist)
    height = sp.sqrt(b**2 - along**2)  # upper branch, as assembled
    cx = bx + along * ux / dist - height * uy / dist
    cy = by + along * uy / dist + height * ux / dist
    rocker_angle = sp.atan2(cy, cx - d)
    (p, rate, acc) = closed_form([cx, cy, rocker_angle], results.times)
    zero = np.zeros(len(results.times))
    assert np.abs(kinematics.point_position(results, "rocker", "C") - np.c_[p[:, 0], p[:, 1], zero]).max() < 1e-10
    assert np.abs(kinematics.point_velocity(results, "coupler", "C") - np.c_[rate[:, 0], rate[:, 1], zero]).max() < 1e-9
    assert np.abs(kinematics.point_acceleration(results, "coupler", "C") - np.c_[acc[:, 0], acc[:, 1], zero]).max() < 1e-8
    assert np.abs(kinematics.omega(results, "rocker") - np.c_[zero, zero, rate[:, 2]]).max() < 1e-9
    assert np.abs(kinematics.omega_dot(results, "rocker") - np.c_[zero, zero, acc[:, 2]]).max() < 1e-8


@pytest.mark.parametrize("param", PARAMS)
def test_rssr_velocity_and_acceleration_match_central_differences(param):
    """Spatial mechanism: no closed form, so differentiate kinegen's own positions.

    Richardson-extrapolated central differences with h = 1e-3 have truncation error
    O(h^4) ~ 1e-12 and round-off ~ 1e-14/h (velocity), 1e-14/h^2 (acceleration).
    """
    system = generated_system(f"rssr_{param}")
    solver = Solver(system, SolverOptions(tolerance=1e-14))
    full = solver.solve()  # start each stencil from the nearest pose of the tracked branch
    h = 1e-3
    checked = 0
    for t0 in (0.13, 0.41, 0.77):
        times = t0 + h * np.arange(-2, 3)
        nearest = full.q[np.argmin(np.abs(full.times - times[0]))]
        r = solver.solve(times, q0=solver.position(nearest, system.driver_inputs(times[0])[0])[0])
        for body, point in (("crank", "B"), ("rocker", "C")):
            p = kinematics.point_position(r, body, point)
            v1 = (p[3] - p[1]) / (2 * h)
            v2 = (p[4] - p[0]) / (4 * h)
            a1 = (p[3] - 2 * p[2] + p[1]) / h**2
            a2 = (p[4] - 2 * p[2] + p[0]) / (4 * h**2)
            assert np.allclose(kinematics.point_velocity(r, body, point)[2], (4 * v1 - v2) / 3, rtol=0, atol=1e-9)
            assert np.allclose(kinematics.point_acceleration(r, body, point)[2], (4 * a1 - a2) / 3, rtol=0, atol=1e-6)
            checked += 1
        rotation = kinematics.rotation_matrix(r, "rocker")
        rate = (4 * (rotation[3] - rotation[1]) / (2 * h) - (rotation[4] - rotation[0]) / (4 * h)) / 3
        spin = rate @ rotation[2].T  # [omega]x = dA/dt A^T
        assert np.allclose(kinematics.omega(r, "rocker")[2], [spin[2, 1], spin[0, 2], spin[1, 0]], rtol=0, atol=1e-9)
        assert np.abs(r.residuals).max() < 1e-12
    assert checked == 6


@pytest.mark.parametrize("other", ["rssr_euler_parameters", "rssr_dual_quaternion", "rssr_dual_euler_parameters"])
def test_rssr_parametrizations_agree(other):
    a = solve(generated_system("rssr_quaternion"))
    b = solve(generated_system(other))
    for body, point in (("crank", "B"), ("rocker", "C")):
        assert np.abs(kinematics.point_position(a, body, point) - kinematics.point_position(b, body, point)).max() < 1e-9
    assert np.abs(kinematics.omega(a, "rocker") - kinematics.omega(b, "rocker")).max() < 1e-8
    assert np.abs(kinematics.omega_dot(a, "rocker") - kinematics.omega_dot(b, "rocker")).max() < 1e-6


REGULAR = ["quaternion", "euler-parameters", "euler:xyz", "euler:zyx", "dual-quaternion", "dual-euler-parameters"]


@pytest.mark.parametrize("param", REGULAR)
def test_chain_tip_matches_closed_form(param):
    """Pass criterion of the chain-N benchmark: tip position within 1e-9 m.

    Newton stops at max |Phi| <= 1e-10 per joint; over 4 links the tip error reaches ~2e-10.
    """
    n = 4
    results = solve(chain_system(n, param))
    position, velocity, acceleration = tip_reference(n, results.times)
    assert np.abs(kinematics.point_position(results, f"link{n}", "tip") - position).max() < 1e-9
    assert np.abs(kinematics.point_velocity(results, f"link{n}", "tip") - velocity).max() < 1e-9
    assert np.abs(kinematics.point_acceleration(results, f"link{n}", "tip") - acceleration).max() < 1e-8
    assert results.iterations[0] >= 2  # the start was assembled from an off-solution pose


def test_chain_omega_identical_across_regular_parametrizations():
    """Solved to max |Phi| <= 1e-13, every regular parametrization gives the same motion."""
    tight = SolverOptions(tolerance=1e-13)
    runs = {p: Solver(chain_system(4, p), tight).solve() for p in REGULAR}
    reference = runs["quaternion"]
    for name, r in runs.items():
        for body in ("link1", "link4"):
            assert np.abs(kinematics.rotation_matrix(r, body) - kinematics.rotation_matrix(reference, body)).max() < 1e-12, name
            assert np.abs(kinematics.omega(r, body) - kinematics.omega(reference, body)).max() < 1e-12, name
            assert np.abs(kinematics.omega_dot(r, body) - kinematics.omega_dot(reference, body)).max() < 1e-11, name


def test_chain_with_zxz_euler_angles_is_singular():
    with pytest.raises(SingularJacobianError) as info:
        solve(chain_system(3, "euler:zxz"))
    assert "link1.alpha - link1.gamma" in "; ".join(info.value.null_space)
