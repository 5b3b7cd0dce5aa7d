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

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from kinegen.errors import AssemblyError, ConvergenceError, SingularJacobianError
from kinegen.rotations import quaternion_algebra as qa
from kinegen.runtime.results import Results
from kinegen.runtime.system import NumericSystem

_getrf, _getrs, _gecon = scipy.linalg.get_lapack_funcs(("getrf", "getrs", "gecon"), dtype=np.float64)


def _lu_solve(factors: tuple[np.ndarray, np.ndarray], rhs: np.ndarray) -> np.ndarray:
    """Solve with LU factors, or in the least-squares sense with a (pinv,) pair."""
    if factors[1] is None:  # redundant system: pseudo-inverse (consistent equations)
        return factors[0] @ rhs
    x, _ = _getrs(factors[0], factors[1], rhs)
    return x


@dataclass(frozen=True)
class SolverOptions:
    """Tolerances and limits of the solver."""

    tolerance: float = 1e-10  #: max |Phi_i| at convergence
    max_iterations: int = 25  #: per time point, before emergency termination
    singular_tolerance: float = 1e-10  #: sigma_min / sigma_max below which Phi_q is singular
    line_search: bool = True  #: fallbacks (line search, homotopy) when full Newton steps fail
    divergence_limit: float = 1e8  #: max |Phi| beyond which Newton is stopped at once
    #: condition number recorded per step: "estimate" (1-norm, LAPACK gecon on the LU
    #: already computed), "exact" (2-norm, sigma_max/sigma_min by SVD) or "none"
    condition: str = "estimate"
    #: predict each step from the previous q, v, a (else: start from the previous q)
    predictor: bool = True


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


class Solver:
    """Solves one :class:`NumericSystem` over time."""

    def __init__(self, system: NumericSystem, options: SolverOptions | None = None) -> None:
        self.system = system
        self.options = options or SolverOptions()
        m, n = len(system.constraint_names), system.n_velocity
        if m < n:
            raise ValueError(f"{system.model}/{system.case}: {m} constraints for {n} velocity coordinates")
        #: more equations than coordinates: a model with redundant constraints, solved by least squares
        self.redundant = m > n
        self._tangent = system.parametrization.name == "quaternion"
        positions_q, positions_v, rot_q, rot_v = [], [], [], []
        for s_off, v_off in system.bodies.values():
            positions_q += range(s_off, s_off + 3)
            positions_v += range(v_off, v_off + 3)
            rot_q += range(s_off + 3, s_off + 7)
            rot_v += range(v_off + 3, v_off + 6)
        self._pos_q, self._pos_v = np.array(positions_q), np.array(positions_v)
        self._rot_q, self._rot_v = np.array(rot_q), np.array(rot_v)

    # ---- building blocks ---------------------------------------------------------------
    def retract(self, q: np.ndarray, step: np.ndarray) -> np.ndarray:
        """q moved by ``step`` (velocity coordinates); quaternions by the exponential map."""
        if not self._tangent:
            return q + step
        out = q.copy()
        out[self._pos_q] += step[self._pos_v]
        quaternions = q[self._rot_q].reshape(-1, 4)
        increments = step[self._rot_v].reshape(-1, 3)
        out[self._rot_q] = qa.multiply(qa.exp(increments), quaternions).ravel()
        return out

    def factorize(self, q: np.ndarray, u: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """LU factors of Phi_q at (q, u); raises SingularJacobianError (at time t) when singular."""
        return self._factor(self.system.jacobian(q, u), t)

    def _factor(self, jacobian: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """LU factors of a dense Phi_q (pseudo-inverse for a redundant system)."""
        if not np.all(np.isfinite(jacobian)):
            raise ConvergenceError(t, 0, float("nan"), [("Phi_q", float("nan"))])
        if self.redundant:
            _, s, _ = np.linalg.svd(jacobian)
            if s[-1] <= self.options.singular_tolerance * s[0]:  # column rank lost: a singular pose
                self.check_singular(jacobian, t)
            return np.linalg.pinv(jacobian, rcond=self.options.singular_tolerance), None
        lu, piv, info = _getrf(jacobian, overwrite_a=False)
        diagonal = np.abs(np.diag(lu))
        if info > 0 or diagonal.min() <= self.options.singular_tolerance * max(diagonal.max(), 1e-300):
            self.check_singular(jacobian, t)
        return lu, piv

    def condition(self, q: np.ndarray, u: np.ndarray, factors: tuple[np.ndarray, np.ndarray] | None = None) -> float:
        """Condition number of Phi_q as chosen by ``options.condition`` (NaN for "none")."""
        if self.options.condition == "none":
            return float("nan")
        jacobian = self.system.jacobian(q, u)
        return self._condition(jacobian, factors if factors is not None else self._factor(jacobian, float("nan")))

    def _condition(self, jacobian: np.ndarray, factors: tuple[np.ndarray, np.ndarray]) -> float:
        kind = self.options.condition
        if kind == "none":
            return float("nan")
        if kind == "exact" or self.redundant:
            s = np.linalg.svd(jacobian, compute_uv=False)
            return float(s[0] / s[min(jacobian.shape) - 1])
        rcond, _ = _gecon(factors[0], np.abs(jacobian).sum(axis=0).max(), norm="1")
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
        raise SingularJacobianError(t, rank, jacobian.shape, dependent, null, f"sigma_min/sigma_max = {s[-1] / s[0]:.2e}")

    def residual(self, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, float]:
        """Phi(q, u) and its max norm."""
        phi = self.system.phi(q, u)
        return phi, float(np.max(np.abs(phi))) if phi.size else 0.0

    def _failure(self, q: np.ndarray, u: np.ndarray, t: float, iterations: int) -> ConvergenceError:
        phi, norm = self.residual(q, u)
        order = np.argsort(-np.abs(phi))[:3]
        return ConvergenceError(t, iterations, norm, [(self.system.constraint_names[i], float(phi[i])) for i in order])

    # ---- position ------------------------------------------------------------------------
    def position(self, q0: np.ndarray, u: np.ndarray, t: float = float("nan")) -> tuple[np.ndarray, int, float]:
        """Newton-Raphson from ``q0`` for driver inputs ``u``: (q, iterations, max |Phi|).

        Full steps first; if they fail, a backtracking line search; if that fails too, a
        homotopy that moves the residual of ``q0`` to zero in stages.
        """
        q, iterations, norm, _ = self._position(q0, u, t)
        return q, iterations, norm

    def _position(self, q0: np.ndarray, u: np.ndarray, t: float) -> tuple[np.ndarray, int, float, np.ndarray]:
        """:meth:`position`, also returning Phi_q at the solution."""
        try:
            return self._newton(q0, u, t, damped=False)
        except ConvergenceError:
            if not self.options.line_search:
                raise
        try:
            return self._newton(q0, u, t, damped=True)
        except ConvergenceError:
            return self._homotopy(q0, u, t)

    def _newton(
        self, q: np.ndarray, u: np.ndarray, t: float, damped: bool, offset: np.ndarray | None = None
    ) -> tuple[np.ndarray, int, float, np.ndarray]:
        """Newton iterations; each evaluates Phi and Phi_q in one call (Phi_q at the solution is returned)."""
        opts = self.options
        evaluate = self.system.evaluate

        def residual(x: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
            phi, jacobian = evaluate(x, u)
            if offset is not None:
                phi = phi - offset
            return phi, float(np.max(np.abs(phi))) if phi.size else 0.0, jacobian

        phi, norm, jacobian = residual(q)
        iterations = 0
        while norm > opts.tolerance:
            if iterations >= opts.max_iterations or not np.isfinite(norm) or norm > opts.divergence_limit:
                raise self._failure(q, u, t, iterations)
            step = -_lu_solve(self._factor(jacobian, t), phi)
            iterations += 1
            trial = self.retract(q, step)
            trial_phi, trial_norm, trial_jacobian = residual(trial)
            if damped:
                alpha = 1.0
                while not trial_norm < norm and alpha > 1e-4:
                    alpha *= 0.5
                    trial = self.retract(q, alpha * step)
                    trial_phi, trial_norm, trial_jacobian = residual(trial)
            q, phi, norm, jacobian = trial, trial_phi, trial_norm, trial_jacobian
        return q, iterations, norm, jacobian

    def _homotopy(self, q: np.ndarray, u: np.ndarray, t: float, stages: int = 64) -> tuple[np.ndarray, int, float, np.ndarray]:
        """Solve Phi(q, u) = (1 - s) Phi(q0, u) for s = 0 -> 1 with adaptive stages."""
        start, _ = self.residual(q, u)
        s, ds, total = 0.0, 1.0 / 8, 0
        while s < 1.0:
            target = min(1.0, s + ds)
            try:
                q, iterations, _, _ = self._newton(q, u, t, damped=True, offset=(1.0 - target) * start)
            except (ConvergenceError, SingularJacobianError):
                ds /= 2
                if ds < 1.0 / (8 * stages):
                    raise self._failure(q, u, t, total) from None
                continue
            total += iterations
            s = target
            ds = min(2 * ds, 0.25)
        phi, jacobian = self.system.evaluate(q, u)
        return q, total, float(np.max(np.abs(phi))) if phi.size else 0.0, jacobian

    def rates(self, q: np.ndarray, u: np.ndarray, ud: np.ndarray, udd: np.ndarray, factors) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and acceleration (velocity coordinates) from one factorization of Phi_q."""
        v = _lu_solve(factors, self.system.velocity_rhs(q, u, ud))
        return v, _lu_solve(factors, self.system.acceleration_rhs(q, v, u, ud, udd))

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
        """
        system = self.system
        if times is None:
            times = np.linspace(system.t0, system.t1, system.steps)
        times = np.asarray(times, dtype=float)
        k, n, nv = len(times), system.n_stored, system.n_velocity
        if inputs is None:
            inputs = system.driver_inputs(times)
        u_all, ud_all, udd_all = (np.asarray(x, dtype=float).reshape(system.n_inputs, k) for x in inputs)
        qs, vs, accs = np.empty((k, n)), np.empty((k, nv)), np.empty((k, nv))
        iterations, residuals, conditions = np.empty(k, dtype=int), np.empty(k), np.empty(k)
        q = system.initial_q.copy() if q0 is None else np.asarray(q0, dtype=float).copy()
        v = a = None
        for i, t in enumerate(times):
            u, ud, udd = u_all[:, i], ud_all[:, i], udd_all[:, i]
            if i > 0 and self.options.predictor:
                h = t - times[i - 1]
                q = self.retract(q, v * h + 0.5 * a * h * h)
            q, iterations[i], residuals[i], jacobian = self._position(q, u, t)
            factors = self._factor(jacobian, t)
            v, a = self.rates(q, u, ud, udd, factors)
            conditions[i] = self._condition(jacobian, factors)
            qs[i], vs[i], accs[i] = q, v, a
        return Results(system, times, qs, vs, accs, iterations, residuals, conditions, u_all.T.copy(), self.options.condition)


def solve(system: NumericSystem, times: np.ndarray | None = None, options: SolverOptions | None = None) -> Results:
    """Convenience: ``Solver(system, options).solve(times)``."""
    return Solver(system, options).solve(times)


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
    order = np.argsort(-np.abs(phi))[:3]
    worst = [(system.constraint_names[i], float(phi[i])) for i in order]
    try:
        _, iterations, final = solver.position(system.initial_q, u, system.t0)
    except (ConvergenceError, SingularJacobianError) as exc:
        raise AssemblyError(system.t0, norm, worst, str(exc).splitlines()[0]) from exc
    return f"{prefix} off by max |Phi| = {norm:.2e} ({worst[0][0]}); assembled in {iterations} Newton iterations (max |Phi| = {final:.1e})"
