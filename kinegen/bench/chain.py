"""The chain-N benchmark mechanism (``docs/chain-N.md``) in kinegen's model format.

N unit links in series, every joint axis parallel to global z. Link i has its frame at
joint i and its tip at (1, 0, 0); the relative joint angle is driven by
theta_i(t) = 0.3 + 0.5 sin(t + 0.1 i). The initial pose is assembled but off the
solution: relative angles theta_i(0) + 0.05 (-1)^i. The tip of link N is at
sum_k (cos S_k, sin S_k, 0) with S_k = theta_1 + ... + theta_k.

Each joint lists the child link first (``bodies: [link_i, link_{i-1}]``) and drives the
parent's angle relative to the child, -theta_i. kinegen's revolute rows (``h1·f2``,
``h1·g2``) then are the benchmark's ``x_a·z_b``, ``y_a·z_b``; its point rows are the
benchmark's negated, and its half-angle joint-angle driver (Euler parameters, quaternion)
is the benchmark's driver times -2. Row signs, scale and order do not change Newton's
iterates: kinegen solves the benchmark's equations.
"""

from __future__ import annotations

import numpy as np


def joint_angle(i: int, t: np.ndarray | float) -> np.ndarray | float:
    """theta_i(t) of joint i (1-based)."""
    return 0.3 + 0.5 * np.sin(t + 0.1 * i)


def chain_yaml(n: int, t1: float = 10.0, steps: int = 1000) -> str:
    """The chain-N model as YAML text (case ``drive`` on linspace(0, t1, steps))."""
    lines = [
        f"model: chain{n}",
        "ground:",
        "  points: {O: [0, 0, 0]}",
        "  vectors: {z: [0, 0, 1]}",
        "bodies:",
    ]
    absolute, x, y = 0.0, 0.0, 0.0
    for i in range(1, n + 1):
        absolute += float(joint_angle(i, 0.0)) + 0.05 * (-1) ** i
        lines += [
            f"  link{i}:",
            f"    position: [{x!r}, {y!r}, 0]",
            f"    orientation: {{axis: [0, 0, 1], angle: {absolute!r}}}",
            "    points: {O: [0, 0, 0], tip: [1, 0, 0]}",
            "    vectors: {z: [0, 0, 1]}",
        ]
        x, y = x + float(np.cos(absolute)), y + float(np.sin(absolute))
    lines.append("joints:")
    for i in range(1, n + 1):
        parent, point = ("ground", "O") if i == 1 else (f"link{i - 1}", "tip")
        lines.append(f"  J{i}: {{type: revolute, bodies: [link{i}, {parent}], points: [O, {point}], axes: [z, z]}}")
    lines += ["cases:", "  drive:", "    drivers:"]
    for i in range(1, n + 1):
        lines.append(f"      theta{i}: {{type: joint_angle, joint: J{i}, function: -(0.3 + 0.5*sin(t + {i}/10))}}")
    lines += ["    t0: 0", f"    t1: {t1!r}", f"    steps: {steps}"]
    return "\n".join(lines) + "\n"


def tip_reference(n: int, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Analytic tip position, velocity and acceleration of link N, each (K, 3)."""
    position, velocity, acceleration = (np.zeros((len(times), 3)) for _ in range(3))
    s = sd = sdd = 0.0
    for k in range(1, n + 1):
        s = s + joint_angle(k, times)
        sd = sd + 0.5 * np.cos(times + 0.1 * k)
        sdd = sdd - 0.5 * np.sin(times + 0.1 * k)
        c, si = np.cos(s), np.sin(s)
        position[:, :2] += np.c_[c, si]
        velocity[:, :2] += sd[:, None] * np.c_[-si, c]
        acceleration[:, :2] += sdd[:, None] * np.c_[-si, c] - (sd**2)[:, None] * np.c_[c, si]
    return position, velocity, acceleration
