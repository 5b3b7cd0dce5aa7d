"""Exact sensitivities of a solved trajectory with respect to the design parameters.

At every time point the constraints hold, Φ(q(p), u(t), p) = 0, so by implicit
differentiation ``Φ_q S + Φ_p = 0``: the configuration sensitivities ``S = dq/dp = −Φ_q⁻¹ Φ_p``
(n_v × n_design, in velocity coordinates: a change of the pose along the parametrization's
tangent directions, like a velocity). Differentiating the velocity and acceleration
equations ``Φ_q v = ν`` and ``Φ_q a = γ`` the same way gives ``Φ_q V = −(ζ_v(S) + η_v)`` and
``Φ_q W = −(ζ_a(S, V) + η_a)`` for V = dv/dp and W = da/dp, with ζ and η generated exactly
per constraint (:func:`kinegen.codegen.kernels._sensitivity_rows`). Φ_q is factored once per
time point (the solver's LU) for the three solves; the kernels run once over all (time point,
parameter) pairs. A frame's and a named point's
position, velocity and acceleration then change as the generated ``frames_d`` kernel says
(the frames' 24 values moved along (S, V, W)) plus what the point's own body coordinates do
(ds/dp).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from kinegen.model.schema import GROUND
from kinegen.runtime import linear

if TYPE_CHECKING:
    from kinegen.runtime.results import Results

#: what a point sensitivity can be of
KINDS = ("position", "velocity", "acceleration")


def _trajectory(results: Results) -> tuple[np.ndarray, ...]:
    """The converged time points' indices, then q, v, a, u, ud, udd there (components first,
    (n, K)) and the values of Phi_q at its pattern (n_jac, K)."""
    system = results.system
    done = np.flatnonzero(results.converged)
    q, v, a = results.q[done].T, results.v[done].T, results.a[done].T
    u, ud, udd = np.asarray(system.inputs(results.times[done]), dtype=float).reshape(3, system.n_inputs, len(done))
    return done, q, v, a, u, ud, udd, np.asarray(system.jac(q, u), dtype=float).reshape(len(system.jac_rows), -1)


def _each(x: np.ndarray, n_design: int) -> np.ndarray:
    """(n, K) -> (n, K n_design): every time point's column once per parameter (one kernel call
    for every (time point, parameter) pair)."""
    return np.repeat(x, n_design, axis=1)


def _pairs(x: np.ndarray) -> np.ndarray:
    """(K, n, n_design) -> (n, K n_design), in the order of :func:`_each`."""
    return x.transpose(1, 0, 2).reshape(x.shape[1], -1)


def state_sensitivities(results: Results) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(dq/dp, dv/dp, da/dp) at every time point, each (K, n_v, n_design); NaN where the solve
    did not converge. Phi_q is factored once per time point by the solver's own LU
    (:func:`kinegen.runtime.linear.choose`: dense, or band for long chains)."""
    system = results.system
    if not system.design:
        raise ValueError(f"model {system.model!r} has no design parameters: nothing to differentiate by")
    if system.phi_p is None or system.vsens is None:
        raise ValueError(f"the module of {system.model!r} has no sensitivity kernels (built by an older kinegen): rebuild it")
    m, n, n_design = len(system.constraint_names), system.n_velocity, len(system.design)
    if m != n:
        raise ValueError(f"Phi_q of {system.model!r}/{system.case} is {m} x {n} (redundant constraints): sensitivities need it square")
    done, q, v, a, u, ud, udd, jac = _trajectory(results)
    count = len(done)
    lu = linear.choose(system.jac_rows, system.jac_cols, (m, n))
    factors = [lu.factor(jac[:, k])[0] for k in range(count)]

    def solve(rhs: np.ndarray) -> np.ndarray:  # (K, m, n_design), each time point by its factors
        return np.stack([lu.solve(f, b) for f, b in zip(factors, rhs)]) if count else rhs.copy()

    design = np.zeros((count, m, n_design))
    design[:, system.p_rows, system.p_cols] = np.asarray(system.phi_p(q, u)).reshape(len(system.p_rows), -1).T
    s = -solve(design)
    q_, v_, u_, ud_ = (_each(x, n_design) for x in (q, v, u, ud))
    rhs = _values(system.vsens(q_, v_, _pairs(s), u_, ud_), m, count, n_design, system.sensitivity_patterns["vsens"])
    velocity = -solve(rhs)
    values = system.asens(q_, v_, _each(a, n_design), _pairs(s), _pairs(velocity), u_, ud_, _each(udd, n_design))
    acceleration = -solve(_values(values, m, count, n_design, system.sensitivity_patterns["asens"]))
    out = tuple(np.full((len(results.times), n, n_design), np.nan) for _ in range(3))
    for full, part in zip(out, (s, velocity, acceleration)):
        full[done] = part
    return out


def frame_sensitivities(results: Results) -> np.ndarray:
    """The change of every body's 24 frame values (origin, rotation matrix row by row, origin
    velocity, ω, origin acceleration, ω̇) per unit of each design parameter, (K, n_bodies, 24,
    n_design): the generated ``frames_d`` kernel along (dq/dp, dv/dp, da/dp), one call."""
    system = results.system
    s, velocity, acceleration = results.state_sensitivities()
    n_design, count = len(system.design), len(results.times)
    state = (_each(x.T, n_design) for x in (results.q, results.v, results.a))
    changes = system.frames_d(*state, _pairs(s), _pairs(velocity), _pairs(acceleration))
    return np.asarray(changes, dtype=float).reshape(len(system.bodies), 24, count, n_design).transpose(2, 0, 1, 3)


def singular_value_sensitivity(results: Results) -> tuple[np.ndarray, np.ndarray]:
    """The smallest singular value σ of Φ_q at every time point (K,) -- the distance to a
    singular pose -- and its exact derivative by the design parameters (K, n_design):
    dσ/dp = uᵀ (dΦ_q/dp) x with u, x its singular vectors and dΦ_q/dp x = D_S(Φ_q x) + ∂_p(Φ_q x)
    (the velocity sensitivity kernel with x in place of v and no time rates). NaN where the
    solve did not converge."""
    system = results.system
    s, _, _ = results.state_sensitivities()
    m, n_design = len(system.constraint_names), len(system.design)
    done, q, _, _, u, _, _, jac = _trajectory(results)
    count = len(done)
    jacobian = np.zeros((count, m, system.n_velocity))
    jacobian[:, system.jac_rows, system.jac_cols] = jac.T
    left, values, right = np.linalg.svd(jacobian)
    smallest, x = values[:, -1], right[:, -1, :]  # (K,), (K, n)
    u_ = _each(u, n_design)
    out = system.vsens(_each(q, n_design), _each(x.T, n_design), _pairs(s[done]), u_, np.zeros_like(u_))
    d_jacobian_x = _values(out, m, count, n_design, system.sensitivity_patterns["vsens"])  # (K, m, n_design)
    sigma, derivative = np.full(len(results.times), np.nan), np.full((len(results.times), n_design), np.nan)
    sigma[done] = smallest
    derivative[done] = np.einsum("ki,kij->kj", left[:, :, -1], d_jacobian_x)
    return sigma, derivative


def _values(kernel_output: np.ndarray, m: int, count: int, n_design: int, pattern: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(count, m, n_design) from a sensitivity kernel's output over (time point, parameter) pairs:
    the per-constraint values plus each parameter's entries of the sparse part."""
    rows, cols = pattern
    values = np.broadcast_to(np.asarray(kernel_output, dtype=float).reshape(m + len(rows), -1), (m + len(rows), count * n_design))
    values = values.reshape(m + len(rows), count, n_design)
    out = values[:m].transpose(1, 0, 2).copy()
    for j, (row, col) in enumerate(zip(rows, cols)):
        out[:, row, col] += values[m + j, :, col]
    return out


def point_sensitivity(results: Results, body: str, point: str, kind: str = "position") -> np.ndarray:
    """d(global position, velocity or acceleration of a named point)/dp, (K, 3, n_design)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    system = results.system
    derivatives = system.point_derivatives.get(body, {})
    if point not in derivatives:
        raise KeyError(f"no point {point!r} on body {body!r}")
    n_design, count = len(system.design), len(results.times)
    if body == GROUND:
        change = derivatives[point] if kind == "position" else np.zeros((3, n_design))
        return np.broadcast_to(change, (count, 3, n_design)).copy()
    frame = results._frame_sensitivities()[:, list(system.bodies).index(body)]  # (K, 24, n_design)
    rotation, arm = results.rotation_matrix(body), results._arm(body, point)
    omega, omega_dot = results.omega(body), results.omega_dot(body)
    local = np.asarray(system.points[body][point], dtype=float)
    out = np.empty((count, 3, n_design))
    for k in range(n_design):
        d_rotation = frame[:, 3:12, k].reshape(count, 3, 3)
        d_arm = d_rotation @ local + rotation @ derivatives[point][:, k]
        if kind == "position":
            out[:, :, k] = frame[:, 0:3, k] + d_arm
        elif kind == "velocity":
            out[:, :, k] = frame[:, 12:15, k] + np.cross(frame[:, 15:18, k], arm) + np.cross(omega, d_arm)
        else:
            d_omega, d_omega_dot = frame[:, 15:18, k], frame[:, 21:24, k]
            out[:, :, k] = (
                frame[:, 18:21, k] + np.cross(d_omega_dot, arm) + np.cross(omega_dot, d_arm)
                + np.cross(d_omega, np.cross(omega, arm)) + np.cross(omega, np.cross(d_omega, arm) + np.cross(omega, d_arm))
            )  # fmt: skip
    return out


def rotation_sensitivity(results: Results, body: str) -> np.ndarray:
    """The change of a body's orientation per unit of each design parameter, as a global rotation
    vector (dA/dp = [dθ/dp]× A), (K, 3, n_design)."""
    system = results.system
    if body not in system.bodies:
        raise KeyError(f"no body {body!r} (bodies: {', '.join(system.bodies)})")
    d_rotation = results._frame_sensitivities()[:, list(system.bodies).index(body), 3:12]  # (K, 9, n_design)
    count = len(results.times)
    rotation = results.rotation_matrix(body)
    out = np.empty((count, 3, len(system.design)))
    for k in range(len(system.design)):
        spin = d_rotation[:, :, k].reshape(count, 3, 3) @ np.swapaxes(rotation, 1, 2)  # [dθ]x
        out[:, :, k] = np.stack([spin[:, 2, 1] - spin[:, 1, 2], spin[:, 0, 2] - spin[:, 2, 0], spin[:, 1, 0] - spin[:, 0, 1]], axis=1) / 2
    return out
