"""What the machine can do where it goes: the forces that hold a load (:mod:`kinegen.forces.statics`)."""

from kinegen.forces.statics import Forces, forces

__all__ = ["Forces", "forces"]
