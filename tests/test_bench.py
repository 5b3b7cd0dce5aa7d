"""The benchmark: kinegen solves chain-N's literal equations, and every contender still runs
and agrees with the analytic tip (N = 3) or with kinegen's quaternion solution (excavator)."""

from __future__ import annotations

import os

import numpy as np
import pytest
import sympy as sp

from kinegen.bench import contenders
from kinegen.bench.contenders import best_time, kinegen_run, naive_sympy_run, symbolic_phi, workload
from kinegen.runtime.linear import BandLU, DenseLU, choose


@pytest.fixture(autouse=True)
def _one_trajectory(monkeypatch):
    """The contenders' rows here check their answers, not their times: one trajectory each."""
    monkeypatch.setattr(contenders, "REPEATS", 1)


def benchmark_equations(n: int, q: list[sp.Symbol], t: sp.Symbol) -> list[sp.Expr]:
    """chain-N's equations exactly as docs/chain-N.md states them."""

    def matrix(e):
        e0, e1, e2, e3 = e
        return 2 * sp.Matrix(
            [
                [e0**2 + e1**2 - sp.Rational(1, 2), e1 * e2 - e0 * e3, e1 * e3 + e0 * e2],
                [e1 * e2 + e0 * e3, e0**2 + e2**2 - sp.Rational(1, 2), e2 * e3 - e0 * e1],
                [e1 * e3 - e0 * e2, e2 * e3 + e0 * e1, e0**2 + e3**2 - sp.Rational(1, 2)],
            ]
        )

    rows = []
    for i in range(1, n + 1):
        rb, eb = sp.Matrix(q[7 * (i - 1) : 7 * i - 4]), list(q[7 * i - 4 : 7 * i])
        if i == 1:
            ra, ea, Aa = sp.zeros(3, 1), [1, 0, 0, 0], sp.eye(3)
            rows += list(-rb)
        else:
            ra, ea = sp.Matrix(q[7 * (i - 2) : 7 * i - 11]), list(q[7 * i - 11 : 7 * i - 7])
            Aa = matrix(ea)
            rows += list(ra + Aa * sp.Matrix([1, 0, 0]) - rb)
        zb = matrix(eb)[:, 2]
        rows += [(Aa[:, 0].T * zb)[0], (Aa[:, 1].T * zb)[0]]
        rows.append(sum(e**2 for e in eb) - 1)
        theta = sp.Rational(3, 10) + sp.sin(t + sp.Rational(i, 10)) / 2
        a0, a1, a2, a3 = ea
        b0, b1, b2, b3 = eb
        p0 = a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3
        p3 = a0 * b3 - b0 * a3 - (a1 * b2 - a2 * b1)
        rows.append(sp.sin(theta / 2) * p0 - sp.cos(theta / 2) * p3)
    return rows


def test_kinegen_solves_the_benchmarks_literal_equations():
    """Each kinegen row of chain-3 is a benchmark row times -2, -1, 1 or 2 (same Newton iterates).

    Compared at random points (q, t) to 30 digits: two different functions agree to 1e-25
    at three random points only by accident."""
    from kinegen.model.expressions import T

    q, phi = symbolic_phi(workload("chain-3"))
    reference = benchmark_equations(3, q, T)
    assert len(phi) == len(reference) == 21
    rng = np.random.default_rng(2)
    points = [dict(zip([*q, T], (sp.Rational(int(x * 10**6), 10**6) for x in rng.normal(size=len(q) + 1)))) for _ in range(3)]

    def values(expr):
        return [sp.N(expr.subs(point), 30) for point in points]

    reference_values = [values(e) for e in reference]
    unmatched = list(range(len(reference)))
    for row in phi:
        row_values = values(row)
        match = next(
            (k for k in unmatched for f in (1, -1, 2, -2) if all(abs(a - f * b) < 1e-25 for a, b in zip(row_values, reference_values[k]))),
            None,
        )
        assert match is not None, row
        unmatched.remove(match)


def test_chain3_contenders_match_the_analytic_tip():
    cache = os.environ.get("KINEGEN_CACHE")
    compiled = kinegen_run("chain-3", True, compiled=True)  # its C compiled in a fresh cache, timed with the build
    assert os.environ.get("KINEGEN_CACHE") == cache  # and the process's cache is its own again
    for row in (compiled, kinegen_run("chain-3", True), kinegen_run("chain-3", False), naive_sympy_run("chain-3", True)):
        assert row["error"] < 1e-9
        assert row["build"] > 0 and row["trajectory"] > 0
    assert kinegen_run("chain-3", False)["iterations"] > 2  # plain previous-q starts need more Newton steps


def test_a_contenders_time_is_the_shortest_of_its_repeats_within_the_budget():
    """best_time: the shortest of the timed calls (the same work each time), at most ``repeats`` of
    them, fewer once they took ``budget`` seconds; the result is the last call's."""
    import time

    pauses = iter([0.06, 0.002, 0.03, 0.1, 0.05])
    calls = []

    def run():
        pause = next(pauses)
        calls.append(pause)
        time.sleep(pause)
        return pause

    best, last = best_time(run, repeats=3, budget=10.0)
    assert calls == [0.06, 0.002, 0.03] and last == 0.03 and 0.002 <= best < 0.03
    calls.clear()
    best, last = best_time(run, repeats=5, budget=0.12)  # 0.1 + 0.05 pass the budget: no third call
    assert calls == [0.1, 0.05] and last == 0.05 and 0.05 <= best < 0.1


def test_optional_contenders_match_the_analytic_tip():
    pytest.importorskip("casadi")
    pytest.importorskip("symengine")
    from kinegen.bench.contenders import casadi_run, symengine_run

    for row in (casadi_run("chain-3", False), casadi_run("chain-3", True), symengine_run("chain-3")):
        assert row["error"] < 1e-9


def test_band_lu_solves_like_dense_lu_on_a_chain_pattern():
    """Band LU after the bandwidth-reducing permutation = dense LU (random values on chain-14's pattern)."""
    from kinegen.bench.chain import chain_yaml
    from kinegen.codegen.inmemory import lambdify_model
    from kinegen.model import loads
    from kinegen.rotations import get
    from kinegen.runtime import from_module

    system = from_module(lambdify_model(loads(chain_yaml(14, 1.0, 3), "chain14.yaml"), get("euler-parameters")))
    n = system.n_velocity
    shape = (n, n)
    chosen = choose(system.jac_rows, system.jac_cols, shape)
    assert isinstance(chosen, BandLU) and chosen.kl + chosen.ku < 30  # two links' coordinates, not 98
    rng = np.random.default_rng(5)
    values = rng.normal(size=len(system.jac_rows)) + 5 * (system.jac_rows == system.jac_cols)
    dense = DenseLU(system.jac_rows, system.jac_cols, shape)
    matrix = dense.dense(values)
    rhs = rng.normal(size=n)
    expected = np.linalg.solve(matrix, rhs)
    for solver in (chosen, dense):
        factors, _ = solver.factor(values)
        assert np.abs(solver.solve(factors, rhs) - expected).max() < 1e-9 * np.abs(expected).max()
        assert abs(1 / solver.rcond(factors, values) / np.linalg.cond(matrix, 1) - 1) < 10  # an estimate


def test_both_factorizations_bound_the_inverses_absolute_values_from_their_factors():
    """The certificate's coarse bound in Python (linear's ``bound``: the factors' comparison matrices
    solved by getrs or gbtrs) is at least |Phi_q^-1| b for b >= 0, entry by entry: chain-14's Phi_q
    at its solved start, band and dense, every unit vector (each column of |Phi_q^-1|) and a positive
    one; against NumPy's inverse. Coarse by design: loose somewhere."""
    from kinegen.bench.chain import chain_yaml
    from kinegen.codegen.inmemory import lambdify_model
    from kinegen.model import loads
    from kinegen.rotations import get
    from kinegen.runtime import Solver, from_module

    system = from_module(lambdify_model(loads(chain_yaml(14, 1.0, 3), "chain14.yaml"), get("euler-parameters")))
    n = system.n_velocity
    rng = np.random.default_rng(8)
    start = Solver(system).solve(np.array([system.t0]))
    values = system.evaluate(start.q[0], start.inputs[0])[1]
    band, dense = choose(system.jac_rows, system.jac_cols, (n, n)), DenseLU(system.jac_rows, system.jac_cols, (n, n))
    assert isinstance(band, BandLU)
    inverse = np.abs(np.linalg.inv(dense.dense(values)))
    for solver in (band, dense):
        factors, _ = solver.factor(values)
        for b in [*np.eye(n), rng.uniform(0.5, 1.5, n)]:
            exact, bound = inverse @ b, solver.bound(factors, b)
            assert np.isfinite(bound).all() and (bound >= exact - 1e-12 * exact.max()).all(), type(solver).__name__
        assert (solver.bound(factors, np.ones(n)) > 1.5 * (inverse @ np.ones(n))).any()


def test_the_c_targets_memory_row_counts_the_step_and_a_kernel():
    """The benchmark's memory row of one standalone C solver (chain-3): workspace, struct and static
    tables measured by the compiler's sizes, and the step's stack from gcc's call graph -- the solver's
    deepest chain from kinegen_step plus the deepest kernel it calls through the kernel table, found
    whether or not -O2 inlined the kernel into its table entry (call_<kernel>); within the 4 kB the
    standalone target keeps a step to."""
    from kinegen.bench.contenders import c_target_memory

    memory = c_target_memory("chain-3")
    assert memory["workspace"] > 0 and memory["struct"] > 0 and memory["static"] > 0
    assert 0 < memory["stack"] <= 4096, memory


def test_the_issue_41_target_line_covers_the_workloads_it_names():
    """`make bench` checks issue 41's 0.2x CasADi's whole-trajectory C on the workloads the issue
    measured (chain-14, -50, -100 and the excavator's cases); chain-3 keeps only its untagged ratio."""
    from kinegen.bench.__main__ import CASADI_C, KINEGEN_C_OWN, targets

    workloads = ("chain-3", "chain-14", "chain-100", "excavator-digging")
    rows = {(w, name): {"trajectory": t} for w in workloads for name, t in ((KINEGEN_C_OWN, 0.3), (CASADI_C, 1.0))}
    lines = targets(rows, None)
    tagged = [line for line in lines if "(issue 41)" in line]
    assert sorted(line.split()[0] for line in tagged) == ["chain-100", "chain-14", "excavator-digging"], tagged
    assert all("0.3 (<= 0.2) NOT met" in line for line in tagged), tagged
    assert any(line.startswith("chain-3 kinegen compiled C (own predictor) trajectory / CasADi whole-trajectory C:") for line in lines), lines
