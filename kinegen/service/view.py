"""A case's motion to be shown in 3-D: the work behind ``kinegen view``.

:func:`plan` checks the request (the case, design values, the tracked point, the frame of the
animation's plane) before anything is solved; :func:`run` solves the case, stopping at a step that
fails (the failure is kept in the results, with every time point solved before it). Writing the
page and the animation is the command's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinegen import rotations
from kinegen.api import Session
from kinegen.service.requests import case_system, check_frame, named_point


@dataclass(frozen=True)
class ViewPlan:
    """A checked request: the model, the case's numeric system, the tracked point (body, point;
    None: the model's own) and the body whose x-z plane the animation is drawn in (None: chosen from the motion)."""

    model: Any  #: kinegen.model.Model
    system: Any  #: kinegen.runtime.NumericSystem
    point: tuple[str, str] | None
    frame_body: str | None


@dataclass(frozen=True)
class ViewReport:
    """The solved motion (:class:`kinegen.runtime.Results`; ``results.failure`` where a step failed)."""

    plan: ViewPlan
    results: Any


def plan(session: Session, model_file: str | Path, parametrization: str = rotations.REFERENCE, case: str | None = None,
         point: str | None = None, frame_body: str | None = None, design: dict[str, float] | None = None) -> ViewPlan:  # fmt: skip
    """The checked request to show ``case`` (default: the first) of ``model_file``: ``point`` a
    named point ``BODY.POINT`` (a :class:`~kinegen.errors.RequestError` of ``--point`` otherwise),
    ``frame_body`` a body (of ``--frame``), ``design`` values of design parameters (of ``--design``)."""
    model, system = case_system(session, model_file, case, parametrization, None, design)
    tracked = named_point(system, point)
    check_frame(system, frame_body)
    return ViewPlan(model, system, tracked, frame_body)


def run(plan: ViewPlan) -> ViewReport:
    """Solve the case with kinegen's solver (its condition numbers the CSV's and the plot's),
    stopping at a failed step."""
    from kinegen.runtime import Solver, SolverOptions

    return ViewReport(plan, Solver(plan.system, SolverOptions(on_failure="stop")).solve())


__all__ = ["ViewPlan", "ViewReport", "plan", "run"]
