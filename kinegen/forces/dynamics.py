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

import functools
from dataclasses import dataclass

import numpy as np
import sympy as sp

from kinegen.errors import KinegenError
from kinegen.model import Model
from kinegen.model.expressions import T
from kinegen.model.schema import GROUND, design_value
from kinegen.runtime import kinematics
from kinegen.runtime.results import Results
from kinegen.runtime.sensitivity import frame_sensitivities, point_sensitivity


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
    rotation = np.broadcast_to(np.eye(3), (count, 3, 3)) if load.axes == GROUND else kinematics.rotation_matrix(results, load.axes)
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
        rotation = kinematics.rotation_matrix(results, body.name)
        arm = rotation @ center
        omega = kinematics.omega(results, body.name)
        velocity = kinematics.velocity(results, body.name) + np.cross(omega, arm)
        spin = np.einsum("kij,jl,kml,km->ki", rotation, tensor, rotation, omega)  # (R J Rᵀ) ω
        kinetic += 0.5 * mass * np.einsum("ki,ki->k", velocity, velocity) + 0.5 * np.einsum("ki,ki->k", omega, spin)
        potential -= mass * (kinematics.position(results, body.name) + arm) @ gravity
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
    that line's name; with ``changes``, every line's margin's derivative by the design parameters."""

    margin: np.ndarray  #: (K,)
    line: np.ndarray  #: (K,) of str: front, rear, left or right
    margins: dict[str, np.ndarray]  #: every line's (K,)
    changes: dict[str, np.ndarray] | None = None  #: every line's d margin / d p, (K, n_design) [N m per unit]


def tipping_margin(results: Results, model: Model, loads: tuple[str, ...] = (), inertia: bool = True, changes: bool = False) -> TippingMargin:
    """The tipping margin along ``results`` (a model with masses and a ``machine:`` section): about
    each of the undercarriage's tipping lines (over the front and rear at half the tumbler distance,
    over the sides at half the gauge; on the ground, z = 0), minus the moment of every force on the
    machine tending to turn it over that line -- the weights (the undercarriage's too), the named
    ``loads`` and, with ``inertia``, the bodies' d'Alembert forces.

    With ``changes``, also each line's margin's exact derivative by the design parameters (the
    module's sensitivity kernels): the frames' changes along (dq/dp, dv/dp, da/dp)
    (:func:`kinegen.runtime.sensitivity.frame_sensitivities`) and the design's own in the masses,
    centres, inertias, loads' points and the undercarriage, by the product rule on the sums below."""
    machine = model.machine
    if not model.tips:
        raise KinegenError(f"the model {model.name!r} needs masses and a machine: section (undercarriage, tracks) for its tipping margin")
    wrenches = MachineWrenches(results, model, changes)
    wrenches.add_undercarriage(machine)
    for body in model.massive:
        wrenches.add_body(body, inertia)
    for name in loads:
        wrenches.add_load(model.loads[name])
    number, gradient = wrenches.number, wrenches.gradient
    margins, d_margins = {}, {}
    for name, (normal, which) in TIPPING_LINES.items():
        size = (machine.track_length, machine.gauge)[which]
        on_line, d_on_line = number(size) / 2 * normal, np.outer(normal, gradient(size) / 2)  # a point of the line, on the ground
        along = np.cross([0.0, 0.0, 1.0], normal)  # a force beyond the line pushing down turns the machine about +along
        margins[name] = -sum(along @ (np.cross(point - on_line, force) + moment).T for point, force, moment, *_ in wrenches.items)
        if changes:
            d_turning = 0.0
            for point, force, _, d_point, d_force, d_moment in wrenches.items:
                arm_change = d_point - d_on_line[None]
                d_turning = d_turning + np.einsum("i,kip->kp", along, np.cross(arm_change, force[:, :, None], axis=1)
                                                  + np.cross((point - on_line)[:, :, None], d_force, axis=1) + d_moment)  # fmt: skip
            d_margins[name] = -d_turning
    stacked = np.stack(list(margins.values()))
    nearest = np.argmin(stacked, axis=0)
    count = np.arange(stacked.shape[1])
    return TippingMargin(stacked[nearest, count], np.array(list(margins))[nearest], margins, d_margins if changes else None)


class MachineWrenches:
    """The forces on the machine for its tipping margin, each (point (K, 3), force (K, 3), moment
    (K, 3)) in global axes, with their design changes ((K, 3, P) each; zeros unless ``changes``)."""

    def __init__(self, results: Results, model: Model, changes: bool) -> None:
        from kinegen.model.schema import design_gradient

        self.results, self.model, self.changes = results, model, changes
        design = results.system.design
        self.order = list(design)
        self.count, self.n_design = len(results.times), len(self.order)
        self.number = lambda x: design_value(x, design)
        self.gradient = lambda x: np.asarray(design_gradient(x, self.order, design), dtype=float).reshape(self.n_design)
        self.gravity = np.array([self.number(x) for x in model.gravity])
        self.d_gravity = np.array([self.gradient(x) for x in model.gravity])  # (3, P)
        self.frames = frame_sensitivities(results) if changes else None
        self.items: list[tuple[np.ndarray, ...]] = []

    def _zeros(self) -> np.ndarray:
        return np.zeros((self.count, 3, self.n_design))

    def _frame(self, body: str, field: str) -> np.ndarray:
        """A frame value's change (K, 3, P) or the rotation's (K, 3, 3, P)."""
        system = self.results.system
        values = self.frames[:, list(system.bodies).index(body), system.frame_slices[field]]
        return values.reshape(self.count, 3, 3, -1) if field == "rotation" else values

    def add_undercarriage(self, machine) -> None:
        mass = self.number(machine.undercarriage_mass)
        center = np.array([self.number(x) for x in machine.undercarriage_center])
        d_center = np.array([self.gradient(x) for x in machine.undercarriage_center])
        d_force = np.outer(self.gravity, self.gradient(machine.undercarriage_mass)) + mass * self.d_gravity
        k = self.count
        self.items.append((np.broadcast_to(center, (k, 3)), np.broadcast_to(mass * self.gravity, (k, 3)), np.zeros((k, 3)),
                           np.broadcast_to(d_center, (k, 3, self.n_design)), np.broadcast_to(d_force, (k, 3, self.n_design)), self._zeros()))  # fmt: skip

    def add_body(self, body, inertia: bool) -> None:
        """The body's weight (and with ``inertia`` its d'Alembert forces) at its centre of mass, with
        their changes; computed once per results (a cycle's limits ask it twice: the inertia's
        changes and the tipping margin's)."""
        cache = self.results.__dict__.setdefault("_wrench_cache", {})
        key = (body.name, body.inertia, inertia, self.changes)
        if key not in cache:
            self._add_body(body, inertia)
            cache[key] = self.items[-1]
        else:
            self.items.append(cache[key])

    def _add_body(self, body, inertia: bool) -> None:
        results, name = self.results, body.name
        mass, local, body_tensor = inertia_numbers(body.inertia, results.system.design)
        rotation = kinematics.rotation_matrix(results, name)
        arm = rotation @ local
        center = kinematics.position(results, name) + arm
        force, moment = np.broadcast_to(mass * self.gravity, (self.count, 3)).copy(), np.zeros((self.count, 3))
        if inertia:  # d'Alembert: -m a_C at the centre, -(J w' + w x J w) on the body
            omega, omega_dot = kinematics.omega(results, name), kinematics.omega_dot(results, name)
            acceleration = kinematics.acceleration(results, name) + np.cross(omega_dot, arm) + np.cross(omega, np.cross(omega, arm))
            tensor = rotation @ body_tensor @ rotation.swapaxes(1, 2)
            force -= mass * acceleration
            moment = -(np.einsum("kij,kj->ki", tensor, omega_dot) + np.cross(omega, np.einsum("kij,kj->ki", tensor, omega)))
        if not self.changes:
            self.items.append((center, force, moment, None, None, None))
            return
        d_mass = self.gradient(body.inertia.mass)
        d_local = np.array([self.gradient(x) for x in body.inertia.center])  # (3, P)
        d_body_tensor = np.array([[self.gradient(x) for x in row] for row in body.inertia.tensor.tolist()])  # (3, 3, P)
        d_rotation = self._frame(name, "rotation")
        d_arm = np.einsum("kijp,j->kip", d_rotation, local) + np.einsum("kij,jp->kip", rotation, d_local)
        d_center = self._frame(name, "origin") + d_arm
        d_force = np.outer(self.gravity, d_mass)[None] + mass * self.d_gravity[None]
        d_moment = self._zeros()
        if inertia:
            cross = functools.partial(np.cross, axis=1)
            d_omega, d_omega_dot = self._frame(name, "angular_velocity"), self._frame(name, "angular_acceleration")
            w, w_dot, r = omega[:, :, None], omega_dot[:, :, None], arm[:, :, None]
            d_acceleration = (self._frame(name, "acceleration") + cross(d_omega_dot, r) + cross(w_dot, d_arm)
                              + cross(d_omega, cross(w, r)) + cross(w, cross(d_omega, r) + cross(w, d_arm)))  # fmt: skip
            d_force = d_force - acceleration[:, :, None] * d_mass[None, None] - mass * d_acceleration
            # (three factors: einsum contracts them pairwise only when asked, ~3x faster here)
            d_tensor = (np.einsum("kijp,jl,kml->kimp", d_rotation, body_tensor, rotation, optimize=True)
                        + np.einsum("kij,jlp,kml->kimp", rotation, d_body_tensor, rotation, optimize=True)
                        + np.einsum("kij,jl,kmlp->kimp", rotation, body_tensor, d_rotation, optimize=True))  # fmt: skip
            spin = np.einsum("kij,kj->ki", tensor, omega)[:, :, None]
            d_spin = np.einsum("kijp,kj->kip", d_tensor, omega) + np.einsum("kij,kjp->kip", tensor, d_omega)
            d_moment = -(np.einsum("kijp,kj->kip", d_tensor, omega_dot) + np.einsum("kij,kjp->kip", tensor, d_omega_dot)
                         + cross(d_omega, spin) + cross(w, d_spin))  # fmt: skip
        self.items.append((center, force, moment, d_center, np.broadcast_to(d_force, (self.count, 3, self.n_design)), d_moment))

    def add_load(self, load) -> None:

        results = self.results
        body, point = load.point.body, load.point.name
        force, moment = load_wrench(results, load)
        if not self.changes:
            self.items.append((kinematics.point_position(results, body, point), force, moment, None, None, None))
            return
        d_force, d_moment = self._zeros(), self._zeros()
        if load.axes != GROUND:  # turned with its body: F = R f, dF = dR f
            d_rotation = self._frame(load.axes, "rotation")
            inverse = kinematics.rotation_matrix(results, load.axes).swapaxes(1, 2)
            d_force = np.einsum("kijp,kjl,kl->kip", d_rotation, inverse, force)
            d_moment = np.einsum("kijp,kjl,kl->kip", d_rotation, inverse, moment)
        self.items.append((kinematics.point_position(results, body, point), force, moment, point_sensitivity(results, body, point), d_force, d_moment))


def time_vector(vector: sp.ImmutableMatrix, times: np.ndarray) -> np.ndarray:
    """A 3-vector of exact functions of t (a load's force or moment) at ``times``, (K, 3)."""
    out = np.empty((len(times), 3))
    for i, expr in enumerate(vector):
        if expr.free_symbols:
            out[:, i] = np.broadcast_to(sp.lambdify(T, expr, "numpy")(times), times.shape)
        else:
            out[:, i] = float(expr)
    return out
