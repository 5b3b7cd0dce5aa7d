"""Batched Newton: the same solutions as the sequential solver and the closed-form planar excavator."""

from __future__ import annotations

import numpy as np
import pytest

from kinegen.runtime import Solver
from kinegen.runtime.batch import BlockSolve, _lagrange_weights, solve_batch, sweep_grid
from tests.conftest import generated_system, model
from tests.excavator_reference import planar_pins, spatial


def test_block_solve_equals_a_dense_solve():
    system = generated_system("excavator_quaternion", "digging")
    rng = np.random.default_rng(4)
    q = system.initial_q[:, None] + 0.01 * rng.normal(size=(system.n_stored, 6))
    u = np.repeat(system.driver_inputs(0.0)[0][:, None], 6, axis=1)
    values = system.jac(q, u)
    rhs = rng.normal(size=(len(system.constraint_names), 6))
    x = BlockSolve(system).solve(values, rhs)
    for k in range(6):
        dense = system.jacobian(q[:, k], u[:, k])
        assert np.abs(dense @ x[:, k] - rhs[:, k]).max() < 1e-10


def test_batch_newton_equals_the_sequential_solver():
    system = generated_system("excavator_quaternion", "digging")
    solver = Solver(system)
    u0 = system.driver_inputs(0.0)[0]
    start = solver.position(system.initial_q, u0, 0.0)[0]
    rng = np.random.default_rng(8)
    u = u0[:, None] + np.array([0.2, 0.05, 0.05, 0.05])[:, None] * rng.uniform(-1, 1, (4, 40))
    result = solve_batch(system, u, np.repeat(start[:, None], 40, axis=1))
    assert result.converged.all() and result.residuals.max() <= 1e-10
    for k in range(0, 40, 7):
        assert np.abs(solver.position(start, u[:, k], 0.0)[0] - result.q[:, k]).max() < 1e-10


@pytest.mark.parametrize("counts", [(7, 4, 7), (21, 3, 21)])
def test_grid_sweep_matches_the_closed_form_planar_excavator(counts):
    """Grids over the three cylinder ranges at zero swing, solved by slice continuation only
    (7 x 4 x 7) and coarse to fine (21 x 3 x 21: an 11 x 3 x 11 continuation, then two
    interpolated fills): every bucket tip equals the law-of-cosines reference to 1e-9 m."""
    system = generated_system("excavator_quaternion", "digging")
    spec = model("excavator").working_range
    names = list(system.driver_names)
    swept = [names.index(n) for n in ("boom_length", "arm_length", "bucket_length")]
    axes = [np.linspace(*spec.numbers(system.design)[names[i]], c) for i, c in zip(swept, counts)]
    base = np.zeros(len(names))
    base[swept] = [a[0] for a in axes]
    solver = Solver(system)
    q, u = system.initial_q.copy(), system.driver_inputs(0.0)[0]
    for s in np.linspace(0, 1, 21)[1:]:  # continuation from the model's pose to the grid corner
        q = solver.position(q, u + s * (base - u))[0]
    result = sweep_grid(system, base, swept, axes, q)
    assert result.converged.all()
    offset = system.bodies["bucket"][0]
    tip = np.array(system.points["bucket"]["T"])
    worst = 0.0
    for index in np.ndindex(*result.converged.shape):
        body = result.q[(slice(offset, offset + 7), *index)]
        position = body[:3] + system.parametrization.to_matrix(body[3:]) @ tip
        pins, _ = planar_pins(*(axes[d][i] for d, i in enumerate(index)))
        worst = max(worst, np.abs(position - spatial(pins["T"], 0.0)).max())
    assert worst < 1e-9, worst


def test_interpolation_weights_reproduce_quintics():
    """The fill's start values: quintic Lagrange weights from six known values are exact for
    any quintic, also next to the ends of an axis and on an uneven grid."""
    values = np.cumsum(np.random.default_rng(3).uniform(0.5, 1.5, 11))
    known, wanted = np.array([0, 2, 4, 6, 8, 10]), np.array([1, 3, 5, 7, 9])
    weights = _lagrange_weights(values, known, wanted)
    quintic = 1e-3 * values**5 - 0.3 * values**3 - 2.0 * values**2 + values - 5.0
    assert np.abs(weights @ quintic[known] - quintic[wanted]).max() < 1e-9 * np.abs(quintic).max()
    assert np.allclose(weights.sum(axis=1), 1.0)
