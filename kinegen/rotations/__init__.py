"""Orientation parametrizations, one module each; :func:`get` picks one by name."""

from __future__ import annotations

from kinegen.rotations.base import Parametrization
from kinegen.rotations.dual_quaternion import DualEulerParameters, DualQuaternion
from kinegen.rotations.euler_angles import SEQUENCES, EulerAngles
from kinegen.rotations.euler_parameters import EulerParameters
from kinegen.rotations.quaternion import Quaternion

NAMES = ("quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters", *(f"euler:{s}" for s in SEQUENCES))
#: The reference parametrization, regular for every orientation: a configuration is solved in it and
#: converted where another one (possibly singular there) is inspected, classified or compared.
REFERENCE = "quaternion"


def get(name: str) -> Parametrization:
    """The parametrization called ``name`` (``quaternion``, ``euler-parameters``,
    ``dual-quaternion``, ``dual-euler-parameters``, ``euler:<seq>``)."""
    key = name.strip().lower()
    if key == "quaternion":
        return Quaternion()
    if key in ("euler-parameters", "euler_parameters"):
        return EulerParameters()
    if key in ("dual-quaternion", "dual_quaternion"):
        return DualQuaternion()
    if key in ("dual-euler-parameters", "dual_euler_parameters"):
        return DualEulerParameters()
    if key.startswith("euler:") or key.startswith("euler_"):
        return EulerAngles(key[6:])
    raise ValueError(f"unknown parametrization {name!r}; use quaternion, euler-parameters, dual-quaternion, dual-euler-parameters or euler:<seq>")


__all__ = ["NAMES", "Parametrization", "get"]
