"""Exact sensitivities of a solved trajectory with respect to the design parameters.

At every time point the constraints hold, Φ(q(p), u(t), p) = 0, so by implicit
differentiation ``Φ_q S + Φ_p = 0``: the configuration sensitivities ``S = dq/dp = −Φ_q⁻¹ Φ_p``
(n_v × n_design, in velocity coordinates: a change of the pose along the parametrization's
tangent directions, like a velocity). Differentiating the velocity and acceleration
equations ``Φ_q v = ν`` and ``Φ_q a = γ`` the same way gives ``Φ_q V = −(M_v S + E_v)`` and
``Φ_q W = −(M_a S + N_a V + E_a)`` for V = dv/dp and W = da/dp, with the sparse matrices
``[M_v | E_v]`` (kernel ``dvel``) and ``[M_a | N_a | E_a]`` (kernel ``dacc``) generated exactly
(:data:`kinegen.codegen.kernels.SENSITIVITY_KERNELS`). Each kernel runs once per time point, for
all parameters; Φ_q is factored once per time point for the three solves -- in C
(``kinegen_sensitivities``) on the compiled path, else by the solver's LU in NumPy. A frame's
and a named point's position, velocity and acceleration then change as the generated
``frames_d`` kernel says (the frames' 24 values moved along (S, V, W)) plus what the point's
own body coordinates do (ds/dp).

These are functions of a :class:`kinegen.runtime.Results` (the data of one solve): a point's, a
body's, a relative angle's, an actuator length's and σ_min's derivatives, by one design parameter
(``parameter``) or by all of them (the last axis); the state's and the frames' sensitivities are
computed once per results (:meth:`~kinegen.runtime.Results.once`). Units: those of the quantity
per unit of the parameter.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

import kinegen.runtime.linear as linear
from kinegen.model.schema import GROUND
from kinegen.runtime import kinematics
from kinegen.runtime.blocksolve import BlockSolve

if TYPE_CHECKING:
    from kinegen.runtime.results import Results
    from kinegen.runtime.system import NumericSystem

#: the name :func:`state_sensitivities` keeps its value under (:meth:`kinegen.runtime.Results.once`):
#: a caller that knows them otherwise (motions stacked from one solve) may seed them
STATE = "state_sensitivities"
#: what a point sensitivity can be of
KINDS = ("position", "velocity", "acceleration")
#: time points per NumPy batch of the Python path (bounds its memory: entries x batch x n_design)
BATCH = 64


def _trajectory(results: Results) -> tuple[np.ndarray, ...]:
    """The converged time points' indices, then q, v, a, u, ud, udd there (components first, (n, K))."""
    system = results.system
    done = np.flatnonzero(results.converged)
    q, v, a = results.q[done].T, results.v[done].T, results.a[done].T
    u, ud, udd = np.asarray(system.inputs(results.times[done]), dtype=float).reshape(3, system.n_inputs, len(done))
    return done, q, v, a, u, ud, udd


def _each(x: np.ndarray, n_design: int) -> np.ndarray:
    """(n, K) -> (n, K n_design): every time point's column once per parameter (one kernel call
    for every (time point, parameter) pair). Laid out column by column (the transpose of a
    C-contiguous array), as the compiled kernels read a batch: no copy on the way there."""
    return np.repeat(x.T, n_design, axis=0).T


def _pairs(x: np.ndarray) -> np.ndarray:
    """(K, n, n_design) -> (n, K n_design), in the order of :func:`_each`, laid out as it lays out."""
    return x.transpose(0, 2, 1).reshape(-1, x.shape[1]).T


def _check(system: NumericSystem) -> None:
    if not system.design:
        raise ValueError(f"model {system.model!r} has no design parameters: nothing to differentiate by")
    if not system.sensitivity_kernels:
        raise ValueError(
            f"the module of {system.model!r} ({system.parametrization.name}) has no sensitivity kernels (built with "
            "--no-sensitivities, or by an older kinegen): rebuild it with `kinegen build` without that option"
        )
    if len(system.constraint_names) != system.n_velocity:
        raise ValueError(
            f"Phi_q of {system.model!r}/{system.case} is {len(system.constraint_names)} x {system.n_velocity} "
            "(redundant constraints): sensitivities need it square"
        )


def state_sensitivities(results: Results) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(dq/dp, dv/dp, da/dp) at every time point, each (K, n_v, n_design), in velocity coordinates;
    NaN where the solve did not converge (or Φ_q is singular). Computed once per results. On the
    compiled path one C call does every time point; else Φ_q is factored once per time point by
    the solver's own LU (:func:`kinegen.runtime.linear.choose`: dense, or band for long chains)."""
    return results.once(STATE, _state_sensitivities)


def _state_sensitivities(results: Results) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    system = results.system
    _check(system)
    n, n_design = system.n_velocity, len(system.design)
    done, *state = _trajectory(results)
    parts = system.native.sensitivities(*state) if system.native is not None and system.native.sensitivity_doubles else None
    if parts is None:  # no compiled sensitivity kernels (none in the module, or they would not compile)
        parts = _python_sensitivities(system, *state)
    if len(done) == len(results.times):  # every time point converged: the computed arrays are the whole answer
        return tuple(np.asarray(part, dtype=float).reshape(len(results.times), n, n_design) for part in parts)
    out = tuple(np.full((len(results.times), n, n_design), np.nan) for _ in range(3))
    for full, part in zip(out, parts):
        full[done] = part
    return out


#: from this many configurations on, :func:`_inverse` solves block by block in batches (as the batched Newton)
BLOCK_BATCH = 32
_BLOCK_SOLVES: dict[bytes, object] = {}


def _block_solve(system: NumericSystem):
    """The batched block-triangular solve (:class:`kinegen.runtime.batch.BlockSolve`) of the
    system's Phi_q pattern, made once per pattern; None when it has no square block form."""
    key = np.asarray(system.jac_rows).tobytes() + b"|" + np.asarray(system.jac_cols).tobytes() + bytes(str(system.n_velocity), "ascii")
    if key not in _BLOCK_SOLVES:
        try:
            _BLOCK_SOLVES[key] = BlockSolve(system)
        except ValueError:
            _BLOCK_SOLVES[key] = None
    return _BLOCK_SOLVES[key]


def _inverse(system: NumericSystem, q: np.ndarray, u: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """x = Φ_q⁻¹ b at each configuration (columns of q and u), Φ_q factored once each by the
    solver's own LU (:func:`kinegen.runtime.linear.choose`): b, x of shape (K, m, ...)."""
    m = system.n_velocity
    count = np.shape(q)[1]
    jac = np.broadcast_to(np.asarray(system.jac(q, u), dtype=float).reshape(len(system.jac_rows), -1), (len(system.jac_rows), count))
    if count >= BLOCK_BATCH:  # many: Phi_q's diagonal blocks solved for all configurations at once
        blocks = _block_solve(system)
        if blocks is not None:
            return lambda b: blocks.solve(jac, b.reshape(count, m, -1).transpose(1, 0, 2)).transpose(1, 0, 2).reshape(b.shape)
    lu = linear.choose(system.jac_rows, system.jac_cols, (m, m))
    factors = [lu.factor(jac[:, k])[0] for k in range(count)]
    return lambda b: np.stack([lu.solve(f, x) for f, x in zip(factors, b)])


def _python_sensitivities(system: NumericSystem, q, v, a, u, ud, udd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`state_sensitivities` at the columns of (q, v, a, u, ud, udd) in NumPy, each kernel
    called once per batch of :data:`BATCH` time points."""
    m, n_design = system.n_velocity, len(system.design)
    count = q.shape[1]
    kernels, patterns = system.sensitivity_kernels, system.sensitivity_patterns
    out = tuple(np.empty((count, m, n_design)) for _ in range(3))
    for first in range(0, count, BATCH):
        k = slice(first, min(first + BATCH, count))
        inverse = _inverse(system, q[:, k], u[:, k])

        def solve(rhs: np.ndarray, inverse=inverse) -> np.ndarray:  # -Phi_q^-1 rhs, (K, m, n_design)
            return -inverse(rhs)

        shape = (k.stop - k.start, m, n_design)
        s = solve(_sparse_times(patterns["phi_p"], kernels["phi_p"](q[:, k], u[:, k]), shape, 0))
        velocity = solve(_sparse_times(patterns["dvel"], kernels["dvel"](q[:, k], v[:, k], u[:, k], ud[:, k]), shape, m, s))
        values = kernels["dacc"](q[:, k], v[:, k], a[:, k], u[:, k], ud[:, k], udd[:, k])
        acceleration = solve(_sparse_times(patterns["dacc"], values, shape, 2 * m, s, velocity))
        for full, part in zip(out, (s, velocity, acceleration)):
            full[k] = part
    return out


def _sparse_times(pattern: tuple[np.ndarray, np.ndarray], values, shape: tuple[int, int, int], first_parameter: int,
                  *blocks: np.ndarray) -> np.ndarray:  # fmt: skip
    """The sparse matrix given by ``values`` (n_entries, K) at ``pattern`` times [blocks...; I]
    at every time point: ``shape`` = (K, m, n_design). Columns below ``first_parameter`` multiply
    the rows of the blocks (each (K, m, n_design), stacked), the others are the parameters'
    (identity)."""
    rows, cols = pattern
    values = np.broadcast_to(np.asarray(values, dtype=float).reshape(len(rows), -1), (len(rows), shape[0]))
    out = np.zeros(shape)
    by_state = cols < first_parameter
    if blocks:
        stacked = np.concatenate(blocks, axis=1)  # (K, first_parameter, n_design)
        products = values[by_state].T[:, :, None] * stacked[:, cols[by_state], :]  # (K, entries, n_design)
        np.add.at(out, (slice(None), rows[by_state]), products)
    parameter = ~by_state
    np.add.at(out, (slice(None), rows[parameter], cols[parameter] - first_parameter), values[parameter].T)
    return out


def frame_sensitivities(results: Results) -> np.ndarray:
    """The change of every body's frame values (FRAME_VALUES of them, as the module's
    FRAME_FIELDS lists: origin, rotation matrix row by row, origin velocity, ω, origin
    acceleration, ω̇) per unit of each design parameter, (K, n_bodies, FRAME_VALUES, n_design): the
    generated ``frames_d`` kernel along (dq/dp, dv/dp, da/dp), one call; computed once per results."""
    return results.once("frame_sensitivities", lambda r: frame_changes(r.system, r.q.T, r.v.T, r.a.T, *state_sensitivities(r)))


def frame_changes(system: NumericSystem, q, v, a, s: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray) -> np.ndarray:
    """The change of every body's frame values at the states (q, v, a) (columns, (n, K)) along
    m changes of the state: ``s`` of q (in velocity coordinates), ``velocity`` of v and
    ``acceleration`` of a, each (K, n_v, m); (K, n_bodies, FRAME_VALUES, m), one ``frames_d`` call."""
    count, m = s.shape[0], s.shape[2]
    state = (_each(np.asarray(x, dtype=float).reshape(-1, count), m) for x in (q, v, a))
    changes = system.frames_d(*state, _pairs(s), _pairs(velocity), _pairs(acceleration))
    return np.asarray(changes, dtype=float).reshape(len(system.bodies), -1, count, m).transpose(2, 0, 1, 3)


def configuration_sensitivities(
    system: NumericSystem, q: np.ndarray, u: np.ndarray, design: bool = True
) -> tuple[np.ndarray | None, np.ndarray]:
    """At solved configurations q (n_q, K) with inputs u (n_inputs, K) -- a sweep's or an
    envelope's, not a trajectory's --: (dq/dp (K, n_v, n_design), dq/du (K, n_v, n_inputs)), in
    velocity coordinates, by implicit differentiation of Φ(q, u, p) = 0: dq/dp = −Φ_q⁻¹ Φ_p and
    dq/du = −Φ_q⁻¹ Φ_u with Φ_u e_j = −ν(q, u, u̇ = e_j) (time enters Φ only through u). Without
    ``design`` (or design parameters) only dq/du, which any module gives: (None, dq/du)."""
    q, u = np.asarray(q, dtype=float), np.asarray(u, dtype=float)
    m, n_inputs, count = system.n_velocity, system.n_inputs, q.shape[1]
    if system.native is not None and not (design and system.design):  # compiled: in C, configuration by configuration
        return None, system.native.input_effects(q, u)
    if count == 1 and not (design and system.design):  # one configuration: the system's fast kernels (compiled when there)
        unit = np.eye(n_inputs)
        rates = np.stack([system.velocity_rhs(q[:, 0], u[:, 0], unit[j]) for j in range(n_inputs)], axis=1)  # -Phi_u
        return None, scipy.linalg.solve(system.jacobian(q[:, 0], u[:, 0]), rates)[None]
    inverse = _inverse(system, q, u)
    unit = np.eye(n_inputs)
    by_input = np.stack([np.broadcast_to(np.asarray(system.nu(q, u, np.broadcast_to(unit[:, [j]], u.shape)), dtype=float).reshape(m, -1), (m, count))
                         for j in range(n_inputs)], axis=2).transpose(1, 0, 2)  # fmt: skip  # -Phi_u, (K, m, n_inputs)
    by_design = None
    if design and system.design:
        _check(system)
        values = system.sensitivity_kernels["phi_p"](q, u)
        by_design = -inverse(_sparse_times(system.sensitivity_patterns["phi_p"], values, (count, m, len(system.design)), 0))
    return by_design, inverse(by_input)


def point_position_sensitivities(
    system: NumericSystem, q: np.ndarray, u: np.ndarray, points: list[tuple[str, str]], design: bool = True
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Global positions of the named ``points`` (body, point) at solved configurations q (n_q, K)
    with inputs u (n_inputs, K), and their exact derivatives by the design parameters and by the
    driver inputs: (K, P, 3), (K, P, 3, n_design) (None without ``design``), (K, P, 3, n_inputs).
    A change of the configuration along a tangent direction moves a body point as a velocity
    does (the parametrization's ``frame_velocity``); a design parameter also moves the point in
    its body (ds'/dp)."""
    q = np.asarray(q, dtype=float)
    count = q.shape[1]
    by_design, by_input = configuration_sensitivities(system, q, u, design)
    change = by_input if by_design is None else np.concatenate([by_design, by_input], axis=2)  # (K, n_v, m)
    n_design = 0 if by_design is None else by_design.shape[2]
    parametrization = system.parametrization
    positions, derivatives = np.empty((count, len(points), 3)), np.empty((count, len(points), 3, change.shape[2]))
    for i, (body, point) in enumerate(points):
        local_change = np.zeros((3, change.shape[2]))
        if n_design:
            local_change[:, :n_design] = system.point_derivatives.get(body, {}).get(point, np.zeros((3, n_design)))
        if body == GROUND:
            positions[:, i] = system.ground_points[point]
            derivatives[:, i] = local_change
            continue
        stored = system.body_coordinates(q.T, body)  # (K, nq)
        origin, rotation = parametrization.pose(stored)
        arm = rotation @ np.asarray(system.points[body][point], dtype=float)
        positions[:, i] = origin + arm
        tangent = system.body_coordinates(change.transpose(0, 2, 1), body, velocity=True)  # (K, m, nv)
        moved, turned = parametrization.frame_velocity(np.repeat(stored[:, None], change.shape[2], axis=1), tangent)
        derivatives[:, i] = (moved + _cross(turned, arm[:, None, :])).transpose(0, 2, 1)
        derivatives[:, i] += np.einsum("kij,jm->kim", rotation, local_change)
    return positions, None if by_design is None else derivatives[..., :n_design], derivatives[..., n_design:]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (3), broadcast: np.cross's products and differences, in the same
    order (the same bits), without its axis handling (most of its time on the few vectors here)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def body_blocks(system: NumericSystem, bodies: tuple[str, ...]) -> list[tuple[np.ndarray, np.ndarray]]:
    """(rows, columns) of the diagonal blocks of Φ_q's block-triangular form that hold a velocity
    coordinate of one of ``bodies`` (a linkage's loops: where its toggles show)."""
    from kinegen.symbolic.blocks import block_triangular

    blocks = block_triangular((len(system.constraint_names), system.n_velocity), system.jac_rows, system.jac_cols) or []
    nv = system.parametrization.nv
    columns = {system.bodies[b][1] + k for b in bodies for k in range(nv)}
    return [(np.array(b.rows), np.array(b.cols)) for b in blocks if columns & set(b.cols)]


def critical_block_sensitivity(results: Results, bodies: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """At every time point the smallest σ_min of the diagonal blocks that hold coordinates of
    ``bodies`` (K,) -- the critical block's distance to a singular pose --, its exact derivative
    by the design parameters (K, n_design) and which block it is (K,: index into
    :func:`body_blocks`)."""
    blocks = body_blocks(results.system, bodies)
    if not blocks:
        raise ValueError(f"no diagonal block of Phi_q holds coordinates of {', '.join(bodies)}")
    measured = [singular_value_sensitivity(results, block) for block in blocks]
    sigma = np.stack([s for s, _ in measured])  # (blocks, K)
    critical = np.nanargmin(np.where(np.isnan(sigma), np.inf, sigma), axis=0)
    count = np.arange(sigma.shape[1])
    return sigma[critical, count], np.stack([d for _, d in measured])[critical, count], critical


def singular_value_sensitivity(results: Results, block: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The smallest singular value σ of Φ_q at every time point (K,) -- the distance to a
    singular pose -- and its exact derivative by the design parameters (K, n_design):
    dσ/dp = uᵀ (dΦ_q/dp) x with u, x its singular vectors and dΦ_q/dp x = M_v(x) S + E_v(x)
    (the ``dvel`` kernel with x in place of v and no time rates). With ``block`` (rows,
    columns of Φ_q), of that block instead: a diagonal block of Φ_q's block-triangular form,
    where a singularity shows undiluted by the rest of the mechanism. NaN where the solve did
    not converge."""
    system = results.system
    s, _, _ = state_sensitivities(results)
    m, n_design = system.n_velocity, len(system.design)
    done, q, _, _, u, _, _ = _trajectory(results)
    rows, cols = (np.arange(m), np.arange(m)) if block is None else (np.asarray(block[0]), np.asarray(block[1]))
    jacobian = np.zeros((len(done), m, m))
    jacobian[:, system.jac_rows, system.jac_cols] = np.asarray(system.jac(q, u), dtype=float).reshape(len(system.jac_rows), -1).T
    left, values, right = np.linalg.svd(jacobian[:, rows][:, :, cols])
    smallest = values[:, -1]
    x = np.zeros((len(done), m))
    x[:, cols] = right[:, -1, :]  # the right singular vector, zero outside the block's columns
    dvel = system.sensitivity_kernels["dvel"](q, x.T, u, np.zeros_like(u))
    d_jacobian_x = _sparse_times(system.sensitivity_patterns["dvel"], dvel, (len(done), m, n_design), m, s[done])
    sigma, derivative = np.full(len(results.times), np.nan), np.full((len(results.times), n_design), np.nan)
    sigma[done] = smallest
    derivative[done] = np.einsum("ki,kij->kj", left[:, :, -1], d_jacobian_x[:, rows])
    return sigma, derivative


def point_sensitivity(results: Results, body: str, point: str, *, kind: str = "position", parameter: str | None = None) -> np.ndarray:
    """d(global position, velocity or acceleration of a named point)/dp: by every design
    parameter, (K, 3, n_design), or by ``parameter``, (K, 3)."""
    return by_parameter(results, _point_sensitivity(results, body, point, kind), parameter)


def _point_sensitivity(results: Results, body: str, point: str, kind: str) -> np.ndarray:
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    system = results.system
    _check(system)
    derivatives = system.point_derivatives.get(body, {})
    if point not in derivatives:
        raise KeyError(f"no point {point!r} on body {body!r}")
    n_design, count = len(system.design), len(results.times)
    if body == GROUND:
        change = derivatives[point] if kind == "position" else np.zeros((3, n_design))
        return np.broadcast_to(change, (count, 3, n_design)).copy()
    frame = frame_sensitivities(results)[:, list(system.bodies).index(body)]  # (K, FRAME_VALUES, n_design)
    at = system.frame_slices
    rotation, arm = kinematics.rotation_matrix(results, body), kinematics.arm(results, body, point)
    omega, omega_dot = kinematics.omega(results, body), kinematics.omega_dot(results, body)
    local = np.asarray(system.points[body][point], dtype=float)
    out = np.empty((count, 3, n_design))
    for k in range(n_design):
        d_rotation = frame[:, at["rotation"], k].reshape(count, 3, 3)
        d_arm = d_rotation @ local + rotation @ derivatives[point][:, k]
        if kind == "position":
            out[:, :, k] = frame[:, at["origin"], k] + d_arm
        elif kind == "velocity":
            out[:, :, k] = frame[:, at["velocity"], k] + np.cross(frame[:, at["angular_velocity"], k], arm) + np.cross(omega, d_arm)
        else:
            d_omega, d_omega_dot = frame[:, at["angular_velocity"], k], frame[:, at["angular_acceleration"], k]
            out[:, :, k] = (
                frame[:, at["acceleration"], k] + np.cross(d_omega_dot, arm) + np.cross(omega_dot, d_arm)
                + np.cross(d_omega, np.cross(omega, arm)) + np.cross(omega, np.cross(d_omega, arm) + np.cross(omega, d_arm))
            )  # fmt: skip
    return out


def rotation_sensitivity(results: Results, body: str, *, parameter: str | None = None) -> np.ndarray:
    """The change of a body's orientation per unit of each design parameter, as a global rotation
    vector (dA/dp = [dθ/dp]× A), (K, 3, n_design), or of ``parameter``, (K, 3)."""
    return by_parameter(results, _rotation_sensitivity(results, body), parameter)


def _rotation_sensitivity(results: Results, body: str) -> np.ndarray:
    system = results.system
    if body not in system.bodies:
        raise KeyError(f"no body {body!r} (bodies: {', '.join(system.bodies)})")
    d_rotation = frame_sensitivities(results)[:, list(system.bodies).index(body), system.frame_slices["rotation"]]  # (K, 9, n_design)
    count = len(results.times)
    rotation = kinematics.rotation_matrix(results, body)
    out = np.empty((count, 3, len(system.design)))
    for k in range(len(system.design)):
        spin = d_rotation[:, :, k].reshape(count, 3, 3) @ np.swapaxes(rotation, 1, 2)  # [dθ]x
        out[:, :, k] = np.stack([spin[:, 2, 1] - spin[:, 1, 2], spin[:, 0, 2] - spin[:, 2, 0], spin[:, 1, 0] - spin[:, 0, 1]], axis=1) / 2
    return out


def relative_angle_sensitivity(results: Results, body1: str, body2: str, axis: tuple[float, float, float], *,
                               parameter: str | None = None) -> np.ndarray:  # fmt: skip
    """Exact derivative of the rotation angle of ``body2`` relative to ``body1`` about ``axis``
    (a unit vector in body-1 coordinates, e.g. a revolute joint's axis; ``body1`` may be
    ``ground``) by every design parameter, (K, n_design), or by ``parameter``, (K,)."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    turn = _rotation_sensitivity(results, body2)
    if body1 == GROUND:
        direction = np.broadcast_to(axis, (len(results.times), 3))
    else:
        turn = turn - _rotation_sensitivity(results, body1)
        direction = kinematics.rotation_matrix(results, body1) @ axis
    return by_parameter(results, np.einsum("ki,kij->kj", direction, turn), parameter)


def smallest_singular_value_sensitivity(results: Results, *, parameter: str | None = None,
                                        bodies: tuple[str, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """σ_min of Φ_q at every time point (the distance to a singular pose) and its exact
    derivative by every design parameter, (K, n_design), or by ``parameter``, (K,). With ``bodies``
    (a linkage), of the critical block instead: at each time point the diagonal block of Φ_q's
    block-triangular form holding their coordinates with the smallest σ_min, where a toggle
    shows undiluted by the rest of the mechanism (:func:`critical_block_sensitivity`)."""
    if bodies is None:
        sigma, derivative = singular_value_sensitivity(results)
    else:
        sigma, derivative, _ = critical_block_sensitivity(results, tuple(bodies))
    return sigma, by_parameter(results, derivative, parameter)


def actuator_length_sensitivity(results: Results, name: str, *, parameter: str | None = None) -> np.ndarray:
    """Exact derivative of an actuator's length by every design parameter, (K, n_design), or by
    ``parameter``, (K,)."""
    system = results.system
    if name not in system.actuators:
        raise KeyError(f"no actuator {name!r} (actuators: {', '.join(system.actuators) or 'none'})")
    (b1, p1), (b2, p2), _ = system.actuators[name]
    d = kinematics.point_position(results, b2, p2) - kinematics.point_position(results, b1, p1)
    change = _point_sensitivity(results, b2, p2, "position") - _point_sensitivity(results, b1, p1, "position")
    out = np.einsum("ki,kij->kj", d / np.linalg.norm(d, axis=1)[:, None], change)
    return by_parameter(results, out, parameter)


def by_parameter(results: Results, values: np.ndarray, parameter: str | None) -> np.ndarray:
    """``values`` with the design parameters on the last axis: all of them (None), or one
    (a KeyError naming the model's design parameters for an unknown name)."""
    if parameter is None:
        return values
    names = list(results.system.design)
    if parameter not in names:
        raise KeyError(f"no design parameter {parameter!r} (design parameters: {', '.join(names) or 'none'})")
    return values[..., names.index(parameter)]


def sensitivity_table(results: Results) -> tuple[list[str], np.ndarray]:
    """Column names and values of the sensitivity CSV export: per time point, the derivative
    of every named point's position, velocity and acceleration (``d(body.point_x)/d(p)``,
    ``d(body.point_vx)/d(p)``, ``d(body.point_ax)/d(p)``) and of every actuator's length by
    every design parameter."""
    system = results.system
    names, columns = ["t"], [results.times[:, None]]
    for body, points in system.points.items():
        for point in points:
            for kind, label in (("position", ""), ("velocity", "v"), ("acceleration", "a")):
                values = point_sensitivity(results, body, point, kind=kind)  # (K, 3, n_design)
                for k, parameter in enumerate(system.design):
                    names += [f"d({body}.{point}_{label}{c})/d({parameter})" for c in "xyz"]
                    columns.append(values[:, :, k])
    for actuator in system.actuators:
        values = actuator_length_sensitivity(results, actuator)
        names += [f"d({actuator}.length)/d({parameter})" for parameter in system.design]
        columns.append(values)
    return names, np.hstack(columns)


def sensitivities_to_csv(results: Results, path: str | Path) -> Path:
    """Write :func:`sensitivity_table` to a CSV file (one row per time point; ``-``: standard output)."""
    from kinegen.runtime.export import write_csv

    return write_csv(path, *sensitivity_table(results))


def sensitivities_to_json(results: Results, path: str | Path) -> Path:
    """Write :func:`sensitivity_table` as JSON: model, case, the design values, and per column
    name its values over time."""
    import json

    from kinegen.files import write_atomic

    names, values = sensitivity_table(results)
    path = Path(path)
    system = results.system
    document = {
        "model": system.model, "case": system.case, "design": system.design,
        "columns": {name: values[:, i].tolist() for i, name in enumerate(names)},
    }  # fmt: skip
    write_atomic(path, json.dumps(document))
    return path
