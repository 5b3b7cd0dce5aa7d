"""Masses along a motion: the generalized force of gravity and of the bodies' inertia, and the
mechanism's kinetic and potential energy.

With masses, the forces that move the mechanism along a solved motion (inverse dynamics) solve
**Φ_qᵀ λ = Q_loads + Q_inertia** (:func:`kinegen.forces.forces` with ``inertia=True``), where
Q_inertia is the generated ``inertia`` kernel: per body with mass m, centre of mass C and inertia J
about C, the weight and d'Alembert's forces m (g − a_C) at C and −(J ω̇ + ω × J ω) on the body,
taken to the parametrization's velocity coordinates (:func:`kinegen.symbolic.statics.inertia_row`).

Energies (J): kinetic T = Σ ½ m |v_C|² + ½ ω·J ω, potential V = −Σ m g·r_C (zero at the global
origin's height for g along −z). SI units; global axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from kinegen.errors import KinegenError
from kinegen.model import Model
from kinegen.model.expressions import T
from kinegen.model.schema import GROUND, design_value
from kinegen.runtime.results import Results


@dataclass(frozen=True)
class Energies:
    """The mechanism's energies at each time point of a motion [J]."""

    kinetic: np.ndarray  #: (K,)
    potential: np.ndarray  #: (K,)

    @property
    def total(self) -> np.ndarray:
        return self.kinetic + self.potential


def inertial_load(results: Results) -> np.ndarray:
    """Q_inertia (K, n_v) along ``results``: gravity and the bodies' inertia, from the module's
    generated ``inertia`` kernel."""
    system = results.system
    kernels = system.statics
    if kernels is None or kernels.inertia is None:
        raise KinegenError(f"the model {system.model!r} has no masses (a body's mass:, center_of_mass:, inertia:): "
                           "no inertial forces to add")  # fmt: skip
    values = kernels.inertia(*(np.ascontiguousarray(x.T) for x in (results.q, results.v, results.a)))
    out = np.zeros((len(results.times), system.n_velocity))
    out[:, kernels.inertia_cols] = np.asarray(values, dtype=float).reshape(len(kernels.inertia_cols), -1).T
    return out


def inertia_numbers(inertia, design: dict[str, float]) -> tuple[float, np.ndarray, np.ndarray]:
    """A body's :class:`~kinegen.model.schema.Inertia` at the design values: mass [kg], centre of mass
    (3,) [m, body coordinates], inertia tensor about it (3, 3) [kg m^2, body axes]."""
    center = np.array([design_value(x, design) for x in inertia.center], dtype=float)
    tensor = np.array([[design_value(x, design) for x in row] for row in inertia.tensor.tolist()], dtype=float)
    return design_value(inertia.mass, design), center, tensor


def load_wrench(results: Results, load) -> tuple[np.ndarray, np.ndarray]:
    """A :class:`~kinegen.model.schema.Load`'s force and moment (each (K, 3), global) along
    ``results``: its exact functions of t at the times, turned from the body's axes if it is given in them."""
    count = len(results.times)
    rotation = np.broadcast_to(np.eye(3), (count, 3, 3)) if load.axes == GROUND else results.rotation_matrix(load.axes)
    return (np.einsum("kij,kj->ki", rotation, time_vector(load.force, results.times)),
            np.einsum("kij,kj->ki", rotation, time_vector(load.moment, results.times)))  # fmt: skip


def energies(results: Results, model: Model) -> Energies:
    """Kinetic and potential energy of the model's massive bodies along ``results`` (numeric, from
    the solved frames: independent of the generated inertia kernel)."""
    design = results.system.design
    gravity = np.array([design_value(x, design) for x in model.gravity], dtype=float)
    kinetic = np.zeros(len(results.times))
    potential = np.zeros(len(results.times))
    for body in model.massive:
        mass, center, tensor = inertia_numbers(body.inertia, design)
        rotation = results.rotation_matrix(body.name)
        arm = rotation @ center
        omega = results.omega(body.name)
        velocity = results.velocity(body.name) + np.cross(omega, arm)
        spin = np.einsum("kij,jl,kml,km->ki", rotation, tensor, rotation, omega)  # (R J Rᵀ) ω
        kinetic += 0.5 * mass * np.einsum("ki,ki->k", velocity, velocity) + 0.5 * np.einsum("ki,ki->k", omega, spin)
        potential -= mass * (results.position(body.name) + arm) @ gravity
    return Energies(kinetic, potential)


#: the tipping lines of a crawler undercarriage, by name: (outward normal, which half-size: 0 the
#: tumbler distance, 1 the gauge), the lines at that half-size from the swing axis (global, fixed)
TIPPING_LINES = {
    "front": (np.array([1.0, 0.0, 0.0]), 0),
    "rear": (np.array([-1.0, 0.0, 0.0]), 0),
    "left": (np.array([0.0, 1.0, 0.0]), 1),
    "right": (np.array([0.0, -1.0, 0.0]), 1),
}


@dataclass(frozen=True)
class TippingMargin:
    """The stability along a motion: per time point the moment [N m] that keeps the machine on the
    ground about its nearest tipping line (positive: stable; the smallest of the four lines) and
    that line's name."""

    margin: np.ndarray  #: (K,)
    line: np.ndarray  #: (K,) of str: front, rear, left or right
    margins: dict[str, np.ndarray]  #: every line's (K,)


def tipping_margin(results: Results, model: Model, loads: tuple[str, ...] = (), inertia: bool = True) -> TippingMargin:
    """The tipping margin along ``results`` (a model with masses and a ``machine:`` section): about
    each of the undercarriage's tipping lines (over the front and rear at half the tumbler distance,
    over the sides at half the gauge; on the ground, z = 0), minus the moment of every force on the
    machine tending to turn it over that line -- the weights (the undercarriage's too), the named
    ``loads`` and, with ``inertia``, the bodies' d'Alembert forces."""
    machine = model.machine
    if machine is None or not model.massive:
        raise KinegenError(f"the model {model.name!r} needs masses and a machine: section (undercarriage, tracks) for its tipping margin")
    design = results.system.design

    def number(x) -> float:
        return design_value(x, design)

    gravity = np.array([number(x) for x in model.gravity])
    k = len(results.times)
    forces_at: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (point (K, 3), force (K, 3), moment (K, 3))
    under = np.array([number(x) for x in machine.undercarriage_center])
    forces_at.append((np.broadcast_to(under, (k, 3)), np.broadcast_to(number(machine.undercarriage_mass) * gravity, (k, 3)), np.zeros((k, 3))))
    for body in model.massive:
        mass, local, body_tensor = inertia_numbers(body.inertia, design)
        rotation = results.rotation_matrix(body.name)
        arm = rotation @ local
        center = results.position(body.name) + arm
        force, moment = np.broadcast_to(mass * gravity, (k, 3)).copy(), np.zeros((k, 3))
        if inertia:
            omega, omega_dot = results.omega(body.name), results.omega_dot(body.name)
            acceleration = results.acceleration(body.name) + np.cross(omega_dot, arm) + np.cross(omega, np.cross(omega, arm))
            tensor = rotation @ body_tensor @ rotation.swapaxes(1, 2)
            force -= mass * acceleration
            moment = -(np.einsum("kij,kj->ki", tensor, omega_dot) + np.cross(omega, np.einsum("kij,kj->ki", tensor, omega)))
        forces_at.append((center, force, moment))
    for name in loads:
        load = model.loads[name]
        forces_at.append((results.point_position(load.point.body, load.point.name), *load_wrench(results, load)))
    halves = (number(machine.track_length) / 2, number(machine.gauge) / 2)
    margins = {}
    for name, (normal, which) in TIPPING_LINES.items():
        on_line = halves[which] * normal  # a point of the line, on the ground
        along = np.cross([0.0, 0.0, 1.0], normal)  # a force beyond the line pushing down turns the machine about +along
        turning = sum(np.einsum("i,ki->k", along, np.cross(point - on_line, force) + moment) for point, force, moment in forces_at)
        margins[name] = -turning
    stacked = np.stack(list(margins.values()))
    nearest = np.argmin(stacked, axis=0)
    return TippingMargin(stacked[nearest, np.arange(k)], np.array(list(margins))[nearest], margins)


def time_vector(vector: sp.ImmutableMatrix, times: np.ndarray) -> np.ndarray:
    """A 3-vector of exact functions of t (a load's force or moment) at ``times``, (K, 3)."""
    out = np.empty((len(times), 3))
    for i, expr in enumerate(vector):
        if expr.free_symbols:
            out[:, i] = np.broadcast_to(sp.lambdify(T, expr, "numpy")(times), times.shape)
        else:
            out[:, i] = float(expr)
    return out
