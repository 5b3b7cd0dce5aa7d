"""Unit dual quaternions, numeric (NumPy), components last: ``σ = q_r + ε q_d`` stored as the
8 values ``(q_r, q_d)``, each quaternion in w-x-y-z order, ``q_d = ½ t ⊗ q_r`` with ``t`` the
frame origin (a pure quaternion). A point ``p`` (body coordinates) is moved to
``vec(q_r ⊗ p ⊗ q_r*) + 2 vec(q_d ⊗ q_r*)``.

Twists here are *spatial* (global frame, at the global origin) and ordered angular then
linear: ``ξ = (ω, v)`` with ``v = ṙ − ω × r`` the velocity of the body point passing through
the global origin; then ``σ̇ = ½ ξ̂ ⊗ σ`` with ``ξ̂ = (0, ω) + ε (0, v)``, and a step ``ξ`` moves ``σ`` to
``exp(ξ) ⊗ σ`` where ``exp(ξ) = exp(ξ̂ / 2)`` is the SE(3) exponential map written as a
dual quaternion (a screw motion: rotation ``|ω|`` about, and translation along, one line).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

import kinegen.rotations.quaternion_algebra as qa

#: At or below this squared half-angle h² (2.5e-4: the rotation angle 2h ~0.032 rad of the quaternion's
#: quaternion_algebra.SERIES_BELOW) the exponential's coefficients cos h, sin(h)/h and (cos h - sin h/h)/h²
#: are their Taylor polynomials in h² to (h²)³ (Horner's form): the first term left out is below 1e-19 of
#: each value there, far under its rounding; the third would otherwise cancel (~1e-16/h² of itself
#: lost). A Newton step's and nearly every predictor's half-angles are that small: the generated C's
#: retract_body then takes no sine or cosine.
SERIES_BELOW = qa.SERIES_BELOW / 4
#: c0 - x (c1 - x (c2 - c3 x)) of each, exact: cos h = 1 - x/2 + x²/24 - x³/720 + ..., sin(h)/h = 1 - x/6 +
#: x²/120 - x³/5040 + ..., (cos h - sin h/h)/h² = -1/3 + x/30 - x²/840 + x³/45360 - ... (x = h²)
COS_SERIES = (sp.Integer(1), sp.Rational(1, 2), sp.Rational(1, 24), sp.Rational(1, 720))
SINC_SERIES = (sp.Integer(1), sp.Rational(1, 6), sp.Rational(1, 120), sp.Rational(1, 5040))
BEND_SERIES = (-sp.Rational(1, 3), -sp.Rational(1, 30), -sp.Rational(1, 840), -sp.Rational(1, 45360))
_COS, _SINC, _BEND = (tuple(float(c) for c in series) for series in (COS_SERIES, SINC_SERIES, BEND_SERIES))


def _coefficients(h: np.ndarray, h2: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """cos h, sin(h)/h and (cos h − sin h / h)/h² (the derivative of sin(h)/h divided by h) at
    the half-angles ``h`` (``h2``: their squares as summed, default h²); by their Taylor
    polynomials where h² <= :data:`SERIES_BELOW` (exact there: the next terms are below rounding)."""
    h = np.asarray(h, dtype=float)
    h2 = h * h if h2 is None else np.asarray(h2, dtype=float)
    if h2.size and h2.min() > SERIES_BELOW:  # a large step: no polynomial needed
        cos, sinc = np.cos(h), np.sin(h) / h
        return cos, sinc, (cos - sinc) / h2
    small = h2 <= SERIES_BELOW
    safe = np.where(small, 1.0, h)
    cos = np.where(small, qa.horner(h2, _COS), np.cos(h))
    sinc = np.where(small, qa.horner(h2, _SINC), np.sin(h) / safe)
    bend = np.where(small, qa.horner(h2, _BEND), (cos - sinc) / np.where(small, 1.0, h2))  # (as the large steps' line above)
    return cos, sinc, bend


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Dual quaternion product p ⊗ q = p_r q_r + ε (p_r q_d + p_d q_r) (components last)."""
    p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    real = qa.multiply(p[..., :4], q[..., :4])
    dual = qa.multiply(p[..., :4], q[..., 4:]) + qa.multiply(p[..., 4:], q[..., :4])
    return np.concatenate([real, dual], axis=-1)


def conjugate(s: np.ndarray) -> np.ndarray:
    """Quaternion conjugate of both parts (the inverse of a unit dual quaternion)."""
    s = np.asarray(s, dtype=float)
    return np.concatenate([qa.conjugate(s[..., :4]), qa.conjugate(s[..., 4:])], axis=-1)


def from_pose(position: np.ndarray, rotation_quaternion: np.ndarray) -> np.ndarray:
    """σ of a frame at ``position`` with orientation ``rotation_quaternion`` (w, x, y, z)."""
    position = np.asarray(position, dtype=float)
    q = np.asarray(rotation_quaternion, dtype=float)
    t = np.concatenate([np.zeros(position.shape[:-1] + (1,)), position], axis=-1)
    return np.concatenate([q, 0.5 * qa.multiply(t, q)], axis=-1)


def translation(s: np.ndarray) -> np.ndarray:
    """Frame origin ``2 vec(q_d ⊗ q_r*)`` (..., 3)."""
    s = np.asarray(s, dtype=float)
    return 2.0 * qa.multiply(s[..., 4:], qa.conjugate(s[..., :4]))[..., 1:]


def translation_first(s: np.ndarray) -> np.ndarray:
    """:func:`translation` with the components on the FIRST axis: (8, ...) -> (3, ...)."""
    return np.einsum("ijk,j...,k...->i...", _TRANSLATION, s[4:], s[:4])


def cross_first(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b with the components on the FIRST axis (np.cross(..., axis=0) moves axes: slower)."""
    return np.einsum("ijk,j...,k...->i...", _LEVI_CIVITA, a, b)


def transform_point(s: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The global position of body point ``point`` (3,) for pose σ."""
    return qa.to_matrix(np.asarray(s)[..., :4]) @ np.asarray(point, dtype=float) + translation(s)


def exp(twist: np.ndarray) -> np.ndarray:
    """exp(ξ̂/2) for twists ``twist`` (..., 6) = (ω, v) (components last): a unit dual quaternion."""
    twist = np.asarray(twist, dtype=float)
    a, b = 0.5 * twist[..., :3], 0.5 * twist[..., 3:]
    h = np.linalg.norm(a, axis=-1)
    cos, sinc, bend = _coefficients(h)
    ab = np.sum(a * b, axis=-1)
    real = np.concatenate([cos[..., None], sinc[..., None] * a], axis=-1)
    dual = np.concatenate([(-sinc * ab)[..., None], sinc[..., None] * b + (bend * ab)[..., None] * a], axis=-1)
    return np.concatenate([real, dual], axis=-1)


def log(s: np.ndarray) -> np.ndarray:
    """The twist ξ (..., 6) with exp(ξ) = σ (rotation angle in [0, π], σ taken with q_r.w ≥ 0)."""
    s = np.asarray(s, dtype=float)
    s = np.where((s[..., :1] < 0), -s, s)
    real, dual = s[..., :4], s[..., 4:]
    vector = real[..., 1:]
    sin_h = np.linalg.norm(vector, axis=-1)
    h = np.arctan2(sin_h, real[..., 0])
    _, sinc, bend = _coefficients(h)
    a = vector / sinc[..., None]
    ab = -dual[..., 0] / sinc
    b = (dual[..., 1:] - (bend * ab)[..., None] * a) / sinc[..., None]
    return np.concatenate([2.0 * a, 2.0 * b], axis=-1)


def project(s: np.ndarray) -> np.ndarray:
    """The nearest unit dual quaternion in the sense kinegen needs after interpolation:
    q_r normalized, q_d scaled alike and made orthogonal to it (components last)."""
    s = np.asarray(s, dtype=float)
    norm = np.linalg.norm(s[..., :4], axis=-1, keepdims=True)
    real, dual = s[..., :4] / norm, s[..., 4:] / norm
    dual = dual - np.sum(real * dual, axis=-1, keepdims=True) * real
    return np.concatenate([real, dual], axis=-1)


def to_homogeneous(s: np.ndarray) -> np.ndarray:
    """The 4x4 homogeneous matrix [[A, r], [0, 1]] of σ (..., 8)."""
    s = np.asarray(s, dtype=float)
    out = np.zeros(s.shape[:-1] + (4, 4))
    out[..., :3, :3] = qa.to_matrix(s[..., :4])
    out[..., :3, 3] = translation(s)
    out[..., 3, 3] = 1.0
    return out


# ---- symbolic ----------------------------------------------------------------------------
def symbolic_translation(s: sp.Matrix) -> sp.Matrix:
    """The frame origin 2 vec(q_d ⊗ q_r*) of symbolic σ = (q_r, q_d) (8x1)."""
    return 2 * qa.symbolic_product(s[4:8, :], qa.symbolic_conjugate(s[0:4, :]))[1:, :]


def symbolic_increment(angular: sp.Matrix, linear: sp.Matrix, s: sp.Matrix) -> list[sp.Expr]:
    """``exp(ξ) ⊗ σ`` of a symbolic twist's angular and linear parts (3x1 each) and pose σ (8x1),
    as :func:`increment_parts` computes it: with h the half-angle, cos h, sin(h)/h and
    (cos h − sin h / h)/h² by their Taylor polynomials where h² <= :data:`SERIES_BELOW` (the branch
    taken alone is evaluated in the generated C)."""
    a, b = angular / 2, linear / 2
    h2 = sum((x * x for x in a), sp.Integer(0))
    h = sp.sqrt(h2)
    ab = sum((x * y for x, y in zip(a, b)), sp.Integer(0))
    small = h2 <= sp.Float(SERIES_BELOW)
    cos = sp.Piecewise((qa.horner(h2, COS_SERIES), small), (sp.cos(h), True))
    sinc = sp.Piecewise((qa.horner(h2, SINC_SERIES), small), (sp.sin(h) / h, True))
    bend = sp.Piecewise((qa.horner(h2, BEND_SERIES), small), ((cos - sinc) / h2, True))  # (cos h, sin h alone in their branches)
    real = sp.Matrix([cos, *(sinc * x for x in a)])
    dual = sp.Matrix([-sinc * ab, *(sinc * y + bend * ab * x for x, y in zip(a, b))])
    r, d = s[0:4, :], s[4:8, :]
    return [*qa.symbolic_product(real, r), *(qa.symbolic_product(real, d) + qa.symbolic_product(dual, r))]


def increment(twist: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``exp(ξ) ⊗ σ`` with the components on the FIRST axis: ``twist`` (6, ...), ``s`` (8, ...)
    -> (8, ...). The same as ``multiply(exp(ξ), σ)`` in few NumPy calls (the retraction of every
    Newton step, where NumPy's per-call cost outweighs the arithmetic): the product through the
    dual Hamilton product's structure tensor, one matrix product. The generated C's ``retract_body``
    writes it out."""
    twist = np.asarray(twist, dtype=float)
    return increment_parts(twist[:3], twist[3:], s)


def increment_parts(angular: np.ndarray, linear: np.ndarray, s: np.ndarray) -> np.ndarray:
    """:func:`increment` with the twist's angular (3, ...) and linear (3, ...) parts apart."""
    a, b = 0.5 * angular, 0.5 * linear
    h2 = np.einsum("i...,i...->...", a, a)
    ab = np.einsum("i...,i...->...", a, b)
    cos, sinc, bend = _coefficients(np.sqrt(h2), h2)
    p = np.empty((8, *h2.shape))
    p[0], p[1:4] = cos, sinc * a
    p[4], p[5:8] = -sinc * ab, sinc * b + (bend * ab) * a
    outer = p[:, None] * s[None, :]  # (8, 8, ...): every product p_j s_k, then one matrix product
    return (_DUAL_HAMILTON.reshape(8, 64) @ outer.reshape(64, -1)).reshape(8, *outer.shape[2:])


#: (p ⊗ q)_i = sum_jk _HAMILTON[i, j, k] p_j q_k for quaternions, and for dual quaternions (8 values)
_HAMILTON = np.stack([np.stack([qa.multiply(np.eye(4)[j], np.eye(4)[k]) for k in range(4)], axis=-1) for j in range(4)], axis=1)
_DUAL_HAMILTON = np.zeros((8, 8, 8))
_DUAL_HAMILTON[:4, :4, :4] = _HAMILTON
_DUAL_HAMILTON[4:, :4, 4:] = _HAMILTON
_DUAL_HAMILTON[4:, 4:, :4] = _HAMILTON
#: 2 vec(q_d ⊗ q_r*)_i = sum_jk _TRANSLATION[i, j, k] q_d_j q_r_k
_TRANSLATION = 2.0 * _HAMILTON[1:] * np.array([1.0, -1.0, -1.0, -1.0])
#: (a × b)_i = sum_jk _LEVI_CIVITA[i, j, k] a_j b_k
_LEVI_CIVITA = np.stack([np.cross(np.eye(3)[j], np.eye(3)[k]) for j in range(3) for k in range(3)], axis=-1).reshape(3, 3, 3)
