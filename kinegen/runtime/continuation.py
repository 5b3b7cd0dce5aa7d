"""The working range's evaluator: the tracked points (the working-range point, the dump and arm
pivots) at given swept inputs, by Newton continuation from the last solve -- what the sampled
range (:mod:`kinegen.analysis.envelope`), its exact boundary (:mod:`kinegen.analysis.boundary`)
and the chart (:mod:`kinegen.analysis.chart`), and the force maps (:mod:`kinegen.forces.maps`) all evaluate."""

from __future__ import annotations

import numpy as np

from kinegen.model.schema import WorkingRange
from kinegen.runtime import NumericSystem, Solver, SolverOptions

STAGE = 0.065  # of an input's range, per continuation stage
#: max |Phi| of the refinement's solves: the figures' own noise (the default 1e-10 leaves ~1e-10 m,
#: which differences of figures and their optimality conditions would see)
TOLERANCE = 1e-13


class RangeEvaluator:
    """Point position for given swept inputs, by Newton continuation from the last solve."""

    def __init__(self, system: NumericSystem, spec: WorkingRange) -> None:
        self.system = system
        self.solver = Solver(system, SolverOptions(tolerance=TOLERANCE))
        self.spec = spec
        inputs = self.inputs_spec = spec.numbers(system.design)  # at the system's design values
        self.names = [n for n in system.driver_names if isinstance(inputs[n], tuple)]
        self.base = np.array([v if not isinstance(v, tuple) else 0.5 * (v[0] + v[1]) for v in (inputs[n] for n in system.driver_names)])
        self.index = [system.driver_names.index(n) for n in self.names]
        self.ranges = [inputs[n] for n in self.names]
        #: largest change of each input per Newton stage: continuation never jumps branches
        self.stage = np.array([STAGE * (high - low) for low, high in self.ranges])
        self.tracked = [(spec.point.body, spec.point.name)]
        if spec.dump_pivot is not None:
            self.tracked.append((spec.dump_pivot.body, spec.dump_pivot.name))
        if spec.arm_pivot is not None:
            self.tracked.append((spec.arm_pivot.body, spec.arm_pivot.name))
        self.q = system.initial_q.copy()
        self.u = system.driver_inputs(system.t0)[0].copy()
        self.solves = 0

    def inputs(self, values: np.ndarray) -> np.ndarray:
        u = self.base.copy()
        u[self.index] = values
        return u

    def points(self, q: np.ndarray) -> np.ndarray:
        """Global positions of the tracked point (and of the dump pivot): (1 or 2, 3) for
        q of shape (n,), (K, 1 or 2, 3) for a batch (n, K)."""
        points = self.system.point_positions(q.reshape(q.shape[0], -1).T, self.tracked)
        return points[0] if q.ndim == 1 else points

    def derivatives(self) -> tuple[np.ndarray, np.ndarray]:
        """The tracked points at the last solve (P, 3) and their exact derivatives by the swept
        inputs (P, 3, n_swept)."""
        from kinegen.runtime.sensitivity import point_position_sensitivities

        positions, _, by_input = point_position_sensitivities(self.system, self.q[:, None], self.u[:, None], self.tracked, design=False)
        return positions[0], by_input[0][:, :, self.index]

    def move_to(self, values: np.ndarray) -> None:
        """Solve at the swept ``values`` by continuation from the last solve (then ``q``, ``u``;
        :meth:`points` and :meth:`derivatives` there)."""
        target = self.inputs(values)
        steps = max(1, int(np.ceil(np.max(np.abs(target[self.index] - self.u[self.index]) / self.stage))))
        q = self.q
        for s in np.linspace(0, 1, steps + 1)[1:]:
            u = self.u + s * (target - self.u)
            q, _, _ = self.solver.position(q, u)
            self.solves += 1
        self.q, self.u = q, target
