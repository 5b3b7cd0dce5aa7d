"""The working range of a model's ``working_range`` point: the work behind ``kinegen envelope``.

:func:`plan` checks the request (a ``working_range:`` section, the sampling grid) and :func:`run`
samples the range (:func:`kinegen.analysis.envelope.working_range`), traces its exact boundary
where asked (:func:`kinegen.analysis.boundary.working_range_boundary`) and, for a model with
design parameters and their kernels, the figures' exact sensitivities by the envelope theorem,
into an :class:`EnvelopeReport`. Units: m, s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinegen import rotations
from kinegen.api import Session
from kinegen.errors import ModelError, RequestError
from kinegen.service.requests import case_system

#: Most samples a grid may take (the excavator's default grid has 4,851)
MAX_GRID = 1_000_000


@dataclass(frozen=True)
class EnvelopePlan:
    """A checked request (:func:`plan`): the model, the working range's case system, the samples
    per swept input (None: the default grid), whether the exact boundary is traced and whether the
    figures' sensitivities are computed (where the model has design parameters and their kernels)."""

    model: Any  #: kinegen.model.Model
    system: Any  #: kinegen.runtime.NumericSystem
    counts: tuple[int, ...] | None
    boundary: bool
    sensitivities: bool = True


@dataclass(frozen=True)
class EnvelopeReport:
    """The sampled range (``result``: :class:`kinegen.analysis.envelope.Envelope`), its exact
    boundary (:class:`kinegen.analysis.boundary.Boundary`, or None when not asked for) and the
    figures' sensitivities (figure -> design parameter -> m per unit; empty without a design)."""

    plan: EnvelopePlan
    result: Any
    boundary: Any = None
    sensitivities: dict[str, dict[str, float]] = field(default_factory=dict)

    def document(self) -> dict:
        """The report as JSON data (``kinegen envelope --json``)."""
        result = self.result
        document: dict[str, Any] = {
            "figures": result.figures,
            "inputs": result.arguments,
            "published_unverified": self.plan.model.working_range.published,
            "samples": len(result.samples),
            "seconds": result.seconds,
        }
        if result.front is not None:
            document["min_front_swing_radius"] = {"radius": result.front.radius, "inputs": result.front.arguments,
                                                  "farthest": result.front.farthest}  # fmt: skip
        if self.sensitivities:
            document["sensitivities"] = self.sensitivities
        if self.boundary is not None:
            document["boundary"] = self.boundary.document()
        return document


def plan(session: Session, model_file: str | Path, parametrization: str = rotations.REFERENCE,
         counts: tuple[int, ...] | None = None, boundary: bool = False, sensitivities: bool = True) -> EnvelopePlan:  # fmt: skip
    """The checked request to sample the working range of ``model_file`` (``counts`` samples per
    swept input, in the section's order; None: its default grid), tracing the exact boundary when
    ``boundary``, the figures' sensitivities unless ``sensitivities`` is False. A model without a ``working_range:`` section is a ModelError; a grid that does
    not fit it a :class:`RequestError` of ``--grid``."""
    model = session.model(model_file)
    if model.working_range is None:
        raise ModelError(str(model_file), "working_range", "the model has no working_range section")
    _, system = case_system(session, model_file, model.working_range.case, parametrization, None)
    if counts is not None:
        if any(c < 2 for c in counts):
            raise RequestError("--grid", "at least 2 samples per input")
        swept = [name for name, value in model.working_range.inputs.items() if isinstance(value, tuple)]
        if len(counts) != len(swept):
            raise RequestError("--grid", f"{len(counts)} count(s) for the {len(swept)} swept input(s) ({', '.join(swept)}): "
                               "give one per input, in this order")  # fmt: skip
        total = int(np.prod(counts, dtype=float))
        if total > MAX_GRID:
            raise RequestError("--grid", f"{','.join(map(str, counts))} is {total:,} samples; at most {MAX_GRID:,}")
    return EnvelopePlan(model, system, counts, boundary, sensitivities)


def run(plan: EnvelopePlan) -> EnvelopeReport:
    """Sample the range, trace the boundary if asked and compute the figures' sensitivities."""
    from kinegen.analysis.envelope import figure_sensitivities, working_range

    model, system = plan.model, plan.system
    result = working_range(system, model.working_range, plan.counts)
    boundary = None
    if plan.boundary:
        from kinegen.analysis.boundary import working_range_boundary

        boundary = working_range_boundary(system, model.working_range)
    sensitivities = {}
    if plan.sensitivities and system.design and system.sensitivity_kernels:  # d(figure)/d(design parameter), by the envelope theorem
        exact = figure_sensitivities(result, system)
        sensitivities = {figure: dict(zip(system.design, (float(x) for x in values))) for figure, values in exact.items()}
    return EnvelopeReport(plan, result, boundary, sensitivities)


__all__ = ["MAX_GRID", "EnvelopePlan", "EnvelopeReport", "plan", "run"]
