"""Intrinsic Euler angles, any of the 12 sequences (``zxz``, ``zyx``, ...).

``euler:abc`` means ``A = R_a(alpha) R_b(beta) R_c(gamma)``: rotate about body axis ``a``,
then about the new ``b``, then about the newest ``c``; SciPy writes this
``Rotation.from_euler("ABC", [alpha, beta, gamma])`` (upper case = intrinsic).
The velocity coordinates are the angle rates themselves.
"""

from __future__ import annotations

import warnings

import numpy as np
import sympy as sp

from kinegen.rotations import SEQUENCES
from kinegen.rotations.base import Parametrization

_AXIS = {"x": 0, "y": 1, "z": 2}


def _elementary(axis: int, angle: sp.Expr) -> sp.Matrix:
    return {0: sp.rot_axis1, 1: sp.rot_axis2, 2: sp.rot_axis3}[axis](angle).T


def _elementary_numeric(axis: int, angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.zeros(np.shape(angle) + (3, 3))
    m[..., axis, axis] = 1.0
    m[..., i, i], m[..., i, j], m[..., j, i], m[..., j, j] = c, -s, s, c
    return m


class EulerAngles(Parametrization):
    """Intrinsic Euler angles (alpha, beta, gamma) for one of the 12 sequences."""

    stored_names = ("alpha", "beta", "gamma")
    velocity_names = ("alpha", "beta", "gamma")

    def __init__(self, sequence: str) -> None:
        sequence = sequence.lower()
        if sequence not in SEQUENCES:
            raise ValueError(f"unknown Euler sequence {sequence!r}; use one of {', '.join(SEQUENCES)}")
        self.sequence = sequence
        self.axes = tuple(_AXIS[c] for c in sequence)
        self.name = f"euler:{sequence}"
        proper = sequence[0] == sequence[2]  # e.g. zxz: beta = 0 or pi; Tait-Bryan e.g. zxy: beta = +-pi/2
        self.singular_set = (
            f"where beta = 0 or pi: the first and third axes ({sequence[0]}) align (a body's {sequence[0]} axis parallel to global {sequence[0]})"
            if proper
            else f"where beta = +-pi/2: the first ({sequence[0]}) and third ({sequence[2]}) axes align (gimbal lock)"
        )

    def matrix(self, o: sp.Matrix) -> sp.Matrix:
        a, b, c = self.axes
        return _elementary(a, o[0]) * _elementary(b, o[1]) * _elementary(c, o[2])

    def from_matrix(self, rotation: np.ndarray) -> np.ndarray:
        from scipy.spatial.transform import Rotation

        with warnings.catch_warnings():  # gimbal lock: SciPy sets the third angle to 0
            warnings.simplefilter("ignore", UserWarning)
            return Rotation.from_matrix(rotation).as_euler(self.sequence.upper())

    def to_matrix(self, o: np.ndarray) -> np.ndarray:
        a, b, c = self.axes
        return _elementary_numeric(a, o[..., 0]) @ _elementary_numeric(b, o[..., 1]) @ _elementary_numeric(c, o[..., 2])

    def _global_axes(self, o: np.ndarray) -> list[np.ndarray]:
        a, b, c = self.axes
        r1 = _elementary_numeric(a, o[..., 0])
        r12 = r1 @ _elementary_numeric(b, o[..., 1])
        unit = np.eye(3)
        return [np.broadcast_to(unit[a], np.shape(o)[:-1] + (3,)), r1[..., :, b], r12[..., :, c]]

    def _global_axes_expression(self, o: sp.Matrix) -> list[sp.Matrix]:
        a, b, c = self.axes
        r1 = _elementary(a, o[0])
        r12 = r1 * _elementary(b, o[1])
        unit = sp.eye(3)
        return [unit[:, a], r1[:, b], r12[:, c]]

    def omega_expression(self, o: sp.Matrix, w: sp.Matrix) -> sp.Matrix:
        k1, k2, k3 = self._global_axes_expression(o)
        return k1 * w[0] + k2 * w[1] + k3 * w[2]

    def omega_dot_expression(self, o: sp.Matrix, w: sp.Matrix, w_dot: sp.Matrix) -> sp.Matrix:
        k1, k2, k3 = self._global_axes_expression(o)
        w1, w2 = k1 * w[0], k2 * w[1]
        return k1 * w_dot[0] + k2 * w_dot[1] + k3 * w_dot[2] + w1.cross(k2) * w[1] + (w1 + w2).cross(k3) * w[2]

    def omega(self, o: np.ndarray, w: np.ndarray) -> np.ndarray:
        k1, k2, k3 = self._global_axes(o)
        return k1 * w[..., 0:1] + k2 * w[..., 1:2] + k3 * w[..., 2:3]

    def omega_dot(self, o: np.ndarray, w: np.ndarray, w_dot: np.ndarray) -> np.ndarray:
        k1, k2, k3 = self._global_axes(o)
        w1 = k1 * w[..., 0:1]
        w2 = k2 * w[..., 1:2]
        return (
            k1 * w_dot[..., 0:1]
            + k2 * w_dot[..., 1:2]
            + k3 * w_dot[..., 2:3]
            + np.cross(w1, k2) * w[..., 1:2]
            + np.cross(w1 + w2, k3) * w[..., 2:3]
        )
