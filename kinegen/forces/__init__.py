"""What the machine can do where it goes: the forces that hold a load (:mod:`kinegen.forces.statics`).

``Forces`` and ``forces`` are imported when first read: the pumps' flows (:mod:`.supply`) need
kinematics only, not the statics' linear algebra."""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinegen.lazy import exported

if TYPE_CHECKING:
    from kinegen.forces.statics import Forces, forces

__getattr__ = exported(__name__, {"Forces": "kinegen.forces.statics", "forces": "kinegen.forces.statics"})


__all__ = ["Forces", "forces"]
