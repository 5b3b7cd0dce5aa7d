"""Reading a model's masses (``mass:``, ``center_of_mass:``, ``inertia:`` of a body; ``gravity:``):
what the dynamics (:mod:`kinegen.forces.dynamics`) needs beside the kinematics.

Units SI: kg, m (body coordinates), kg m^2 (about the centre of mass, in body axes), m/s^2.
An inertia is given as its three principal values along the body axes ``[Ixx, Iyy, Izz]``, as six
values ``[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`` (the tensor's entries: Ixy = J[0][1], the negative of
the product of inertia ∫xy dm), or as ``{principal: [I1, I2, I3], axes: [[...], [...], [...]]}``
(unit principal axes in body coordinates, as rows). Design parameters may appear in all of them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import sympy as sp

from kinegen.model.schema import STANDARD_GRAVITY, Body, Inertia, Machine, Vector

#: a body's keys that carry its inertial data
KEYS = ("mass", "center_of_mass", "inertia")


def read_inertia(loader: Any, spec: dict, entry: str, pose: Body, points: dict[str, Vector]) -> Inertia | None:
    """The body's inertial data from its ``spec`` (None when it gives none: a massless body)."""
    given = [k for k in KEYS if k in spec]
    if not given:
        return None
    if "mass" not in spec:
        raise loader.fail(entry, f"{', '.join(given)} without 'mass': give the body's mass [kg]")
    mass = loader.positive(spec["mass"], f"{entry}.mass", "kg: a mass")
    loader.plausible(mass, f"{entry}.mass", "kg", (1e-3, 1e6), "a machine part's mass", "masses are in kg")
    center_spec = spec.get("center_of_mass", [0, 0, 0])
    if isinstance(center_spec, str):
        if center_spec not in points:
            raise loader.fail(f"{entry}.center_of_mass", f"unknown point {center_spec!r} on body {pose.name!r} (known: {', '.join(points) or 'none'})")
        center = points[center_spec]
    else:
        center = loader.vector(center_spec, f"{entry}.center_of_mass")
    tensor = _tensor(loader, spec.get("inertia", [0, 0, 0]), f"{entry}.inertia")
    return Inertia(mass, center, tensor)


def _tensor(loader: Any, value: Any, entry: str) -> sp.ImmutableMatrix:
    if isinstance(value, dict):
        spec = loader.mapping(value, entry, ("principal", "axes"), ("principal", "axes"))
        principal = loader.vector(spec["principal"], f"{entry}.principal")
        rows = spec["axes"]
        if not isinstance(rows, (list, tuple)) or len(rows) != 3:
            raise loader.fail(f"{entry}.axes", "expected three unit vectors (the principal axes, body coordinates)")
        axes = sp.Matrix([list(loader.unit(r, f"{entry}.axes[{i}]")) for i, r in enumerate(rows)])
        numeric = np.array(axes.xreplace(loader.nominal).evalf(), dtype=float)
        if np.abs(numeric @ numeric.T - np.eye(3)).max() > 1e-9:
            raise loader.fail(f"{entry}.axes", "the principal axes are not mutually perpendicular")
        tensor = sp.ImmutableMatrix(axes.T * sp.diag(*principal) * axes)
    elif isinstance(value, (list, tuple)) and len(value) in (3, 6):
        v = [loader.scalar(x, f"{entry}[{i}]", design=True) for i, x in enumerate(value)]
        xy, xz, yz = (v[3], v[4], v[5]) if len(v) == 6 else (0, 0, 0)
        tensor = sp.ImmutableMatrix([[v[0], xy, xz], [xy, v[1], yz], [xz, yz, v[2]]])
    else:
        raise loader.fail(entry, "expected [Ixx, Iyy, Izz], [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] or {principal: [...], axes: [...]} (kg m^2)")
    moments = np.linalg.eigvalsh(np.array(tensor.xreplace(loader.nominal).evalf(), dtype=float))
    scale = max(abs(moments).max(), 1e-300)
    if moments.min() < -1e-12 * scale or moments[0] + moments[1] < moments[2] * (1 - 1e-12):
        raise loader.fail(entry, f"principal moments {', '.join(f'{m:.6g}' for m in moments)} kg m^2 are not those of a body "
                                 "(each at least 0 and none larger than the other two together)")  # fmt: skip
    return tensor


def read_gravity(loader: Any, value: Any) -> Vector:
    """``gravity: [gx, gy, gz]`` (m/s^2, global; default [0, 0, -9.80665])."""
    return STANDARD_GRAVITY if value is None else loader.vector(value, "gravity")


def read_machine(loader: Any, value: Any) -> Machine | None:
    """``machine: {undercarriage: {mass, center_of_mass}, tracks: {length, gauge, shoe_width}}``: the
    undercarriage (kg; m, global) and its tracks (m: tumbler distance, gauge, shoe width)."""
    if value is None:
        return None
    spec = loader.mapping(value, "machine", ("undercarriage", "tracks"), ("undercarriage", "tracks"))
    under = loader.mapping(spec["undercarriage"], "machine.undercarriage", ("mass", "center_of_mass"), ("mass", "center_of_mass"))
    mass = loader.positive(under["mass"], "machine.undercarriage.mass", "kg: a mass")
    loader.plausible(mass, "machine.undercarriage.mass", "kg", (1.0, 1e6), "an undercarriage's mass", "masses are in kg")
    center = loader.vector(under["center_of_mass"], "machine.undercarriage.center_of_mass")
    tracks = loader.mapping(spec["tracks"], "machine.tracks", ("length", "gauge", "shoe_width"), ("length", "gauge", "shoe_width"))
    sizes = {key: loader.positive(tracks[key], f"machine.tracks.{key}", "m: a length") for key in ("length", "gauge", "shoe_width")}
    if not loader.value(sizes["shoe_width"]) < loader.value(sizes["gauge"]):
        raise loader.fail("machine.tracks.shoe_width", "the shoes are wider than the gauge: the tracks would overlap")
    return Machine(mass, center, sizes["length"], sizes["gauge"], sizes["shoe_width"])
