"""Closed-form planar kinematics of the ZX200 front (independent of kinegen).

Pin positions from the swing angle and the three cylinder lengths by the law of cosines
in each closed loop, with the assembly-branch signs of ``zx200_geometry.json``. No
Newton, no kinegen code: this is the reference the tests compare kinegen against.
"""

from __future__ import annotations

import numpy as np

# pins in their body frames (x forward, z up), from the PWRI ZX200 geometry (docs/excavator-geometry.md)
A, B = np.array([0.22767, 1.95729]), np.array([0.68912, 1.35478])  # upper structure
BOOM = {"C": np.array([1.39283, 2.001922]), "D": np.array([2.2875, 2.785]), "E": np.array([4.7878, 2.9959])}
ARM = {
    "F": np.array([-0.786562, -0.369691]),
    "G": np.array([-0.24687, 0.73594]),
    "H": np.array([1.5754, 1.8799]),
    "Q": np.array([1.8954, 2.1809]),
}
SIDE_J = np.array([-0.332658, 0.481235])  # side link, frame at H
LINK_J = np.array([-0.342428, -0.450737])  # bucket link, frame at K
BUCKET = {"K": np.array([-0.32404, 0.33854]), "T": np.array([1.28, 0.806])}
SIGN = {"boom": 1, "arm": -1, "side_link": -1, "bucket_link": -1}
BOOM_CYLINDER_OFFSET = 0.32  # lateral offset of each boom cylinder from the boom plane [m]


def rot(angle: float) -> np.ndarray:
    """In-plane rotation (x toward z, counter-clockwise)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def heading(v: np.ndarray) -> float:
    return float(np.arctan2(v[1], v[0]))


def triangle_angle(adjacent1: float, adjacent2: float, opposite: float) -> float:
    """Angle between the two adjacent sides, law of cosines."""
    cosine = (adjacent1**2 + adjacent2**2 - opposite**2) / (2 * adjacent1 * adjacent2)
    if abs(cosine) > 1:
        raise ValueError("loop cannot close")
    return float(np.arccos(cosine))


def close(pivot: np.ndarray, known: np.ndarray, arm_length: float, length: float, sign: int) -> np.ndarray:
    """The point at ``arm_length`` from ``pivot`` and ``length`` from ``known``."""
    angle = triangle_angle(np.linalg.norm(known - pivot), arm_length, length)
    return pivot + arm_length * (rot(sign * angle) @ ((known - pivot) / np.linalg.norm(known - pivot)))


def planar_pins(boom: float, arm: float, bucket: float) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """All pins (x, z) and absolute link angles for the three cylinder lengths."""
    pins = {"A": A, "B": B}
    pins["C"] = close(A, B, np.linalg.norm(BOOM["C"]), boom, SIGN["boom"])
    angles = {"boom": heading(pins["C"] - A) - heading(BOOM["C"])}
    for name in ("D", "E"):
        pins[name] = A + rot(angles["boom"]) @ BOOM[name]
    e = pins["E"]
    pins["F"] = close(e, pins["D"], np.linalg.norm(ARM["F"]), arm, SIGN["arm"])
    angles["arm"] = heading(pins["F"] - e) - heading(ARM["F"])
    for name in ("G", "H", "Q"):
        pins[name] = e + rot(angles["arm"]) @ ARM[name]
    pins["J"] = close(pins["H"], pins["G"], np.linalg.norm(SIDE_J), bucket, SIGN["side_link"])
    angles["side_link"] = heading(pins["J"] - pins["H"]) - heading(SIDE_J)
    pins["K"] = close(pins["Q"], pins["J"], np.linalg.norm(BUCKET["K"]), np.linalg.norm(LINK_J), SIGN["bucket_link"])
    angles["bucket"] = heading(pins["K"] - pins["Q"]) - heading(BUCKET["K"])
    angles["bucket_link"] = heading(pins["J"] - pins["K"]) - heading(LINK_J)
    pins["T"] = pins["Q"] + rot(angles["bucket"]) @ BUCKET["T"]
    return pins, angles


def spatial(point: np.ndarray, swing: float, lateral: float = 0.0) -> np.ndarray:
    """3-D position of a plane point (x, z) with lateral offset y0 after swinging by ``swing``."""
    x, z = point
    return np.array([x * np.cos(swing) - lateral * np.sin(swing), x * np.sin(swing) + lateral * np.cos(swing), z])
