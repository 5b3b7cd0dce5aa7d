"""How much oil a motion asks of the pumps, and how much power (a model's ``pumps:`` section,
:class:`kinegen.model.schema.Supply`).

Conventions (SI: m^3/s, Pa, W; ``L/min`` only in reports):

* **A cylinder's flow** is its cap area times its extension rate when it extends, its annulus area
  times the rate when it retracts (the other side's oil returns to tank); a hydraulic actuation
  element's flow sums its cylinders' (the actuator and those ``parallel`` to it).
* **A motor's flow** is its displacement [m^3/rad] times the joint's turn rate.
* **Confluence**: an element fed by several pumps draws from them in equal shares; a pump's flow is
  the sum of its shares.
* **Pressures and power** (with the forces of a solve): an element's filling pressure is the pressure
  on the side the pump fills -- the cap side's force / cap area while extending, the rod side's while
  retracting, zero where the load pulls the cylinder along (it meters out); a motor's, torque /
  displacement where it drives. A pump delivers at the highest filling pressure among the elements
  it feeds; its power is that pressure times its flow; the engine's load is the pumps' powers together
  (total power control), limited by ``engine_power``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegen.model import Model
from kinegen.model.schema import GROUND, design_value
from kinegen.runtime import kinematics
from kinegen.runtime.results import Results

#: m^3/s -> L/min
LITRES_PER_MINUTE = 60000.0


@dataclass
class Flows:
    """The pumps' flows (and, with forces, pressures and power) along a solved motion."""

    times: np.ndarray  #: (K,) [s]
    elements: dict[str, np.ndarray]  #: each fed element's flow (K,) [m^3/s]
    pumps: tuple[str, ...]
    flow: np.ndarray  #: (P, K) [m^3/s]
    max_flow: np.ndarray  #: (P,) [m^3/s]
    max_pressure: np.ndarray  #: (P,) [Pa]
    engine_power: float  #: [W]
    pressure: np.ndarray | None = None  #: (P, K) [Pa] with forces, else None
    power: np.ndarray | None = None  #: (P, K) [W] with forces, else None

    def spans(self, excess: np.ndarray) -> list[tuple[float, float, int]]:
        """(t start, t end, index of the largest) of each run of time points where ``excess`` (K,) > 0."""
        out, k = [], 0
        while k < len(excess):
            if excess[k] > 0:
                end = k
                while end + 1 < len(excess) and excess[end + 1] > 0:
                    end += 1
                out.append((float(self.times[k]), float(self.times[end]), k + int(np.argmax(excess[k : end + 1]))))
                k = end + 1
            else:
                k += 1
        return out

    def flow_excesses(self) -> list[tuple[str, float, float, float, float]]:
        """(pump, t start, t end, largest demand [m^3/s], at time) where a pump's demand exceeds its largest flow."""
        found = []
        for p, name in enumerate(self.pumps):
            for t0, t1, k in self.spans(self.flow[p] - self.max_flow[p] * (1 + 1e-12)):
                found.append((name, t0, t1, float(self.flow[p, k]), float(self.times[k])))
        return sorted(found, key=lambda item: item[1])

    def power_excesses(self) -> list[tuple[float, float, float, float]]:
        """(t start, t end, largest power [W], at time) where the pumps need more than the engine gives."""
        if self.power is None:
            return []
        total = self.power.sum(axis=0)
        return [(t0, t1, float(total[k]), float(self.times[k])) for t0, t1, k in self.spans(total - self.engine_power * (1 + 1e-12))]

    def table(self) -> tuple[list[str], np.ndarray]:
        """The CSV's columns: per pump its flow and largest flow [m^3/s] (with forces: its pressure [Pa]
        and power [W]); with forces, the engine's load and its power [W]."""
        names, columns = [], []
        for p, name in enumerate(self.pumps):
            names += [f"pump.{name}.flow", f"pump.{name}.max_flow"]
            columns += [self.flow[p], np.full(len(self.times), self.max_flow[p])]
            if self.pressure is not None:
                names += [f"pump.{name}.pressure", f"pump.{name}.power"]
                columns += [self.pressure[p], self.power[p]]
        if self.power is not None:
            names += ["engine.power", "engine.power_limit"]
            columns += [self.power.sum(axis=0), np.full(len(self.times), self.engine_power)]
        return names, np.column_stack(columns)


def turn_rate(results: Results, model: Model, joint_name: str) -> np.ndarray:
    """(K,) the rate at which ``joint_name``'s second body turns relative to its first about the
    joint's axis (carried by the first body) [rad/s]."""
    joint = next(j for j in model.joints if j.name == joint_name)
    design = results.system.design
    axis = np.array([design_value(x, design) for x in joint.axis1], dtype=float)
    axis = axis / np.linalg.norm(axis)
    count = len(results.times)
    omega = {b: np.zeros((count, 3)) if b == GROUND else kinematics.omega(results, b) for b in (joint.body1, joint.body2)}
    carried = np.broadcast_to(axis, (count, 3)) if joint.body1 == GROUND else kinematics.rotation_matrix(results, joint.body1) @ axis
    return np.einsum("ki,ki->k", carried, omega[joint.body2] - omega[joint.body1])


def flows(results: Results, model: Model, held=None) -> Flows:
    """The flows the motion ``results`` asks of ``model``'s pumps (see the module docstring); with
    ``held`` (:class:`kinegen.forces.statics.Forces` of the same motion), also the pumps' pressures and
    power. The pumps' flows, pressures and powers are the generated module's ``supply`` kernel (q, v,
    f[, p]), the one the standalone C program calls; each element's flow (:attr:`Flows.elements`) is
    computed here from its areas and rates."""
    supply = model.supply
    if supply is None:
        raise ValueError(f"{model.name} has no pumps: section")
    system = results.system
    kernel = system.kernels.get("supply")
    if kernel is None or system.statics is None:
        raise ValueError(f"{system.model}/{system.case}: the module has no supply kernel (built before kinegen declared it); "
                         f"rebuild it with `kinegen build <model>.yaml --param {system.parametrization.name}`")  # fmt: skip
    design = system.design
    actuators = {a.name: a for a in model.actuators}
    motors = {m.name: m for m in model.motors}
    element_flow: dict[str, np.ndarray] = {}
    for name in supply.circuits:
        if name in actuators:
            cap, annulus = actuators[name].hydraulics.areas(design)
            rates = [kinematics.actuator_rate(results, member.name) for member in model.members(name)]
            element_flow[name] = sum(np.where(rate > 0, cap * rate, -annulus * rate) for rate in rates)
        else:
            motor = motors[name]
            element_flow[name] = design_value(motor.displacement, design) * np.abs(turn_rate(results, model, motor.joint))
    count = len(results.times)
    force = np.zeros((len(system.statics.elements), count))
    if held is not None:
        force = np.array([held.element_force(name) for name, _ in system.statics.elements])
    flow, pressure, power, _ = (_rows(values, count) for values in kernel(results.q.T, results.v.T, force))
    return Flows(results.times, element_flow, tuple(p.name for p in supply.pumps), flow,
                 np.array([design_value(p.max_flow, design) for p in supply.pumps]),
                 np.array([design_value(p.max_pressure, design) for p in supply.pumps]), float(design_value(supply.engine_power, design)),
                 None if held is None else pressure, None if held is None else power)  # fmt: skip


def _rows(values, count: int) -> np.ndarray:
    """A kernel's output on a batch of ``count`` columns as rows (a row it found constant, broadcast)."""
    return np.array([np.broadcast_to(np.asarray(row, dtype=float), (count,)) for row in values])
