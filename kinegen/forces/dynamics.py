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

from kinegen.errors import KinegenError
from kinegen.model import Model
from kinegen.model.schema import design_value
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


def energies(results: Results, model: Model) -> Energies:
    """Kinetic and potential energy of the model's massive bodies along ``results`` (numeric, from
    the solved frames: independent of the generated inertia kernel)."""
    design = results.system.design
    gravity = np.array([design_value(x, design) for x in model.gravity], dtype=float)
    kinetic = np.zeros(len(results.times))
    potential = np.zeros(len(results.times))
    for body in model.massive:
        inertia = body.inertia
        mass = design_value(inertia.mass, design)
        center = np.array([design_value(x, design) for x in inertia.center], dtype=float)
        tensor = np.array([[design_value(x, design) for x in row] for row in inertia.tensor.tolist()], dtype=float)
        rotation = results.rotation_matrix(body.name)
        arm = rotation @ center
        omega = results.omega(body.name)
        velocity = results.velocity(body.name) + np.cross(omega, arm)
        spin = np.einsum("kij,jl,kml,km->ki", rotation, tensor, rotation, omega)  # (R J Rᵀ) ω
        kinetic += 0.5 * mass * np.einsum("ki,ki->k", velocity, velocity) + 0.5 * np.einsum("ki,ki->k", omega, spin)
        potential -= mass * (results.position(body.name) + arm) @ gravity
    return Energies(kinetic, potential)
