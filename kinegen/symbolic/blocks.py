"""Block-triangular form of a sparse square matrix (Dulmage-Mendelsohn, fine part).

A maximum bipartite matching of rows to columns puts a nonzero on every diagonal entry;
the strongly connected components of the resulting dependency graph are the diagonal
blocks, in the order in which they can be solved. Then det = +-prod(det(blocks)), and a
singularity lives in the blocks whose determinant vanishes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Block:
    """One diagonal block: its row and column indices (matched pairwise)."""

    rows: tuple[int, ...]
    cols: tuple[int, ...]

    @property
    def size(self) -> int:
        return len(self.rows)


def block_triangular(shape: tuple[int, int], rows: np.ndarray, cols: np.ndarray) -> list[Block] | None:
    """Diagonal blocks of the block-triangular form, in solve order.

    ``rows``/``cols`` give the sparsity pattern. Returns None when the matrix is not
    square or is structurally singular (no perfect matching).
    """
    from scipy.sparse import csr_matrix  # (SciPy's sparse graphs: imported when first needed)
    from scipy.sparse.csgraph import connected_components, maximum_bipartite_matching

    m, n = shape
    if m != n or m == 0:
        return None
    rows, cols = np.asarray(rows), np.asarray(cols)
    pattern = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=shape)
    column_of_row = maximum_bipartite_matching(pattern, perm_type="column")
    if (column_of_row < 0).any():
        return None
    row_of_column = np.empty(n, dtype=int)
    row_of_column[column_of_row] = np.arange(m)
    # row i needs the unknown that row j is matched to: edge i -> j
    needs = csr_matrix((np.ones(len(rows)), (rows, row_of_column[cols])), shape=(m, m))
    count, labels = connected_components(needs, directed=True, connection="strong")
    # solve order: a component comes after every component it needs (Kahn's algorithm)
    required = [set() for _ in range(count)]
    for i, j in zip(rows, row_of_column[cols]):
        if labels[i] != labels[j]:
            required[labels[i]].add(labels[j])
    order, done = [], set()
    while len(order) < count:
        ready = sorted(c for c in range(count) if c not in done and required[c] <= done)
        order += ready
        done.update(ready)
    members = [np.flatnonzero(labels == c) for c in order]
    return [Block(tuple(int(i) for i in r), tuple(int(column_of_row[i]) for i in r)) for r in members]
