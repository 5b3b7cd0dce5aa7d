"""Design parameters (issue 13, part 1): the ``design:`` section keeps geometry symbolic.

* the geometry that uses a design parameter is an expression of its symbol ``p_<name>``;
* ``Model.at(values)`` is the model as if its file had been written with those numbers
  (compared with such a file, and solved against the slider-crank's closed form);
* malformed design sections and design parameters used outside the geometry name the file
  and the entry.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from kinegen import rotations
from kinegen.codegen.inmemory import lambdify_model
from kinegen.errors import ModelError
from kinegen.model import load, loads
from kinegen.runtime import from_module, solve
from tests.conftest import MODELS

PLAIN = (MODELS / "slider_crank.yaml").read_text()
PARAMETERS = "parameters:\n  r: 0.2    # crank A-B\n  l: 0.6    # connecting rod B-C\n"
DESIGN = "design:\n  r: {nominal: 0.2, bounds: [0.15, 0.25], description: crank}\n  l: {nominal: 0.6, bounds: [0.5, 0.7]}\n"


def design_model(design: str = DESIGN, extra: str = "") -> str:
    assert PARAMETERS in PLAIN
    return PLAIN.replace(PARAMETERS, design + extra)


def written_with(crank: str, rod: str) -> str:
    return PLAIN.replace(PARAMETERS, f"parameters:\n  r: {crank}\n  l: {rod}\n")


def same_model(a, b) -> bool:
    """Equal up to the file they were read from."""
    return a.__class__(**{**a.__dict__, "file": b.file, "source_sha256": b.source_sha256}) == b


def test_design_parameters_stay_symbols_in_the_geometry():
    model = loads(design_model(), "slider_crank_design.yaml")
    crank, rod = (d.symbol for d in model.design)
    assert [(d.name, d.nominal, d.lower, d.upper) for d in model.design] == [
        ("r", sp.Rational(1, 5), sp.Rational(3, 20), sp.Rational(1, 4)),
        ("l", sp.Rational(3, 5), sp.Rational(1, 2), sp.Rational(7, 10)),
    ]
    assert model.body("crank").points["B"] == sp.ImmutableMatrix([crank, 0, 0])
    assert model.body("rod").points["C"] == sp.ImmutableMatrix([rod, 0, 0])
    assert model.design[0].description == "crank"


def test_a_model_at_given_values_is_the_model_written_with_them():
    model = loads(design_model(), "slider_crank_design.yaml")
    assert same_model(model.at(), load(MODELS / "slider_crank.yaml"))  # nominal
    assert same_model(model.at({"r": 0.21, "l": 0.65}), loads(written_with("0.21", "0.65"), "x.yaml"))
    assert same_model(model.at({"l": 0.55}), loads(written_with("0.2", "0.55"), "x.yaml"))
    with pytest.raises(KeyError, match="not design parameters of slider_crank: q"):
        model.at({"q": 1.0})


def test_a_model_at_other_values_solves_to_the_closed_form():
    """The slider at x = r cos θ + sqrt(l² − r² sin² θ) with r = 0.21, l = 0.65 (not the nominal)."""
    model = loads(design_model(), "slider_crank_design.yaml").at({"r": 0.21, "l": 0.65})
    results = solve(from_module(lambdify_model(model, rotations.get("quaternion")), "run"))
    t = results.times
    theta = 0.3 + 2 * np.pi * t + 0.5 * t**2
    x = 0.21 * np.cos(theta) + np.sqrt(0.65**2 - 0.21**2 * np.sin(theta) ** 2)
    assert np.abs(results.point_position("slider", "C")[:, 0] - x).max() < 1e-10


@pytest.mark.parametrize(
    ("design", "extra", "entry", "problem"),
    [
        ("design:\n  r: {nominal: 0.3, bounds: [0.15, 0.25]}\n  l: 0.6\n", "", "design.r.nominal", "outside the bounds"),
        ("design:\n  r: {nominal: 0.2, bounds: [0.25, 0.15]}\n", "parameters:\n  l: 0.6\n", "design.r.bounds", "not below"),
        ("design:\n  r: {nominal: 0.2, bounds: 0.25}\n", "parameters:\n  l: 0.6\n", "design.r.bounds", "expected [low, high]"),
        ("design:\n  r: {nominal: 0.2}\n", "parameters:\n  l: 0.6\n", "design.r", "missing required key 'bounds'"),
        ("design:\n  r: {nominal: 0.2, bounds: [0, 1], unit: m}\n", "parameters:\n  l: 0.6\n", "design.r.unit", "unknown key"),
        (DESIGN, "parameters:\n  r: 0.3\n", "parameters.r", "already a design parameter"),
    ],
)
def test_a_malformed_design_section_names_the_entry(design, extra, entry, problem):
    with pytest.raises(ModelError) as error:
        loads(design_model(design, extra), "bad.yaml")
    assert error.value.file == "bad.yaml" and error.value.entry == entry and problem in error.value.problem


def test_design_parameters_are_geometry_only():
    text = design_model().replace("function: 0.3 + 2*pi*t + 0.5*t**2", "function: 0.3 + 2*pi*t + r*t**2")
    with pytest.raises(ModelError) as error:
        loads(text, "bad.yaml")
    assert error.value.entry == "cases.run.drivers.crank_angle.function"
    assert "uses design parameter(s) r" in error.value.problem and "geometry" in error.value.problem
    with pytest.raises(ModelError, match="'p' names the design parameters' symbols"):
        loads(design_model().replace("\n  crank:\n", "\n  p:\n").replace("[ground, crank]", "[ground, p]").replace("[crank, rod]", "[p, rod]"), "bad.yaml")


def test_the_derivation_refuses_design_parameters_with_the_way_out():
    model = loads(design_model(), "slider_crank_design.yaml")
    with pytest.raises(ModelError, match=r"does not take design parameters \(r, l\) yet: build model.at"):
        lambdify_model(model, rotations.get("quaternion"))
