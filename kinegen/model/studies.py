"""Reading a model file's ``studies:`` section (design studies for ``kinegen optimize``).

```yaml
studies:
  bucket_linkage:
    description: free text
    parameters: [side_link, bucket_link]       # design parameters varied (the others nominal)
    maximize:                                  # or minimize: a list of weighted terms
      - {rotation_range: bucket, relative_to: arm, axis: [0, 1, 0], case: bucket_stroke}
    constraints:
      - {toggle_margin: [bucket_link, bucket], case: bucket_stroke, at_least: 0.08}
```

A term or constraint names one quantity (:data:`kinegen.model.schema.QUANTITY_KINDS`) by its
key; every quantity but ``working_range`` is measured over a ``case``. A term has an optional
``weight`` (default 1) and ``target`` (then it is weight x (quantity - target)^2; ``published``
takes a working-range figure's published value); a constraint ``at_least`` and/or ``at_most``.
"""

from __future__ import annotations

from typing import Any

from kinegen.errors import shown
from kinegen.model.schema import (
    GROUND,
    LIFT_LIMITS,
    LIFT_SIDES,
    MACHINE,
    QUANTITY_KINDS,
    TIPPING_KINDS,
    WORKING_RANGE_FIGURES,
    Actuator,
    Case,
    Quantity,
    Study,
    StudyConstraint,
    Term,
    WorkingRange,
)

#: the loader's reader of a model file (kinegen.model.loader._Reader: mapping, fail, scalar, ...); the
#: studies are read through it, so that their errors name the file and entry as every other's
Loader = Any

#: keys a term or constraint may have besides its quantity's
_QUANTITY_KEYS = {
    "rotation_range": ("relative_to", "axis"), "cylinder_pressure": ("load",), "pin_load": ("load",), "tool_force": ("direction",),
    "lift_capacity": ("over", "limit"), "tipping_margin": ("load",), "peak_pressure": ("load",), "cycle_time": ("load",),
}  # fmt: skip
_OPTIONAL_KEYS = tuple(sorted({key for keys in _QUANTITY_KEYS.values() for key in keys}))


def read_studies(
    loader: Loader, value: Any, cases: dict[str, Case], actuators: tuple[Actuator, ...], working_range: WorkingRange | None
) -> dict[str, Study]:
    """The ``studies:`` section, every entry checked against the model (names, cases, figures)."""
    studies = {}
    for key, spec in loader.mapping(value, "studies", loader.keys(value)).items():
        entry = f"studies.{key}"
        name = loader.name(key, entry)
        spec = loader.mapping(spec, entry, ("description", "parameters", "minimize", "maximize", "constraints"), ("parameters",))
        senses = [s for s in ("minimize", "maximize") if s in spec]
        if len(senses) != 1:
            raise loader.fail(entry, "expected exactly one of minimize or maximize (a list of terms)")
        parameters = spec["parameters"]
        if not isinstance(parameters, list) or not parameters:
            raise loader.fail(f"{entry}.parameters", "expected a list of design parameters")
        for i, parameter in enumerate(parameters):
            if not isinstance(parameter, str) or parameter not in loader.design:
                raise loader.fail(
                    f"{entry}.parameters[{i}]", f"{shown(parameter)} is not a design parameter (design: {', '.join(loader.design) or 'none'})"
                )
        if len(set(parameters)) != len(parameters):  # (all strings here)
            raise loader.fail(f"{entry}.parameters", "a parameter is named twice")
        description = spec.get("description", "")
        if not isinstance(description, str):
            raise loader.fail(f"{entry}.description", "expected a string")
        reader = _StudyReader(loader, cases, {a.name: a for a in actuators}, working_range)
        terms = tuple(reader.term(item, f"{entry}.{senses[0]}[{i}]") for i, item in enumerate(_items(loader, spec[senses[0]], f"{entry}.{senses[0]}")))
        constraints = tuple(
            reader.constraint(item, f"{entry}.constraints[{i}]") for i, item in enumerate(_items(loader, spec.get("constraints", []), f"{entry}.constraints"))
        )
        studies[name] = Study(name, tuple(parameters), senses[0], terms, constraints, description)
    return studies


def _items(loader: Loader, value: Any, entry: str) -> list:
    if not isinstance(value, list):
        raise loader.fail(entry, f"expected a list, got {type(value).__name__}")
    return value


class _StudyReader:
    def __init__(self, loader: Loader, cases: dict[str, Case], actuators: dict[str, Actuator], working_range: WorkingRange | None) -> None:
        self.loader, self.cases, self.actuators, self.working_range = loader, cases, actuators, working_range

    def term(self, value: Any, entry: str) -> Term:
        spec = self.loader.mapping(value, entry, (*QUANTITY_KINDS, "case", *_OPTIONAL_KEYS, "weight", "target"))
        quantity = self.quantity(spec, entry)
        weight = self.number(spec.get("weight", 1), f"{entry}.weight")
        target = spec.get("target")
        if target == "published":
            published = self.working_range.published if self.working_range else {}
            if quantity.kind != "working_range" or quantity.figure not in published:
                raise self.loader.fail(f"{entry}.target", f"'published' needs a working-range figure with a published value (published: {', '.join(published) or 'none'})")
            target = published[quantity.figure]
        elif target is not None:
            target = self.number(target, f"{entry}.target")
        return Term(quantity, weight, target)

    def constraint(self, value: Any, entry: str) -> StudyConstraint:
        spec = self.loader.mapping(value, entry, (*QUANTITY_KINDS, "case", *_OPTIONAL_KEYS, "at_least", "at_most"))
        quantity = self.quantity(spec, entry)
        low, high = (self.number(spec[k], f"{entry}.{k}") if k in spec else None for k in ("at_least", "at_most"))
        if low is None and high is None:
            raise self.loader.fail(entry, "a constraint needs at_least and/or at_most")
        if low is not None and high is not None and not low < high:
            raise self.loader.fail(entry, f"at_least {low} is not below at_most {high}")
        return StudyConstraint(quantity, low, high)

    def number(self, value: Any, entry: str) -> float:
        return float(self.loader.scalar(value, entry))

    def quantity(self, spec: dict, entry: str) -> Quantity:
        kinds = [k for k in QUANTITY_KINDS if k in spec]
        if len(kinds) != 1:
            raise self.loader.fail(entry, f"expected exactly one quantity ({', '.join(QUANTITY_KINDS)})")
        kind = kinds[0]
        where = f"{entry}.{kind}"
        for key in _OPTIONAL_KEYS:
            if key in spec and key not in _QUANTITY_KEYS.get(kind, ()):
                raise self.loader.fail(f"{entry}.{key}", f"not used by {kind}")
        what = spec[kind]
        if kind == "working_range":
            if "case" in spec:
                raise self.loader.fail(f"{entry}.case", "a working-range figure is measured over the working_range section's inputs, not a case")
            if self.working_range is None:
                raise self.loader.fail(where, "the model has no working_range section")
            if not isinstance(what, str) or what not in WORKING_RANGE_FIGURES:
                raise self.loader.fail(where, f"unknown figure {shown(what)} (one of {', '.join(WORKING_RANGE_FIGURES)})")
            return Quantity(kind, figure=what)
        if kind == "mass":
            if "case" in spec:
                raise self.loader.fail(f"{entry}.case", "a mass is the design's, not a case's")
            massive = getattr(self.loader, "massive", ())
            if what == MACHINE:
                if not self.tipping:
                    raise self.loader.fail(where, "the machine's mass needs the bodies' masses and a machine: section (the undercarriage)")
            elif what not in massive:
                raise self.loader.fail(where, f"expected {MACHINE} or a body with a mass ({', '.join(massive) or 'none'}), got {shown(what)}")
            return Quantity(kind, body=what)
        if kind == "lift_capacity":
            chart = getattr(self.loader, "lift_chart", None)
            if chart is None:
                raise self.loader.fail(where, "a lift capacity is measured at the lift_chart section's point: the model has none")
            if "case" in spec:
                raise self.loader.fail(f"{entry}.case", "a lift capacity is measured in the lift_chart section's case")
            if not isinstance(what, list) or len(what) != 2:
                raise self.loader.fail(where, f"expected [radius, height] (m), got {shown(what)}")
            radius, height = (self.number(x, f"{where}[{i}]") for i, x in enumerate(what))
            if radius <= 0:
                raise self.loader.fail(f"{where}[0]", "the radius is a distance from the swing axis: positive")
            over, limit = (self.choice(spec, key, choices, entry) for key, choices in (("over", LIFT_SIDES), ("limit", LIFT_LIMITS)))
            if limit == "tipping" and not self.tipping:
                raise self.loader.fail(f"{entry}.limit", "a tipping load needs the bodies' masses and a machine: section")
            return Quantity(kind, chart.case, at=(radius, height), over=over, limit=limit)
        if kind == "cycle_time":  # {cycle_time: <case>, load: ...}: the case is its value
            if "case" in spec:
                raise self.loader.fail(f"{entry}.case", "a cycle time names its case as its value: {cycle_time: digging}")
            if not isinstance(what, str) or what not in self.cases:
                raise self.loader.fail(where, f"a cycle time re-times a case's path: expected one of {', '.join(self.cases)}, got {shown(what)}")
            if not getattr(self.loader, "massive", ()) and getattr(self.loader, "supply", None) is None:
                raise self.loader.fail(where, "a cycle time needs what limits the motion: the bodies' masses or a pumps: section")
            return Quantity(kind, what, load=self.load(spec, entry, "a cycle time") if "load" in spec else None)
        case = spec.get("case")
        if not isinstance(case, str) or case not in self.cases:
            raise self.loader.fail(f"{entry}.case", f"{kind} is measured over a case: expected one of {', '.join(self.cases)}, got {shown(case)}")
        if kind == "tool_force":
            ref = self.loader.point_ref(what, where)
            if ref.body == GROUND:
                raise self.loader.fail(where, "a tool force acts at a point of a moving body")
            if not any(a.hydraulics is not None for a in self.actuators.values()):
                raise self.loader.fail(where, "a tool force is limited by the hydraulic cylinders: the model has none")
            direction = self.unit(spec, "direction", entry, "a tool force needs its direction (global)")
            return Quantity(kind, case, points=((ref.body, ref.name),), axis=direction)
        if kind == "tipping_margin":
            if not self.tipping:
                raise self.loader.fail(where, "a tipping margin needs the bodies' masses and a machine: section")
            if what not in TIPPING_KINDS:
                raise self.loader.fail(where, f"expected one of {', '.join(TIPPING_KINDS)} (with or without the d'Alembert forces), got {shown(what)}")
            load = self.load(spec, entry, "a tipping margin") if "load" in spec else None
            return Quantity(kind, case, load=load, inertia=what == "dynamic")
        if kind == "pin_load":
            joints = list(self.loader.joints)
            if not isinstance(what, str) or what not in joints:
                raise self.loader.fail(where, f"unknown joint {shown(what)} (joints: {', '.join(joints)})")
            return Quantity(kind, case, actuator=what, load=self.load(spec, entry, "a pin load"))
        if kind in ("digging_force", "crowd_force", "cylinder_pressure", "peak_pressure"):
            hydraulic = [a for a, actuator in self.actuators.items() if actuator.hydraulics is not None]
            if not isinstance(what, str) or what not in hydraulic:
                raise self.loader.fail(where, f"{shown(what)} is not an actuator with hydraulic data (those: {', '.join(hydraulic) or 'none'})")
            if kind == "cylinder_pressure":
                return Quantity(kind, case, actuator=what, load=self.load(spec, entry, "a cylinder pressure"))
            if kind == "peak_pressure":
                if not getattr(self.loader, "massive", ()):
                    raise self.loader.fail(where, "a peak pressure is the inverse dynamics' at speed: the model's bodies have no masses")
                return Quantity(kind, case, actuator=what, load=self.load(spec, entry, "a peak pressure") if "load" in spec else None)
            if getattr(self.loader, "tool_forces", None) is None:
                raise self.loader.fail(where, f"{kind} acts at the tool_forces section's lip: the model has none")
            return Quantity(kind, case, actuator=what)
        if kind in ("stroke", "actuator_margin"):
            if not isinstance(what, str) or what not in self.actuators:
                raise self.loader.fail(where, f"unknown actuator {shown(what)} (actuators: {', '.join(self.actuators) or 'none'})")
            if kind == "actuator_margin" and self.actuators[what].range is None:
                raise self.loader.fail(where, f"actuator {what} has no range")
            return Quantity(kind, case, actuator=what)
        if kind == "toggle_margin":
            bodies = what if isinstance(what, list) else [what]
            for i, body in enumerate(bodies):
                if not isinstance(body, str) or body == GROUND or body not in self.loader.bodies:
                    raise self.loader.fail(f"{where}[{i}]" if isinstance(what, list) else where, f"unknown moving body {shown(body)} (bodies: {', '.join(self.loader.bodies)})")
            return Quantity(kind, case, bodies=tuple(bodies))
        if kind == "transmission_angle":
            if not isinstance(what, list) or len(what) != 3:
                raise self.loader.fail(where, "expected three points 'body.point': the angle is at the second")
            refs = [self.loader.point_ref(x, f"{where}[{i}]") for i, x in enumerate(what)]
            return Quantity(kind, case, points=tuple((r.body, r.name) for r in refs))
        body = self.loader.body_name(what, where)
        if body == GROUND:
            raise self.loader.fail(where, "the ground does not rotate: name a moving body")
        relative_to = self.loader.body_name(spec.get("relative_to", GROUND), f"{entry}.relative_to")
        axis = self.unit(spec, "axis", entry, "a rotation range needs its axis (in the frame of relative_to)")
        return Quantity(kind, case, body=body, relative_to=relative_to, axis=axis)

    @property
    def tipping(self) -> bool:
        """Whether the model has what a tipping load needs: masses and a machine: section."""
        return bool(getattr(self.loader, "massive", ())) and getattr(self.loader, "machine", None) is not None

    def choice(self, spec: dict, key: str, choices: tuple[str, ...], entry: str) -> str:
        """``spec[key]``, one of ``choices`` (the first when absent)."""
        value = spec.get(key, choices[0])
        if value not in choices:
            raise self.loader.fail(f"{entry}.{key}", f"expected one of {', '.join(choices)}, got {shown(value)}")
        return value

    def load(self, spec: dict, entry: str, what: str) -> str:
        """``spec["load"]``: one of the model's loads, which ``what`` (the quantity, in words) holds."""
        loads = getattr(self.loader, "loads", {})
        if not isinstance(spec.get("load"), str) or spec["load"] not in loads:
            raise self.loader.fail(f"{entry}.load", f"{what} holds one of the model's loads ({', '.join(loads) or 'none'}), got {shown(spec.get('load'))}")
        return spec["load"]

    def unit(self, spec: dict, key: str, entry: str, missing: str) -> tuple[float, float, float]:
        """``spec[key]``: a non-zero vector of numbers, normalized."""
        if key not in spec:
            raise self.loader.fail(entry, missing)
        vector = self.loader.vector(spec[key], f"{entry}.{key}")
        values = [float(x) for x in vector]
        norm = sum(x * x for x in values) ** 0.5
        if norm < 1e-12 or vector.free_symbols:
            raise self.loader.fail(f"{entry}.{key}", "expected a non-zero vector of numbers")
        return (values[0] / norm, values[1] / norm, values[2] / norm)
