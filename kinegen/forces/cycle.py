"""The fastest timing of a case's path: time-optimal path parametrization with the machine's limits.

A case's solved motion is a path of poses q(s), s its own time. Re-timed as s(t) with path speed
ṡ >= 0, the machine moves with

    v = q' ṡ,   a = q' s̈ + q'' ṡ²

where q' and q'' are the case's own velocity and acceleration at s (the velocity and acceleration
equations are linear in the inputs' rates). Along the path, with u = s̈ and x = ṡ²:

* **flows** are linear in ṡ: a cylinder's flow is its cap (extending) or annulus (retracting) area
  times |L'(s)| ṡ, a motor's its displacement times |θ'(s)| ṡ, a pump's its share of what it feeds
  (:mod:`kinegen.forces.supply`): every pump's largest flow bounds x from above;
* **forces** are affine in (u, x): the inverse dynamics Φ_qᵀ λ = Q_loads + Q_inertia(v, a) holds
  the case's loads, the weight (u = x = 0), the inertia of q' s̈ and of q'' ṡ² plus the velocity
  terms of q' ṡ; so an element's force is F0 + Fu u + Fx x, from three force solves per point.
  Each cylinder's force stays within the settings :func:`kinegen.forces.statics.forces` checks it
  against (the relief setting on the side that does the work -- no higher than its pumps' largest
  pressure --, the holding setting on the other); a motor's torque within its displacement times
  its pumps' largest pressure;
* **the tipping margin** (a machine: section) is affine in (u, x) too: it stays >= 0 about every
  tipping line;
* **power** (pump pressure x flow, the pumps together within the engine's power) is not linear in
  (u, x): it is bounded as a path speed, ṡ <= P / Σ_p p_p c_p with the pumps' pressures p_p of the
  profile before, repeated until the profile stops changing (a fixed point: the final profile's own
  pressures meet the bound);
* **speed limits** of actuators (optional) bound |L'| ṡ.

The limits are met at the grid points of the path (the case's solve grid) with s̈ constant between
two points (toppra's reachability analysis, collocation): exactly the points the re-timed case is
solved at. Every limit is tightened by :data:`MARGIN` (relative) so that the re-timed solve's
checks, which allow no excess, hold through the solver's rounding.

Units SI; s in seconds of the case's own time, ṡ dimensionless, s̈ in 1/s.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinegen.errors import KinegenError
from kinegen.forces.reachability import PowerLimit
from kinegen.model import Model
from kinegen.runtime import kinematics
from kinegen.runtime.results import Results

#: every limit is met with this relative room (the re-timed solve's checks allow no excess at all)
MARGIN = 1e-6
#: a constraint within this (relative) of its limit is active (limits the motion there)
ACTIVE = 1e-4


@dataclass(frozen=True)
class PathConstraints:
    """The limits along a path at its grid points s (N+1,), in toppra's canonical form.

    Linear rows: ``rows_u * s̈ + rows_x * ṡ² <= rows_bound`` (each (N+1, m), scaled so that the
    bound is the fraction of the limit left); path-speed bounds ``ṡ <= speed_bound`` (N+1, k)."""

    s: np.ndarray
    row_names: tuple[str, ...]
    rows_u: np.ndarray
    rows_x: np.ndarray
    rows_bound: np.ndarray
    speed_names: tuple[str, ...]
    speed_bound: np.ndarray
    power: PowerLimit | None = None
    #: with changes: each field's exact derivative by the design parameters (parameters last)
    changes: dict = dataclasses.field(default_factory=dict)

    def slack(self, u: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The fraction of every limit left at (u, x) (N+1,) each: rows (N+1, m), speeds (N+1, k)."""
        rows = self.rows_bound - self.rows_u * u[:, None] - self.rows_x * x[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            speeds = 1.0 - np.sqrt(np.maximum(x, 0.0))[:, None] / self.speed_bound
        return rows, np.where(np.isfinite(self.speed_bound), speeds, np.inf)


@dataclass
class Cycle:
    """The fastest timing of a case's path (:func:`fastest`)."""

    model: str
    case: str
    s: np.ndarray  #: (N+1,) grid points of the path, the case's own time [s]
    speed: np.ndarray  #: (N+1,) path speed ṡ at them
    acceleration: np.ndarray  #: (N+1,) path acceleration s̈ from each point to the next (at the last: 0, standing)
    times: np.ndarray  #: (N+1,) the re-timed motion's time at each point [s]
    constraints: PathConstraints
    limiting: np.ndarray  #: (N+1,) of str: the constraint with the least room at each point
    room: np.ndarray  #: (N+1,) that constraint's fraction left (<= ACTIVE: active)
    controllable: np.ndarray  #: (N+1, 2) the controllable sets of ṡ² (reachability analysis)
    loads: tuple[str, ...]
    speed_limits: dict[str, float] = dataclasses.field(default_factory=dict)  #: actuator or motor -> largest speed

    @property
    def duration(self) -> float:
        """The re-timed motion's duration [s]."""
        return float(self.times[-1] - self.times[0])

    @property
    def own_duration(self) -> float:
        """The case's own duration [s]."""
        return float(self.s[-1] - self.s[0])

    def phases(self) -> list[tuple[str, float, float, float, float]]:
        """Runs of points limited by one constraint: (name, s start, s end, t start, t end)."""
        out, k = [], 0
        names = self.limiting
        while k < len(names):
            end = k
            while end + 1 < len(names) and names[end + 1] == names[k]:
                end += 1
            out.append((str(names[k]), float(self.s[k]), float(self.s[end]), float(self.times[k]), float(self.times[end])))
            k = end + 1
        return out

    def timing_table(self) -> tuple[list[str], np.ndarray]:
        """The re-timing as columns: t [s], s [s], ṡ, s̈ [1/s] and the limiting constraint's room."""
        return ["t", "s", "s_dot", "s_ddot", "room"], np.column_stack(
            [self.times, self.s, self.speed, self.acceleration, self.room]
        )


def path_times(s: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """The time at every grid point of a path run at ``speed`` (ṡ, (N+1,)) with s̈ constant between
    points: each step takes 2 Δs / (ṡ_i + ṡ_(i+1))."""
    steps = np.diff(s)
    with np.errstate(divide="ignore"):
        taken = 2 * steps / (speed[:-1] + speed[1:])
    if not np.isfinite(taken).all():
        k = int(np.argmax(~np.isfinite(taken)))
        raise KinegenError(
            f"the path speed is zero on both ends of the step at s = {s[k]:g} .. {s[k + 1]:g} s: the path cannot be timed"
        )
    return np.concatenate([[0.0], np.cumsum(taken)])


def _element_forces(results: Results, model: Model, loads: tuple[str, ...]) -> tuple[tuple[str, ...], np.ndarray]:
    """The elements' names and forces (K, n_elements) moving ``results`` with its inertia and weight
    and holding ``loads``."""
    from kinegen.forces.dynamics import inertial_load
    from kinegen.forces.statics import Statics

    statics = Statics(results, model)
    multipliers = statics.compiled_multipliers([model.loads[name] for name in loads], inertia=True)
    if multipliers is None:
        load = sum((statics.generalized_load(model.loads[name]) for name in loads), np.zeros((len(results.times), statics.n_v)))
        multipliers = statics.solve(statics.matrix(), load + inertial_load(results))
    return tuple(e.name for e in statics.elements), statics.element_forces(multipliers)


def path_constraints(results: Results, model: Model, loads: tuple[str, ...] = (), tipping: bool = True,
                     speed_limits: dict[str, float] | None = None, changes: bool = False) -> PathConstraints:  # fmt: skip
    """The limits of :mod:`this module <kinegen.forces.cycle>` along ``results`` (a case solved on its
    path grid), tightened by :data:`MARGIN`; with ``changes``, every coefficient's exact derivative by
    the design parameters too (:mod:`kinegen.forces.cycle_changes`; ``PathConstraints.changes``)."""
    from kinegen.forces import cycle_changes as cc
    from kinegen.forces.dynamics import tipping_margin
    from kinegen.forces.supply import flows, turn_rate

    supply = model.supply
    design = results.system.design
    count, n_design = len(results.times), len(design)
    names, row_u, row_x, bound = [], [], [], []
    d_row_u, d_row_x, d_bound = [], [], []
    zeros = np.zeros((count, n_design))

    def add(name: str, parts, d_parts, limit: np.ndarray, d_limit: np.ndarray, sign: float) -> None:
        """sign * (rest + per_u u + per_x x) <= limit, as a fraction of |limit|."""
        (rest, per_u, per_x), scale = parts, np.abs(limit)
        names.append(name)
        row_u.append(sign * per_u / scale)
        row_x.append(sign * per_x / scale)
        bound.append(np.sign(limit) * (1 - MARGIN) - sign * rest / scale)
        if changes:
            d_scale = np.sign(limit)[:, None] * d_limit
            (d_rest, d_u, d_x), s2 = d_parts, scale[:, None]
            d_row_u.append(sign * (d_u / s2 - per_u[:, None] * d_scale / s2**2))
            d_row_x.append(sign * (d_x / s2 - per_x[:, None] * d_scale / s2**2))
            d_bound.append(-sign * (d_rest / s2 - rest[:, None] * d_scale / s2**2))

    elements = None
    if model.massive:
        stacked = cc.stacked_motions(results, changes)
        if changes:
            elements, force, d_force = cc.element_force_changes(stacked, model, loads)
            d_parts_all = cc.split(d_force)
        else:
            elements, force = _element_forces(stacked, model, loads)
        parts_all = cc.split(force)
    pump_pressure = {p.name: cc.number(p.max_pressure, design) for p in supply.pumps} if supply is not None else {}
    fed_by = supply.circuits if supply is not None else {}
    for actuator in model.actuators:
        hydraulics = actuator.hydraulics
        if hydraulics is None or elements is None or actuator.name not in elements:
            continue
        k = elements.index(actuator.name)
        cap, annulus = hydraulics.areas(design)
        d_cap, d_annulus = hydraulics.area_gradients(list(design), design) if changes else (np.zeros(n_design),) * 2
        relief = [cc.number(x, design) for x in hydraulics.relief]
        holding = [cc.number(x, design) for x in hydraulics.holding]
        supplied = min((pump_pressure[p] for p in fed_by.get(actuator.name, ())), key=lambda item: item[0], default=(np.inf, zeros[0]))
        rate = sum(kinematics.actuator_rate(results, member.name) for member in model.members(actuator.name))
        working = [min(relief[side], supplied, key=lambda item: item[0]) for side in (0, 1)]  # relief, no higher than the pumps give
        setting = [np.where(rate > 0, working[0][0], holding[0][0]), np.where(rate < 0, working[1][0], holding[1][0])]
        d_setting = [np.where((rate > 0)[:, None], working[0][1], holding[0][1]), np.where((rate < 0)[:, None], working[1][1], holding[1][1])]
        parts = tuple(x[:, k] for x in parts_all)
        d_parts = tuple(x[:, k] for x in d_parts_all) if changes else None
        add(f"{actuator.name} pressure (cap side)", parts, d_parts, setting[0] * cap, d_setting[0] * cap + setting[0][:, None] * d_cap, 1.0)
        add(f"{actuator.name} pressure (rod side)", parts, d_parts, setting[1] * annulus, d_setting[1] * annulus + setting[1][:, None] * d_annulus, -1.0)
    for motor in model.motors:
        if motor.displacement is None or elements is None or motor.name not in elements or not fed_by.get(motor.name):
            continue
        k = elements.index(motor.name)
        displacement = cc.number(motor.displacement, design)
        pressure = min((pump_pressure[p] for p in fed_by[motor.name]), key=lambda item: item[0])
        torque = displacement[0] * pressure[0] * np.ones(count)
        d_torque = np.broadcast_to(displacement[1] * pressure[0] + displacement[0] * pressure[1], (count, n_design))
        parts = tuple(x[:, k] for x in parts_all)
        d_parts = tuple(x[:, k] for x in d_parts_all) if changes else None
        add(f"{motor.name} torque (positive)", parts, d_parts, torque, d_torque, 1.0)
        add(f"{motor.name} torque (negative)", parts, d_parts, torque, d_torque, -1.0)
    if tipping and model.tips:
        margin = tipping_margin(stacked, model, loads, changes=changes)
        for line in margin.margins:
            rest, per_u, per_x = cc.split(margin.margins[line])
            top = int(np.argmax(np.abs(rest)))
            scale = abs(rest[top])  # the margin at rest's size along the path
            names.append(f"tipping ({line})")
            row_u.append(-per_u / scale)
            row_x.append(-per_x / scale)
            bound.append(rest / scale - MARGIN)
            if changes:
                d_rest, d_u, d_x = cc.split(margin.changes[line])
                d_scale = np.sign(rest[top]) * d_rest[top]
                d_row_u.append(-(d_u / scale - per_u[:, None] * d_scale / scale**2))
                d_row_x.append(-(d_x / scale - per_x[:, None] * d_scale / scale**2))
                d_bound.append(d_rest / scale - rest[:, None] * d_scale / scale**2)
    speed_names, speed_bound, d_speed_bound = [], [], []
    rates = {}  # a hydraulic element's or speed-limited actuator's (rate, its derivative)

    def rate_of(name: str) -> tuple[np.ndarray, np.ndarray]:
        if name not in rates:
            if name in {m.name for m in model.motors}:
                joint = next(m.joint for m in model.motors if m.name == name)
                rates[name] = cc.turn_rate_changes(results, model, joint) if changes else (turn_rate(results, model, joint), None)
            else:
                rates[name] = cc.actuator_rate_changes(results, name) if changes else (kinematics.actuator_rate(results, name), None)
        return rates[name]

    def add_speed(name: str, limit: float, d_limit: np.ndarray, per_speed: np.ndarray, d_per_speed) -> None:
        """ṡ <= limit / per_speed (per_speed >= 0: what moves per unit path speed)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            value = limit * (1 - MARGIN) / per_speed
            speed_names.append(name)
            speed_bound.append(value)
            if changes:
                d_value = np.where(per_speed[:, None] > 0, (d_limit * (1 - MARGIN) - value[:, None] * d_per_speed) / per_speed[:, None], 0.0)
                d_speed_bound.append(d_value)

    demand = None
    element_flow: dict[str, tuple[np.ndarray, np.ndarray | None]] = {}
    if supply is not None:
        demand = flows(results, model)
        actuators, motors = {a.name: a for a in model.actuators}, {m.name: m for m in model.motors}
        for name in supply.circuits:  # each element's flow per unit path speed, and its derivative
            if not changes:
                element_flow[name] = (demand.elements[name], None)
                continue
            if name in actuators:
                cap, annulus = actuators[name].hydraulics.areas(design)
                d_cap, d_annulus = actuators[name].hydraulics.area_gradients(list(design), design)
                total, d_total = np.zeros(count), np.zeros((count, n_design))
                for member in model.members(name):
                    rate, d_rate = rate_of(member.name)
                    side, d_side = np.where(rate > 0, cap, annulus), np.where((rate > 0)[:, None], d_cap, d_annulus)
                    total += side * np.abs(rate)
                    d_total += d_side * np.abs(rate)[:, None] + side[:, None] * np.sign(rate)[:, None] * d_rate
            else:
                displacement = cc.number(motors[name].displacement, design)
                rate, d_rate = rate_of(name)
                total = displacement[0] * np.abs(rate)
                d_total = np.outer(np.abs(rate), displacement[1]) + displacement[0] * np.sign(rate)[:, None] * d_rate
            element_flow[name] = (total, d_total)
        for p, pump in enumerate(supply.pumps):
            d_flow = None
            if changes:
                d_flow = sum((element_flow[e][1] / len(fed) for e, fed in supply.circuits.items() if pump.name in fed), zeros)
            add_speed(f"pump {pump.name} flow", *cc.number(pump.max_flow, design), demand.flow[p], d_flow)
    for name, limit in (speed_limits or {}).items():
        rate, d_rate = rate_of(name)
        add_speed(f"{name} speed", limit, np.zeros(n_design), np.abs(rate), None if d_rate is None else np.sign(rate)[:, None] * d_rate)
    power = None
    if supply is not None and elements is not None:
        power = _power_limit(results, model, demand, elements, parts_all, d_parts_all if changes else None, element_flow, changes)

    def stack(items: list, shape: tuple) -> np.ndarray:
        return np.stack(items, axis=1) if items else np.zeros(shape)

    found = PathConstraints(results.times.copy(), tuple(names), stack(row_u, (count, 0)), stack(row_x, (count, 0)),
                            stack(bound, (count, 0)), tuple(speed_names), stack(speed_bound, (count, 0)), power)  # fmt: skip
    if changes:
        shape = (count, 0, n_design)
        found.changes.update(rows_u=stack(d_row_u, shape), rows_x=stack(d_row_x, shape), rows_bound=stack(d_bound, shape),
                             speed_bound=stack(d_speed_bound, shape))  # fmt: skip
    return found


def _power_limit(results: Results, model: Model, demand, elements: tuple[str, ...], parts, d_parts, element_flow,
                 changes: bool) -> PowerLimit:  # fmt: skip
    """The engine's limit on the pumps' power: each pump's flow per unit path speed and the filling
    pressures of the elements it feeds as affine functions of (s̈, ṡ²) (:mod:`kinegen.forces.supply`'s
    conventions: the cap side's force / cap area extending, the rod side's retracting, a motor's
    torque / displacement where it drives; nothing where the element does not take oil); with
    ``changes``, their derivatives (``PowerLimit.changes``)."""
    from kinegen.forces import cycle_changes as cc
    from kinegen.forces.supply import turn_rate

    design = results.system.design
    n_design = len(design)
    supply = model.supply
    actuators, motors = {a.name: a for a in model.actuators}, {m.name: m for m in model.motors}
    pump_of, rest, per_u, per_x, d_rest, d_per_u, d_per_x = [], [], [], [], [], [], []
    for name, fed in supply.circuits.items():
        k = elements.index(name)
        if name in actuators:
            cap, annulus = actuators[name].hydraulics.areas(design)
            d_cap, d_annulus = actuators[name].hydraulics.area_gradients(list(design), design)
            rate = sum(kinematics.actuator_rate(results, member.name) for member in model.members(name))
            scale = np.where(rate > 0, 1 / cap, np.where(rate < 0, -1 / annulus, 0.0))
            d_scale = np.where((rate > 0)[:, None], -d_cap / cap**2, np.where((rate < 0)[:, None], d_annulus / annulus**2, 0.0))
        else:
            motor = motors[name]
            rate = turn_rate(results, model, motor.joint)
            displacement, d_displacement = cc.number(motor.displacement, design)
            scale = np.sign(rate) / displacement
            d_scale = -np.outer(np.sign(rate), d_displacement) / displacement**2
        taking = demand.elements[name] > 0
        for pump in fed:
            pump_of.append(demand.pumps.index(pump))
            for values, out, j in ((rest, d_rest, 0), (per_u, d_per_u, 1), (per_x, d_per_x, 2)):
                values.append(np.where(taking, parts[j][:, k] * scale, -np.inf if j == 0 else 0.0))
                if changes:
                    change = d_parts[j][:, k] * scale[:, None] + parts[j][:, k][:, None] * d_scale
                    out.append(np.where(taking[:, None], change, 0.0))
    engine, d_engine = cc.number(supply.engine_power, design)
    flow = demand.flow.T.copy()
    found = PowerLimit(engine * (1 - MARGIN), np.array(pump_of), flow, np.column_stack(rest), np.column_stack(per_u), np.column_stack(per_x))
    if changes:
        d_flow = np.zeros((*flow.shape, n_design))
        for p, pump in enumerate(supply.pumps):
            d_flow[:, p] = sum((element_flow[e][1] / len(fed) for e, fed in supply.circuits.items() if pump.name in fed),
                               np.zeros((len(flow), n_design)))  # fmt: skip
        found.changes.update(power=d_engine * (1 - MARGIN), flow=d_flow, rest=np.stack(d_rest, axis=1), per_u=np.stack(d_per_u, axis=1),
                             per_x=np.stack(d_per_x, axis=1))  # fmt: skip
    return found


def fastest(results: Results, model: Model, loads: tuple[str, ...] = (), tipping: bool = True,
            speed_limits: dict[str, float] | None = None) -> Cycle:  # fmt: skip
    """The fastest timing of the path of ``results`` (a case of ``model`` solved on the grid the
    limits are checked at) from rest to rest, with the case's ``loads`` held (see the module
    docstring)."""
    from kinegen.forces.reachability import Reachability

    if not results.complete:
        raise KinegenError("a cycle needs the whole path solved; this solve stopped early")
    constraints = path_constraints(results, model, loads, tipping, speed_limits)
    x_max = np.min(constraints.speed_bound**2, axis=1, initial=np.inf)
    profile = Reachability(constraints.s, constraints.rows_u, constraints.rows_x, constraints.rows_bound, x_max,
                           constraints.power).solve()  # fmt: skip
    speed, acceleration = profile.speed, np.append(profile.acceleration, 0.0)  # at the end it stands: s̈ = 0 after arriving
    rows, speeds = constraints.slack(acceleration, speed**2)
    labels = [*constraints.row_names, *constraints.speed_names]
    room = np.concatenate([rows, speeds], axis=1)
    if constraints.power is not None:
        need = np.array([constraints.power.need(i, acceleration[i], speed[i] ** 2) for i in range(len(speed))])
        room = np.column_stack([room, 1 - need / constraints.power.power])
        labels.append("engine power")
    least = np.argmin(room, axis=1)
    return Cycle(model.name, results.system.case, results.times.copy(), speed, acceleration, path_times(results.times, speed),
                 constraints, np.array(labels)[least], room[np.arange(len(least)), least], profile.controllable, tuple(loads),
                 dict(speed_limits or {}))  # fmt: skip


def retimed_inputs(
    system, s: np.ndarray, speed: np.ndarray, acceleration: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The case's driver inputs along the re-timed path: u = f(s), u̇ = f'(s) ṡ, ü = f''(s) ṡ² + f'(s) s̈
    (each (n_inputs, N+1)), f the case's own input functions of its time."""
    u, ud, udd = system.checked_inputs(np.asarray(s, dtype=float))
    return u, ud * speed, udd * speed**2 + ud * acceleration


def phase_summary(cycle: Cycle, smallest: float = 0.02) -> list[tuple[str, float, float, float, float]]:
    """The limiting constraint's runs as phases an engineer reads: runs shorter than ``smallest`` of
    the cycle time (switch points, flicker between two limits) join the run before them; (name, s
    start, s end, t start, t end)."""
    merged: list[list] = []
    for name, s0, s1, t0, t1 in cycle.phases():
        if merged and (t1 - t0 < smallest * cycle.duration or merged[-1][0] == name):
            merged[-1][2], merged[-1][4] = s1, t1
        else:
            merged.append([name, s0, s1, t0, t1])
    return [tuple(item) for item in merged]


def shares(cycle: Cycle) -> dict[str, float]:
    """Each constraint's share of the re-timed cycle's time: the steps it limits (at their start)."""
    taken = np.diff(cycle.times)
    out: dict[str, float] = {}
    for name, dt in zip(cycle.limiting[:-1], taken):
        out[str(name)] = out.get(str(name), 0.0) + float(dt)
    return {name: value / cycle.duration for name, value in sorted(out.items(), key=lambda item: -item[1])}


#: the timing file's first line: what it re-times
TIMING_HEADER = "# kinegen cycle timing: model {model}, case {case}, loads {loads}"


def write_timing(cycle: Cycle, path) -> Path:
    """The re-timing as CSV (a comment line naming the model, case and loads, then t, s, s_dot, s_ddot,
    room and the limiting constraint per point), written atomically; ``kinegen solve --timing`` solves it."""
    from kinegen.files import atomic_writer

    names, values = cycle.timing_table()
    lines = [
        TIMING_HEADER.format(model=cycle.model, case=cycle.case, loads=" ".join(cycle.loads) or "none"),
        ",".join([*names, "limit"]),
    ]
    lines += [",".join([*(repr(float(v)) for v in row), str(limit)]) for row, limit in zip(values, cycle.limiting)]
    path = Path(path)
    with atomic_writer(path) as handle:
        handle.write(("\n".join(lines) + "\n").encode())
    return path


@dataclass(frozen=True)
class Timing:
    """A timing file read back: the case it re-times and (t, s, ṡ, s̈) per point."""

    model: str
    case: str
    loads: tuple[str, ...]
    times: np.ndarray
    s: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray


def read_timing(path) -> Timing:
    """A file of :func:`write_timing`; a :class:`KinegenError` naming the file and what is wrong."""
    path = Path(path)
    try:
        text = path.read_text().splitlines()
    except OSError as error:
        raise KinegenError(f"{path}: cannot read the timing file ({error.strerror})") from None
    import re

    match = re.fullmatch(r"# kinegen cycle timing: model (\S+), case (\S+), loads (.*)", text[0]) if text else None
    if match is None or len(text) < 4 or not text[1].startswith("t,s,s_dot,s_ddot"):
        raise KinegenError(
            f"{path}: not a timing file of `kinegen cycle` (its first line: {TIMING_HEADER.format(model='M', case='C', loads='L')!r})"
        )
    try:
        values = np.array([[float(v) for v in line.split(",")[:4]] for line in text[2:]])
    except ValueError as error:
        raise KinegenError(f"{path}: a row is not numbers ({error})") from None
    if (
        not np.isfinite(values).all()
        or np.any(np.diff(values[:, 0]) <= 0)
        or np.any(np.diff(values[:, 1]) <= 0)
        or np.any(values[:, 2] < 0)
    ):
        raise KinegenError(f"{path}: t and s must increase and s_dot be >= 0 on every row")
    loads = () if match[3] == "none" else tuple(match[3].split())
    return Timing(match[1], match[2], loads, *values.T)


def retimed_motion(
    system, s: np.ndarray, speed: np.ndarray, acceleration: np.ndarray, times: np.ndarray, options=None
) -> Results:
    """The case's path solved at the re-timing (ṡ, s̈ at the path's points s, reached at ``times``),
    from tabulated inputs at exactly those points. The solver's warning about inputs sampled below
    their variation is silenced: s̈ steps at every point by design, and the points are the ones the
    limits were met at."""
    import warnings

    from kinegen.runtime import SolverOptions
    from kinegen.runtime.solver import SamplingWarning, Solver

    inputs = retimed_inputs(system, s, speed, acceleration)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SamplingWarning)
        return Solver(system, options or SolverOptions(compiled=system.native is not None)).solve(times, inputs=inputs)


@dataclass
class Check:
    """The re-timed motion solved again and measured against the limits it was timed to: the
    largest share of each limit used (1: touching), over the points."""

    results: Results
    used: dict[str, float]  #: limit -> the largest share used along the cycle
    flows: object = None  #: :class:`kinegen.forces.supply.Flows` with pressures and power (a model with pumps and masses)

    def exceeded(self) -> list[str]:
        return [name for name, value in self.used.items() if value > 1.0]

    def lines(self) -> list[str]:
        parts = ", ".join(f"{name} {100 * value:.4f} %" for name, value in self.used.items())
        verdict = "no limit exceeded" if not self.exceeded() else f"EXCEEDED: {', '.join(self.exceeded())}"
        return [f"check: the re-timed case solved at its {len(self.results.times)} points uses at most {parts} -- {verdict}"]

    def document(self, cycle: Cycle, parametrization: str, share: dict[str, float], phases) -> dict:
        """The JSON report of ``cycle`` and this check."""
        return {
            "model": cycle.model, "case": cycle.case, "parametrization": parametrization, "loads": list(cycle.loads),
            "cycle_time": cycle.duration, "own_duration": cycle.own_duration, "points": len(cycle.s),
            "limit_shares": share,
            "phases": [{"limit": n, "s_start": s0, "s_end": s1, "t_start": t0, "t_end": t1} for n, s0, s1, t0, t1 in phases],
            "check": {"largest_share_used": self.used, "exceeded": self.exceeded()},
        }  # fmt: skip


def check_retimed(system, model: Model, cycle: Cycle) -> Check:
    """Solve the re-timed case and measure it with the same code ``kinegen solve`` reports with:
    flows and power (:func:`kinegen.forces.supply.flows`), pressures and the tipping margin
    (:func:`kinegen.forces.statics.forces` with inertia), speed limits from the actuators' rates."""
    from kinegen.forces.statics import forces
    from kinegen.forces.supply import flows, turn_rate

    results = retimed_motion(system, cycle.s, cycle.speed, cycle.acceleration, cycle.times)
    used: dict[str, float] = {}
    held = forces(results, model, cycle.loads, inertia=True) if model.massive else None
    supplied = None
    if model.supply is not None:
        supplied = flows(results, model, held)
        for p, name in enumerate(supplied.pumps):
            used[f"pump {name} flow"] = float(supplied.flow[p].max() / supplied.max_flow[p])
        if supplied.power is not None:
            used["engine power"] = float(supplied.power.sum(axis=0).max() / supplied.engine_power)
    if held is not None:
        if held.pressures:
            used["pressure"] = float(max((p.pressure / p.limit).max() for p in held.pressures.values()))
        if held.tipping is not None and "tipping" in " ".join(cycle.constraints.row_names):
            scale = np.abs(np.stack(list(held.tipping.margins.values()))).max()
            used["tipping"] = float(1 - held.tipping.margin.min() / scale)  # 1: the margin touches zero
    for name, limit in cycle.speed_limits.items():
        motor = next((m for m in model.motors if m.name == name), None)
        rate = kinematics.actuator_rate(results, name) if motor is None else turn_rate(results, model, motor.joint)
        used[f"{name} speed"] = float(np.abs(rate).max() / limit)
    return Check(results, used, supplied)


def window_limits(cycle: Cycle, windows: list[tuple[str, float, float]]) -> list[tuple[str, float, str, float]]:
    """For each named span of the path (label, s start, s end in the case's own time): (label, the
    re-timed time it takes [s], the constraint that limits most of that time, its share of it)."""
    middle = 0.5 * (cycle.s[:-1] + cycle.s[1:])
    taken = np.diff(cycle.times)
    out = []
    for label, s0, s1 in windows:
        inside = (middle >= s0) & (middle < s1)
        spent: dict[str, float] = {}
        for name, dt in zip(cycle.limiting[:-1][inside], taken[inside]):
            spent[str(name)] = spent.get(str(name), 0.0) + float(dt)
        total = float(taken[inside].sum())
        name = max(spent, key=spent.get) if spent else "-"
        out.append((label, total, name, spent.get(name, 0.0) / total if total else 0.0))
    return out


def cycle_time(results: Results, model: Model, loads: tuple[str, ...] = (), tipping: bool = True,
               speed_limits: dict[str, float] | None = None, gradient: bool = True) -> tuple[float, np.ndarray | None]:  # fmt: skip
    """The fastest cycle time along the path of ``results`` [s] (:func:`fastest`'s, on the same grid)
    and, with ``gradient``, its exact derivative by every design parameter (P,) [s per unit]: the
    derivative of the discretized problem along its active constraints, the limits' coefficients
    differentiated exactly (:mod:`kinegen.forces.cycle_changes`) and carried through the profile's
    decisions (:func:`kinegen.forces.reachability.tangent_profile`)."""
    from kinegen.forces.reachability import Reachability, tangent_profile

    if not results.complete:
        raise KinegenError("a cycle needs the whole path solved; this solve stopped early")
    constraints = path_constraints(results, model, loads, tipping, speed_limits, changes=gradient)
    squared = constraints.speed_bound**2
    x_max = np.min(squared, axis=1, initial=np.inf)
    reach = Reachability(constraints.s, constraints.rows_u, constraints.rows_x, constraints.rows_bound, x_max, constraints.power)
    profile = reach.solve()
    duration = float(path_times(constraints.s, profile.speed)[-1])
    if not gradient:
        return duration, None
    n_design = len(results.system.design)
    d_x_max = np.zeros((len(x_max), n_design))
    if squared.shape[1]:
        which = np.argmin(squared, axis=1)
        at = np.arange(len(x_max))
        finite = np.isfinite(x_max)
        d_x_max[finite] = (2 * constraints.speed_bound[at, which][:, None] * constraints.changes["speed_bound"][at, which])[finite]
    power_changes = constraints.power.changes if constraints.power is not None else None
    _, _, d_duration = tangent_profile(reach, constraints.changes, power_changes, d_x_max)
    return duration, d_duration
