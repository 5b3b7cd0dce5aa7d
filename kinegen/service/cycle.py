"""The fastest timing of a case's path: the work behind ``kinegen cycle`` (docs/cycle.md).

:func:`plan` checks the request -- the case, the loads, the speed limits, that something limits
how fast the path can be followed -- and :func:`run` solves the path on its grid, re-times it
(:func:`kinegen.forces.cycle.fastest`) and measures the re-timed motion with the code ``kinegen
solve`` reports with (:func:`kinegen.forces.cycle.check_retimed`), into a :class:`CycleReport`.
Units: SI (s, m/s for a cylinder's speed limit, rad/s for a motor's).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinegen import rotations
from kinegen.api import Session
from kinegen.errors import RequestError
from kinegen.service.requests import case_system, check_loads


@dataclass(frozen=True)
class CyclePlan:
    """A checked request (:func:`plan`): the model, the case's numeric system, the path's grid [s],
    the loads held, whether the tipping margin limits, and the speed limits by actuator or motor."""

    model: Any  #: kinegen.model.Model
    system: Any  #: kinegen.runtime.NumericSystem
    times: np.ndarray
    loads: tuple[str, ...]
    tipping: bool
    speed_limits: dict[str, float] = field(default_factory=dict)
    compiled: bool | None = None


@dataclass(frozen=True)
class CycleReport:
    """The fastest timing (``found``: :class:`kinegen.forces.cycle.Cycle`), the re-timed motion's
    check (``checked``: :class:`kinegen.forces.cycle.Check`), each limit's share of the cycle time
    and the phases (:func:`kinegen.forces.cycle.shares`, :func:`~kinegen.forces.cycle.phase_summary`),
    and the wall time [s] of the path's solve and re-timing."""

    plan: CyclePlan
    found: Any
    checked: Any
    share: dict[str, float]
    phases: list[tuple[str, float, float, float, float]]
    elapsed: float

    @property
    def held(self) -> list[str]:
        """What the re-timed motion holds, in words: the loads, and the machine's weight and inertia
        where the model has masses."""
        return [*self.found.loads, "the machine's weight and inertia"] if self.plan.model.massive else list(self.found.loads)


def plan(
    session: Session,
    model_file: str | Path,
    case: str | None = None,
    parametrization: str = rotations.REFERENCE,
    *,
    loads: tuple[str, ...] = (),
    steps: int | None = None,
    tipping: bool = True,
    speed_limits: Mapping[str, float] | None = None,
    compiled: bool | None = None,
) -> CyclePlan:
    """The checked request to re-time ``case`` (default: the first) of ``model_file``, its path
    solved on the case's grid or ``steps`` points, with ``loads`` held, the tipping margin kept
    (``tipping``) and ``speed_limits`` (actuator or motor name -> largest speed > 0). Raises
    :class:`RequestError` for what the model cannot answer as asked."""
    model, system = case_system(session, model_file, case, parametrization, compiled)
    loads = check_loads(model, loads)
    limits = dict(speed_limits or {})
    movers = [a.name for a in model.actuators] + [m.name for m in model.motors]
    for name, value in limits.items():
        if name not in movers or not value > 0:
            raise RequestError("--max-speed", f"'{name}={value:g}': name an actuator or motor ({', '.join(movers)}) and a speed > 0")
    if not model.massive and model.supply is None and not limits:
        raise RequestError("MODEL_FILE", "the model has no masses, no pumps: section and no --max-speed: nothing limits how fast "
                           "the path can be followed")  # fmt: skip
    times = np.linspace(system.t0, system.t1, steps or system.steps)
    return CyclePlan(model, system, times, loads, tipping, limits, compiled)


def run(plan: CyclePlan) -> CycleReport:
    """Solve the plan's path, re-time it and check the re-timed motion (see :class:`CycleReport`)."""
    from kinegen.forces.cycle import check_retimed, fastest, phase_summary, shares
    from kinegen.runtime import SolverOptions
    from kinegen.runtime import solve as solve_motion

    start = time.perf_counter()
    path = solve_motion(plan.system, plan.times, SolverOptions(compiled=plan.compiled is not False))
    found = fastest(path, plan.model, plan.loads, tipping=plan.tipping, speed_limits=plan.speed_limits)
    elapsed = time.perf_counter() - start
    checked = check_retimed(plan.system, plan.model, found)
    return CycleReport(plan, found, checked, shares(found), phase_summary(found), elapsed)


__all__ = ["CyclePlan", "CycleReport", "plan", "run"]
