"""Forces that hold loads (kinegen.forces): against closed forms written here, the power balance,
and every body's equilibrium -- none of them computed by the code under test."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from kinegen.errors import SingularJacobianError
from kinegen.forces import forces
from kinegen.forces.statics import Forces
from kinegen.model.schema import GROUND, Load, Motor, PointRef
from kinegen.runtime import SolverOptions, solve
from tests.conftest import MODELS, generated_system, model

PARAMETRIZATIONS = ("quaternion", "euler_parameters", "dual_quaternion", "dual_euler_parameters")


@functools.cache
def solved(stem: str, case: str | None = None):
    system = generated_system(stem, case)
    return solve(system, np.linspace(system.t0, system.t1, 61), SolverOptions())


def test_slider_crank_torque_equals_the_closed_form():
    """Crank torque holding a gas force F on the slider: tau = -F dx/dtheta, with the slider's
    closed-form position x = r cos(theta) + sqrt(l^2 - r^2 sin^2(theta))."""
    r, length, gas = 0.2, 0.6, -1000.0
    for param in PARAMETRIZATIONS:
        results = solved(f"slider_crank_{param}", "run")
        held = forces(results, model("slider_crank"), ["gas"])
        theta = 0.3 + 2 * np.pi * results.times + 0.5 * results.times**2
        dx = -r * np.sin(theta) - r**2 * np.sin(theta) * np.cos(theta) / np.sqrt(length**2 - r**2 * np.sin(theta) ** 2)
        torque = -gas * dx
        assert held.elements[0].unit == "N m"
        np.testing.assert_allclose(held.force[:, 0], torque, rtol=0, atol=1e-10 * np.abs(torque).max(), err_msg=param)


def test_four_bar_crank_torque_equals_the_closed_form():
    """A torque M on the rocker is held by the crank torque -M w4/w2, w4/w2 = a sin(t3 - t2) /
    (c sin(t3 - t4)) from the four-bar's closed-form position (circle intersection, upper branch)."""
    a, b, c, d, moment = 0.3, 0.9, 0.7, 1.0, -50.0
    for param in PARAMETRIZATIONS:
        results = solved(f"four_bar_{param}")
        held = forces(results, model("four_bar"), ["rocker_torque"])
        t2 = 0.5 + 2 * np.pi * results.times + 0.3 * np.sin(2 * np.pi * results.times)
        bx, by = a * np.cos(t2), a * np.sin(t2)
        ex, ey = d - bx, -by  # B -> D
        e = np.hypot(ex, ey)
        along = (b**2 - c**2 + e**2) / (2 * e)
        across = np.sqrt(b**2 - along**2)
        cx, cy = bx + (along * ex - across * ey) / e, by + (along * ey + across * ex) / e
        t3, t4 = np.arctan2(cy - by, cx - bx), np.arctan2(cy, cx - d)
        assert np.all(cy > 0)
        ratio = a * np.sin(t3 - t2) / (c * np.sin(t3 - t4))
        torque = -moment * ratio
        np.testing.assert_allclose(held.force[:, 0], torque, rtol=0, atol=1e-9 * np.abs(torque).max(), err_msg=param)


def _element_rates(held: Forces, m) -> np.ndarray:
    """Each element's rate from the solved motion's point velocities and angular velocities
    (an actuator's dL/dt, a motor's relative angular rate about its axis, a driver's input rate)."""
    results, system = held.results, held.results.system
    out = np.empty_like(held.force)
    for k, element in enumerate(held.elements):
        if element.kind == "actuator":
            out[:, k] = results.actuator_rate(element.name)
        elif element.kind == "motor":
            out[:, k] = _relative_rate(results, _motor_joint(m, element.name))
        else:
            out[:, k] = system.driver_inputs(results.times)[1][system.driver_names.index(element.name)]
    return out


def _motor_joint(m, name: str):
    motor = next(x for x in m.motors if x.name == name)
    return next(j for j in m.joints if j.name == motor.joint)


def _relative_rate(results, joint) -> np.ndarray:
    """axis . (omega2 - omega1), the axis carried by body 1."""
    axis = np.array([float(x) for x in joint.axis1])
    omega = {b: (np.zeros((len(results.times), 3)) if b == GROUND else results.omega(b)) for b in (joint.body1, joint.body2)}
    carried = axis[None, :] if joint.body1 == GROUND else results.rotation_matrix(joint.body1) @ axis
    return np.einsum("ki,ki->k", carried, omega[joint.body2] - omega[joint.body1])


def _load_power(results, loads: list[Load]) -> np.ndarray:
    power = np.zeros(len(results.times))
    for load in loads:
        body, point = load.point.body, load.point.name
        rotation = np.eye(3)[None] if load.axes == GROUND else results.rotation_matrix(body)
        force = rotation @ np.array([float(x) for x in load.force])
        moment = rotation @ np.array([float(x) for x in load.moment])
        power += np.einsum("ki,ki->k", force * np.ones((len(results.times), 3)), results.point_velocity(body, point))
        power += np.einsum("ki,ki->k", moment * np.ones((len(results.times), 3)), results.omega(body))
    return power


@pytest.mark.parametrize("case", ["digging", "level_cut"])
def test_excavator_power_balance(case):
    """Sum of element force x element rate + the loads' power = 0 along the shipped cases."""
    excavator = model("excavator")
    results = solved("excavator_quaternion", case)
    held = forces(results, excavator, ["payload", "cutting"])
    work = np.einsum("ki,ki->k", held.force, _element_rates(held, excavator))
    load_power = _load_power(results, [excavator.loads["payload"], excavator.loads["cutting"]])
    scale = np.abs(held.force * _element_rates(held, excavator)).max()
    np.testing.assert_allclose(work + load_power, 0.0, atol=1e-9 * scale)


@settings(max_examples=25, deadline=None)
@given(
    force=st.lists(st.floats(-5e4, 5e4), min_size=3, max_size=3),
    moment=st.lists(st.floats(-2e4, 2e4), min_size=3, max_size=3),
    where=st.sampled_from([("bucket", "T"), ("bucket", "K"), ("arm", "H"), ("boom", "D"), ("side_link", "J")]),
    in_body_axes=st.booleans(),
)
def test_random_loads_balance_power_and_every_body(force, moment, where, in_body_axes):
    """Random wrenches anywhere on the front: the power balance, and every body in equilibrium (its
    joints' reactions, the actuation forces at their points and the load sum to zero)."""
    excavator = model("excavator")
    body, point = where
    local = excavator.body(body).points[point]
    load = Load("random", PointRef(body, point, local), sp.ImmutableMatrix(force), sp.ImmutableMatrix(moment), body if in_body_axes else GROUND)
    loaded = dataclasses.replace(excavator, loads={"random": load})
    results = solved("excavator_quaternion", "digging")
    held = forces(results, loaded, ["random"])
    rates = _element_rates(held, loaded)
    scale = max(np.abs(held.force * rates).max(), 1.0)
    np.testing.assert_allclose(np.einsum("ki,ki->k", held.force, rates) + _load_power(results, [load]), 0.0, atol=1e-9 * scale)
    _assert_equilibrium(held, loaded, [load])


def _assert_equilibrium(held: Forces, m, loads: list[Load]) -> None:
    """Per body: the sum of the forces and of the moments about its origin on it is zero."""
    results = held.results
    n = len(results.times)
    totals = {b.name: [np.zeros((n, 3)), np.zeros((n, 3))] for b in m.bodies}
    origin = {b.name: results.position(b.name) for b in m.bodies}

    def add(body: str, force: np.ndarray, moment: np.ndarray, at: np.ndarray) -> None:
        if body == GROUND:
            return
        totals[body][0] += force
        totals[body][1] += moment + np.cross(at - origin[body], force)

    for load in loads:
        rotation = np.eye(3)[None] if load.axes == GROUND else results.rotation_matrix(load.point.body)
        f = np.broadcast_to(rotation @ np.array([float(x) for x in load.force]), (n, 3))
        mo = np.broadcast_to(rotation @ np.array([float(x) for x in load.moment]), (n, 3))
        add(load.point.body, f, mo, results.point_position(load.point.body, load.point.name))
    for reaction in held.reactions.values():
        add(reaction.body2, reaction.force, reaction.moment, reaction.point)
        add(reaction.body1, -reaction.force, -reaction.moment, reaction.point)
    actuators = {a.name: a for a in m.actuators}
    for k, element in enumerate(held.elements):
        f = held.force[:, k]
        if element.kind == "actuator":
            p1, p2 = actuators[element.name].points
            r1, r2 = results.point_position(p1.body, p1.name), results.point_position(p2.body, p2.name)
            e = (r1 - r2) / np.linalg.norm(r1 - r2, axis=1)[:, None]
            add(p1.body, f[:, None] * e, np.zeros((n, 3)), r1)
            add(p2.body, -f[:, None] * e, np.zeros((n, 3)), r2)
        else:
            joint = _motor_joint(m, element.name)
            axis = np.array([float(x) for x in joint.axis1])
            carried = np.broadcast_to(axis, (n, 3)) if joint.body1 == GROUND else results.rotation_matrix(joint.body1) @ axis
            add(joint.body2, np.zeros((n, 3)), f[:, None] * carried, origin.get(joint.body2, np.zeros((n, 3))))
            add(joint.body1, np.zeros((n, 3)), -f[:, None] * carried, origin.get(joint.body1, np.zeros((n, 3))))
    scale = max(np.abs(held.force).max(), 1.0) * 10  # N, and N m over the front's ~10 m
    for body, (force, moment) in totals.items():
        np.testing.assert_allclose(force, 0.0, atol=1e-9 * scale, err_msg=f"force on {body}")
        np.testing.assert_allclose(moment, 0.0, atol=1e-9 * scale, err_msg=f"moment on {body}")


def test_every_excavator_body_in_equilibrium_in_every_parametrization():
    excavator = model("excavator")
    loads = [excavator.loads["payload"], excavator.loads["cutting"]]
    reference = None
    for param in (*PARAMETRIZATIONS, "euler_zxy"):
        results = solved(f"excavator_{param}", "level_cut")
        held = forces(results, excavator, ["payload", "cutting"])
        _assert_equilibrium(held, excavator, loads)
        if reference is None:
            reference = held.force
        np.testing.assert_allclose(held.force, reference, rtol=0, atol=1e-7 * np.abs(reference).max(), err_msg=param)


def test_cylinder_pressures_by_hand():
    """p = F / (n pi/4 D^2) on the cap side when pushing, F / (n pi/4 (D^2 - d^2)) on the rod side
    when pulling; the limit is the relief setting where the cylinder moves with its force, else
    the holding setting."""
    excavator = model("excavator")
    results = solved("excavator_quaternion", "digging")
    held = forces(results, excavator, ["payload", "cutting"])
    for name, (bore, rod, count) in {"boom_cylinder_left": (0.120, 0.085, 2), "arm_cylinder": (0.135, 0.095, 1),
                                     "bucket_cylinder": (0.115, 0.080, 1)}.items():  # fmt: skip
        f = held.element_force(name)
        pressure = held.pressures[name]
        cap, annulus = count * np.pi / 4 * bore**2, count * np.pi / 4 * (bore**2 - rod**2)
        expected = np.where(f >= 0, f / cap, -f / annulus)
        np.testing.assert_allclose(pressure.pressure, expected, rtol=1e-14)
        moving_with = f * results.actuator_rate(name) > 0
        np.testing.assert_array_equal(pressure.limit, np.where(moving_with, 34.3e6, 39.2e6))
        assert pressure.cap_side.any() and (~pressure.cap_side).any()  # the cycle pushes and pulls every cylinder
    # eight times the cutting load: beyond the settings somewhere, and every such point reported
    heavy = dataclasses.replace(excavator.loads["cutting"], force=8 * excavator.loads["cutting"].force)
    overloaded = forces(results, dataclasses.replace(excavator, loads={"heavy": heavy}), ["heavy"])
    violations = overloaded.violations()
    assert violations
    for t, name, p, limit, _ in violations:
        k = int(np.flatnonzero(results.times == t)[0])
        assert p == overloaded.pressures[name].pressure[k] > limit == overloaded.pressures[name].limit[k]
    assert len(violations) == sum(int(p.exceeded.sum()) for p in overloaded.pressures.values())


def test_a_load_the_actuation_cannot_hold_is_named(tmp_path):
    """A four-bar held by a motor at its rocker cannot hold a torque on its crank where crank and
    coupler are in line (the rocker at its extreme: it does not move when the crank turns)."""
    from scipy.optimize import brentq

    from kinegen.api import Session

    # in line: |AC| = a + b = 1.2, |DC| = 0.7, D = (1, 0) -> C = (0.975, sqrt(1.44 - 0.975^2))
    in_line = np.arctan2(np.sqrt(1.44 - 0.975**2), 0.975)
    t_star = brentq(lambda t: 0.5 + 2 * np.pi * t + 0.3 * np.sin(2 * np.pi * t) - in_line, 0.0, 0.1, xtol=1e-15)
    text = (MODELS / "four_bar.yaml").read_text().split("\nloads:")[0]
    path = tmp_path / "held_at_rocker.yaml"
    path.write_text(text + "\nmotors:\n  rocker_motor: {joint: D}\nloads:\n  crank_torque: {point: crank.A, moment: [0, 0, 10]}\n")
    session = Session(tmp_path / "generated")
    held_at_rocker, system = session.model(path), session.system(path, parametrization="quaternion")
    results = solve(system, np.array([0.0, t_star / 2, t_star]), SolverOptions())
    with pytest.raises(SingularJacobianError, match="cannot hold the load") as caught:
        forces(results, held_at_rocker, ["crank_torque"])
    assert caught.value.t == pytest.approx(t_star)
    assert "rocker_motor" in caught.value.dependent_constraints
    away = solve(system, np.array([0.0, t_star / 2]), SolverOptions())
    assert np.isfinite(forces(away, held_at_rocker, ["crank_torque"]).force).all()


def test_unknown_load_and_incomplete_solve():
    with pytest.raises(KeyError, match="no load 'nope'"):
        forces(solved("slider_crank_quaternion", "run"), model("slider_crank"), ["nope"])


def test_declared_motor_is_read():
    excavator = model("excavator")
    assert [type(e) for e in excavator.actuation] == [Motor, *[type(excavator.actuators[0])] * 3]


FORCES = """\
actuators:
  lift: {points: [ground.O, arm.tip], hydraulics: {bore: 0.1, rod: 0.05, relief: 30e6}}
tool_points:
  tip: arm.tip
loads:
  weight: {point: tip, force: [0, "-1000 - 10*t", 0], moment: [0, 0, 5], axes: arm}
"""


def test_force_sections_are_read():
    from kinegen.model import loads as read
    from tests.test_model_validation import BASE

    m = read(BASE + FORCES, "forces.yaml")
    (lift,) = m.actuation
    assert lift.hydraulics.relief == lift.hydraulics.holding  # holding defaults to relief
    assert lift.hydraulics.areas() == pytest.approx((np.pi / 4 * 0.01, np.pi / 4 * (0.01 - 0.0025)), rel=1e-15)
    assert m.tool_points["tip"].body == "arm"
    from kinegen.model.expressions import T

    assert m.loads["weight"].axes == "arm" and m.loads["weight"].force[1] == -1000 - 10 * T


@pytest.mark.parametrize(
    ("old", "new", "entry", "problem"),
    [
        ("rod: 0.05", "rod: 0.1", "actuators.lift.hydraulics.rod", "0 < rod < bore"),
        ("relief: 30e6", "relief: 300", "actuators.lift.hydraulics.relief", "below 1 bar"),
        ("relief: 30e6", "relief: {extend: 30e6}", "actuators.lift.hydraulics.relief", "missing required key 'retract'"),
        ("relief: 30e6}", "relief: 30e6, cylinders: 0}", "actuators.lift.hydraulics.cylinders", "whole number >= 1"),
        ("tip: arm.tip\n", "tip: ground.O\n", "tool_points.tip", "moving body"),
        ("point: tip, force", "point: ground.O, force", "loads.weight.point", "moves nothing"),
        ("axes: arm", "axes: ground", "loads.weight.axes", "expected global or arm"),
        (', moment: [0, 0, 5]', ', moment: [0, 5]', "loads.weight.moment", "list of 3"),
        ('force: [0, "-1000 - 10*t", 0], moment: [0, 0, 5], ', "", "loads.weight", "a force, a moment or both"),
        ("tool_points:", "motors:\n  spin: {joint: pivot}\ntool_points:", "motors", "as many as the mobility (1); 2 are declared"),
        ("tool_points:", "motors:\n  spin: {joint: hinge}\ntool_points:", "motors.spin.joint", "unknown joint 'hinge'"),
    ],
)
def test_malformed_force_sections_name_the_entry(old, new, entry, problem):
    from kinegen.errors import ModelError
    from kinegen.model import loads as read
    from tests.test_model_validation import BASE

    text = BASE + FORCES
    assert old in text
    with pytest.raises(ModelError) as caught:
        read(text.replace(old, new), "forces.yaml")
    assert caught.value.entry == entry
    assert problem in caught.value.problem


def test_solve_with_loads_writes_the_force_columns(tmp_path):
    """`kinegen solve --load` adds the forces to the CSV (equal to the library's) and reports them;
    an unknown load is a usage error naming the model's loads."""
    import csv

    from click.testing import CliRunner

    from kinegen.cli import main

    out = tmp_path / "run.csv"
    args = ["solve", "models/slider_crank.yaml", "--steps", "61", "--no-compile", "--load", "gas", "--out", str(out)]
    run = CliRunner().invoke(main, args)
    assert run.exit_code == 0, run.output
    assert "forces holding gas:" in run.output and "crank_angle" in run.output
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    held = forces(solved("slider_crank_quaternion", "run"), model("slider_crank"), ["gas"])
    np.testing.assert_array_equal([float(r["crank_angle.force"]) for r in rows], held.force[:, 0])
    assert {"A.force_x", "A.joint_moment_z", "lambda.crank_angle"} <= set(rows[0])
    bad = CliRunner().invoke(main, ["solve", "models/slider_crank.yaml", "--load", "wind"])
    assert bad.exit_code == 64 and "no load 'wind' (loads: gas)" in bad.output


SHIPPED_CASES = [(m, c) for m in ("boom", "rssr", "four_bar", "slider_crank", "excavator") for c in model(m).cases]


@functools.cache
def solved_prefix(name: str, case: str):
    """A case solved on 41 points; a case that ends at a singular pose on purpose (a toggle, a dead
    centre) up to the last point before it."""
    system = generated_system(f"{name}_quaternion", case)
    results = solve(system, np.linspace(system.t0, system.t1, 41), SolverOptions(on_failure="stop"))
    if results.complete:
        return results
    end = max(int(np.argmin(results.converged)) - 1, 2)
    return dataclasses.replace(results.time_points(slice(end)), converged=None, failure=None)


@settings(max_examples=30, deadline=None)
@given(
    which=st.sampled_from(SHIPPED_CASES),
    force=st.lists(st.floats(-1e4, 1e4), min_size=3, max_size=3),
    moment=st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3),
    pick=st.integers(0, 10_000),
    in_body_axes=st.booleans(),
)
def test_power_balance_along_every_shipped_case(which, force, moment, pick, in_body_axes):
    """Any wrench at any named point of any moving body, along every shipped case (each model's own
    actuation: its motors and hydraulic cylinders, else the case's drivers): the elements' power
    balances the load's to 1e-9 of |f| |L'| + (|F| + |M| / 1 m) s at each time point, s the case's
    speed (the largest |v| + |ω| of a body frame). The forces carry the solve's rounding, about
    eps x cond(force matrix) x |f|, and a point's velocity that of the motion's speed, so that is the
    scale of the sum's error -- not the matched terms f_i L'_i: a small load beside a toggle needs
    large forces whose powers cancel (4 N at bucket_link.J on bucket_toggle: 0.95 W each way), and a
    point on a joint axis moves at rounding speed. Measured over 150 random loads on bucket_toggle
    (cond <= 1.1e3): at most 1.8e-10 of |f| |L'| + |P_load|."""
    name, case = which
    m = model(name)
    points = [(b.name, p) for b in m.bodies for p in b.points]
    body, point = points[pick % len(points)]
    load = Load("random", PointRef(body, point, m.body(body).points[point]), sp.ImmutableMatrix(force), sp.ImmutableMatrix(moment),
                body if in_body_axes else GROUND)  # fmt: skip
    loaded = dataclasses.replace(m, loads={"random": load})
    results = solved_prefix(name, case)
    held = forces(results, loaded, ["random"])
    rates = _element_rates(held, loaded)
    work = np.einsum("ki,ki->k", held.force, rates)
    power = _load_power(results, [load])
    speed = max((np.linalg.norm(results.velocity(b), axis=1) + np.linalg.norm(results.omega(b), axis=1)).max() for b in results.system.bodies)
    size = functools.partial(np.hypot.reduce, axis=-1)  # |x| without the underflow of sum(x^2) (Hypothesis tries 1e-225 N)
    scale = size(held.force) * size(rates) + (size(force) + size(moment)) * speed
    assert np.all(np.abs(work + power) <= 1e-9 * scale + 1e-300)  # W, per time point


def test_info_shows_the_force_sections():
    from kinegen.analysis.info import describe

    text = describe(model("excavator"), ("quaternion",))
    assert "cylinders 2 x 120/85 mm, relief 34.3 MPa" in text and "cylinder 1 x 115/80 mm, relief 34.3 MPa" in text
    assert "motors: swing_motor (at swing)" in text and "loads: payload (at bucket.Q), cutting (at bucket.T)" in text
    assert "masses (kinegen solve --dynamics): 14 of 14 bodies, 12,700 kg" in text
    assert "tool forces (kinegen forces): bucket, arm at bucket.T, lift chart" in text
