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
from kinegen.runtime import SolverOptions, kinematics, solve
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
        if element.kind == "actuator":  # its cylinders' rates together (those parallel to it push with its force)
            out[:, k] = sum(kinematics.actuator_rate(results, member.name) for member in m.members(element.name))
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
    omega = {b: (np.zeros((len(results.times), 3)) if b == GROUND else kinematics.omega(results, b)) for b in (joint.body1, joint.body2)}
    carried = axis[None, :] if joint.body1 == GROUND else kinematics.rotation_matrix(results, joint.body1) @ axis
    return np.einsum("ki,ki->k", carried, omega[joint.body2] - omega[joint.body1])


def _load_power(results, loads: list[Load]) -> np.ndarray:
    power = np.zeros(len(results.times))
    for load in loads:
        body, point = load.point.body, load.point.name
        rotation = np.eye(3)[None] if load.axes == GROUND else kinematics.rotation_matrix(results, body)
        force = rotation @ np.array([float(x) for x in load.force])
        moment = rotation @ np.array([float(x) for x in load.moment])
        power += np.einsum("ki,ki->k", force * np.ones((len(results.times), 3)), kinematics.point_velocity(results, body, point))
        power += np.einsum("ki,ki->k", moment * np.ones((len(results.times), 3)), kinematics.omega(results, body))
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
    origin = {b.name: kinematics.position(results, b.name) for b in m.bodies}

    def add(body: str, force: np.ndarray, moment: np.ndarray, at: np.ndarray) -> None:
        if body == GROUND:
            return
        totals[body][0] += force
        totals[body][1] += moment + np.cross(at - origin[body], force)

    for load in loads:
        rotation = np.eye(3)[None] if load.axes == GROUND else kinematics.rotation_matrix(results, load.point.body)
        f = np.broadcast_to(rotation @ np.array([float(x) for x in load.force]), (n, 3))
        mo = np.broadcast_to(rotation @ np.array([float(x) for x in load.moment]), (n, 3))
        add(load.point.body, f, mo, kinematics.point_position(results, load.point.body, load.point.name))
    for reaction in held.reactions.values():
        add(reaction.body2, reaction.force, reaction.moment, reaction.point)
        add(reaction.body1, -reaction.force, -reaction.moment, reaction.point)
    for k, element in enumerate(held.elements):
        f = held.force[:, k]
        if element.kind == "actuator":  # each physical cylinder (the element and those parallel to it) pushes with f
            for member in m.members(element.name):
                p1, p2 = member.points
                r1, r2 = kinematics.point_position(results, p1.body, p1.name), kinematics.point_position(results, p2.body, p2.name)
                e = (r1 - r2) / np.linalg.norm(r1 - r2, axis=1)[:, None]
                add(p1.body, f[:, None] * e, np.zeros((n, 3)), r1)
                add(p2.body, -f[:, None] * e, np.zeros((n, 3)), r2)
        else:
            joint = _motor_joint(m, element.name)
            axis = np.array([float(x) for x in joint.axis1])
            carried = np.broadcast_to(axis, (n, 3)) if joint.body1 == GROUND else kinematics.rotation_matrix(results, joint.body1) @ axis
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
    the holding setting (each boom cylinder's own force and area: the two are parallel)."""
    excavator = model("excavator")
    results = solved("excavator_quaternion", "digging")
    held = forces(results, excavator, ["payload", "cutting"])
    for name, (bore, rod, count) in {"boom_cylinder_left": (0.120, 0.085, 1), "arm_cylinder": (0.135, 0.095, 1),
                                     "bucket_cylinder": (0.115, 0.080, 1)}.items():  # fmt: skip
        f = held.element_force(name)
        pressure = held.pressures[name]
        cap, annulus = count * np.pi / 4 * bore**2, count * np.pi / 4 * (bore**2 - rod**2)
        expected = np.where(f >= 0, f / cap, -f / annulus)
        np.testing.assert_allclose(pressure.pressure, expected, rtol=1e-14)
        rate = kinematics.actuator_rate(results, name) + (kinematics.actuator_rate(results, "boom_cylinder_right") if name == "boom_cylinder_left" else 0)
        moving_with = f * rate > 0
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
        ("tool_points:", "motors:\n  spin: {joint: pivot}\ntool_points:", "motors", "leave mobility 1 for 2 motors and hydraulic actuators"),
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


#: every shipped case but the certificate's stress case (oscillation: 2-3 rad of phase a step, thousands of halved steps)
SHIPPED_CASES = [(m, c) for m in ("boom", "rssr", "four_bar", "slider_crank", "excavator") for c in model(m).cases if c != "oscillation"]


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
    speed = max((np.linalg.norm(kinematics.velocity(results, b), axis=1) + np.linalg.norm(kinematics.omega(results, b), axis=1)).max() for b in results.system.bodies)
    size = functools.partial(np.hypot.reduce, axis=-1)  # |x| without the underflow of sum(x^2) (Hypothesis tries 1e-225 N)
    scale = size(held.force) * size(rates) + (size(force) + size(moment)) * speed
    assert np.all(np.abs(work + power) <= 1e-9 * scale + 1e-300)  # W, per time point


def test_info_shows_the_force_sections():
    from kinegen.analysis.info import describe

    text = describe(model("excavator"), ("quaternion",))
    assert "cylinder 1 x 120/85 mm, relief 34.3 MPa" in text and "cylinder 1 x 115/80 mm, relief 34.3 MPa" in text
    assert "boom_cylinder_right" in text and "parallel to boom_cylinder_left" in text
    assert "motors: swing_motor (at swing)" in text and "loads: payload (at bucket.Q), cutting (at bucket.T)" in text
    assert "masses (kinegen solve --dynamics): 14 of 14 bodies, 12,700 kg" in text
    assert "tool forces (kinegen forces): bucket, arm at bucket.T, lift chart" in text


def test_the_two_boom_cylinders_share_the_load_at_their_own_pins(tmp_path):
    """The excavator's boom cylinders are parallel on one circuit: each pushes with the same force at
    its own pins. Against the same machine with the pair lumped into the left cylinder (``cylinders:
    2``, the right one carrying nothing), built from that model file: each cylinder's force is half
    the pair's, the two base pins' and the two eye pins' loads are equal, their sums equal the lumped
    cylinder's pins', the boom foot's force is unchanged, and every body is in equilibrium."""
    from click.testing import CliRunner

    from kinegen.cli import main
    from kinegen.model import load
    from kinegen.runtime import from_module, load_module

    text = (MODELS / "excavator.yaml").read_text()
    parallel = ", parallel: boom_cylinder_left}"
    assert parallel in text and "hydraulics: {bore: 0.120, rod: 0.085, relief" in text
    lumped_file = tmp_path / "excavator.yaml"
    lumped_file.write_text(text.replace(parallel, "}").replace("hydraulics: {bore: 0.120, rod: 0.085, relief",
                                                               "hydraulics: {bore: 0.120, rod: 0.085, cylinders: 2, relief"))  # fmt: skip
    built = CliRunner().invoke(main, ["build", str(lumped_file), "--param", "quaternion", "--no-sensitivities", "--out-dir", str(tmp_path / "out")])
    assert built.exit_code == 0, built.output
    lumped_model = load(lumped_file)
    lumped_system = from_module(load_module(tmp_path / "out" / "excavator_quaternion.py"), "digging")
    lumped = forces(solve(lumped_system, np.linspace(0, 17, 61)), lumped_model, ["payload", "cutting"])
    excavator = model("excavator")
    held = forces(solved("excavator_quaternion", "digging"), excavator, ["payload", "cutting"])
    assert "boom_cylinder_right" not in [e.name for e in held.elements]
    left, right = held.element_force("boom_cylinder_left"), held.element_force("boom_cylinder_right")
    scale = np.abs(lumped.element_force("boom_cylinder_left")).max()
    np.testing.assert_array_equal(left, right)
    np.testing.assert_allclose(2 * left, lumped.element_force("boom_cylinder_left"), rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(held.pressures["boom_cylinder_left"].pressure, lumped.pressures["boom_cylinder_left"].pressure, rtol=1e-9)
    for end in ("base", "eye"):
        mine = [held.reactions[f"boom_cyl_{side}_{end}"].force for side in "lr"]
        assert np.abs(lumped.reactions[f"boom_cyl_r_{end}"].force).max() == 0.0  # the lumped model's follower carries nothing
        np.testing.assert_allclose(*(np.linalg.norm(f, axis=1) for f in mine), rtol=1e-9)
        np.testing.assert_allclose(2 * np.linalg.norm(mine[0], axis=1), np.linalg.norm(lumped.reactions[f"boom_cyl_l_{end}"].force, axis=1),
                                   rtol=0, atol=1e-9 * scale)  # half the pair's load each  # fmt: skip
        np.testing.assert_allclose(mine[0] + mine[1], lumped.reactions[f"boom_cyl_l_{end}"].force, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(held.reactions["boom_foot"].force, lumped.reactions["boom_foot"].force, rtol=0, atol=1e-9 * scale)
    _assert_equilibrium(held, excavator, [excavator.loads["payload"], excavator.loads["cutting"]])
    names, table = held.table()
    np.testing.assert_array_equal(table[:, names.index("boom_cylinder_right.force")], right)


def test_solve_load_holds_the_machines_own_weight_by_default(tmp_path):
    """`kinegen solve --load` on a model with masses holds the bodies' weight too, and says so;
    --no-weight leaves it out. The difference of the two CSVs' forces is the weight's alone: along the
    motion its power balances the power of gravity on every centre of mass (Σ f ė = −Σ m g·v_C), to
    1e-9 of the terms' scale; in C (`kinegen_forces` at rest) and Python alike."""
    from click.testing import CliRunner

    from kinegen.cli import main
    from kinegen.model.schema import design_value

    excavator = model("excavator")
    tables = {}
    for flags in ((), ("--no-weight",)):
        out = tmp_path / f"cut{len(flags)}.csv"
        done = CliRunner().invoke(main, ["solve", "models/excavator.yaml", "--case", "level_cut", "--steps", "41", "--load", "payload",
                                         "--out", str(out), *flags])  # fmt: skip
        assert done.exit_code == 0, done.output
        if flags:
            assert "forces holding payload, not the machine's weight (--no-weight):" in done.output
        else:
            assert "forces holding payload, the machine's own weight (14 bodies, " in done.output and "--no-weight leaves it out" in done.output
        header = out.read_text().splitlines()[0].split(",")
        tables[flags] = header, np.loadtxt(out, delimiter=",", skiprows=1)
    header, with_weight = tables[()]
    without = tables[("--no-weight",)][1]
    system = generated_system("excavator_quaternion", "level_cut")
    times = np.linspace(system.t0, system.t1, 41)
    results = solve(system, times)
    held = forces(results, excavator, [])
    rates = _element_rates(held, excavator)
    columns = [header.index(f"{e.name}.force") for e in held.elements]
    weight_forces = with_weight[:, columns] - without[:, columns]
    power = np.einsum("ki,ki->k", weight_forces, rates)
    design = {d.name: float(d.nominal) for d in excavator.design}
    gravity = np.array([float(g) for g in excavator.gravity])
    gravity_power = np.zeros(len(times))
    for body in excavator.massive:
        mass = design_value(body.inertia.mass, design)
        center = np.array([design_value(x, design) for x in body.inertia.center])
        arm = kinematics.rotation_matrix(results, body.name) @ center
        velocity = kinematics.velocity(results, body.name) + np.cross(kinematics.omega(results, body.name), arm)
        gravity_power += mass * velocity @ gravity
    scale = np.abs(weight_forces * rates).max()
    assert scale > 1e3  # the weight does work along the cut
    np.testing.assert_allclose(power + gravity_power, 0.0, atol=1e-9 * scale)
    refused = CliRunner().invoke(main, ["solve", "models/excavator.yaml", "--case", "level_cut", "--dynamics", "--no-weight", "--load", "payload"])
    assert refused.exit_code == 64 and "--dynamics holds the weight with the inertia" in refused.output
