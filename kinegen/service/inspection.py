"""Phi_q inspected exactly at one configuration: the work behind ``kinegen inspect``.

:func:`plan` checks the request -- the case, the time ``at`` (an exact real constant within the
case's range), a given configuration (every stored coordinate, a finite number) -- and
:func:`run` computes the exact rank, null spaces and determinant
(:func:`kinegen.analysis.inspect.inspect`) and, where Phi_q is singular, what kind of
singularity it is (:func:`kinegen.analysis.classify.classify`), into an
:class:`InspectionReport`. A model with design parameters is inspected at their nominal values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinegen import rotations
from kinegen.api import Session
from kinegen.errors import RequestError


@dataclass(frozen=True)
class InspectionPlan:
    """A checked request (:func:`plan`): the model (design parameters at nominal), the
    parametrization, the case, the time (exact text), the given configuration (None: solved at
    that time with ``numeric``, the case's quaternion system), the budget [s] of the exact work and
    whether every small block's symbolic determinant is wanted (the JSON report, ``--det-file``) or
    only the singular blocks' (the text report)."""

    model: Any  #: kinegen.model.Model
    parametrization: rotations.Parametrization
    case: str
    at: str
    q: np.ndarray | None
    numeric: Any
    budget: float
    session: Session
    model_file: str | Path
    every_block: bool = True


@dataclass(frozen=True)
class InspectionReport:
    """The inspection (:class:`kinegen.analysis.inspect.Inspection`) and, where Phi_q is singular,
    its classification (:class:`kinegen.analysis.classify.Classification`; else None)."""

    plan: InspectionPlan
    inspection: Any
    verdict: Any = None

    def document(self) -> dict:
        """The report as JSON data (``kinegen inspect --json``)."""
        data = self.inspection.to_json()
        if self.verdict:
            data["classification"] = {"kind": self.verdict.kind, "evidence": self.verdict.evidence}
        return data


def plan(session: Session, model_file: str | Path, parametrization: str = rotations.REFERENCE, case: str | None = None,
         at: str | None = None, q: Any = None, q_source: str = "the configuration", budget: float = 60.0,
         every_block: bool = True) -> InspectionPlan:  # fmt: skip
    """The checked request to inspect ``case`` (default: the first) of ``model_file`` in
    ``parametrization`` at time ``at`` (exact text; default the case's start) or at the
    configuration ``q`` (an object {stored coordinate: value} or a list in stored order, read from
    ``q_source``, as named in errors). Raises :class:`RequestError` for what does not fit."""
    if not (math.isfinite(budget) and budget > 0):  # (click's range lets NaN through: it compares false)
        raise RequestError("--budget", f"expected a positive, finite number of seconds, got {budget}")
    model = session.model(model_file)
    model = model.at() if model.design else model
    chosen_parametrization = rotations.get(parametrization)
    if case is not None and case not in model.cases:
        raise RequestError("--case", f"no case {case!r} (cases: {', '.join(model.cases)})")
    chosen = case or next(iter(model.cases))
    when = inspection_time(at, model.cases[chosen])
    values = None
    numeric = None
    if q is not None:
        from kinegen.symbolic import coordinates

        values = configuration(q, coordinates(model, chosen_parametrization).stored_names, q_source)
    else:  # the configuration is solved with the quaternion module of the case
        numeric = session.system(model_file, chosen, rotations.REFERENCE)
    return InspectionPlan(model, chosen_parametrization, chosen, when, values, numeric, budget, session, model_file, every_block)


def run(plan: InspectionPlan) -> InspectionReport:
    """Inspect Phi_q exactly, and classify it where it is singular (see :class:`InspectionReport`)."""
    from kinegen.analysis.inspect import inspect

    inspection = inspect(plan.model, plan.parametrization, plan.case, plan.at, plan.q, plan.numeric, budget=plan.budget,
                         every_block=plan.every_block)  # fmt: skip
    verdict = None
    if inspection.singular:
        from kinegen.analysis.classify import classify
        from kinegen.analysis.inspect import convert

        quaternion = rotations.get(rotations.REFERENCE)
        numeric = plan.numeric if plan.numeric is not None else plan.session.system(plan.model_file, plan.case, rotations.REFERENCE)
        physical = None if plan.q is None else convert(plan.q, plan.parametrization, quaternion, len(plan.model.bodies))
        verdict = classify(plan.model, plan.parametrization, plan.case, float(inspection.t), inspection, numeric, physical=physical,
                           system_of=lambda name: _fresh_system(plan, name))  # fmt: skip
    return InspectionReport(plan, inspection, verdict)


def _fresh_system(plan: InspectionPlan, parametrization: str) -> Any:
    """The case's numeric system in ``parametrization`` from its generated module when that is there
    and fresh (Python functions: one Jacobian is evaluated), else None: nothing is built for it."""
    from kinegen.errors import GeneratedModuleError
    from kinegen.runtime import from_module, load_module

    try:
        module = load_module(plan.session.module_path(plan.model_file, parametrization), plan.model_file)
    except GeneratedModuleError:
        return None
    return from_module(module, plan.case, compiled=False)


def inspection_time(at: str | None, case: Any) -> str:
    """``at`` checked: an exact real constant within the case's time range (the configuration
    there is solved from the case's start), as text for the inspection; the case's start if None."""
    from kinegen.errors import ExpressionError
    from kinegen.model.expressions import float_value, parse

    if at is None:
        return str(case.t0)
    try:
        value = float_value(parse(at, allow_time=False))
    except ExpressionError as exc:
        raise RequestError("--at", f"{at!r} is not a time: {exc}") from None
    span = case.t1 - case.t0
    if not case.t0 - 1e-9 * span <= value <= case.t1 + 1e-9 * span:
        raise RequestError("--at", f"t = {value:g} is outside the time range [{case.t0:g}, {case.t1:g}] s of case {case.name!r}, "
                           "over which its motion is solved")  # fmt: skip
    return at


def configuration(data: Any, names: list[str], where: str) -> np.ndarray:
    """A configuration given as an object {name: value} or a list in stored order (``names``):
    every stored coordinate a finite number; ``where`` names its source in errors (``--q``)."""
    if isinstance(data, list):
        if len(data) != len(names):
            raise RequestError("--q", f"{where}: a list needs {len(names)} values ({', '.join(names)}), got {len(data)}")
        data = dict(zip(names, data))
    if not isinstance(data, dict):
        raise RequestError("--q", f"{where}: expected an object {{coordinate name: value}}")
    missing = [n for n in names if n not in data]
    if missing:
        raise RequestError("--q", f"{where} lacks {', '.join(missing)}")
    values = [data[n] for n in names]
    bad = [n for n, v in zip(names, values) if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v)]
    if bad:
        raise RequestError("--q", f"{where}: {', '.join(bad)} not a finite number")
    return np.array(values, dtype=float)


__all__ = ["InspectionPlan", "InspectionReport", "configuration", "inspection_time", "plan", "run"]
