"""Unit quaternion with rotation increments (the paper's formulation, eq. 19).

The stored orientation is a unit quaternion ``(qw, qx, qy, qz)``. Velocity coordinates
are ``(theta_x, theta_y, theta_z)``: a small rotation about the *global* axes, so the
Jacobian column of ``theta`` is ``dPhi/dtheta`` with ``A -> exp([theta]x) A``, the
velocity is the global angular velocity ``omega`` and the acceleration ``omega_dot``.
A Newton step updates the quaternion by the exponential map ``q <- exp(theta) ⊗ q``, which
keeps it unit to rounding; it is never renormalized.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

import kinegen.rotations.quaternion_algebra as qa
from kinegen.rotations.base import Parametrization
from kinegen.rotations.euler_parameters import quaternion_matrix


class Quaternion(Parametrization):
    """Stored unit quaternion, tangent-space (global rotation increment) velocity coordinates."""

    name = "quaternion"
    stored_names = ("qw", "qx", "qy", "qz")
    stores_quaternion = True
    velocity_names = ("theta_x", "theta_y", "theta_z")
    singular_set = "nowhere: rotation increments span every rotation; Phi_q is singular only where the mechanism is"

    def matrix(self, o: sp.Matrix) -> sp.Matrix:
        return quaternion_matrix(o)

    def velocity_map(self, o: sp.Matrix) -> sp.Matrix:
        # dq/dt = 1/2 [0, omega] ⊗ q = 1/2 [[-v^T], [w I - [v]x]] omega
        return sp.Rational(1, 2) * qa.left_pure(o)

    def rotation_derivatives(self, a: sp.Matrix, o: sp.Matrix) -> list[sp.Matrix]:
        # A -> exp([theta]x) A: dA/dtheta_k = [e_k]x A, linear in the entries of A
        return qa.spin_derivatives(a)

    def omega_expression(self, o: sp.Matrix, w: sp.Matrix) -> sp.Matrix:
        return sp.Matrix(w)

    def omega_dot_expression(self, o: sp.Matrix, w: sp.Matrix, w_dot: sp.Matrix) -> sp.Matrix:
        return sp.Matrix(w_dot)

    def from_matrix(self, rotation: np.ndarray) -> np.ndarray:
        return qa.from_matrix(rotation)

    def to_matrix(self, o: np.ndarray) -> np.ndarray:
        return qa.to_matrix(o)

    def omega(self, o: np.ndarray, w: np.ndarray) -> np.ndarray:
        return np.asarray(w, dtype=float)

    def omega_dot(self, o: np.ndarray, w: np.ndarray, w_dot: np.ndarray) -> np.ndarray:
        return np.asarray(w_dot, dtype=float)

    def retract_orientation(self, o: np.ndarray, step: np.ndarray) -> np.ndarray:
        # exp(theta/2) ⊗ q: stays unit to rounding, never renormalized
        return qa.increment(step, o)

    def retraction(self, q: sp.Matrix, step: sp.Matrix) -> list[sp.Expr]:
        # positions added; q <- exp(theta/2) ⊗ q, which stays unit to rounding (never renormalized)
        return [*(q[k] + step[k] for k in range(3)), *qa.symbolic_increment(step[3:, :], q[3:, :])]

    def project(self, q: np.ndarray) -> np.ndarray:
        out = np.array(q, dtype=float, copy=True)
        out[3:] /= np.linalg.norm(out[3:], axis=0)
        return out

