"""One model in several parametrizations: the work behind ``kinegen scan`` (the smallest singular
value and condition of Phi_q along a case, per parametrization, against the physical reference)
and ``kinegen compare`` (every parametrization built and solved, one table). Parametrization
names are kinegen's canonical ones (:func:`kinegen.rotations.get`'s ``name``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinegen import rotations
from kinegen.api import Session
from kinegen.errors import RequestError
from kinegen.service.requests import case_system


@dataclass(frozen=True)
class ScanReport:
    """The scan of a case (:class:`kinegen.analysis.scan.ScanResult`) and what it is of."""

    model: str
    case: str
    result: Any

    @property
    def title(self) -> str:
        """``<model> / <case>``: the plot's title."""
        return f"{self.model} / {self.case}"

    def text(self) -> str:
        """The scan as ``kinegen scan`` prints it."""
        return f"{self.model}/{self.case}: " + self.result.text()


def scan(session: Session, model_file: str | Path, case: str | None, parametrizations: tuple[str, ...],
         warn_ratio: float = 1e-3, horizon: int = 20) -> ScanReport:  # fmt: skip
    """Scan ``case`` (default: the first; an unknown one is a :class:`RequestError` of ``--case``)
    in each of ``parametrizations`` against the reference parametrization's physical system
    (:func:`kinegen.analysis.scan.scan`; ``warn_ratio`` and ``horizon`` as there)."""
    from kinegen.analysis.scan import scan as run

    _, physical = case_system(session, model_file, case, rotations.REFERENCE, None)
    systems = {name: case_system(session, model_file, physical.case, name, None)[1] for name in parametrizations}
    return ScanReport(physical.model, physical.case, run(physical, systems, warn_ratio=warn_ratio, horizon=horizon))


@dataclass(frozen=True)
class ComparisonReport:
    """One table row per parametrization (:class:`kinegen.analysis.compare.Comparison`) of ``case``
    of the model (its design parameters at their nominal values)."""

    model: Any  #: kinegen.model.Model
    case: str
    rows: list

    def text(self) -> str:
        """The table as ``kinegen compare`` prints it."""
        from kinegen.analysis.compare import table

        return table(self.rows, self.model.name, self.case)

    def document(self) -> dict:
        """The table as JSON data (``kinegen compare --json``)."""
        from kinegen.analysis.compare import to_json

        return {"model": self.model.name, "case": self.case, "rows": to_json(self.rows)}


def compare(session: Session, model_file: str | Path, case: str | None, parametrizations: tuple[str, ...] | None = None,
            compiled: bool = True) -> ComparisonReport:  # fmt: skip
    """Build and solve ``case`` (default: the first; an unknown one is a :class:`RequestError` of
    ``--case``) in each of ``parametrizations`` (default: :data:`kinegen.analysis.compare.DEFAULT`),
    the compiled solve too when ``compiled`` (:func:`kinegen.analysis.compare.compare`)."""
    from kinegen.analysis import compare as comparison

    model = session.model(model_file)
    model = model.at() if model.design else model
    if case is not None and case not in model.cases:
        raise RequestError("--case", f"no case {case!r} (cases: {', '.join(model.cases)})")
    chosen = case or next(iter(model.cases))
    return ComparisonReport(model, chosen, comparison.compare(model, chosen, parametrizations or comparison.DEFAULT, compiled=compiled))


__all__ = ["ComparisonReport", "ScanReport", "compare", "scan"]
