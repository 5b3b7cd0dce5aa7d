"""The forces that hold loads on a mechanism along a solved motion, by virtual work: Φ_qᵀ λ = Q.

Conventions (SI: N, N m, Pa; global axes unless a field says otherwise):

* **Tangent maps.** A body's velocity coordinates v_b give its origin's velocity and its
  angular velocity linearly, [ṙ; ω] = T_b(q) v_b; T_b is the parametrization's own map
  (``frame_velocity``) at unit velocities, so it is exact in every parametrization. A point P
  of the body at the global arm s from its origin moves with J_P = T_v + ω(·) × s.
* **Loads.** A force F at P and a moment M on a body do the virtual work (F·J_P + M·T_ω) δv:
  their generalized force Q.
* **Rows.** The joint rows of Φ_q and one row per *actuation element*: an actuator's length L
  (its row is dL/dv), a motor's joint angle θ (dθ/dv = a·(T_ω2 − T_ω1), a the joint axis), or,
  for a model that declares neither, each case driver's own row. The constraint forces are
  −Φ_qᵀ λ; equilibrium with the loads is Φ_qᵀ λ = Q, one linear solve per time point.
* **Element forces** f = −λ: an actuator's push [N] (positive pushes its two points apart), a
  motor's torque [N m] on the joint's second body about its axis (positive turns it positively
  relative to the first), a driver's generalized force along its input (N for lengths and
  coordinates, N m for angles).
* **Power.** For any motion the joints allow, Σ f_e ė_e + Σ_loads (F·v_P + M·ω) = 0: the
  elements do the work the loads take (ė_e of parallel cylinders: the sum of their rates).
* **Reactions.** The force and moment the joint's first body exerts on its second, the moment
  about the joint's point on the second body; also in the joint's axes (x: its reference
  direction, z: its axis, both turning with the first body; a joint without an axis: the first
  body's axes).
* **Parallel cylinders.** An actuator declared ``parallel`` to a hydraulic one sits on the same
  circuit with the same data: at one pressure both push with the same force, each at its own pins.
  The two are one element whose row is the sum of their length rows (the element's force f does
  the work f (L̇1 + L̇2)); its force is each cylinder's, and the pins of both carry their share.
* **Pressures.** A pushing cylinder is pressurized on its cap side (all ``cylinders`` of the
  actuator together, area n π/4 bore²), a pulling one on its rod side (n π/4 (bore² − rod²)).
  The pressure is limited by the circuit's relief setting while the cylinder moves with its
  force (f·L̇ > 0: the pump does the work), else by the holding (port relief) setting.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import sympy as sp
from scipy.linalg.lapack import dgecon as gecon
from scipy.linalg.lapack import dgetrf as getrf
from scipy.linalg.lapack import dgetrs as getrs

from kinegen.errors import KinegenError, ModelError, SingularJacobianError
from kinegen.forces.dynamics import energies, inertia_numbers, inertial_load, load_wrench, tipping_margin
from kinegen.interface import row_owner
from kinegen.model import Model
from kinegen.model.expressions import T
from kinegen.model.schema import GROUND, Actuator, Joint, Load, Motor, design_value
from kinegen.runtime import kinematics
from kinegen.runtime.results import Results

#: a reciprocal 1-norm condition of Phi_q at or below this is singular: no force holds the load there
SINGULAR = 1e-12


@dataclass(frozen=True)
class Rows:
    """Rows of Φ_q at K poses, sparse: entry e is (``rows[e]``, ``cols[e]``), its values ``values[:, e]``."""

    rows: np.ndarray
    cols: np.ndarray
    values: np.ndarray  #: (K, entries)
    shape: tuple[int, int]

    def dense(self, k: int) -> np.ndarray:
        """The matrix at pose k."""
        out = np.zeros(self.shape)
        np.add.at(out, (self.rows, self.cols), self.values[k])
        return out

    def block(self, rows: list[int], columns: slice) -> np.ndarray:
        """(K, len(rows), columns) the dense sub-block of ``rows`` and ``columns`` at every pose."""
        out = np.zeros((len(self.values), len(rows), columns.stop - columns.start))
        for i, r in enumerate(rows):
            inside = np.flatnonzero((self.rows == r) & (self.cols >= columns.start) & (self.cols < columns.stop))
            out[:, i, self.cols[inside] - columns.start] = self.values[:, inside]
        return out

    def transpose_times(self, multipliers: np.ndarray, rows: list[int]) -> np.ndarray:
        """(K, n) the rows' part of Φ_qᵀ λ: Σ over those rows of λ_r times row r."""
        inside = np.flatnonzero(np.isin(self.rows, rows))
        out = np.zeros((len(self.values), self.shape[1]))
        np.add.at(out.T, self.cols[inside], (self.values[:, inside] * multipliers[:, self.rows[inside]]).T)
        return out


@dataclass(frozen=True)
class Element:
    """One actuation element: what carries the load along one degree of freedom."""

    name: str
    kind: str  #: "actuator" (a length), "motor" (a joint angle) or "driver" (a case's driver)
    unit: str  #: of its force: "N" or "N m"


@dataclass(frozen=True)
class Reaction:
    """A joint's reaction over time: what ``body1`` exerts on ``body2``."""

    joint: str
    body1: str
    body2: str
    point: np.ndarray  #: (K, 3) where the moment is taken: the joint's point on body2
    force: np.ndarray  #: (K, 3) [N]
    moment: np.ndarray  #: (K, 3) [N m] about ``point``
    axes: np.ndarray  #: (K, 3, 3) the joint's axes as columns (x, y, z), global

    @property
    def joint_force(self) -> np.ndarray:
        """The force in the joint's axes, (K, 3)."""
        return np.einsum("kji,kj->ki", self.axes, self.force)

    @property
    def joint_moment(self) -> np.ndarray:
        """The moment in the joint's axes, (K, 3)."""
        return np.einsum("kji,kj->ki", self.axes, self.moment)


@dataclass(frozen=True)
class Pressure:
    """A hydraulic actuator's working pressure over time and the limit it meets."""

    actuator: str
    pressure: np.ndarray  #: (K,) [Pa] on the side that carries the force
    cap_side: np.ndarray  #: (K,) True where it pushes (cap side), False where it pulls (rod side)
    limit: np.ndarray  #: (K,) [Pa] the relief setting where it works, the holding setting where it holds
    working: np.ndarray  #: (K,) True where the cylinder moves with its force (f L' > 0)

    @property
    def exceeded(self) -> np.ndarray:
        """(K,) True where the pressure is beyond its limit."""
        return self.pressure > self.limit


@dataclass
class Forces:
    """The forces holding ``loads`` along a solved motion (see the module docstring)."""

    results: Results
    loads: tuple[str, ...]
    elements: tuple[Element, ...]
    force: np.ndarray  #: (K, n_elements) element forces [N or N m]
    multipliers: np.ndarray  #: (K, rows) λ of the rows: the joint rows, then the elements
    row_names: tuple[str, ...]
    reactions: dict[str, Reaction]
    pressures: dict[str, Pressure] = field(default_factory=dict)
    #: (K, n_v) the loads' generalized force Q (with ``inertia``: gravity and the bodies' inertia included)
    generalized_load: np.ndarray | None = None
    #: whether the bodies' weight and inertia are held too (inverse dynamics)
    inertia: bool = False
    #: with ``inertia``: the kinetic and potential energy (:class:`kinegen.forces.dynamics.Energies`)
    energies: Any = None
    #: with ``inertia`` and a ``machine:`` section: the tipping margin (:class:`kinegen.forces.dynamics.TippingMargin`)
    tipping: Any = None
    #: cylinders parallel to an element (name -> the element's name): each pushes with its element's force
    parallel: dict[str, str] = field(default_factory=dict)
    #: whether the bodies' own weight is held (statics with ``weight``, or with ``inertia``)
    weight: bool = False

    def element_force(self, name: str) -> np.ndarray:
        """The force of one element, or of a cylinder parallel to one (the same), over time, (K,)."""
        names = [e.name for e in self.elements]
        if name not in names and name not in self.parallel:
            raise KeyError(f"no actuation element {name!r} (elements: {', '.join([*names, *self.parallel])})")
        return self.force[:, names.index(self.parallel.get(name, name))]

    def violations(self) -> list[tuple[float, str, float, float, str]]:
        """(time, actuator, pressure, limit, what) where a pressure is beyond its relief or holding setting."""
        found = []
        for name, p in self.pressures.items():
            for k in np.flatnonzero(p.exceeded):
                side = "cap" if p.cap_side[k] else "rod"
                found.append((float(self.results.times[k]), name, float(p.pressure[k]), float(p.limit[k]),
                              f"{'relief' if p.working[k] else 'holding'} setting, {side} side"))  # fmt: skip
        return sorted(found)

    def table(self) -> tuple[list[str], np.ndarray]:
        """Column names and values (one row per time point) of the force export."""
        names, columns = [], []
        for k, element in enumerate(self.elements):
            names.append(f"{element.name}.force")
            columns.append(self.force[:, k : k + 1])
        for name, element in self.parallel.items():  # each physical cylinder's own force
            names.append(f"{name}.force")
            columns.append(self.element_force(element)[:, None])
        for name, p in self.pressures.items():
            names += [f"{name}.pressure", f"{name}.pressure_limit"]
            columns.append(np.c_[np.where(p.cap_side, p.pressure, -p.pressure), p.limit])
        for name, r in self.reactions.items():
            for label, values in (("force", r.force), ("moment", r.moment), ("joint_force", r.joint_force), ("joint_moment", r.joint_moment)):
                names += [f"{name}.{label}_{c}" for c in "xyz"]
                columns.append(values)
        names += [f"lambda.{row}" for row in self.row_names]
        columns.append(self.multipliers)
        if self.energies is not None:
            names += ["energy.kinetic", "energy.potential"]
            columns.append(np.c_[self.energies.kinetic, self.energies.potential])
        if self.tipping is not None:
            names += ["tipping_margin", *(f"tipping_margin.{line}" for line in self.tipping.margins)]
            columns.append(np.column_stack([self.tipping.margin, *self.tipping.margins.values()]))
        return names, np.hstack(columns)


def pose_results(system, q: np.ndarray, inputs: np.ndarray, v: np.ndarray | None = None) -> Results:
    """K poses (stored coordinates q (K, n) at inputs (K, n_inputs); velocities v, zero when not
    given) as :class:`Results`, so that :class:`Statics` and the point kinematics take them as they
    take a motion: their "times" are the poses' indices."""
    count = len(q)
    v = np.zeros((count, system.n_velocity)) if v is None else v
    return Results(system, np.arange(count, dtype=float), q, v, np.zeros_like(v), np.zeros(count, dtype=int), np.zeros(count),
                   np.full(count, np.nan), inputs)  # fmt: skip


def unit_rate_velocities(system, q: np.ndarray, inputs: np.ndarray, driver: str) -> np.ndarray:
    """(K, n_v) the velocities at the poses q (K, n) when ``driver``'s input changes at unit rate and
    the others stand still: dq/du of that input (implicit differentiation, every pose at once)."""
    from kinegen.runtime.sensitivity import configuration_sensitivities

    return configuration_sensitivities(system, q.T, inputs.T, design=False)[1][:, :, system.driver_names.index(driver)]


def forces(results: Results, model: Model, loads: tuple[str, ...] | list[str], inertia: bool = False, weight: bool = False) -> Forces:
    """The forces that hold the model's named ``loads`` at every solved time point of ``results``
    (a motion of ``model``; its time points must all have converged); with ``weight``, also the
    bodies' own weight (statics: the masses at rest in every pose); with ``inertia``, their weight
    and inertia along the motion (inverse dynamics, :mod:`kinegen.forces.dynamics`; the weight
    included). ``weight`` and ``inertia`` need a model with masses."""
    unknown = [name for name in loads if name not in model.loads]
    if unknown:
        raise KeyError(f"no load {', '.join(map(repr, unknown))} (loads: {', '.join(model.loads) or 'none'})")
    if not results.complete:
        raise KinegenError("forces need every time point solved; this solve stopped early")
    if (weight or inertia) and not model.massive:
        raise KinegenError(f"{model.name} declares no masses: no weight or inertia to hold (a body's mass:, center_of_mass:, inertia:)")
    weight = weight and not inertia
    statics = Statics(results, model)
    q_load = sum((statics.generalized_load(model.loads[name]) for name in loads), np.zeros((len(results.times), statics.n_v)))
    if inertia:
        q_load = q_load + inertial_load(results)
    elif weight:
        q_load = q_load + statics.weight_load(model.massive)
    matrix = statics.matrix()
    multipliers = statics.compiled_multipliers([model.loads[name] for name in loads], inertia, weight)
    if multipliers is None:
        multipliers = statics.solve(matrix, q_load)
    elements = statics.elements
    force = statics.element_forces(multipliers)
    reactions = {joint.name: statics.reaction(joint, matrix, multipliers) for joint in model.joints}
    pressures = {}
    for k, element in enumerate(elements):
        actuator = statics.actuators.get(element.name)
        if actuator is not None and actuator.hydraulics is not None:
            pressures[element.name] = statics.pressure(actuator, force[:, k])
    energy = tipping = None
    if inertia:
        energy = energies(results, model)
        tipping = tipping_margin(results, model, tuple(loads)) if model.tips else None
    parallel = {a.name: a.parallel for a in model.actuators if a.parallel is not None and statics.declared}
    return Forces(results, tuple(loads), elements, force, multipliers, statics.row_names, reactions, pressures, q_load, inertia, energy,
                  tipping, parallel, weight or inertia)  # fmt: skip


def check_load_functions(model: Model, load: Load, times: np.ndarray) -> None:
    """A :class:`ModelError` naming the model file and the load's entry (``loads.<name>.force[i]``)
    where a component of its force or moment is not a finite real number at one of ``times``
    (``sqrt(t - 20)`` before t = 20, ``1/(t - 1)`` at 1, ``exp(1000 t)``): a function of t outside its
    domain on the time grid, as the drivers' time functions are checked."""
    for kind, vector in (("force", load.force), ("moment", load.moment)):
        for i, expr in enumerate(vector):
            if not expr.free_symbols:
                continue
            bad = ~np.isfinite(_time_function(expr)(times))
            if bad.any():
                first = int(np.argmax(bad))
                raise ModelError(model.file, f"loads.{load.name}.{kind}[{i}]",
                                 f"{sp.sstr(expr)}: not a finite real number at t = {times[first]:.6g} ({int(bad.sum())} of {len(times)} "
                                 "time points) -- the function leaves its domain on this time grid")  # fmt: skip


@functools.cache
def _time_function(expr: sp.Expr):
    """``expr`` (of t) as a NumPy function of the times (NaN where it leaves its domain), silent about it."""
    function = sp.lambdify(T, expr, modules="numpy")

    def evaluate(times: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            try:
                return np.broadcast_to(np.asarray(function(times), dtype=float), times.shape)
            except (ArithmeticError, ValueError, TypeError):
                return np.full(times.shape, np.nan)

    return evaluate


class PerBody(dict):
    """A body's value, by its name, computed on the first lookup and kept (a force at one point
    needs one body's maps, not every body's)."""

    def __init__(self, compute: Any) -> None:
        super().__init__()
        self.compute = compute

    def __missing__(self, body: str) -> Any:
        value = self[body] = self.compute(body)
        return value


class Statics:
    """The numbers a force solve needs at every time point (or pose) of ``results``: the rows
    (:meth:`matrix`), the loads' generalized forces, the solve, reactions and pressures."""

    def __init__(self, results: Results, model: Model) -> None:
        self.results = results
        self.model = model
        self.system = results.system
        self.n_v = self.system.n_velocity
        self.actuators = {a.name: a for a in model.actuators}
        self.joints = {j.name: j for j in model.joints}
        self.declared: tuple[Actuator | Motor, ...] = model.actuation
        #: the joint (and normalization) rows come first in every case, then one row per driver
        self.joint_rows = len(self.system.constraint_names) - len(self.system.driver_names)

    @cached_property
    def elements(self) -> tuple[Element, ...]:
        if not self.declared:
            units = {"joint_angle": "N m", "body_angle": "N m"}
            kinds = {d.name: d.type for d in self.model.cases[self.system.case].drivers}
            return tuple(Element(name, "driver", units.get(kinds.get(name, ""), "N")) for name in self.system.driver_names)
        return tuple(Element(e.name, "motor", "N m") if isinstance(e, Motor) else Element(e.name, "actuator", "N") for e in self.declared)

    @cached_property
    def row_names(self) -> tuple[str, ...]:
        return (*self.system.constraint_names[: self.joint_rows], *(e.name for e in self.elements))

    def element_forces(self, multipliers: np.ndarray) -> np.ndarray:
        """(K, n_elements) the elements' forces from the multipliers of :meth:`solve`."""
        return multipliers[:, self.joint_rows :] * self.input_gains()

    def hold(self, body: str, point: str, force: np.ndarray, batch: bool = False) -> tuple[Rows, np.ndarray]:
        """The rows and the multipliers that hold the global ``force`` (K, 3) at ``body``'s named
        ``point``: :meth:`solve` (errors name a singular pose), or with ``batch`` :meth:`solve_batch`."""
        matrix = self.matrix()
        load = self.point_load(body, point, force)
        return matrix, self.solve_batch(matrix, load) if batch else self.solve(matrix, load)

    def hydraulic_limits(self, per_unit: np.ndarray, working, carried: np.ndarray | None = None) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per hydraulic actuator, :func:`hydraulic_limit` of its force per unit load (the columns of
        ``per_unit``, (K, n_elements)): the load (K,) at which it reaches its setting, the setting and
        the side. ``working``: True (every cylinder at its relief setting) or the name of the one that
        works (the others hold); ``carried`` (K, n_elements): forces the elements carry before any
        load (the machine's own weight)."""
        names = [e.name for e in self.elements]
        out = {}
        for a in self.model.actuators:
            if a.hydraulics is not None:
                k = names.index(a.name)
                before = None if carried is None else carried[:, k]
                out[a.name] = hydraulic_limit(a, per_unit[:, k], self.system.design, working is True or a.name == working, before)
        return out

    def weight_terms(self, bodies) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """Per body of ``bodies``: (name, centre of mass (body coordinates), its derivative by the
        design parameters (3, P), weight m g (3,), its derivative (3, P)) -- what
        :class:`kinegen.forces.sensitivity.MultiplierChanges` differentiates the weights by."""
        from kinegen.model.schema import design_gradient

        design = self.system.design
        order = list(design)
        gravity = self.design_vector(self.model.gravity)
        d_gravity = np.array([design_gradient(x, order, design) for x in self.model.gravity]).reshape(3, len(order))
        out = []
        for body in bodies:
            mass = design_value(body.inertia.mass, design)
            d_mass = np.asarray(design_gradient(body.inertia.mass, order, design), dtype=float).reshape(len(order))
            d_center = np.array([design_gradient(x, order, design) for x in body.inertia.center]).reshape(3, len(order))
            out.append((body.name, self.design_vector(body.inertia.center), d_center, mass * gravity,
                        np.outer(gravity, d_mass) + mass * d_gravity))  # fmt: skip
        return out

    def weight_load(self, bodies) -> np.ndarray:
        """Q (K, n_v) of the weight m g of ``bodies`` (with inertial data) at their centres of mass."""
        gravity = self.design_vector(self.model.gravity)
        out = np.zeros((len(self.results.times), self.n_v))
        for body in bodies:
            mass, local, _ = inertia_numbers(body.inertia, self.system.design)
            center = self.position(body.name, local)
            weight = mass * gravity
            out[:, self.columns(body.name)] += np.einsum("kij,i->kj", self.point_jacobian(body.name, center), weight)
        return out

    def joint_row_indices(self, joint: str) -> list[int]:
        """The rows of ``joint`` among the joint rows (its equations, in order)."""
        return [i for i, name in enumerate(self.row_names[: self.joint_rows]) if row_owner(name) == (joint, False)]

    def normalization_rows(self, body: str) -> list[int]:
        """``body``'s normalization rows among the joint rows (none in most parametrizations)."""
        return [i for i, name in enumerate(self.row_names[: self.joint_rows]) if row_owner(name) == (body, True)]

    def input_gains(self) -> np.ndarray:
        """(K, n_elements) dPhi_e/du_e of each element's row by its input: an element's force along
        its input is f = λ dPhi/du (the row's constraint force -λ Phi_q does the work f du, as
        Phi_q dq + Phi_u du = 0 along it). -1 for the declared elements (rows L - u, θ - u); for a
        case's drivers, -nu at a unit input rate (nu = -Phi_u u' exactly: a driver's row depends on
        time only through its input)."""
        k_points, n = len(self.results.times), len(self.elements)
        if self.declared:
            return -np.ones((k_points, n))
        out = np.empty((k_points, n))
        rate = np.zeros(n)
        for k in range(k_points):
            for j in range(n):
                rate[:] = 0.0
                rate[j] = 1.0
                out[k, j] = -self.system.velocity_rhs(self.results.q[k], self.results.inputs[k], rate)[self.joint_rows + j]
        return out

    # ---- kinematic maps --------------------------------------------------------------
    @cached_property
    def tangents(self) -> PerBody:
        """Per body: (T_v, T_ω), each (K, 3, n_v of the body): [ṙ; ω] = T v_b (computed when first asked for)."""
        p = self.system.parametrization

        def tangent(body: str) -> tuple[np.ndarray, np.ndarray]:
            q = self.system.body_coordinates(self.results.q, body)
            unit = np.zeros((len(q), p.nv))
            tv, tw = np.empty((len(q), 3, p.nv)), np.empty((len(q), 3, p.nv))
            for k in range(p.nv):
                unit[:] = 0.0
                unit[:, k] = 1.0
                tv[:, :, k], tw[:, :, k] = p.frame_velocity(q, unit)
            return tv, tw

        return PerBody(tangent)

    @cached_property
    def poses(self) -> PerBody:
        """Per body: origin (K, 3) and rotation matrix (K, 3, 3) (computed when first asked for)."""
        p = self.system.parametrization
        return PerBody(lambda body: p.pose(self.system.body_coordinates(self.results.q, body)))

    def columns(self, body: str) -> slice:
        offset = self.system.bodies[body][1]
        return slice(offset, offset + self.system.parametrization.nv)

    def rotation(self, body: str) -> np.ndarray:
        if body == GROUND:
            return np.broadcast_to(np.eye(3), (len(self.results.times), 3, 3))
        return self.poses[body][1]

    def position(self, body: str, local: np.ndarray) -> np.ndarray:
        """Global positions (K, 3) of a point given in ``body``'s coordinates."""
        return self.system.local_positions(self.results.q, body, np.asarray(local, dtype=float)[None, :])[:, 0]

    def point_jacobian(self, body: str, point: np.ndarray) -> np.ndarray:
        """J_P (K, 3, n_v of the body) of the point at global position ``point`` (K, 3) moving with ``body``."""
        tv, tw = self.tangents[body]
        arm = point - self.poses[body][0]
        return tv + np.cross(tw.swapaxes(1, 2), arm[:, None, :]).swapaxes(1, 2)

    def local(self, body: str, name: str) -> np.ndarray:
        points = self.system.ground_points if body == GROUND else self.system.points[body]
        return np.asarray(points[name], dtype=float)

    def design_vector(self, vector) -> np.ndarray:
        return np.array([design_value(x, self.system.design) for x in vector], dtype=float)

    # ---- the matrix and its solve ----------------------------------------------------
    @property
    def kernels(self):
        """The module's force-solve kernels (:class:`kinegen.runtime.system.StaticsKernels`)."""
        kernels = self.system.statics
        if kernels is None:
            raise KinegenError(f"the generated module of {self.system.model!r} has no force kernels: "
                               "its model declares no loads or actuation elements")  # fmt: skip
        return kernels

    def matrix(self) -> Rows:
        """Φ_q of the joint rows with the elements' rows at every pose, sparse (:class:`Rows`): the
        generated ``actuation`` kernel, or without declared elements the case's Φ_q."""
        results, system = self.results, self.system
        shape = (self.joint_rows + len(self.elements), self.n_v)
        q = np.ascontiguousarray(results.q.T)
        if self.declared:
            kernels = self.kernels
            names = tuple(name for name, _ in kernels.elements)
            if names != tuple(e.name for e in self.elements):
                raise KinegenError(f"the generated module of {system.model!r} has the actuation elements {', '.join(names) or 'none'}, "
                                   f"the model {', '.join(e.name for e in self.elements)}: build the module from this model")  # fmt: skip
            return Rows(kernels.matrix_rows, kernels.matrix_cols, np.asarray(kernels.matrix(q), dtype=float).reshape(-1, len(q[0])).T.copy(), shape)
        values = np.asarray(system.jac(q, np.ascontiguousarray(results.inputs.T)), dtype=float).reshape(-1, len(q[0])).T.copy()
        return Rows(np.asarray(system.jac_rows), np.asarray(system.jac_cols), values, shape)

    def compiled_multipliers(self, loads: list[Load], inertia: bool = False, weight: bool = False) -> np.ndarray | None:
        """λ holding ``loads`` (with ``inertia``, also the bodies' weight and inertia; with ``weight``,
        their weight at rest) at every time point by the compiled force solve (``kinegen_forces``), or
        None: no compiled case, a load the module was not built with, or a singular time point (then
        :meth:`solve` decides, and names it)."""
        native, kernels = self.system.native, self.system.statics
        if native is None or kernels is None or not all(kernels.serves(load) for load in loads):
            return None
        weights = np.array([sum(load.name == name for load in loads) for name in kernels.load_names], dtype=float)
        results = self.results
        # the inertia kernel at zero velocity and acceleration is gravity alone: the weight
        motion = (results.v, results.a) if inertia else (np.zeros_like(results.v), np.zeros_like(results.a)) if weight else None
        multipliers, _ = native.forces(results.times, results.q, results.inputs, weights, motion)
        return multipliers if np.isfinite(multipliers).all() else None

    def solve(self, matrix: Rows, load: np.ndarray) -> np.ndarray:
        """λ with Φ_qᵀ λ = Q at every time point, one LU per point; a singular Φ_q names the time and
        the dependent rows."""
        rows, cols = matrix.shape
        if rows != cols:
            raise KinegenError(f"forces need a square Phi_q: {self.joint_rows} joint rows and {len(self.elements)} actuation "
                               f"elements make {rows} rows for {cols} velocity coordinates")  # fmt: skip
        multipliers = np.empty(load.shape)
        for k, q in enumerate(load):
            a = matrix.dense(k)
            lu, pivots, info = getrf(a)
            rcond = gecon(lu, np.abs(a).sum(axis=0).max())[0] if info == 0 else 0.0
            if not rcond > SINGULAR:
                self._singular(a, k)
            multipliers[k] = getrs(lu, pivots, q, trans=1)[0]
        return multipliers

    def solve_batch(self, matrix: Rows, load: np.ndarray) -> np.ndarray:
        """λ with Φ_qᵀ λ = Q at every pose at once, block by block over the transposed matrix's
        block-triangular form (:class:`kinegen.runtime.blocksolve.BlockSolve`): for maps of many
        poses. A pose where a block is singular gets NaN (no error: a map shows it as a gap)."""
        from kinegen.runtime.blocksolve import BlockSolve

        if matrix.shape[0] != matrix.shape[1]:
            return self.solve(matrix, load)  # the same error
        transposed = BlockSolve.for_pattern(matrix.cols, matrix.rows, matrix.shape[1], "the transposed actuation matrix")
        with np.errstate(all="ignore"):
            return transposed.solve(matrix.values.T, load.T).T

    def _singular(self, a: np.ndarray, k: int) -> None:
        from kinegen.runtime.solver import describe_combination

        u, s, vt = np.linalg.svd(a)
        rank = int(np.sum(s > 1e-10 * s[0]))
        dependent = sorted({self.row_names[i] for j in range(rank, len(s)) for i in np.flatnonzero(np.abs(u[:, j]) > 1e-6)})
        null = [describe_combination(vt[j], self.system.velocity_names) for j in range(rank, len(s))]
        raise SingularJacobianError(float(self.results.times[k]), rank, a.shape, dependent, null,
                                    "the actuation cannot hold the load here: a force is undetermined")  # fmt: skip

    # ---- loads, reactions, pressures ---------------------------------------------------
    def generalized_load(self, load: Load) -> np.ndarray:
        """Q (K, n_v) of one load: the generated ``loads`` kernel for a load the module was built with
        (by name and content), else (a load made at run time: a study's, a test's) from the numeric
        tangent maps. A :class:`ModelError` naming the load's entry where its force or moment is not a
        finite real number at a time point (a function of t outside its domain there)."""
        times = np.asarray(self.results.times, dtype=float)
        check_load_functions(self.model, load, times)
        kernels = self.system.statics
        if kernels is None or not kernels.serves(load):
            return self.point_load(load.point.body, load.point.name, *load_wrench(self.results, load))
        index = kernels.load_names.index(load.name)
        values = np.asarray(kernels.loads(np.ascontiguousarray(self.results.q.T), times), dtype=float).reshape(-1, len(times))
        mine = kernels.load_rows == index
        out = np.zeros((len(times), self.n_v))
        out[:, kernels.load_cols[mine]] = values[mine].T
        return out

    def point_load(self, body: str, point: str, force: np.ndarray, moment: np.ndarray | None = None) -> np.ndarray:
        """Q (K, n_v) of a force (K, 3) at a named point of ``body`` and a moment (K, 3) on it, global."""
        position = self.position(body, self.local(body, point))
        out = np.zeros((len(self.results.times), self.n_v))
        out[:, self.columns(body)] = np.einsum("kij,ki->kj", self.point_jacobian(body, position), force)
        if moment is not None:
            out[:, self.columns(body)] += np.einsum("kij,ki->kj", self.tangents[body][1], moment)
        return out

    def _wrench(self, body: str, generalized: np.ndarray, matrix: Rows) -> tuple[np.ndarray, np.ndarray]:
        """(F, M about the body's origin) whose generalized force on ``body`` is ``generalized`` (K, n_v).

        A wrench w does the work w.(T_b v_b) for the velocities the body's normalization rows N_b
        allow (N_b v_b = 0), so g = T_bᵀ w + N_bᵀ μ; T_b (6 rows) and N_b (one row per stored
        coordinate beyond six) make a square system."""
        tv, tw = self.tangents[body]
        columns = self.columns(body)
        norms = self.normalization_rows(body)
        square = np.concatenate([tv, tw, matrix.block(norms, columns)], axis=1)  # (K, n_v of the body, n_v of the body)
        w = np.linalg.solve(square.swapaxes(1, 2), generalized[:, columns, None])[:, :, 0]
        return w[:, :3], w[:, 3:6]

    def reaction(self, joint: Joint, matrix: Rows, multipliers: np.ndarray) -> Reaction:
        """What ``joint``'s first body exerts on its second, from the joint's rows and multipliers."""
        rows = self.joint_row_indices(joint.name)
        generalized = -matrix.transpose_times(multipliers, rows)
        local2 = joint.point2 if joint.point2 is not None else [0, 0, 0]
        point = self.position(joint.body2, self.design_vector(local2))
        if joint.body2 != GROUND:
            force, moment = self._wrench(joint.body2, generalized, matrix)
            origin = self.poses[joint.body2][0]
        else:  # the ground's side is the opposite of what it exerts on the first body
            force, moment = self._wrench(joint.body1, generalized, matrix)
            force, moment = -force, -moment
            origin = self.poses[joint.body1][0]
        moment = moment - np.cross(point - origin, force)
        return Reaction(joint.name, joint.body1, joint.body2, point, force, moment, self._joint_axes(joint))

    def _joint_axes(self, joint: Joint) -> np.ndarray:
        """Columns (x, y, z) of the joint's axes, global: z its axis, x its reference direction."""
        rotation = self.rotation(joint.body1)
        if joint.axis1 is None:
            return np.array(rotation)
        z = self.design_vector(joint.axis1)
        z = z / np.linalg.norm(z)
        if joint.reference1 is not None:
            x = self.design_vector(joint.reference1)
        else:
            helper = np.eye(3)[int(np.argmin(np.abs(z)))]
            x = helper - z * (helper @ z)
        x = x / np.linalg.norm(x)
        local = np.column_stack([x, np.cross(z, x), z])
        return rotation @ local

    def pressure(self, actuator: Actuator, force: np.ndarray) -> Pressure:
        """The pressure on the side that carries ``force`` (K,) and the limit it meets."""
        hydraulics = actuator.hydraulics
        assert hydraulics is not None
        design = self.system.design
        cap, annulus = hydraulics.areas(design)
        pushing = force >= 0
        pressure = np.where(pushing, force / cap, -force / annulus)
        rate = sum(kinematics.actuator_rate(self.results, member.name) for member in self.model.members(actuator.name))
        working = force * rate > 0  # the pump does work on the element's cylinders
        relief = [design_value(x, design) for x in hydraulics.relief]
        holding = [design_value(x, design) for x in hydraulics.holding]
        limit = np.where(working, np.where(pushing, relief[0], relief[1]), np.where(pushing, holding[0], holding[1]))
        return Pressure(actuator.name, pressure, pushing, limit, working)


def hydraulic_limit(
    actuator: Actuator, per_unit: np.ndarray, design: dict[str, float], working: bool, carried: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The load (K,) at which a hydraulic ``actuator`` reaches its setting, given its force per unit
    of that load ``per_unit`` (K,) and the force it carries before any load ``carried`` (K,; the
    machine's own weight, default none): its relief setting where it ``working``, else its holding
    setting, on the side its force needs; with that setting [Pa] and the side ("cap"/"rod"). inf
    where the load does not reach it, 0 where the carried force alone is beyond it."""
    hydraulics = actuator.hydraulics
    cap, annulus = hydraulics.areas(design)
    extend, retract = (design_value(x, design) for x in (hydraulics.relief if working else hydraulics.holding))
    pushing = per_unit >= 0
    pressure = np.where(pushing, extend, retract)
    capacity = pressure * np.where(pushing, cap, annulus)
    if carried is not None:  # the load adds per_unit each: the room left on that side
        capacity = np.maximum(capacity - np.where(pushing, carried, -carried), 0.0)
    with np.errstate(divide="ignore"):
        limit = np.where(per_unit == 0, np.inf, capacity / np.abs(per_unit))
    return limit, pressure, np.where(pushing, "cap", "rod")
