"""Orientation parametrizations, one module each, registered here: :data:`REGISTRY` is the one
list (the CLI's choices and help, ``kinegen info`` and ``kinegen compare`` read it);
:func:`get` picks one by name.

The registry names the modules without importing them (they import SymPy, which a command's
start-up should not pay for): a parametrization's module is imported when one is made."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinegen.rotations.base import Parametrization

#: the twelve intrinsic Euler-angle sequences (Tait-Bryan and proper)
SEQUENCES = tuple(a + b + c for a in "xyz" for b in "xyz" for c in "xyz" if a != b and b != c)


def _class(module: str, name: str) -> Callable[..., Parametrization]:
    """The parametrization class ``name`` of ``kinegen.rotations.<module>``, imported when called."""

    def make(*args: Any) -> Parametrization:
        return getattr(importlib.import_module(f"kinegen.rotations.{module}"), name)(*args)

    return make


Quaternion = _class("quaternion", "Quaternion")
EulerParameters = _class("euler_parameters", "EulerParameters")
DualQuaternion = _class("dual_quaternion", "DualQuaternion")
DualEulerParameters = _class("dual_quaternion", "DualEulerParameters")
EulerAngles = _class("euler_angles", "EulerAngles")


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




def __getattr__(name: str) -> Any:
    """``Parametrization`` (the base class), imported when first asked for."""
    if name == "Parametrization":
        from kinegen.rotations.base import Parametrization

        return Parametrization
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["NAMES", "REFERENCE", "REGISTRY", "SEQUENCES", "SHOWN", "Parametrization", "get"]
