"""The kernel description of a generated module: what is computed, from which arguments,
into which outputs -- target-neutral. The backends (``kinegen/codegen/backends/<target>/``)
print it; nothing here knows Python or C.

* **Slots** are the kernels' arguments: ``q`` (stored coordinates), ``v`` (velocity
  coordinates), ``a`` (their time derivatives), ``u``, ``ud``, ``udd`` (driver inputs and
  their first two time derivatives, per case), ``t`` (time) -- and room for ``p`` (design
  parameters).
* **Sections** are runs of rows computed together: the joint rows' Phi, a case's driver
  rows' gamma, the body frames. A section is a list of groups (one joint, driver or body
  each), eliminated (CSE) once per shape (:class:`kinegen.codegen.shapes.Shapes`).
* **Kernels** are what a runtime calls, per case: ``phi_jac`` (q, u -> Phi, Phi_q values at
  the case's pattern), ``nu`` (q, u, ud -> nu = -Phi_t), ``gamma`` (q, v, u, ud, udd ->
  gamma), ``inputs`` (t -> u, ud, udd), ``input_ranges`` (span = (t0, t1) -> enclosures of u,
  ud, udd over that time interval: :mod:`kinegen.codegen.intervals`); and ``frames`` (q, v, a -> per body origin, rotation
  matrix, velocity, angular velocity, acceleration, angular acceleration). A kernel's output
  is the concatenation of sections (or zeros).
* The **plan** of a case is the block-triangular order of its Phi_q (rows and columns
  permuted, block boundaries): found once at build time, so that a solver factorizes Phi_q
  block by block (the excavator's 84 x 84: 41 blocks of at most 9).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np
import symengine as se
import sympy as sp
from sympy.printing.codeprinter import CodePrinter

import kinegen
from kinegen.codegen.intervals import IntervalProgram, interval_program
from kinegen.codegen.shapes import Definitions, Group, Shapes
from kinegen.collector import collector_paused
from kinegen.constraints import GROUND_FRAME
from kinegen.interface import FRAME_FIELDS, FRAME_VALUES, SENSITIVITY_KERNELS, row_owner
from kinegen.model import Model
from kinegen.model.expressions import T
from kinegen.model.schema import GROUND, design_value
from kinegen.rotations import Parametrization
from kinegen.symbolic import engine
from kinegen.symbolic.assembly import (
    Coordinates,
    Row,
    System,
    Templates,
    along,
    build_systems,
    generic_body,
)
from kinegen.symbolic.blocks import block_triangular

#: (kernel, argument slots without p, section doc) of the sensitivity kernels; the joint
#: rows' sections leave out the slots of the driver inputs (u, ud, udd)
SENSITIVITY_SECTIONS = (
    ("phi_p", ("q", "u"), "Phi_p values"),
    ("dvel", ("q", "v", "u", "ud"), "[M_v | E_v] values (velocity sensitivity)"),
    ("dacc", ("q", "v", "a", "u", "ud", "udd"), "[M_a | N_a | E_a] values (acceleration sensitivity)"),
)


@dataclass(frozen=True)
class Section:
    """Rows computed together: ``groups`` in order, using the arguments ``slots``."""

    name: str
    slots: tuple[str, ...]
    groups: tuple[Group, ...]
    size: int
    doc: str


@dataclass(frozen=True)
class Enclosure:
    """Rows computed by interval arithmetic from the time interval ``span`` = (t0, t1): the lower
    bounds of the program's outputs, then their upper bounds (``size`` = 2 x its outputs; an output
    the program cannot enclose is the whole real line)."""

    name: str
    program: IntervalProgram
    size: int
    doc: str


@dataclass(frozen=True)
class Zeros:
    """Rows that are exactly zero (the joint rows of nu)."""

    size: int


@dataclass(frozen=True)
class Output:
    """One output array of a kernel: its parts (section names or zeros) concatenated."""

    name: str
    parts: tuple[str | Zeros, ...]
    size: int


@dataclass(frozen=True)
class Kernel:
    """A function a runtime calls: its argument slots, in order, and its outputs."""

    name: str
    slots: tuple[str, ...]
    outputs: tuple[Output, ...]
    doc: str


@dataclass(frozen=True)
class Plan:
    """Block-triangular order of Phi_q: ``row_order[i]``/``col_order[i]`` are the constraint and
    velocity coordinate at position i of the permuted matrix; block k spans positions
    ``block_start[k]`` to ``block_start[k + 1]``; no entry lies above the block diagonal."""

    row_order: tuple[int, ...]
    col_order: tuple[int, ...]
    block_start: tuple[int, ...]

    @property
    def largest_block(self) -> int:
        return max(b - a for a, b in zip(self.block_start, self.block_start[1:]))


@dataclass(frozen=True)
class CaseDescription:
    """One case: names, time grid, sparsity pattern, input symbols, kernels and plan."""

    name: str
    t0: float
    t1: float
    steps: int
    constraints: tuple[str, ...]
    drivers: tuple[str, ...]
    driver_sources: tuple[tuple[str, str], ...]
    jac_rows: tuple[int, ...]
    jac_cols: tuple[int, ...]
    slots: dict[str, tuple[sp.Symbol, ...]]
    kernels: dict[str, Kernel]
    plan: Plan | None  #: None for a redundant (non-square) or structurally singular Phi_q
    #: a model with design parameters: the sparsity (rows, columns) of each sensitivity kernel's
    #: output (phi_p, dvel, dacc; :data:`SENSITIVITY_KERNELS`); empty without design parameters
    patterns: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] = field(default_factory=dict)


@dataclass(frozen=True)
class StaticsDescription:
    """What a force solve Φ_qᵀ λ = Q needs beside a case's kernels (:mod:`kinegen.symbolic.statics`).

    With actuation elements (``elements``: name, kind "actuator" or "motor"), the matrix is the
    joint rows of Φ_q, then one row per element: the kernel ``actuation`` gives its values at
    (``matrix_rows``, ``matrix_cols``) -- the joint rows' Φ_q values first, as in every case's
    ``jac`` -- factorized in the block-triangular order ``plan``. Without elements each case's
    drivers carry the load: the matrix is the case's Φ_q (``elements`` empty, no ``actuation``).
    The kernel ``loads`` gives every load's Q (``loads``: names) at (``load_rows`` = the load's
    index, ``load_cols``)."""

    elements: tuple[tuple[str, str], ...]
    matrix_rows: tuple[int, ...]
    matrix_cols: tuple[int, ...]
    plan: Plan | None
    loads: tuple[str, ...]
    load_rows: tuple[int, ...]
    load_cols: tuple[int, ...]
    load_keys: tuple[str, ...] = ()  #: each load's :attr:`~kinegen.model.schema.Load.fingerprint`
    #: a model with masses: the kernel ``inertia`` (q, v, a) gives the generalized force of gravity and
    #: of the bodies' inertia at these columns (empty: no masses)
    inertia_cols: tuple[int, ...] = ()
    #: pin reactions (the C target's kinegen_reactions), per joint: its name, the body whose wrench is
    #: reported (index; its second, or its first when the second is the ground), that wrench's sign (1,
    #: or -1 for the first body's), the body of the joint's point (index; -1: the ground), the point's
    #: coordinates in it at the nominal design, and the joint's rows among the joint rows
    joints: tuple[tuple[str, int, int, int, tuple[float, float, float], tuple[int, ...]], ...] = ()
    #: per body (in order), its normalization rows among the joint rows (parametrizations with them)
    norm_rows: tuple[tuple[int, ...], ...] = ()
    #: per element at the nominal design: cap and rod side areas [m^2], relief (extend, retract) and
    #: holding (extend, retract) settings [Pa], the index of its actuator; a motor's NaN and -1
    hydraulics: tuple[tuple[float, float, float, float, float, float, int], ...] = ()
    #: cylinders parallel to an element (each pushes with its force): name, the element's index, the
    #: cylinder's index among the actuators
    parallel: tuple[tuple[str, int, int], ...] = ()


@dataclass
class ModuleDescription:
    """Everything a backend prints for one model in one parametrization (all its cases)."""

    model: str
    source: str
    sha256: str
    parametrization: Parametrization
    version: str
    stored_names: tuple[str, ...]
    velocity_names: tuple[str, ...]
    bodies: tuple[tuple[str, int, int], ...]  #: name, offset in q, offset in v
    points: dict[str, dict[str, tuple[float, float, float]]]
    ground_points: dict[str, tuple[float, float, float]]
    actuators: tuple[tuple[str, tuple[str, str], tuple[str, str], tuple[float, float] | None], ...]
    initial_q: tuple[float, ...]
    slots: dict[str, tuple[sp.Symbol, ...]]
    definitions: Definitions
    sections: dict[str, Section]
    cases: dict[str, CaseDescription]
    kernels: dict[str, Kernel]  #: kernels shared by every case (frames)
    shapes: Shapes = field(default_factory=Shapes)
    #: design parameters: name, nominal, lower, upper (empty: no ``p`` slot anywhere)
    design: tuple[tuple[str, float, float, float], ...] = ()
    #: a model with design parameters: whether the sensitivity kernels are there
    sensitivities: bool = False
    #: the model's C files written beside the Python module (name -> SHA-256 of their bytes), made
    #: before it: the module names the C that belongs to it (empty: none does)
    c_files: dict[str, str] = field(default_factory=dict)
    #: a model with loads or actuation elements: what the force solve's kernels compute (None: neither)
    statics: StaticsDescription | None = None
    #: rows computed by interval arithmetic (each case's input_ranges), by name, like ``sections``
    enclosures: dict[str, Enclosure] = field(default_factory=dict)
    #: a model with a pumps: section: the pumps' names, in the order of the ``supply`` kernel's outputs
    pumps: tuple[str, ...] = ()

    @property
    def joint_rows(self) -> int:
        """Rows common to every case (joints and normalizations), first in each case."""
        return self.sections["joints_phi"].size


def _runs(rows: list[Row]) -> list[tuple[int, int]]:
    """(start, end) of each run of consecutive rows of one joint, driver or normalization."""
    runs = []
    start = 0
    while start < len(rows):
        end = start + 1
        while end < len(rows) and rows[end].group and rows[end].group == rows[start].group:
            end += 1
        runs.append((start, end))
        start = end
    return runs


def _groups(rows: list[Row], templates: Templates | None, kind: str) -> tuple[Group, ...]:
    """Rows in groups (one joint, driver or normalization each) with their shape keys.

    ``kind`` is "phi", "jac" (the row's non-zero entries by column), "nu" or "gamma"."""
    out: list[Group] = []
    for start, end in _runs(rows):
        members = rows[start:end]
        if templates is None or any(r.shape is None for r in members):
            out.append(Group(None, lambda members=members: _real(members, kind), {}))
            continue
        orders = tuple(tuple(r.columns[c] for c in r.jacobian_columns) for r in members) if kind == "jac" else ()
        key = (kind, tuple(r.shape for r in members), orders)
        rename: dict = {}
        for r in members:
            rename.update(r.rename)

        def generic(members=members, orders=orders) -> list[sp.Expr]:
            shapes = [templates.generic(r.shape) for r in members]
            if kind == "jac":
                return [g.jacobian[c] for g, order in zip(shapes, orders) for c in order]
            return [getattr(g, kind) for g in shapes]

        out.append(Group(key, generic, rename))
    return tuple(out)


def _real(rows: list[Row], kind: str) -> list[sp.Expr]:
    if kind == "jac":
        return [e for r in rows for _, e in sorted(r.jacobian.items())]
    return [getattr(r, kind) for r in rows]


def _acceleration_symbols(coords: Coordinates) -> tuple[sp.Symbol, ...]:
    """``dv_<body>_<coordinate>``: the time derivatives of the velocity coordinates."""
    return tuple(sp.Symbol("d" + str(s), real=True) for s in coords.velocity_symbols)


def _frame_groups(coords: Coordinates, tangent: bool = False) -> tuple[Group, ...]:
    """One group per body, all of one shape: the generic body's frame, renamed. With
    ``tangent``: the change of those FRAME_VALUES values when q moves along w, v by y and a by z (the
    ``frames_d`` kernel, to carry the state's sensitivities to frames and points)."""
    param = coords.parametrization
    generic = generic_body(param)
    q = sp.Matrix(generic.stored)
    v = sp.Matrix(generic.velocity)
    a = sp.Matrix([sp.Symbol("d" + str(s), real=True) for s in generic.velocity])
    directions = [_direction_symbols(tuple(generic.velocity), letter) for letter in "wyz"] if tangent else []
    generic_symbols = [*q, *v, *a, *(s for d in directions for s in d)]

    def expressions() -> list[sp.Expr]:
        values = param.frame_expressions(q, v, a)
        # A(s) -> the symbols a_ij, and an origin that is not stored -> its symbols
        values = [e.xreplace(dict(zip(generic.frame_values, generic.frame_symbols))) for e in values]
        if not tangent:
            return values
        w, y, z = directions
        return [
            along(e, [generic], [w]) + sum((e.diff(s) * d for s, d in zip([*v, *a], [*y, *z]) if s in e.free_symbols), sp.Integer(0))
            for e in values
        ]

    groups = []
    for body in coords.bodies:
        velocity = tuple(body.velocity)
        real = [*body.stored, *velocity, *(sp.Symbol("d" + str(s), real=True) for s in velocity)]
        if tangent:
            real += [s for letter in "wyz" for s in _direction_symbols(velocity, letter)]
        rename = dict(zip(generic_symbols, real))
        rename.update(zip(generic.frame_symbols, body.frame_symbols))
        groups.append(Group(("frames_d" if tangent else "frames", param.name), expressions, rename))
    return tuple(groups)


def plan(rows: tuple[int, ...], cols: tuple[int, ...], shape: tuple[int, int]) -> Plan | None:
    """The block-triangular plan of a pattern, or None (not square, structurally singular)."""
    blocks = block_triangular(shape, np.array(rows, dtype=np.intp), np.array(cols, dtype=np.intp))
    if blocks is None:
        return None
    starts = np.cumsum([0] + [b.size for b in blocks])
    return Plan(
        tuple(r for b in blocks for r in b.rows), tuple(c for b in blocks for c in b.cols), tuple(int(s) for s in starts)
    )


def initial_q(model: Model, parametrization: Parametrization) -> np.ndarray:
    """Stored coordinates of the model's initial pose in ``parametrization`` (design parameters
    at their nominal values)."""
    nominal = _nominal(model)
    return np.concatenate(
        [
            parametrization.from_pose(
                [float(sp.N(x.xreplace(nominal), 30)) for x in body.position],
                np.array(body.rotation.xreplace(nominal).evalf(30), dtype=float),
            )
            for body in model.bodies
        ]
    )


def _nominal(model: Model) -> dict[sp.Symbol, sp.Expr]:
    return {d.symbol: d.nominal for d in model.design}


def _direction_symbols(symbols: tuple[sp.Symbol, ...], letter: str) -> tuple[sp.Symbol, ...]:
    """``v_<body>_<c>`` -> ``<letter>_<body>_<c>``: a change of those velocity coordinates."""
    return tuple(sp.Symbol(letter + str(s)[1:], real=True) for s in symbols)


class _Sensitivities:
    """The rows' parts of the sensitivity kernels, derived in SymEngine: each row's expressions are
    converted once, and the entries stay SymEngine's (the CSE takes them so, their symbols by name
    in ``symbols``). A row is derived once per content (its name and equation): a driver at the
    same place in several cases is the same row, with the same input symbols."""

    def __init__(self, coords: Coordinates, design: tuple[sp.Symbol, ...]) -> None:
        self.coords = coords
        self._bridge = engine.Bridge()
        to = self._bridge.to
        self._v = [to(s) for s in coords.velocity_symbols]
        self._a = [to(s) for s in _acceleration_symbols(coords)]
        self._design = [to(s) for s in design]
        self._tangents: dict[str, list] = {}
        self._rows: dict[tuple, tuple[list, list]] = {}
        self._by_column = {c: k for k, body in enumerate(coords.bodies)
                           for c in range(body.velocity_offset, body.velocity_offset + len(body.velocity))}  # fmt: skip

    @property
    def symbols(self) -> dict[str, sp.Symbol]:
        """The symbols of every entry made so far, by name."""
        return self._bridge.names

    def design_derivatives(self, rows: list[Row]) -> list[list[tuple[int, se.Basic]]]:
        """Phi_p of ``rows``: per row the (parameter, dPhi/dp) of every entry not identically zero."""
        return [self._by_design(self._bridge.to(row.phi)) for row in rows]

    def rows(self, rows: list[Row]) -> tuple[list, list]:
        """(dvel, dacc) of ``rows`` (:meth:`_derive`), each row's derived once."""
        for row in rows:
            key = (row.name, row.phi, row.is_driver)
            if key not in self._rows:
                self._rows[key] = self._derive(row)
        done = [self._rows[r.name, r.phi, r.is_driver] for r in rows]
        return [d for d, _ in done], [a for _, a in done]

    def _by_design(self, expr: se.Basic) -> list[tuple[int, se.Basic]]:
        """(parameter, d expr/dp) for every design parameter ``expr`` depends on, derivative not
        identically zero. Rows hold the design parameters explicitly (the frame symbols do not
        depend on them), so this is one derivative per parameter a row uses."""
        free = expr.free_symbols
        return [(k, d) for k, p in enumerate(self._design) if p in free for d in [expr.diff(p)] if d != 0]

    def _tangent(self, expr: se.Basic, bodies: list) -> dict[int, se.Basic]:
        """:func:`kinegen.symbolic.assembly.tangent_jacobian` in SymEngine."""
        out = {}
        derivatives: dict[se.Basic, se.Basic] = {}  # d expr/ds, once per symbol: it enters several directions

        def derivative(s: se.Basic) -> se.Basic:
            if s not in derivatives:
                derivatives[s] = expr.diff(s)
            return derivatives[s]

        for body in bodies:
            if body.name not in self._tangents:
                to = self._bridge.to
                self._tangents[body.name] = [[(to(s), to(d)) for s, d in pairs] for pairs in body.tangents]
            for k, pairs in enumerate(self._tangents[body.name]):
                total = se.Add(*(derivative(s) * d for s, d in pairs))
                if total != 0:
                    out[body.velocity_offset + k] = total
        return out

    def _derive(self, row: Row) -> tuple[list, list]:
        """What the runtime needs to differentiate the velocity and acceleration solves by the
        design parameters, for one row, as sparse matrix rows. With Phi(q(p), u, p) = 0 solved, a
        parameter moves the configuration along S = dq/dp, the velocities by V and the
        accelerations by W; differentiating Phi_q v = nu and Phi_q a = gamma gives
        Phi_q V = -(M_v S + E_v) and Phi_q W = -(M_a S + N_a V + E_a), with
        M_v = D_q(Phi_q v - nu), E_v = d(Phi_q v - nu)/dp, M_a = D_q(Phi_q a - gamma),
        N_a = d(Phi_q a - gamma)/dv, E_a = d(Phi_q a - gamma)/dp (D_q: the derivatives along the
        velocity coordinates' tangent directions, as for Phi_q).

        Returns (dvel, dacc): the (column, expression) entries of [M_v | E_v] (columns
        0..n_v-1 the coordinates, then the parameters) and of [M_a | N_a | E_a] (n_v coordinate,
        n_v velocity, then the parameter columns)."""
        to, v, a, n = self._bridge.to, self._v, self._a, len(self._v)
        columns = row.jacobian_columns
        bodies = [self.coords.bodies[k] for k in dict.fromkeys(self._by_column[c] for c in columns)]
        jacobian = {c: to(row.jacobian[c]) for c in columns}
        velocity = se.Add(*(jacobian[c] * v[c] for c in columns)) - to(row.nu)
        acceleration = se.Add(*(jacobian[c] * a[c] for c in columns)) - to(row.gamma)
        # every velocity coordinate of the row's bodies: gamma may hold one whose Phi_q entry is zero
        # (a point row's y component has no theta_y column, its gamma has omega_y^2)
        velocities = [c for b in bodies for c in range(b.velocity_offset, b.velocity_offset + len(b.velocity))]
        if row.is_driver:
            m_v = self._tangent(velocity, bodies)
            n_a = {c: d for c in velocities for d in [acceleration.diff(v[c])] if d != 0}
        else:
            m_v, n_a = self._joint_rates(jacobian, velocities, bodies)
        dvel = [*sorted(m_v.items()), *((n + k, d) for k, d in self._by_design(velocity))]
        dacc = [
            *sorted(self._tangent(acceleration, bodies).items()), *((n + c, d) for c, d in sorted(n_a.items())),
            *((2 * n + k, d) for k, d in self._by_design(acceleration)),
        ]  # fmt: skip
        return dvel, dacc

    def _joint_rates(self, jacobian: dict[int, se.Basic], velocities: list[int], bodies: list) -> tuple[dict, dict]:
        """M_v = D_q(Phi_q v) and N_a = d(Phi_q a - gamma)/dv of a row without time dependence (a joint
        or a normalization), whose gamma is exactly -D_q(Phi_q v) v: from the second derivatives
        H[c][k] = D_k(Phi_q[c]) (one tangent derivative of each Jacobian entry), M_v[k] = sum_c H[c][k] v_c
        and, as Phi_q a - gamma = Phi_q a + sum_ck H[c][k] v_c v_k, N_a[j] = sum_k H[j][k] v_k + sum_c H[c][j] v_c.
        Cheaper than differentiating gamma by every velocity coordinate (a third of the derivation)."""
        v = self._v
        second = {c: self._tangent(e, bodies) for c, e in jacobian.items()}
        m_v = {k: total for k in velocities for total in [se.Add(*(h[k] * v[c] for c, h in second.items() if k in h))] if total != 0}
        n_a = {}
        for j in velocities:
            total = se.Add(*(e * v[k] for k, e in second.get(j, {}).items()), *(h[j] * v[c] for c, h in second.items() if j in h))
            if total != 0:
                n_a[j] = total
        return m_v, n_a


class _Derived:
    """The sensitivity kernels' entries derived in this process: :meth:`result` gives them (and no texts)."""

    def __init__(self, entries: tuple) -> None:
        self._entries = entries

    def result(self) -> tuple:
        return self._entries, {}, {}


def _derive_sensitivities(derived: _Sensitivities, joints: list[Row], systems: dict[str, System], printers: tuple):
    """The sensitivity kernels' entries (:func:`_sensitivity_entries`): an object whose ``result()``
    gives (entries, texts, naming). Where this process may fork (:func:`kinegen.codegen.forked.may_fork`)
    and ``printers`` are given, a forked process derives them, eliminates and prints their groups with
    those printers (:func:`_printed_sensitivities`), and sends back the texts and each entry's column
    alone; else they are derived here, their values in the entries, no texts. The same bytes either way:
    each process derives and eliminates them by the same steps (SymEngine keeps no state between
    expressions); only text travels (SymEngine's terms, unpickled, could come in another order)."""
    from kinegen.codegen.forked import Child, may_fork

    if printers and may_fork():
        return Child(_printed_sensitivities, derived, joints, systems, printers)
    return _Derived(_sensitivity_entries(derived, joints, systems))


def _sensitivity_entries(derived: _Sensitivities, joints: list[Row], systems: dict[str, System]) -> tuple:
    """(the joint rows' entries by kind, each case's driver rows' entries by kind, the entries'
    symbols by name): per kind of :data:`SENSITIVITY_SECTIONS`, per row the (column, value) of
    every entry not identically zero, the joint rows first, then each case's drivers in turn."""
    joint = {"phi_p": derived.design_derivatives(joints)}
    joint["dvel"], joint["dacc"] = derived.rows(joints)
    drivers: dict[str, dict[str, list]] = {}
    for name, system in systems.items():
        rows = system.rows[len(joints) :]
        drivers[name] = {"phi_p": derived.design_derivatives(rows)}
        drivers[name]["dvel"], drivers[name]["dacc"] = derived.rows(rows)
    return joint, drivers, derived.symbols


def _printed_sensitivities(derived: _Sensitivities, joints: list[Row], systems: dict[str, System], printers: tuple) -> tuple:
    """In the forked process: the entries derived, every group of theirs eliminated and printed by
    ``printers`` (as :meth:`Shapes.prepare` would), and (the entries with their columns alone -- values
    None --, the texts, their naming) sent back."""
    entries = _sensitivity_entries(derived, joints, systems)
    shapes = Shapes()
    groups = [g for *_, gs, _ in _sensitivity_groups(entries, joints, systems) for g in gs]
    texts, naming = shapes.printed_texts(shapes.unprinted([(printer, group) for group in groups for printer in printers]))
    joint, drivers, _ = entries
    columns = ({k: _columns(v) for k, v in joint.items()}, {n: {k: _columns(v) for k, v in d.items()} for n, d in drivers.items()}, {})
    return columns, texts, naming


def _columns(entries: list[list[tuple[int, se.Basic]]]) -> list[list[tuple[int, None]]]:
    """The entries' columns alone (values None)."""
    return [[(c, None) for c, _ in row] for row in entries]


def _sensitivity_groups(entries: tuple, joints: list[Row], systems: dict[str, System], derive=None):
    """(kind, case -- None for the joint rows --, section name, groups, that section's entries) of every
    sensitivity section, in order: the joint rows' by kind, then each case's drivers' by kind.
    ``derive``: where the entries hold only their columns, a function giving the entries themselves
    (called only if a group's expressions are asked for in this process)."""
    joint, drivers, symbols = entries
    mj = len(joints)
    out = []
    for kind, _, _ in SENSITIVITY_SECTIONS:
        whole = None if derive is None else (lambda kind=kind: derive()[0][kind])
        out.append((kind, None, f"joints_{kind}", _entry_groups(joints, joint[kind], (f"joints_{kind}",), symbols, whole), joint[kind]))
    for case, system in systems.items():
        for kind, _, _ in SENSITIVITY_SECTIONS:
            whole = None if derive is None else (lambda case=case, kind=kind: derive()[1][case][kind])
            own = drivers[case][kind]
            groups = _entry_groups(system.rows[mj:], own, (f"drivers_{kind}",), symbols, whole)
            out.append((kind, case, f"drivers_{kind}_{case}", groups, own))
    return out


def _sensitivity_sections(
    entries: tuple, joints: list[Row], systems: dict[str, System], section, cases: dict[str, CaseDescription], derive=None
) -> None:  # fmt: skip
    """The sensitivity kernels' sections (``section``: the joint rows', then each case's drivers'), and
    each case's kernels and patterns, from their ``entries`` (:func:`_sensitivity_entries`; ``derive``
    as :func:`_sensitivity_groups` takes it)."""
    described = {kind: (slots, doc) for kind, slots, doc in SENSITIVITY_SECTIONS}
    joint = entries[0]
    for kind, case, name, groups, own in _sensitivity_groups(entries, joints, systems, derive):
        slots, doc = described[kind]
        size = sum(map(len, own))
        if case is None:
            section(name, (*(s for s in slots if s not in ("u", "ud", "udd")), "p"), groups, size, f"{doc} of the joint rows ({size} entries).")
            continue
        section(name, (*slots, "p"), groups, size, f"{doc} of the driver rows of case {case!r}.")
        entries_pattern = _pattern(joint[kind]) + _pattern(own, len(joints))
        cases[case].patterns[kind] = (tuple(i for i, _ in entries_pattern), tuple(j for _, j in entries_pattern))
        cases[case].kernels[kind] = Kernel(kind, (*slots, "p"), (Output(kind, (f"joints_{kind}", name), len(entries_pattern)),),
                                           f"{SENSITIVITY_KERNELS[kind]} of case {case!r}: values at {kind}_rows, {kind}_cols.")  # fmt: skip


def _entry_groups(
    rows: list[Row], entries: list[list[tuple[int, se.Basic]]], key: tuple, symbols: dict[str, sp.Symbol], derive=None
) -> tuple[Group, ...]:  # fmt: skip
    """The entries of ``rows`` in groups of one joint, driver or normalization each (sharing
    their subexpressions), keyed ``key + (the rows' names and equations,)``: eliminated once for
    every backend and every case. ``derive``: where ``entries`` hold their columns alone (values None),
    a function giving the entries themselves, called only when a group's expressions are asked for."""
    groups: list[Group] = []
    for start, end in _runs(rows):
        if any(entries[start:end]):  # keyed by content: the same driver in several cases is eliminated and printed once
            content = tuple((row.name, row.phi) for row in rows[start:end])
            source = entries if derive is None else None
            groups.append(Group((*key, content), lambda start=start, end=end, source=source: [
                e for row in (derive() if source is None else source)[start:end] for _, e in row], {}, symbols))  # fmt: skip
    return tuple(groups)


def _pattern(entries: list[list[tuple[int, sp.Expr]]], first_row: int = 0) -> list[tuple[int, int]]:
    """(row, column) of every entry, row-major, rows counted from ``first_row``."""
    return [(first_row + i, c) for i, row in enumerate(entries) for c, _ in row]


def _constant(values: list[sp.Expr]):
    """A group's expressions, already derived."""
    return lambda: values


def _statics(
    model: Model, coords: Coordinates, joint_pattern: list[tuple[int, int]], joint_names: list[str], p: tuple[str, ...], section,
    shared: dict,
) -> StaticsDescription | None:  # fmt: skip
    """The ``actuation``, ``loads`` and ``inertia`` kernels (sections made with ``section``, kernels put
    into ``shared``) and their description; None for a model with neither elements, loads nor masses.
    ``joint_pattern``: the joint rows' Phi_q pattern (the first values of every case's); ``joint_names``
    the joint rows' names."""
    from kinegen.symbolic.statics import element_rows, inertia_row, load_row

    if not model.actuation and not model.loads and not model.massive:
        return None
    mj = len(joint_names)
    elements = element_rows(model, coords)
    matrix = [*joint_pattern, *((mj + i, c) for i, (_, _, row) in enumerate(elements) for c in row)]
    matrix_plan = None
    if elements:
        size = sum(len(row) for _, _, row in elements)
        values = [e for _, _, row in elements for e in row.values()]
        section("actuation_rows", ("q", *p), (Group(None, _constant(values), {}),), size,
                f"The rows of the {len(elements)} actuation elements: d(length or angle)/dv, {size} values.")  # fmt: skip
        shared["actuation"] = Kernel("actuation", ("q", *p), (Output("actuation_matrix", ("joints_jac", "actuation_rows"), len(matrix)),),
                                     "The force solve's matrix: the joint rows' Phi_q values, then the actuation elements' rows, "
                                     "at ACTUATION_ROWS, ACTUATION_COLS.")  # fmt: skip
        matrix_plan = plan(tuple(r for r, _ in matrix), tuple(c for _, c in matrix), (mj + len(elements), len(coords.velocity_symbols)))
    loads = [(name, load_row(load, coords)) for name, load in model.loads.items()]
    load_pattern = [(k, c) for k, (_, row) in enumerate(loads) for c in row]
    if loads:
        section("loads", ("q", "t", *p), (Group(None, _constant([e for _, row in loads for e in row.values()]), {}),), len(load_pattern),
                f"Every load's generalized force Q (F.J_P + M.T_w), {len(load_pattern)} values at LOAD_ROWS, LOAD_COLS.")  # fmt: skip
        shared["loads"] = Kernel("loads", ("q", "t", *p), (Output("loads", ("loads",), len(load_pattern)),),
                                 "Every load's generalized force Q at time t, at LOAD_ROWS (the load), LOAD_COLS.")  # fmt: skip
    per_body = inertia_row(model, coords) if model.massive else []  # a body's columns are its own: in order
    inertia = {c: e for row in per_body for c, e in row.items()}
    if inertia:
        groups = tuple(Group(None, _constant(list(row.values())), {}) for row in per_body if row)
        section("inertia", ("q", "v", "a", *p), groups, len(inertia),
                f"The generalized force of gravity and of the {len(model.massive)} massive bodies' inertia (d'Alembert), "
                f"{len(inertia)} values at INERTIA_COLS.")  # fmt: skip
        shared["inertia"] = Kernel("inertia", ("q", "v", "a", *p), (Output("inertia", ("inertia",), len(inertia)),),
                                   "The generalized force of gravity and the bodies' inertia at (q, v, a), at INERTIA_COLS.")  # fmt: skip
    return StaticsDescription(
        tuple((name, kind) for name, kind, _ in elements), tuple(r for r, _ in matrix) if elements else (),
        tuple(c for _, c in matrix) if elements else (), matrix_plan, tuple(name for name, _ in loads),
        tuple(r for r, _ in load_pattern), tuple(c for _, c in load_pattern), tuple(load.fingerprint for load in model.loads.values()),
        tuple(inertia), *_reaction_tables(model, coords, joint_names, [name for name, _, _ in elements]),
        _parallel_table(model, [name for name, _, _ in elements]),
    )  # fmt: skip


def _parallel_table(model: Model, elements: list[str]) -> tuple[tuple[str, int, int], ...]:
    """:class:`StaticsDescription`'s ``parallel``: each cylinder parallel to an element."""
    index = [a.name for a in model.actuators]
    return tuple((a.name, elements.index(a.parallel), index.index(a.name)) for a in model.actuators if a.parallel in elements)


def _reaction_tables(model: Model, coords: Coordinates, joint_names: list[str], elements: list[str]) -> tuple[tuple, tuple, tuple]:
    """:class:`StaticsDescription`'s ``joints``, ``norm_rows`` and ``hydraulics`` (numbers at the
    nominal design)."""
    nominal = {d.name: float(d.nominal) for d in model.design}
    index = {b.name: i for i, b in enumerate(coords.bodies)}
    rows: dict[str, list[int]] = {}
    norms: dict[str, list[int]] = {b.name: [] for b in coords.bodies}
    for i, name in enumerate(joint_names):
        owner, normalization = row_owner(name)
        (norms[owner] if normalization else rows.setdefault(owner, [])).append(i)
    joints = []
    for joint in model.joints:
        body, sign = (joint.body2, 1) if joint.body2 != GROUND else (joint.body1, -1)
        local = tuple(float(design_value(x, nominal)) for x in (joint.point2 if joint.point2 is not None else (0, 0, 0)))
        joints.append((joint.name, index[body], sign, -1 if joint.body2 == GROUND else index[joint.body2], local, tuple(rows.get(joint.name, ()))))
    actuators = {a.name: (i, a) for i, a in enumerate(model.actuators)}
    hydraulics = []
    for name in elements:
        if name not in actuators or actuators[name][1].hydraulics is None:
            hydraulics.append((float("nan"),) * 6 + (-1,))
            continue
        k, actuator = actuators[name]
        h = actuator.hydraulics
        settings = [design_value(x, nominal) for x in (*h.relief, *h.holding)]
        hydraulics.append((*(float(a) for a in h.areas(nominal)), *settings, k))
    return tuple(joints), tuple(tuple(norms[b.name]) for b in coords.bodies), tuple(hydraulics)


def point_expressions(model: Model) -> list[sp.Expr]:
    """Every named point's coordinates, flattened: the bodies' (body coordinates) in the order
    of ``POINTS``, then the ground's (global) -- what the ``points`` kernel of a model with
    design parameters computes from ``p``."""
    values = [x for body in model.bodies for point in body.points.values() for x in point]
    return values + [x for point in model.ground_points.values() for x in point]


def actuator_lengths(model: Model, coords: Coordinates) -> list[sp.Expr]:
    """Every actuator's length as an expression of its bodies' stored and frame symbols."""
    frames = {b.name: b.frame for b in coords.bodies}
    out = []
    for actuator in model.actuators:
        ends = [GROUND_FRAME.point(ref.local) if ref.body == GROUND else frames[ref.body].point(ref.local) for ref in actuator.points]
        gap = ends[0] - ends[1]
        out.append(sp.sqrt(sum((x * x for x in gap), sp.Integer(0))))
    return out


def _max(values: list[sp.Expr]) -> sp.Expr:
    """The largest of ``values`` (none: 0) in the functions the printers know: max(a, b) = (a + b + |a - b|)/2."""
    out = values[0] if values else sp.Integer(0)
    for value in values[1:]:
        out = (out + value + _abs(out - value)) / 2
    return out


def _abs(x: sp.Expr) -> sp.Abs:
    """|x|, not evaluated: SymPy's sign analysis of a large expression costs more than the rest of the row."""
    return sp.Abs(x, evaluate=False)


def _sign(x: sp.Expr) -> sp.sign:
    """sign(x), not evaluated (as :func:`_abs`)."""
    return sp.sign(x, evaluate=False)


def supply_expressions(model: Model, coords: Coordinates, forces: tuple[sp.Symbol, ...]) -> dict[str, list[sp.Expr]]:
    """The pumps' flows, pressures and powers as expressions of q, v, the actuation elements' forces
    ``forces`` (in the order of ``model.actuation``) and the design parameters
    (:mod:`kinegen.forces.supply`'s conventions: a cylinder's flow is its cap area times its rate
    extending, its annulus times the rate retracting; a motor's, its displacement times the turn rate;
    an element fed by several pumps takes equal shares; a pump delivers at the highest filling
    pressure of what it feeds, its power that pressure times its flow); and their limits (each pump's
    largest flow, then the engine's power)."""
    supply = model.supply
    bodies = {b.name: b for b in coords.bodies}
    frames = {b.name: b.frame for b in coords.bodies}
    names = [e.name for e in model.actuation]
    actuators, motors = {a.name: a for a in model.actuators}, {m.name: m for m in model.motors}
    generic = generic_body(coords.parametrization)

    def moving(refs) -> list:
        return [bodies[r] for r in dict.fromkeys(refs) if r != GROUND]

    def omega(body: str) -> sp.Matrix:
        """A body's angular velocity (global) in its symbols."""
        if body == GROUND:
            return sp.zeros(3, 1)
        b = bodies[body]
        values = coords.parametrization.frame_expressions(sp.Matrix(generic.stored), sp.Matrix(generic.velocity), sp.zeros(len(generic.velocity), 1))
        values = [e.xreplace(dict(zip(generic.frame_values, generic.frame_symbols))) for e in values]
        rename = {**dict(zip(generic.stored, b.stored)), **dict(zip(generic.velocity, b.velocity)), **dict(zip(generic.frame_symbols, b.frame_symbols))}
        offset = sum(count for _, count in FRAME_FIELDS[: [n for n, _ in FRAME_FIELDS].index("angular_velocity")])
        return sp.Matrix([values[offset + k].xreplace(rename) for k in range(3)])

    flows, filling = {}, {}
    for name in supply.circuits:
        force = forces[names.index(name)]
        if name in actuators:
            hydraulics = actuators[name].hydraulics
            cap = hydraulics.cylinders * sp.pi / 4 * hydraulics.bore**2
            annulus = hydraulics.cylinders * sp.pi / 4 * (hydraulics.bore**2 - hydraulics.rod**2)
            rate = sp.Integer(0)
            for member in model.members(name):
                ends = [GROUND_FRAME.point(ref.local) if ref.body == GROUND else frames[ref.body].point(ref.local) for ref in member.points]
                gap = ends[0] - ends[1]
                length = sp.sqrt(sum((x * x for x in gap), sp.Integer(0)))
                rate += along(length, moving([ref.body for ref in member.points]))
            flows[name] = (cap + annulus) / 2 * _abs(rate) + (cap - annulus) / 2 * rate
            sign = _sign(rate)
            filling[name] = ((sign + _abs(sign)) / 2 * (force + _abs(force)) / (2 * cap)
                             + (_abs(sign) - sign) / 2 * (_abs(force) - force) / (2 * annulus))  # fmt: skip
        else:
            motor = motors[name]
            joint = next(j for j in model.joints if j.name == motor.joint)
            axis = sp.Matrix(joint.axis1)
            axis = axis / sp.sqrt(sum((x * x for x in axis), sp.Integer(0)))
            carried = axis if joint.body1 == GROUND else frames[joint.body1].A * axis
            rate = (carried.T * (omega(joint.body2) - omega(joint.body1)))[0]
            flows[name] = motor.displacement * _abs(rate)
            sign = _sign(rate)
            filling[name] = (force * sign + _abs(force) * _abs(sign)) / (2 * motor.displacement)
    pump_flows, pressures = [], []
    for pump in supply.pumps:
        fed = [name for name, pumps in supply.circuits.items() if pump.name in pumps]
        pump_flows.append(sum((flows[name] / len(supply.circuits[name]) for name in fed), sp.Integer(0)))
        pressures.append(_max([filling[name] for name in fed]))
    return {
        "pump_flows": pump_flows, "pump_pressures": pressures, "pump_powers": [p * q for p, q in zip(pressures, pump_flows)],
        "pump_limits": [*(pump.max_flow for pump in supply.pumps), supply.engine_power],
    }  # fmt: skip


@collector_paused()
def describe(
    model: Model, parametrization: Parametrization, systems: dict[str, System] | None = None, sensitivities: bool = True,
    forces: bool = True, printers: tuple[CodePrinter, ...] = (), meanwhile: Callable[[ModuleDescription], None] | None = None,
) -> ModuleDescription:  # fmt: skip
    """The kernel description of ``model`` (every case) in ``parametrization``. A model with
    design parameters gets the sensitivity kernels (:data:`SENSITIVITY_KERNELS`, ``frames_d``,
    ``points_p``) unless ``sensitivities`` is False: they are the largest part of such a build
    (second derivatives of gamma), and a module that only solves designs does not need them.
    ``forces`` False leaves out the force solve's and the supply's kernels (``statics`` None, no
    ``supply``): the kinematics alone, as the in-memory path (:mod:`kinegen.codegen.inmemory`) evaluates
    them (the excavator's description without sensitivities 0.44 -> 0.07 s, systems built).
    ``printers``: those that will print every section (the targets'); given, the sensitivity kernels'
    entries are derived, eliminated and printed by them in a forked process while this one describes
    the rest, where it may fork (:func:`_derive_sensitivities`): the same description and texts. Then
    ``meanwhile(description)`` is called while that process works, on the description whose
    sensitivity sections are still None (e.g. to print the other sections: :meth:`Shapes.prepare`).
    Python's garbage collector is paused meanwhile (:mod:`kinegen.collector`)."""
    systems = systems or build_systems(model, parametrization)
    first = next(iter(systems.values()))
    coords = first.coordinates
    templates = first.templates
    joints = [r for r in first.rows if not r.is_driver]
    mj = len(joints)
    sections: dict[str, Section] = {}

    shared: dict[str, Kernel] = {}  # kernels shared by every case, each computing one section

    def section(name: str, slots: tuple[str, ...], groups: tuple[Group, ...], size: int, doc: str) -> str:
        sections[name] = Section(name, slots, groups, size, doc)
        return name

    def shared_section(name: str, slots: tuple[str, ...], groups: tuple[Group, ...], size: int, doc: str) -> None:
        """A section every case shares, and the kernel computing it alone (its one output named as it)."""
        section(name, slots, groups, size, doc)
        shared[name] = Kernel(name, slots, (Output(name, (name,), size),), doc)

    n_joint_entries = sum(len(r.jacobian_columns) for r in joints)
    p = ("p",) if model.design else ()  # the design parameters' slot, last, in every kernel of Phi
    section("joints_phi", ("q", *p), _groups(joints, templates, "phi"), mj, f"Phi of the {mj} joint (and normalization) rows, common to every case.")
    section("joints_jac", ("q", *p), _groups(joints, templates, "jac"), n_joint_entries, f"Phi_q values of the joint rows ({n_joint_entries} entries).")
    section("joints_gamma", ("q", "v", *p), _groups(joints, templates, "gamma"), mj, "gamma of the joint rows (they do not depend on time).")
    design_symbols = tuple(d.symbol for d in model.design)
    sensitive = bool(model.design) and sensitivities
    # the sensitivity kernels' entries (a third of the excavator's description) are derived beside the rest,
    # in a forked process where this one may fork (_derive_sensitivities); their sections and kernels are
    # filled in once they are back, at the places held for them here (a dict keeps a key's place)
    pending = _derive_sensitivities(_Sensitivities(coords, design_symbols), joints, systems, printers) if sensitive else None
    if sensitive:  # the joint rows' parts of the sensitivity kernels, common to every case
        for kind, _, _ in SENSITIVITY_SECTIONS:
            sections[f"joints_{kind}"] = None
    shared_section(
        "frames", ("q", "v", "a"), _frame_groups(coords), FRAME_VALUES * len(coords.bodies),
        f"Per body {FRAME_VALUES} values, global: " + ", ".join(f"{name} ({count})" for name, count in FRAME_FIELDS)
        + "; the rotation matrix row by row.",
    )  # fmt: skip
    if model.actuators:
        shared_section("lengths", ("q", *p), (Group(None, lambda: actuator_lengths(model, coords), {}),), len(model.actuators),
                "The length of every actuator (in the order of ACTUATORS) [m]: the distance between its two points.")  # fmt: skip
    statics = _statics(model, coords, first.jacobian_pattern[:n_joint_entries], [r.name for r in joints], p, section, shared) if forces else None
    force_symbols: tuple[sp.Symbol, ...] = ()
    if forces and model.supply is not None:  # the pumps: flows (q, v), pressures and powers (with the elements' forces f), limits
        force_symbols = tuple(sp.Symbol(f"f_{e.name}", real=True) for e in model.actuation)
        supplied = supply_expressions(model, coords, force_symbols)
        docs = {
            "pump_flows": "Each pump's flow [m^3/s] (in the order of PUMPS): its shares of the elements it feeds.",
            "pump_pressures": "Each pump's pressure [Pa]: the highest filling pressure of the elements it feeds, from their forces f.",
            "pump_powers": "Each pump's power [W]: its pressure times its flow.",
            "pump_limits": "Each pump's largest flow [m^3/s], then the engine's power for them all [W].",
        }
        slots_supply = ("q", "v", "f", *p)
        for name, values in supplied.items():
            section(name, slots_supply, (Group(None, lambda values=values: values, {}),), len(values), docs[name])
        shared["supply"] = Kernel("supply", slots_supply, tuple(Output(name, (name,), len(values)) for name, values in supplied.items()),
                                  "The hydraulic supply along a motion: the pumps' flows, pressures, powers and limits "
                                  "(kinegen.forces.supply's conventions).")  # fmt: skip
    cases: dict[str, CaseDescription] = {}
    enclosures: dict[str, Enclosure] = {}
    for name, system in systems.items():
        rows = system.rows
        drivers = rows[mj:]
        inputs = system.inputs
        m, nd = len(rows), len(inputs.u)
        pattern = system.jacobian_pattern
        n_driver_entries = len(pattern) - n_joint_entries
        stacked = inputs.stacked()
        section(f"inputs_{name}", ("t",), (Group(None, lambda stacked=stacked: stacked, {}),), 3 * nd,
                f"Driver inputs of case {name!r} at time t: rows u ({nd}), then du/dt, then d2u/dt2.")  # fmt: skip
        enclosures[f"input_ranges_{name}"] = Enclosure(
            f"input_ranges_{name}", interval_program(stacked), 6 * nd,
            f"Enclosures of the driver inputs of case {name!r} over the time interval span = (t0, t1): the lower bounds "
            f"of u ({nd}), du/dt and d2u/dt2, then their upper bounds (interval arithmetic, rounded outward).",
        )  # fmt: skip
        section(f"drivers_phi_{name}", ("q", "u", *p), _groups(drivers, templates, "phi"), m - mj, f"Phi of the driver rows of case {name!r}.")
        section(f"drivers_jac_{name}", ("q", "u", *p), _groups(drivers, templates, "jac"), n_driver_entries,
                f"Phi_q values of the driver rows of case {name!r}.")  # fmt: skip
        section(f"drivers_nu_{name}", ("q", "u", "ud", *p), _groups(drivers, templates, "nu"), m - mj, f"nu of the driver rows of case {name!r}.")
        section(f"drivers_gamma_{name}", ("q", "v", "u", "ud", "udd", *p), _groups(drivers, templates, "gamma"), m - mj,
                f"gamma of the driver rows of case {name!r}.")  # fmt: skip
        kernels = {
            "phi_jac": Kernel(
                "phi_jac", ("q", "u", *p),
                (Output("phi", ("joints_phi", f"drivers_phi_{name}"), m), Output("jac", ("joints_jac", f"drivers_jac_{name}"), len(pattern))),
                f"Phi and the Phi_q values (at jac_rows, jac_cols) of case {name!r}.",
            ),
            "nu": Kernel("nu", ("q", "u", "ud", *p), (Output("nu", (Zeros(mj), f"drivers_nu_{name}"), m),),
                         f"nu = -Phi_t of case {name!r} (zero in the joint rows)."),
            "gamma": Kernel("gamma", ("q", "v", "u", "ud", "udd", *p), (Output("gamma", ("joints_gamma", f"drivers_gamma_{name}"), m),),
                            f"gamma = -(Phi_q v)_q v - 2 Phi_qt v - Phi_tt of case {name!r}."),
            "inputs": Kernel("inputs", ("t",), (Output("inputs", (f"inputs_{name}",), 3 * nd),),
                             f"Driver inputs of case {name!r} at time t: u, then du/dt, then d2u/dt2."),
            "input_ranges": Kernel("input_ranges", ("span",), (Output("input_ranges", (f"input_ranges_{name}",), 6 * nd),),
                                   f"Enclosures of the driver inputs of case {name!r} over span = (t0, t1): the lower bounds of "
                                   "u, du/dt, d2u/dt2, then their upper bounds."),
        }  # fmt: skip
        patterns: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] = {}
        if sensitive:  # (filled in below)
            for kind, _, _ in SENSITIVITY_SECTIONS:
                sections[f"drivers_{kind}_{name}"] = None
                kernels[kind] = None
        rows_, cols_ = tuple(i for i, _ in pattern), tuple(j for _, j in pattern)
        case = system.case
        cases[name] = CaseDescription(
            name, float(case.t0), float(case.t1), case.steps, tuple(r.name for r in rows), tuple(inputs.names),
            tuple(inputs.sources), rows_, cols_, {"u": tuple(inputs.u), "ud": tuple(inputs.ud), "udd": tuple(inputs.udd)},
            kernels, plan(rows_, cols_, (m, len(coords.velocity_symbols))), patterns,
        )  # fmt: skip
    slots = {"t": (T,), "q": tuple(coords.stored_symbols), "v": tuple(coords.velocity_symbols), "a": _acceleration_symbols(coords)}
    if force_symbols:
        slots["f"] = force_symbols
    if model.design:
        values = point_expressions(model)
        shared_section("points", ("p",), (Group(None, lambda: values, {}),), len(values),
                "Every named point's coordinates from the design parameters: the bodies' (body coordinates, in the "
                "order of POINTS), then the ground's (global, GROUND_POINTS).")  # fmt: skip
        bounds = [x for a in model.actuators if a.range is not None for x in a.range]
        shared_section("actuator_ranges", ("p",), (Group(None, lambda: bounds, {}),), len(bounds),
                "The ranges of the actuators that have one (in the order of ACTUATORS), min then max, from the design parameters.")  # fmt: skip
        slots["p"] = tuple(d.symbol for d in model.design)
    if sensitive:
        derivatives = [v.diff(p) for v in values for p in design_symbols]
        shared_section("points_p", ("p",), (Group(None, lambda: derivatives, {}),), len(derivatives),
                "d(point coordinate)/d(design parameter), row-major (coordinate by coordinate as in points(p), "
                "a parameter per column).")  # fmt: skip
        for letter in "wyz":
            slots[letter] = _direction_symbols(tuple(coords.velocity_symbols), letter)
        shared_section("frames_d", ("q", "v", "a", "w", "y", "z"), _frame_groups(coords, tangent=True), FRAME_VALUES * len(coords.bodies),
                f"Per body: the change of the frames kernel's {FRAME_VALUES} values when q moves along w, v by y and a by z.")  # fmt: skip
    nominal = _nominal(model)
    nominal_values = {d.name: float(d.nominal) for d in model.design}
    definitions = Definitions(
        tuple((b.name, tuple(b.frame_symbols), tuple(b.frame_values)) for b in coords.bodies), tuple(generic_body(parametrization).frame_values)
    )
    description = ModuleDescription(
        model=model.name,
        source=Path(model.file).name,
        sha256=model.source_sha256,
        parametrization=parametrization,
        version=kinegen.__version__,
        stored_names=tuple(coords.stored_names),
        velocity_names=tuple(coords.velocity_names),
        bodies=tuple((b.name, b.stored_offset, b.velocity_offset) for b in coords.bodies),
        points={b.name: {k: tuple(float(sp.N(x.xreplace(nominal), 30)) for x in v) for k, v in b.points.items()} for b in model.bodies},
        ground_points={k: tuple(float(sp.N(x.xreplace(nominal), 30)) for x in v) for k, v in model.ground_points.items()},
        actuators=tuple(
            (a.name, (a.points[0].body, a.points[0].name), (a.points[1].body, a.points[1].name), a.limits(nominal_values))
            for a in model.actuators
        ),
        initial_q=tuple(float(x) for x in initial_q(model, parametrization)),
        slots=slots,
        definitions=definitions,
        sections=sections,
        cases=cases,
        kernels=shared,
        design=tuple((d.name, float(d.nominal), float(d.lower), float(d.upper)) for d in model.design),
        sensitivities=sensitive,
        statics=statics,
        enclosures=enclosures,
        pumps=tuple(pump.name for pump in model.supply.pumps) if forces and model.supply is not None else (),
    )
    if sensitive:
        if meanwhile is not None and not isinstance(pending, _Derived):
            meanwhile(description)  # (its sensitivity sections None: still being derived)
        entries, texts, naming = pending.result()
        derive = None
        if texts:  # printed in the forked process: the values themselves only if another printer asks for them here
            symbols: dict[str, sp.Symbol] = {}

            @cache
            def derive() -> tuple:
                derived = _sensitivity_entries(_Sensitivities(coords, design_symbols), joints, systems)
                symbols.update(derived[2])
                return derived

            entries = (*entries[:2], symbols)
            description.shapes.adopt(texts, naming)
        _sensitivity_sections(entries, joints, systems, section, cases, derive)
    return description
