"""The interface every orientation parametrization implements.

A body's *stored* coordinates are ``s = [r, o]`` (position ``r``, 3 values, then the
orientation values ``o``). Its *velocity* coordinates ``v`` are what the Jacobian's
columns, the Newton step and the velocity/acceleration solves use. They coincide for
Euler angles and Euler parameters; for the ``quaternion`` parametrization ``o`` is a unit
quaternion and ``v`` holds global rotation increments / the angular velocity.
The two are linked by ``ds/dt = B(s) v`` (the *velocity map*).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
import sympy as sp


class Parametrization(ABC):
    """One orientation parametrization (see the module docstring for the terms)."""

    #: Name as used on the command line, e.g. ``quaternion`` or ``euler:zxz``.
    name: str
    #: Names of the stored orientation values of one body.
    stored_names: tuple[str, ...]
    #: Names of the orientation velocity coordinates of one body.
    velocity_names: tuple[str, ...]
    #: True when the stored orientation values are a unit quaternion (w, x, y, z)
    stores_quaternion: bool = False

    @property
    def file_tag(self) -> str:
        """The name as used in generated file names (``euler:zxz`` -> ``euler_zxz``)."""
        return self.name.replace(":", "_").replace("-", "_")

    # ---- symbolic -------------------------------------------------------------------
    @abstractmethod
    def matrix(self, o: sp.Matrix) -> sp.Matrix:
        """Rotation matrix A(o) (body -> global) for the stored orientation symbols ``o``."""

    def velocity_map(self, o: sp.Matrix) -> sp.Matrix:
        """B(o) with ``do/dt = B(o) w`` (identity unless overridden)."""
        return sp.eye(len(self.stored_names))

    def rotation_derivatives(self, a: sp.Matrix, o: sp.Matrix) -> list[sp.Matrix]:
        """dA/dw for each orientation velocity coordinate w.

        ``a`` is the rotation matrix as a matrix of symbols, ``o`` the stored orientation
        symbols; the result may use either. Default: dA(o)/do_k (velocity = stored rates).
        """
        matrix = self.matrix(o)
        return [matrix.diff(x) for x in o]

    def normalization(self, o: sp.Matrix) -> list[sp.Expr]:
        """Extra constraints a body of this parametrization carries (none by default)."""
        return []

    # ---- numeric --------------------------------------------------------------------
    @abstractmethod
    def from_matrix(self, rotation: np.ndarray) -> np.ndarray:
        """Stored orientation values for a rotation matrix."""

    @abstractmethod
    def to_matrix(self, o: np.ndarray) -> np.ndarray:
        """Rotation matrix of stored orientation values ``o`` (shape (k,) or (K, k))."""

    @abstractmethod
    def omega(self, o: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Global angular velocity from stored values ``o`` and velocity coordinates ``w``."""

    @abstractmethod
    def omega_dot(self, o: np.ndarray, w: np.ndarray, w_dot: np.ndarray) -> np.ndarray:
        """Global angular acceleration from ``o``, ``w`` and their derivative ``w_dot``."""

    def retract(self, o: np.ndarray, step: np.ndarray) -> np.ndarray:
        """Apply a Newton step / increment in velocity coordinates to stored values."""
        return o + step
