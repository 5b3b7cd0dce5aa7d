"""The exact working-range boundary and its chart, against closed forms.

References: the excavator's planar closed form (law of cosines, tests/excavator_reference.py) for
the boundary's points and the sampled reachable set; a planar two-link arm whose working range is
bounded by circular arcs known in closed form."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from kinegen.analysis.boundary import working_range_boundary
from kinegen.analysis.envelope import FrontSwing
from kinegen.cli import main
from kinegen.codegen.inmemory import lambdify_model
from kinegen.errors import ExitCode
from kinegen.model import loads
from kinegen.rotations import get
from kinegen.runtime import from_module
from tests.conftest import WORKING_RANGE_GROUP, excavator_working_range
from tests.excavator_reference import planar_pins
from tests.test_envelope import RANGES, closed_form_optimum

#: the figures that lie on the boundary by definition (a largest reach or height of the tip)
ON_BOUNDARY = ("max_reach", "max_reach_at_ground", "max_depth", "max_cutting_height")


@pytest.fixture
def excavator():
    return excavator_working_range()


def _chart(pins: dict, name: str) -> tuple[float, float]:
    return float(pins[name][0]), float(pins[name][1])


@WORKING_RANGE_GROUP
def test_every_printed_figure_is_on_or_inside_the_drawn_boundary(excavator):
    _, system, envelope, boundary = excavator
    from kinegen.analysis.chart import figure_marks

    marks = {m.figure: m for m in figure_marks(envelope, system, boundary.direction)}
    for name in ON_BOUNDARY:
        mark = marks[name]
        assert boundary.on_boundary(mark.reach, mark.height) < 1e-3, name  # the 1 mm
    # the boundary's own extremes are the figures (to the chord error)
    points = boundary.points
    assert abs(points[:, 0].max() - envelope.figures["max_reach"]) < 1e-4
    assert abs(points[:, 1].max() - envelope.figures["max_cutting_height"]) < 1e-4
    assert abs(-points[:, 1].min() - envelope.figures["max_depth"]) < 1e-4
    a, b = points[:-1], points[1:]
    crossing = (a[:, 1] <= 0) != (b[:, 1] <= 0)
    at_ground = a[crossing, 0] + (b[crossing, 0] - a[crossing, 0]) * (-a[crossing, 1]) / (b[crossing, 1] - a[crossing, 1])
    assert abs(at_ground.max() - envelope.figures["max_reach_at_ground"]) < 1e-4
    # dumping height and vertical-wall depth are constrained maxima: inside the range, not on its edge
    for name in ("max_dumping_height", "max_vertical_wall_depth"):
        mark = marks[name]
        assert boundary.contains(np.array([mark.reach]), np.array([mark.height]))[0] < 1e-3, name
    assert boundary.chord_error < 1e-4


@WORKING_RANGE_GROUP
def test_boundary_points_are_exact_solutions_of_the_planar_closed_form(excavator):
    _, _, _, boundary = excavator
    rng = np.random.default_rng(3)
    for k in rng.choice(len(boundary.points) - 1, 60, replace=False):
        pins, _ = planar_pins(*boundary.inputs[k])
        assert np.allclose(boundary.points[k], _chart(pins, "T"), atol=1e-9, rtol=0), k
    assert boundary.refined >= 1 and boundary.unrefined == 0
    for k in boundary.switching:  # a switching point is an exact point of the curve that follows it
        pins, _ = planar_pins(*boundary.inputs[k])
        assert np.allclose(boundary.points[k], _chart(pins, "T"), atol=1e-9, rtol=0)
        assert np.all(boundary.inputs[k] >= RANGES[:, 0] - 1e-12) and np.all(boundary.inputs[k] <= RANGES[:, 1] + 1e-12)


@WORKING_RANGE_GROUP
def test_every_reachable_tip_lies_inside_the_boundary_and_the_boundary_is_tight(excavator):
    _, _, _, boundary = excavator
    rng = np.random.default_rng(5)
    inputs = RANGES[:, 0] + rng.uniform(0, 1, (4000, 3)) * (RANGES[:, 1] - RANGES[:, 0])
    # corners and edges of the box too: where the boundary is made
    inputs[:800, 0] = RANGES[0, rng.integers(0, 2, 800)]
    inputs[:400, 1] = RANGES[1, rng.integers(0, 2, 400)]
    tips = np.array([_chart(planar_pins(*u)[0], "T") for u in inputs])
    signed = boundary.contains(tips[:, 0], tips[:, 1])
    assert signed.max() < boundary.chord_error + 1e-9  # none outside (beyond the chord error: the polyline cuts convex arcs)
    # tight: every boundary point is reachable, its inputs inside the box (and the closed form's tip there:
    # test_boundary_points_are_exact_solutions_of_the_planar_closed_form)
    assert np.all(boundary.inputs >= RANGES[:, 0] - 1e-12) and np.all(boundary.inputs <= RANGES[:, 1] + 1e-12)


@WORKING_RANGE_GROUP
def test_new_figures_match_the_closed_form(excavator):
    _, _, envelope, _ = excavator
    depth = -closed_form_optimum(lambda p: p["T"][1], lambda p: p["E"][0] - p["Q"][0])
    assert abs(envelope.figures["max_vertical_wall_depth"] - depth) < 1e-6
    front = envelope.front
    assert isinstance(front, FrontSwing)
    # the minimum over the box of the largest pin radius (pins in the boom plane; the boom cylinders'
    # eyes C are 0.32 m beside it): brute force on a grid, then SLSQP from the best node
    lateral = {"C": 0.32}
    front_pins = ("C", "D", "E", "F", "G", "H", "J", "K", "Q", "T")

    def radius(x):
        pins, _ = planar_pins(*(RANGES[:, 0] + np.clip(x, 0, 1) * (RANGES[:, 1] - RANGES[:, 0])))
        return max(np.hypot(pins[n][0], lateral.get(n, 0.0)) for n in front_pins)

    grid = np.stack(np.meshgrid(*[np.linspace(0, 1, 9)] * 3, indexing="ij"), -1).reshape(-1, 3)
    best = min(grid, key=radius)
    from scipy.optimize import minimize

    refined = minimize(radius, best, method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 4000})
    assert front.radius <= radius(best) + 1e-9
    assert abs(front.radius - min(refined.fun, radius(best))) < 1e-6


TWO_LINK = """
model: two_link
description: planar two-link arm in the x-z plane (links 2.0 and 1.2 m), shoulder and elbow angles driven
ground:
  points: {O: [0, 0, 0]}
  vectors: {y: [0, 1, 0]}
bodies:
  upper_link:
    position: [0, 0, 0]
    points: {O: [0, 0, 0], E: [2.0, 0, 0]}
    vectors: {y: [0, 1, 0]}
  lower_link:
    position: [2.0, 0, 0]
    points: {E: [0, 0, 0], T: [1.2, 0, 0]}
    vectors: {y: [0, 1, 0]}
joints:
  shoulder: {type: revolute, bodies: [ground, upper_link], points: [O, O], axes: [y, y]}
  elbow: {type: revolute, bodies: [upper_link, lower_link], points: [E, E], axes: [y, y]}
cases:
  move:
    drivers:
      shoulder_angle: {type: joint_angle, joint: shoulder, function: 0.3*t}
      elbow_angle: {type: joint_angle, joint: elbow, function: 0.2*t}
    t0: 0
    t1: 1
    steps: 11
working_range:
  case: move
  point: lower_link.T
  inputs:
    shoulder_angle: [-0.9, 0.7]
    elbow_angle: [-1.0, 1.8]
"""


def test_two_link_boundary_is_made_of_its_closed_form_arcs():
    spec_model = loads(TWO_LINK, "two_link.yaml")
    system = from_module(lambdify_model(spec_model, get("quaternion")))
    boundary = working_range_boundary(system, spec_model.working_range)
    l1, l2 = 2.0, 1.2
    shoulder, elbow = (-0.9, 0.7), (-1.0, 1.8)
    # the arcs: about the shoulder with the elbow at a limit or straight (the fold, elbow = 0); about
    # the elbow with the shoulder at a limit (the elbow at (l1 cos a, +-l1 sin a): the sign convention of
    # a joint angle is the model's, both are candidates)
    radii = [l1 + l2, *(np.hypot(l1 + l2 * np.cos(b), l2 * np.sin(b)) for b in elbow)]
    elbows = [np.array([l1 * np.cos(a), s * l1 * np.sin(a)]) for a in shoulder for s in (1, -1)]
    points = boundary.points[:-1]
    on_shoulder_arc = np.min([np.abs(np.linalg.norm(points, axis=1) - r) for r in radii], axis=0)
    on_elbow_arc = np.min([np.abs(np.linalg.norm(points - e, axis=1) - l2) for e in elbows], axis=0)
    assert np.all(np.minimum(on_shoulder_arc, on_elbow_arc) < 1e-9)
    assert abs(np.linalg.norm(points, axis=1).max() - (l1 + l2)) < 1e-9  # the fold (arm straight) is on it
    assert any(c.kind == "fold" for c in (boundary.curves[i] for i in set(boundary.curve.tolist())))
    # every reachable tip is inside
    rng = np.random.default_rng(2)
    a = rng.uniform(*shoulder, 3000)
    b = rng.uniform(*elbow, 3000)
    for sign in (1, -1):  # the candidate conventions: one of them is the model's
        tips = np.column_stack([l1 * np.cos(a) + l2 * np.cos(a + b), sign * (l1 * np.sin(a) + l2 * np.sin(a + b))])
        if boundary.contains(tips[:, 0], tips[:, 1]).max() < boundary.chord_error + 1e-9:  # the polyline cuts convex arcs by up to that
            break
    else:
        pytest.fail("sampled tips outside the boundary under both sign conventions")
    # the enclosed area against the closed form: the elbow sweeps an annulus sector per shoulder angle
    # (area of the reachable set = integral over the shoulder of the elbow's sector, without overlap here)
    x, z = points[:, 0], points[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1)))
    samples = rng.uniform(0, 1, (200000, 2))
    box = np.array([points.min(axis=0), points.max(axis=0)])
    cloud = box[0] + samples * (box[1] - box[0])
    from shapely import Polygon, contains_xy

    inside = contains_xy(Polygon(points), cloud[:, 0], cloud[:, 1]).mean() * np.prod(box[1] - box[0])
    assert abs(area - inside) < 0.02 * area


def test_envelope_cli_writes_the_boundary_as_csv_and_json_and_the_chart(tmp_path):
    runner = CliRunner()
    csv_file, png = tmp_path / "b.csv", tmp_path / "chart.png"
    result = runner.invoke(main, ["envelope", "models/excavator.yaml", "--json", "--boundary", str(csv_file), "--plot", str(png)])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert document["min_front_swing_radius"]["farthest"] and document["boundary"]["chord_error_m"] < 1e-4
    lines = csv_file.read_text().splitlines()
    assert lines[0].startswith("reach_m,height_m,curve,kind,switching,boom_length,arm_length,bucket_length")
    assert len(document["boundary"]["points"]) == len(lines) - 1
    for line in lines[1::400]:  # each row's point is the closed form's at its inputs
        row = line.split(",")
        pins, _ = planar_pins(*map(float, row[-3:]))
        assert np.allclose([float(row[0]), float(row[1])], _chart(pins, "T"), atol=1e-9)
    assert png.stat().st_size > 20000
    bad = runner.invoke(main, ["envelope", "models/excavator.yaml", "--boundary", str(tmp_path / "b.txt")])
    assert bad.exit_code == ExitCode.USAGE and "--boundary" in bad.output


@pytest.mark.parametrize(
    ("old", "new", "entry", "problem"),
    [
        ("    elbow_angle: [-1.0, 1.8]\n", "    elbow_angle: [-1.0, 1.8]\n  arm_pivot: upper_link.E\n", "working_range.arm_pivot", "needs dump_pivot"),
        ("    elbow_angle: [-1.0, 1.8]\n", "    elbow_angle: [-1.0, 1.8]\n  transport: {shoulder_angle: 0.1, elbow_angle: 2.5}\n",
         "working_range.transport.elbow_angle", "outside the input's range"),
        ("    elbow_angle: [-1.0, 1.8]\n", "    elbow_angle: [-1.0, 1.8]\n  transport: {shoulder_angle: 0.1}\n", "working_range.transport", "missing required key 'elbow_angle'"),
    ],
)  # fmt: skip
def test_working_range_pivots_and_transport_are_checked(old, new, entry, problem):
    from kinegen.errors import ModelError

    with pytest.raises(ModelError) as info:
        loads(TWO_LINK.replace(old, new), "two_link.yaml")
    assert entry in str(info.value) and problem in str(info.value) and "two_link.yaml" in str(info.value)
