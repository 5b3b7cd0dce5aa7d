"""The Python side of ``trajectory.c``: the solver's step loop in C, for compiled systems.

:meth:`kinegen.runtime.solver.Solver.solve` hands a run of time steps to
:func:`run_steps` when the system carries compiled code; the C loop solves steps until the
first one that needs anything beyond the usual step (then Python solves that step with its
fallbacks and refinements and hands the next ones back). Phi_q is factorized by the same
LAPACK routines as :mod:`kinegen.runtime.linear` (SciPy's ``cython_lapack``, by function
pointer) with the same dense or band layout, so both paths make the same decisions.
"""

from __future__ import annotations

import ctypes
from functools import cache
from typing import TYPE_CHECKING

import numpy as np

from kinegen.runtime.linear import BandLU

if TYPE_CHECKING:
    from kinegen.runtime.solver import Solver

_INT_P = ctypes.POINTER(ctypes.c_int)
_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


class _Problem(ctypes.Structure):
    """``struct kinegen_problem`` of trajectory.c, field by field."""

    _fields_ = [
        ("n_stored", ctypes.c_int), ("n", ctypes.c_int), ("n_inputs", ctypes.c_int), ("entries", ctypes.c_int),
        ("flat", _INT_P), ("cols", _INT_P),
        ("band", ctypes.c_int), ("kl", ctypes.c_int), ("ku", ctypes.c_int), ("ld", ctypes.c_int),
        ("row_order", _INT_P), ("col_order", _INT_P),
        ("n_positions", ctypes.c_int), ("n_rotations", ctypes.c_int),
        ("position_q", _INT_P), ("position_v", _INT_P), ("rotation_q", _INT_P), ("rotation_v", _INT_P),
        ("phi_jac", ctypes.c_void_p), ("nu", ctypes.c_void_p), ("gamma", ctypes.c_void_p),
        ("getrf", ctypes.c_void_p), ("getrs", ctypes.c_void_p), ("gbtrf", ctypes.c_void_p),
        ("gbtrs", ctypes.c_void_p), ("gecon", ctypes.c_void_p), ("gbcon", ctypes.c_void_p),
        ("tolerance", ctypes.c_double), ("singular_tolerance", ctypes.c_double),
        ("divergence_limit", ctypes.c_double), ("chord_rate", ctypes.c_double),
        ("jump_ratio", ctypes.c_double), ("jump_floor", ctypes.c_double),
        ("max_iterations", ctypes.c_int), ("predictor", ctypes.c_int), ("chord", ctypes.c_int),
        ("polish", ctypes.c_int), ("keep_branch", ctypes.c_int), ("condition", ctypes.c_int),
    ]  # fmt: skip


@cache
def _lapack() -> dict[str, int]:
    """Addresses of the LAPACK routines SciPy exports for Cython (``scipy.linalg.cython_lapack``)."""
    from scipy.linalg import cython_lapack

    get_name = ctypes.pythonapi.PyCapsule_GetName
    get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
    get_pointer.restype, get_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
    capsules = cython_lapack.__pyx_capi__
    return {
        name: get_pointer(capsules[name], get_name(capsules[name]))
        for name in ("dgetrf", "dgetrs", "dgbtrf", "dgbtrs", "dgecon", "dgbcon")
    }


def _ints(values) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=np.intc)


class CompiledSteps:
    """The C loop for one solver (its factorization layout and options), built once."""

    def __init__(self, solver: Solver, library: ctypes.CDLL, case: str) -> None:
        system, options, linear = solver.system, solver.options, solver.linear
        n = system.n_velocity
        rows, cols = np.asarray(system.jac_rows), np.asarray(system.jac_cols)
        self._keep: list[np.ndarray] = []  # arrays the C struct points into

        def pointer(values) -> ctypes._Pointer:
            array = _ints(values)
            self._keep.append(array)
            return array.ctypes.data_as(_INT_P)

        problem = _Problem()
        problem.n_stored, problem.n, problem.n_inputs, problem.entries = system.n_stored, n, system.n_inputs, len(rows)
        problem.cols = pointer(cols)
        if isinstance(linear, BandLU):
            problem.band, problem.kl, problem.ku, problem.ld = 1, linear.kl, linear.ku, 2 * linear.kl + linear.ku + 1
            problem.flat = pointer(linear.band_index)
            problem.row_order, problem.col_order = pointer(linear.row_order), pointer(linear.col_order)
        else:  # column-major dense matrix
            problem.band, problem.kl, problem.ku, problem.ld = 0, 0, 0, n
            problem.flat = pointer(cols * n + rows)
            problem.row_order = problem.col_order = pointer(np.arange(n))
        indices = system.retraction_indices
        if indices is None:
            problem.n_positions = problem.n_rotations = 0
            problem.position_q = problem.position_v = problem.rotation_q = problem.rotation_v = pointer([0])
        else:
            position_q, position_v, rotation_q, rotation_v = indices
            problem.n_positions, problem.n_rotations = len(position_q), rotation_q.shape[1]
            problem.position_q, problem.position_v = pointer(position_q), pointer(position_v)
            problem.rotation_q, problem.rotation_v = pointer(rotation_q.ravel()), pointer(rotation_v.ravel())
        for field, symbol in (("phi_jac", "phi_jac"), ("nu", "nu"), ("gamma", "gamma")):
            setattr(problem, field, ctypes.cast(getattr(library, f"{symbol}_{case}"), ctypes.c_void_p).value)
        for field, address in _lapack().items():
            setattr(problem, field[1:], address)
        problem.tolerance, problem.singular_tolerance = options.tolerance, options.singular_tolerance
        problem.divergence_limit, problem.chord_rate = options.divergence_limit, options.chord_rate
        problem.jump_ratio, problem.jump_floor = options.jump_ratio, options.jump_floor
        problem.max_iterations, problem.predictor, problem.chord = options.max_iterations, options.predictor, solver.chord
        problem.polish, problem.keep_branch = options.polish, options.keep_branch
        problem.condition = options.condition == "estimate"
        self.problem = problem
        self._function = library.kinegen_trajectory
        self._function.restype = ctypes.c_int
        self._function.argtypes = [ctypes.POINTER(_Problem), ctypes.c_int, ctypes.c_int] + [ctypes.c_void_p] * 10 + [ctypes.c_int]

    def run(
        self,
        first: int,
        times: np.ndarray,
        inputs: tuple[np.ndarray, np.ndarray, np.ndarray],
        out: tuple[np.ndarray, ...],
        sign: int,
    ) -> int:
        """Steps ``first``, ``first + 1``, ... from the solved step ``first - 1`` (whose det(Phi_q)
        has ``sign``) into ``out`` = (q, v, a, iterations, residuals, conditions), arrays of
        shape (steps, ...), C-contiguous, float64 (iterations: C int). ``inputs`` = (u, ud,
        udd), each (steps, n_inputs). Returns the first step not solved."""
        arrays = [np.ascontiguousarray(times, dtype=float), *(np.ascontiguousarray(x, dtype=float) for x in inputs)]
        return self._function(
            ctypes.byref(self.problem), first, len(times), *(a.ctypes.data for a in arrays), *(o.ctypes.data for o in out), sign
        )


def usable(solver: Solver) -> bool:
    """Whether the C loop can stand in for the Python one: compiled code, a square Phi_q, and
    a condition number that it can record (the estimate, or none)."""
    native = solver.system.native
    return (
        native is not None
        and hasattr(native, "library")
        and not solver.redundant
        and solver.options.condition in ("estimate", "none")
    )
