"""A case solved as a user asks for it: the work behind ``kinegen solve``.

Two steps, so that a caller can check its own options against the case before the solve runs:

* :func:`plan` reads the model and its generated module (:class:`kinegen.api.Session`), checks the
  request -- the case, the design values, the loads, ``dynamics``/``weight``, a timing file, the
  results' memory -- and fixes the time points; a request the model cannot answer raises a
  :class:`RequestError` naming the command line's option it concerns;
* :func:`run` solves position, velocity and acceleration, then the forces (``loads``, the weight,
  with ``dynamics`` the inertia) and the oil the motion asks of the pumps (a model with a
  ``supply:``), and returns them as a :class:`SolveReport`.

Nothing here prints or writes a file: the command line and the main job format the report.
Units: SI (m, s, N, Pa, m^3/s).
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinegen import rotations
from kinegen.api import Session
from kinegen.errors import RequestError
from kinegen.interface import FRAME_VALUES
from kinegen.service.requests import case_system, check_loads

#: bytes a solved time point keeps per stored coordinate, velocity and input (q, v, a, the inputs
#: and their rates, frames of every body) -- measured on the excavator, rounded up
BYTES_PER_VALUE = 8 * 6


@dataclass(frozen=True)
class SolvePlan:
    """A checked request (:func:`plan`): the model, its case's numeric system, the time points
    [s] and what :func:`run` computes beyond the motion."""

    model: Any  #: kinegen.model.Model
    system: Any  #: kinegen.runtime.NumericSystem
    times: np.ndarray
    loads: tuple[str, ...]
    dynamics: bool
    weight: bool
    keep_going: bool
    compiled: bool | None
    retimed: Any = None  #: a timing file's re-timed path (kinegen.forces.cycle.read_timing), or None


@dataclass(frozen=True)
class SolveReport:
    """What :func:`run` found: the motion (``results``, :class:`kinegen.runtime.Results`; complete
    unless the solve stopped early with ``keep_going``), the solve's wall time [s], the forces
    (``held``, :func:`kinegen.forces.forces`; None when none were asked for or the motion is not
    complete) and the pumps' flows (``supplied``, :func:`kinegen.forces.supply.flows`; None
    without a ``supply:`` or a complete motion)."""

    plan: SolvePlan
    results: Any
    elapsed: float
    held: Any = None
    supplied: Any = None

    @property
    def forces_missed(self) -> bool:
        """Forces were asked for, but the solve stopped before the last time point."""
        return bool(self.plan.loads or self.plan.dynamics) and self.held is None


def plan(
    session: Session,
    model_file: str | Path,
    case: str | None = None,
    parametrization: str = rotations.REFERENCE,
    *,
    t0: float | None = None,
    t1: float | None = None,
    steps: int | None = None,
    loads: tuple[str, ...] = (),
    dynamics: bool = False,
    weight: bool = True,
    timing: str | Path | None = None,
    keep_going: bool = False,
    compiled: bool | None = None,
    design: Mapping[str, float] | None = None,
    force: bool = False,
) -> SolvePlan:
    """The checked request to solve ``case`` (default: the first) of ``model_file`` over its grid,
    or ``t0``..``t1`` in ``steps`` points, or a timing file's time points (``kinegen cycle
    --timing``). ``weight`` False leaves the machine's own weight out of the loads' statics;
    ``force`` solves even when the results would take more than half the available memory.
    Raises :class:`RequestError` for what the model cannot answer as asked."""
    model, system = case_system(session, model_file, case, parametrization, compiled, dict(design) if design else None)
    check_memory(system, steps or system.steps, force)
    loads = check_loads(model, loads)
    if dynamics and not model.massive:
        raise RequestError("--dynamics", "the model has no masses (a body's mass:, center_of_mass:, inertia:)")
    if not weight and (dynamics or not loads):
        raise RequestError("--no-weight", "leaves the weight out of --load's statics; --dynamics holds the weight with the inertia"
                           if dynamics else "goes with --load (the statics it leaves the weight out of)")  # fmt: skip
    retimed = None
    if timing is not None:
        from kinegen.forces.cycle import read_timing

        if t0 is not None or t1 is not None or steps is not None:
            raise RequestError("--timing", "the timing file gives the time points: no --t0, --t1 or --steps with it")
        retimed = read_timing(timing)
        if (retimed.model, retimed.case) != (system.model, system.case):
            raise RequestError("--timing", f"{timing} re-times {retimed.model}/{retimed.case}, not {system.model}/{system.case} (--case)")
        times = retimed.times
    else:
        times = np.linspace(system.t0 if t0 is None else t0, system.t1 if t1 is None else t1, steps or system.steps)
    if loads:
        from kinegen.forces.statics import check_load_functions

        for name in dict.fromkeys(loads):
            check_load_functions(model, model.loads[name], times)  # before the solve: a load's function outside its domain
    return SolvePlan(model, system, times, loads, dynamics, weight, keep_going, compiled, retimed)


def run(plan: SolvePlan) -> SolveReport:
    """Solve the plan's motion, then its forces and the pumps' flows (see :class:`SolveReport`).
    A solve that fails raises its error, unless ``keep_going``: then the report holds the
    results up to the failure (``results.failure``)."""
    from kinegen.runtime import SolverOptions
    from kinegen.runtime import solve as solve_motion

    model, system = plan.model, plan.system
    start = time.perf_counter()
    options = SolverOptions(on_failure="stop" if plan.keep_going else "raise", compiled=plan.compiled is not False)
    if plan.retimed is not None:
        from kinegen.forces.cycle import retimed_motion

        retimed = plan.retimed
        results = retimed_motion(system, retimed.s, retimed.speed, retimed.acceleration, plan.times, options)
    else:
        results = solve_motion(system, plan.times, options)
    elapsed = time.perf_counter() - start
    held = supplied = None
    if (plan.loads or plan.dynamics) and results.complete:
        from kinegen.forces import forces

        held = forces(results, model, plan.loads, inertia=plan.dynamics, weight=bool(model.massive) and plan.weight)
    if model.supply is not None and results.complete:  # the oil the motion asks of the pumps (and, with forces, their power)
        from kinegen.forces.supply import flows

        supplied = flows(results, model, held)
    return SolveReport(plan, results, elapsed, held, supplied)


def available_memory() -> int | None:
    """Bytes a new allocation can take without swapping, or None where the system does not say.

    Linux's ``MemAvailable`` (/proc/meminfo): free memory plus the page cache and slabs the
    kernel would reclaim. Free pages alone (``SC_AVPHYS_PAGES``) leave the cache out, and on a
    machine whose files fill its cache they read a fraction of what a solve may take.
    """
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(system: Any, steps: int, force: bool = False) -> None:
    """Refuse (unless ``force``) a solve whose results would not fit in half the available memory."""
    need = steps * BYTES_PER_VALUE * (system.n_stored + 2 * system.n_velocity + 3 * len(system.driver_names)
                                      + FRAME_VALUES * len(system.bodies))  # fmt: skip
    available = available_memory()
    if available is None:  # not on this system: no estimate
        return
    if need > available / 2 and not force:
        raise RequestError(
            "--steps",
            f"{steps:,} time points would keep about {need / 2**30:.1f} GiB of results; {available / 2**30:.1f} GiB of memory is "
            "available: fewer --steps, or --force",
        )


__all__ = ["RequestError", "SolvePlan", "SolveReport", "available_memory", "check_memory", "plan", "run"]
