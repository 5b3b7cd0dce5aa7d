"""The hydraulic lift capacity (kinegen forces --lift) against planar virtual work on the
excavator's closed-form kinematics (tests/excavator_reference.py): a weight W at the bucket pin Q
is held by the boom cylinders with the force W dz_Q/dL_boom and by the arm cylinder with
W dz_Q/dL_arm (central differences of the closed-form position); each reaches its setting
(boom: relief, arm: holding) at W = p A / |that derivative|, A the side the force needs."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from kinegen.forces.lift import HYDRAULIC_SHARE, G, lift_chart
from tests import excavator_reference as ref
from tests.conftest import generated_system, model

BUCKET0 = 1.857898  # the digging case's start
H = 1e-6
#: (bore, rod, cylinders, setting) of the lifting boom cylinders (relief) and the holding arm cylinder
BOOM, ARM = (0.120, 0.085, 2, 34.3e6), (0.135, 0.095, 1, 39.2e6)


@functools.cache
def chart():
    return lift_chart(generated_system("excavator_quaternion", "digging"), model("excavator"))


def _q(boom: float, arm: float) -> np.ndarray:
    return ref.planar_pins(boom, arm, BUCKET0)[0]["Q"]


def _limit(per_newton: float, cylinder: tuple[float, float, int, float]) -> float:
    bore, rod, count, pressure = cylinder
    area = count * np.pi / 4 * (bore**2 if per_newton >= 0 else bore**2 - rod**2)
    return pressure * area / abs(per_newton)


def _closed_form(boom: float, arm: float) -> tuple[float, str]:
    dz_boom = (_q(boom + H, arm)[1] - _q(boom - H, arm)[1]) / (2 * H)
    dz_arm = (_q(boom, arm + H)[1] - _q(boom, arm - H)[1]) / (2 * H)
    limits = {"boom_cylinder_left": _limit(dz_boom, BOOM), "arm_cylinder": _limit(dz_arm, ARM)}
    name = min(limits, key=limits.get)
    return limits[name], name


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
            assert p.rated_kg == pytest.approx(HYDRAULIC_SHARE * capacity / G, rel=1e-7)
            checked += 1
    assert checked >= 30
    assert {p.limiting for row in c.grid for p in row if p} == {"boom_cylinder_left", "arm_cylinder"}  # both limits occur


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


def test_lift_command_prints_the_table():
    import json

    from click.testing import CliRunner

    from kinegen.cli import main

    table = CliRunner().invoke(main, ["forces", "models/excavator.yaml", "--lift", "--no-compile"])
    assert table.exit_code == 0, table.output
    assert "87 % of the hydraulic lift capacity" in table.output and "tipping" in table.output
    first = chart().grid[chart().heights.index(0.0)][chart().radii.index(4.5)]
    assert f"*{first.rated_kg:,.0f}" in table.output
    document = json.loads(CliRunner().invoke(main, ["forces", "models/excavator.yaml", "--lift", "--json", "--no-compile"]).output)
    assert document["tipping"] is None and document["grid"][chart().heights.index(0.0)][chart().radii.index(4.5)]["rated_kg"] == pytest.approx(first.rated_kg)
