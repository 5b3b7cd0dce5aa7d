"""Results of a trajectory solve: the solved coordinates, rates and accelerations over time.

The data only: arrays indexed by time first. What follows from them is computed by functions
that take the results first: poses, velocities and accelerations of bodies, points and
actuators in :mod:`kinegen.runtime.kinematics`, their derivatives by the design parameters in
:mod:`kinegen.runtime.sensitivity`, the CSV table in :mod:`kinegen.runtime.export`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinegen.runtime.system import NumericSystem


@dataclass
class Results:
    """Time histories of one solve (the *data*; the system is the model)."""

    system: NumericSystem
    times: np.ndarray
    q: np.ndarray  #: stored coordinates, (K, n)
    v: np.ndarray  #: velocity coordinates, (K, nv)
    a: np.ndarray  #: their time derivatives, (K, nv)
    iterations: np.ndarray  #: Newton iterations per time point
    residuals: np.ndarray  #: max |Phi| at convergence per time point
    conditions: np.ndarray  #: the solver's condition number of Phi_q per time point (``condition_kind``)
    inputs: np.ndarray  #: driver inputs u per time point, (K, n_inputs)
    condition_kind: str = "none"  #: "none" (NaN, the solver's default), "estimate" (1-norm) or "exact" (2-norm)
    #: per time point: True where Newton reached the tolerance (False only for the last
    #: point of a run stopped with ``on_failure="stop"``; its q, v, a are NaN)
    converged: np.ndarray | None = None
    failure: Exception | None = None  #: the error that stopped the run, if it stopped

    def __post_init__(self) -> None:
        if self.converged is None:
            self.converged = np.ones(len(self.times), dtype=bool)

    @property
    def complete(self) -> bool:
        """True when every time point converged."""
        return self.failure is None and bool(np.all(self.converged))

    def body_coordinates(self, body: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The body's stored, velocity and acceleration coordinates over time (K, nq), (K, nv), (K, nv)."""
        if body not in self.system.bodies:
            raise KeyError(f"no body {body!r} (bodies: {', '.join(self.system.bodies)})")
        coordinates = self.system.body_coordinates
        return coordinates(self.q, body), coordinates(self.v, body, velocity=True), coordinates(self.a, body, velocity=True)

    def time_points(self, which: slice | np.ndarray) -> Results:
        """These results at some of their time points (a slice or indices): what a quantity measured
        at one time point (its maximum over a motion) differentiates there. Sensitivities are
        recomputed for them, not sliced."""
        fields = ("times", "q", "v", "a", "iterations", "residuals", "conditions", "inputs", "converged")
        return dataclasses.replace(self, **{name: getattr(self, name)[which] for name in fields})

    def once(self, name: str, compute: Callable[[Results], Any]) -> Any:
        """``compute(self)``, computed once for these results and kept with them under ``name``
        (what is derived from one solve: its condition numbers, its state's sensitivities)."""
        cache = self.__dict__.setdefault("_once", {})
        if name not in cache:
            cache[name] = compute(self)
        return cache[name]
