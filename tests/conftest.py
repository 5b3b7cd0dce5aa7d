"""Shared helpers: paths, model loading, and the chain-of-revolute-links model factory."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from kinegen import rotations
from kinegen.codegen.inmemory import lambdify_model
from kinegen.model import load, loads
from kinegen.runtime import from_module, load_module

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
GENERATED = ROOT / "generated"


@functools.cache
def generated_system(stem: str, case: str | None = None):
    """The numeric system of a committed generated module (e.g. ``boom_quaternion``)."""
    return from_module(load_module(GENERATED / f"{stem}.py"), case)


@functools.cache
def model(name: str):
    return load(MODELS / f"{name}.yaml")


def chain_angles(i: int, t):
    """Relative joint angle of joint i (1-based), as in the chain-N benchmark."""
    return 0.3 + 0.5 * np.sin(t + 0.1 * i)


def chain_yaml(n: int) -> str:
    """N unit links in series, all joint axes parallel to global z, assembled off the solution.

    Link i has its frame origin at joint i and its tip at (1, 0, 0); the initial relative
    angles are theta_i(0) + 0.05 (-1)^i, as in the chain-N benchmark (not the solution).
    """
    lines = [
        f"model: chain{n}",
        "ground:",
        "  points: {O: [0, 0, 0]}",
        "  vectors: {z: [0, 0, 1]}",
        "bodies:",
    ]
    absolute, x, y = 0.0, 0.0, 0.0
    for i in range(1, n + 1):
        absolute += float(chain_angles(i, 0.0)) + 0.05 * (-1) ** i
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
        parent = "ground" if i == 1 else f"link{i - 1}"
        point = "O" if i == 1 else "tip"
        lines.append(f"  J{i}: {{type: revolute, bodies: [{parent}, link{i}], points: [{point}, O], axes: [z, z]}}")
    lines += ["cases:", "  drive:", "    drivers:"]
    for i in range(1, n + 1):
        lines.append(f"      theta{i}: {{type: joint_angle, joint: J{i}, function: 0.3 + 0.5*sin(t + {0.1 * i!r})}}")
    lines += ["    t0: 0", "    t1: 2", "    steps: 41"]
    return "\n".join(lines) + "\n"


@functools.cache
def chain_system(n: int, parametrization: str):
    """In-memory (lambdify) system of the N-link chain."""
    return from_module(lambdify_model(loads(chain_yaml(n), f"chain{n}.yaml"), rotations.get(parametrization)))


@pytest.fixture
def boom_text() -> str:
    return (MODELS / "boom.yaml").read_text()
