"""What the machine can do where it goes: the forces that hold a load (:mod:`kinegen.forces.statics`).

``Forces`` and ``forces`` are imported when first read: the pumps' flows (:mod:`.supply`) need
kinematics only, not the statics' linear algebra."""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from kinegen.forces.statics import Forces, forces


def __getattr__(name: str) -> Any:
    if name in ("Forces", "forces"):
        return getattr(import_module("kinegen.forces.statics"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["Forces", "forces"]
