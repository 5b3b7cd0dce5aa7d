"""Every joint and driver type against closed-form motion (in-memory lambdify path).

The 'gadget' has four independent sub-mechanisms:
* screw: cylindrical joint on global z, driven by joint_angle phi(t) and joint_translation s(t);
* cap: fixed to the screw (moves rigidly with it);
* slider: prismatic along global x through (0, 1, 0), driven by the coordinate x(t) of its point;
* wheel: revolute about global y through (2, 0, 0), driven by body_angle a(t) about global y.
Count: 4 bodies x 6 = 24 = cylindrical 4 + fixed 6 + prismatic 5 + revolute 5 + 4 drivers.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinegen import rotations
from kinegen.codegen.inmemory import lambdify_model
from kinegen.model import loads
from kinegen.runtime import from_module, kinematics, solve

GADGET = """\
model: gadget
ground:
  points: {O: [0, 0, 0], S: [0, 1, 0], W: [2, 0, 0]}
  vectors: {z: [0, 0, 1], x: [1, 0, 0], y: [0, 1, 0]}
bodies:
  screw:
    position: [0, 0, 0.1]
    points: {O: [0, 0, 0], P: [0.4, 0, 0]}
    vectors: {z: [0, 0, 1]}
  cap:
    position: [0.4, 0, 0.1]
    orientation: {axis: [1, 0, 0], angle: 0.3}
    points: {Q: [0, 0.2, 0]}
  slider:
    position: [0.2, 1, 0]
    points: {C: [0, 0, 0]}
    vectors: {x: [1, 0, 0]}
  wheel:
    position: [2, 0, 0]
    points: {W: [0, 0, 0], R: [0.5, 0, 0]}
    vectors: {y: [0, 1, 0]}
joints:
  barrel: {type: cylindrical, bodies: [ground, screw], points: [O, O], axes: [z, z]}
  weld: {type: fixed, bodies: [screw, cap], at: [0.4, 0, 0.1]}
  rail: {type: prismatic, bodies: [ground, slider], points: [S, C], axes: [x, x]}
  axle: {type: revolute, bodies: [ground, wheel], points: [W, W], axes: [y, y]}
cases:
  all:
    drivers:
      turn: {type: joint_angle, joint: barrel, function: 0.5*t + 0.2*sin(t)}
      lift: {type: joint_translation, joint: barrel, function: 0.1 + 0.3*t**2}
      slide: {type: coordinate, point: slider.C, component: x, function: 0.2 + 0.1*sin(2*t)}
      spin: {type: body_angle, body: wheel, axis: [0, 1, 0], function: t**2}
    t0: 0
    t1: 1
    steps: 51
"""


@pytest.mark.parametrize("param", ["quaternion", "euler-parameters", "euler:xyz", "dual-quaternion", "dual-euler-parameters"])
def test_every_joint_and_driver_follows_its_closed_form(param):
    model = loads(GADGET, "gadget.yaml")
    results = solve(from_module(lambdify_model(model, rotations.get(param))))
    t = results.times
    zero, one = np.zeros_like(t), np.ones_like(t)
    phi, phid, phidd = 0.5 * t + 0.2 * np.sin(t), 0.5 + 0.2 * np.cos(t), -0.2 * np.sin(t)
    s, sd, sdd = 0.1 + 0.3 * t**2, 0.6 * t, 0.6 * one

    # screw: point P = (0.4 cos phi, 0.4 sin phi, s)
    c, si = np.cos(phi), np.sin(phi)
    assert np.abs(kinematics.point_position(results, "screw", "P") - np.c_[0.4 * c, 0.4 * si, s]).max() < 1e-10
    velocity = np.c_[-0.4 * si * phid, 0.4 * c * phid, sd]
    assert np.abs(kinematics.point_velocity(results, "screw", "P") - velocity).max() < 1e-9
    acceleration = np.c_[-0.4 * (si * phidd + c * phid**2), 0.4 * (c * phidd - si * phid**2), sdd]
    assert np.abs(kinematics.point_acceleration(results, "screw", "P") - acceleration).max() < 1e-8
    assert np.abs(kinematics.omega(results, "screw") - np.c_[zero, zero, phid]).max() < 1e-9

    # cap: rigidly welded to the screw
    w = np.array([0.4, 0, 0]) + Rotation.from_rotvec([0.3, 0, 0]).apply([0, 0.2, 0])
    expected = np.c_[zero, zero, s] + Rotation.from_rotvec(np.c_[zero, zero, phi]).apply(w)
    assert np.abs(kinematics.point_position(results, "cap", "Q") - expected).max() < 1e-10
    assert np.abs(kinematics.omega(results, "cap") - kinematics.omega(results, "screw")).max() < 1e-9
    assert np.abs(kinematics.omega_dot(results, "cap") - kinematics.omega_dot(results, "screw")).max() < 1e-8

    # slider: x(t) on the rail, no rotation
    x, xd, xdd = 0.2 + 0.1 * np.sin(2 * t), 0.2 * np.cos(2 * t), -0.4 * np.sin(2 * t)
    assert np.abs(kinematics.point_position(results, "slider", "C") - np.c_[x, one, zero]).max() < 1e-10
    assert np.abs(kinematics.point_velocity(results, "slider", "C") - np.c_[xd, zero, zero]).max() < 1e-9
    assert np.abs(kinematics.point_acceleration(results, "slider", "C") - np.c_[xdd, zero, zero]).max() < 1e-8
    assert np.abs(kinematics.rotation_matrix(results, "slider") - np.eye(3)).max() < 1e-10

    # wheel: absolute rotation a = t^2 about global y, R = W + R_y(a) (0.5, 0, 0)
    a = t**2
    assert np.abs(kinematics.point_position(results, "wheel", "R") - np.c_[2 + 0.5 * np.cos(a), zero, -0.5 * np.sin(a)]).max() < 1e-10
    assert np.abs(kinematics.omega(results, "wheel") - np.c_[zero, 2 * t, zero]).max() < 1e-9
    assert np.abs(kinematics.omega_dot(results, "wheel") - np.c_[zero, 2 * one, zero]).max() < 1e-8
