"""Exact symbolic assembly of Phi, sparse Phi_q, nu and gamma."""

from kinegen.symbolic.assembly import Coordinates, Row, System, build_systems, coordinates

__all__ = ["Coordinates", "Row", "System", "build_systems", "coordinates"]
