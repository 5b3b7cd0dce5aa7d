"""ISO 6015 tool forces (kinegen forces) against a planar virtual-work formula on the excavator's
closed-form kinematics (tests/excavator_reference.py, independent of kinegen): a cylinder at
pressure p with area A turning a part about its pivot holds the tool force F = p A (dL/dphi) / R at
the lip, R the lip's distance from the pivot, dL/dphi the cylinder length's derivative by the
part's angle (central differences of the closed-form position)."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from kinegen.forces.iso6015 import tool_forces
from tests import excavator_reference as ref
from tests.conftest import generated_system, model

#: the file's tests in one test process (make test distributes with --dist loadgroup): the tool forces (found()), computed once
pytestmark = pytest.mark.xdist_group(name="iso6015")

BOOM0, ARM0 = 2.507892, 1.943212  # the digging case's start (the reference pose)
RELIEF = 34.3e6
H = 1e-6


@functools.cache
def found():
    return tool_forces(generated_system("excavator_quaternion", "digging"), model("excavator"))


def _closed_form(part: str, pivot: str, boom: float, arm: float, bucket: float, bore: float) -> float:
    """Tool force at relief of the cylinder that turns ``part`` about ``pivot``, at the lengths given."""
    lengths = {"boom": boom, "arm": arm, "bucket": bucket}

    def angle(length: float) -> float:
        return ref.planar_pins(**{**lengths, part: length})[1][part]

    dphi = (angle(lengths[part] + H) - angle(lengths[part] - H)) / (2 * H)
    pins = ref.planar_pins(boom, arm, bucket)[0]
    radius = np.linalg.norm(pins["T"] - pins[pivot])
    return RELIEF * np.pi / 4 * bore**2 / (abs(dphi) * radius)


def test_bucket_cylinder_tool_force_at_relief_equals_virtual_work():
    bucket = found()["bucket"]
    expected = [_closed_form("bucket", "Q", BOOM0, ARM0, s, 0.115) for s in bucket.stroke]
    np.testing.assert_allclose(bucket.capacities["bucket_cylinder"], expected, rtol=1e-7)
    _assert_ceiling(bucket.ceiling, bucket.ceiling_at, lambda s: _closed_form("bucket", "Q", BOOM0, ARM0, s, 0.115))


def test_arm_cylinder_tool_force_at_relief_equals_virtual_work():
    arm = found()["arm"]
    bucket = arm.inputs["bucket_length"]
    # the bucket at the longest lever about the arm pivot E, from the closed form
    lever = minimize_scalar(lambda s: -np.linalg.norm(ref.planar_pins(BOOM0, ARM0, s)[0]["T"] - ref.planar_pins(BOOM0, ARM0, s)[0]["E"]),
                            bounds=(1.6529, 2.6613), method="bounded", options={"xatol": 1e-10})  # fmt: skip
    assert bucket == pytest.approx(lever.x, abs=1e-6)
    expected = [_closed_form("arm", "E", BOOM0, s, bucket, 0.135) for s in arm.stroke]
    np.testing.assert_allclose(arm.capacities["arm_cylinder"], expected, rtol=1e-7)
    _assert_ceiling(arm.ceiling, arm.ceiling_at, lambda s: _closed_form("arm", "E", BOOM0, s, bucket, 0.135))


def _assert_ceiling(ceiling: float, at: float, closed_form) -> None:
    """The ceiling is the closed form's value where it is reached, and a maximum there."""
    assert ceiling == pytest.approx(closed_form(at), rel=1e-7)
    assert max(closed_form(at - 1e-4), closed_form(at + 1e-4)) < ceiling


def test_the_figures_are_the_largest_first_limit_and_name_it():
    """At the reported pose the figure is every cylinder's limit's minimum, the limiting circuits
    reach it, it is at most the working cylinder's ceiling, and no nearby pose of the free inputs
    does better (a local maximum of the smallest limit)."""
    from kinegen.forces.iso6015 import _Finder

    system, excavator = generated_system("excavator_quaternion", "digging"), model("excavator")
    finder = _Finder(system, excavator)
    for name, free in (("bucket", ("boom_length", "arm_length", "bucket_length")), ("arm", ("boom_length", "arm_length"))):
        r = found()[name]
        item = excavator.tool_forces.forces[name]
        u = np.array([r.inputs[d] for d in system.driver_names])
        caps, settings = finder._capacities(item, u[None])
        assert r.force == pytest.approx(min(c[0] for c in caps.values()), rel=1e-9)  # poses solved to max|Phi| <= 1e-10
        for actuator, setting, pressure, side in [(r.limiting, r.setting, r.pressure, r.side), *r.also]:
            assert caps[actuator][0] == pytest.approx(r.force, rel=1e-6)
            assert settings[actuator][0] == (actuator, setting, pressure, side)
        assert r.force <= r.ceiling * (1 + 1e-9)
        rng = np.random.default_rng(6015)
        for _ in range(12):
            moved = u.copy()
            for driver in free:
                moved[system.driver_names.index(driver)] += rng.uniform(-2e-3, 2e-3)
            caps, _ = finder._capacities(item, moved[None])
            assert min(c[0] for c in caps.values()) <= r.force * (1 + 1e-6)


def test_forces_command_prints_the_figures_and_json():
    import json

    from click.testing import CliRunner

    from kinegen.cli import main

    text = CliRunner().invoke(main, ["forces", "models/excavator.yaml", "--no-compile"])
    assert text.exit_code == 0, text.output
    assert "bucket digging force" in text.output and "published 158 kN (unverified)" in text.output
    document = json.loads(CliRunner().invoke(main, ["forces", "models/excavator.yaml", "--no-compile", "--json"]).output)
    for name in ("bucket", "arm"):
        assert document["forces"][name]["force"] == pytest.approx(found()[name].force, rel=1e-9)
        assert document["forces"][name]["limiting"]["actuator"] == found()[name].limiting
    missing = CliRunner().invoke(main, ["forces", "models/boom.yaml"])
    assert missing.exit_code == 2 and "no tool_forces section" in missing.output


TOOL_FORCES = """\
tool_forces:
  case: digging
  lip: lip
  bucket: {actuator: bucket_cylinder, driver: bucket_length, pivot: bucket.Q}
"""


@pytest.mark.parametrize(
    ("old", "new", "entry", "problem"),
    [
        ("actuator: bucket_cylinder", "actuator: boom_cylinder_right", "tool_forces.bucket.actuator", "not an actuator with hydraulic data"),
        ("driver: bucket_length", "driver: bucket_speed", "tool_forces.bucket.driver", "not a driver of case digging"),
        ("case: digging", "case: level_cut", "tool_forces.bucket.driver", "not a driver of case level_cut"),
        ("pivot: bucket.Q}", "pivot: bucket.Q, stroke: [2, 1]}", "tool_forces.bucket.stroke", "must be below"),
        ("  bucket: {actuator: bucket_cylinder, driver: bucket_length, pivot: bucket.Q}\n", "", "tool_forces", "at least one of bucket, arm"),
    ],
)
def test_malformed_tool_forces_name_the_entry(old, new, entry, problem):
    from kinegen.errors import ModelError
    from kinegen.model import loads
    from tests.conftest import MODELS

    text = (MODELS / "excavator.yaml").read_text()
    text = text[: text.index("tool_forces:")] + TOOL_FORCES.replace(old, new)
    with pytest.raises(ModelError) as caught:
        loads(text, "excavator.yaml")
    assert caught.value.entry == entry
    assert problem in caught.value.problem


def test_the_docs_forces_table_states_these_figures():
    """docs/forces.md's table (kinegen's figures, to the 0.1 kN it prints) is this run's."""
    from tests.conftest import ROOT

    text = (ROOT / "docs" / "forces.md").read_text()
    start = text.index("## In short")
    table = text[start : text.index("\n## ", start + 1)]
    for row, name in (("| bucket digging force |", "bucket"), ("| arm crowd force |", "arm")):
        line = next(text for text in table.splitlines() if text.startswith(row))
        stated = float(line.split("|")[2].strip().removesuffix(" kN"))
        assert stated == round(found()[name].force / 1e3, 1), (name, stated, found()[name].force)
