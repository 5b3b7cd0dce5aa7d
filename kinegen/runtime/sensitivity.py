"""Exact sensitivities of a solved trajectory with respect to the design parameters.

At every time point the constraints hold, Φ(q(p), u(t), p) = 0, so by implicit
differentiation ``Φ_q S + Φ_p = 0``: the coordinate sensitivities ``S = dq/dp = −Φ_q⁻¹ Φ_p``
(n_v × n_design, in velocity coordinates: a change of the pose along the parametrization's
tangent directions, like a velocity). Φ_q and Φ_p are the generated exact kernels; the
solves are batched over the time points. A named point ``P = r + A s(p)`` then moves by
``dP/dp = dr + dθ × (A s) + A ds/dp``, with (dr, dθ) the frame's change for S (the
parametrization's ``frame_velocity`` applied to S) and ds/dp the generated derivative of the
point's body coordinates.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from kinegen.model.schema import GROUND

if TYPE_CHECKING:
    from kinegen.runtime.results import Results


def coordinate_sensitivities(results: Results) -> np.ndarray:
    """dq/dp at every time point, (K, n_v, n_design); NaN where the solve did not converge."""
    system = results.system
    if not system.design:
        raise ValueError(f"model {system.model!r} has no design parameters: nothing to differentiate by")
    if system.phi_p is None:
        raise ValueError(f"the module of {system.model!r} has no Phi_p (built by an older kinegen): rebuild it")
    m, n, n_design = len(system.constraint_names), system.n_velocity, len(system.design)
    if m != n:
        raise ValueError(f"Phi_q of {system.model!r}/{system.case} is {m} x {n} (redundant constraints): sensitivities need it square")
    done = np.flatnonzero(results.converged)
    q, u = results.q[done].T, results.inputs[done].T
    jacobian = np.zeros((len(done), m, n))
    jacobian[:, system.jac_rows, system.jac_cols] = np.asarray(system.jac(q, u)).T
    design = np.zeros((len(done), m, n_design))
    design[:, system.p_rows, system.p_cols] = np.asarray(system.phi_p(q, u)).reshape(len(system.p_rows), -1).T
    out = np.full((len(results.times), n, n_design), np.nan)
    out[done] = -np.linalg.solve(jacobian, design)
    return out


def point_sensitivity(results: Results, body: str, point: str, sensitivities: np.ndarray | None = None) -> np.ndarray:
    """d(global position of a named point)/dp, (K, 3, n_design)."""
    system = results.system
    derivatives = system.point_derivatives.get(body, {})
    if point not in derivatives:
        raise KeyError(f"no point {point!r} on body {body!r}")
    if body == GROUND:
        return np.broadcast_to(derivatives[point], (len(results.times), 3, len(system.design))).copy()
    s = coordinate_sensitivities(results) if sensitivities is None else sensitivities
    stored, _, _ = results._body(body)
    start = system.bodies[body][1]
    along = s[:, start : start + system.parametrization.nv, :]  # (K, nv, n_design)
    arm = results._arm(body, point)  # A s, (K, 3)
    rotation = results.rotation_matrix(body)
    out = np.empty((len(results.times), 3, len(system.design)))
    for k in range(len(system.design)):
        shift, turn = system.parametrization.frame_velocity(stored, along[:, :, k])
        out[:, :, k] = shift + np.cross(turn, arm) + rotation @ derivatives[point][:, k]
    return out
