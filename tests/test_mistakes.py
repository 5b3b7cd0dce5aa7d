"""Issue 39, part 3: errors in the words of the mistake -- a linkage that cannot assemble says which
loop stays open and by how much, an over-constrained model says which joints' equations repeat, a
quantity typed in the wrong unit is warned about in its units; no "-0.00" in a report."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from kinegen.cli import main
from kinegen.errors import UnassembledError
from kinegen.runtime import Solver, SolverOptions, from_module, load_module
from tests.conftest import MODELS

FOUR_BAR = (MODELS / "four_bar.yaml").read_text()


@pytest.fixture(scope="module")
def short_coupler(tmp_path_factory):
    """The four-bar with a coupler of 0.3 m instead of 0.9 (ground 1.0, crank 0.3, rocker 0.7): it
    assembles at t = 0 but the crank's turn pulls B more than coupler + rocker = 1.0 m from D."""
    folder = tmp_path_factory.mktemp("short")
    path = folder / "short.yaml"
    assert "  b: 0.9 " in FOUR_BAR
    path.write_text(FOUR_BAR.replace("  b: 0.9 ", "  b: 0.3 "))
    built = CliRunner().invoke(main, ["build", str(path), "--param", "quaternion", "--out-dir", str(folder)])
    assert built.exit_code == 0, built.output
    return path, folder


def test_a_coupler_too_short_says_the_linkage_cannot_assemble_and_by_how_much(short_coupler):
    """The closed form: |BD|^2 = (1 - 0.3 cos θ)^2 + (0.3 sin θ)^2 reaches (b + c)^2 = 1 at cos θ* = 0.15;
    beyond it the loop stays open by |BD| - 1. The solve stops at the step holding θ*, the error says
    the linkage cannot assemble (before any solver vocabulary), names the loop's four joints, and its
    widest gap on the rest of the grid equals |BD| - 1 there to 1e-6 m."""
    path, folder = short_coupler
    system = from_module(load_module(folder / "four_bar_quaternion.py"))
    times = np.linspace(system.t0, system.t1, system.steps)
    with pytest.raises(UnassembledError) as caught:
        Solver(system, SolverOptions()).solve(times)
    error = caught.value

    def angle(t):
        return 0.5 + 2 * np.pi * t + 0.3 * np.sin(2 * np.pi * t)

    limit = np.arccos(0.15)
    assert angle(error.t0) <= limit <= angle(error.t1)
    assert {joint for joint, _ in error.gaps} == {"A", "B", "C", "D"}
    when, gap = error.widest
    theta = angle(when)
    assert abs(gap - (np.hypot(1 - 0.3 * np.cos(theta), 0.3 * np.sin(theta)) - 1.0)) < 1e-6
    assert str(error).startswith(f"the linkage cannot assemble at t = {error.t1:.6g} s: with crank_angle = ")
    assert str(error).index("loop through joints") < str(error).index("continuation")  # the mechanism first, the solver after
    done = CliRunner().invoke(main, ["solve", str(path), "--generated-dir", str(folder)])
    assert done.exit_code == 3 and done.output.startswith("error: the linkage cannot assemble at t = "), done.output


@pytest.mark.parametrize(
    ("old", "new", "joints", "repeated"),
    [  # a spherical joint written twice repeats its 3 equations; a planar loop of 4 revolutes repeats 3 (20 - 3 = 17 = 18 - 1)
        ("  D: {type: revolute, bodies: [ground, rocker], points: [D, D], axes: [z, z]}",
         "  D: {type: revolute, bodies: [ground, rocker], points: [D, D], axes: [z, z]}\n"
         "  D2: {type: spherical, bodies: [ground, rocker], points: [D, D]}", "D, D2", 3),
        ("  B: {type: spherical, bodies: [crank, coupler], points: [B, B]}\n  C: {type: universal, bodies: [coupler, rocker], points: [C, C], axes: [n, z]}",
         "  B: {type: revolute, bodies: [crank, coupler], points: [B, B], axes: [z, z]}\n"
         "  C: {type: revolute, bodies: [coupler, rocker], points: [C, C], axes: [z, z]}", "A, B, C, D", 3),
    ],
)  # fmt: skip
def test_an_over_constrained_model_names_the_joints_whose_equations_repeat(tmp_path, old, new, joints, repeated):
    """Instead of a negative mobility: the model is over-constrained, which joints' equations
    depend on each other (the rank of their rows at the initial pose), and that the independent
    ones leave the one degree of freedom the crank drives -- so `redundant: true` would do."""
    from kinegen.api import Session
    from kinegen.errors import ModelError, OverConstrainedError
    from kinegen.model import load

    assert old in FOUR_BAR
    text = FOUR_BAR.replace(old, new).replace("vectors: {n: [0, 1, 0]}", "vectors: {n: [0, 1, 0], z: [0, 0, 1]}")  # the coupler's z axis
    path = tmp_path / "over.yaml"
    path.write_text(text)
    with pytest.raises(OverConstrainedError) as counted:
        load(path)  # the loader counts; the rank is the symbolic layer's (kinegen.symbolic.rank.explain)
    assert counted.value.problem.startswith("over-constrained: 20 joint equations on 18 coordinates (6 per body) leave mobility -2 for 1 driver(s)")
    with pytest.raises(ModelError) as caught:
        Session(str(tmp_path / "gen")).model(path)
    problem = caught.value.problem
    assert caught.value.entry == "cases.crank_turn.drivers"
    done = CliRunner().invoke(main, ["info", str(path)])
    assert done.exit_code == 2 and done.output.strip() == f"error: {caught.value}", done.output
    assert problem.startswith(f"over-constrained: joints {joints} repeat {repeated} of their equations (rank of Phi_q at the initial pose: "
                              f"{20 - repeated} of 20)"), problem  # fmt: skip
    assert "leave 1 degree(s) of freedom for the 1 driver(s)" in problem and "redundant: true" in problem


CRANE = """\
model: crane
ground:
  points: {O: [0, 0, 0], B: [0.6, 0, -0.8]}
  vectors: {y: [0, 1, 0]}
bodies:
  boom:
    position: [0, 0, 0]
    mass: 300
    center_of_mass: [2, 0, 0]
    inertia: [5, 400, 400]
    points: {O: [0, 0, 0], C: [1.5, 0, 0], tip: [4, 0, 0]}
    vectors: {y: [0, 1, 0]}
joints:
  pivot: {type: revolute, bodies: [ground, boom], points: [O, O], axes: [y, y]}
actuators:
  lift: {points: [ground.B, boom.C], range: [0.5, 3.0], hydraulics: {bore: BORE, rod: ROD, relief: 25e6}}
loads:
  hook: {point: boom.tip, force: [0, 0, -5000]}
cases:
  raise:
    drivers:
      angle: {type: joint_angle, joint: pivot, function: -0.2 - 0.5*t}
    t0: 0
    t1: 1
    steps: 11
"""


def test_a_bore_typed_in_millimetres_is_warned_about_in_its_units(tmp_path):
    """A bore of 100 and a rod of 60 (millimetres typed as metres) are accepted, but each gets a
    warning line naming the file, the line, the entry and the usual range in m with the value it
    likely meant; the report shows the tiny pressure in kPa, never "0.0 MPa", and no "-0.00"."""
    path = tmp_path / "crane.yaml"
    path.write_text(CRANE.replace("BORE", "100").replace("ROD", "60"))
    done = CliRunner().invoke(main, ["solve", str(path), "--load", "hook", "--generated-dir", str(tmp_path / "gen"), "--no-compile"])
    assert done.exit_code == 0, done.output
    warned = [line for line in done.output.splitlines() if line.startswith("warning:")]
    assert any(f"{path}:16: actuators.lift.hydraulics.bore: 100 m is outside the usual 0.01 .. 1 m" in w and "100 mm is 0.1" in w
               for w in warned), warned  # fmt: skip
    assert any("actuators.lift.hydraulics.rod: 60 m" in w for w in warned), warned
    report = next(line for line in done.output.splitlines() if line.strip().startswith("lift "))
    assert "kPa" in report and "0.0 MPa" not in done.output and "-0.00" not in done.output, report
    sane = tmp_path / "sane.yaml"
    sane.write_text(CRANE.replace("BORE", "0.1").replace("ROD", "0.06"))
    fine = CliRunner().invoke(main, ["solve", str(sane), "--load", "hook", "--generated-dir", str(tmp_path / "gen"), "--no-compile"])
    assert fine.exit_code == 0 and "warning" not in fine.output and " MPa (cap side)" in fine.output, fine.output
