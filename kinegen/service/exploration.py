"""A design-space exploration of a model's study: the work behind ``kinegen explore``.

:func:`plan` checks the request (the study) and settles its settings: what was asked, else on
``resume`` what the folder being resumed recorded, else the defaults (1,024 Sobol samples, seed 0,
partitions of :data:`kinegen.explore.run.PARTITION_SIZE`). :func:`run` measures the variants on
Dask, partition by partition into Parquet (:func:`kinegen.explore.run.explore`), and reads the
table back with the parameters' sensitivity ranking. Plotting is the command's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinegen import rotations
from kinegen.api import Session
from kinegen.errors import RequestError

#: The settings a request leaves open take these values (or, resumed, the folder's own).
DEFAULTS = {"samples": 1024, "sampler": "sobol", "seed": 0}


@dataclass(frozen=True)
class ExplorationPlan:
    """A checked request: the model, the Parquet folder written (``target``) and what is explored."""

    model: Any  #: kinegen.model.Model
    target: Path
    exploration: Any  #: kinegen.explore.run.Exploration
    resume: bool


@dataclass(frozen=True)
class ExplorationReport:
    """What the run did (:class:`kinegen.explore.run.Report`), the whole table written (this run's
    partitions and those found), its provenance, and the sensitivity ranking over the ok variants
    (None where there is none to rank)."""

    plan: ExplorationPlan
    done: Any
    table: Any  #: pyarrow.Table
    provenance: dict
    ranking: Any = None


def plan(session: Session, model_file: str | Path, study: str, parametrization: str = rotations.REFERENCE, *,
         samples: int | None = None, sampler: str | None = None, seed: int | None = None, partition_size: int | None = None,
         out: str | Path | None = None, resume: bool = False, compiled: bool = True) -> ExplorationPlan:  # fmt: skip
    """The checked request to explore ``study`` (a :class:`RequestError` of ``--study`` when the
    model has no such study) into ``out`` (default ``out/<model>_<study>.parquet``)."""
    from kinegen.explore.run import PARTITION_SIZE, Exploration
    from kinegen.explore.store import Store

    model = session.model(model_file)
    if study not in model.studies:  # before the module is built, if it must be
        raise RequestError("--study", f"no study {study!r} (studies: {', '.join(model.studies) or 'none declared'})")
    module = session.module(model_file, parametrization)
    target = Path(out) if out else Path("out") / f"{model.name}_{study}.parquet"
    asked = {"samples": samples, "sampler": sampler, "seed": seed, "partition_size": partition_size}
    defaults = {**DEFAULTS, "partition_size": PARTITION_SIZE}
    if resume and Store(target).exists():
        held = Store(target).provenance()
        defaults = {key: held.get(key, value) for key, value in defaults.items()}
    chosen = {key: defaults[key] if value is None else value for key, value in asked.items()}
    exploration = Exploration(Path(model_file).resolve(), Path(module.__file__).resolve(), study, compiled=compiled, **chosen)
    return ExplorationPlan(model, target, exploration, resume)


def run(plan: ExplorationPlan, scheduler: str | None = None, workers: int | None = None,
        say: Callable[[str], None] | None = None) -> ExplorationReport:  # fmt: skip
    """Explore on Dask (``scheduler``'s address, else a local cluster of ``workers``); ``say`` is
    told how the cluster was set up and what was found on disk."""
    from kinegen.explore.plots import ranking_of
    from kinegen.explore.run import explore
    from kinegen.explore.store import Store

    done = explore(plan.exploration, plan.target, resume=plan.resume, scheduler=scheduler, workers=workers, say=say)
    store = Store(plan.target)
    table, provenance = store.read(), store.provenance()
    return ExplorationReport(plan, done, table, provenance, ranking_of(table, provenance))


__all__ = ["DEFAULTS", "ExplorationPlan", "ExplorationReport", "plan", "run"]
