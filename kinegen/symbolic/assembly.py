"""Assembly of the exact symbolic system of one model, parametrization and case.

For every constraint row kinegen derives, *only in the coordinates of the (at most two)
bodies the row touches*:

* ``Phi`` (the row itself),
* the sparse Jacobian ``Phi_q`` with respect to the velocity coordinates
  (``Phi_q = dPhi/ds · B(s)``, with ``ds/dt = B(s) v`` the parametrization's velocity map),
* ``nu = -Phi_t``,
* ``gamma = -(Phi_q v)_s B(s) v - 2 (Phi_q v)_t - Phi_tt``.

So build cost grows linearly with the number of constraints. Constraints of the same
shape (the same equation up to the names of their bodies and inputs: the links of a chain,
the two sides of an excavator's symmetric pins) are derived once, in placeholder bodies,
and renamed (:class:`Templates`).

Time enters only through the *driver inputs*: driver k's equation uses a symbol ``u_k``
(its angle, translation, length or coordinate) with rate ``ud_k`` and acceleration
``udd_k``; a case's time functions give ``u_k = f_k(t)``. The time derivative of an
expression is therefore ``D(e) = sum_k de/du_k ud_k + de/dud_k udd_k``. Driving a case
from tabulated values (a controller, a sweep, another case's results) needs no rebuild.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import sympy as sp

from kinegen.constraints import GROUND_FRAME, Equation, Frame, driver_equation, joint_equations
from kinegen.interface import normalization_row
from kinegen.model.expressions import T, time_derivative
from kinegen.model.schema import GROUND, Case, Model
from kinegen.rotations import Parametrization
from kinegen.symbolic.engine import gradient


@dataclass(frozen=True)
class BodyCoordinates:
    """Symbols of one body: stored ``s`` and velocity ``v`` (as the parametrization names
    them), the velocity map ``B`` (``ds/dt = B(s) v``).

    The rotation matrix enters the equations as the symbols ``a`` (``{body}_a{i}{j}``),
    defined by ``rotation`` = A(s); ``rotation_derivatives[k]`` is dA/dv_k for every
    velocity coordinate k (zero for a pure translation). Where the frame origin is not among
    the stored coordinates (dual quaternions) it enters as the symbols ``origin_symbols``
    (``{body}_o{x,y,z}``), defined by ``origin``, with dr/dv_k ``origin_derivatives[k]``.
    """

    name: str
    stored: tuple[sp.Symbol, ...]
    velocity: tuple[sp.Symbol, ...]
    stored_offset: int
    velocity_offset: int
    velocity_map: sp.Matrix  # nq x nv
    frame: Frame  # r = the origin's expression, A = the symbols a
    rotation: sp.Matrix  # A(s)
    rotation_derivatives: tuple[sp.Matrix, ...]
    origin_symbols: tuple[sp.Symbol, ...] = ()
    origin: tuple[sp.Expr, ...] = ()
    origin_derivatives: tuple[sp.Matrix, ...] = ()

    @property
    def frame_symbols(self) -> list[sp.Symbol]:
        """The symbols defined from the stored coordinates: origin (if not stored), then A."""
        return [*self.origin_symbols, *self.frame.A]

    @property
    def frame_values(self) -> list[sp.Expr]:
        """Their definitions, in the same order."""
        return [*self.origin, *self.rotation]

    def frame_derivatives(self, k: int) -> list[sp.Expr]:
        """d(frame symbol)/dv_k for each frame symbol, in order."""
        origin = list(self.origin_derivatives[k]) if self.origin_symbols else []
        return [*origin, *self.rotation_derivatives[k]]

    @cached_property
    def tangents(self) -> tuple[tuple[tuple[sp.Symbol, sp.Expr], ...], ...]:
        """Per velocity coordinate k, the (configuration symbol, its derivative along v_k) pairs
        not identically zero: frame symbols (dA/dv_k, dr/dv_k), then stored (B[:, k])."""
        out = []
        for k in range(len(self.velocity)):
            pairs = [(s, d) for s, d in zip(self.frame_symbols, self.frame_derivatives(k)) if d != 0]
            pairs += [(s, b) for s, b in zip(self.stored, self.velocity_map[:, k]) if b != 0]
            out.append(tuple(pairs))
        return tuple(out)

    def frame_rates(self, direction: tuple[sp.Symbol, ...] | None = None) -> list[sp.Expr]:
        """d(frame symbol)/dt = sum_k d/dv_k v_k, in order (along ``direction`` instead of the
        velocity symbols: the change as the body moves along that tangent direction)."""
        if direction is None:
            return list(self._velocity_rates[0])
        return self._frame_rates(direction)

    def stored_rates(self, direction: tuple[sp.Symbol, ...] | None = None) -> list[sp.Expr]:
        """d(stored coordinate)/dt = B(s) v, in order (along ``direction`` instead of v)."""
        if direction is None:
            return list(self._velocity_rates[1])
        return list(self.velocity_map * sp.Matrix(direction))

    @cached_property
    def _velocity_rates(self) -> tuple[tuple[sp.Expr, ...], tuple[sp.Expr, ...]]:
        """(frame rates, stored rates) along the velocity symbols: the same for every row the body is in."""
        return tuple(self._frame_rates(self.velocity)), tuple(self.stored_rates(self.velocity))

    def _frame_rates(self, direction: tuple[sp.Symbol, ...]) -> list[sp.Expr]:
        rates = [sp.Integer(0)] * len(self.frame_symbols)
        for k, w in enumerate(direction):
            for i, d in enumerate(self.frame_derivatives(k)):
                if d != 0:
                    rates[i] += d * w
        return rates


@dataclass(frozen=True)
class Coordinates:
    """All bodies' coordinates in order: the layout of ``q`` (stored) and ``v`` (velocity)."""

    parametrization: Parametrization
    bodies: tuple[BodyCoordinates, ...]

    @property
    def stored_names(self) -> list[str]:
        p = self.parametrization
        return [f"{b.name}.{c}" for b in self.bodies for c in p.coordinate_names]

    @property
    def velocity_names(self) -> list[str]:
        p = self.parametrization
        return [f"{b.name}.{c}" for b in self.bodies for c in p.velocity_coordinate_names]

    @property
    def stored_symbols(self) -> list[sp.Symbol]:
        return [s for b in self.bodies for s in b.stored]

    @property
    def velocity_symbols(self) -> list[sp.Symbol]:
        return [s for b in self.bodies for s in b.velocity]

    def body(self, name: str) -> BodyCoordinates:
        return self._by_name[name]

    @cached_property
    def _by_name(self) -> dict[str, BodyCoordinates]:
        return {b.name: b for b in self.bodies}

    @property
    def frame_definitions(self) -> dict[sp.Symbol, sp.Expr]:
        """a_ij -> A(s)_ij (and origin symbols -> their expressions) for every body, to
        substitute the symbols away."""
        return {a: e for b in self.bodies for a, e in zip(b.frame_symbols, b.frame_values)}


class Row:
    """One constraint row with its derived quantities (Jacobian by velocity column).

    A row derived through :class:`Templates` holds its shape's key, the renaming generic ->
    real symbol and each real Jacobian column's (placeholder body, coordinate); its own
    Jacobian, nu and gamma are renamed from the shape's only when first asked for (code
    generation prints the shape once and renames the printed text instead).
    """

    __slots__ = ("_gamma", "_jacobian", "_nu", "columns", "generic", "group", "is_driver", "name", "phi", "rename", "shape")

    def __init__(
        self,
        name: str,
        phi: sp.Expr,
        jacobian: dict[int, sp.Expr] | None,
        nu: sp.Expr | None,
        gamma: sp.Expr | None,
        is_driver: bool = False,
        group: str = "",
        shape: tuple | None = None,
        rename: dict[sp.Symbol, sp.Symbol] | None = None,
        columns: dict[int, tuple[int, int]] | None = None,
        generic: Row | None = None,
    ) -> None:
        self.name, self.phi, self.is_driver = name, phi, is_driver
        self.group = group  #: the joint, driver or body ("norm:<body>") the row belongs to
        self.shape, self.rename, self.columns, self.generic = shape, rename or {}, columns or {}, generic
        self._jacobian, self._nu, self._gamma = jacobian, nu, gamma

    @property
    def jacobian(self) -> dict[int, sp.Expr]:
        if self._jacobian is None:
            self._jacobian = {c: self.generic.jacobian[bk].xreplace(self.rename) for c, bk in self.columns.items()}
        return self._jacobian

    @property
    def jacobian_columns(self) -> list[int]:
        """The velocity columns of the row's non-zero Jacobian entries, ascending."""
        return sorted(self.columns if self.generic is not None else self.jacobian)

    @property
    def nu(self) -> sp.Expr:
        if self._nu is None:
            self._nu = self.generic.nu.xreplace(self.rename)
        return self._nu

    @property
    def gamma(self) -> sp.Expr:
        if self._gamma is None:
            self._gamma = self.generic.gamma.xreplace(self.rename)
        return self._gamma


@dataclass(frozen=True)
class DriverInputs:
    """Symbols of the driver inputs of a case and their time functions."""

    names: tuple[str, ...]
    u: tuple[sp.Symbol, ...]
    ud: tuple[sp.Symbol, ...]
    udd: tuple[sp.Symbol, ...]
    functions: tuple[sp.Expr, ...]  # f_k(t)
    #: (entry, text) of each function in the model file, for messages
    sources: tuple[tuple[str, str], ...] = ()

    @cached_property
    def index(self) -> dict[sp.Symbol, int]:
        """Input symbol u_k -> k."""
        return {u: k for k, u in enumerate(self.u)}

    def stacked(self) -> list[sp.Expr]:
        """The functions, then their first and then their second time derivatives (the rows of ``inputs(t)``)."""
        rates = [time_derivative(f) for f in self.functions]
        return [*self.functions, *rates, *(time_derivative(r) for r in rates)]

    def time_derivative(self, expr: sp.Expr) -> sp.Expr:
        """D(expr) with u_k = f_k(t): sum_k de/du_k ud_k + de/dud_k udd_k."""
        total = sp.Integer(0)
        for u, ud, udd in zip(self.u, self.ud, self.udd):
            total += sp.diff(expr, u) * ud + sp.diff(expr, ud) * udd
        return total

    def at_time(self, t: sp.Expr) -> dict[sp.Symbol, sp.Expr]:
        """Exact substitution u, ud, udd <- f(t), f'(t), f''(t)."""
        values: dict[sp.Symbol, sp.Expr] = {}
        for u, ud, udd, f in zip(self.u, self.ud, self.udd, self.functions):
            values[u] = f.subs(T, t)
            values[ud] = sp.diff(f, T).subs(T, t)
            values[udd] = sp.diff(f, T, 2).subs(T, t)
        return values


def driver_inputs(case: Case) -> DriverInputs:
    """Input symbols ``u{k}``, ``ud{k}``, ``udd{k}`` of the drivers of ``case`` in order."""
    n = len(case.drivers)
    return DriverInputs(
        names=tuple(d.name for d in case.drivers),
        u=tuple(sp.Symbol(f"u{k}", real=True) for k in range(n)),
        ud=tuple(sp.Symbol(f"ud{k}", real=True) for k in range(n)),
        udd=tuple(sp.Symbol(f"udd{k}", real=True) for k in range(n)),
        functions=tuple(d.function for d in case.drivers),
        sources=tuple((d.entry, d.text) for d in case.drivers),
    )


@dataclass
class System:
    """The exact symbolic kinematics of one case."""

    model: Model
    case: Case
    coordinates: Coordinates
    inputs: DriverInputs
    rows: list[Row] = field(default_factory=list)
    templates: Templates | None = None  #: the shapes the rows were derived from

    @property
    def constraint_names(self) -> list[str]:
        return [r.name for r in self.rows]

    @property
    def jacobian_pattern(self) -> list[tuple[int, int]]:
        """(row, column) of every non-zero of ``Phi_q``, row-major (without deriving the expressions)."""
        return [(i, j) for i, r in enumerate(self.rows) for j in r.jacobian_columns]

    @property
    def jacobian_entries(self) -> list[tuple[int, int, sp.Expr]]:
        """Sparse ``Phi_q`` as (row, column, expression), row-major; the pattern is constant."""
        return [(i, j, e) for i, r in enumerate(self.rows) for j, e in sorted(r.jacobian.items())]

    def jacobian_matrix(self, substitute: bool = True) -> sp.Matrix:
        """Dense symbolic ``Phi_q`` (for inspection of small systems), in the stored coordinates."""
        definitions = self.coordinates.frame_definitions if substitute else {}
        m = sp.zeros(len(self.rows), len(self.coordinates.velocity_symbols))
        for i, j, e in self.jacobian_entries:
            m[i, j] = e.xreplace(definitions)
        return m


def coordinates(model: Model, parametrization: Parametrization) -> Coordinates:
    """Symbols and frames of every moving body of ``model``."""
    bodies = []
    s_off = v_off = 0
    for body in model.bodies:
        coordinates = _body_coordinates(body.name, parametrization, s_off, v_off)
        bodies.append(coordinates)
        s_off += len(coordinates.stored)
        v_off += len(coordinates.velocity)
    return Coordinates(parametrization, tuple(bodies))


def _body_coordinates(name: str, parametrization: Parametrization, s_off: int, v_off: int) -> BodyCoordinates:
    """A body's symbols, velocity map and rotation derivatives: those of a generic body, renamed."""
    generic = generic_body(parametrization)
    names = {
        s: sp.Symbol(str(s).replace(GENERIC_NAME, name, 1), real=True)
        for s in (*generic.stored, *generic.velocity, *generic.frame.A, *generic.origin_symbols)
    }

    def rename(m: sp.Matrix | None) -> sp.Matrix | None:
        return None if m is None else m.xreplace(names)

    frame = Frame(rename(generic.frame.r), rename(generic.frame.A), rename(generic.frame.e), generic.frame.unified)
    return BodyCoordinates(
        name, tuple(names[s] for s in generic.stored), tuple(names[s] for s in generic.velocity), s_off, v_off,
        rename(generic.velocity_map), frame, rename(generic.rotation), tuple(rename(d) for d in generic.rotation_derivatives),
        tuple(names[s] for s in generic.origin_symbols), tuple(e.xreplace(names) for e in generic.origin),
        tuple(rename(d) for d in generic.origin_derivatives),
    )  # fmt: skip


GENERIC_NAME = "_generic"  # not a valid model name: "v__generic_x" -> "v_<body>_x"
_GENERIC_BODIES: dict[str, BodyCoordinates] = {}


def generic_body(parametrization: Parametrization) -> BodyCoordinates:
    """The coordinates of a body named ``_generic`` (derived once per parametrization)."""
    if parametrization.name not in _GENERIC_BODIES:
        name = GENERIC_NAME
        p = parametrization
        stored = tuple(sp.Symbol(f"{name}_{c}", real=True) for c in p.coordinate_names)
        velocity = tuple(sp.Symbol(f"v_{name}_{c}", real=True) for c in p.velocity_coordinate_names)
        s = sp.Matrix(stored)
        a = sp.Matrix(3, 3, [sp.Symbol(f"{name}_a{i}{j}", real=True) for i in range(3) for j in range(3)])
        r = sp.Matrix([sp.Symbol(f"{name}_o{c}", real=True) for c in "xyz"])
        origin_derivatives = p.body_origin_derivatives(r, s)
        stored_origin = origin_derivatives is None
        frame = Frame(p.body_origin(s) if stored_origin else r, a, p.body_quaternion(s), p.unified)
        derivatives = tuple(p.body_rotation_derivatives(a, s))
        _GENERIC_BODIES[parametrization.name] = BodyCoordinates(
            name, stored, velocity, 0, 0, p.body_velocity_map(s), frame, p.body_rotation(s), derivatives,
            () if stored_origin else tuple(r), () if stored_origin else tuple(p.body_origin(s)),
            () if stored_origin else tuple(origin_derivatives),
        )  # fmt: skip
    return _GENERIC_BODIES[parametrization.name]


class Templates:
    """Derived rows by shape: an equation is renamed to placeholder bodies ``_b0``, ``_b1``
    and inputs ``_u0``..., derived once per distinct renamed expression, and renamed back.

    Renaming symbols is exact (SymPy re-canonicalizes the same expression tree), so the
    rows are identical to deriving every equation on its own.
    """

    def __init__(self, parametrization: Parametrization) -> None:
        self.parametrization = parametrization
        self._placeholders: list[BodyCoordinates] = []
        self._rows: dict[tuple, Row] = {}

    def _placeholder(self, k: int) -> BodyCoordinates:
        """Placeholder body ``_b{k}``; its velocity columns start at k * (coordinates per body),
        so a generic row's column c is (body c // size, coordinate c % size)."""
        size = self.parametrization.nv
        while len(self._placeholders) <= k:
            i = len(self._placeholders)
            self._placeholders.append(_body_coordinates(f"_b{i}", self.parametrization, 0, i * size))
        return self._placeholders[k]

    def derive(
        self, equation: Equation, coords: Coordinates, inputs: DriverInputs | None, is_driver: bool, group: str = ""
    ) -> Row:
        touched = [coords.body(name) for name in equation.bodies]
        placeholders = tuple(self._placeholder(k) for k in range(len(touched)))
        forward: dict[sp.Symbol, sp.Symbol] = {}
        for body, placeholder in zip(touched, placeholders):
            for real, generic in (
                (body.stored, placeholder.stored),
                (body.velocity, placeholder.velocity),
                (body.frame_symbols, placeholder.frame_symbols),
            ):
                forward.update(zip(real, generic))
        generic_inputs = None
        if inputs is not None:
            used = sorted(inputs.index[s] for s in equation.expr.free_symbols if s in inputs.index)
            generic_inputs = _generic_inputs(len(used))
            for g, k in enumerate(used):
                forward[inputs.u[k]] = generic_inputs.u[g]
                forward[inputs.ud[k]] = generic_inputs.ud[g]
                forward[inputs.udd[k]] = generic_inputs.udd[g]
        generic_expr = equation.expr.xreplace(forward)
        key = (generic_expr, len(touched), is_driver, generic_inputs is not None)
        row = self._rows.get(key)
        if row is None:
            generic = Equation("", tuple(p.name for p in placeholders), generic_expr)
            row = _derive(generic, Coordinates(self.parametrization, placeholders), generic_inputs, is_driver)
            size = self.parametrization.nv
            row = Row("", row.phi, {divmod(c, size): e for c, e in row.jacobian.items()}, row.nu, row.gamma, is_driver)
            self._rows[key] = row
        backward = {g: r for r, g in forward.items()}
        columns = {touched[b].velocity_offset + k: (b, k) for (b, k) in row.jacobian}
        return Row(equation.name, equation.expr, None, None, None, is_driver, group, key, backward, columns, row)

    def generic(self, key: tuple) -> Row:
        """The row of a shape in placeholder symbols (Jacobian keyed by (placeholder body, coordinate))."""
        return self._rows[key]


def _generic_inputs(n: int) -> DriverInputs:
    return DriverInputs(
        names=tuple(f"_u{k}" for k in range(n)),
        u=tuple(sp.Symbol(f"_u{k}", real=True) for k in range(n)),
        ud=tuple(sp.Symbol(f"_ud{k}", real=True) for k in range(n)),
        udd=tuple(sp.Symbol(f"_udd{k}", real=True) for k in range(n)),
        functions=tuple(sp.Integer(0) for _ in range(n)),
    )


def derive(
    equation: Equation,
    coords: Coordinates,
    inputs: DriverInputs | None = None,
    is_driver: bool = False,
    templates: Templates | None = None,
    group: str = "",
) -> Row:
    """Jacobian, nu and gamma of one equation (through ``templates`` when given)."""
    if templates is not None:
        return templates.derive(equation, coords, inputs, is_driver, group)
    row = _derive(equation, coords, inputs, is_driver)
    return Row(row.name, row.phi, row.jacobian, row.nu, row.gamma, is_driver, group)


def _derive(equation: Equation, coords: Coordinates, inputs: DriverInputs | None = None, is_driver: bool = False) -> Row:
    """Jacobian, nu and gamma of one equation, in its bodies' coordinates only.

    The equation is written in each body's stored symbols ``s`` (its origin is an expression
    of them: the positions themselves, or a dual quaternion's translation) and rotation-matrix
    symbols ``a``. With the chain rule, for velocity coordinate k,
    dPhi/dv_k = sum_ij dPhi/da_ij (dA/dv_k)_ij + dPhi/ds B(s)[:, k], and the configuration
    part of the time derivative is D_q(E) = sum_ij dE/da_ij A'_ij + dE/ds B(s) v.
    """
    phi = equation.expr
    touched = [coords.body(name) for name in equation.bodies]

    def configuration_rate(expr: sp.Expr) -> sp.Expr:
        return along(expr, touched)

    jacobian = tangent_jacobian(phi, touched)
    psi = sp.Integer(0)  # Phi_q v
    for body in touched:
        for k, velocity in enumerate(body.velocity):
            if body.velocity_offset + k in jacobian:
                psi += jacobian[body.velocity_offset + k] * velocity
    if inputs is None:  # a joint: no time dependence
        phi_t, gamma = sp.Integer(0), sp.Integer(0)
    else:
        phi_t = inputs.time_derivative(phi)
        gamma = -2 * inputs.time_derivative(psi) - inputs.time_derivative(phi_t)
    gamma -= configuration_rate(psi)
    return Row(equation.name, phi, jacobian, -phi_t, gamma, is_driver)


def tangent_jacobian(expr: sp.Expr, bodies: list[BodyCoordinates]) -> dict[int, sp.Expr]:
    """The derivatives of ``expr`` (written in the bodies' stored and frame symbols) along each
    velocity coordinate's tangent direction, keyed by the coordinate's column (its body's
    velocity offset + k), entries identically zero left out. With the chain rule, for velocity
    coordinate k, d/dv_k = sum_ij d/da_ij (dA/dv_k)_ij + d/ds B(s)[:, k]; velocity and other
    symbols in ``expr`` are held."""
    derivatives = gradient(expr, [s for body in bodies for s in (*body.stored, *body.frame_symbols)])
    out: dict[int, sp.Expr] = {}
    for body in bodies:
        for k, pairs in enumerate(body.tangents):
            total = sp.Add(*(derivatives[s] * d for s, d in pairs if s in derivatives))
            if total != 0:
                out[body.velocity_offset + k] = total
    return out


def along(expr: sp.Expr, bodies: list[BodyCoordinates], directions: list[tuple[sp.Symbol, ...]] | None = None) -> sp.Expr:
    """The change of ``expr`` (written in the bodies' stored and frame symbols) as each body's
    configuration moves along a tangent direction given in its velocity coordinates: by
    default its velocity (the configuration part of d/dt), else ``directions`` (one tuple of
    symbols per body). Velocity and other symbols in ``expr`` are held."""
    configuration = [s for body in bodies for s in (*body.stored, *body.frame_symbols)]
    derivatives = gradient(expr, configuration)
    zero = sp.Integer(0)
    total = zero
    for k, body in enumerate(bodies):
        direction = None if directions is None else directions[k]
        for symbol, rate in zip(body.frame_symbols, body.frame_rates(direction)):
            if rate != 0:
                total += derivatives.get(symbol, zero) * rate
        for s, rate in zip(body.stored, body.stored_rates(direction)):
            if rate != 0:
                total += derivatives.get(s, zero) * rate
    return total


def _moving(names: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(n for n in dict.fromkeys(names) if n != GROUND)


def kinematic_rows(model: Model, coords: Coordinates, templates: Templates | None = None) -> list[Row]:
    """Rows of the joints and of the parametrization's normalization constraints (case-independent)."""
    frames = {b.name: b.frame for b in coords.bodies}
    rows = []
    for joint in model.joints:
        frame1 = GROUND_FRAME if joint.body1 == GROUND else frames[joint.body1]
        frame2 = GROUND_FRAME if joint.body2 == GROUND else frames[joint.body2]
        for eq in joint_equations(joint, frame1, frame2, _moving((joint.body1, joint.body2))):
            rows.append(derive(eq, coords, templates=templates, group=joint.name))
    for body in coords.bodies:
        for k, expr in enumerate(coords.parametrization.body_normalization(sp.Matrix(body.stored))):
            equation = Equation(normalization_row(body.name, k), (body.name,), expr)
            rows.append(derive(equation, coords, templates=templates, group=f"norm:{body.name}"))
    return rows


def build_systems(model: Model, parametrization: Parametrization, cases: list[str] | None = None) -> dict[str, System]:
    """The symbolic system of each case (all cases by default); joint rows are derived once."""
    coords = coordinates(model, parametrization)
    templates = Templates(parametrization)
    shared = kinematic_rows(model, coords, templates)
    frames = {b.name: b.frame for b in coords.bodies}
    joints = {j.name: j for j in model.joints}

    def frame_of(name: str) -> Frame:
        return GROUND_FRAME if name == GROUND else frames[name]

    systems = {}
    for name in cases or list(model.cases):
        case = model.cases[name]
        inputs = driver_inputs(case)
        rows = list(shared)
        for driver, u in zip(case.drivers, inputs.u):
            equation = driver_equation(driver, joints, frame_of, _moving, u)
            rows.append(derive(equation, coords, inputs, is_driver=True, templates=templates, group=f"driver:{driver.name}"))
        systems[name] = System(model, case, coords, inputs, rows, templates)
    return systems
