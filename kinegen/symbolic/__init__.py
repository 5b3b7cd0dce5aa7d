"""Exact symbolic assembly of Phi, sparse Phi_q, nu and gamma.

The assembly's names are imported when first used: the runtime reads :mod:`kinegen.symbolic.blocks`
(NumPy and SciPy only) without loading SymPy with the rest of this package.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from kinegen.symbolic.assembly import Coordinates, Row, System, build_systems, coordinates

__all__ = ["Coordinates", "Row", "System", "build_systems", "coordinates"]


def __getattr__(name: str) -> object:
    if name in __all__:
        from kinegen.symbolic import assembly

        return getattr(assembly, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
