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

from kinegen.analysis.blocks import block_triangular
from kinegen.errors import KinegenError
from kinegen.runtime.solver import Solver, SolverOptions
from kinegen.runtime.system import NumericSystem


class BlockSolve:
    """Phi_q x = b for a batch, by forward substitution over the diagonal blocks.

    Blocks of the same size at the same level of the dependency order (no block of a level
    needs another of that level) are solved together: one batched ``numpy.linalg.solve``
    per (level, size), a division for the 1 x 1 blocks (31 of the excavator's 41).
    """

    def __init__(self, system: NumericSystem) -> None:
        rows, cols = system.jac_rows, system.jac_cols
        n = system.n_velocity
        blocks = block_triangular((len(system.constraint_names), n), rows, cols)
        if blocks is None:
            raise ValueError(f"{system.model}/{system.case}: Phi_q is not square or structurally singular")
        self.n = n
        block_of_col = np.empty(n, dtype=np.intp)
        block_of_row = np.empty(n, dtype=np.intp)
        for b, block in enumerate(blocks):
            block_of_col[list(block.cols)] = b
            block_of_row[list(block.rows)] = b
        levels: list[int] = []
        for b in range(len(blocks)):
            needs = set(block_of_col[cols[block_of_row[rows] == b]]) - {b}
            levels.append(1 + max((levels[x] for x in needs), default=-1))
        groups: dict[tuple[int, int], list[int]] = {}
        for b, block in enumerate(blocks):
            groups.setdefault((levels[b], block.size), []).append(b)
        self.plan = []
        for (_, size), members in sorted(groups.items()):
            group_rows = np.array([blocks[b].rows for b in members])  # (G, size)
            group_cols = np.array([blocks[b].cols for b in members])
            slot_of_row = {r: (g, i) for g, b in enumerate(members) for i, r in enumerate(blocks[b].rows)}
            slot_of_col = {c: (g, i) for g, b in enumerate(members) for i, c in enumerate(blocks[b].cols)}
            in_rows = np.isin(rows, group_rows.ravel())
            inside = in_rows & np.isin(cols, group_cols.ravel())
            diag, off = np.flatnonzero(inside), np.flatnonzero(in_rows & ~inside)
            diag_g = np.array([slot_of_row[r][0] for r in rows[diag]], dtype=np.intp)
            diag_r = np.array([slot_of_row[r][1] for r in rows[diag]], dtype=np.intp)
            diag_c = np.array([slot_of_col[c][1] for c in cols[diag]], dtype=np.intp)
            off_slot = np.array([slot_of_row[r][0] * size + slot_of_row[r][1] for r in rows[off]], dtype=np.intp)
            self.plan.append((size, group_rows, group_cols, diag, diag_g, diag_r, diag_c, off, off_slot, cols[off]))

    def solve(self, values: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """x (n, K) with Phi_q(values[:, k]) x[:, k] = rhs[:, k]."""
        k = rhs.shape[1]
        x = np.zeros((self.n, k))
        for size, group_rows, group_cols, diag, dg, dr, dc, off, off_slot, off_col in self.plan:
            right = rhs[group_rows.ravel()]  # (G * size, K)
            if len(off):
                np.add.at(right, off_slot, -values[off] * x[off_col])
            if size == 1:
                matrix = np.zeros((len(group_rows), k))
                matrix[dg] = values[diag]
                x[group_cols.ravel()] = right / matrix
                continue
            matrix = np.zeros((k, len(group_rows), size, size))
            matrix[:, dg, dr, dc] = values[diag].T
            solved = np.linalg.solve(matrix, right.T.reshape(k, len(group_rows), size, 1))
            x[group_cols.ravel()] = solved.reshape(k, -1).T
        return x


#: below this many configurations a batch is solved one by one (NumPy's per-call overhead wins)
SMALL_BATCH = 8


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
    """Full-step Newton on every column of ``q0`` (n, K) for inputs ``u`` (n_inputs, K)."""
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


def sweep_grid(
    system: NumericSystem,
    base: np.ndarray,
    swept: list[int],
    axes: list[np.ndarray],
    q_start: np.ndarray,
    tolerance: float = 1e-10,
) -> BatchResult:
    """Every configuration of the grid ``axes`` (input ``swept[d]`` takes the values ``axes[d]``;
    the other inputs stay at ``base``), by batched continuation across the grid.

    The corner (every axis at its first value) is solved from ``q_start``; then the grid
    grows one axis at a time: slice j along axis d is solved in one batch, one grid step
    from the last, starting from the quadratic extrapolation of slices j-1, j-2, j-3. Returns q of shape (n, *counts)
    and per-configuration convergence, residuals and iterations of shape ``counts``.
    """
    counts = [len(a) for a in axes]
    n = system.n_stored
    block_solve = BlockSolve(system)
    q = np.full((n, *counts), np.nan)
    converged = np.zeros(counts, dtype=bool)
    residuals = np.full(counts, np.inf)
    iterations = np.zeros(counts, dtype=int)

    def inputs(index: tuple) -> np.ndarray:
        """Inputs (n_inputs, K) of the grid points ``index`` (a tuple of index arrays)."""
        u = np.repeat(np.asarray(base, dtype=float)[:, None], len(index[0]), axis=1)
        for d, i in enumerate(index):
            u[swept[d]] = axes[d][i]
        return u

    sequential = Solver(system, SolverOptions(tolerance=tolerance))

    def solve(index: tuple, guess: np.ndarray) -> None:
        u = inputs(index)
        if len(index[0]) < SMALL_BATCH:  # few configurations: the plain-float code one by one is quicker
            result = _one_by_one(sequential, u, guess)
        else:
            result = solve_batch(system, u, guess, tolerance, block_solve=block_solve)
        q[(slice(None), *index)] = result.q
        converged[index], residuals[index], iterations[index] = result.converged, result.residuals, result.iterations

    corner = tuple(np.zeros(1, dtype=int) for _ in counts)
    solve(corner, np.asarray(q_start, dtype=float)[:, None])
    for d in range(len(counts)):
        # the solved part: every index < counts[e] for e < d, index 0 beyond
        shape = counts[:d]
        grid = np.indices(shape).reshape(d, -1) if d else np.zeros((0, 1), dtype=int)
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
            if system.parametrization.stores_quaternion:  # extrapolated quaternions: back to unit length
                for s_off, _ in system.bodies.values():
                    part = guess[s_off + 3 : s_off + 7]
                    guess[s_off + 3 : s_off + 7] = part / np.linalg.norm(part, axis=0)
            guess = np.where(np.isfinite(guess), guess, previous)
            solve(at(j), guess)
    return BatchResult(q, converged, residuals, iterations)
