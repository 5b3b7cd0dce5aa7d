"""`kinegen compare`: every parametrization of a model built and solved, one table."""

from __future__ import annotations

import json

from click.testing import CliRunner

from kinegen.cli import main
from tests.conftest import MODELS


def test_compare_tabulates_every_parametrization_of_the_four_bar():
    result = CliRunner().invoke(main, ["compare", str(MODELS / "four_bar.yaml"), "--no-compile", "--json"])
    assert result.exit_code == 0, result.output
    rows = {r["parametrization"]: r for r in json.loads(result.output)["rows"]}
    assert set(rows) == {"quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters", "euler:zxz", "euler:zxy"}
    bodies = 3
    assert rows["quaternion"]["coordinates"] == 7 * bodies and rows["quaternion"]["velocity_columns"] == 6 * bodies
    assert rows["dual-quaternion"]["coordinates"] == 8 * bodies and rows["dual-quaternion"]["velocity_columns"] == 6 * bodies
    assert rows["dual-euler-parameters"]["velocity_columns"] == 8 * bodies
    # the algebraic forms carry their normalization rows: one per body, two per body
    assert rows["euler-parameters"]["equations"] == rows["quaternion"]["equations"] + bodies
    assert rows["dual-euler-parameters"]["equations"] == rows["dual-quaternion"]["equations"] + 2 * bodies
    assert rows["euler:zxy"]["degree"] == "trigonometric" and rows["quaternion"]["degree"].isdigit()
    for name in ("quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters"):
        row = rows[name]
        assert row["failure"] is None and row["largest_step"] > 0
        low, high = row["condition"]
        assert 1.0 <= low <= high < 1e6
    # the planar four-bar's links turn about global z: zxz Euler angles are singular there
    assert rows["euler:zxz"]["failure"] is not None and "singular" in rows["euler:zxz"]["failure"].lower()


def test_compare_prints_a_table_and_where_each_parametrization_is_singular():
    result = CliRunner().invoke(main, ["compare", str(MODELS / "slider_crank.yaml"), "--no-compile", "--param", "quaternion",
                                       "--param", "dual-quaternion"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "quaternion" in result.output and "dual-quaternion: singular nowhere" in result.output
