"""Newton-Raphson on many configurations at once (working-range sweeps, design studies).

Each configuration k has its own driver inputs u[:, k] and start q[:, k]. Phi and the
Phi_q values come from the generated NumPy functions evaluated on the whole batch (shape
(n, K)); Phi_q is solved block by block in its block-triangular form (found once from the
sparsity pattern: excavator in quaternions, 84 coordinates -> 41 blocks of at most 9), each
block as one batched ``numpy.linalg.solve``. Configurations leave the batch as they
converge (max |Phi| <= tolerance, the same criterion as :class:`Solver`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegen.errors import KinegenError
from kinegen.runtime.blocksolve import BlockSolve
from kinegen.runtime.solver import Solver, SolverOptions
from kinegen.runtime.system import NumericSystem

#: below this many configurations a batch is solved one by one (NumPy's per-call overhead wins)
SMALL_BATCH = 12


@dataclass
class BatchResult:
    """Solved configurations of a batch."""

    q: np.ndarray  #: (n, K) stored coordinates
    converged: np.ndarray  #: (K,) max |Phi| <= tolerance
    residuals: np.ndarray  #: (K,) max |Phi|
    iterations: np.ndarray  #: (K,) Newton iterations


def solve_batch(
    system: NumericSystem,
    u: np.ndarray,
    q0: np.ndarray,
    tolerance: float = 1e-10,
    max_iterations: int = 25,
    block_solve: BlockSolve | None = None,
) -> BatchResult:
    """Full-step Newton on every column of ``q0`` (n, K) for inputs ``u`` (n_inputs, K): in C
    (kinegen_solve_batch) when the system is compiled, else batched NumPy."""
    if system.native is not None:
        from kinegen.runtime.native import Options

        options = Options.newton_only(tolerance, 1e-300, max_iterations)  # full Newton per configuration
        q, converged, iterations, residuals = system.native.solve_batch(u, q0, options)
        return BatchResult(q, converged, residuals, iterations)
    solver = block_solve or BlockSolve(system)
    q = np.array(q0, dtype=float, copy=True)
    k = q.shape[1]
    iterations = np.zeros(k, dtype=int)
    residuals = np.full(k, np.inf)
    active = np.arange(k)
    for _ in range(max_iterations + 1):
        phi = system.phi(q[:, active], u[:, active])
        norm = np.abs(phi).max(axis=0)
        residuals[active] = norm
        going = np.isfinite(norm) & (norm > tolerance) & (norm < 1e8)
        active, phi = active[going], phi[:, going]
        if not len(active) or (iterations[active] >= max_iterations).all():
            break
        values = system.jac(q[:, active], u[:, active])
        step = solver.solve(values, -phi)
        q[:, active] = system.retract(q[:, active], step)
        iterations[active] += 1
    return BatchResult(q, residuals <= tolerance, residuals, iterations)


def _one_by_one(solver: Solver, u: np.ndarray, guess: np.ndarray) -> BatchResult:
    """Each column solved by the sequential solver (fallbacks included); failures marked."""
    k = u.shape[1]
    q, converged = guess.copy(), np.zeros(k, dtype=bool)
    residuals, iterations = np.full(k, np.inf), np.zeros(k, dtype=int)
    for i in range(k):
        try:
            q[:, i], iterations[i], residuals[i] = solver.position(guess[:, i], u[:, i])
            converged[i] = True
        except KinegenError:
            pass
    return BatchResult(q, converged, residuals, iterations)


#: an axis is thinned to every other value only while it keeps at least this many values, so
#: that continuation never steps more than a tenth of a range (as the envelope's own grid)
FEWEST_VALUES = 11


def sweep_grid(
    system: NumericSystem,
    base: np.ndarray,
    swept: list[int],
    axes: list[np.ndarray],
    q_start: np.ndarray,
    tolerance: float = 1e-10,
) -> BatchResult:
    """Every configuration of the grid ``axes`` (input ``swept[d]`` takes the values ``axes[d]``;
    the other inputs stay at ``base``), starting from ``q_start``, solved at the corner where
    every axis is at its first value.

    Coarse to fine: the sub-grid of every other value along each axis that has at least
    ``2 * FEWEST_VALUES - 1`` values (both ends kept) is solved first (recursively), then the
    grid fills the missing values one axis at a time, each fill one batch started from the
    quintic interpolation (Lagrange, three solved neighbours each side) of the solved points
    along that axis. Interpolation between solutions of one branch is a closer start than
    extrapolation, and the batches are large: the excavator's 21 x 11 x 21 grid is an
    11 x 11 x 11 continuation (slices of 1, 11 and 121 configurations), then fills of 1210
    and 2310, instead of slices of 1, 21 and 231. The coarsest grid is solved by slice
    continuation (``_Grid.continuation``). Returns q of shape (n, *counts) and
    per-configuration convergence, residuals and iterations of shape ``counts``.
    """
    return _Grid(system, base, swept, tolerance).solve(list(axes), np.asarray(q_start, dtype=float))


def _lagrange_weights(values: np.ndarray, known: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """(len(wanted), len(known)) weights of the quintic Lagrange interpolation of each wanted
    index from six known indices around it: three on either side, or, near an end of the
    axis, the six nearest (fewer when fewer are known). (Quintic rather than cubic: the
    excavator's fills then need 1.9 Newton iterations on average instead of 2.2.)"""
    weights = np.zeros((len(wanted), len(known)))
    for row, index in enumerate(wanted):
        first = int(np.clip(np.searchsorted(known, index) - 3, 0, max(0, len(known) - 6)))
        use = np.arange(first, min(len(known), first + 6))
        x, nodes = values[index], values[known[use]]
        for j, node in enumerate(nodes):
            others = np.delete(nodes, j)
            weights[row, use[j]] = np.prod((x - others) / (node - others))
    return weights


def _every_other(count: int) -> np.ndarray:
    """Indices 0, 2, 4, ... of an axis of ``count`` values, the last index always included."""
    picks = np.arange(0, count, 2)
    return picks if picks[-1] == count - 1 else np.append(picks, count - 1)


class _Grid:
    """The grid solves of :func:`sweep_grid` for one system, base input and swept set."""

    def __init__(self, system: NumericSystem, base: np.ndarray, swept: list[int], tolerance: float) -> None:
        self.system, self.base, self.swept, self.tolerance = system, np.asarray(base, dtype=float), swept, tolerance
        self.block_solve = BlockSolve(system) if system.native is None else None
        self.sequential = Solver(system, SolverOptions(tolerance=tolerance))

    def inputs(self, values: list[np.ndarray]) -> np.ndarray:
        """Inputs (n_inputs, K) of the configurations whose swept inputs are ``values[d]`` (K,)."""
        u = np.repeat(self.base[:, None], len(values[0]), axis=1)
        for d, v in enumerate(values):
            u[self.swept[d]] = v
        return u

    def batch(self, values: list[np.ndarray], guess: np.ndarray) -> BatchResult:
        """Solve the configurations ``values`` (swept inputs, each (K,)) from ``guess`` (n, K)."""
        u = self.inputs(values)
        if self.system.native is None and len(values[0]) < SMALL_BATCH:  # few: plain-float Python one by one is quicker
            return _one_by_one(self.sequential, u, guess)
        done = solve_batch(self.system, u, guess, self.tolerance, block_solve=self.block_solve)
        missed = np.flatnonzero(~done.converged)
        if self.system.native is not None and len(missed):  # full Newton in C failed: the fallbacks of the sequential solver
            retry = _one_by_one(self.sequential, u[:, missed], guess[:, missed])
            done.q[:, missed], done.converged[missed] = retry.q, retry.converged
            done.residuals[missed], done.iterations[missed] = retry.residuals, retry.iterations
        return done


    def solve(self, axes: list[np.ndarray], q_start: np.ndarray) -> BatchResult:
        counts = [len(a) for a in axes]
        if max(counts) < 2 * FEWEST_VALUES - 1:
            return self.continuation(axes, q_start)
        picks = [_every_other(c) if c >= 2 * FEWEST_VALUES - 1 else np.arange(c) for c in counts]
        coarse = self.solve([a[p] for a, p in zip(axes, picks)], q_start)
        result = _unsolved(len(q_start), counts)
        _store(result, np.ix_(*picks), coarse)
        for d in range(len(counts)):
            wanted = np.setdiff1d(np.arange(counts[d]), picks[d])
            if not len(wanted):
                continue
            known = [np.arange(c) if e < d else picks[e] for e, c in enumerate(counts)]
            block = np.ix_(*known)
            # unconverged neighbours take no part: NaN, then the nearest solved value
            solved = np.where(result.converged[block], result.q[(slice(None), *block)], np.nan)
            guess = _along(_lagrange_weights(axes[d], picks[d], wanted), solved, d)
            nearest = np.abs(axes[d][wanted][:, None] - axes[d][picks[d]][None, :]).argmin(axis=1)
            guess = np.where(np.isfinite(guess), guess, np.take(solved, nearest, axis=1 + d))
            target = [*known[:d], wanted, *known[d + 1 :]]
            mesh = np.meshgrid(*(a[i] for a, i in zip(axes, target)), indexing="ij")
            flat = self.system.project(guess).reshape(len(q_start), -1)
            _store(result, np.ix_(*target), self.batch([m.ravel() for m in mesh], flat), mesh[0].shape)
            picks[d] = np.arange(counts[d])
        return result

    def continuation(self, axes: list[np.ndarray], q_start: np.ndarray) -> BatchResult:
        """Slice continuation: the corner from ``q_start``, then the grid grows one axis at a
        time, slice j along axis d solved in one batch from the quadratic extrapolation of
        slices j-1, j-2, j-3."""
        counts = [len(a) for a in axes]
        result = _unsolved(len(q_start), counts)

        def solve(index: tuple, guess: np.ndarray) -> None:
            done = self.batch([a[i] for a, i in zip(axes, index)], guess)
            _store(result, index, done)

        solve(tuple(np.zeros(1, dtype=int) for _ in counts), q_start[:, None])
        q = result.q
        for d in range(len(counts)):
            # the solved part: every index < counts[e] for e < d, index 0 beyond
            grid = np.indices(counts[:d]).reshape(d, -1) if d else np.zeros((0, 1), dtype=int)
            rest = [np.zeros(grid.shape[1], dtype=int) for _ in range(len(counts) - d - 1)]
            for j in range(1, counts[d]):

                def at(step: int, grid=grid, rest=rest) -> tuple:
                    return (*grid, np.full(grid.shape[1], step), *rest)

                previous = q[(slice(None), *at(j - 1))]
                if j == 1:
                    guess = previous
                elif j == 2:
                    guess = 2 * previous - q[(slice(None), *at(0))]
                else:  # quadratic extrapolation from the last three slices
                    guess = 3 * previous - 3 * q[(slice(None), *at(j - 2))] + q[(slice(None), *at(j - 3))]
                guess = np.where(np.isfinite(guess), self.system.project(guess), previous)
                solve(at(j), guess)
        return result


def _along(weights: np.ndarray, values: np.ndarray, axis: int) -> np.ndarray:
    """``weights`` (m, k) applied along grid axis ``axis`` of ``values`` (n, ..., k, ...)."""
    return np.moveaxis(np.tensordot(weights, values, axes=([1], [1 + axis])), 0, 1 + axis)


def _unsolved(n: int, counts: list[int]) -> BatchResult:
    """A grid result with nothing solved yet: q NaN (n, *counts), not converged, residuals inf."""
    return BatchResult(
        np.full((n, *counts), np.nan), np.zeros(counts, dtype=bool), np.full(counts, np.inf), np.zeros(counts, dtype=int)
    )


def _store(result: BatchResult, index: tuple, done: BatchResult, shape: tuple | None = None) -> None:
    """Write a solved batch (flat, or of the grid shape of ``index``) into ``result`` at ``index``."""
    n = result.q.shape[0]
    grid_shape = shape if shape is not None else done.converged.shape
    result.q[(slice(None), *index)] = done.q.reshape(n, *grid_shape)
    result.converged[index] = done.converged.reshape(grid_shape)
    result.residuals[index] = done.residuals.reshape(grid_shape)
    result.iterations[index] = done.iterations.reshape(grid_shape)
