"""kinegen: mechanism description -> exact symbolic kinematics -> generated solvers.

Conventions used everywhere in kinegen:

* SI units (metres, seconds), angles in radians.
* One global, right-handed frame; every body has a body frame whose pose is its
  origin position ``r`` and rotation matrix ``A`` (body -> global: ``p = r + A s'``).
* Quaternions are ordered ``(w, x, y, z)`` (scalar first).
* Euler sequences are *intrinsic* (rotations about the moving axes), named by three
  letters such as ``zxz``: ``A = R_z(alpha) R_x(beta) R_z(gamma)``, which is SciPy's
  ``Rotation.from_euler("ZXZ", ...)``.
* Angular velocity ``omega`` and acceleration ``omega_dot`` are global vectors.
"""

__version__ = "0.2.0"
