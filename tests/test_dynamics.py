"""Inverse dynamics (kinegen.forces with inertia=True) against Pinocchio's recursive Newton-Euler
algorithm (``pin``, an independent rigid-body dynamics library) on open chains, the energy balance
along a motion, and every body's equilibrium with its d'Alembert forces."""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin  # the independent reference: Pinocchio (`pin`, in the test extra)
import pytest
import scipy.linalg

from kinegen.api import Session
from kinegen.forces import forces
from kinegen.forces.dynamics import energies
from kinegen.model.schema import GROUND, design_value
from kinegen.runtime import kinematics, solve
from tests.conftest import ROOT, chain_yaml, generated_system, model, nominal_inertia

ARM = ROOT / "tests" / "models" / "arm3.yaml"
PARAMETRIZATIONS = ("quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters")


@functools.cache
def _session(folder: str) -> Session:
    return Session(folder)


def _solved(tmp_path_factory, path, parametrization: str, times=None):
    session = _session(str(tmp_path_factory.getbasetemp() / "dynamics-modules"))
    system = session.system(path, parametrization=parametrization, compiled=False)
    return session.model(path), solve(system, times)


def _floats(values) -> np.ndarray:
    return np.array([float(v) for v in values], dtype=float)


def pinocchio_chain(model):
    """Pinocchio's model of an open chain of revolute joints rooted at the ground, from the model's
    data alone: each joint frame at the joint's point on its child with the child's initial
    orientation, placed in its parent's joint frame as at the initial pose; the axis and the body's
    inertia (about its centre of mass, body axes) in that frame. Returns the model and, per joint
    in Pinocchio's order, (joint, parent, child, axis in the child's axes)."""
    bodies = {b.name: b for b in model.bodies}
    frames = {GROUND: (np.eye(3), np.zeros(3))}
    ids = {GROUND: 0}
    chain = pin.Model()
    chain.gravity = pin.Motion(np.r_[_floats(model.gravity), 0.0, 0.0, 0.0])
    order, remaining = [], list(model.joints)
    while remaining:
        joint = next(j for j in remaining if j.body1 in ids or j.body2 in ids)
        remaining.remove(joint)
        assert joint.type == "revolute"
        parent, child = (joint.body1, joint.body2) if joint.body1 in ids else (joint.body2, joint.body1)
        point = _floats(joint.point2 if child == joint.body2 else joint.point1)
        axis = _floats(joint.axis2 if child == joint.body2 else joint.axis1)
        axis /= np.linalg.norm(axis)
        body = bodies[child]
        rotation = np.array(body.rotation.evalf(), dtype=float)
        frame = (rotation, _floats(body.position) + rotation @ point)
        parent_rotation, parent_origin = frames[parent]
        placement = pin.SE3(parent_rotation.T @ frame[0], parent_rotation.T @ (frame[1] - parent_origin))
        index = chain.addJoint(ids[parent], pin.JointModelRevoluteUnaligned(axis), placement, joint.name)
        inertia = body.inertia
        tensor = np.array(inertia.tensor.evalf(), dtype=float)
        chain.appendBodyToJoint(index, pin.Inertia(float(inertia.mass), _floats(inertia.center) - point, tensor), pin.SE3.Identity())
        frames[child], ids[child] = frame, index
        order.append((joint, parent, child, axis))
    return chain, order


def joint_motion(model, results, order, initial: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pinocchio's (q, v, a) from kinegen's solved bodies: each joint's angle from the child's
    rotation relative to its parent (zero at ``initial``, each body's rotation where Pinocchio's joint
    frames were placed: by default the model's initial pose), its rate a.(w_child - w_parent) and that
    rate's derivative (a global = turning with the child)."""
    k = len(results.times)
    initial = dict(initial or {b.name: np.array(b.rotation.evalf(), dtype=float) for b in model.bodies})
    initial[GROUND] = np.eye(3)

    def rotation(body):
        return np.broadcast_to(np.eye(3), (k, 3, 3)) if body == GROUND else kinematics.rotation_matrix(results, body)

    def omega(body, derivative=False):
        if body == GROUND:
            return np.zeros((k, 3))
        return kinematics.omega_dot(results, body) if derivative else kinematics.omega(results, body)

    q, v, a = [], [], []
    for _, parent, child, axis in order:
        relative = np.einsum("kji,kjl->kil", rotation(parent), rotation(child))
        at_zero = initial[parent].T @ initial[child]
        turn = np.einsum("ji,kjl->kil", at_zero, relative)  # about the axis, in the child's axes
        sine = np.stack([turn[:, 2, 1] - turn[:, 1, 2], turn[:, 0, 2] - turn[:, 2, 0], turn[:, 1, 0] - turn[:, 0, 1]], axis=1) @ axis / 2
        cosine = (np.einsum("kii->k", turn) - 1) / 2
        q.append(np.unwrap(np.arctan2(sine, cosine)))
        global_axis = np.einsum("kij,j->ki", rotation(child), axis)
        relative_rate = omega(child) - omega(parent)
        v.append(np.einsum("ki,ki->k", global_axis, relative_rate))
        a.append(np.einsum("ki,ki->k", global_axis, omega(child, True) - omega(parent, True))
                 + np.einsum("ki,ki->k", np.cross(omega(parent), global_axis), relative_rate))  # fmt: skip
    return np.array(q).T, np.array(v).T, np.array(a).T


def _against_pinocchio(model, results) -> None:
    chain, order = pinocchio_chain(model)
    data = chain.createData()
    q, v, a = joint_motion(model, results, order)
    tau = np.array([pin.rnea(chain, data, q[k], v[k], a[k]) for k in range(len(q))])
    held = forces(results, model, [], inertia=True)
    # each driver is one joint's angle: its force is that joint's torque, with the sign of dq/du
    drivers = {d.joint: d.name for d in model.cases[results.system.case].drivers}
    ours = np.column_stack([held.element_force(drivers[joint.name]) for joint, *_ in order])
    rates = results.system.driver_inputs(results.times)[1]
    u_dot = np.column_stack([rates[results.system.driver_names.index(drivers[joint.name])] for joint, *_ in order])
    sign = np.sign(np.einsum("ki,ki->i", v, u_dot))
    assert set(sign) <= {-1.0, 1.0}
    np.testing.assert_allclose(ours * sign, tau, rtol=0, atol=1e-9 * np.abs(tau).max())


@pytest.mark.parametrize("parametrization", PARAMETRIZATIONS)
def test_a_spatial_arm_equals_pinocchio(tmp_path_factory, parametrization):
    """A 3-link spatial arm (yaw, shoulder, elbow; offset centres of mass, full inertia tensors, one
    given by principal axes) driven at its joints: the joint torques along the motion equal
    Pinocchio's RNEA to 1e-9 of the largest."""
    model, results = _solved(tmp_path_factory, ARM, parametrization)
    _against_pinocchio(model, results)


def test_chain_n_with_masses_equals_pinocchio(tmp_path_factory):
    """The chain-N benchmark mechanism (docs/chain-N.md, 8 links) with a mass on every link."""
    text = chain_yaml(8)
    lines = []
    for line in text.splitlines():
        lines.append(line)
        if line.strip().startswith("vectors: {z: [0, 0, 1]}") and line.startswith("    "):
            lines += ["    mass: 3.5", "    center_of_mass: [0.45, 0.03, 0.01]", "    inertia: [0.02, 0.3, 0.31, 0.002, 0.001, -0.003]"]
    path = tmp_path_factory.mktemp("chain") / "chain8.yaml"
    path.write_text("\n".join(lines) + "\n")
    model, results = _solved(tmp_path_factory, path, "quaternion")
    assert len(model.massive) == 8
    _against_pinocchio(model, results)


def test_the_drivers_work_is_the_change_of_energy(tmp_path_factory):
    """Along the arm's motion (no loads), the drivers' work (integrated power f.u') equals the
    change of kinetic plus potential energy (computed from the solved frames, not the multipliers)
    to 1e-8 of the energies' scale; and the power equals dE/dt at every point."""
    path = ARM
    session = _session(str(tmp_path_factory.getbasetemp() / "dynamics-modules"))
    system = session.system(path, parametrization="quaternion", compiled=False)
    times = np.linspace(system.t0, system.t1, 2001)
    model, results = session.model(path), solve(system, times)
    held = forces(results, model, [], inertia=True)
    power = np.einsum("ki,ki->k", held.force, system.driver_inputs(times)[1].T)
    energy = energies(results, model)
    from scipy.integrate import simpson

    work = simpson(power, x=times)
    scale = np.abs(energy.kinetic).max() + np.abs(energy.potential).max()
    assert abs(work - (energy.total[-1] - energy.total[0])) <= 1e-8 * scale
    rate = np.gradient(energy.total, times, edge_order=2)
    assert np.abs(power - rate)[5:-5].max() <= 1e-5 * np.abs(power).max()


def test_every_body_is_in_equilibrium_with_its_dalembert_forces(tmp_path_factory):
    """On every body of the arm at every time point: the joints' reactions, its weight m g and its
    inertial force -m a_C sum to zero, and their moments about its centre of mass with -(J w' + w x J w)."""
    model, results = _solved(tmp_path_factory, ARM, "euler-parameters")
    held = forces(results, model, [], inertia=True)
    gravity = _floats(model.gravity)
    for body in model.bodies:
        inertia = body.inertia
        rotation = kinematics.rotation_matrix(results, body.name)
        center = kinematics.position(results, body.name) + rotation @ _floats(inertia.center)
        omega, omega_dot = kinematics.omega(results, body.name), kinematics.omega_dot(results, body.name)
        arm = center - kinematics.position(results, body.name)
        acceleration = kinematics.acceleration(results, body.name) + np.cross(omega_dot, arm) + np.cross(omega, np.cross(omega, arm))
        tensor = rotation @ np.array(inertia.tensor.evalf(), dtype=float) @ rotation.swapaxes(1, 2)
        force = float(inertia.mass) * (gravity - acceleration)
        moment = -(np.einsum("kij,kj->ki", tensor, omega_dot) + np.cross(omega, np.einsum("kij,kj->ki", tensor, omega)))
        scale = np.abs(force).max()
        for driver in model.cases[results.system.case].drivers:  # a joint-angle driver's torque f a: on body2, and -f a on body1
            joint = next(j for j in model.joints if j.name == driver.joint)
            carried = np.broadcast_to(_floats(joint.axis1), (len(force), 3)) if joint.body1 == GROUND else \
                kinematics.rotation_matrix(results, joint.body1) @ _floats(joint.axis1)
            torque = held.element_force(driver.name)[:, None] * carried
            moment = moment + (torque if joint.body2 == body.name else -torque if joint.body1 == body.name else 0.0)
        for reaction in held.reactions.values():
            for side, sign in ((reaction.body2, 1.0), (reaction.body1, -1.0)):
                if side == body.name:
                    force = force + sign * reaction.force
                    moment = moment + sign * (reaction.moment + np.cross(reaction.point - center, reaction.force))
                    scale = max(scale, np.abs(reaction.force).max())
        assert np.abs(force).max() <= 1e-9 * scale, body.name
        assert np.abs(moment).max() <= 1e-9 * scale * 1.0, body.name  # N m: the arm's lengths are ~1 m


def test_the_compiled_inverse_dynamics_of_the_arm_equals_python(tmp_path_factory):
    """The arm's drivers carry its weight and inertia (no actuation elements: each case's Phi_q):
    kinegen_forces in C against the Python kernels and LAPACK, to 1e-12 of the largest torque."""
    from kinegen.forces.dynamics import inertial_load
    from kinegen.forces.statics import Statics

    session = _session(str(tmp_path_factory.getbasetemp() / "dynamics-modules"))
    system = session.system(ARM, parametrization="dual-quaternion", compiled=True)
    if system.native is None:
        pytest.skip("no C compiler")
    model, results = session.model(ARM), solve(system)
    statics = Statics(results, model)
    expected = statics.element_forces(statics.solve(statics.matrix(), inertial_load(results)))
    _, force = system.native.forces(results.times, results.q, results.inputs, np.zeros(0), (results.v, results.a))
    np.testing.assert_allclose(force, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_solve_dynamics_reports_the_forces_that_move_the_excavator_and_its_energy(tmp_path):
    """`kinegen solve --dynamics` (the excavator's estimated masses): the report names what is held,
    the CSV gains every force column and the energies; a model without masses is refused."""
    from click.testing import CliRunner

    from kinegen.cli import main

    out = tmp_path / "digging.csv"
    done = CliRunner().invoke(main, ["solve", "models/excavator.yaml", "--case", "digging", "--steps", "69", "--dynamics",
                                     "--load", "payload", "--out", str(out), "--no-compile"])  # fmt: skip
    assert done.exit_code == 0, done.output
    assert "forces moving the machine (its weight and inertia: 14 bodies, " in done.output and "kg) and holding payload:" in done.output
    assert "energy: kinetic up to" in done.output
    assert "tipping margin: smallest" in done.output
    header = out.read_text().splitlines()[0].split(",")
    assert {"swing_motor.force", "boom_cylinder_left.pressure", "energy.kinetic", "energy.potential", "tipping_margin",
            "tipping_margin.left"} <= set(header)
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    kinetic, potential = table[:, header.index("energy.kinetic")], table[:, header.index("energy.potential")]
    assert 0 < kinetic[0] < 1e-4 * kinetic.max()  # the cycle starts all but at rest (its tanh steps are not flat)
    assert (potential > 0).all()  # every centre of mass above the ground (z = 0)
    refused = CliRunner().invoke(main, ["solve", "models/four_bar.yaml", "--dynamics"])
    assert refused.exit_code == 64 and "no masses" in refused.output  # a usage error (README: exit codes)


def test_the_tipping_margin_is_the_moment_the_ground_sees(tmp_path_factory):
    """Along the excavator's digging cycle with its payload, at speed: the tipping margin about each
    line equals the moment of what the machine puts on the undercarriage -- the swing bearing's
    reaction and the swing motor's torque from the multipliers (kinegen.forces), plus the
    undercarriage's weight -- not the direct sum of weights and d'Alembert forces it is computed by,
    to 1e-9 of the largest; standing still (no inertia), the front line's margin is the lever rule."""
    from kinegen.forces.dynamics import TIPPING_LINES, tipping_margin

    excavator = model("excavator")
    results = solve(generated_system("excavator_quaternion", "digging"), np.linspace(0, 17, 171))
    held = forces(results, excavator, ["payload"], inertia=True)
    swing = held.reactions["swing"]  # what the ground exerts on the upper structure, about the swing axis's point
    torque = held.element_force("swing_motor")[:, None] * np.array([0.0, 0.0, 1.0])  # on the upper; its reaction on the ground
    weight = 7300 * _floats(excavator.gravity)
    under = np.array([0.0, 0.0, 0.45])
    scale = max(np.abs(m).max() for m in held.tipping.margins.values())
    for name, (normal, which) in TIPPING_LINES.items():
        on_line = (3.37 / 2, 2.2 / 2)[which] * normal
        along = np.cross([0.0, 0.0, 1.0], normal)
        on_ground = np.cross(swing.point - on_line, -swing.force) - swing.moment - torque + np.cross(under - on_line, weight)
        np.testing.assert_allclose(held.tipping.margins[name], -(on_ground @ along), rtol=0, atol=1e-9 * scale, err_msg=name)
    still = tipping_margin(results, excavator, inertia=False)
    lever = 7300 * 9.80665 * 3.37 / 2
    for b in excavator.massive:
        mass, center, _ = nominal_inertia("excavator", b)
        lever = lever + mass * 9.80665 * (3.37 / 2 - (kinematics.position(results, b.name) + kinematics.rotation_matrix(results, b.name) @ center)[:, 0])
    np.testing.assert_allclose(still.margins["front"], lever, rtol=1e-12)


def test_the_excavators_front_cut_open_equals_pinocchio(tmp_path_factory):
    """The excavator's upper structure, boom, arm and bucket with their estimated masses, the loops cut
    open (cylinders and links removed, each joint driven by its angle: the cylinders replaced by joint
    torques), swinging and digging at once: the joint torques equal Pinocchio's RNEA to 1e-9."""
    excavator = model("excavator")
    bodies = {b.name: b for b in excavator.bodies}

    def vector(v) -> str:
        return "[" + ", ".join(repr(float(x)) for x in v) + "]"

    lines = ["model: front", "ground:", "  points: {O: [0, 0, 0]}", "  vectors: {z: [0, 0, 1]}", "bodies:"]
    for name in ("upper", "boom", "arm", "bucket"):
        b = bodies[name]
        matrix = "[" + ", ".join(vector(row) for row in np.array(b.rotation.evalf(), dtype=float)) + "]"
        points = ", ".join(f"{p}: {vector(b.points[p])}" for p in ("O", "A", "E", "Q") if p in b.points)
        mass, center, tensor = nominal_inertia("excavator", b)
        lines += [f"  {name}:", f"    position: {vector(b.position)}", f"    orientation: {{matrix: {matrix}}}",
                  f"    points: {{{points}}}", "    vectors: {y: [0, 1, 0], z: [0, 0, 1]}",
                  f"    mass: {mass!r}", f"    center_of_mass: {vector(center)}",
                  f"    inertia: {vector([tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]])}"]  # fmt: skip
    lines += [
        "joints:",
        "  swing: {type: revolute, bodies: [ground, upper], points: [O, O], axes: [z, z]}",
        "  boom_foot: {type: revolute, bodies: [upper, boom], points: [A, A], axes: [y, y]}",
        "  arm_pin: {type: revolute, bodies: [boom, arm], points: [E, E], axes: [y, y]}",
        "  bucket_pin: {type: revolute, bodies: [arm, bucket], points: [Q, Q], axes: [y, y]}",
        "cases:",
        "  dig:",
        "    drivers:",
        "      swing: {type: joint_angle, joint: swing, function: 0.6*sin(0.8*t)}",
        "      boom: {type: joint_angle, joint: boom_foot, function: -0.3*sin(0.9*t)}",
        "      arm: {type: joint_angle, joint: arm_pin, function: 0.5*sin(1.1*t)}",
        "      bucket: {type: joint_angle, joint: bucket_pin, function: 0.8*sin(1.3*t)}",
        "    t0: 0",
        "    t1: 3",
        "    steps: 61",
    ]
    path = tmp_path_factory.mktemp("front") / "front.yaml"
    path.write_text("\n".join(lines) + "\n")
    front, results = _solved(tmp_path_factory, path, "quaternion")
    _against_pinocchio(front, results)


@pytest.mark.parametrize(("case", "loads"), [("digging", ["payload"]), ("level_cut", ["payload", "cutting"]), ("trench_wall", []),
                                             ("bucket_stroke", ["cutting"]), ("bucket_near_toggle", []), ("digging_fast", ["payload"])])  # fmt: skip
def test_along_the_excavators_cases_the_work_is_the_change_of_energy(case, loads):
    """Along every shipped excavator case at speed (but bucket_toggle, which runs into its toggle on
    purpose), with its estimated masses: the actuators' work
    (each cylinder's force times its rate, the swing motor's torque times its rate, integrated) equals
    the change of kinetic plus potential energy minus the loads' work, to 1e-8 of the energies'
    scale (Simpson on 3,401 points); the rates and energies from the solved frames, not the multipliers."""
    from scipy.integrate import simpson

    from tests.test_forces import _element_rates, _load_power

    excavator = model("excavator")
    system = generated_system("excavator_quaternion", case, compiled=True)
    times = np.linspace(system.t0, system.t1, 3401)
    results = solve(system, times)
    held = forces(results, excavator, loads, inertia=True)
    power = np.einsum("ki,ki->k", held.force, _element_rates(held, excavator))
    load_power = _load_power(results, [excavator.loads[name] for name in loads])
    energy = energies(results, excavator)
    scale = np.abs(energy.kinetic).max() + np.abs(energy.potential).max()
    change = energy.total[-1] - energy.total[0]
    assert abs(simpson(power + load_power, x=times) - change) <= 1e-8 * scale, (simpson(power + load_power, x=times), change)


def closed_loop_accelerations(chain, closure, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Pinocchio's constrained forward dynamics (``constraintDynamics``) of the tree ``chain`` closed by
    the constraint ``closure``: the accelerations (K, nv) at each row of q, v and the joint forces tau.
    The proximal solver takes the redundant out-of-plane equation of a planar loop."""
    data, closures, closure_data = chain.createData(), pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    closures.append(closure)
    closure_data.append(closure.createData())
    pin.initConstraintDynamics(chain, data, closures, closure_data)
    settings = pin.ProximalSettings(1e-14, 1e-10, 100)
    return np.array([pin.constraintDynamics(chain, data, q[k], v[k], tau[k], closures, closure_data, settings) for k in range(len(q))])


FOUR_BAR_MASSES = {  # kg; m, body coordinates; kg m^2 [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] about the centre of mass
    "crank": (2.0, [0.15, 0.01, 0.005], [0.002, 0.016, 0.017, 0.0002, 0.0001, -0.0001]),
    "coupler": (4.5, [0.45, 0.03, -0.01], [0.012, 0.30, 0.31, 0.001, -0.002, 0.0005]),
    "rocker": (3.0, [0.35, -0.02, 0.0], [0.006, 0.12, 0.125, -0.0005, 0.0, 0.0003]),
}


@pytest.mark.parametrize("parametrization", ["quaternion", "euler-parameters"])
def test_the_four_bars_crank_torque_drives_pinocchios_closed_loop(tmp_path_factory, parametrization):
    """A closed loop against Pinocchio's constrained dynamics: the four-bar (models/four_bar.yaml) with
    masses and gravity in its plane, its crank torque from kinegen's inverse dynamics (the multipliers
    of Φ_qᵀλ = Q_inertia) applied to Pinocchio's tree (crank and coupler from A, rocker from D, joints
    about z) closed by a point constraint between the coupler's and the rocker's C: Pinocchio's forward
    dynamics (constraintDynamics) gives back kinegen's accelerations to 1e-9 of the largest."""
    text = (ROOT / "models" / "four_bar.yaml").read_text().replace("ground:\n", "gravity: [0, -9.80665, 0]\nground:\n", 1)
    for body, (mass, center, inertia) in FOUR_BAR_MASSES.items():
        text = text.replace(f"  {body}:\n", f"  {body}:\n    mass: {mass}\n    center_of_mass: {center}\n    inertia: {inertia}\n", 1)
    path = tmp_path_factory.mktemp("four_bar") / "four_bar_masses.yaml"
    path.write_text(text)
    model, results = _solved(tmp_path_factory, path, parametrization, np.linspace(0, 1, 41))
    torque = forces(results, model, [], inertia=True).force[:, 0]  # the crank-angle driver's: about +z on the crank (du/dt > 0)
    assert np.all(results.system.driver_inputs(results.times)[1] > 0)

    chain = pin.Model()
    chain.gravity = pin.Motion(np.r_[0.0, -9.80665, 0.0, 0.0, 0.0, 0.0])
    joints = {}
    for name, parent, at, body in (("A", 0, [0, 0, 0], "crank"), ("B", "A", [0.3, 0, 0], "coupler"), ("D", 0, [1.0, 0, 0], "rocker")):
        joints[name] = chain.addJoint(joints.get(parent, 0), pin.JointModelRZ(), pin.SE3(np.eye(3), np.array(at, dtype=float)), name)
        mass, center, (xx, yy, zz, xy, xz, yz) = FOUR_BAR_MASSES[body]
        tensor = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        chain.appendBodyToJoint(joints[name], pin.Inertia(mass, np.array(center), tensor), pin.SE3.Identity())
    closure = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, chain, joints["B"], pin.SE3(np.eye(3), np.array([0.9, 0.0, 0.0])),
                                       joints["D"], pin.SE3(np.eye(3), np.array([0.7, 0.0, 0.0])), pin.ReferenceFrame.LOCAL)  # fmt: skip

    def angle(body: str) -> np.ndarray:
        rotation = kinematics.rotation_matrix(results, body)
        return np.unwrap(np.arctan2(rotation[:, 1, 0], rotation[:, 0, 0]))

    crank, coupler, rocker = (np.column_stack([angle(b), kinematics.omega(results, b)[:, 2], kinematics.omega_dot(results, b)[:, 2]]) for b in FOUR_BAR_MASSES)
    relative = coupler - crank  # joint B turns the coupler relative to the crank
    q, v, a = (np.column_stack([crank[:, i], relative[:, i], rocker[:, i]]) for i in range(3))
    found = closed_loop_accelerations(chain, closure, q, v, np.column_stack([torque, np.zeros((len(q), 2))]))
    np.testing.assert_allclose(found, a, rtol=0, atol=1e-9 * np.abs(a).max())
    assert np.abs(torque).max() > 1.0  # N m: gravity and inertia both load the crank


LIFTED_BOOM = """\
# a boom lifted by a hydraulic cylinder, the excavator's cylinder joints (universal base, prismatic
# barrel-rod, spherical eye): a closed loop whose element is a cylinder, not a driver
model: lifted_boom
ground:
  points: {A: [0, 0, 0], B: [0.5, 0, -0.8]}
  vectors: {y: [0, 1, 0]}
bodies:
  boom:
    position: [0, 0, 0]
    mass: 500
    center_of_mass: [1.4, 0, 0.1]
    inertia: [30, 400, 410, 0, 10, 0]
    points: {A: [0, 0, 0], C: [1.2, 0, -0.15]}
    vectors: {y: [0, 1, 0]}
  barrel:
    position: [0.5, 0, -0.8]
    orientation: {axis: [0, 1, 0], angle: -0.748378}
    mass: 60
    center_of_mass: [0.3, 0, 0]
    inertia: [0.5, 4, 4]
    points: {base: [0, 0, 0]}
    vectors: {x: [1, 0, 0], n: [0, 0, 1]}
  rod:
    position: [1.2, 0, -0.15]
    orientation: {axis: [0, 1, 0], angle: -0.748378}
    mass: 40
    center_of_mass: [-0.3, 0, 0.01]
    inertia: [0.3, 3, 3]
    points: {eye: [0, 0, 0]}
    vectors: {x: [1, 0, 0]}
joints:
  foot: {type: revolute, bodies: [ground, boom], points: [A, A], axes: [y, y]}
  base: {type: universal, bodies: [ground, barrel], points: [B, base], axes: [y, n]}
  slide: {type: prismatic, bodies: [barrel, rod], points: [base, eye], axes: [x, x]}
  eye: {type: spherical, bodies: [rod, boom], points: [eye, C]}
actuators:
  lift: {points: [barrel.base, rod.eye], hydraulics: {bore: 0.1, rod: 0.07, relief: 30e6, holding: 35e6}}
cases:
  raise:
    drivers:
      lift: {type: distance, points: [barrel.base, rod.eye], function: sqrt(0.9125) + 0.25*t**2 - 0.1*sin(3*t)}
    t0: 0
    t1: 1.5
    steps: 61
"""


@pytest.mark.parametrize("parametrization", ["quaternion", "euler-parameters"])
def test_a_cylinders_force_drives_pinocchios_closed_loop(tmp_path_factory, parametrization):
    """The cylinder's force from kinegen's inverse dynamics (its element row of Φ_qᵀλ = Q_inertia, the
    bodies' weight and inertia) applied at the prismatic joint of Pinocchio's tree (boom about y at A;
    barrel about y at B, the rod sliding along it) closed by a point constraint at the eye: Pinocchio's
    constrained forward dynamics gives back kinegen's accelerations to 1e-9 of the largest."""
    path = tmp_path_factory.mktemp("lifted_boom") / "lifted_boom.yaml"
    path.write_text(LIFTED_BOOM)
    model, results = _solved(tmp_path_factory, path, parametrization)
    held = forces(results, model, [], inertia=True)
    push = held.element_force("lift")  # N, positive pushing the cylinder's points apart

    chain = pin.Model()
    chain.gravity = pin.Motion(np.r_[0.0, 0.0, -9.80665, 0.0, 0.0, 0.0])
    joints = {}
    bodies = {b.name: b for b in model.bodies}
    for name, parent, joint, at in (("boom", 0, pin.JointModelRY(), [0.0, 0, 0]), ("barrel", 0, pin.JointModelRY(), [0.5, 0, -0.8]),
                                    ("rod", "barrel", pin.JointModelPX(), [0.0, 0, 0])):  # fmt: skip
        joints[name] = chain.addJoint(joints.get(parent, 0), joint, pin.SE3(np.eye(3), np.array(at)), name)
        inertia = bodies[name].inertia
        chain.appendBodyToJoint(joints[name], pin.Inertia(float(inertia.mass), _floats(inertia.center), np.array(inertia.tensor.evalf(), dtype=float)),
                                pin.SE3.Identity())  # fmt: skip
    closure = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, chain, joints["rod"], pin.SE3.Identity(), joints["boom"],
                                       pin.SE3(np.eye(3), np.array([1.2, 0.0, -0.15])), pin.ReferenceFrame.LOCAL)  # fmt: skip

    def about_y(body: str) -> np.ndarray:  # angle, rate and its rate about +y (each body turns about y alone)
        rotation = kinematics.rotation_matrix(results, body)
        return np.column_stack([np.unwrap(np.arctan2(rotation[:, 0, 2], rotation[:, 0, 0])), kinematics.omega(results, body)[:, 1], kinematics.omega_dot(results, body)[:, 1]])

    length = np.column_stack([kinematics.actuator_length(results, "lift"), kinematics.actuator_rate(results, "lift"), kinematics.actuator_acceleration(results, "lift")])
    boom, barrel = about_y("boom"), about_y("barrel")
    q, v, a = (np.column_stack([boom[:, i], barrel[:, i], length[:, i]]) for i in range(3))
    found = closed_loop_accelerations(chain, closure, q, v, np.column_stack([np.zeros((len(q), 2)), push]))
    for i, scale in enumerate(np.abs(a).max(axis=0)):  # rad/s^2, rad/s^2, m/s^2: each to its own scale
        np.testing.assert_allclose(found[:, i], a[:, i], rtol=0, atol=1e-9 * scale, err_msg=f"coordinate {i}")
    assert push.min() > 1e3  # N: the cylinder holds the boom up


def test_the_excavators_cylinder_forces_equal_pinocchios_closed_loop_inverse_dynamics():
    """The whole excavator with its estimated masses along the digging cycle at speed: Pinocchio's
    model of it as a tree (every revolute joint; each cylinder's base universal as a revolute about
    its parent's pin axis, its barrel-rod prismatic; the bucket link hung from the bucket at K) closed
    by point constraints at the cylinders' eyes and the link pin J. From kinegen's motion, Pinocchio's
    M a + b(q, v) = S τ + Jᵀ λ, solved for the actuated forces τ (swing motor, boom, arm and bucket
    cylinders; the two boom cylinders push with one force, parallel on one circuit) and the constraint
    forces λ (least squares: the planar loops make J rank-deficient, τ stays unique), equals kinegen's
    swing torque and cylinder forces to 1e-9 of each."""
    excavator = model("excavator")
    results = solve(generated_system("excavator_quaternion", "digging"), np.linspace(0, 17, 35))
    held = forces(results, excavator, [], inertia=True)
    nominal = {d.name: float(d.nominal) for d in excavator.design}
    bodies = {b.name: b for b in excavator.bodies}
    count = len(results.times)

    def vector(values) -> np.ndarray:
        return np.array([design_value(x, nominal) for x in values])

    start = {GROUND: np.eye(3), **{name: kinematics.rotation_matrix(results, name)[0] for name in bodies}}  # Pinocchio's zero: the solved start

    edges = []  # (parent, child, revolute?, the joint's point on the parent, its axis, the body that axis is given on)
    for j in excavator.joints:
        if j.type == "revolute":
            edges.append((j.body1, j.body2, True, j.point1, j.axis2, j.body2))
        elif j.type == "universal" and j.body1 != "bucket_link":  # a cylinder's base: about the parent's pin axis
            edges.append((j.body1, j.body2, True, j.point1, j.axis1, j.body1))
        elif j.type == "universal":  # link_K: the bucket link hung from the bucket, about the bucket's pin axis
            edges.append((j.body2, j.body1, True, j.point2, j.axis2, j.body2))
        elif j.type == "prismatic":
            edges.append((j.body1, j.body2, False, None, j.axis1, j.body1))
    chain = pin.Model()
    chain.gravity = pin.Motion(np.r_[vector(excavator.gravity), 0.0, 0.0, 0.0])
    ids, placed = {GROUND: 0}, []
    while len(placed) < len(edges):
        for parent, child, revolute, point, axis, on in edges:
            if parent not in ids or child in ids:
                continue
            at_zero = start[parent].T @ start[child]  # joint frames = body frames at the solved start
            local_axis = start[child].T @ start[on] @ vector(axis)
            local_axis /= np.linalg.norm(local_axis)
            joint = pin.JointModelRevoluteUnaligned(local_axis) if revolute else pin.JointModelPrismaticUnaligned(local_axis)
            ids[child] = chain.addJoint(ids[parent], joint, pin.SE3(at_zero, np.zeros(3) if point is None else vector(point)), child)
            mass, center, tensor = nominal_inertia("excavator", bodies[child])
            chain.appendBodyToJoint(ids[child], pin.Inertia(mass, center, tensor), pin.SE3.Identity())
            placed.append((parent, child, revolute, local_axis))
    pairs = []  # the closures' two frames: the spherical joints' points on either body
    for j in excavator.joints:
        if j.type == "spherical":
            pairs.append([chain.addFrame(pin.Frame(f"{j.name}.{i}", ids[b], 0, pin.SE3(np.eye(3), vector(p)), pin.FrameType.OP_FRAME))
                          for i, (b, p) in enumerate(((j.body1, j.point1), (j.body2, j.point2)))])  # fmt: skip
    data = chain.createData()

    q, v, a = (np.zeros((count, chain.nv)) for _ in range(3))
    rods = {act.points[1].body: act.name for act in excavator.actuators}
    revolutes = [(None, parent, child, local_axis) for parent, child, revolute, local_axis in placed if revolute]
    angles, rates, accelerations = joint_motion(excavator, results, revolutes, start)
    turned = {child: (angles[:, n], rates[:, n], accelerations[:, n]) for n, (_, _, child, _) in enumerate(revolutes)}
    actuated = {}  # velocity index -> kinegen's force there
    for _, child, revolute, _ in placed:
        i = chain.joints[ids[child]].idx_v
        if revolute:  # the angle from the start about the axis, its rate and acceleration
            q[:, i], v[:, i], a[:, i] = turned[child]
        else:  # the rod slides out of its barrel by the cylinder's length
            name = rods[child]
            q[:, i], v[:, i], a[:, i] = kinematics.actuator_length(results, name), kinematics.actuator_rate(results, name), kinematics.actuator_acceleration(results, name)
        element = "swing_motor" if child == "upper" else excavator.lead(rods[child]) if child in rods else None
        if element in [e.name for e in held.elements]:  # the two boom cylinders: one element, one force, two joints
            actuated.setdefault(element, []).append(i)
    assert len(actuated) == 4 and len(actuated["boom_cylinder_left"]) == 2
    columns = list(actuated)
    select = np.zeros((chain.nv, len(columns)))
    for c, name in enumerate(columns):
        select[actuated[name], c] = 1.0
    found = np.empty((count, len(columns)))
    for k in range(count):
        demand = pin.rnea(chain, data, q[k], v[k], a[k])  # M a + b
        pin.computeJointJacobians(chain, data, q[k])
        pin.updateFramePlacements(chain, data)
        jacobian = np.vstack([pin.getFrameJacobian(chain, data, f1, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
                              - pin.getFrameJacobian(chain, data, f2, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3] for f1, f2 in pairs])  # fmt: skip
        system = np.hstack([select, jacobian.T])
        solution = np.linalg.lstsq(system, demand, rcond=1e-12)[0]
        assert np.abs(system @ solution - demand).max() < 1e-9 * np.abs(demand).max()  # kinegen's motion is one Pinocchio can make
        unloaded = scipy.linalg.null_space(system)
        assert np.abs(unloaded[: len(columns)]).max() < 1e-9  # the actuated forces are unique
        found[k] = solution[: len(columns)]
    for c, name in enumerate(columns):
        expected = held.element_force(name)
        np.testing.assert_allclose(found[:, c], expected, rtol=0, atol=1e-9 * np.abs(expected).max(), err_msg=name)
