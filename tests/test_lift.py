"""The ISO 10567 lift chart (kinegen lift) against planar virtual work on the excavator's
closed-form kinematics (tests/excavator_reference.py): a weight W at the bucket pin Q and the
front's own weights m_i g at their centres of mass C_i (the bucket removed) are held by the boom
cylinders with the force W dz_Q/dL_boom + sum m_i g dz_Ci/dL_boom and by the arm cylinder likewise
(central differences of the closed-form positions); each reaches its setting (boom: relief, arm:
holding) at the W that leaves p A - that carried force, A the side the force needs. The tipping
loads against the lever rule about each tipping line, from the centres of mass found here."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from kinegen.forces.lift import HYDRAULIC_SHARE, TIPPING_SHARE, G, lift_chart
from tests import excavator_reference as ref
from tests.conftest import generated_system, model, nominal_inertia

#: the file's tests in one test process (make test distributes with --dist loadgroup): the lift chart (chart()), computed once
pytestmark = pytest.mark.xdist_group(name="lift")

BUCKET0 = 1.857898  # the digging case's start
H = 1e-6
#: (bore, rod, cylinders, setting) of the lifting boom cylinders (relief) and the holding arm cylinder
BOOM, ARM = (0.120, 0.085, 2, 34.3e6), (0.135, 0.095, 1, 39.2e6)


@functools.cache
def chart():
    return lift_chart(generated_system("excavator_quaternion", "digging"), model("excavator"))


def _q(boom: float, arm: float) -> np.ndarray:
    return ref.planar_pins(boom, arm, BUCKET0)[0]["Q"]


def _masses() -> dict[str, tuple[float, np.ndarray]]:
    """Each moving body's mass and centre of mass (x, z) in its body coordinates, from the model file."""
    return {b.name: (nominal_inertia("excavator", b)[0], nominal_inertia("excavator", b)[1][[0, 2]]) for b in model("excavator").massive}


def _centers(boom: float, arm: float) -> dict[str, np.ndarray]:
    """Every body's centre of mass (x, z) at the pose, by the closed form: a part's from its pivot and
    angle, a cylinder's barrel from its base and rod from its eye along the base-eye line."""
    pins, angles = ref.planar_pins(boom, arm, BUCKET0)
    masses = _masses()

    def on(part: str, pivot: str) -> np.ndarray:
        return pins[pivot] + ref.rot(angles[part]) @ masses[part][1]

    out = {"boom": on("boom", "A"), "arm": on("arm", "E"), "side_link": on("side_link", "H"), "bucket_link": on("bucket_link", "K"),
           "bucket": on("bucket", "Q"), "upper": masses["upper"][1]}  # fmt: skip
    for prefix, base, eye in (("boom_cyl_l", "B", "C"), ("boom_cyl_r", "B", "C"), ("arm_cyl", "D", "F"), ("bucket_cyl", "G", "J")):
        e = (pins[eye] - pins[base]) / np.linalg.norm(pins[eye] - pins[base])
        out[f"{prefix}_barrel"] = pins[base] + masses[f"{prefix}_barrel"][1][0] * e
        out[f"{prefix}_rod"] = pins[eye] + masses[f"{prefix}_rod"][1][0] * e
    return out


def _carried(boom: float, arm: float, which: str) -> float:
    """The force [N] the boom (``which`` = "boom") or arm cylinder carries from the front's weight, the
    bucket removed: sum m_i g dz_Ci/dL."""
    masses = _masses()
    step = {"boom": (H, 0.0), "arm": (0.0, H)}[which]
    up, down = _centers(boom + step[0], arm + step[1]), _centers(boom - step[0], arm - step[1])
    return sum(masses[n][0] * G * (up[n][1] - down[n][1]) / (2 * H) for n in masses if n != "bucket")


def _limit(per_newton: float, cylinder: tuple[float, float, int, float], carried: float) -> float:
    bore, rod, count, pressure = cylinder
    area = count * np.pi / 4 * (bore**2 if per_newton >= 0 else bore**2 - rod**2)
    return max(pressure * area - np.sign(per_newton or 1.0) * carried, 0.0) / abs(per_newton)


def _closed_form(boom: float, arm: float) -> tuple[float, str]:
    dz_boom = (_q(boom + H, arm)[1] - _q(boom - H, arm)[1]) / (2 * H)
    dz_arm = (_q(boom, arm + H)[1] - _q(boom, arm - H)[1]) / (2 * H)
    limits = {"boom_cylinder_left": _limit(dz_boom, BOOM, _carried(boom, arm, "boom")),
              "arm_cylinder": _limit(dz_arm, ARM, _carried(boom, arm, "arm"))}  # fmt: skip
    name = min(limits, key=limits.get)
    return limits[name], name


def _tipping(boom: float, arm: float, radius: float) -> tuple[float, float]:
    """The lever rule about each tipping line (over the front: half the tumbler distance 3.37 m; over
    the side: half the gauge 2.2 m): the load W with W (r - d) = sum m_i (d - x_i) + m_u (d - x_u), the
    undercarriage (7,300 kg) on the swing axis."""
    masses, centers = _masses(), _centers(boom, arm)
    out = []
    for line in (3.37 / 2, 2.2 / 2):
        restoring = sum(m * (line - centers[n][0]) for n, (m, _) in masses.items() if n != "bucket") + 7300 * line
        out.append(restoring / (radius - line))
    return out[0], out[1]


def test_every_grid_point_is_where_it_says_and_holds_the_closed_forms_load():
    c = chart()
    checked = 0
    for row in (*c.grid, c.max_reach):
        for p in row:
            if p is None:
                continue
            boom, arm = p.inputs["boom_length"], p.inputs["arm_length"]
            np.testing.assert_allclose(_q(boom, arm), [p.radius, p.height], atol=1e-6)  # the closed form puts Q there too
            capacity, limiting = _closed_form(boom, arm)
            assert p.capacity == pytest.approx(capacity, rel=1e-7)
            assert p.limiting == limiting and p.setting == ("relief" if limiting == "boom_cylinder_left" else "holding")
            assert p.hydraulic_kg == pytest.approx(HYDRAULIC_SHARE * capacity / G, rel=1e-7)
            front, side = _tipping(boom, arm, p.radius)
            assert (p.tipping_front, p.tipping_side) == (pytest.approx(front, rel=1e-7), pytest.approx(side, rel=1e-7))
            for over_side, tipping in ((False, front), (True, side)):
                rated, limit = p.rated(over_side)
                assert rated == pytest.approx(min(TIPPING_SHARE * tipping, HYDRAULIC_SHARE * capacity / G), rel=1e-7)
                assert limit == ("tipping" if TIPPING_SHARE * tipping < HYDRAULIC_SHARE * capacity / G else "hydraulic")
            checked += 1
    assert checked >= 30
    assert {p.limiting for row in c.grid for p in row if p} == {"boom_cylinder_left", "arm_cylinder"}  # both limits occur
    limits = {p.rated(side)[1] for row in c.grid for p in row if p for side in (False, True)}
    assert limits == {"hydraulic", "tipping"}  # both halves of the chart rule somewhere


def test_max_reach_is_the_farthest_point_at_its_height():
    """At the reported largest radius no pose of the two cylinders within their ranges puts Q
    farther out at that height (closed form, a dense scan of the boom length with the arm solved)."""
    from scipy.optimize import brentq

    for p in chart().max_reach:
        if p is None:
            continue
        best = -np.inf
        booms, arms = np.linspace(1.7352, 3.0649, 90), np.linspace(1.8164, 3.2939, 40)
        for boom in booms:  # inside and on the boom's ends: the arm that puts Q at the height
            z = np.array([_q(boom, a)[1] for a in arms]) - p.height
            for k in np.flatnonzero(np.sign(z[:-1]) != np.sign(z[1:])):
                arm = brentq(lambda a, boom=boom, h=p.height: _q(boom, a)[1] - h, arms[k], arms[k + 1], xtol=1e-12)
                best = max(best, _q(boom, arm)[0])
        for arm in arms[[0, -1]]:  # on the arm's ends: the boom that puts Q at the height
            z = np.array([_q(b, arm)[1] for b in booms]) - p.height
            for k in np.flatnonzero(np.sign(z[:-1]) != np.sign(z[1:])):
                boom = brentq(lambda b, arm=arm, h=p.height: _q(b, arm)[1] - h, booms[k], booms[k + 1], xtol=1e-12)
                best = max(best, _q(boom, arm)[0])
        assert best <= p.radius + 1e-6
        assert best >= p.radius - 1e-3  # the scan's resolution


def test_lift_command_prints_the_table_json_and_csv(tmp_path):
    import json

    from click.testing import CliRunner

    from kinegen.cli import main

    out = tmp_path / "lift.csv"
    table = CliRunner().invoke(main, ["lift", "models/excavator.yaml", "--no-compile", "--out", str(out)])
    assert table.exit_code == 0, table.output
    assert "the smaller of 87 % of the hydraulic lift capacity and 75 % of the tipping load" in table.output
    first = chart().grid[chart().heights.index(0.0)][chart().radii.index(4.5)]
    front, side = first.rated(False), first.rated(True)
    assert f"{'*' if front[1] == 'hydraulic' else ''}{front[0]:,.0f}" in table.output
    assert f"{'*' if side[1] == 'hydraulic' else ''}{side[0]:,.0f}" in table.output
    assert CliRunner().invoke(main, ["forces", "models/excavator.yaml", "--lift", "--no-compile"]).output.startswith(table.output.splitlines()[0])
    document = json.loads(CliRunner().invoke(main, ["lift", "models/excavator.yaml", "--json", "--no-compile"]).output)
    cell = document["grid"][chart().heights.index(0.0)][chart().radii.index(4.5)]
    assert document["tipping"] is True and cell["rated_front_kg"] == pytest.approx(front[0]) and cell["side_limit"] == side[1]
    header, *rows = out.read_text().splitlines()
    assert header.startswith("height_m,radius_m,at_max_reach") and len(rows) == sum(
        1 for row in (*chart().grid, chart().max_reach) for p in row if p is not None)


def test_a_rigid_block_tips_by_the_lever_rule():
    """A block of mass M with its centre on the swing axis and an arm of mass m whose centre is at x_m,
    on tracks of tumbler distance L and gauge g: the load at radius r that tips it is
    (M d + m (d - x_m)) / (r - d), d = L/2 over the front and g/2 over the side; none inside the line."""
    import dataclasses

    import sympy as sp

    from kinegen.forces.lift import tipping_loads
    from kinegen.forces.statics import Statics, pose_results
    from kinegen.model.schema import Machine

    excavator = model("excavator")
    system = generated_system("excavator_quaternion", "digging")
    statics = Statics(pose_results(system, system.initial_q[None], system.driver_inputs(system.t0)[0][None]), excavator)
    arm = next(b for b in excavator.massive if b.name == "arm")
    x_arm = statics.position("arm", np.array([float(x) for x in arm.inertia.center]))[0, 0]
    block = dataclasses.replace(excavator, machine=Machine(sp.Integer(9000), sp.ImmutableMatrix([0, 0, 1]), sp.Rational(4), sp.Rational(2), sp.Rational(1, 2)))
    for radius in (5.0, 8.0):
        front, side = tipping_loads(block, statics, [arm], radius)
        assert front == pytest.approx((9000 * 2.0 + 700 * (2.0 - x_arm)) / (radius - 2.0), rel=1e-12)
        assert side == pytest.approx((9000 * 1.0 + 700 * (1.0 - x_arm)) / (radius - 1.0), rel=1e-12)
    assert tipping_loads(block, statics, [arm], 1.5)[0] == np.inf  # inside the front line: no tipping over it
