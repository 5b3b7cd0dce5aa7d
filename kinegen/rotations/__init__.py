"""Orientation parametrizations, one module each, registered here: :data:`REGISTRY` is the one
list (the CLI's choices and help, ``kinegen info`` and ``kinegen compare`` read it);
:func:`get` picks one by name."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from kinegen.rotations.base import Parametrization
from kinegen.rotations.dual_quaternion import DualEulerParameters, DualQuaternion
from kinegen.rotations.euler_angles import SEQUENCES, EulerAngles
from kinegen.rotations.euler_parameters import EulerParameters
from kinegen.rotations.quaternion import Quaternion


@dataclass(frozen=True)
class Registered:
    """A parametrization by name: how to make it, and its other spellings."""

    name: str
    make: Callable[[], Parametrization]
    aliases: tuple[str, ...] = ()


def _euler(sequence: str) -> Callable[[], Parametrization]:
    return lambda: EulerAngles(sequence)


#: every parametrization, by name (the twelve Euler-angle sequences as euler:<seq>)
REGISTRY: dict[str, Registered] = {
    r.name: r
    for r in (
        Registered("quaternion", Quaternion),
        Registered("euler-parameters", EulerParameters, ("euler_parameters",)),
        Registered("dual-quaternion", DualQuaternion, ("dual_quaternion",)),
        Registered("dual-euler-parameters", DualEulerParameters, ("dual_euler_parameters",)),
        *(Registered(f"euler:{s}", _euler(s), (f"euler_{s}",)) for s in SEQUENCES),
    )
}
NAMES = tuple(REGISTRY)
#: what the comparisons (``kinegen info``, ``kinegen compare``) show unless told: the four regular
#: ones, and the Euler angles whose singular set a link's z axis along the global z meets (zxz) or not (zxy)
SHOWN = ("quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters", "euler:zxz", "euler:zxy")
_BY_SPELLING = {spelling: r for r in REGISTRY.values() for spelling in (r.name, *r.aliases)}
#: The reference parametrization, regular for every orientation: a configuration is solved in it and
#: converted where another one (possibly singular there) is inspected, classified or compared.
REFERENCE = "quaternion"


def get(name: str) -> Parametrization:
    """The parametrization called ``name`` (``quaternion``, ``euler-parameters``,
    ``dual-quaternion``, ``dual-euler-parameters``, ``euler:<seq>``; see :data:`REGISTRY`)."""
    key = name.strip().lower()
    if key in _BY_SPELLING:
        return _BY_SPELLING[key].make()
    if key.startswith(("euler:", "euler_")):
        return EulerAngles(key[6:])  # says which sequences exist
    families = [n for n in NAMES if not n.startswith("euler:")] + ["euler:<seq>"]
    raise ValueError(f"unknown parametrization {name!r}; use {', '.join(families[:-1])} or {families[-1]}")


__all__ = ["NAMES", "REFERENCE", "REGISTRY", "SHOWN", "Parametrization", "get"]
