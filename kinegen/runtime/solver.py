"""Newton-Raphson position solve, velocity and acceleration solves over a time grid.

At each time point: predict q from the previous step (q, v, a), Newton-Raphson on
Phi(q, u) = 0 until max|Phi| <= tolerance (full steps; when they fail, a backtracking
line search, then a homotopy from the starting pose), then Phi_q v = nu and
Phi_q a = gamma with one LU factorization of Phi_q shared by both. The driver inputs u
(and their rates) come from the case's time functions or are supplied by the caller.
In the quaternion parametrization the steps, velocities and accelerations live in the
tangent space and the quaternion is updated by the exponential map.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, cached_property
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

import kinegen.runtime.linear as linear
from kinegen.collector import collector_paused
from kinegen.errors import (
    AssemblyError,
    BranchError,
    ConvergenceError,
    KinegenError,
    PrecisionError,
    SingularJacobianError,
    UnassembledError,
    UnreachableError,
)
from kinegen.progress import counter
from kinegen.runtime.buffers import Reusable
from kinegen.runtime.results import Results
from kinegen.runtime.system import NumericSystem, from_module, module_from_source
from kinegen.symbolic.blocks import Block, block_triangular

#: The largest motion a certified step may make in any velocity coordinate but a body's translations
#: (max-norm of Newton's path from the last solution, the predictor's included): a quarter turn. The
#: certificate's ball about the new solution holds the last one; beyond half a turn a rotation coordinate
#: repeats within it (its Jacobian too), where the Lipschitz constant measured over the step says nothing.
#: A translation repeats nothing, and a chain's far links move metres in a step
#: (:attr:`kinegen.runtime.system.NumericSystem.turning`).
MAX_MOTION = np.pi / 2
#: ... and the least over which omega is measured: Phi_q's change over a smaller motion is rounding
#: (a step that moves less is as certain as x0 itself; below 1e-154, |d|^2 underflows)
MIN_MOTION = 1e-12
#: Trajectories of at least this many time points get a progress bar on a terminal, shown once
#: the solve has lasted PROGRESS_DELAY seconds (a compiled solve is mostly done by then) ...
PROGRESS_STEPS = 2_000
PROGRESS_DELAY = 0.5
#: ... and the C loop runs them in pieces of this many steps (its state carries over).
NATIVE_CHUNK = 10_000


class Solution(NamedTuple):
    """A converged position: q, Newton iterations, max |Phi|, Phi_q values and Phi at q."""

    q: np.ndarray
    iterations: int
    norm: float
    values: Any
    phi: np.ndarray
    #: the motion from the start point in velocity coordinates (the sum of Newton's steps), None when unknown
    moved: np.ndarray | None = None


@dataclass
class Factors:
    """A factorized Phi_q: its values, and LU factors or (redundant systems) a pseudo-inverse."""

    values: np.ndarray
    lu: Any = None
    pinv: np.ndarray | None = None
    block_signs: np.ndarray | None = None  #: sign of det of every diagonal block (Solver._block_signs)


#: The most halvings of one step, as the C solver's KINEGEN_MAX_REFINEMENTS (kinegen_solver.h).
MAX_REFINEMENTS = 52


@dataclass(frozen=True)
class SolverOptions:
    """Tolerances and limits of the solver."""

    tolerance: float = 1e-10  #: max |Phi_i| at convergence
    max_iterations: int = 25  #: per time point, before emergency termination
    singular_tolerance: float = 1e-10  #: sigma_min / sigma_max below which Phi_q is singular
    line_search: bool = True  #: fallbacks (line search, homotopy) when full Newton steps fail
    divergence_limit: float = 1e8  #: max |Phi| beyond which Newton is stopped at once
    #: condition number recorded per step (``Results.conditions``): "none" (NaN), "estimate"
    #: (1-norm, LAPACK gecon on the LU already computed; a quarter of a compiled step) or "exact"
    #: (2-norm, sigma_max/sigma_min by SVD). The CSV, the plots, the 3-D view and ``kinegen compare``
    #: take kinegen.runtime.kinematics.condition_numbers -- the exact 2-norm's, computed when first
    #: asked for -- so by default no step pays for an estimate nothing reads
    condition: str = "none"
    #: predict each step from the previous q, v, a (else: start from the previous q)
    predictor: bool = True
    #: certify every step (see :meth:`Solver._certify`): the diagonal blocks of Phi_q keep the
    #: signs of their determinants (their assembly modes) and the Newton-Kantorovich bound
    #: alpha * omega <= 1/2 holds with omega measured over the step times ``safety``; otherwise
    #: halve the step, up to ``max_refinements`` times (at most MAX_REFINEMENTS), then raise BranchError
    keep_branch: bool = True
    safety: float = 2.0
    max_refinements: int = 12
    #: chord iterations within a time step: start from the factorization of Phi_q made at the
    #: previous step's solution (for its velocity solve) and keep a factorization while each
    #: iteration cuts max |Phi| by at least ``chord_rate``; otherwise factorize afresh. They
    #: trade factorizations for evaluations, which pays in Python when the start is far (no
    #: predictor: ~3 iterations a step). None: exactly then. (The C solver's block
    #: factorization costs about one evaluation, so compiled systems leave them off.)
    #: Their convergence is linear, so such a step always ends with the polishing correction
    #: below (a pose only just within the tolerance would carry ~cond(Phi_q) x 1e-10 errors).
    chord: bool | None = None
    chord_rate: float = 0.1
    #: after convergence, one more Newton correction with the factorization made for the
    #: velocity solve (no extra Phi_q evaluation): a residual at the tolerance becomes ~its square
    polish: bool = True
    #: "raise": a step that fails raises; "stop": the run stops there and the results end
    #: with that step marked not converged (``Results.converged``, ``Results.failure``)
    on_failure: str = "raise"
    #: use the system's compiled C (kernels and the C step loop) when it has it; False: the
    #: Python functions and loop only
    compiled: bool = True

    def __post_init__(self) -> None:
        if not 0 <= self.max_refinements <= MAX_REFINEMENTS:
            raise ValueError(f"max_refinements = {self.max_refinements}: a step is halved 0 to {MAX_REFINEMENTS} times "
                             f"(2^-{MAX_REFINEMENTS} of a step is below a double's resolution of its time)")  # fmt: skip


def describe_combination(vector: np.ndarray, names: tuple[str, ...] | list[str], threshold: float = 1e-6) -> str:
    """A null-space vector as a readable combination, largest coefficient scaled to 1."""
    coefficients = vector / np.abs(vector).max()
    first = np.flatnonzero(np.abs(coefficients) > threshold)[0]
    coefficients = coefficients * np.sign(coefficients[first])  # first term positive
    terms = []
    for c, name in zip(coefficients, names):
        if abs(c) <= threshold:
            continue
        sign = "-" if c < 0 else "+"
        magnitude = "" if abs(abs(c) - 1) < 1e-9 else f"{abs(c):.4g}*"
        terms.append(f"{sign} {magnitude}{name}")
    text = " ".join(terms)
    return text[2:] if text.startswith("+ ") else text


def _max_norm(phi: np.ndarray) -> float:
    """max |Phi_i| (0 for no rows)."""
    return float(abs(phi).max()) if phi.size else 0.0


class Solver:
    """Solves one :class:`NumericSystem` over time."""

    def __init__(self, system: NumericSystem, options: SolverOptions | None = None) -> None:
        self.options = options or SolverOptions()
        if not self.options.compiled and system.native is not None:
            system = dataclasses.replace(system, native=None)
        self.system = system
        m, n = len(system.constraint_names), system.n_velocity
        if m < n:
            raise ValueError(f"{system.model}/{system.case}: {m} constraints for {n} velocity coordinates")
        #: more equations than coordinates: a model with redundant constraints, solved by least squares
        self.redundant = m > n
        chord = self.options.chord
        #: chord iterations within a step (see SolverOptions.chord)
        self.chord = chord if chord is not None else (system.native is None and not self.options.predictor)
        #: the large arrays of a trajectory (results, the C loop's inputs), made again only when the
        #: last ones are still held (:mod:`kinegen.runtime.buffers`: no fresh pages a repeated solve)
        self._arrays = Reusable()

    @cached_property
    def linear(self) -> linear.DenseLU | linear.BandLU:
        """The factorization of Phi_q chosen once for its pattern (dense or band LU); made when first
        needed (a solve in C never needs it)."""
        system = self.system
        return linear.choose(system.jac_rows, system.jac_cols, (len(system.constraint_names), system.n_velocity))

    @cached_property
    def blocks(self) -> list[Block] | None:
        """The diagonal blocks of Phi_q's block-triangular form (None for a redundant or structurally
        singular system), found when first needed."""
        system = self.system
        return None if self.redundant else block_triangular((len(system.constraint_names), system.n_velocity), system.jac_rows, system.jac_cols)

    @cached_property
    def _blocks_by_size(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, int]]:
        """The blocks grouped by size for their determinants (:func:`_block_groups`)."""
        return _block_groups(self.blocks, self.system.jac_rows, self.system.jac_cols) if self.blocks else []

    # ---- building blocks ---------------------------------------------------------------
    def retract(self, q: np.ndarray, step: np.ndarray) -> np.ndarray:
        """q moved by ``step`` (velocity coordinates); quaternions by the exponential map."""
        return self.system.retract(q, step)

    def factorize(self, q: np.ndarray, u: np.ndarray, t: float) -> Factors:
        """Factors of Phi_q at (q, u); raises SingularJacobianError (at time t) when singular."""
        return self._factor(self.system.jac(q, u), t)

    def _factor(self, values: Any, t: float) -> Factors:
        """Factors of Phi_q given its values (a pseudo-inverse for a redundant system)."""
        values = np.asarray(values, dtype=float)  # once: the plain-float kernels give a list, which the certificate reads again
        if self.redundant:
            if not np.all(np.isfinite(values)):
                raise ConvergenceError(t, 0, float("nan"), [("Phi_q", float("nan"))])
            jacobian = self.linear.dense(values)
            _, s, _ = np.linalg.svd(jacobian)
            if s[-1] <= self.options.singular_tolerance * s[0]:  # column rank lost: a singular pose
                self.check_singular(jacobian, t)
            return Factors(values, pinv=np.linalg.pinv(jacobian, rcond=self.options.singular_tolerance))
        lu, diagonal = self.linear.factor(values)
        low, high = diagonal.min(), diagonal.max()  # NaN propagates (unlike Python's min)
        if not low > self.options.singular_tolerance * max(high, 1e-300):  # also for NaN (a NaN in Phi_q reaches U)
            if not np.all(np.isfinite(values)):
                raise ConvergenceError(t, 0, float("nan"), [("Phi_q", float("nan"))])
            self.check_singular(self.linear.dense(values), t)
        return Factors(values, lu=lu)

    def _solve(self, factors: Factors, rhs: np.ndarray) -> np.ndarray:
        if factors.pinv is not None:  # redundant system: least squares (consistent equations)
            return factors.pinv @ rhs
        return self.linear.solve(factors.lu, rhs)

    def condition(self, q: np.ndarray, u: np.ndarray, factors: Factors | None = None) -> float:
        """Condition number of Phi_q as chosen by ``options.condition`` (NaN for "none")."""
        if self.options.condition == "none":
            return float("nan")
        return self._condition(factors if factors is not None else self._factor(self.system.jac(q, u), float("nan")))

    def _condition(self, factors: Factors) -> float:
        kind = self.options.condition
        if kind == "none":
            return float("nan")
        if kind == "exact" or self.redundant:
            return linear.condition_number(self.linear.dense(factors.values))
        rcond = self.linear.rcond(factors.lu, factors.values)
        return float("inf") if rcond == 0 else 1.0 / rcond

    def check_singular(self, jacobian: np.ndarray, t: float) -> None:
        """Raise SingularJacobianError (naming the dependencies) if ``jacobian`` is singular."""
        u, s, vt = np.linalg.svd(jacobian)
        tol = self.options.singular_tolerance * s[0]
        rank = int(np.sum(s > tol))
        if rank == min(jacobian.shape):
            return
        names = self.system.constraint_names
        dependent: list[str] = []
        for k in range(rank, jacobian.shape[0]):
            dependent += [names[i] for i in np.flatnonzero(np.abs(u[:, k]) > 1e-6) if names[i] not in dependent]
        null = [describe_combination(vt[k], self.system.velocity_names) for k in range(rank, jacobian.shape[1])]
        raise SingularJacobianError(t, rank, jacobian.shape, dependent, null, f"sigma_min/sigma_max = {abs(s[-1] / s[0]):.2e}")

    def residual(self, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, float]:
        """Phi(q, u) and its max norm."""
        phi = self.system.phi(q, u)
        return phi, _max_norm(phi)

    def worst(self, phi: np.ndarray, count: int = 3) -> list[tuple[str, float]]:
        """The ``count`` constraints with the largest |Phi_i|, with their values."""
        return [(self.system.constraint_names[i], float(phi[i])) for i in np.argsort(-np.abs(phi))[:count]]

    def _failure(self, q: np.ndarray, u: np.ndarray, t: float, iterations: int) -> ConvergenceError:
        phi, norm = self.residual(q, u)
        return self._rounding_limited(q, u, t, iterations, norm) or ConvergenceError(t, iterations, norm, self.worst(phi))

    def _rounding_limited(self, q: np.ndarray, u: np.ndarray, t: float, iterations: int, norm: float) -> PrecisionError | None:
        """A :class:`PrecisionError` when the residual ``norm`` left at q is what double precision's
        rounding of the coordinates alone makes of Phi there (within 100 times what moving every
        coordinate by a few units in the last place changes it by): the tolerance cannot be met in
        these units, whatever the solver does. None otherwise (a residual the solver could lower)."""
        if not np.isfinite(norm) or not np.all(np.isfinite(q)):
            return None
        signs = np.where(np.arange(len(q)) % 2, 1.0, -1.0)
        noise = max(_max_norm(self.system.phi(q * (1.0 + 8 * np.finfo(float).eps * signs), u) - self.system.phi(q, u)),
                    _max_norm(self.system.phi(q * (1.0 - 8 * np.finfo(float).eps * signs), u) - self.system.phi(q, u)))  # fmt: skip
        if not norm <= 100.0 * noise:
            return None
        return PrecisionError(t, iterations, norm, noise, float(np.abs(q).max()), self.options.tolerance)

    # ---- position ------------------------------------------------------------------------
    def position(self, q0: np.ndarray, u: np.ndarray, t: float = float("nan")) -> tuple[np.ndarray, int, float]:
        """Newton-Raphson from ``q0`` for driver inputs ``u``: (q, iterations, max |Phi|).

        Full steps first; if they fail (or meet a singular Phi_q), a backtracking line search;
        then a homotopy that moves the residual of ``q0`` to zero in stages; last,
        Levenberg-Marquardt, which either finds a solution or raises UnreachableError with
        the closest reachable residual.
        """
        solution = self._position(q0, u, t)
        return solution.q, solution.iterations, solution.norm

    def _position(
        self, q0: np.ndarray, u: np.ndarray, t: float, thorough: bool = True, factors: Factors | None = None, native: bool = True
    ) -> Solution:
        """:meth:`position`, also returning Phi_q at the solution (``thorough=False``: no homotopy,
        for the short sub-steps of a refined step, where it rarely helps and costs most;
        ``factors``: a factorized Phi_q near ``q0`` for the first, chord iterations)."""
        try:
            return self._newton(q0, u, t, damped=False, factors=factors if self.chord else None, native=native)
        except (ConvergenceError, SingularJacobianError) as error:
            if not self.options.line_search:
                raise
            first = error
        try:
            return self._newton(q0, u, t, damped=True)
        except (ConvergenceError, SingularJacobianError):
            pass
        if thorough:
            try:
                return self._homotopy(q0, u, t)
            except (ConvergenceError, SingularJacobianError):
                pass
        try:
            return self._least_squares(q0, u, t)
        except UnreachableError:
            if isinstance(first, SingularJacobianError):
                raise first from None  # a singular Phi_q is the finding, not an unreachable target
            raise

    def _unassembled(self, error: BranchError | ConvergenceError, q: np.ndarray, times: np.ndarray, u_all: np.ndarray, i: int) -> UnassembledError | None:
        """The failed step to ``times[i]`` (from the solved pose ``q``) in the mechanism's words, when
        the linkage cannot assemble there: an :class:`UnassembledError` naming the joints that stay
        open and by how much (and the widest gap on up to 12 later time points); None when a pose
        closes every joint (the failure is the solver's to explain)."""
        drivers = self.system.driver_names
        closest, gaps = self.closest_assembly(q, u_all[:, i])
        if not gaps:
            return None
        widest = None
        later = np.unique(np.linspace(i + 1, len(times) - 1, min(12, len(times) - 1 - i)).round().astype(int)) if i + 1 < len(times) else []
        for j in later:
            closest, found = self.closest_assembly(closest, u_all[:, j])
            total = sum(g for _, g in found)
            if found and (widest is None or total > widest[1]):
                widest = (float(times[j]), total)
        inputs = ", ".join(f"{name} = {value:.6g}" for name, value in zip(drivers, u_all[:, i]))
        stop = error.t0 if isinstance(error, BranchError) else float(times[i - 1])  # where the solved rows end
        return UnassembledError(float(stop), float(times[i]), inputs, gaps, widest, error)

    def closest_assembly(self, q: np.ndarray, u: np.ndarray, max_iterations: int = 100) -> tuple[np.ndarray, list[tuple[str, float]]]:
        """The pose nearest to closing every joint with the drivers (and the normalization rows) held
        at ``u``: Levenberg-Marquardt on sum(w_i Phi_i^2), the drivers' and normalization rows weighted
        1e4 over the joints', from ``q``. Returns it and the joints it leaves open beyond 1e3 times the
        tolerance, widest first: (joint, its points' distance in m, or its largest residual for a joint
        without point rows)."""
        from kinegen.interface import row_owner

        names = self.system.constraint_names
        n_joint_rows = len(names) - self.system.n_inputs
        held = np.array([i >= n_joint_rows or row_owner(name)[1] for i, name in enumerate(names)])
        weights = np.where(held, 1e4, 1.0)

        q, phi, _, _ = self._weighted_least_squares(q, u, weights, max_iterations)
        if not np.all(np.isfinite(phi)) or np.abs(phi[held]).max(initial=0.0) > 1e3 * self.options.tolerance:
            return q, []  # the drivers themselves cannot be held: not a question of the joints
        by_joint: dict[str, dict[str, float]] = {}
        for k in range(n_joint_rows):
            joint, normalization = row_owner(names[k])
            if not normalization:
                by_joint.setdefault(joint, {})[names[k].rsplit(".", 1)[-1]] = float(phi[k])
        gaps = []
        for joint, rows in by_joint.items():
            point = [rows[c] for c in "xyz" if c in rows]
            gap = float(np.linalg.norm(point)) if point else max(abs(x) for x in rows.values())
            if gap > 1e3 * self.options.tolerance:
                gaps.append((joint, gap))
        return q, sorted(gaps, key=lambda item: -item[1])

    def _weighted_least_squares(self, q: np.ndarray, u: np.ndarray, weights: np.ndarray, max_iterations: int) -> tuple[np.ndarray, np.ndarray, Any, int]:
        """Levenberg-Marquardt on sum((w_i Phi_i)^2) at inputs ``u`` from ``q`` (steps retracted onto the
        parametrization's manifold), until max |Phi| meets the tolerance, no step descends (a local
        minimum) or the cost stops improving: (q, Phi, Phi's values, iterations)."""

        def evaluate(x: np.ndarray) -> tuple[np.ndarray, Any, float]:
            phi, values = self.system.evaluate(x, u)
            return phi, values, float(np.sum((weights * phi) ** 2))

        phi, values, cost = evaluate(q)
        damping, iterations = 1e-3, 0
        for iterations in range(1, max_iterations + 1):  # noqa: B007
            if np.max(np.abs(phi)) <= self.options.tolerance or not np.isfinite(cost):
                break
            jacobian = weights[:, None] * self.linear.dense(values)
            gradient = jacobian.T @ (weights * phi)
            normal = jacobian.T @ jacobian
            scale = np.diag(normal) + 1e-12 * max(1.0, float(np.diag(normal).max()))
            while damping < 1e12:
                trial = self.retract(q, -np.linalg.solve(normal + damping * np.diag(scale), gradient))
                trial_phi, trial_values, trial_cost = evaluate(trial)
                if trial_cost < cost:
                    break
                damping *= 4
            else:
                break  # no descent in any direction: a (local) minimum
            improvement = cost - trial_cost
            q, phi, values, cost = trial, trial_phi, trial_values, trial_cost
            damping = max(damping / 3, 1e-12)
            if improvement <= 1e-15 * cost:
                break
        return q, phi, values, iterations

    def _least_squares(self, q: np.ndarray, u: np.ndarray, t: float, max_iterations: int = 100) -> Solution:
        """Levenberg-Marquardt on sum(w_i Phi_i^2), joint rows weighted 1e4 over driver rows:
        the solution if one exists nearby; otherwise the assembled configuration closest to
        the drivers' targets, reported by UnreachableError (the target is outside the workspace)."""
        m = len(self.system.constraint_names)
        weights = np.ones(m)
        weights[: m - self.system.n_inputs] = 1e4

        q, phi, values, iterations = self._weighted_least_squares(q, u, weights, max_iterations)
        norm = _max_norm(phi)
        if norm <= self.options.tolerance:
            return Solution(q, iterations, norm, values, phi)
        raise self._rounding_limited(q, u, t, iterations, norm) or UnreachableError(t, iterations, norm, self.worst(phi))

    def _newton(
        self,
        q: np.ndarray,
        u: np.ndarray,
        t: float,
        damped: bool,
        offset: np.ndarray | None = None,
        factors: Factors | None = None,
        native: bool = True,
    ) -> Solution:
        """Newton iterations; each evaluates Phi and Phi_q in one call (Phi_q at the solution is
        returned). With ``factors`` (full steps only): chord iterations with them, and with each
        later factorization, while max |Phi| falls by ``chord_rate`` per iteration."""
        opts = self.options
        evaluate = self.system.evaluate
        if native and not damped and offset is None and factors is None and self.system.native is not None:
            status, x, iterations, norm = self._native_newton(q, u)
            if status == "ok":  # converged in C: Phi and Phi_q at the solution for the caller (its motion not tracked)
                phi, values = evaluate(x, u)
                return Solution(x, iterations, _max_norm(phi), values, phi)
            if status != "singular":  # not converged (a singular Phi_q on the way: the Python loop below names it)
                raise self._failure(x, u, t, iterations)

        def residual(x: np.ndarray) -> tuple[np.ndarray, float, Any]:
            phi, values = evaluate(x, u)  # values of Phi_q at the pattern
            if offset is not None:
                phi = phi - offset
            return phi, _max_norm(phi), values

        phi, norm, jacobian = residual(q)
        iterations, moved = 0, np.zeros(self.system.n_velocity)
        while norm > opts.tolerance:
            if iterations >= opts.max_iterations or not np.isfinite(norm) or norm > opts.divergence_limit:
                raise self._failure(q, u, t, iterations)
            if factors is None:
                factors = self._factor(jacobian, t)
            step = -self._solve(factors, phi)
            iterations += 1
            trial = self.retract(q, step)
            trial_phi, trial_norm, trial_jacobian = residual(trial)
            alpha = 1.0
            if damped:
                while not trial_norm < norm and alpha > 1e-4:
                    alpha *= 0.5
                    trial = self.retract(q, alpha * step)
                    trial_phi, trial_norm, trial_jacobian = residual(trial)
            moved += alpha * step
            if damped or not self.chord or not trial_norm <= self.options.chord_rate * norm:
                factors = None  # Newton: factorize at the new point
            q, phi, norm, jacobian = trial, trial_phi, trial_norm, trial_jacobian
        return Solution(q, iterations, norm, jacobian, phi, moved)

    def _homotopy(self, q: np.ndarray, u: np.ndarray, t: float, stages: int = 64) -> Solution:
        """Solve Phi(q, u) = (1 - s) Phi(q0, u) for s = 0 -> 1 with adaptive stages."""
        start, _ = self.residual(q, u)
        s, ds, total = 0.0, 1.0 / 8, 0
        while s < 1.0:
            target = min(1.0, s + ds)
            try:
                q, iterations = self._newton(q, u, t, damped=True, offset=(1.0 - target) * start)[:2]
            except (ConvergenceError, SingularJacobianError):
                ds /= 2
                if ds < 1.0 / (8 * stages):
                    raise self._failure(q, u, t, total) from None
                continue
            total += iterations
            s = target
            ds = min(2 * ds, 0.25)
        phi, values = self.system.evaluate(q, u)
        return Solution(q, total, _max_norm(phi), values, phi)

    def rates(
        self, q: np.ndarray, u: np.ndarray, ud: np.ndarray, udd: np.ndarray, factors: Factors
    ) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and acceleration (velocity coordinates) from one factorization of Phi_q."""
        v = self._solve(factors, self.system.velocity_rhs(q, u, ud))
        return v, self._solve(factors, self.system.acceleration_rhs(q, v, u, ud, udd))

    # ---- trajectory ----------------------------------------------------------------------
    def solve(
        self,
        times: np.ndarray | None = None,
        q0: np.ndarray | None = None,
        inputs: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> Results:
        """Position, velocity and acceleration at every time of ``times`` (default: the case grid).

        ``inputs`` = (u, ud, udd), each of shape (n_inputs, K), replaces the case's time
        functions (e.g. cylinder lengths from another case or a controller).

        Python's cyclic garbage collector is paused during the loop: the loop creates no
        reference cycles (reference counting frees everything), and a collection that
        walks the objects a SymPy build left in the same process cost up to 40 % of a
        chain-14 trajectory.
        """
        with collector_paused():
            return self._trajectory(times, q0, inputs)

    def _trajectory(
        self,
        times: np.ndarray | None,
        q0: np.ndarray | None,
        inputs: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
    ) -> Results:
        system = self.system
        if times is None:
            times = np.linspace(system.t0, system.t1, system.steps)
        times = np.asarray(times, dtype=float)
        k, n, nv = len(times), system.n_stored, system.n_velocity
        tabulated = inputs is not None
        if inputs is None:
            inputs = system.checked_inputs(times)  # a ModelError before any step where a function leaves its domain
        u_all, ud_all, udd_all = (np.asarray(x, dtype=float).reshape(system.n_inputs, k) for x in inputs)
        if tabulated and not all(np.isfinite(x).all() for x in (u_all, ud_all, udd_all)):
            first = int(np.argmax(~np.isfinite(np.vstack((u_all, ud_all, udd_all))).all(axis=0)))
            raise ValueError(f"tabulated driver inputs are not finite at t = {times[first]:.6g} (index {first})")
        if tabulated and k > 1:
            _warn_if_undersampled(system, times, u_all, ud_all, udd_all)

        grid_deviations: list[np.ndarray] = []  # the inputs' chord deviations over every grid step, made when first needed

        def deviations_of(t0: float, t1: float, i: int, u0: np.ndarray, u1: np.ndarray) -> np.ndarray | None:
            """Per input, its chord deviation and that deviation's split (:func:`chord_bounds`) over [t0, t1]
            within grid step i, from u0 at t0 to u1 at t1 (None: tabulated inputs). Over the grid's own steps
            every step's at once: the enclosures of the case's functions in one call, the bounds in one pass
            (the same values)."""
            if tabulated or system.input_ranges is None:
                return None
            if (t0, t1) != (times[i - 1], times[i]):
                ranges = np.asarray(system.input_ranges((np.array([t0]), np.array([t1]))), dtype=float)[:, 0]
                return chord_bounds(ranges, t1 - t0, u1, u1 - u0)
            if not grid_deviations:
                ranges = np.asarray(system.input_ranges((times[:-1], times[1:])), dtype=float).reshape(-1, k - 1)
                together = chord_bounds(ranges, np.diff(times), u_all[:, 1:], np.diff(u_all, axis=1))
                grid_deviations.append(np.ascontiguousarray(together.transpose(2, 0, 1)))
            return grid_deviations[0][i - 1]

        def inputs_at(t: float, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            """Inputs at a refinement time between samples i-1 and i: the case's functions, or for
            tabulated inputs the cubic Hermite interpolant of (u, du/dt) and its derivatives."""
            if not tabulated:  # a ModelError naming the driver where a function leaves its domain between samples
                return tuple(x[:, 0] for x in system.checked_inputs(np.array([t]), (times[i - 1], times[i])))
            d = times[i] - times[i - 1]
            s = (t - times[i - 1]) / d
            u0, u1, m0, m1 = u_all[:, i - 1], u_all[:, i], d * ud_all[:, i - 1], d * ud_all[:, i]
            u = (2 * s**3 - 3 * s**2 + 1) * u0 + (s**3 - 2 * s**2 + s) * m0 + (3 * s**2 - 2 * s**3) * u1 + (s**3 - s**2) * m1
            ud = ((6 * s**2 - 6 * s) * (u0 - u1) + (3 * s**2 - 4 * s + 1) * m0 + (3 * s**2 - 2 * s) * m1) / d
            udd = ((12 * s - 6) * (u0 - u1) + (6 * s - 4) * m0 + (6 * s - 2) * m1) / d**2
            return u, ud, udd

        # every row up to the last step tried is written below (that step's, when it fails: NaN)
        qs, vs, accs = (self._arrays.empty(shape) for shape in ((k, n), (k, nv), (k, nv)))
        iterations, residuals, conditions = np.zeros(k, dtype=int), np.empty(k), np.empty(k)
        converged = np.zeros(k, dtype=bool)
        q = system.initial_q.copy() if q0 is None else np.asarray(q0, dtype=float).copy()
        v = a = None
        factors: Factors | None = None
        failure: KinegenError | None = None
        native = self._native_steps(not tabulated)
        if native is not None:
            c_inputs = tuple(self._arrays.copy(x.T) for x in (u_all, ud_all, udd_all))
            c_iterations = np.zeros(k, dtype=np.intc)
        i = 0
        bar = counter(f"solve {system.model}/{system.case}", k, "step", PROGRESS_DELAY) if k >= PROGRESS_STEPS else None
        chunk = NATIVE_CHUNK if bar is not None else k
        try:
            while i < k:
                if native is not None:
                    # the C loop takes the usual steps; it returns at the first step that needs Python
                    end = min(k, i + chunk)
                    done = native.run(i, end, times, q, c_inputs, (qs, vs, accs, c_iterations, residuals, conditions))
                    converged[i:done], iterations[i:done] = True, c_iterations[i:done]
                    if bar is not None:
                        bar.update(done - i)
                    if done >= k:
                        break
                    if done > i:  # Python takes step done from the state the C loop reached
                        q, v, a = qs[done - 1].copy(), vs[done - 1].copy(), accs[done - 1].copy()
                        factors = None
                        i = done
                    if done == end:  # a piece done: the C loop goes on from its own state
                        continue
                    qs[i], vs[i], accs[i] = np.nan, np.nan, np.nan  # the C loop's unfinished try
                t = times[i]
                u, ud, udd = u_all[:, i], ud_all[:, i], udd_all[:, i]
                try:
                    if factors is None and i > 0:  # Phi_q at the C loop's last pose
                        factors = self._factor(system.evaluate(q, u_all[:, i - 1])[1], times[i - 1])
                    if i == 0:
                        solution = self._position(q, u, t)
                        factors = self._factor(solution.values, t)
                    else:
                        start_inputs = (u_all[:, i - 1], ud_all[:, i - 1], udd_all[:, i - 1])
                        solution, factors = self._step(
                            q, v, a, factors, times[i - 1], t, (u, ud, udd), lambda s, i=i: inputs_at(s, i), start_inputs,
                            lambda t0, t1, u0, u1, i=i: deviations_of(t0, t1, i, u0, u1),
                            previous_step=(accs[i - 2], times[i - 1] - times[i - 2]) if i >= 2 else None,
                        )
                    q, iterations[i], residuals[i] = solution.q, solution.iterations, solution.norm
                    if (self.options.polish or self.chord) and factors.lu is not None:
                        q = self.retract(q, -self._solve(factors, solution.phi))
                except KinegenError as error:
                    if i > 0 and isinstance(error, (BranchError, ConvergenceError)) and not isinstance(error, PrecisionError):
                        error = self._unassembled(error, q, times, u_all, i) or error
                    if self.options.on_failure != "stop":
                        raise error from error.cause if isinstance(error, UnassembledError) else None
                    failure = error
                    qs[i], vs[i], accs[i], conditions[i] = np.nan, np.nan, np.nan, np.nan
                    residuals[i] = getattr(error, "residual", np.nan)
                    k = i + 1
                    break
                v, a = self.rates(q, u, ud, udd, factors)
                conditions[i] = self._condition(factors)
                qs[i], vs[i], accs[i] = q, v, a
                converged[i] = True
                if native is not None:
                    native.resume(t, q, v, a, u, ud, (accs[i - 1], t - times[i - 1]) if i >= 1 else None)
                i += 1
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        return Results(
            system, times[:k], qs[:k], vs[:k], accs[:k], iterations[:k], residuals[:k], conditions[:k],
            (c_inputs[0] if native is not None else self._arrays.copy(u_all.T))[:k], self.options.condition, converged[:k], failure,
        )  # fmt: skip

    @cached_property
    def _native_newton(self) -> Any:
        """Full Newton on one configuration in C (kinegen_newton) with this solver's options."""
        from kinegen.runtime.native import Newton

        return Newton(self.system.native, _native_options(self.options, False))

    def _native_steps(self, case_inputs: bool) -> _NativeSteps | None:
        """The C step loop of the system's compiled code, when it can stand in for the Python
        one: compiled code, a square Phi_q, a condition number it can record (the estimate or none)."""
        native = self.system.native
        if native is None or self.redundant or self.options.condition not in ("estimate", "none"):
            return None
        return _NativeSteps(native, self.options, self.chord, case_inputs)

    def _step(self, q, v, a, previous: Factors, t0: float, t1: float, inputs, inputs_at, start_inputs, deviations_of=None,
              depth: int = 0, previous_step: tuple[np.ndarray, float] | None = None) -> tuple:  # fmt: skip
        """Position at t1 from the solved state (q, v, a) at t0 (inputs ``start_inputs``), whose
        Phi_q is factorized in ``previous``, certified to continue it (:meth:`_certify`;
        ``deviations_of(t0, t1, u0, u1)``: the case's inputs' chord deviations over a step from u0 to u1,
        None for tabulated inputs). The predictor moves by v h + a h^2/2 and, on a whole step after
        another (``previous_step``: the acceleration at that step's start and its length), by the jerk
        term (a - a_prev) / h_prev h^3/6 too: on chain-50 and chain-100 one Newton iteration a step
        instead of 1.72 (the C solver's attempt(), the same sums).

        Returns the solution and the factors of its Phi_q. When the certificate fails (or Newton
        does), the interval is halved and both halves are solved in turn, up to
        ``max_refinements`` times; then BranchError says what was observed.
        """
        opts = self.options
        h = t1 - t0
        motion = v * h + 0.5 * a * h * h if opts.predictor else np.zeros_like(v)
        if opts.predictor and previous_step is not None and depth == 0 and previous_step[1] > 0:
            motion = motion + (a - previous_step[0]) / previous_step[1] * h * h * h / 6.0  # (C's sum, left to right)
        guess = self.retract(q, motion) if opts.predictor else q
        u = inputs[0]
        try:
            # chord iterations only on whole steps: a refined sub-step is where Phi_q changes fast
            # (a singular pose, a branch point), and full Newton reports a singular Phi_q there
            solution = self._position(guess, u, t1, thorough=depth == 0, factors=previous if depth == 0 else None, native=False)
            factors = self._factor(solution.values, t1)
            observed = None
            if opts.keep_branch and (factors.lu is not None or factors.pinv is not None):  # pinv: redundant, least squares
                moved = None if solution.moved is None else motion + solution.moved
                deviation = None if deviations_of is None else deviations_of(t0, t1, start_inputs[0], u)
                observed = self._certify(previous, solution, factors, moved, h, start_inputs, inputs, deviation,
                                         last_try=depth >= self.options.max_refinements)
        except (ConvergenceError, SingularJacobianError):
            if depth >= self.options.max_refinements or not self.options.keep_branch:
                raise
            observed = "Newton did not converge"
        if observed is None:
            return solution, factors
        if depth >= self.options.max_refinements:
            raise BranchError(t0, t1, h, observed)
        middle = 0.5 * (t0 + t1)
        mid_inputs = inputs_at(middle)
        first, factors_m = self._step(q, v, a, previous, t0, middle, mid_inputs, inputs_at, start_inputs, deviations_of, depth + 1)
        vm, am = self.rates(first.q, *mid_inputs, factors_m)
        second, factors = self._step(first.q, vm, am, factors_m, middle, t1, inputs, inputs_at, mid_inputs, deviations_of, depth + 1)
        return second._replace(iterations=first.iterations + second.iterations), factors

    def _certify(self, previous: Factors, solution: Solution, factors: Factors, moved, h: float, start_inputs, inputs,
                 deviation: np.ndarray | None = None, last_try: bool = True) -> str | None:  # fmt: skip
        """None when the step from x0 (Phi_q values and factors ``previous``) to Newton's solution x1
        (``solution``, factors of its Phi_q in ``factors``; ``moved`` = x1 - x0 in velocity
        coordinates) over a time step h is certified to continue x0; else what was observed.

        Every diagonal block of Phi_q must keep the sign of its determinant (its assembly mode:
        which intersection of the circles, which sign of which factor). Then, in the max-norm,

        * omega = safety |J1^-1 (J0 - J1) d| / |d|^2, the affine-covariant Lipschitz constant of
          Phi_q measured over the step (d = x1 - x0);
        * alpha = |J1^-1 Phi(x1, u1)| + max over the step of |J1^-1 Phi_u (u(s) - u1)| (first order in
          u), W = J1^-1 Phi_u (Phi_u w = -nu(x1, u1, w)), bounded by :func:`input_effect`: for the case's
          own time functions from their chord deviations over the step (``deviation``), for tabulated inputs along
          the cubic Hermite path of their values and rates at both ends.

        If alpha omega <= 1/2 and omega |d| < 1, the Newton-Kantorovich theorem gives every
        Phi(., u(s)) exactly one zero in the ball of radius 1/omega about x1; these zeros form one
        continuous path, x1 is its end and x0 (a zero at t0 inside the ball) its start. The inputs'
        term is first bounded coarsely (:meth:`_coarse_effect`), which decides the same steps;
        ``last_try``: a refusal here is final, so it names the input.
        """
        signs = self._block_signs(factors)
        before = self._block_signs(previous)
        if signs is not None and before is not None and not np.array_equal(signs, before):
            b = int(np.flatnonzero(signs != before)[0])
            return (
                f"the assembly mode of Phi_q's diagonal block {b} ({self._describe_block(self.blocks[b])}) flips: the sign of "
                f"its determinant changes from {before[b]:+d} to {signs[b]:+d}, so a singular pose (a toggle or dead point) lies within the step"
            )
        if moved is None:
            return "Newton needed a fallback (line search, homotopy or least squares), whose path is not certified"
        system = self.system
        magnitudes = abs(moved)
        distance = float(magnitudes.max()) if moved.size else 0.0
        omega = 0.0
        if distance > MIN_MOTION:
            change = (previous.values - factors.values) * moved[system.jac_cols]
            w = np.bincount(system.jac_rows, weights=change, minlength=len(system.constraint_names))
            omega = self.options.safety * float(abs(self._solve(factors, w)).max()) / distance**2
        turns = magnitudes[system.turning]
        turn = float(turns.max()) if turns.size else 0.0
        if not turn < MAX_MOTION or not np.isfinite(distance):
            which = system.velocity_names[system.turning[int(np.argmax(turns))]] if turns.size else "no coordinate"
            return (
                f"the step turns {which} by {turn:.3g} (Newton's path from the last solution), beyond a quarter turn "
                f"({MAX_MOTION:.3g}): within such a ball a rotation coordinate repeats, so no continuation bound holds there"
            )
        x1, u1 = solution.q, inputs[0]

        @cache
        def driver_rates() -> np.ndarray:
            """-Phi_u 1: driver k's equation is the row n_v - n_inputs + k and depends on u_k alone
            (NumericSystem checks the order), so one nu(q, u, 1) holds every column of Phi_u: its one
            value, in that row (the value nu(q, u, e_k) gives there)."""
            return system.velocity_rhs(x1, u1, np.ones(system.n_inputs))

        def columns(which: np.ndarray) -> np.ndarray:
            """W's columns ``which`` (n_v, len(which)): J1^-1 Phi_u e_k, up to one sign for all."""
            if not which.size:
                return np.zeros((system.n_velocity, 0))
            rates = driver_rates()
            first = len(rates) - system.n_inputs
            out = np.zeros((system.n_velocity, which.size))
            for j, k in enumerate(which):
                unit = np.zeros_like(rates)
                unit[first + k] = rates[first + k]
                # one solve per column: LAPACK's multi-column solve runs threaded, 50x slower on a busy machine
                out[:, j] = self._solve(factors, unit)
            return out

        correction = float(abs(self._solve(factors, solution.phi)).max())
        allowed = 0.5 / omega - correction if omega > 0 else np.inf
        coarse = self._coarse_effect(factors, driver_rates, u1, start_inputs[0], deviation, allowed, last_try)
        effect, worst = (coarse, None) if coarse is not None else input_effect(columns, h, start_inputs[:2], inputs[:2], deviation)
        alpha = correction + effect
        bound = alpha * omega
        if bound <= 0.5 and omega * distance < 1.0:
            return None
        name = system.driver_names[worst[0]] if worst is not None else None
        return (
            f"the continuation bound fails: alpha * omega = {bound:.3g} (at most 0.5 certifies) and omega * |d| = "
            f"{omega * distance:.3g} (below 1 certifies), with alpha = {alpha:.3g} (the inputs' effect), omega = {omega:.3g} "
            f"(Phi_q's change) and |d| = {distance:.3g} (the motion) -- "
            + (f"the input {name} moves too much within the step ({worst[1]}), " if name else "the inputs change faster than the step can follow, ")
            + f"or a singular pose is near; {self._worst_block(factors)}"
        )

    def _coarse_effect(self, factors: Factors, driver_rates: Callable[[], np.ndarray], u1: np.ndarray, u0: np.ndarray,
                       deviation: np.ndarray | None, allowed: float, last_try: bool) -> float | None:  # fmt: skip
        """The inputs' term of the certificate from two solves, whatever the number of inputs (the C
        solver's, kinegen_solver.c's input_effect): |W D| from one solve of Phi_u D, and
        sum_k |W_k| c_k <= |Phi_q^-1| |Phi_u| c by the factors' comparison matrices
        (:func:`kinegen.runtime.linear.comparison`). Returned when their sum is below ``allowed`` (what
        alpha omega <= 1/2 leaves the term) by 1e-12 of it -- never below the exact bound, so the exact
        one certifies that step too --, or |W D| alone when it is above ``allowed`` by that margin and
        this is not the last try -- the exact bound is at least |W D|, so it refuses that step too.
        Then, where inputs curve, |W D| + max(|W curve| + the comparison bound of sum_k |W_k| beyond_k)
        (:func:`chord_bounds`; two more solves), returned by the same rule (the C solver's order).
        None when they decide nothing (or do not apply: tabulated inputs, fewer than two inputs moving,
        an input that nothing bounds, least squares): the exact bound decides. ``driver_rates()``:
        -Phi_u 1 at the solution (the exact bound's columns take the same values)."""
        if deviation is None or factors.lu is None:
            return None
        deviation, curve, beyond = deviation  # chord_bounds: c, then its split
        change = u1 - u0
        if np.count_nonzero((change != 0) | (deviation != 0)) < 2 or not np.isfinite(deviation).all():
            return None
        rates = driver_rates()  # -Phi_u 1: driver k's row holds its one value
        first = len(rates) - self.system.n_inputs
        effect, spread = np.zeros_like(rates), np.zeros_like(rates)
        with np.errstate(all="ignore"):  # (an input that stays put: its change and deviation 0)
            effect[first:], spread[first:] = rates[first:] * change, np.abs(rates[first:]) * deviation
            changed = float(abs(self._solve(factors, effect)).max())
            coarse = changed + float(self.linear.bound(factors.lu, spread).max())
            if coarse <= allowed * (1.0 - 1e-12):  # (NaN is neither)
                return coarse
            if not last_try and changed >= allowed + 1e-12 * abs(allowed):
                return changed
            if curve.any():  # then with the curvature split: |W D| + max(|W curve| + the bound of sum_k |W_k| beyond_k)
                mean = np.zeros_like(rates)
                mean[first:], spread[first:] = rates[first:] * curve, np.abs(rates[first:]) * beyond
                top = float((abs(self._solve(factors, mean)) + self.linear.bound(factors.lu, spread)).max())
                if changed + top <= allowed * (1.0 - 1e-12):
                    return changed + top
        return None

    def _block_signs(self, factors: Factors) -> np.ndarray | None:
        """Sign of det of every diagonal block of Phi_q (its rows and columns in the blocks' fixed order)."""
        if not self._blocks_by_size:
            return None
        if factors.block_signs is None:
            values = factors.values
            signs = np.empty(len(self.blocks))
            for members, value_index, flat, size in self._blocks_by_size:
                stack = np.zeros((len(members), size, size))
                stack.flat[flat] = values[value_index]
                signs[members] = np.sign(stack[:, 0, 0]) if size == 1 else np.linalg.slogdet(stack)[0]
            factors.block_signs = signs.astype(int)
        return factors.block_signs

    def _describe_block(self, block: Block) -> str:
        """A diagonal block named by its bodies and constraints."""
        system = self.system
        bodies = sorted({system.velocity_names[c].split(".")[0] for c in block.cols})
        constraints = [system.constraint_names[r] for r in block.rows]
        shown_ = ", ".join(constraints[:4]) + (f" and {len(constraints) - 4} more" if len(constraints) > 4 else "")
        return f"bodies {', '.join(bodies)}; constraints {shown_}"

    def _worst_block(self, factors: Factors) -> str:
        """The diagonal block with the smallest relative pivot: the one nearest a singular pose."""
        if not self.blocks:
            return "no block structure"
        dense = self.linear.dense(factors.values)
        smallest = [np.linalg.svd(dense[np.ix_(b.rows, b.cols)], compute_uv=False) for b in self.blocks]
        ratios = [sv[-1] / sv[0] if sv[0] > 0 else 0.0 for sv in smallest]
        b = int(np.argmin(ratios))
        return f"the block nearest a singular pose: block {b} ({self._describe_block(self.blocks[b])}), sigma_min/sigma_max = {abs(ratios[b]):.2e}"


#: above this ratio (:func:`table_mismatch`) a table of inputs is sampled below its own variation
TABLE_MISMATCH = 0.5


class SamplingWarning(UserWarning):
    """Tabulated inputs sampled below their own variation: between samples the solve follows the
    cubic Hermite path of their values and rates, which is not the signal's."""


def table_mismatch(times: np.ndarray, u: np.ndarray, ud: np.ndarray, udd: np.ndarray) -> np.ndarray:
    """Per step and input (n_inputs, K - 1): how far tabulated inputs (u, du/dt, d2u/dt2, each
    (n_inputs, K) at ``times``) disagree with the cubic Hermite path a halved step follows between
    samples -- h^2 |the path's d2u/dt2 - the table's| at either end, relative to the input's own
    change over the step (|du| + h |du/dt| + h^2 |d2u/dt2|, the two samples' means). About 0.2 for a
    sine sampled 4 times a period, 1.6 at 2 (its Nyquist rate). As kinegen_table_mismatch (C)."""
    h = np.diff(times)
    change = np.diff(u, axis=1)
    start = (6.0 * change - h * (4.0 * ud[:, :-1] + 2.0 * ud[:, 1:])) / h**2
    end = (-6.0 * change + h * (2.0 * ud[:, :-1] + 4.0 * ud[:, 1:])) / h**2
    scale = (np.abs(change) + h * (np.abs(ud[:, :-1]) + np.abs(ud[:, 1:])) / 2 + h**2 * (np.abs(udd[:, :-1]) + np.abs(udd[:, 1:])) / 4
             + 1e-12 * (1.0 + np.abs(u[:, :-1])))  # fmt: skip
    return h**2 * np.maximum(np.abs(start - udd[:, :-1]), np.abs(end - udd[:, 1:])) / scale


def _warn_if_undersampled(system: NumericSystem, times: np.ndarray, u: np.ndarray, ud: np.ndarray, udd: np.ndarray) -> None:
    """A :class:`SamplingWarning` naming the first step and input where a table of inputs is
    sampled below its own variation (:func:`table_mismatch` above :data:`TABLE_MISMATCH`)."""
    with np.errstate(all="ignore"):
        ratio = table_mismatch(times, u, ud, udd)
    coarse = ratio > TABLE_MISMATCH
    if not coarse.any():
        return
    steps = coarse.any(axis=0)
    i = int(np.argmax(steps))
    k = int(np.argmax(ratio[:, i]))
    warnings.warn(
        f"{system.model}/{system.case}: the tabulated inputs are sampled below their own variation in {int(steps.sum())} of "
        f"{len(times) - 1} steps, first from t = {times[i]:.6g} to {times[i + 1]:.6g} (input {system.driver_names[k]}: its "
        f"d2u/dt2 there disagrees with the cubic path through its values and rates, ratio {ratio[k, i]:.3g} > {TABLE_MISMATCH}); "
        "between samples the solve follows that cubic path, not the signal -- sample at least 4 times a period of the fastest input",
        SamplingWarning, stacklevel=4,
    )  # fmt: skip


def chord_deviation(ranges: np.ndarray, h: float | np.ndarray, u1: np.ndarray, change: np.ndarray) -> np.ndarray:
    """Per input, a bound on |u(t) - L(t)| over a step of length h, L the chord from u(t0) to
    u(t1) = ``u1`` (``change`` = u1 - u0), from the enclosures ``ranges`` of u, du/dt and d2u/dt2 over
    the step (the ``input_ranges`` kernel's rows): h^2/8 max |d2u/dt2| (the linear interpolation's
    error), or where that is not finite, min(max |u - u1|, h max |du/dt|) + |change| (|u - L| <=
    |u - u1| + |L - u1|). Infinite where nothing bounds it. Many steps at once: ``h`` (K,), ``u1`` and
    ``change`` (n_inputs, K), ``ranges`` (6 n_inputs, K); each step's values those of its own call."""
    n = len(u1)
    lower, upper = ranges[: 3 * n].reshape(3, n, *ranges.shape[1:]), ranges[3 * n :].reshape(3, n, *ranges.shape[1:])
    with np.errstate(all="ignore"):
        magnitude = np.maximum(np.abs(lower), np.abs(upper))  # of u - 0, du/dt, d2u/dt2
        offset = np.maximum(np.abs(lower[0] - u1), np.abs(upper[0] - u1))  # max |u - u1|
        fine = h * h / 8.0 * magnitude[2]
        coarse = np.minimum(offset, h * magnitude[1]) + np.abs(change)
        bound = np.fmin(fine, coarse)
    return np.where(np.isnan(bound), np.inf, bound)


def chord_bounds(ranges: np.ndarray, h: float | np.ndarray, u1: np.ndarray, change: np.ndarray) -> np.ndarray:
    """Per input, (c, curve, beyond): its :func:`chord_deviation` c, and where c is the curvature's bound
    h^2/8 max |d2u/dt2|, with d2u/dt2 enclosed in mid +- rad over the step, curve = h^2/8 mid and beyond
    = h^2/8 rad (|curve| + beyond is c); elsewhere curve = 0 and beyond = c. The linear interpolation's
    error is e(s) = -(sigma/2) d2u/dt2 at some point of the step, sigma = (s - t0)(t1 - s), one factor for
    every input: so e(s) = -(4 sigma / h^2)(curve + delta), |delta| <= beyond (:func:`input_effect`).
    Arguments as :func:`chord_deviation`'s; the three stacked first (3, n_inputs[, K]). The C solver's
    chord_deviation (kinegen_solver.c) to the bit."""
    n = len(u1)
    deviation = chord_deviation(ranges, h, u1, change)
    lower, upper = ranges[2 * n : 3 * n], ranges[5 * n :]
    with np.errstate(all="ignore"):
        fine = h * h / 8.0 * np.maximum(np.abs(lower), np.abs(upper))
        mid = 0.5 * (lower + upper)
        rad = np.maximum(upper - mid, mid - lower)
        split = (deviation == fine) & np.isfinite(mid) & np.isfinite(rad)
        return np.stack((deviation, np.where(split, h * h / 8.0 * mid, 0.0), np.where(split, h * h / 8.0 * rad, deviation)))


def input_effect(columns, h: float, start: tuple[np.ndarray, np.ndarray], end: tuple[np.ndarray, np.ndarray],
                 deviation: np.ndarray | None) -> tuple[float, tuple[int, str] | None]:  # fmt: skip
    """A bound on max over a step of h of |W (u(s) - u1)| (max-norm), W = J1^-1 Phi_u given by
    ``columns(which)`` (its columns ``which``), the inputs (u, du/dt) at the step's ``start`` and
    ``end``; and the input that contributes most, with what it does there (None when nothing moves).

    * The case's own time functions (``deviation``: (c, curve, beyond), each input's :func:`chord_bounds`
      over the step, from their enclosures there): u(s) - u1 = -(1 - r) D + e(s), D = u1 - u0, |e_k| <=
      c_k, and e(s) = -(4 sigma / h^2)(curve + delta(s)) with 0 <= 4 sigma / h^2 <= 1 and |delta_k| <=
      beyond_k, so at most |W D| + max over rows of (|W curve| + sum_k |W_k| beyond_k) -- never above |W D|
      + |sum_k |W_k| c_k|: certified for the functions themselves, however they move between the step's ends.
    * Tabulated inputs (``deviation`` None): the cubic Hermite path of the values and rates at both
      ends, u(s) - u1 = -(1-r) D + r (1-r)^2 A - r^2 (1-r) B with A = h ud0 - D, B = h ud1 - D, so at
      most |W D| + 4/27 (|W A| + |W B|) -- certified for that path (the stated assumption).
    """
    (u0, ud0), (u1, ud1) = start, end
    change = u1 - u0
    tabulated = deviation is None
    if tabulated:
        a, b = h * ud0 - change, h * ud1 - change
        deviation = curve = beyond = np.zeros_like(change)
    else:
        a = b = np.zeros_like(change)
        deviation, curve, beyond = deviation
    moving = np.flatnonzero((change != 0) | (a != 0) | (b != 0) | (deviation != 0))
    if not moving.size:
        return 0.0, None
    w = columns(moving)
    with np.errstate(all="ignore"):
        # an input that does nothing adds nothing
        spread = np.abs(w) @ np.where(w.any(axis=0), beyond[moving], 0.0) + np.abs(w @ curve[moving])
        effect = float(abs(w @ change[moving]).max()) + float(spread.max())
        effect += 4.0 / 27.0 * (float(abs(w @ a[moving]).max()) + float(abs(w @ b[moving]).max()))
        shares = np.abs(w).max(axis=0) * (np.abs(change[moving]) + deviation[moving] + 4.0 / 27.0 * (np.abs(a[moving]) + np.abs(b[moving])))
    j = int(np.nanargmax(np.where(np.isnan(shares), np.inf, shares)))
    k = int(moving[j])
    if tabulated:
        what = f"it changes by {change[k]:.3g} and its rates by {ud0[k]:.3g} .. {ud1[k]:.3g} along the samples' cubic path"
    else:
        what = f"it changes by {change[k]:.3g} between the step's ends and strays up to {deviation[k]:.3g} from that chord in between"
    return (effect if np.isfinite(effect) else float("inf")), (k, what)


def _block_groups(blocks: list[Block], rows: np.ndarray, cols: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, int]]:
    """Per block size: (block indices, indices into Phi_q's values, flat positions in a stack of
    the blocks' dense matrices, size), for the blocks' determinants in one call per size."""
    row_at = {r: (b, i) for b, block in enumerate(blocks) for i, r in enumerate(block.rows)}
    col_at = {c: (b, j) for b, block in enumerate(blocks) for j, c in enumerate(block.cols)}
    members: dict[int, list[int]] = {}  # size -> the blocks of that size, in order
    for b, block in enumerate(blocks):
        members.setdefault(block.size, []).append(b)
    position = {b: k for group in members.values() for k, b in enumerate(group)}  # a block's place in its size's stack
    entries: dict[int, tuple[list[int], list[int]]] = {size: ([], []) for size in members}
    for e, (r, c) in enumerate(zip(rows.tolist(), cols.tolist())):
        (b, i), (b2, j) = row_at[r], col_at[c]
        if b == b2:
            size = blocks[b].size
            entries[size][0].append(e)
            entries[size][1].append(position[b] * size * size + i * size + j)
    return [(np.array(members[size]), np.array(entries[size][0], dtype=np.intp), np.array(entries[size][1], dtype=np.intp), size)
            for size in sorted(members)]  # fmt: skip


def _native_options(options: SolverOptions, chord: bool, case_inputs: bool = False) -> Any:
    """The C solver's options (kinegen_options) for these; ``case_inputs``: refinement points take
    the case's own time functions (else the cubic Hermite interpolant of the given inputs)."""
    from kinegen.runtime.native import Options

    return Options(
        tolerance=options.tolerance, singular_tolerance=options.singular_tolerance, divergence_limit=options.divergence_limit,
        chord_rate=options.chord_rate, safety=options.safety, max_iterations=options.max_iterations,
        predictor=options.predictor, chord=chord, polish=options.polish, keep_branch=options.keep_branch,
        condition=options.condition == "estimate", max_refinements=options.max_refinements, case_inputs=case_inputs,
    )  # fmt: skip


class _NativeSteps:
    """The C solver (kinegen_solver.c) for one trajectory, with this solver's options."""

    def __init__(self, native: Any, options: SolverOptions, chord: bool, case_inputs: bool) -> None:
        self.options = _native_options(options, chord, case_inputs)
        self.solver = native.solver(self.options)

    def run(self, first: int, end: int, times: np.ndarray, q0: np.ndarray, inputs: tuple, out: tuple) -> int:
        """Steps ``first`` .. ``end - 1`` into ``out`` (rows per step), each from the C solver's
        last state; step 0 from ``q0``. Returns the first step not solved (``end``: all were)."""
        if first == 0:
            u, ud, udd = (x[0] for x in inputs)
            if self.solver.start(times[0], q0, u, ud, udd) != "ok":
                return 0
            self._store(0, out)
            first = 1
        if first >= end:
            return first
        rows = tuple(np.ascontiguousarray(x[first:end]) for x in inputs)
        views = tuple(o[first:end] for o in out)
        done, _ = self.solver.trajectory(np.ascontiguousarray(times[first:end]), rows, views)
        return first + done

    def _store(self, i: int, out: tuple) -> None:
        q, v, a = self.solver.state_arrays()
        state = self.solver.state
        out[0][i], out[1][i], out[2][i] = q, v, a
        out[3][i], out[4][i], out[5][i] = state.iterations, state.residual, state.condition

    def resume(self, t: float, q: np.ndarray, v: np.ndarray, a: np.ndarray, u: np.ndarray, ud: np.ndarray,
               previous: tuple[np.ndarray, float] | None) -> None:  # fmt: skip
        self.solver.resume(t, q, v, a, u, ud, previous)


def solve(system: NumericSystem, times: np.ndarray | None = None, options: SolverOptions | None = None) -> Results:
    """Convenience: ``Solver(system, options).solve(times)``."""
    return Solver(system, options).solve(times)


def check_source(source: str, model_file: str | Path) -> list[str]:
    """Check the source of a generated module built from ``model_file`` before it is
    written: every case's time functions are finite on its time grid (else
    :class:`ModelError`) and its initial pose satisfies Phi or can be assembled (else
    :class:`AssemblyError`). Returns one report line per case."""
    module = module_from_source(source, filename=f"<generated from {model_file}>")
    reports = []
    for case in module.CASES:
        system = dataclasses.replace(from_module(module, case), source=str(model_file))
        system.checked_inputs(np.linspace(system.t0, system.t1, system.steps))
        reports.append(check_initial_pose(system))
    return reports


def check_initial_pose(system: NumericSystem, options: SolverOptions | None = None) -> str:
    """Check the initial pose against Phi at the case start; assemble it if needed.

    Returns a one-line report; raises AssemblyError (naming the constraints with the
    largest residuals) when no assembled pose can be found from it.
    """
    solver = Solver(system, options)
    u = system.driver_inputs(system.t0)[0]
    phi, norm = solver.residual(system.initial_q, u)
    prefix = f"case {system.case}: initial pose"
    if norm <= solver.options.tolerance:
        return f"{prefix} satisfies Phi at t0 = {system.t0:g} (max |Phi| = {norm:.1e})"
    worst = solver.worst(phi)
    try:
        _, iterations, final = solver.position(system.initial_q, u, system.t0)
    except (ConvergenceError, SingularJacobianError) as exc:
        raise AssemblyError(system.t0, norm, worst, str(exc).splitlines()[0]) from exc
    return f"{prefix} off by max |Phi| = {norm:.2e} ({worst[0][0]}); assembled in {iterations} Newton iterations (max |Phi| = {final:.1e})"
