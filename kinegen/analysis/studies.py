"""Design studies (``kinegen optimize``): a model's ``studies:`` entry solved with SciPy on the
exact gradients.

At a design p (the study's parameters; the model's other design parameters at their nominal
values) every quantity the study names is measured from the one generated module, no rebuild:

* a case's quantities from one trajectory solve of that case at p and the exact sensitivities
  of it (:mod:`kinegen.runtime.sensitivity`): rotation ranges and strokes from the extreme time
  points' sensitivities, the toggle margin from the σ_min of the linkage's diagonal blocks of
  Φ_q and its derivative dσ/dp = uᵀ(dΦ_q/dp)x at the critical time point and block, the actuator
  margin from the length's sensitivity and the range's own derivative (a range may use p);
* working-range figures from the envelope, refined at each design from the last design's optima
  (:func:`kinegen.analysis.envelope.refine_from`) and differentiated by the envelope theorem.

A minimum or maximum over a case is measured at the case's time points, its derivative that of
the time point where it is reached (exact for that point; the quantity has a kink where the
critical point changes). The optimizer works in the parameters scaled to [0, 1] by their bounds.
With ``gradients="fd"`` SciPy's finite differences replace the exact gradients (the comparison
of issue 13).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from kinegen.errors import KinegenError
from kinegen.model.kinds import check_registered
from kinegen.model.schema import GROUND, MACHINE, QUANTITY_KINDS, Model, Quantity, Study, design_gradient, design_value
from kinegen.runtime import Solver, from_module, kinematics
from kinegen.runtime.results import Results
from kinegen.runtime.sensitivity import (
    actuator_length_sensitivity,
    point_sensitivity,
    relative_angle_sensitivity,
    state_sensitivities,
)

#: SLSQP's step of finite differences in the scaled parameters (issue 13's comparison): 1e-6 of a
#: parameter's range -- 4e-8 m for +-2 cm -- well above the quantities' own noise (~1e-12)
FD_STEP = 1e-6
#: a constraint is reported active when its slack is below this (relative to its bound, at least in its own unit)
ACTIVE = 1e-6


@dataclass
class Measured:
    """Quantities at one design: value per label, and (when asked) d/d(study parameters); for a
    minimum over a case (a margin) also every time point's (and block's) value and gradient, so
    that a constraint on it is one smooth constraint per point instead of one with kinks."""

    values: dict[str, float]
    gradients: dict[str, np.ndarray] | None = None
    series: dict[str, tuple[np.ndarray, np.ndarray | None]] = field(default_factory=dict)


class DesignFailure(KinegenError):
    """A design the study cannot measure (its mechanism cannot be assembled along a case)."""


@dataclass
class StudyResult:
    """What ``kinegen optimize`` reports."""

    study: Study
    method: str
    gradients: str  #: "exact" or "finite differences"
    bounds: dict[str, tuple[float, float]]
    nominal: dict[str, float]
    optimum: dict[str, float]
    before: dict[str, float]  #: quantities at the nominal design
    after: dict[str, float]  #: and at the optimum
    objective_before: float
    objective_after: float
    active: list[str]
    iterations: int
    evaluations: int  #: designs measured (values)
    gradient_evaluations: int  #: designs whose gradients were computed (exact), or SciPy's jacobian calls (fd)
    seconds: float
    success: bool
    message: str
    progress: list[tuple[int, float, float, float]] = field(default_factory=list)  #: iteration, objective, worst violation, s

    def table(self, published: dict[str, float] | None = None) -> str:
        """Parameters and quantities, nominal beside optimum."""
        lines = [f"study {self.study.name}: {self.study.sense} ({self.method}, {self.gradients} gradients)"]
        lines.append(f"  {'parameter':<16} {'nominal':>11} {'optimum':>11} {'change':>10}  bounds")
        for name, value in self.optimum.items():
            low, high = self.bounds[name]
            at = "  (at its bound)" if min(value - low, high - value) <= 1e-9 * (high - low) else ""
            lines.append(f"  {name:<16} {self.nominal[name]:>11.6f} {value:>11.6f} {value - self.nominal[name]:>+10.6f}  [{low:g}, {high:g}]{at}")
        units = {q.label: q.unit for q in [t.quantity for t in self.study.terms] + [c.quantity for c in self.study.constraints]}
        width = max([44, *(len(label) for label in self.after)])
        lines.append(f"  {'quantity':<{width}} {'nominal':>10} {'optimum':>10}")
        for label, value in self.after.items():
            unit = units.get(label, "m")
            extra = f"   published {published[label]:.2f} (unverified)" if published and label in published else ""
            if unit == "rad":
                extra = f"   ({np.degrees(self.before[label]):.1f} -> {np.degrees(value):.1f} deg)"
            lines.append(f"  {label:<{width}} {self.before[label]:>10.4f} {value:>10.4f} {unit:<3}{extra}")
        lines.append(f"  objective {self.objective_before:.6g} -> {self.objective_after:.6g}")
        lines.append(f"  active: {', '.join(self.active) or 'none'}")
        lines.append(
            f"  {self.iterations} iterations, {self.evaluations} designs measured, {self.gradient_evaluations} gradient evaluations, "
            f"{self.seconds:.1f} s ({self.message})"
        )
        return "\n".join(lines)

    def to_json(self) -> dict:
        keys = ("method", "gradients", "bounds", "nominal", "optimum", "before", "after", "objective_before", "objective_after",
                "active", "iterations", "evaluations", "gradient_evaluations", "seconds", "success", "message")  # fmt: skip
        return {"study": self.study.name, **{k: getattr(self, k) for k in keys}}


class StudyProblem:
    """One study of a model on one generated module (``module``: with design parameters and,
    for exact gradients, sensitivity kernels)."""

    def __init__(self, model: Model, module, study: Study, compiled: bool | None = None, resample: bool = True) -> None:
        self.model, self.module, self.study, self.compiled = model, module, study, compiled
        #: when a working range cannot be refined from the last design's optima, sample it afresh
        #: (False: the failure ends the measurement -- an exploration's variant is then marked)
        self.resample = resample
        design = {d.name: d for d in model.design}
        self.order = list(design)  #: every design parameter, in the module's order
        self.names = list(study.parameters)
        self.index = [self.order.index(n) for n in self.names]
        self.nominal_design = {name: float(d.nominal) for name, d in design.items()}
        self.bounds = np.array([(float(design[n].lower), float(design[n].upper)) for n in self.names])
        self.quantities = list({q.label: q for q in [t.quantity for t in study.terms] + [c.quantity for c in study.constraints]}.values())
        self.actuators = {a.name: a for a in model.actuators}
        self.envelope = None  #: the last working range measured (the next one starts from its optima)
        self.starts: dict[str, np.ndarray] = {}  #: per case, the last design's pose at its start (the next solve's first guess)
        self.evaluations = self.gradient_evaluations = 0

    # ---- designs ---------------------------------------------------------------------------
    def design(self, p: np.ndarray) -> dict[str, float]:
        """Every design parameter's value: the study's at p, the others nominal."""
        values = dict(self.nominal_design)
        values.update(zip(self.names, (float(x) for x in p)))
        return values

    def scaled(self, p: np.ndarray) -> np.ndarray:
        return (np.asarray(p) - self.bounds[:, 0]) / (self.bounds[:, 1] - self.bounds[:, 0])

    def unscaled(self, x: np.ndarray) -> np.ndarray:
        return self.bounds[:, 0] + np.clip(x, 0, 1) * (self.bounds[:, 1] - self.bounds[:, 0])

    # ---- measuring -------------------------------------------------------------------------
    def measure(self, p: np.ndarray, gradients: bool = True) -> Measured:
        """Every quantity of the study at the study parameters ``p`` (and their gradients)."""
        design = self.design(p)
        self.evaluations += 1
        self.gradient_evaluations += gradients
        values: dict[str, float] = {}
        derivatives: dict[str, np.ndarray] = {}
        by_case: dict[str, list[Quantity]] = {}
        for quantity in self.quantities:
            if quantity.kind in DESIGN_MEASURES:  # the design's alone: no solve
                values[quantity.label], derivative = DESIGN_MEASURES[quantity.kind](self.model, design, quantity)
                if gradients:
                    derivatives[quantity.label] = derivative[self.index]
            elif quantity.kind == "working_range":
                by_case.setdefault("", []).append(quantity)
            else:
                by_case.setdefault(str(quantity.case), []).append(quantity)
        series: dict[str, tuple[np.ndarray, np.ndarray | None]] = {}
        for case, quantities in by_case.items():
            try:
                if case == "":
                    measured = self._working_range(design, gradients)
                else:
                    results = Solver(from_module(self.module, case, self.compiled, design)).solve(q0=self.starts.get(case))
                    self.starts[case] = results.q[0]
                    measured = {q.label: MEASURES[q.kind](self, results, q, gradients) for q in quantities}
            except KinegenError as exc:
                shown = ", ".join(f"{n} = {design[n]:.6g}" for n in self.names)
                raise DesignFailure(f"the design {shown} cannot be measured{f' over case {case}' if case else ''}: {exc}") from exc
            for label, (value, gradient, *points) in measured.items():
                values[label] = value
                if gradients:
                    derivatives[label] = np.asarray(gradient)[self.index]
                if points and points[0] is not None:
                    point_values, point_gradients = points[0]
                    series[label] = (point_values, None if point_gradients is None else point_gradients[:, self.index])
        return Measured(values, derivatives if gradients else None, series)

    def _working_range(self, design: dict[str, float], gradients: bool) -> dict[str, tuple[float, np.ndarray | None]]:
        from kinegen.analysis.envelope import figure_sensitivities, refine_from, working_range

        spec = self.model.working_range
        system = from_module(self.module, spec.case, self.compiled, design)
        envelope = None
        if self.envelope is not None:
            try:
                envelope = refine_from(system, self.envelope)
            except KinegenError:  # a continuation that lost its way: sample the working range afresh
                if not self.resample:
                    raise
                envelope = None
        if envelope is None:
            envelope = working_range(system, spec)
        self.envelope = envelope
        exact = figure_sensitivities(envelope, system) if gradients else {}
        return {name: (value, exact.get(name)) for name, value in envelope.figures.items()}

    # ---- the objective and constraints ---------------------------------------------------------
    def objective(self, measured: Measured) -> tuple[float, np.ndarray | None]:
        """The study's objective as minimized (a maximized sum negated) and its gradient in p."""
        sign = -1.0 if self.study.sense == "maximize" else 1.0
        total, gradient = 0.0, np.zeros(len(self.names))
        for term in self.study.terms:
            value = measured.values[term.quantity.label]
            d = measured.gradients[term.quantity.label] if measured.gradients is not None else None
            if term.target is None:
                total += term.weight * value
                if d is not None:
                    gradient += term.weight * d
            else:
                total += term.weight * (value - term.target) ** 2
                if d is not None:
                    gradient += 2 * term.weight * (value - term.target) * d
        return sign * total, None if measured.gradients is None else sign * gradient

    def constraints(self, measured: Measured) -> tuple[np.ndarray, np.ndarray | None]:
        """Every constraint as slack >= 0 (at_least: value - bound; at_most: bound - value) and its gradient in p."""
        slacks, rows = [], []
        n = len(self.names)
        for constraint in self.study.constraints:
            label = constraint.quantity.label
            value = np.atleast_1d(measured.values[label])
            d = measured.gradients[label][None] if measured.gradients is not None else np.zeros((1, n))
            if constraint.at_least is not None:
                if label in measured.series:  # a minimum over a case: every time point (and block) at least the bound
                    value, points = measured.series[label]
                    d = points if points is not None else np.zeros((len(value), n))
                slacks.append(value - constraint.at_least)
                rows.append(d)
            if constraint.at_most is not None:
                slacks.append(constraint.at_most - np.atleast_1d(measured.values[label]))
                rows.append(-(measured.gradients[label][None] if measured.gradients is not None else np.zeros((1, n))))
        gradient = np.vstack(rows) if measured.gradients is not None and rows else None
        return (np.concatenate(slacks) if slacks else np.zeros(0)), gradient

    def active(self, measured: Measured, p: np.ndarray) -> list[str]:
        """The constraints and parameter bounds active at p."""
        out = []
        for constraint in self.study.constraints:
            value = measured.values[constraint.quantity.label]
            for bound, side in ((constraint.at_least, "at least"), (constraint.at_most, "at most")):
                if bound is not None and abs(value - bound) <= ACTIVE * max(1.0, abs(bound)):
                    out.append(f"{constraint.quantity.label} {side} {bound:g}")
        for name, value, (low, high) in zip(self.names, p, self.bounds):
            if value - low <= 1e-9 * (high - low):
                out.append(f"{name} at its lower bound")
            elif high - value <= 1e-9 * (high - low):
                out.append(f"{name} at its upper bound")
        return out


# ---- quantities measured over a case ---------------------------------------------------------------
def _extremes(values: np.ndarray, derivatives: Callable[[], np.ndarray] | None) -> tuple[float, np.ndarray | None]:
    """max - min of a time series and its derivative (those of the two time points)."""
    high, low = int(np.nanargmax(values)), int(np.nanargmin(values))
    gradient = None if derivatives is None else (lambda d: d[high] - d[low])(derivatives())
    return float(values[high] - values[low]), gradient


def relative_angle(results: Results, body: str, relative_to: str, axis: np.ndarray) -> np.ndarray:
    """The rotation angle of ``body`` relative to ``relative_to`` about ``axis`` (unit, in
    ``relative_to``'s frame) at every time point, continuous over time (rad)."""
    rotation = kinematics.rotation_matrix(results, body)
    if relative_to != GROUND:
        rotation = np.einsum("kji,kjl->kil", kinematics.rotation_matrix(results, relative_to), rotation)
    first = np.cross(axis, np.eye(3)[int(np.argmin(np.abs(axis)))])
    first /= np.linalg.norm(first)
    second = np.cross(axis, first)
    turned = rotation @ first
    return np.unwrap(np.arctan2(turned @ second, turned @ first))


def _rotation_range(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    axis = np.asarray(q.axis, dtype=float)
    angle = relative_angle(results, str(q.body), q.relative_to, axis)
    return _extremes(angle, (lambda: relative_angle_sensitivity(results, q.relative_to, str(q.body), tuple(axis))) if gradients else None)


def _stroke(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    name = str(q.actuator)
    return _extremes(kinematics.actuator_length(results, name), (lambda: actuator_length_sensitivity(results, name)) if gradients else None)


def _actuator_margin(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """The smallest distance to the range's ends over the case; per time point both distances."""
    actuator = problem.actuators[str(q.actuator)]
    design = results.system.design
    low, high = actuator.limits(design)
    length = kinematics.actuator_length(results, actuator.name)
    points = np.concatenate([length - low, high - length])
    k = int(np.nanargmin(points))
    if not gradients:
        return float(points[k]), None, (points, None)
    d_length = actuator_length_sensitivity(results, actuator.name)
    order = list(design)
    d_points = np.concatenate([d_length - design_gradient(actuator.range[0], order, design),
                               design_gradient(actuator.range[1], order, design) - d_length])  # fmt: skip
    return float(points[k]), d_points[k], (points, d_points)


def _toggle_margin(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    from kinegen.runtime.sensitivity import body_blocks, singular_value_sensitivity

    blocks = body_blocks(results.system, q.bodies)
    if not blocks:
        raise ValueError(f"{q.label}: no diagonal block of Phi_q holds coordinates of {', '.join(q.bodies)}")
    measured = [singular_value_sensitivity(results, block) if gradients else (_block_sigma(results, block), None) for block in blocks]
    points = np.concatenate([sigma for sigma, _ in measured])
    d_points = np.concatenate([d for _, d in measured]) if gradients else None
    k = int(np.nanargmin(points))
    return float(points[k]), None if d_points is None else d_points[k], (points, d_points)


def _block_sigma(results: Results, block: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    system = results.system
    rows, cols = block
    return np.array(
        [np.linalg.svd(system.jacobian(q, u)[np.ix_(rows, cols)], compute_uv=False)[-1] for q, u in zip(results.q, results.inputs)]
    )


def _transmission_angle(problem: StudyProblem | None, results: Results, q: Quantity, gradients: bool):
    """The angle θ at the middle point, per time point θ and π − θ (both kept from 0), and their derivatives."""
    (a, b, c) = q.points
    middle = kinematics.point_position(results, *b)
    u, w = kinematics.point_position(results, *a) - middle, kinematics.point_position(results, *c) - middle
    length_u, length_w = np.linalg.norm(u, axis=1), np.linalg.norm(w, axis=1)
    cosine = np.einsum("ki,ki->k", u, w) / (length_u * length_w)
    theta = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), np.einsum("ki,ki->k", u, w))
    points = np.concatenate([theta, np.pi - theta])
    k = int(np.nanargmin(points))
    if not gradients:
        return float(points[k]), None, (points, None)
    d_middle = point_sensitivity(results, *b)
    du, dw = point_sensitivity(results, *a) - d_middle, point_sensitivity(results, *c) - d_middle  # (K, 3, n_design)
    d_cosine = (np.einsum("kin,ki->kn", du, w) + np.einsum("ki,kin->kn", u, dw)) / (length_u * length_w)[:, None] - cosine[:, None] * (
        np.einsum("ki,kin->kn", u, du) / length_u[:, None] ** 2 + np.einsum("ki,kin->kn", w, dw) / length_w[:, None] ** 2
    )
    d_theta = -d_cosine / np.sin(theta)[:, None]
    d_points = np.concatenate([d_theta, -d_theta])
    return float(points[k]), d_points[k], (points, d_points)


def _relief_tool_force(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """relief x cap area x |L'| / |v_lip| over the case (kN) -- the force at the lip along its path that
    the actuator produces at its relief setting, by virtual work when only it moves -- at its largest
    time point, and its derivative there (the rate's and the lip speed's exact sensitivities)."""
    actuator = problem.actuators[str(q.actuator)]
    hydraulics = actuator.hydraulics
    system = results.system
    design, order = system.design, list(system.design)
    lip = problem.model.tool_forces.lip
    (b1, p1), (b2, p2) = ((ref.body, ref.name) for ref in actuator.points)
    gap = kinematics.point_position(results, b2, p2) - kinematics.point_position(results, b1, p1)
    relative = kinematics.point_velocity(results, b2, p2) - kinematics.point_velocity(results, b1, p1)
    length = np.linalg.norm(gap, axis=1)
    e = gap / length[:, None]
    rate = np.einsum("ki,ki->k", e, relative)
    motion = kinematics.point_velocity(results, lip.body, lip.name)
    speed = np.linalg.norm(motion, axis=1)
    cap = hydraulics.cylinders * np.pi / 4 * design_value(hydraulics.bore, design) ** 2
    pressure = design_value(hydraulics.relief[0], design)
    with np.errstate(divide="ignore", invalid="ignore"):
        values = np.where(speed > 0, pressure * cap * np.abs(rate) / speed / 1e3, np.nan)
    k = int(np.nanargmax(values))
    if not gradients:
        return float(values[k]), None
    d_gap = point_sensitivity(results, b2, p2)[k] - point_sensitivity(results, b1, p1)[k]  # (3, n_design)
    d_relative = point_sensitivity(results, b2, p2, kind="velocity")[k] - point_sensitivity(results, b1, p1, kind="velocity")[k]
    d_e = (d_gap - np.outer(e[k], e[k] @ d_gap)) / length[k]
    d_rate = relative[k] @ d_e + e[k] @ d_relative
    d_speed = motion[k] @ point_sensitivity(results, lip.body, lip.name, kind="velocity")[k] / speed[k]
    d_cap = hydraulics.area_gradients(order, design)[0]
    d_pressure = design_gradient(hydraulics.relief[0], order, design)
    magnitude = abs(rate[k])
    gradient = (d_pressure * cap * magnitude + pressure * d_cap * magnitude + pressure * cap * np.sign(rate[k]) * d_rate) / speed[k] - (
        pressure * cap * magnitude * d_speed / speed[k] ** 2
    )
    return float(values[k]), gradient / 1e3


def _held_at(problem: StudyProblem, results: Results, q: Quantity, k: int):
    """The solve holding ``q``'s load at time point k and its multipliers' design changes."""
    from kinegen.forces.sensitivity import MultiplierChanges
    from kinegen.forces.statics import Statics, pose_results

    body, point, force = _constant_load(problem, q)
    statics = Statics(pose_results(results.system, results.q[k : k + 1], results.inputs[k : k + 1]), problem.model)
    matrix, multipliers = statics.hold(body, point, force)
    return statics, MultiplierChanges(statics, matrix, multipliers, body, point, force)


def _pin_load(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """The largest force (kN) the joint carries over the case holding the load, and its derivative there."""
    from kinegen.forces import forces

    held = forces(results, problem.model, [str(q.load)])
    magnitude = np.linalg.norm(held.reactions[str(q.actuator)].force, axis=1)
    k = int(np.argmax(magnitude))
    if not gradients:
        return float(magnitude[k]) / 1e3, None
    _, changes = _held_at(problem, results, q, k)
    force, d_force, _, _ = changes.reaction(next(j for j in problem.model.joints if j.name == q.actuator))
    return float(magnitude[k]) / 1e3, force[0] @ d_force[0] / magnitude[k] / 1e3


def _tool_force(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """Over the case's poses, the largest force (kN) the point can exert along the direction, every
    cylinder at most at its relief setting (a force map's value), and its derivative at that pose."""
    from kinegen.forces.sensitivity import MultiplierChanges
    from kinegen.forces.statics import Statics, pose_results

    system, model = results.system, problem.model
    (body, point), direction = q.points[0], np.asarray(q.axis, dtype=float)
    statics = Statics(results, model)
    load = np.broadcast_to(-direction, (len(results.times), 3))  # the machine holds -F when the tool exerts F
    per_newton = statics.element_forces(statics.hold(body, point, load)[1])
    by_cylinder = statics.hydraulic_limits(per_newton, working=True)
    names = list(by_cylinder)
    limits = np.stack([by_cylinder[name][0] for name in names])
    capacity = limits.min(axis=0)
    k = int(np.argmax(capacity))
    value = float(capacity[k]) / 1e3
    if not gradients:
        return value, None
    single = Statics(pose_results(system, results.q[k : k + 1], results.inputs[k : k + 1]), model)
    matrix, multipliers = single.hold(body, point, load[k : k + 1])
    changes = MultiplierChanges(single, matrix, multipliers, body, point, load[k : k + 1])
    actuator = problem.actuators[names[int(np.argmin(limits[:, k]))]]
    j = [e.name for e in single.elements].index(actuator.name)
    f, d_f = per_newton[k, j], -changes.d_multipliers[0, single.joint_rows + j]
    return value, _limit_gradient(actuator, f, d_f, system.design, True) / 1e3


def _limit_gradient(actuator, f: float, d_f: np.ndarray, design: dict[str, float], working: bool, carried: float = 0.0,
                    d_carried: np.ndarray | float = 0.0) -> np.ndarray:  # fmt: skip
    """d/dp of the load W = (setting x area - s carried) / |f| at which ``actuator`` reaches its setting
    (f its force per unit load, s = sign f, ``carried`` the force it holds before the load: the
    machine's weight): dW = (setting area (d setting / setting + d area / area) - s d carried) / |f|
    - W s df / |f|; zero where the carried force alone is beyond it."""
    from kinegen.forces.statics import hydraulic_limit

    hydraulics = actuator.hydraulics
    order = list(design)
    capacity, setting, side = hydraulic_limit(actuator, np.array([f]), design, working, np.array([carried]))
    if capacity[0] <= 0.0:
        return np.zeros(len(order))
    cap_side = side[0] == "cap"
    area = hydraulics.areas(design)[0 if cap_side else 1]
    d_area = hydraulics.area_gradients(order, design)[0 if cap_side else 1]
    settings = hydraulics.relief if working else hydraulics.holding
    d_setting = design_gradient(settings[0 if cap_side else 1], order, design)
    sign = np.sign(f)
    return (setting[0] * area * (d_setting / setting[0] + d_area / area) - sign * d_carried) / abs(f) - capacity[0] * sign * d_f / abs(f)


def _lift_capacity(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """The lift capacity (kN: a load's weight) with the lift point at ``q.at`` over ``q.over``: ISO
    10567's rating (the smaller of 75 % of the tipping load and 87 % of the hydraulic capacity) or
    either whole limit (``q.limit``). Its derivative is that of the limit that rules, the placing
    inputs moving with the design (du/dp = -(dP/du)^-1 dP/dp keeps the point in place)."""
    from kinegen.forces.lift import HYDRAULIC_SHARE, TIPPING_SHARE, G, Placer, tipping_load_changes
    from kinegen.forces.sensitivity import MultiplierChanges, TangentChanges
    from kinegen.runtime.sensitivity import configuration_sensitivities

    system, model = results.system, problem.model
    chart = model.lift_chart
    placer = Placer(system, model)
    found = placer.at(*q.at)
    if found is None:
        raise KinegenError(f"{q.label}: the lift point cannot be placed there")
    side = q.over == "side"
    tipping = found.tipping_side if side else found.tipping_front  # kg
    if q.limit == "rated":
        rated, ruling = found.rated(side)
        value, share = rated * G, HYDRAULIC_SHARE if ruling == "hydraulic" else TIPPING_SHARE
    else:
        ruling, share = q.limit, 1.0
        value = found.capacity if ruling == "hydraulic" else tipping * G
    if not np.isfinite(value):
        raise KinegenError(f"{q.label}: the machine cannot tip over its {q.over} with the load there (inside the tipping line)")
    if not gradients:
        return value / 1e3, None
    u = np.array([found.inputs[n] for n in system.driver_names])
    _, pose, statics, matrix, multipliers, weight = placer.held(u[placer.index])
    body, point = chart.point.body, chart.point.name
    by_design, by_input = configuration_sensitivities(system, pose[:, None], u[:, None])
    position = statics.position(body, statics.local(body, point))
    jacobian = np.zeros((3, system.n_velocity))
    jacobian[:, statics.columns(body)] = statics.point_jacobian(body, position)[0]
    moved = by_input[0][:, placer.index]  # dq/du of the placing inputs, (n_v, 2)
    in_plane = [0, 2]
    d_point = TangentChanges(statics, by_design).point(body, point)[1][0]  # dP/dp at held inputs, (3, P)
    d_inputs = -np.linalg.solve((jacobian @ moved)[in_plane], d_point[in_plane])  # (2, P)
    moving = by_design + (moved @ d_inputs)[None]
    if ruling == "tipping":
        d_front, d_side = tipping_load_changes(model, statics, TangentChanges(statics, moving), placer.weighed, q.at[0])
        return value / 1e3, share * G * (d_side if side else d_front) / 1e3
    change = MultiplierChanges(statics, matrix, multipliers, body, point, np.array([[0.0, 0.0, -1.0]]), s=moving)
    names = [e.name for e in statics.elements]
    per_newton = statics.element_forces(multipliers)[0]
    actuator = next(a for a in model.actuators if a.name == found.limiting)
    k = names.index(actuator.name)
    f, d_f = per_newton[k], -change.d_multipliers[0, statics.joint_rows + k]
    carried, d_carried = 0.0, 0.0
    if weight is not None:  # the front's own weight, held before the load: its force and that force's change
        carried = statics.element_forces(weight)[0, k]
        changes = MultiplierChanges(statics, matrix, weight, None, None, None, s=moving, weights=statics.weight_terms(placer.weighed))
        d_carried = -changes.d_multipliers[0, statics.joint_rows + k]
    return value / 1e3, share * _limit_gradient(actuator, f, d_f, system.design, actuator.name == chart.lifting, carried, d_carried) / 1e3


def _cylinder_pressure(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """The largest pressure (MPa) the actuator needs over the case to hold the load, and its
    derivative at that time point (:mod:`kinegen.forces.sensitivity`, the inputs held)."""
    from kinegen.forces import forces

    held = forces(results, problem.model, [str(q.load)])
    pressure = held.pressures[str(q.actuator)]
    k = int(np.argmax(pressure.pressure))
    value = float(pressure.pressure[k]) / 1e6
    if not gradients:
        return value, None
    statics, changes = _held_at(problem, results, q, k)
    names = [e.name for e in statics.elements]
    d_force = -changes.d_multipliers[0, statics.joint_rows + names.index(str(q.actuator))]
    f = held.element_force(str(q.actuator))[k]
    return value, _pressure_gradient(problem.actuators[str(q.actuator)], results.system.design, bool(pressure.cap_side[k]), f, d_force)


def _pressure_gradient(actuator, design: dict[str, float], cap_side: bool, f: float, d_force: np.ndarray) -> np.ndarray:
    """d(pressure)/dp [MPa per unit] of the cylinder's force f on the side that carries it (p = |f| / A):
    sign(f) df / A - |f| dA / A^2."""
    hydraulics = actuator.hydraulics
    side = 0 if cap_side else 1
    area, d_area = hydraulics.areas(design)[side], hydraulics.area_gradients(list(design), design)[side]
    return (np.sign(f) * d_force / area - abs(f) * d_area / area**2) / 1e6


def _constant_load(problem: StudyProblem, q: Quantity) -> tuple[str, str, np.ndarray]:
    """``q``'s load as (body, point, its global force (1, 3)): what a gradient through the multipliers'
    sensitivities can hold (a constant force in global axes)."""
    load = problem.model.loads[str(q.load)]
    if load.axes != GROUND or any(x != 0 for x in load.moment) or any(e.free_symbols for e in load.force):
        raise KinegenError(f"{q.label}: its gradient needs a constant force in global axes (load {load.name})")
    return load.point.body, load.point.name, np.array([[float(x) for x in load.force]])


def _mass(model: Model, design: dict[str, float], q: Quantity) -> tuple[float, np.ndarray]:
    """The mass (t) of ``q.body`` or of the whole machine at ``design``, and its exact gradient (every
    design parameter, the module's order)."""
    order = list(design)
    if q.body == MACHINE:
        expressions = [b.inertia.mass for b in model.massive] + [model.machine.undercarriage_mass]
    else:
        expressions = [next(b for b in model.massive if b.name == q.body).inertia.mass]
    return (sum(design_value(e, design) for e in expressions) / 1e3,
            sum(design_gradient(e, order, design) for e in expressions) / 1e3)  # fmt: skip


def _tipping_margin(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """The smallest tipping margin (kN m) over the case and its lines; per time point every line's
    margin and its exact derivative (:func:`kinegen.forces.dynamics.tipping_margin`)."""
    from kinegen.forces.dynamics import tipping_margin

    loads = (str(q.load),) if q.load else ()
    margin = tipping_margin(results, problem.model, loads, q.inertia, changes=gradients)
    points = np.concatenate(list(margin.margins.values())) / 1e3
    k = int(np.argmin(points))
    if not gradients:
        return float(points[k]), None, (points, None)
    d_points = np.concatenate(list(margin.changes.values())) / 1e3
    return float(points[k]), d_points[k], (points, d_points)


def _peak_pressure(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """The largest pressure (MPa) the actuator needs over the case at its speed (inverse dynamics:
    the weights, the d'Alembert forces and the load, if any), and its exact derivative at that time
    point (:class:`kinegen.forces.sensitivity.MultiplierChanges` with ``inertia``, the inputs' time
    functions held)."""
    from kinegen.forces import forces
    from kinegen.forces.sensitivity import MultiplierChanges
    from kinegen.forces.statics import Statics

    model, name = problem.model, str(q.actuator)
    loads = [str(q.load)] if q.load else []
    held = forces(results, model, loads, inertia=True)
    pressure = held.pressures[name]
    k = int(np.argmax(pressure.pressure))
    value = float(pressure.pressure[k]) / 1e6
    if not gradients:
        return value, None
    at = results.time_points(slice(k, k + 1))
    statics = Statics(at, model)
    matrix = statics.matrix()
    multipliers = statics.solve(matrix, held.generalized_load[k : k + 1])
    body, point, force = _constant_load(problem, q) if q.load else (None, None, None)
    changes = MultiplierChanges(statics, matrix, multipliers, body, point, force, s=state_sensitivities(at)[0], inertia=True)
    names = [e.name for e in statics.elements]
    d_force = -changes.d_multipliers[0, statics.joint_rows + names.index(name)]
    f = held.element_force(name)[k]
    return value, _pressure_gradient(problem.actuators[name], results.system.design, bool(pressure.cap_side[k]), f, d_force)


def _cycle_time(problem: StudyProblem, results: Results, q: Quantity, gradients: bool):
    """The fastest timing of the case's path (s) with the bodies' weight and inertia and the load, if
    named, and its exact derivative (:func:`kinegen.forces.cycle.cycle_time`: the limits' exact
    sensitivities carried through the optimal profile's active constraints)."""
    from kinegen.forces.cycle import cycle_time

    value, gradient = cycle_time(results, problem.model, (str(q.load),) if q.load else (), gradient=gradients)
    return value, gradient


MEASURES: dict[str, Callable] = {
    "digging_force": _relief_tool_force,
    "crowd_force": _relief_tool_force,
    "cylinder_pressure": _cylinder_pressure,
    "pin_load": _pin_load,
    "lift_capacity": _lift_capacity,
    "tipping_margin": _tipping_margin,
    "peak_pressure": _peak_pressure,
    "cycle_time": _cycle_time,
    "tool_force": _tool_force,
    "transmission_angle": _transmission_angle,
    "rotation_range": _rotation_range,
    "stroke": _stroke,
    "actuator_margin": _actuator_margin,
    "toggle_margin": _toggle_margin,
}
# every quantity a study may name (kinegen.model.schema.QUANTITY_KINDS, the one list) is measured here:
#: quantities of the design alone, measured without a solve: (model, design, quantity) -> (value, gradient)
DESIGN_MEASURES: dict[str, Callable] = {"mass": _mass}
# the working range's figures by the envelope (above), the design's own by DESIGN_MEASURES, the others by MEASURES
check_registered("kinegen.analysis.studies", {k: None for k in QUANTITY_KINDS if k not in ("working_range", *DESIGN_MEASURES)}, MEASURES)


# ---- running a study ----------------------------------------------------------------------------
#: a stalled SLSQP run (line search) counts as converged when its constraints hold to this (in their units)
STALL_VIOLATION = 1e-5
def optimize(
    problem: StudyProblem,
    method: str = "SLSQP",
    gradients: str = "exact",
    max_iterations: int = 100,
    progress: Callable[[str], None] | None = None,
) -> StudyResult:
    """Run the study from the nominal design with SciPy's ``method`` (SLSQP or trust-constr) on
    the exact gradients (``gradients="exact"``) or SciPy's finite differences (``"fd"``);
    ``progress`` gets one line per iteration."""
    if method not in ("SLSQP", "trust-constr"):
        raise ValueError(f"method must be SLSQP or trust-constr, got {method!r}")
    if gradients not in ("exact", "fd"):
        raise ValueError(f"gradients must be exact or fd, got {gradients!r}")
    exact = gradients == "exact"
    start = time.perf_counter()
    problem.envelope = None
    problem.evaluations = problem.gradient_evaluations = 0
    p0 = np.array([problem.nominal_design[n] for n in problem.names])
    before = problem.measure(p0, gradients=False)
    spans = problem.bounds[:, 1] - problem.bounds[:, 0]
    cache: dict[tuple[bytes, bool], Measured] = {}
    jacobian_calls = 0

    best: list = [None, np.inf]  # the best feasible design measured: scaled x, objective

    def measured(x: np.ndarray, with_gradients: bool) -> Measured:
        key = np.asarray(x, dtype=float).tobytes()
        for wanted in ((key, True), (key, with_gradients)):
            if wanted in cache:
                return cache[wanted]
        if len(cache) > 8:
            cache.clear()
        m = cache[key, with_gradients] = problem.measure(problem.unscaled(x), with_gradients)
        value = problem.objective(m)[0]
        if value < best[1] and (not problem.study.constraints or problem.constraints(m)[0].min() >= -1e-9):
            best[:] = [np.clip(np.array(x, dtype=float), 0, 1), value]
        return m

    def fun(x: np.ndarray) -> float:
        return problem.objective(measured(x, exact))[0]

    def jac(x: np.ndarray) -> np.ndarray:
        return problem.objective(measured(x, True))[1] * spans

    def slack(x: np.ndarray) -> np.ndarray:
        return problem.constraints(measured(x, exact))[0]

    def slack_jac(x: np.ndarray) -> np.ndarray:
        return problem.constraints(measured(x, True))[1] * spans

    history: list[tuple[int, float, float, float]] = []

    def report(x: np.ndarray, *_args) -> None:
        m = measured(x, exact)
        worst = float(max(0.0, -problem.constraints(m)[0].min())) if problem.study.constraints else 0.0
        history.append((len(history) + 1, problem.objective(m)[0], worst, time.perf_counter() - start))
        if progress is not None:
            progress(f"  iteration {len(history):>3}: objective {history[-1][1]: .9g}, worst violation {worst:.2e}, {history[-1][3]:.1f} s")

    def counted(function: Callable) -> Callable:
        def call(x: np.ndarray):
            nonlocal jacobian_calls
            jacobian_calls += 1
            return function(x)

        return call

    x0 = problem.scaled(p0)
    best[:] = [x0, problem.objective(before)[0]]
    constraints: list = []
    if problem.study.constraints:
        constraints = [{"type": "ineq", "fun": slack, **({"jac": slack_jac} if exact else {})}]
    try:
        if method == "SLSQP":
            options = {"ftol": 1e-10, "maxiter": max_iterations}
            if not exact:
                options["eps"] = FD_STEP
            result = minimize(fun, x0, jac=jac if exact else None, method="SLSQP", bounds=[(0, 1)] * len(x0),
                              constraints=constraints, options=options, callback=report)  # fmt: skip
        else:
            from scipy.optimize import Bounds, NonlinearConstraint

            nonlinear = []
            if problem.study.constraints:
                nonlinear = [NonlinearConstraint(slack, 0, np.inf, jac=slack_jac if exact else "2-point", finite_diff_rel_step=FD_STEP)]
            result = minimize(fun, x0, jac=counted(jac) if exact else "2-point", method="trust-constr", bounds=Bounds(0, 1),
                              constraints=nonlinear, callback=report,
                              options={"maxiter": max_iterations, "gtol": 1e-9, "xtol": 1e-12, "finite_diff_rel_step": FD_STEP})  # fmt: skip
        x, success, message = result.x, bool(result.success), str(result.message)
        iterations, jacobians = int(getattr(result, "nit", len(history))), int(getattr(result, "njev", 0) or jacobian_calls)
        if method == "SLSQP" and not success and getattr(result, "status", None) == 8 and len(history) >= 2:
            # the line search stalls where a quantity is only piecewise smooth (a cycle time's active set changes from one
            # grid point to the next), or after a trial step outside the constraints brought it back to a point it had
            # reached: converged when the last iterate agrees to 1e-6 with one of the three before it that met the
            # constraints, and the constraints hold to 1e-5
            earlier = [h[1] for h in history[-4:-1] if h[2] <= STALL_VIOLATION] or [history[-2][1]]
            change, worst = min(abs(history[-1][1] - value) for value in earlier), history[-1][2]
            if change <= 1e-6 * max(1.0, abs(history[-1][1])) and worst <= STALL_VIOLATION:
                success = True
                message = (f"converged: SLSQP's line search stalled with the objective within {change:.1e} of an iterate "
                           f"just before and the constraints met to {worst:.1e}")  # fmt: skip
    except DesignFailure as exc:  # the optimizer stepped to a design that cannot be assembled: keep the best one measured
        x, success, iterations, jacobians = best[0], False, len(history), jacobian_calls
        message = f"stopped: {exc}; reported: the best feasible design measured"
    p = problem.unscaled(x)
    after = problem.measure(p, gradients=False)
    return StudyResult(
        study=problem.study,
        method=method,
        gradients="exact" if exact else "finite differences",
        bounds={n: (float(lo), float(hi)) for n, (lo, hi) in zip(problem.names, problem.bounds)},
        nominal=dict(zip(problem.names, p0.tolist())),
        optimum=dict(zip(problem.names, p.tolist())),
        before=before.values,
        after=after.values,
        objective_before=problem.objective(before)[0] * (-1 if problem.study.sense == "maximize" else 1),
        objective_after=problem.objective(after)[0] * (-1 if problem.study.sense == "maximize" else 1),
        active=problem.active(after, p),
        iterations=iterations,
        evaluations=problem.evaluations,
        gradient_evaluations=problem.gradient_evaluations if exact else jacobians,
        seconds=time.perf_counter() - start,
        success=success,
        message=message,
        progress=history,
    )


def write_optimized(model_file: str | Path, model: Model, result: StudyResult, out: str | Path) -> Path:
    """The model file with its design parameters' nominal values set to the study's optimum and
    its name to ``<model>_<study>`` (so that its generated modules do not replace the original's),
    written to ``out`` -- never over the input. Comments and layout are kept: only those scalars
    change, located by the YAML parser."""
    import yaml

    from kinegen.files import write_atomic

    source, target = Path(model_file), Path(out)
    if target.resolve() == source.resolve():
        raise ValueError(f"{out}: the optimized model is not written over its input {model_file}")
    text = source.read_text(encoding="utf-8")
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    top = {key.value: value for key, value in root.value}
    design = {key.value: value for key, value in top["design"].value}
    edits = [(top["model"].start_mark.index, top["model"].end_mark.index, f"{model.name}_{result.study.name}")]
    for name, value in result.optimum.items():
        nominal = next(v for k, v in design[name].value if k.value == "nominal")
        edits.append((nominal.start_mark.index, nominal.end_mark.index, repr(round(value, 12))))
    for begin, end, replacement in sorted(edits, reverse=True):
        text = text[:begin] + replacement + text[end:]
    header = (
        f"# Optimized by `kinegen optimize {model_file} --study {result.study.name}` ({result.method}, {result.gradients} "
        f"gradients): the nominal values of {', '.join(result.optimum)} are the study's optimum.\n"
    )
    write_atomic(target, header + text)
    return target
