"""The interface every orientation parametrization implements.

A parametrization owns the layout of one body's coordinates, as Pinocchio's model owns
``nq``/``nv`` and ``integrate``: every body of a model has ``nq`` *stored* coordinates and
``nv`` *velocity* coordinates, body after body (body b at ``b * nq`` in q and ``b * nv`` in
v), and only this package knows what they are. Velocity coordinates are what the Jacobian's
columns, the Newton step and the velocity/acceleration solves use; a Newton step or a
predicted motion is applied by :meth:`Parametrization.retraction`, written once symbolically
(printed into the generated C; :meth:`Parametrization.retract` is its NumPy form, held to it by
the tests); results read poses, velocities and
accelerations through :meth:`pose`, :meth:`frame_velocity` and :meth:`frame_acceleration`.

The parametrizations here store ``s = [r, o]`` (position ``r``, 3 values, then the
orientation values ``o``) with velocity ``[r', w]``. ``w`` is ``o'`` for Euler angles and
Euler parameters; for the ``quaternion`` parametrization ``o`` is a unit quaternion and
``w`` holds global rotation increments / the angular velocity. The two are linked by
``ds/dt = B(s) v`` (the *velocity map*).

Array conventions: :meth:`retract` and :meth:`project` take components first (``(nq, ...)``,
any batch shape after them, as the solvers hold q); the pose accessors take components last
(``(..., nq)``, as results hold time histories).
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
    #: True when a body's pose is one dual quaternion: the joints are then written with lines
    #: (dual vectors) and relative poses (``kinegen.constraints.joints``)
    unified: bool = False
    #: Where the parametrization itself makes Phi_q singular (what `kinegen compare` prints)
    singular_set: str = "not stated"

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

    def omega_expression(self, o: sp.Matrix, w: sp.Matrix) -> sp.Matrix:
        """Global angular velocity (3x1) of stored orientation symbols ``o`` and orientation
        velocity symbols ``w`` (the symbolic twin of :meth:`omega`)."""
        raise NotImplementedError

    def omega_dot_expression(self, o: sp.Matrix, w: sp.Matrix, w_dot: sp.Matrix) -> sp.Matrix:
        """Global angular acceleration (3x1), the symbolic twin of :meth:`omega_dot`."""
        raise NotImplementedError

    def frame_expressions(self, q: sp.Matrix, v: sp.Matrix, a: sp.Matrix) -> list[sp.Expr]:
        """A body's frame as expressions of its stored ``q``, velocity ``v`` and acceleration
        ``a`` symbols: origin (3), rotation matrix (9, row by row), origin velocity (3), angular
        velocity (3), origin acceleration (3), angular acceleration (3) -- 24 values, all global."""
        o, w, w_dot = q[3:, :], v[3:, :], a[3:, :]
        return [
            *q[:3], *self.matrix(o), *v[:3], *self.omega_expression(o, w), *a[:3], *self.omega_dot_expression(o, w, w_dot)
        ]

    def normalization(self, o: sp.Matrix) -> list[sp.Expr]:
        """Extra constraints a body of this parametrization carries (none by default)."""
        return []

    # ---- a body's symbols (the symbolic side of the layout) -----------------------------
    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """Names of a body's ``nq`` stored coordinates (default: x, y, z, then the orientation's)."""
        return ("x", "y", "z", *self.stored_names)

    @property
    def velocity_coordinate_names(self) -> tuple[str, ...]:
        """Names of a body's ``nv`` velocity coordinates (default: x, y, z, then the orientation's)."""
        return ("x", "y", "z", *self.velocity_names)

    def body_velocity_map(self, s: sp.Matrix) -> sp.Matrix:
        """B(s) (nq x nv) with ``ds/dt = B(s) v`` for a body's stored symbols ``s``."""
        return sp.diag(sp.eye(3), self.velocity_map(s[3:, :]))

    def body_rotation(self, s: sp.Matrix) -> sp.Matrix:
        """The body's rotation matrix A(s) (body -> global)."""
        return self.matrix(s[3:, :])

    def body_rotation_derivatives(self, a: sp.Matrix, s: sp.Matrix) -> list[sp.Matrix]:
        """dA/dv_k for each of the ``nv`` velocity coordinates (``a``: A as symbols)."""
        return [sp.zeros(3, 3)] * 3 + list(self.rotation_derivatives(a, s[3:, :]))

    def body_origin(self, s: sp.Matrix) -> sp.Matrix:
        """The frame origin (3x1) as an expression of the stored symbols."""
        return s[:3, :]

    def body_origin_derivatives(self, r: sp.Matrix, s: sp.Matrix) -> list[sp.Matrix] | None:
        """dr/dv_k (3x1) for each velocity coordinate, where the origin is not stored (``r``:
        the origin as symbols); None (default) when the origin is among the stored coordinates."""
        return None

    def body_quaternion(self, s: sp.Matrix) -> sp.Matrix | None:
        """The unit quaternion (w, x, y, z) of the rotation among the stored symbols, if stored."""
        return s[3:, :] if self.stores_quaternion else None

    def pose_substitution(self, s: sp.Matrix, origin: sp.Matrix) -> dict[sp.Symbol, sp.Expr]:
        """Stored symbols that are functions of the pose, as expressions of the origin symbols
        ``origin`` and the others (none by default): inspection factors determinants on the
        set of valid poses with them."""
        return {}

    def body_normalization(self, s: sp.Matrix) -> list[sp.Expr]:
        """Extra constraints on one body's stored symbols ``s``."""
        return self.normalization(s[3:, :])

    # ---- body layout ------------------------------------------------------------------
    @property
    def nq(self) -> int:
        """Stored coordinates per body."""
        return len(self.coordinate_names)

    @property
    def nv(self) -> int:
        """Velocity coordinates per body."""
        return len(self.velocity_coordinate_names)

    @property
    def additive(self) -> bool:
        """True when the update of a step is plain addition (:meth:`retraction` not overridden):
        the runtime then adds whole vectors at once."""
        return type(self).retraction is Parametrization.retraction

    def retraction(self, q: sp.Matrix, step: sp.Matrix) -> list[sp.Expr]:
        """One body's stored coordinates ``q`` (nq symbols) moved by ``step`` (nv symbols, velocity
        coordinates), symbolically: the one definition of a Newton step's update, which the C
        backend prints (``retract_body``) and :meth:`retract` evaluates. Added, unless the
        parametrization says otherwise (a branch for small steps as ``sp.Piecewise``)."""
        return list(q + step)

    def retract(self, q: np.ndarray, step: np.ndarray) -> np.ndarray:
        """A body's stored coordinates ``q`` (nq, ...) moved by ``step`` (nv, ...) in velocity
        coordinates, in NumPy: what :meth:`retraction` defines (positions added, the orientation
        by :meth:`retract_orientation`), written out for speed -- a Newton step in Python calls it
        once for all bodies; the tests hold it to :meth:`retraction` evaluated by SymPy."""
        if self.additive:
            return q + step
        out = np.array(q, dtype=float, copy=True)
        out[:3] += step[:3]
        out[3:] = self.retract_orientation(q[3:], step[3:])
        return out

    def retract_orientation(self, o: np.ndarray, step: np.ndarray) -> np.ndarray:
        """Orientation values (components first) moved by an increment of the orientation
        velocity coordinates, as :meth:`retraction` says (added, unless overridden)."""
        return o + step

    def project(self, q: np.ndarray) -> np.ndarray:
        """Stored coordinates (nq, ...) that interpolation may have moved off the set of valid
        values, moved back onto it (e.g. a quaternion normalized); unchanged by default."""
        return q

    def pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frame origin (..., 3) and rotation matrix (..., 3, 3) of stored coordinates (..., nq)."""
        return q[..., :3], self.to_matrix(q[..., 3:])

    def frame_velocity(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocity of the frame origin and global angular velocity (..., 3) each."""
        return v[..., :3], self.omega(q[..., 3:], v[..., 3:])

    def frame_acceleration(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Acceleration of the frame origin and global angular acceleration (..., 3) each."""
        return a[..., :3], self.omega_dot(q[..., 3:], v[..., 3:], a[..., 3:])

    def from_pose(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """Stored coordinates (nq,) of a frame at ``position`` with rotation matrix ``rotation``."""
        return np.concatenate([np.asarray(position, dtype=float), self.from_matrix(rotation)])

    # ---- numeric orientation ------------------------------------------------------------
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

