"""A numeric system: one case of a generated module (or of the in-memory lambdify path).

This is the *model* in the Pinocchio sense: immutable description plus the compiled
functions. Solvers and results (the *data*) take it as an argument.
"""

from __future__ import annotations

import hashlib
import sys
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from kinegen import rotations
from kinegen.errors import GeneratedModuleError, KinegenError, ModelError, shown
from kinegen.interface import FRAME_FIELDS, SENSITIVITY_KERNELS, frame_slices
from kinegen.runtime.linear import Pattern


@dataclass(frozen=True)
class StaticsKernels:
    """A module's force-solve kernels (``kinegen.codegen.kernels.StaticsDescription``), p bound:
    ``matrix`` (q) -> the joint rows' Phi_q values, then the actuation elements' rows, at
    (``matrix_rows``, ``matrix_cols``) (None: the model declares no elements, each case's drivers
    carry the load); ``loads`` (q, t) -> every load's Q at (``load_rows`` = its index in
    ``load_names``, ``load_cols``) (None: no loads). Both take one configuration or a batch
    (q (n_q, K), t (K,))."""

    elements: tuple[tuple[str, str], ...]
    matrix: Callable[..., np.ndarray] | None
    matrix_rows: np.ndarray
    matrix_cols: np.ndarray
    load_names: tuple[str, ...]
    loads: Callable[..., np.ndarray] | None
    load_rows: np.ndarray
    load_cols: np.ndarray
    #: each load's content (:attr:`kinegen.model.schema.Load.fingerprint`) as the module was built
    load_keys: tuple[str, ...] = ()
    #: (q, v, a) -> the generalized force of gravity and the bodies' inertia at ``inertia_cols``
    #: (None: a model without masses)
    inertia: Callable[..., np.ndarray] | None = None
    inertia_cols: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))

    def serves(self, load: Any) -> bool:
        """Whether the ``loads`` kernel computes this load (:class:`~kinegen.model.schema.Load`): the
        module was built with it, by name and content."""
        return load.name in self.load_names and self.load_keys[self.load_names.index(load.name)] == load.fingerprint


def _statics(module: ModuleType | Any, p: np.ndarray | None) -> StaticsKernels | None:
    if not hasattr(module, "ELEMENTS"):
        return None

    def function(name: str) -> Callable[..., np.ndarray] | None:
        f = getattr(module, name, None)
        return f if f is None or p is None else _with_design(f, p)

    index = np.intp
    return StaticsKernels(
        tuple(tuple(e) for e in module.ELEMENTS), function("actuation_matrix") if module.ELEMENTS else None,
        np.array(module.ACTUATION_ROWS, dtype=index), np.array(module.ACTUATION_COLS, dtype=index), tuple(module.LOADS),
        function("loads") if module.LOADS else None, np.array(module.LOAD_ROWS, dtype=index), np.array(module.LOAD_COLS, dtype=index),
        tuple(module.LOAD_KEYS), function("inertia") if module.INERTIA_COLS else None, np.array(module.INERTIA_COLS, dtype=index),
    )  # fmt: skip


#: The names kinegen.rotations gives a body's velocity coordinates that translate it: x, y, z of every
#: parametrization that stores the origin, vx, vy, vz of a dual quaternion's twist (``<body>.<name>``). The
#: certificate's quarter-turn cap leaves them out (:attr:`NumericSystem.turning`; kinegen_solver.c's
#: ``translation`` reads the same names).
TRANSLATIONS = ("x", "y", "z", "vx", "vy", "vz")


@dataclass(frozen=True)
class NumericSystem:
    """Compiled kinematics of one case: Phi, sparse Phi_q values, nu, gamma and metadata."""

    model: str
    case: str
    parametrization: rotations.Parametrization
    stored_names: tuple[str, ...]
    velocity_names: tuple[str, ...]
    constraint_names: tuple[str, ...]
    driver_names: tuple[str, ...]
    bodies: dict[str, tuple[int, int]]
    points: dict[str, dict[str, tuple[float, float, float]]]
    initial_q: np.ndarray
    jac_rows: np.ndarray
    jac_cols: np.ndarray
    inputs: Callable[[Any], np.ndarray]  #: t -> rows [u; du/dt; d2u/dt2]
    phi: Callable[[np.ndarray, np.ndarray], np.ndarray]  #: (q, u)
    jac: Callable[[np.ndarray, np.ndarray], np.ndarray]  #: (q, u) -> values at (jac_rows, jac_cols)
    nu: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]  #: (q, u, ud)
    gamma: Callable[..., np.ndarray]  #: (q, v, u, ud, udd)
    t0: float
    t1: float
    steps: int
    source_sha256: str = ""
    #: reported lengths: name -> ((body, point), (body, point), (min, max) or None)
    actuators: dict[str, tuple] = field(default_factory=dict)
    #: the same functions as plain-float code for one configuration (lists in, lists out):
    #: (q, u) -> (Phi, Phi_q values), (q, u, ud) -> nu, (q, v, u, ud, udd) -> gamma; None if absent
    phi_jac_s: Callable[[list, list], tuple[list, list]] | None = None
    nu_s: Callable[..., list] | None = None
    gamma_s: Callable[..., list] | None = None
    #: the case compiled from the module's C (:class:`kinegen.runtime.native.NativeCase`), or None
    native: Any = None
    #: the model file's name and, per driver, (entry, text) of its time function there
    source: str = ""
    driver_sources: tuple[tuple[str, str], ...] = ()
    #: named points of the ground (global, fixed)
    ground_points: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    #: the design parameters' values this system was made for (name -> value; empty without a design: section)
    design: dict[str, float] = field(default_factory=dict)
    #: with design parameters: body -> point -> d(point, body coordinates)/dp, (3, n_design);
    #: the ground's points under "ground" (global)
    point_derivatives: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    #: with design parameters, the sensitivity kernels (:mod:`kinegen.runtime.sensitivity`), p
    #: bound: "phi_p" (q, u), "dvel" (q, v, u, ud), "dacc" (q, v, a, u, ud, udd) -> the values of
    #: a sparse matrix at its pattern (``sensitivity_patterns[kind]``: rows, columns; see
    #: :data:`kinegen.interface.SENSITIVITY_KERNELS`); frames_d (q, v, a, w, y, z)
    sensitivity_kernels: dict[str, Callable[..., np.ndarray]] = field(default_factory=dict)
    sensitivity_patterns: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    frames_d: Callable[..., np.ndarray] | None = None
    #: per body, the frames kernels' values in order: (name, count) (the module's FRAME_FIELDS)
    frame_fields: tuple[tuple[str, int], ...] = FRAME_FIELDS
    #: the force solve's kernels (a model with loads or actuation elements), else None
    statics: StaticsKernels | None = None
    #: span = (t0, t1) (floats or arrays) -> enclosures of the case's inputs over that time interval:
    #: rows of the lower bounds of u, du/dt, d2u/dt2, then of their upper bounds; None: a module without them
    input_ranges: Callable[[Any], np.ndarray] | None = None
    #: every kernel the module declares for all its cases (``KERNELS``; frames, lengths, actuation, loads,
    #: inertia, supply, ...), by name: a function of its argument slots but p (bound), each a value or a
    #: batch (columns), returning its outputs as a tuple in their declared order -- bound from the
    #: declaration alone (:func:`declared_kernels`), so a new kernel needs no code here; with ``native``,
    #: the compiled library's (a batch in one C call), with the same values
    kernels: dict[str, Callable[..., tuple]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # the certificates read Phi_u off one nu call by this order (kinegen_model in kinegen_solver.h)
        tail = self.constraint_names[len(self.constraint_names) - len(self.driver_names) :]
        if tail != self.driver_names:
            raise ValueError(
                f"{self.model}, case {self.case}: the drivers' rows must come last, in the inputs' order "
                f"(drivers {', '.join(self.driver_names)}; last rows {', '.join(tail)})"
            )

    @property
    def n_stored(self) -> int:
        return len(self.stored_names)

    @property
    def n_velocity(self) -> int:
        return len(self.velocity_names)

    @property
    def n_inputs(self) -> int:
        return len(self.driver_names)

    def driver_inputs(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(u, du/dt, d2u/dt2) of the case's time functions at ``t`` (scalar or array)."""
        rows = self.inputs(t)
        k = self.n_inputs
        return rows[:k], rows[k : 2 * k], rows[2 * k :]

    def checked_inputs(self, times: np.ndarray, step: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`driver_inputs` on a time grid, refused with a :class:`ModelError` where a
        time function or one of its first two derivatives is not a finite real number
        (``sqrt(t - 1)`` before t = 1, ``1/t`` at 0, ``exp(1000*t)``): the message names the
        driver's entry in the model file, its expression and the first failing time. ``step``: the
        two time points the solver subdivides between, where ``times`` lie inside a step."""
        times = np.asarray(times, dtype=float)
        if self.n_inputs == 0:  # a structure without drivers (mobility 0): no time function to check
            return tuple(np.zeros((0,) + times.shape) for _ in range(3))
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                rows = np.asarray(self.inputs(times), dtype=float).reshape(3 * self.n_inputs, -1)
                bad = ~np.isfinite(rows)
            except (ArithmeticError, ValueError, TypeError) as exc:  # a generated expression refusing a value
                rows, bad = None, None
                failure = f"{type(exc).__name__}: {exc}"
        if bad is None or bad.any():
            if bad is None:  # locate the failure point by point
                column, row = self._first_failure(times)
            else:
                column = int(np.argmax(bad.any(axis=0)))
                row = int(np.argmax(bad[:, column]))
                failure = str(rows[row, column])  # nan, inf or -inf
            order, driver = divmod(row, max(self.n_inputs, 1))
            entry, text = self.driver_sources[driver] if driver < len(self.driver_sources) else (
                f"driver {self.driver_names[driver]}", "")  # fmt: skip
            what = ("its value", "its first time derivative", "its second time derivative")[order]
            count = int(bad.any(axis=0).sum()) if bad is not None else None
            raise ModelError(
                self.source or self.model, entry,
                f"{shown(text)}: {what} is not a finite real number at t = {times[column]:.6g} ({failure})"
                + (
                    f", inside the step from t = {step[0]:.6g} to {step[1]:.6g} that the solver subdivides"
                    " -- the function leaves its domain between these time points"
                    if step
                    else (f"; {count} of the {len(times)} time points fail" if count else "")
                    + " -- the function leaves its domain on this time grid"
                ),
            )  # fmt: skip
        k = self.n_inputs
        return rows[:k], rows[k : 2 * k], rows[2 * k :]

    def _first_failure(self, times: np.ndarray) -> tuple[int, int]:
        """(time index, input row) of the first time point whose inputs cannot be evaluated or are not finite."""
        for column, t in enumerate(times):
            try:
                values = np.asarray(self.inputs(np.array([t])), dtype=float).ravel()
            except (ArithmeticError, ValueError, TypeError):
                return column, 0
            if not np.isfinite(values).all():
                return column, int(np.argmax(~np.isfinite(values)))
        return 0, 0

    def jacobian(self, q: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Dense Phi_q (constraints x velocity coordinates) at one configuration."""
        return self._pattern.dense(self.evaluate(q, u)[1])

    def retract(self, q: np.ndarray, step: np.ndarray) -> np.ndarray:
        """q (n,) or (n, K) moved by ``step`` (velocity coordinates) body by body, as the
        parametrization says (quaternions by the exponential map, so they stay unit)."""
        p = self.parametrization
        if self._additive:
            return q + step
        bodies = len(self.bodies)
        batch = q.shape[1:]
        moved = p.retract(q.reshape(bodies, p.nq, *batch).swapaxes(0, 1), step.reshape(bodies, p.nv, *batch).swapaxes(0, 1))
        return moved.swapaxes(0, 1).reshape(q.shape)

    def project(self, q: np.ndarray) -> np.ndarray:
        """q (n, ...) whose bodies' coordinates interpolation may have moved off their valid set
        (a quaternion's unit length) put back on it."""
        p = self.parametrization
        bodies = len(self.bodies)
        batch = q.shape[1:]
        return p.project(q.reshape(bodies, p.nq, *batch).swapaxes(0, 1)).swapaxes(0, 1).reshape(q.shape)

    def body_coordinates(self, values: np.ndarray, body: str, velocity: bool = False) -> np.ndarray:
        """The coordinates of ``body`` in ``values`` (K, n) (stored, or velocity when ``velocity``)."""
        p = self.parametrization
        offset = self.bodies[body][1 if velocity else 0]
        return values[..., offset : offset + (p.nv if velocity else p.nq)]

    def point_positions(self, q: np.ndarray, names: Sequence[tuple[str, str]]) -> np.ndarray:
        """Global positions [m] (K, P, 3) of the named body points ``names`` ((body, point) pairs)
        at the configurations ``q`` (K, n) of stored coordinates."""
        q = np.atleast_2d(q)
        out = np.empty((len(q), len(names), 3))
        for body in dict.fromkeys(b for b, _ in names):
            columns = [j for j, (b, _) in enumerate(names) if b == body]
            out[:, columns] = self.local_positions(q, body, [self.points[body][names[j][1]] for j in columns])
        return out

    def local_positions(self, q: np.ndarray, body: str, local: np.ndarray) -> np.ndarray:
        """Global positions [m] (K, P, 3) of points given in ``body``'s coordinates ``local`` (P, 3)
        at the configurations ``q`` (K, n); the ground's (``"ground"``) are their own."""
        q = np.atleast_2d(q)
        local = np.asarray(local, dtype=float)
        if body not in self.bodies:
            return np.broadcast_to(local, (len(q), *local.shape)).copy()
        origin, rotation = self.parametrization.pose(self.body_coordinates(q, body))
        return origin[:, None, :] + local @ rotation.swapaxes(1, 2)

    @cached_property
    def turning(self) -> np.ndarray:
        """The indices of the velocity coordinates that are not a body's translation (:data:`TRANSLATIONS`):
        the ones whose motion in a certified step is capped at a quarter turn (:data:`kinegen.runtime.solver.MAX_MOTION`)."""
        return np.array([i for i, name in enumerate(self.velocity_names) if name.rsplit(".", 1)[-1] not in TRANSLATIONS], dtype=np.intp)

    @cached_property
    def frame_slices(self) -> dict[str, slice]:
        """Where each frame value lies among a body's values in the frames kernels (name -> slice)."""
        return frame_slices(self.frame_fields)

    @cached_property
    def _additive(self) -> bool:
        return self.parametrization.additive

    @cached_property
    def _pattern(self) -> Pattern:
        return Pattern(self.jac_rows, self.jac_cols, (len(self.constraint_names), self.n_velocity))

    def evaluate(self, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, Any]:
        """Phi and the Phi_q values (at jac_rows, jac_cols) at one configuration in one call
        (the plain-float code when the module has it)."""
        if self.native is not None:
            return self.native.evaluate(q, u)
        if self.phi_jac_s is None:
            return self.phi(q, u), self.jac(q, u)
        phi, values = self.phi_jac_s(q.tolist(), u.tolist())
        return np.array(phi), values

    def velocity_rhs(self, q: np.ndarray, u: np.ndarray, ud: np.ndarray) -> np.ndarray:
        """nu = -Phi_t at one configuration."""
        if self.native is not None:
            return self.native.nu(q, u, ud)
        if self.nu_s is None:
            return self.nu(q, u, ud)
        return np.array(self.nu_s(q.tolist(), u.tolist(), ud.tolist()))

    def acceleration_rhs(self, q: np.ndarray, v: np.ndarray, u: np.ndarray, ud: np.ndarray, udd: np.ndarray) -> np.ndarray:
        """gamma at one configuration."""
        if self.native is not None:
            return self.native.gamma(q, v, u, ud, udd)
        if self.gamma_s is None:
            return self.gamma(q, v, u, ud, udd)
        return np.array(self.gamma_s(q.tolist(), v.tolist(), u.tolist(), ud.tolist(), udd.tolist()))


def from_module(
    module: ModuleType | Any, case: str | None = None, compiled: bool | None = None, design: Mapping[str, float] | None = None
) -> NumericSystem:
    """The numeric system of ``case`` (the first case by default) of a generated module.

    ``compiled``: evaluate the kernels and solve trajectories through the module's C (the
    ``.c``/``.h`` beside it, compiled once with kinegen's C solver and cached,
    :mod:`kinegen.runtime.native`). None (default): when the C is there and a compiler is
    found, else the Python functions (a missing compiler is said once, as a warning); True:
    the same, but a missing compiler is an error (:class:`~kinegen.runtime.native.CompileError`);
    False: the Python functions.

    ``design``: values of the model's design parameters by name (the others at their nominal
    values, within their bounds); the kernels take them as their argument ``p``, the named
    points are computed from them -- no rebuild, compiled or not.
    """
    cases = module.CASES
    if case is None:
        case = next(iter(cases))
    if case not in cases:
        raise KeyError(f"model {module.MODEL!r} has no case {case!r} (cases: {', '.join(cases)})")
    data = cases[case]
    p = _design_values(module, design)
    points = {b: dict(pts) for b, pts in module.POINTS.items()}
    ground_points = dict(getattr(module, "GROUND_POINTS", {}))
    outputs, scalar = data["outputs"], data["scalar"]
    kernels = {**{k: outputs[k] for k in ("phi", "jac", "nu", "gamma")}, **{f"{k}_s": scalar.get(k) for k in ("phi_jac", "nu", "gamma")}}
    design_fields: dict[str, Any] = {}
    if p is not None:
        kernels = {k: None if f is None else _with_design(f, p) for k, f in kernels.items()}
        points, ground_points = _design_points(module, p)
        design_fields = {"design": dict(zip(module.DESIGN, p.tolist())), "actuators": _design_actuators(module, p)}
        if all(kind in outputs for kind in SENSITIVITY_KERNELS):  # (a module built without them lacks them)
            design_fields.update(
                point_derivatives=_design_point_derivatives(module, p),
                sensitivity_kernels={kind: _with_design(outputs[kind], p) for kind in SENSITIVITY_KERNELS},
                sensitivity_patterns={
                    kind: tuple(np.array(x, dtype=np.intp) for x in data["patterns"][kind]) for kind in SENSITIVITY_KERNELS
                },
                frames_d=module.frames_d,
                frame_fields=tuple(module.FRAME_FIELDS),
            )
    native = _native(module, case, compiled, p)
    statics, declared = _statics(module, p), declared_kernels(module, p)
    if native is not None:
        statics, declared = _compiled_where_declared(native, module, statics, declared, design_fields)
    return NumericSystem(
        model=module.MODEL,
        case=case,
        parametrization=rotations.get(module.PARAMETRIZATION),
        stored_names=tuple(module.STORED_NAMES),
        velocity_names=tuple(module.VELOCITY_NAMES),
        constraint_names=tuple(data["constraints"]),
        driver_names=tuple(data["drivers"]),
        bodies=dict(module.BODIES),
        points=points,
        initial_q=np.array(module.INITIAL_Q, dtype=float),
        jac_rows=np.array(data["jac_rows"], dtype=np.intp),
        jac_cols=np.array(data["jac_cols"], dtype=np.intp),
        inputs=outputs["inputs"],
        phi=kernels["phi"],
        jac=kernels["jac"],
        nu=kernels["nu"],
        gamma=kernels["gamma"],
        t0=float(data["t0"]),
        t1=float(data["t1"]),
        steps=int(data["steps"]),
        source_sha256=getattr(module, "SOURCE_SHA256", ""),
        actuators=design_fields.pop("actuators", None) or dict(getattr(module, "ACTUATORS", {})),
        phi_jac_s=kernels["phi_jac_s"],
        nu_s=kernels["nu_s"],
        gamma_s=kernels["gamma_s"],
        source=getattr(module, "SOURCE", ""),
        driver_sources=tuple(data.get("driver_sources", ())),
        ground_points=ground_points,
        native=native,
        statics=statics,
        input_ranges=outputs.get("input_ranges"),
        kernels=declared,
        **design_fields,
    )


def _compiled_where_declared(
    native: Any, module: ModuleType | Any, statics: StaticsKernels | None, declared: dict[str, Callable[..., tuple]], design_fields: dict
) -> tuple[StaticsKernels | None, dict[str, Callable[..., tuple]]]:
    """The kernels the runtime evaluates over many configurations (the force solve's, the declared
    ones, the sensitivity kernels and frames_d: in ``design_fields``, replaced there) evaluated by the
    compiled library, one C call a batch (:meth:`kinegen.runtime.native.NativeCase.each`), where it
    declares them: the same expressions as the Python functions', at one pose ~80x and at 10,000
    poses ~2x faster. The sensitivity kernels are the complete library's, compiled when first called;
    where that fails they stay the Python functions."""

    def first(name: str, sensitivity: bool = False) -> Callable[..., np.ndarray]:
        function = native.function(name, [s for s in module.KERNELS[name][0] if s != "p"], sensitivity)
        return lambda *arguments: function(*arguments)[0]

    if statics is not None:
        roles = {"matrix": "actuation", "loads": "loads", "inertia": "inertia"}
        statics = replace(statics, **{role: first(name) for role, name in roles.items() if getattr(statics, role) is not None and name in native.kernels})
    declared = {name: native.function(name) if name in native.kernels else function for name, function in declared.items()}
    python = design_fields.get("sensitivity_kernels")
    if python:
        design_fields["sensitivity_kernels"] = {kind: _compiled_or(native, first(kind, True), function) for kind, function in python.items()}
        # frames_d comes with them (from_module): the complete library's too
        design_fields["frames_d"] = _compiled_or(native, first("frames_d", True), design_fields["frames_d"])
    return statics, declared


def _compiled_or(native: Any, compiled: Callable[..., np.ndarray], python: Callable[..., np.ndarray]) -> Callable[..., np.ndarray]:
    """A sensitivity kernel by the complete compiled library, or by ``python`` where it cannot be compiled."""

    def kernel(*arguments: np.ndarray) -> np.ndarray:
        return python(*arguments) if native.sensitivity_case() is None else compiled(*arguments)

    return kernel


def declared_kernels(module: ModuleType | Any, p: np.ndarray | None) -> dict[str, Callable[..., tuple]]:
    """The kernels a module declares for all its cases (``KERNELS``: name -> (argument slots, output
    names), each output a module function of the slots), by name: a function of the slots but ``p``
    (bound to ``p``) returning the outputs as a tuple. The per-case kernels (their functions suffixed
    with the case) are the case's, not listed here."""
    bound = {}
    for name, (slots, outputs) in getattr(module, "KERNELS", {}).items():
        functions = [getattr(module, output, None) for output in outputs]
        if any(f is None for f in functions):
            continue  # a per-case kernel
        if "p" in slots:
            if p is None or slots[-1] != "p":  # pragma: no cover -- the declaration puts p last, with a design
                raise ValueError(f"{module.MODEL}: kernel {name} takes p {slots} without design parameters to bind")
            functions = [_with_design(f, p) for f in functions]
        bound[name] = _outputs_of(tuple(functions))
    return bound


def _outputs_of(functions: tuple[Callable[..., Any], ...]) -> Callable[..., tuple]:
    def kernel(*arguments: Any) -> tuple:
        return tuple(f(*arguments) for f in functions)

    return kernel


def _design_values(module: ModuleType | Any, design: Mapping[str, float] | None) -> np.ndarray | None:
    """The argument p of a module with design parameters: ``design``'s values, nominal for the rest."""
    table = getattr(module, "DESIGN", None)
    values = dict(design or {})
    if table is None:
        if values:
            raise KeyError(f"model {module.MODEL!r} has no design parameters (given: {', '.join(sorted(values))})")
        return None
    unknown = sorted(set(values) - set(table))
    if unknown:
        raise KeyError(f"not design parameters of {module.MODEL!r}: {', '.join(unknown)} (design parameters: {', '.join(table)})")
    p = []
    for name, (nominal, lower, upper) in table.items():
        value = float(values.get(name, nominal))
        if not lower <= value <= upper:
            raise ValueError(f"design parameter {name} = {value!r} is outside its bounds [{lower!r}, {upper!r}]")
        p.append(value)
    return np.array(p)


def _with_design(function: Callable[..., Any], p: np.ndarray) -> Callable[..., Any]:
    """``function`` with the design parameters ``p`` as its last argument, bound."""
    values = p.tolist()

    def bound(*args: Any) -> Any:
        return function(*args, values)

    return bound


def _design_point_derivatives(module: ModuleType | Any, p: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    """d(point)/dp of every named point at ``p`` (the ground's under "ground")."""
    flat = np.asarray(module.points_p(p.tolist()), dtype=float).reshape(-1, 3, len(p))
    named = [(body, name) for body, points in module.POINTS.items() for name in points]
    named += [("ground", name) for name in getattr(module, "GROUND_POINTS", {})]
    out: dict[str, dict[str, np.ndarray]] = {}
    for (body, name), derivative in zip(named, flat):
        out.setdefault(body, {})[name] = derivative
    return out


def _design_actuators(module: ModuleType | Any, p: np.ndarray) -> dict[str, tuple]:
    """ACTUATORS of a module with design parameters, their ranges at ``p`` (a range may use them)."""
    actuators = dict(getattr(module, "ACTUATORS", {}))
    if not hasattr(module, "actuator_ranges"):  # (modules built before ranges could use design parameters)
        return actuators
    bounds = iter(np.asarray(module.actuator_ranges(p.tolist()), dtype=float).tolist())
    return {name: (p1, p2, None if limits is None else (next(bounds), next(bounds))) for name, (p1, p2, limits) in actuators.items()}


def _design_points(module: ModuleType | Any, p: np.ndarray) -> tuple[dict, dict]:
    """POINTS and GROUND_POINTS of a module with design parameters, at ``p``."""
    flat = iter(np.asarray(module.points(p.tolist()), dtype=float).tolist())
    points = {body: {name: tuple(next(flat) for _ in range(3)) for name in named} for body, named in module.POINTS.items()}
    ground = {name: tuple(next(flat) for _ in range(3)) for name in getattr(module, "GROUND_POINTS", {})}
    return points, ground


def _native(module: ModuleType | Any, case: str, compiled: bool | None, design: np.ndarray | None = None) -> Any:
    if compiled is False or not hasattr(module, "KERNELS"):
        return None
    import kinegen.runtime.native as native

    if compiled and native.module_library(module) is None:  # CompileError without a compiler
        raise native.CompileError(f"{getattr(module, '__file__', module)}: no fresh generated C beside the module")
    return native.native_case(module, case, design=design)


def module_from_source(source: str, name: str = "kinegen_generated", filename: str = "<generated>") -> ModuleType:
    """A generated module made from its source text without a file (e.g. to check a build
    before it is written), compiled one top-level definition at a time (its code kept in kinegen's
    cache for the next time: :mod:`kinegen.runtime.bytecode`)."""
    from kinegen.runtime.bytecode import compiled

    module = ModuleType(name)
    module.__file__ = filename
    for code in compiled(source, filename):
        exec(code, module.__dict__)  # generated by kinegen, not user text
    return module


def load_module(path: str | Path, model_file: str | Path | None = None) -> ModuleType:
    """Load a generated module from ``path``, verified before anything in it runs.

    The file's bytes are read once and must be kinegen's own (:mod:`kinegen.integrity`): in the
    user's trust store (kinegen wrote or verified them), or regenerated from their model -- its
    ``model_file``, else the file its header names in ``models/`` beside the module's folder or
    among kinegen's own models -- to the same bytes (then remembered). Exactly those bytes are then
    executed (their code compiled once and kept in kinegen's cache, by the source's digest, its own
    bytes in the trust store: :mod:`kinegen.runtime.bytecode`). A module built by another kinegen or
    from another version of its model is refused with a :class:`GeneratedModuleError` saying how to
    rebuild it; one whose bytes kinegen did not write (edited, planted) with a
    :class:`~kinegen.errors.ChangedFileError`. With ``model_file``, the module's recorded source hash
    must also match that file's bytes (else it is stale).
    """
    import kinegen
    from kinegen.integrity import trusted

    path = Path(path)
    if not path.is_file():
        raise GeneratedModuleError(f"{path}: no such generated module (run `kinegen build`)")
    rebuild = f"rebuild it with `kinegen build {model_file if model_file is not None else '<model>.yaml'}`"
    try:
        data = path.read_bytes()
        text = data.decode("utf-8")
    except OSError as exc:
        raise GeneratedModuleError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        text = None
    version = _header_field(text, "kinegen version") if text is not None else None
    if text is not None and version is not None and version != kinegen.__version__:
        raise GeneratedModuleError(f"{path} was built by kinegen {version}, this is kinegen {kinegen.__version__}; {rebuild}")
    source = _header_field(text, "source sha256") if text is not None else None
    if model_file is not None and source is not None:
        from kinegen.model.loader import source_digest  # the model's reader (sympy) only where a model file is named

        if source_digest(model_file) != source:
            raise GeneratedModuleError(
                f"{path} is stale: it was built from a different version of {model_file}; "
                f"rebuild with `kinegen build {model_file} --param {_header_field(text, 'parametrization')}`"
            )
    if not trusted(data):
        _verify_by_regeneration(path, data, text, model_file)
    name = f"kinegen_generated_{path.stem}_{hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:8]}"
    try:
        module = module_from_source(text, name=name, filename=str(path))
    except Exception as exc:  # kinegen's own bytes that do not run here: say which and why
        raise GeneratedModuleError(f"{path}: not a valid generated module ({type(exc).__name__}: {exc}); {rebuild}") from exc
    for attribute in ("MODEL", "PARAMETRIZATION", "CASES", "SOURCE_SHA256"):
        if not hasattr(module, attribute):
            raise GeneratedModuleError(f"{path}: not a kinegen generated module (no {attribute})")
    sys.modules[name] = module
    return module


def _verify_by_regeneration(path: Path, data: bytes, text: str | None, model_file: str | Path | None) -> None:
    """Return when kinegen, building the model the module's header names, writes exactly ``data``
    (then remembered as its own); else :class:`ChangedFileError` (nothing of it has run)."""
    from kinegen.errors import ChangedFileError

    header = {k: _header_field(text, k) if text is not None else None for k in ("source", "source sha256", "parametrization", "sensitivities")}
    model = Path(model_file) if model_file is not None else _model_beside(path, header["source"], header["source sha256"])
    if model is None or header["parametrization"] is None:
        raise ChangedFileError(
            f"{path}: kinegen on this account did not write these bytes, and cannot regenerate them to compare (the model "
            f"{header['source'] or 'it came from'} is not given and not in models/ beside its folder); nothing in it ran. "
            "Pass its model file, or build it with `kinegen build <model>.yaml`"
        )
    from kinegen.codegen.writer import regenerates

    try:
        rotations.get(header["parametrization"])
    except ValueError:
        raise ChangedFileError(
            f"{path} was changed since kinegen wrote it: its header names no parametrization kinegen knows "
            f"({header['parametrization']!r}); nothing in it ran. Rebuild it with `kinegen build {model} --param <parametrization>` "
            "(which replaces it)"
        ) from None
    sensitivities = None if header["sensitivities"] is None else header["sensitivities"] == "yes"
    with_c = text is not None and "\nC_FILES = {}\n" not in text
    if not regenerates(data, model, header["parametrization"], sensitivities, with_c):
        raise ChangedFileError(
            f"{path} was changed since kinegen wrote it: its bytes are not what kinegen writes for {model} "
            f"({header['parametrization']}); nothing in it ran. Rebuild it with `kinegen build {model} --param {header['parametrization']}` "
            "(which replaces it)"
        )


def _model_beside(path: Path, source: str | None, source_sha256: str | None) -> Path | None:
    """The model file a module's header names (``source``, its digest ``source_sha256``), in
    ``models/`` beside the module's folder or among kinegen's own models; None where neither has it."""
    if not source or not source_sha256 or Path(source).name != source:
        return None
    from kinegen.model.loader import source_digest

    for folder in (path.resolve().parent.parent / "models", Path(kinegen_models_folder())):
        candidate = folder / source
        try:
            if candidate.is_file() and source_digest(candidate) == source_sha256:
                return candidate
        except (OSError, KinegenError):  # an unreadable candidate: not this model
            continue
    return None


def kinegen_models_folder() -> str:
    """Where kinegen's own models lie (the package data ``kinegen.models``)."""
    from importlib.resources import files

    try:
        return str(files("kinegen.models"))
    except (ModuleNotFoundError, TypeError):  # (not installed with its models)
        return str(Path(__file__).resolve().parents[2] / "models")


def _header_field(text: str, field_name: str) -> str | None:
    """A field of a generated file's header (``kinegen version:   0.1.0``), read as text, or None."""
    for line in text.splitlines()[:20]:
        key, sep, value = line.lstrip(" *").partition(":")
        if sep and key.strip() == field_name:
            return value.strip()
    return None
