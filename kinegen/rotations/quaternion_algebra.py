"""Unit-quaternion algebra, order (w, x, y, z), Hamilton product: numeric (NumPy) and, at the
end, the few symbolic (SymPy) forms the parametrizations and constraints share.

Arrays may carry leading batch dimensions: a quaternion is ``q[..., 0:4]``.
"""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np
import sympy as sp
from sympy.core.parameters import distribute

#: Below this squared rotation angle x = theta . theta (1e-3: an angle of ~0.032 rad) the retraction's
#: cos(angle/2) and sin(angle/2)/angle are their Taylor polynomials in x to x^3: the first term left out is
#: below 1e-19 of either value there (x^4/10,321,920 and x^4/185,794,560), far under its rounding, so
#: the polynomials equal the functions to the last bit or two (tested against mpmath). A Newton
#: step's and nearly every predictor's increments are that small: the generated C's retract_body then
#: takes no sine or cosine (the excavator's certified step 104.1 -> 100.3 M instructions a thousand
#: steps, docs/performance.md).
SERIES_BELOW = 1e-3


#: The polynomials' coefficients, exact: cos(sqrt(x)/2) = 1 - x (1/8 - x (1/384 - x/46,080)) + ..., and
#: sin(sqrt(x)/2)/sqrt(x) = 1/2 - x (1/48 - x (1/3,840 - x/645,120)) + ...
COS_HALF_SERIES = (sp.Integer(1), sp.Rational(1, 8), sp.Rational(1, 384), sp.Rational(1, 46080))
SIN_HALF_OVER_ANGLE_SERIES = (sp.Rational(1, 2), sp.Rational(1, 48), sp.Rational(1, 3840), sp.Rational(1, 645120))
_COS_HALF, _SIN_HALF_OVER_ANGLE = (tuple(float(c) for c in series) for series in (COS_HALF_SERIES, SIN_HALF_OVER_ANGLE_SERIES))


def horner(x, c):
    """c0 - x (c1 - x (c2 - c3 x)): the order of operations the generated C prints (SymPy x and exact
    coefficients there, c3 x kept a product: SymPy would spread a number over a sum; NumPy x and the
    coefficients' doubles here)."""
    with distribute(False) if isinstance(x, sp.Basic) else nullcontext():
        return c[0] - x * (c[1] - x * (c[2] - c[3] * x))


def _half_angle(squared: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos(angle/2) and sin(angle/2)/angle at the squared rotation angles ``squared`` (NumPy): their
    Taylor polynomials at or below :data:`SERIES_BELOW`, as :func:`symbolic_increment` defines them."""
    small = squared <= SERIES_BELOW
    angle = np.sqrt(np.where(small, 1.0, squared))
    half = 0.5 * angle
    return np.where(small, horner(squared, _COS_HALF), np.cos(half)), np.where(small, horner(squared, _SIN_HALF_OVER_ANGLE), np.sin(half) / angle)


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q``."""
    pw, pv = p[..., 0], p[..., 1:]
    qw, qv = q[..., 0], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1)
    v = pw[..., None] * qv + qw[..., None] * pv + np.cross(pv, qv)
    return np.concatenate([w[..., None], v], axis=-1)


def increment(rotation_vector: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``exp(theta/2) ⊗ q`` (q rotated by the global rotation vector ``theta``), with the
    components on the FIRST axis: ``rotation_vector`` (3, ...), ``q`` (4, ...) -> (4, ...).

    The same as ``multiply(exp(theta), q)``, written out component by component: the
    retraction of every Newton step, where NumPy's per-call cost outweighs the arithmetic.
    Below an angle of ~0.032 rad (``theta . theta <= SERIES_BELOW``) the half angle's cosine and
    its sine over the angle are their Taylor polynomials (:data:`SERIES_BELOW`).
    """
    tx, ty, tz = rotation_vector
    qw, qx, qy, qz = q
    cos_half, scale = _half_angle(tx * tx + ty * ty + tz * tz)
    pw, px, py, pz = cos_half, scale * tx, scale * ty, scale * tz
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def conjugate(q: np.ndarray) -> np.ndarray:
    """``q*`` = (w, -x, -y, -z)."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a (not necessarily unit) quaternion, via the Euler-parameter formula."""
    w, x, y, z = (q[..., i] for i in range(4))
    rows = (
        (w * w + x * x - 0.5, x * y - w * z, x * z + w * y),
        (x * y + w * z, w * w + y * y - 0.5, y * z - w * x),
        (x * z - w * y, y * z + w * x, w * w + z * z - 0.5),
    )
    matrix = np.empty((*np.shape(w), 3, 3))  # filled in place: a third of the time of nested np.stack on one quaternion
    for i, row in enumerate(rows):
        for j, entry in enumerate(row):
            matrix[..., i, j] = entry
    return 2.0 * matrix


def from_matrix(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternion (w >= 0) of rotation matrices (..., 3, 3), by Shepperd's method: the
    largest of w², x², y², z² is taken from the diagonal, the others from off-diagonal sums.

    (SciPy's ``Rotation.from_matrix`` gives the same to rounding — tested — but importing
    ``scipy.spatial`` costs ~0.5 s, which a build in a fresh process would pay.)
    """
    m = np.asarray(rotation, dtype=float)
    trace = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    candidates = np.stack([trace, m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]], axis=-1)
    k = np.argmax(candidates, axis=-1)
    d = 1.0 + 2.0 * np.take_along_axis(candidates, k[..., None], axis=-1)[..., 0] - trace  # 4 * (largest)^2
    wx, wy, wz = m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]
    xy, xz, yz = m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1]
    by_largest = np.stack(
        [
            np.stack([d, wx, wy, wz], axis=-1),  # w largest: 4w * (w, x, y, z)
            np.stack([wx, d, xy, xz], axis=-1),  # x largest: 4x * (w, x, y, z)
            np.stack([wy, xy, d, yz], axis=-1),
            np.stack([wz, xz, yz, d], axis=-1),
        ],
        axis=-2,
    )
    q = np.take_along_axis(by_largest, k[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def exp(rotation_vector: np.ndarray) -> np.ndarray:
    """Unit quaternion of the rotation vector ``theta`` (axis * angle): exp(theta/2)."""
    rotation_vector = np.asarray(rotation_vector, dtype=float)
    cos_half, scale = _half_angle(np.einsum("...i,...i->...", rotation_vector, rotation_vector))
    return np.concatenate([cos_half[..., None], scale[..., None] * rotation_vector], axis=-1)


# ---- symbolic ----------------------------------------------------------------------------
def symbolic_product(p: sp.Matrix, q: sp.Matrix) -> sp.Matrix:
    """Hamilton product p ⊗ q of symbolic quaternions (w, x, y, z) as 4x1 matrices."""
    pw, pv, qw, qv = p[0], sp.Matrix(p[1:]), q[0], sp.Matrix(q[1:])
    return sp.Matrix([pw * qw - (pv.T * qv)[0], *(pw * qv + qw * pv + pv.cross(qv))])


def symbolic_increment(theta: sp.Matrix, q: sp.Matrix) -> list[sp.Expr]:
    """``exp(theta/2) ⊗ q`` of a symbolic rotation vector (3x1) and quaternion (4x1), as
    :func:`increment` computes it: the half angle's cosine and its sine over the angle by their
    Taylor polynomials where theta . theta <= :data:`SERIES_BELOW` (the branch taken alone is
    evaluated in the generated C)."""
    squared = sum((x * x for x in theta), sp.Integer(0))
    angle = sp.sqrt(squared)
    small = squared <= sp.Float(SERIES_BELOW)
    cos_half = sp.Piecewise((horner(squared, COS_HALF_SERIES), small), (sp.cos(angle / 2), True))
    scale = sp.Piecewise((horner(squared, SIN_HALF_OVER_ANGLE_SERIES), small), (sp.sin(angle / 2) / angle, True))
    exp = sp.Matrix([cos_half, *(scale * x for x in theta)])
    return list(symbolic_product(exp, q))


def symbolic_conjugate(q: sp.Matrix) -> sp.Matrix:
    """Conjugate (w, -x, -y, -z)."""
    return sp.Matrix([q[0], -q[1], -q[2], -q[3]])


def left_pure(q: sp.Matrix) -> sp.Matrix:
    """M(q) (4x3) with (0, w) ⊗ q = M(q) w."""
    w, x, y, z = q
    return sp.Matrix([[-x, -y, -z], [w, z, -y], [-z, w, x], [y, -x, w]])


def spin_derivatives(a: sp.Matrix) -> list[sp.Matrix]:
    """dA/dθ_k = [e_k]x A (k = x, y, z) for A -> exp([θ]x) A: global rotation increments."""
    axes = [
        sp.Matrix([[0, 0, 0], [0, 0, -1], [0, 1, 0]]),
        sp.Matrix([[0, 0, 1], [0, 0, 0], [-1, 0, 0]]),
        sp.Matrix([[0, -1, 0], [1, 0, 0], [0, 0, 0]]),
    ]
    return [k * a for k in axes]
