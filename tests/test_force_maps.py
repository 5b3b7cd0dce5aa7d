"""Force maps (kinegen forces --map) against planar virtual work on the excavator's closed-form
kinematics (tests/excavator_reference.py): the tool exerting F along d at the tip T makes each
cylinder push F d.dT/dL_i (central differences of the closed-form position, the other two lengths
held), and F is the smallest load at which one reaches its relief setting."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from kinegen.forces.maps import force_map
from tests import excavator_reference as ref
from tests.conftest import generated_system, model

H = 1e-6
#: bore, rod, cylinders of the boom, arm and bucket cylinders; every one at the relief setting
CYLINDERS = {"boom_cylinder_left": (0.120, 0.085, 2), "arm_cylinder": (0.135, 0.095, 1), "bucket_cylinder": (0.115, 0.080, 1)}
RELIEF = 34.3e6


@functools.cache
def mapped(direction: str):
    return force_map(generated_system("excavator_quaternion", "digging"), model("excavator"), direction, grid=(9, 7, 9))


def _tip(lengths: np.ndarray) -> np.ndarray:
    return ref.planar_pins(*lengths)[0]["T"]


def _closed_form(lengths: np.ndarray, direction: str) -> tuple[float, str]:
    derivatives = [(_tip(lengths + H * e) - _tip(lengths - H * e)) / (2 * H) for e in np.eye(3)]  # dT/dL_i, (x, z)
    d = {"pull": np.array([-1.0, 0.0]), "up": np.array([0.0, 1.0])}.get(direction)
    if d is None:  # tangent: along the tip's motion as the bucket cylinder extends
        d = derivatives[2] / np.linalg.norm(derivatives[2])
    limits = {}
    for (name, (bore, rod, count)), dt in zip(CYLINDERS.items(), derivatives):
        per_newton = float(d @ dt)
        area = count * np.pi / 4 * (bore**2 if per_newton >= 0 else bore**2 - rod**2)
        limits[name] = np.inf if per_newton == 0 else RELIEF * area / abs(per_newton)
    name = min(limits, key=limits.get)
    return limits[name], name


@pytest.mark.parametrize("direction", ["pull", "up", "tangent"])
def test_the_map_equals_virtual_work_on_the_closed_form(direction):
    found = mapped(direction)
    names = found.names
    assert len(found.force) == 9 * 7 * 9  # every pose of the grid solved
    rng = np.random.default_rng(28)
    for k in rng.choice(len(found.force), 40, replace=False):
        lengths = np.array([found.inputs[k, names.index(n)] for n in ("boom_length", "arm_length", "bucket_length")])
        np.testing.assert_allclose(_tip(lengths), found.points[k, [0, 2]], atol=1e-8)
        force, limiting = _closed_form(lengths, direction)
        assert found.force[k] == pytest.approx(force, rel=1e-6)
        assert found.limiting[k] == limiting


def test_cells_hold_the_largest_force_of_their_poses():
    found = mapped("pull")
    xs, zs, best, limiting = found.cells(size=0.5)
    ix = np.searchsorted(xs + 0.25, found.points[:, 0])
    iz = np.searchsorted(zs + 0.25, found.points[:, 2])
    for i, j in set(zip(iz.tolist(), ix.tolist())):
        inside = (iz == i) & (ix == j)
        assert best[i, j] == found.force[inside].max()
        assert limiting[i, j] == found.limiting[inside][np.argmax(found.force[inside])]
    assert np.isnan(best).sum() == best.size - len(set(zip(iz.tolist(), ix.tolist())))


def test_map_command_writes_the_poses(tmp_path):
    import csv

    from click.testing import CliRunner

    from kinegen.cli import main

    out = tmp_path / "pull.csv"
    run = CliRunner().invoke(main, ["forces", "models/excavator.yaml", "--map", "pull", "--no-compile", "--out", str(out)])
    assert run.exit_code == 0, run.output
    assert "poses in" in run.output and "limited by:" in run.output
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 25 * 17 * 25
    assert {r["limiting"] for r in rows} <= set(CYLINDERS)
    stray = CliRunner().invoke(main, ["forces", "models/excavator.yaml", "--out", str(out)])
    assert stray.exit_code == 64 and "go with --map" in stray.output
