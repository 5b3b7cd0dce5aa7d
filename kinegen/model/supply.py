"""Reading a model's hydraulic supply (``pumps:``) -- the pumps, the engine power they share and the
circuits that say which pumps feed each actuation element (:class:`kinegen.model.schema.Supply`).

Units SI: flows in m^3/s (212 L/min is 212/60000), pressures in Pa, power in W. Every number may use
the design parameters.
"""

from __future__ import annotations

from typing import Any

from kinegen.errors import shown
from kinegen.model.schema import Actuator, Motor, Pump, Supply

#: the keys of ``pumps:``
KEYS = ("pumps", "engine_power", "circuits")


def read_supply(loader: Any, value: Any, actuators: tuple[Actuator, ...], motors: tuple[Motor, ...]) -> Supply:
    """``pumps: {pumps: {name: {max_flow, max_pressure}}, engine_power, circuits: {element: [pump, ...]}}``."""
    spec = loader.mapping(value, "pumps", KEYS, KEYS)
    pumps = []
    for key, item in loader.mapping(spec["pumps"], "pumps.pumps", loader.keys(spec["pumps"])).items():
        entry = f"pumps.pumps.{key}"
        loader.name(key, entry)
        item = loader.mapping(item, entry, ("max_flow", "max_pressure"), ("max_flow", "max_pressure"))
        flow = loader.positive(item["max_flow"], f"{entry}.max_flow", "m^3/s: a flow")
        loader.plausible(flow, f"{entry}.max_flow", "m^3/s", (1e-5, 0.1), "a pump's largest flow", "flows are in m^3/s: 212 L/min is 212/60000")
        pressure = loader.positive(item["max_pressure"], f"{entry}.max_pressure", "Pa: a pressure")
        loader.plausible(pressure, f"{entry}.max_pressure", "Pa", (1e6, 1e8), "a pump's largest pressure", "pressures are in Pa")
        pumps.append(Pump(key, flow, pressure))
    if not pumps:
        raise loader.fail("pumps.pumps", "name at least one pump")
    power = loader.positive(spec["engine_power"], "pumps.engine_power", "W: a power")
    loader.plausible(power, "pumps.engine_power", "W", (1e3, 2e6), "the engine power the pumps share", "power is in W: 110 kW is 110e3")
    hydraulic = {a.name for a in actuators if a.hydraulics is not None} | {m.name for m in motors if m.displacement is not None}
    names = [p.name for p in pumps]
    circuits: dict[str, tuple[str, ...]] = {}
    for key, item in loader.mapping(spec["circuits"], "pumps.circuits", loader.keys(spec["circuits"])).items():
        entry = f"pumps.circuits.{key}"
        if key not in hydraulic:
            raise loader.fail(entry, f"{shown(key)} is no actuator with hydraulic data or motor with a displacement "
                              f"(those: {', '.join(sorted(hydraulic)) or 'none'})")  # fmt: skip
        if not isinstance(item, (list, tuple)) or not item or not all(isinstance(n, str) for n in item):
            raise loader.fail(entry, f"expected a list of pump names, got {shown(item)}")
        unknown = [n for n in item if n not in names]
        if unknown or len(set(item)) != len(item):
            raise loader.fail(entry, f"unknown or repeated pump {shown(unknown or item)} (pumps: {', '.join(names)})")
        circuits[key] = tuple(item)
    missing = sorted(hydraulic - set(circuits))
    if missing:
        raise loader.fail("pumps.circuits", f"no pump feeds {', '.join(missing)}: give each hydraulic element its pumps")
    return Supply(tuple(pumps), power, circuits)

