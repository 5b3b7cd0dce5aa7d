"""Working range: kinegen's sweep + refinement against the planar closed form optimized independently."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from kinegen.analysis.envelope import working_range
from tests.conftest import generated_system, model
from tests.excavator_reference import planar_pins

RANGES = np.array([[1.7352, 3.0649], [1.8164, 3.2939], [1.6529, 2.6613]])


def closed_form_optimum(objective, constraint=None, starts=40) -> float:
    """Best value of objective(pins) over the cylinder box by SLSQP on the law-of-cosines model."""
    rng = np.random.default_rng(1)
    best = np.inf
    for x0 in rng.uniform(0, 1, size=(starts, 3)):

        def pins(x):
            return planar_pins(*(RANGES[:, 0] + np.clip(x, 0, 1) * (RANGES[:, 1] - RANGES[:, 0])))[0]

        cons = [{"type": "eq", "fun": lambda x: constraint(pins(x))}] if constraint else []
        result = minimize(
            lambda x: objective(pins(x)),
            x0,
            method="SLSQP",
            bounds=[(0, 1)] * 3,
            constraints=cons,
            options={"ftol": 1e-12, "maxiter": 200},
        )
        if result.success and (constraint is None or abs(constraint(pins(result.x))) < 1e-9):
            best = min(best, objective(pins(result.x)))
    return best


def test_working_range_figures_match_the_planar_closed_form():
    spec = model("excavator").working_range
    envelope = working_range(generated_system("excavator_quaternion", spec.case), spec, grid=(9, 5, 9))
    figures = envelope.figures
    assert abs(figures["max_reach"] - -closed_form_optimum(lambda p: -p["T"][0])) < 1e-6
    assert abs(figures["max_reach_at_ground"] - -closed_form_optimum(lambda p: -p["T"][0], lambda p: p["T"][1])) < 1e-6
    assert abs(figures["max_depth"] - -closed_form_optimum(lambda p: p["T"][1])) < 1e-6
    assert abs(figures["max_cutting_height"] - -closed_form_optimum(lambda p: -p["T"][1])) < 1e-6
    dumping = -closed_form_optimum(lambda p: -p["T"][1], lambda p: p["T"][0] - p["Q"][0])
    assert abs(figures["max_dumping_height"] - dumping) < 1e-6
    assert np.isfinite(envelope.points).all()  # every sample solved
    # within the published (unverified) figures' neighbourhood: a sanity check, not a reference
    assert abs(figures["max_reach_at_ground"] - spec.published["max_reach_at_ground"]) < 0.1
