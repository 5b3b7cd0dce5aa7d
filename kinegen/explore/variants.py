"""Design variants measured: one partition of an exploration, on whatever process runs it (a
Dask worker, or the client itself for the in-process baseline).

A variant is a value of the study's parameters (the model's other design parameters at their
nominal values). It is measured exactly as ``kinegen optimize`` measures a design
(:class:`kinegen.analysis.studies.StudyProblem`, one generated module, ``p`` as input, no
rebuild): the working-range figures by refining the *nominal* design's optima at the variant
(:func:`kinegen.analysis.envelope.refine_from`), every case quantity from one solve of its case
started from the nominal design's pose. Every variant starts from the nominal design, not from
the variant before it, so a variant's result depends on nothing but its parameters: the same
variants give the same numbers whatever the partitioning, the worker or the order.

Each variant gets a status, never a silent NaN:

* ``ok``: every quantity measured (finite);
* ``unreachable``: the mechanism cannot be assembled somewhere it must go (Newton found no
  configuration: an input range the linkage cannot reach at this design);
* ``singular``: the solve met a singular Jacobian or would have crossed a toggle (branch change);
* ``failed``: any other failure of the measurement (the message says which).

The quantities of a variant that is not ``ok`` are NaN, and its ``message`` says why.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from kinegen.errors import BranchError, ConvergenceError, GeneratedModuleError, SingularJacobianError

STATUSES = ("ok", "unreachable", "singular", "failed")


@dataclass(frozen=True)
class PartitionTask:
    """What a worker needs to measure one partition: where the model and its generated module
    are (paths the worker can read), the source hash they must have, the study, and the variants
    (rows of the study's parameter values, in the study's parameter order)."""

    model_file: str
    module_file: str
    source_sha256: str
    study: str
    compiled: bool
    partition: int
    first: int  #: index of the partition's first variant in the whole sample
    samples: np.ndarray  #: (count, n_parameters)

    @property
    def key(self) -> tuple:
        return (self.model_file, self.module_file, self.source_sha256, self.study, self.compiled)


@dataclass
class PartitionResult:
    """The measured variants of one partition, column by column."""

    partition: int
    variant: np.ndarray  #: (count,) int64 index in the whole sample
    parameters: dict[str, np.ndarray]
    status: list[str]
    message: list[str]
    quantities: dict[str, np.ndarray]
    feasible: np.ndarray  #: (count,) ok and every study constraint met
    seconds: float = 0.0  #: the worker's time for the partition (not part of the data)
    worker_setup_seconds: float = 0.0  #: loading the module and the nominal design (first task of a process only)
    statuses: dict[str, int] = field(default_factory=dict)


class VariantEvaluator:
    """A model's study ready to measure variants in this process (the module loaded, the nominal
    design measured once as every variant's starting point)."""

    def __init__(self, model_file: str, module_file: str, source_sha256: str, study: str, compiled: bool) -> None:
        from kinegen.analysis.studies import StudyProblem
        from kinegen.model import load
        from kinegen.runtime import load_module

        start = time.perf_counter()
        model = load(model_file)
        module = load_module(module_file, model_file)
        if module.SOURCE_SHA256 != source_sha256:
            raise GeneratedModuleError(
                f"{model_file} on this worker is not the model the exploration was started with (source hash "
                f"{module.SOURCE_SHA256[:12]} here, {source_sha256[:12]} there): workers must see the same model files"
            )
        self.study = model.studies[study]
        self.problem = StudyProblem(model, module, self.study, compiled, resample=False)
        self.parameters = list(self.problem.names)
        self.columns = [q.label for q in self.problem.quantities]
        nominal = np.array([self.problem.nominal_design[n] for n in self.parameters])
        self.nominal = self.problem.measure(nominal, gradients=False).values  # a failure here is the model's: raised
        self.reference = (self.problem.envelope, dict(self.problem.starts))
        self.setup_seconds = time.perf_counter() - start

    def evaluate(self, p: np.ndarray) -> tuple[str, str, dict[str, float]]:
        """(status, message, quantities) of the variant ``p`` (the study's parameters)."""
        from kinegen.analysis.studies import DesignFailure

        self.problem.envelope, starts = self.reference
        self.problem.starts = dict(starts)
        try:
            values = self.problem.measure(np.asarray(p, dtype=float), gradients=False).values
        except DesignFailure as exc:
            return status_of(exc.__cause__), str(exc), dict.fromkeys(self.columns, float("nan"))
        bad = [label for label in self.columns if not np.isfinite(values[label])]
        if bad:
            return "failed", f"not finite: {', '.join(bad)}", dict.fromkeys(self.columns, float("nan"))
        return "ok", "", {label: float(values[label]) for label in self.columns}

    def feasible(self, values: dict[str, float]) -> bool:
        """Every constraint of the study met by the measured ``values``."""
        for constraint in self.study.constraints:
            value = values[constraint.quantity.label]
            if constraint.at_least is not None and not value >= constraint.at_least:
                return False
            if constraint.at_most is not None and not value <= constraint.at_most:
                return False
        return True


def status_of(error: BaseException | None) -> str:
    """The status of a variant whose measurement raised ``error``."""
    if isinstance(error, (SingularJacobianError, BranchError)):
        return "singular"
    if isinstance(error, ConvergenceError):
        return "unreachable"
    return "failed"


#: evaluators of this process, by task key (a worker keeps its module loaded between tasks)
_EVALUATORS: dict[tuple, VariantEvaluator] = {}


def evaluator(model_file: str, module_file: str, source_sha256: str, study: str, compiled: bool) -> tuple[VariantEvaluator, float]:
    """This process's evaluator for a model's study (made once), and the seconds spent making it now."""
    key = (model_file, module_file, source_sha256, study, compiled)
    if key in _EVALUATORS:
        return _EVALUATORS[key], 0.0
    if len(_EVALUATORS) >= 4:
        _EVALUATORS.clear()
    made = _EVALUATORS[key] = VariantEvaluator(*key)
    return made, made.setup_seconds


def evaluator_for(task: PartitionTask) -> tuple[VariantEvaluator, float]:
    """The evaluator for a task's model and study (see :func:`evaluator`)."""
    return evaluator(*task.key)


def evaluate_partition(task: PartitionTask) -> PartitionResult:
    """Measure every variant of one partition (what a Dask task runs)."""
    evaluator, setup = evaluator_for(task)
    start = time.perf_counter()
    count = len(task.samples)
    statuses, messages, feasible = [], [], np.zeros(count, dtype=bool)
    quantities = {label: np.full(count, np.nan) for label in evaluator.columns}
    for i, p in enumerate(task.samples):
        status, message, values = evaluator.evaluate(p)
        statuses.append(status)
        messages.append(message)
        for label, value in values.items():
            quantities[label][i] = value
        feasible[i] = status == "ok" and evaluator.feasible(values)
    return PartitionResult(
        partition=task.partition,
        variant=np.arange(task.first, task.first + count, dtype=np.int64),
        parameters={name: np.array(task.samples[:, j], dtype=float) for j, name in enumerate(evaluator.parameters)},
        status=statuses,
        message=messages,
        quantities=quantities,
        feasible=feasible,
        seconds=time.perf_counter() - start,
        worker_setup_seconds=setup,
        statuses={s: statuses.count(s) for s in STATUSES if s in statuses},
    )
