"""The benchmark contenders still run and agree with the analytic chain-N tip (N = 3)."""

from __future__ import annotations

from kinegen.bench.contenders import kinegen_run, naive_sympy_run


def test_chain3_contenders_match_the_analytic_tip():
    for row in (kinegen_run(3, True), kinegen_run(3, False), naive_sympy_run(3, True)):
        assert row["error"] < 1e-9
        assert row["build"] > 0 and row["trajectory"] > 0
    assert kinegen_run(3, False)["iterations"] > 2  # plain previous-q starts need more Newton steps
