"""The machine's force charts: the work behind ``kinegen forces`` (ISO 6015 tool forces, ``--map``
force maps) and ``kinegen lift`` (the ISO 10567 lift chart). Each needs its section of the model
(``tool_forces:``, ``working_range:``, ``lift_chart:``) and solves on that section's case.
Units: N, m, s; the lift chart's ratings in kg.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinegen import rotations
from kinegen.api import Session
from kinegen.errors import ModelError
from kinegen.service.requests import case_system


def _section(session: Session, model_file: str | Path, section: str, what: str) -> tuple[Any, Any]:
    """The model and its ``section`` (a ModelError naming the section where the model has none)."""
    model = session.model(model_file)
    found = getattr(model, section)
    if found is None:
        raise ModelError(str(model_file), section, f"the model has no {section} section ({what})")
    return model, found


@dataclass(frozen=True)
class ToolForcesReport:
    """The ISO 6015 tool forces by name (:class:`kinegen.forces.iso6015.ToolForceResult`) and the
    wall time of their search [s]."""

    model: Any
    found: dict[str, Any]
    seconds: float


def tool_forces(session: Session, model_file: str | Path, parametrization: str = rotations.REFERENCE,
                compiled: bool | None = None) -> ToolForcesReport:  # fmt: skip
    """The tool forces of the model's ``tool_forces`` section (:func:`kinegen.forces.iso6015.tool_forces`)."""
    from kinegen.forces.iso6015 import tool_forces as search

    model, section = _section(session, model_file, "tool_forces", "what kinegen forces computes")
    _, system = case_system(session, model_file, section.case, parametrization, compiled)
    start = time.perf_counter()
    found = search(system, model)
    return ToolForcesReport(model, found, time.perf_counter() - start)


@dataclass(frozen=True)
class ForceMapReport:
    """A force map over the working range (:class:`kinegen.forces.maps.ForceMap`) and, for its
    picture, the largest force at each place over the tool's attitude
    (:func:`kinegen.forces.maps.reach_map`) with the working range's exact boundary (None unless asked)."""

    model: Any
    system: Any
    direction: str
    found: Any
    smooth: Any = None
    boundary: Any = None


def force_map(session: Session, model_file: str | Path, direction: str, parametrization: str = rotations.REFERENCE,
              compiled: bool | None = None, picture: bool = False) -> ForceMapReport:  # fmt: skip
    """The largest force the tool point can exert in ``direction`` over the working range; with
    ``picture`` also the smooth map over the tool's attitude and the range's boundary."""
    from kinegen.forces.maps import force_map as map_forces

    model, section = _section(session, model_file, "working_range", "a force map covers it")
    _, system = case_system(session, model_file, section.case, parametrization, compiled)
    found = map_forces(system, model, direction)
    if not picture:
        return ForceMapReport(model, system, direction, found)
    from kinegen.analysis.boundary import working_range_boundary
    from kinegen.forces.maps import reach_map

    smooth = reach_map(system, model, direction)
    return ForceMapReport(model, system, direction, found, smooth, working_range_boundary(system, section))


@dataclass(frozen=True)
class LiftReport:
    """The lift chart (:class:`kinegen.forces.lift.LiftChart`), the wall time of its poses'
    searches [s] and, for its picture, the working range's exact boundary (None unless asked, or
    without a ``working_range:`` section)."""

    model: Any
    chart: Any
    seconds: float
    boundary: Any = None


def lift(session: Session, model_file: str | Path, parametrization: str = rotations.REFERENCE, compiled: bool | None = None,
         picture: bool = False) -> LiftReport:  # fmt: skip
    """The lift chart of the model's ``lift_chart`` section (:func:`kinegen.forces.lift.lift_chart`);
    with ``picture`` also the working range's boundary it is drawn over."""
    from kinegen.forces.lift import lift_chart

    model, section = _section(session, model_file, "lift_chart", "what kinegen lift computes")
    _, system = case_system(session, model_file, section.case, parametrization, compiled)
    start = time.perf_counter()
    chart = lift_chart(system, model)
    seconds = time.perf_counter() - start
    boundary = None
    if picture and model.working_range is not None:
        from kinegen.analysis.boundary import working_range_boundary

        _, envelope_system = case_system(session, model_file, model.working_range.case, parametrization, compiled)
        boundary = working_range_boundary(envelope_system, model.working_range)
    return LiftReport(model, chart, seconds, boundary)


__all__ = ["ForceMapReport", "LiftReport", "ToolForcesReport", "force_map", "lift", "tool_forces"]
