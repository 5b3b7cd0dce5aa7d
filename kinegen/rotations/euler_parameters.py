"""Euler parameters: four values ``e = (e0, e1, e2, e3)`` per body (order w, x, y, z) plus
the normalization constraint ``e·e - 1 = 0``. Velocity coordinates are ``de/dt``.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

import kinegen.rotations.quaternion_algebra as qa
from kinegen.rotations.base import Parametrization


def quaternion_matrix(e: sp.Matrix) -> sp.Matrix:
    """Symbolic rotation matrix of Euler parameters (valid for unit ``e``)."""
    e0, e1, e2, e3 = e
    half = sp.Rational(1, 2)
    return 2 * sp.Matrix(
        [
            [e0**2 + e1**2 - half, e1 * e2 - e0 * e3, e1 * e3 + e0 * e2],
            [e1 * e2 + e0 * e3, e0**2 + e2**2 - half, e2 * e3 - e0 * e1],
            [e1 * e3 - e0 * e2, e2 * e3 + e0 * e1, e0**2 + e3**2 - half],
        ]
    )


def _vector_of_product_with_conjugate(p: sp.Matrix, e: sp.Matrix) -> sp.Matrix:
    """Vector part of p ⊗ conj(e) (Hamilton product, w first), symbolic."""
    return qa.symbolic_product(p, qa.symbolic_conjugate(e))[1:, :]


class EulerParameters(Parametrization):
    """Four Euler parameters per body with a normalization constraint."""

    name = "euler-parameters"
    stored_names = ("e0", "e1", "e2", "e3")
    stores_quaternion = True
    velocity_names = ("e0", "e1", "e2", "e3")
    singular_set = "nowhere on |e| = 1: the normalization row is normal to the unit sphere the rotation rows are tangent to"

    def matrix(self, o: sp.Matrix) -> sp.Matrix:
        return quaternion_matrix(o)

    def omega_expression(self, o: sp.Matrix, w: sp.Matrix) -> sp.Matrix:
        return 2 * _vector_of_product_with_conjugate(w, o)

    def omega_dot_expression(self, o: sp.Matrix, w: sp.Matrix, w_dot: sp.Matrix) -> sp.Matrix:
        return 2 * _vector_of_product_with_conjugate(w_dot, o)

    def normalization(self, o: sp.Matrix) -> list[sp.Expr]:
        return [sum(x**2 for x in o) - 1]

    def project(self, q: np.ndarray) -> np.ndarray:
        out = np.array(q, dtype=float, copy=True)
        out[3:] /= np.linalg.norm(out[3:], axis=0)
        return out

    def from_matrix(self, rotation: np.ndarray) -> np.ndarray:
        return qa.from_matrix(rotation)

    def to_matrix(self, o: np.ndarray) -> np.ndarray:
        return qa.to_matrix(o)

    def omega(self, o: np.ndarray, w: np.ndarray) -> np.ndarray:
        # omega (global) = 2 vec(de/dt ⊗ e*)
        return 2.0 * qa.multiply(w, qa.conjugate(o))[..., 1:]

    def omega_dot(self, o: np.ndarray, w: np.ndarray, w_dot: np.ndarray) -> np.ndarray:
        # d/dt 2 (de ⊗ e*) = 2 (dde ⊗ e*) + 2 (de ⊗ de*), whose second term is a scalar
        return 2.0 * qa.multiply(w_dot, qa.conjugate(o))[..., 1:]
