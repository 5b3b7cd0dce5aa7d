"""A design study optimized on exact (or finite-difference) gradients: the work behind
``kinegen optimize``.

:func:`plan` checks the request -- the model declares the study, the optimized model is not
written over the model file, exact gradients have their sensitivity kernels -- and :func:`run`
runs SciPy's optimizer (:func:`kinegen.analysis.studies.optimize`), once, or with
``compare_fd`` a second time on finite-difference gradients, into a :class:`StudyReport`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinegen import rotations
from kinegen.api import Session
from kinegen.errors import RequestError


@dataclass(frozen=True)
class StudyPlan:
    """A checked request (:func:`plan`): the model, its generated module, the study's name, the
    optimizer, the gradients' kinds in order ("exact" and/or "fd"), the iteration limit and the
    file the optimized model goes to."""

    model: Any  #: kinegen.model.Model
    module: Any  #: the generated module
    study: str
    method: str
    gradients: tuple[str, ...]
    max_iterations: int
    target: Path


@dataclass(frozen=True)
class StudyReport:
    """One optimization per gradient kind (:class:`kinegen.analysis.studies.StudyResult`), the
    first the one whose optimum is kept."""

    plan: StudyPlan
    runs: list[Any]

    @property
    def best(self) -> Any:
        return self.runs[0]

    def comparison(self) -> str | None:
        """Exact against finite-difference gradients in one line (None for a single run)."""
        if len(self.runs) != 2:
            return None
        exact, fd = self.runs
        difference = max(abs(exact.optimum[n] - fd.optimum[n]) for n in exact.optimum)
        return (f"exact vs finite-difference gradients: {exact.iterations} vs {fd.iterations} iterations, {exact.evaluations} vs "
                f"{fd.evaluations} designs measured, {exact.seconds:.1f} vs {fd.seconds:.1f} s; optima differ by {difference:.1e} at most")  # fmt: skip


def plan(session: Session, model_file: str | Path, study: str, parametrization: str = rotations.REFERENCE, *,
         method: str = "SLSQP", gradients: str = "exact", compare_fd: bool = False, max_iterations: int = 100,
         out: str | Path | None = None) -> StudyPlan:  # fmt: skip
    """The checked request to optimize ``study`` of ``model_file`` with ``method`` on ``gradients``
    ("exact" or "fd"; ``compare_fd``: also on finite differences), the optimized model to ``out``
    (default ``out/<model>_<study>.yaml``). Raises :class:`RequestError` for what does not fit."""
    model = session.model(model_file)
    module = session.module(model_file, parametrization, sensitivities=True if gradients == "exact" else None)
    if not model.studies:
        raise RequestError("--study", f"{model_file} declares no studies (a studies: section)")
    if study not in model.studies:
        raise RequestError("--study", f"no study {study!r} (studies: {', '.join(model.studies)})")
    target = Path(out) if out else Path("out") / f"{model.name}_{study}.yaml"
    if target.resolve() == Path(model_file).resolve():
        raise RequestError("--out", f"{out} is the model file itself: the optimized model is written to a new file")
    if gradients == "exact" and "dvel" not in next(iter(module.CASES.values()))["outputs"]:
        raise RequestError("--gradients", f"the generated module of {model.name} ({parametrization}) has no sensitivity kernels: "
                           "rebuild it without --no-sensitivities (or use --gradients fd)")  # fmt: skip
    kinds = (gradients, "fd") if compare_fd and gradients == "exact" else (gradients,)
    return StudyPlan(model, module, study, method, kinds, max_iterations, target)


def run(plan: StudyPlan, progress: Callable[[str], None] | None = None, finished: Callable[[Any], None] | None = None) -> StudyReport:
    """Optimize once per gradient kind; ``progress`` is told each run's start and its iterations,
    ``finished`` each run's result as it ends."""
    from kinegen.analysis.studies import StudyProblem, optimize

    say = progress or (lambda line: None)
    runs = []
    for kind in plan.gradients:
        say(f"{plan.model.name}: study {plan.study} ({plan.method}, {'exact' if kind == 'exact' else 'finite-difference'} gradients)")
        result = optimize(StudyProblem(plan.model, plan.module, plan.model.studies[plan.study]), plan.method, kind,
                          plan.max_iterations, progress=say)  # fmt: skip
        runs.append(result)
        if finished is not None:
            finished(result)
    return StudyReport(plan, runs)


__all__ = ["StudyPlan", "StudyReport", "plan", "run"]
