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

#: the file's tests in one test process (make test distributes with --dist loadgroup): the force maps (mapped(), reached()), computed once
pytestmark = pytest.mark.xdist_group(name="force_maps")

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


@functools.cache
def reached():
    from kinegen.forces.maps import reach_map

    return reach_map(generated_system("excavator_quaternion", "digging"), model("excavator"))


#: the boom, arm and bucket cylinders' length ranges (models/excavator.yaml)
RANGES = [(1.7352, 3.0649), (1.8164, 3.2939), (1.6529, 2.6613)]
#: the boom and arm lengths of the brute force's coarse start (25 x 25 over their ranges)
COARSE = [(b, a) for b in np.linspace(*RANGES[0], 25) for a in np.linspace(*RANGES[1], 25)]


def _tip_or_far(lengths) -> np.ndarray:
    """The closed-form tip (x, z), or far from any target where the loop cannot close."""
    try:
        return _tip(np.asarray(lengths, dtype=float))
    except ValueError:
        return np.array([1e3, 1e3])


@functools.cache
def _coarse_tips(bucket: float) -> np.ndarray:
    """The closed-form tip (x, z) at every coarse (boom, arm) start with this bucket length, (625, 2)
    (far away where the loop cannot close): the same for every target, so computed once per length."""
    return np.array([_tip_or_far([boom, arm, bucket]) for boom, arm in COARSE])


def _largest_over_the_attitude(target: np.ndarray) -> tuple[float, set[str]]:
    """By brute force on the closed form: the bucket cylinder's length swept over its range (61
    values, then Brent's method about the best), at each the boom and arm lengths that put the tip
    on ``target`` (x, z) solved from the closed-form position, and the tangent force of
    :func:`_closed_form`; the largest, and the cylinders that limit it (two where it sits at the
    length at which the limit passes from one to the other)."""
    from scipy.optimize import fsolve, minimize_scalar

    ranges, tip = RANGES, _tip_or_far

    def placed(bucket: float, guess) -> np.ndarray | None:
        x, _, ok, _ = fsolve(lambda v: tip([v[0], v[1], bucket]) - target, guess, full_output=True, xtol=1e-13)
        inside = all(lo - 1e-9 <= v <= hi + 1e-9 for v, (lo, hi) in zip(x, ranges[:2]))
        return x if ok == 1 and inside and np.abs(tip([*x, bucket]) - target).max() < 1e-9 else None

    found: list[tuple[float, float, str, np.ndarray]] = []
    guess = None
    for bucket in np.linspace(*ranges[2], 61):
        start = guess if guess is not None else COARSE[int(np.argmin(np.linalg.norm(_coarse_tips(bucket) - target, axis=1)))]
        x = placed(bucket, start)
        if x is None:
            guess = None
            continue
        guess = x
        force, name = _closed_form(np.array([*x, bucket]), "tangent")
        found.append((force, bucket, name, x))
    best = max(range(len(found)), key=lambda k: found[k][0])
    step = (ranges[2][1] - ranges[2][0]) / 60
    bucket0, x0 = found[best][1], found[best][3]

    def negative(bucket: float) -> float:
        x = placed(bucket, x0)
        return 1e30 if x is None else -_closed_form(np.array([*x, bucket]), "tangent")[0]

    top = minimize_scalar(negative, bounds=(max(ranges[2][0], bucket0 - step), min(ranges[2][1], bucket0 + step)), method="bounded",
                          options={"xatol": 1e-10})  # fmt: skip
    names = {found[k][2] for k in (best - 1, best, best + 1) if 0 <= k < len(found)}
    return max(-top.fun, found[best][0]), names


def test_the_reach_map_is_the_largest_force_over_the_buckets_attitude():
    """The smooth force map (`kinegen forces --map tangent --plot`): at 8 places of its raster inside
    the range, its force equals the brute-force largest over the bucket's attitude on the closed-form
    kinematics (virtual work on tests/excavator_reference.py, the attitude swept at 61 lengths and
    refined by Brent's method) to 0.5 % -- what a linear interpolation over 41 x 41 exact poses per
    attitude and a parabola across 33 attitudes leave --, and the cylinder (or the two cylinders)
    that limit it agree with the brute force's."""
    found = reached()
    rng = np.random.default_rng(39)
    finite = np.isfinite(found.force)
    interior = finite.copy()
    for di in range(-4, 5):  # well inside: no edge of the range within 0.2 m
        for dj in range(-4, 5):
            interior &= np.roll(np.roll(finite, di, axis=0), dj, axis=1)
    rows, cols = np.nonzero(interior)
    for k in rng.choice(len(rows), 8, replace=False):
        i, j = rows[k], cols[k]
        target = np.array([found.radius[j], found.height[i]])
        force, names = _largest_over_the_attitude(target)
        assert abs(found.force[i, j] - force) <= 5e-3 * force, (target, found.force[i, j], force)
        region = found.regions[found.limiting[i, j]]
        assert any(name in region for name in names), (target, region, names)
