"""Phi_q x = b for a batch of configurations, block by block over Phi_q's block-triangular form
(what the batched Newton of sweeps and the sensitivities' Python path solve with)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.sparse import csr_matrix

from kinegen.symbolic.blocks import block_triangular

if TYPE_CHECKING:
    from kinegen.runtime.system import NumericSystem


class BlockSolve:
    """Phi_q x = b for a batch, by forward substitution over the diagonal blocks.

    Blocks of the same size at the same level of the dependency order (no block of a level
    needs another of that level) are solved together, one batched solve per (level, size)
    (``numpy.linalg.solve``; a division for the 1 x 1 blocks, 31 of the excavator's 41); the
    coupling to earlier blocks is one sparse product per group. A configuration whose block
    is singular gets NaN (it leaves the Newton batch unconverged), not an error for the batch.
    """

    def __init__(self, system: NumericSystem) -> None:
        self._plan(system.jac_rows, system.jac_cols, len(system.constraint_names), system.n_velocity, f"{system.model}/{system.case}")

    @classmethod
    def for_pattern(cls, rows: np.ndarray, cols: np.ndarray, n: int, name: str = "the matrix") -> BlockSolve:
        """The solver of any square n x n matrix with the sparsity pattern (rows, cols) (values given
        to :meth:`solve` in that order): e.g. a transposed Phi_q, pattern (cols, rows)."""
        solver = cls.__new__(cls)
        solver._plan(np.asarray(rows), np.asarray(cols), n, n, name)
        return solver

    def _plan(self, rows: np.ndarray, cols: np.ndarray, m: int, n: int, name: str) -> None:
        blocks = block_triangular((m, n), rows, cols)
        if blocks is None:
            raise ValueError(f"{name}: Phi_q is not square or structurally singular")
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
            group_rows = np.array([blocks[b].rows for b in members]).ravel()  # (G * size,), block by block
            group_cols = np.array([blocks[b].cols for b in members]).ravel()
            slot_of_row = {r: i for i, r in enumerate(group_rows)}
            slot_of_col = {c: i for i, c in enumerate(group_cols)}
            in_rows = np.isin(rows, group_rows)
            inside = in_rows & np.isin(cols, group_cols)
            diag, off = np.flatnonzero(inside), np.flatnonzero(in_rows & ~inside)
            diag_slots = np.array([[slot_of_row[r], slot_of_col[c]] for r, c in zip(rows[diag], cols[diag])], dtype=np.intp)
            # block g's entry (i, j) sits at (g, i, j) of the (G, size, size) stack
            diag_g, diag_r, diag_c = diag_slots[:, 0] // size, diag_slots[:, 0] % size, diag_slots[:, 1] % size
            coupling = csr_matrix(
                (np.ones(len(off)), ([slot_of_row[r] for r in rows[off]], np.arange(len(off)))),
                shape=(len(group_rows), len(off)),
            )
            self.plan.append(
                _Group(size, len(members), group_rows, group_cols, diag, diag_g, diag_r, diag_c, off, cols[off], coupling)
            )

    def solve(self, values: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """x (n, K) with Phi_q(values[:, k]) x[:, k] = rhs[:, k]; or, for rhs (n, K, r), r right-hand
        sides per configuration at once: x (n, K, r)."""
        k, single = rhs.shape[1], rhs.ndim == 2
        r = 1 if single else rhs.shape[2]
        x = np.zeros((self.n, k, r))
        rhs = rhs.reshape(len(rhs), k, r)
        for group in self.plan:
            right = rhs[group.rows].copy()  # (G * size, K, r)
            if len(group.off):
                right -= (group.coupling @ (values[group.off, :, None] * x[group.off_cols]).reshape(len(group.off), -1)).reshape(right.shape)
            if group.size == 1:
                matrix = np.zeros((group.count, k))
                matrix[group.diag_g] = values[group.diag]
                x[group.cols] = right / matrix[:, :, None]
                continue
            matrix = np.zeros((k, group.count, group.size, group.size))
            matrix[:, group.diag_g, group.diag_r, group.diag_c] = values[group.diag].T
            solved = _solve(matrix, right.transpose(1, 0, 2).reshape(k, group.count, group.size, r))
            x[group.cols] = solved.reshape(k, -1, r).transpose(1, 0, 2)
        return x[:, :, 0] if single else x


@dataclass(frozen=True)
class _Group:
    """Diagonal blocks of one size at one level, and where their entries come from."""

    size: int
    count: int
    rows: np.ndarray  #: (count * size,) rows of Phi_q, block by block
    cols: np.ndarray  #: (count * size,) columns, matched to rows
    diag: np.ndarray  #: indices into the Phi_q values of the blocks' entries
    diag_g: np.ndarray  #: ... their block
    diag_r: np.ndarray  #: ... their row in the block
    diag_c: np.ndarray  #: ... their column in the block
    off: np.ndarray  #: indices into the Phi_q values of entries coupling to earlier blocks
    off_cols: np.ndarray  #: ... their columns
    coupling: csr_matrix  #: (count * size, n_off) row of each coupling entry


def _solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solutions for a stack of square systems; NaN for a singular one (not an error for the batch)."""
    try:
        return np.linalg.solve(matrix, rhs)
    except np.linalg.LinAlgError:
        flat = matrix.reshape(-1, *matrix.shape[-2:]).copy()
        singular = np.linalg.matrix_rank(flat) < matrix.shape[-1]
        flat[singular] = np.eye(matrix.shape[-1])
        solved = np.linalg.solve(flat, rhs.reshape(len(flat), -1, 1))
        solved[singular] = np.nan
        return solved.reshape(rhs.shape)
