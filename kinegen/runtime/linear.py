"""LU factorizations of Phi_q with its constant sparsity pattern, chosen once per system.

* :class:`DenseLU`: LAPACK ``getrf``/``getrs`` on the dense matrix (small systems).
* :class:`BandLU`: rows and columns permuted once (a maximum matching puts non-zeros on the
  diagonal, then reverse Cuthill-McKee narrows the band of the symmetrized pattern) and
  LAPACK ``gbtrf``/``gbtrs`` on the band (partial pivoting within the band). A chain of N
  bodies has a band of ~2 bodies' coordinates, so the cost per factorization grows as N, not N^3.

:func:`choose` takes the band when its estimated cost is under a quarter of the dense one.
Both take the Jacobian as its *values* at the pattern (``rows``, ``cols``), as generated.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np


@functools.cache
def _lapack() -> dict[str, Any]:
    """LAPACK's getrf, getrs, gecon, gbtrf, gbtrs, gbcon for doubles by name, through SciPy (imported
    when first needed: a solve in C never needs them, and SciPy's linear algebra is ~0.3 s to import)."""
    import scipy.linalg

    names = ("getrf", "getrs", "gecon", "gbtrf", "gbtrs", "gbcon")
    return dict(zip(names, scipy.linalg.get_lapack_funcs(names, dtype=np.float64)))


def condition_number(matrix: np.ndarray) -> float:
    """The 2-norm condition number sigma_max / sigma_min of a dense square matrix (inf if singular)."""
    s = np.linalg.svd(matrix, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def _one_norm(matrix: np.ndarray) -> float:
    return float(np.abs(matrix).sum(axis=0).max())


class Pattern:
    """Phi_q given as its values at the constant pattern (``rows``, ``cols``)."""

    def __init__(self, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> None:
        self.shape = shape
        self._dense_flat = np.asarray(rows) * shape[1] + np.asarray(cols)

    def dense(self, values: Any) -> np.ndarray:
        """The dense matrix of ``values``."""
        matrix = np.zeros(self.shape)
        matrix.flat[self._dense_flat] = values
        return matrix


class DenseLU(Pattern):
    """Dense LU with partial pivoting."""

    kind = "dense"

    def factor(self, values: Any) -> tuple[tuple, np.ndarray]:
        """(factors, |diagonal of U|)."""
        lu, piv, info = _lapack()["getrf"](self.dense(values), overwrite_a=True)
        return (lu, piv), abs(lu.diagonal()) if info == 0 else np.zeros(1)

    def solve(self, factors: tuple, rhs: np.ndarray) -> np.ndarray:
        """Phi_q^-1 rhs; rhs (n,) or (n, k) (many columns: in Fortran order, as LAPACK takes them --
        a C-ordered (84, 4) right-hand side took 3.3 ms through f2py instead of 17 us)."""
        x, _ = _lapack()["getrs"](factors[0], factors[1], np.asfortranarray(rhs) if np.ndim(rhs) == 2 else rhs)
        return x

    def rcond(self, factors: tuple, values: Any) -> float:
        """Reciprocal 1-norm condition estimate from the factors."""
        rcond, _ = _lapack()["gecon"](factors[0], _one_norm(self.dense(values)), norm="1")
        return float(rcond)

    def bound(self, factors: tuple, rhs: np.ndarray) -> np.ndarray:
        """An upper bound on |Phi_q^-1| rhs for rhs >= 0 (entry by entry): :func:`comparison` factors solved."""
        return self.solve((comparison(factors[0], 0), factors[1]), rhs)


class BandLU(Pattern):
    """Band LU of the permuted matrix (see the module docstring)."""

    kind = "band"

    def __init__(self, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int], row_order, col_order) -> None:
        super().__init__(rows, cols, shape)
        n = shape[0]
        self.row_order, self.col_order = np.asarray(row_order), np.asarray(col_order)
        new_row = np.empty(n, dtype=np.intp)
        new_row[self.row_order] = np.arange(n)
        new_col = np.empty(n, dtype=np.intp)
        new_col[self.col_order] = np.arange(n)
        i, j = new_row[np.asarray(rows)], new_col[np.asarray(cols)]
        self.kl, self.ku = int(max(0, (i - j).max())), int(max(0, (j - i).max()))
        self._ldab = 2 * self.kl + self.ku + 1
        #: where each value goes in LAPACK's band storage (Fortran order, leading dimension
        #: 2 kl + ku + 1): AB[kl + ku + i - j, j] = A[i, j], i and j in the permuted order
        self.band_index = (self.kl + self.ku + i - j) + j * self._ldab

    def factor(self, values: Any) -> tuple[tuple, np.ndarray]:
        """(factors, |diagonal of U|)."""
        band = np.zeros((self._ldab, self.shape[1]), order="F")
        band.ravel(order="F")[self.band_index] = values
        lu, piv, info = _lapack()["gbtrf"](band, self.kl, self.ku, overwrite_ab=True)
        return (lu, piv), abs(lu[self.kl + self.ku]) if info == 0 else np.zeros(1)

    def solve(self, factors: tuple, rhs: np.ndarray) -> np.ndarray:
        """As DenseLU.solve, on the band (many columns in Fortran order)."""
        permuted = rhs[self.row_order]
        x, _ = _lapack()["gbtrs"](factors[0], self.kl, self.ku, np.asfortranarray(permuted) if permuted.ndim == 2 else permuted, factors[1])
        out = np.empty_like(x)
        out[self.col_order] = x
        return out

    def rcond(self, factors: tuple, values: Any) -> float:
        """Reciprocal 1-norm condition estimate from the factors (permutations keep the 1-norm)."""
        rcond, _ = _lapack()["gbcon"](self.kl, self.ku, factors[0], factors[1], _one_norm(self.dense(values)), norm="1")
        return float(rcond)

    def bound(self, factors: tuple, rhs: np.ndarray) -> np.ndarray:
        """As DenseLU.bound, on the band (U's diagonal is the band's row kl + ku)."""
        return self.solve((comparison(factors[0], self.kl + self.ku), factors[1]), rhs)


def comparison(lu: np.ndarray, diagonal: int) -> np.ndarray:
    """LAPACK's LU factors (getrf's, or gbtrf's band with U's diagonal in row ``diagonal``) turned
    into their comparison matrices' -- U's diagonal as absolute values, every other entry (L's
    multipliers, U's off-diagonal) as negated absolute values -- so that the factors' solve
    (getrs, gbtrs) adds where it subtracted: it then gives M(U)^-1 M(L_n)^-1 P_n ... M(L_1)^-1 P_1 b,
    at least |Phi_q^-1| b for b >= 0, since |T^-1| <= M(T)^-1 for a triangular T (Higham,
    Accuracy and Stability of Numerical Algorithms, 2nd ed., Theorem 8.12) and each elimination
    step's inverse I + l e_k^T is bounded by I + |l| e_k^T. Coarse: every cancellation is lost."""
    out = -np.abs(lu)
    if diagonal == 0:
        np.fill_diagonal(out, np.abs(lu.diagonal()))
    else:
        out[diagonal] = np.abs(lu[diagonal])
    return np.asfortranarray(out)


def band_orders(rows: np.ndarray, cols: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Row and column orders giving a narrow band, or None (no perfect matching: structurally singular)."""
    import scipy.sparse
    from scipy.sparse.csgraph import maximum_bipartite_matching, reverse_cuthill_mckee

    pattern = scipy.sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    match = maximum_bipartite_matching(pattern, perm_type="column")  # match[i] = column of row i
    if np.any(match < 0):
        return None
    # matched pattern: row i -> position match[i], so the diagonal is structurally non-zero
    matched = scipy.sparse.csr_matrix((np.ones(len(rows)), (match[rows], cols)), shape=(n, n))
    order = reverse_cuthill_mckee((matched + matched.T).tocsr(), symmetric_mode=True)
    inverse_match = np.empty(n, dtype=np.intp)
    inverse_match[match] = np.arange(n)  # original row sitting at matched position p
    return inverse_match[order], order


def choose(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> DenseLU | BandLU:
    """The cheaper factorization for this pattern (square systems; dense for small ones)."""
    rows, cols = np.asarray(rows), np.asarray(cols)
    n = shape[0]
    if shape[0] != shape[1] or n < 24:
        return DenseLU(rows, cols, shape)
    orders = band_orders(rows, cols, n)
    if orders is None:
        return DenseLU(rows, cols, shape)
    band = BandLU(rows, cols, shape, *orders)
    band_cost = n * (band.kl + 1) * (band.kl + band.ku + 1)
    return band if band_cost < 0.25 * n**3 / 3 else DenseLU(rows, cols, shape)
