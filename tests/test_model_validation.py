"""Malformed models: every error names the file, the entry and the problem."""

from __future__ import annotations

import re
import warnings

import pytest

from kinegen import rotations
from kinegen.codegen.inmemory import lambdify_model
from kinegen.errors import AssemblyError, ModelError
from kinegen.model import ModelWarning, loads
from kinegen.runtime import check_initial_pose, from_module
from tests.conftest import OPEN_LOOP

BASE = """\
model: m
parameters: {L: 1.0}
ground:
  points: {O: [0, 0, 0]}
  vectors: {z: [0, 0, 1]}
bodies:
  arm:
    position: [L, 0, 0]
    orientation: {quaternion: [1, 0, 0, 0]}
    points: {O: [-L, 0, 0], tip: [L, 0, 0]}
    vectors: {z: [0, 0, 1]}
joints:
  pivot: {type: revolute, bodies: [ground, arm], points: [O, O], axes: [z, z]}
cases:
  spin:
    drivers:
      angle: {type: joint_angle, joint: pivot, function: t}
"""


def load_variant(old: str, new: str):
    assert old in BASE
    return loads(BASE.replace(old, new), "variant.yaml")


def test_base_model_is_valid():
    m = loads(BASE, "variant.yaml")
    assert [b.name for b in m.bodies] == ["arm"]


@pytest.mark.parametrize(
    ("old", "new", "entry", "problem"),
    [
        ("bodies: [ground, arm]", "bodies: [ground, boom]", "joints.pivot.bodies[1]", "unknown body 'boom'"),
        ("points: [O, O]", "points: [O, X]", "joints.pivot.points[1]", "unknown point 'X'"),
        ("joint: pivot", "joint: hinge", "cases.spin.drivers.angle.joint", "unknown joint 'hinge'"),
        ("position: [L, 0, 0]", "position: [L, 0]", "bodies.arm.position", "list of 3"),
        ("vectors: {z: [0, 0, 1]}\njoints", "vectors: {z: [0, 0, 0]}\njoints", "bodies.arm.vectors.z", "zero-length"),
        ("type: revolute", "type: hinge", "joints.pivot.type", "unknown joint type"),
        ("function: t", "function: __import__('os').system('echo pwned')", "cases.spin.drivers.angle.function", "not allowed"),
        ("function: t", "function: t.real", "cases.spin.drivers.angle.function", "attribute access"),
        ("{L: 1.0}", "{L: t}", "parameters.L", "time"),
        ("tip: [L, 0, 0]}", "tip: [L, 0, 0]}\n    outline: [[0, 0, 0], [1, 0, 0]]", "bodies.arm.outline", "at least 3 points"),
        ("tip: [L, 0, 0]}", "tip: [L, 0, 0]}\n    outline: [[0, 0, 0], [1, 0, 0], [1, 1]]", "bodies.arm.outline[2]", "list of 3"),
        ("vectors: {z: [0, 0, 1]}\nbodies", "vectors: {z: [0, 0, 1]}\n  outline: 3\nbodies", "ground.outline", "at least 3 points"),
        ("{L: 1.0}", "{L: .nan}", "parameters.L", "not finite"),
        ("position: [L, 0, 0]", "position: [L, 0, 0]\n    masss: 3", "bodies.arm.masss", "unknown key"),
        ("position: [L, 0, 0]", "position: [L, 0, 0]\n    mass: -3", "bodies.arm.mass", "must be positive"),
        ("position: [L, 0, 0]", "position: [L, 0, 0]\n    center_of_mass: [0.5, 0, 0]", "bodies.arm", "without 'mass'"),
        ("position: [L, 0, 0]", "position: [L, 0, 0]\n    mass: 3\n    inertia: [1, 1, 5]", "bodies.arm.inertia", "not those of a body"),
        ("position: [L, 0, 0]", "position: [L, 0, 0]\n    mass: 3\n    inertia: [1, 2]", "bodies.arm.inertia", "expected [Ixx, Iyy, Izz]"),
        ("position: [L, 0, 0]", "position: [L, 0, 0]\n    mass: 3\n    center_of_mass: X", "bodies.arm.center_of_mass", "unknown point 'X'"),
        ("position: [L, 0, 0]", "position: [L, 0, 0]\n    mass: 3\n    inertia: {principal: [1, 1, 1], axes: [[1, 0, 0], [1, 1, 0], [0, 0, 1]]}",
         "bodies.arm.inertia.axes", "not mutually perpendicular"),
        ("cases:", "gravity: [0, -9.81]\ncases:", "gravity", "list of 3"),
        ("cases:", "loads: true\ncases:", "loads", "expected a mapping, got bool"),
        ("cases:", "motors: 3\ncases:", "motors", "expected a mapping, got int"),
        ("cases:", "tool_points: [1]\ncases:", "tool_points", "expected a mapping, got list"),
        ("function: t}", "function: t, extra: 1}", "cases.spin.drivers.angle.extra", "unknown key"),
        ("function: t}", "function: t, point: arm.tip}", "cases.spin.drivers.angle.point", "not used by a joint_angle driver"),
        ("model: m", "model: 3m", "model", "not a valid name"),
        ("  arm:\n", "  pi:\n", "bodies.pi", "reserved"),
        ("{quaternion: [1, 0, 0, 0]}", "{quaternion: [0, 0, 0, 0]}", "bodies.arm.orientation.quaternion", "zero quaternion"),
        (
            "{quaternion: [1, 0, 0, 0]}",
            "{matrix: [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}",
            "bodies.arm.orientation.matrix",
            "not a rotation",
        ),
        (
            "{quaternion: [1, 0, 0, 0]}",
            "{euler: {sequence: zxq, angles: [0, 0, 0]}}",
            "bodies.arm.orientation.euler.sequence",
            "unknown sequence",
        ),
        ("axes: [z, z]}", "axes: [z, z], references: [z, z]}", "joints.pivot.references[0]", "perpendicular"),
        (
            "      angle: {type: joint_angle, joint: pivot, function: t}",
            "      angle: {type: distance, points: [ground.O, arm.O], function: 1 + t}",
            "cases.spin.drivers.angle.points",
            "coincide",
        ),
        (
            "drivers:\n      angle",
            "drivers:\n      extra: {type: coordinate, point: arm.tip, component: z, function: 0}\n      angle",
            "cases.spin.drivers",
            "over-constrained: 5 joint equations on 6 coordinates (6 per body) leave mobility 1 for 2 driver(s)",
        ),
        ("cases:", "cases: {}\nx:", "x", "unknown key"),
        ("bodies:\n  arm:", "bodies:\n  arm: 3\n  other:", "bodies.arm", "expected a mapping"),
    ],
)
def test_malformed_model_is_rejected_with_file_entry_and_problem(old, new, entry, problem):
    with pytest.raises(ModelError) as info:
        load_variant(old, new)
    error = info.value
    assert error.file == "variant.yaml"
    assert error.entry == entry, str(error)
    assert problem in error.problem, str(error)
    assert str(error).startswith(f"variant.yaml:{error.line}: {entry}: ")  # file:line: entry: problem
    last_key = re.findall(r"[A-Za-z_]\w*", entry)[-1]
    assert last_key in BASE.replace(old, new).splitlines()[error.line - 1]  # the line that holds the entry


def test_degree_of_freedom_message_reports_the_counts():
    with pytest.raises(ModelError) as info:
        load_variant("function: t}", "function: t}\n      more: {type: coordinate, point: arm.tip, component: z, function: 0}")
    assert "6 coordinates" in str(info.value) and "5 joint equations" in str(info.value) and "2 driver(s)" in str(info.value)


def test_duplicate_names_and_broken_yaml_are_rejected():
    with pytest.raises(ModelError, match="duplicate name 'pivot'"):
        load_variant("joints:\n", "joints:\n  pivot: {type: spherical, bodies: [ground, arm], at: [0, 0, 0]}\n")
    with pytest.raises(ModelError, match="invalid YAML"):
        loads("model: [unclosed", "broken.yaml")
    with pytest.raises(ModelError, match=r"\(top level\): expected a mapping"):
        loads("- just\n- a list\n", "list.yaml")


def test_non_unit_quaternion_is_normalized_with_a_warning():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = load_variant("{quaternion: [1, 0, 0, 0]}", "{quaternion: [2, 0, 0, 0]}")
    assert any(issubclass(w.category, ModelWarning) and "normalized" in str(w.message) for w in caught)
    assert m.bodies[0].rotation == m.bodies[0].rotation.__class__.eye(3)


def test_initial_pose_that_cannot_be_assembled_names_the_worst_constraints():
    """A four-bar whose links cannot close: the assembly solve fails and says where."""
    system = from_module(lambdify_model(loads(OPEN_LOOP, "open_loop.yaml"), rotations.get("quaternion")))
    with pytest.raises(AssemblyError) as info:
        check_initial_pose(system)
    assert info.value.worst[0][0] == "coupler.length"
    assert "initial pose cannot be assembled at t = 0" in str(info.value)
