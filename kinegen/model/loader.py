"""Load and validate a model file (YAML) into :class:`kinegen.model.schema.Model`.

Every problem raises :class:`kinegen.errors.ModelError` naming the file, the entry
(a dotted path such as ``joints.pivot.axis``) and what is wrong. Non-unit quaternions
are normalized with a :class:`ModelWarning`; everything else that is off is rejected.
"""

from __future__ import annotations

import hashlib
import re
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp
import yaml

import kinegen.model.expressions as expressions
from kinegen.errors import ExpressionError, KinegenError, ModelError, OverConstrainedError, shown
from kinegen.files import MAX_MODEL_BYTES, STDIN, read_bounded
from kinegen.model.expressions import compact
from kinegen.model.forces import (
    check_actuation,
    read_hydraulics,
    read_lift_chart,
    read_loads,
    read_motors,
    read_tool_forces,
    read_tool_points,
)
from kinegen.model.kinds import DRIVER_KINDS, JOINT_KINDS
from kinegen.model.masses import KEYS as MASS_KEYS
from kinegen.model.masses import read_gravity, read_inertia, read_machine
from kinegen.model.schema import (
    GROUND,
    PUBLISHED_FIGURES,
    STANDARD_GRAVITY,
    Actuator,
    Body,
    Case,
    DesignParameter,
    Driver,
    Joint,
    Model,
    PointRef,
    Vector,
    WorkingRange,
)
from kinegen.model.studies import read_studies
from kinegen.model.supply import read_supply
from kinegen.rotations.euler_angles import SEQUENCES, EulerAngles
from kinegen.rotations.euler_parameters import quaternion_matrix

NAME_PATTERN = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,63}$")
RESERVED = {"t", "pi", "ground", *expressions.FUNCTIONS}
#: Joint types and how many scalar equations each contributes (kinegen.model.kinds: the one list).
JOINT_EQUATIONS = {name: kind.equations for name, kind in JOINT_KINDS.items()}
JOINT_TYPES = tuple(JOINT_KINDS)
DRIVER_TYPES = tuple(DRIVER_KINDS)
ORTHONORMAL_TOLERANCE = 1e-9
MAX_FILE_BYTES = MAX_MODEL_BYTES
#: Nodes that anchors and aliases may add to a document when expanded (each use of an
#: alias counts its whole subtree): enough to share pieces, far too few for a "billion laughs".
MAX_ALIAS_NODES = 10_000
#: Nodes (scalars and collections, aliases expanded) a model file may hold: the parser's
#: node graph takes ~500 bytes a node, so this bounds a load to ~250 MB.
MAX_NODES = 500_000
_EventLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _StrictLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # libyaml's parser when PyYAML has it
    """SafeLoader that rejects duplicate keys (PyYAML would silently keep the last) and turns
    every failure of a constructor (``!!float abc``, ``!!timestamp 2001-99-99``, an integer
    beyond Python's digit limit, ``!!bool maybe``) into a YAML error at the value's line."""

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except (yaml.YAMLError, RecursionError):
            raise
        except Exception as exc:  # a standard constructor raising ValueError, KeyError, ...
            raise yaml.constructor.ConstructorError(None, None, _construct_problem(node, exc), node.start_mark) from None


def _construct_problem(node: yaml.Node, exc: Exception) -> str:
    tag = str(node.tag).replace("tag:yaml.org,2002:", "!!")
    value = node.value if isinstance(node, yaml.ScalarNode) else "..."
    if isinstance(value, str) and value.lstrip("+-").isdigit() and len(value) > 4000:
        return f"{tag} value of {len(value)} digits is too long"
    return f"{tag} value {shown(value)} cannot be read: {str(exc)[:200]}"


def _construct_mapping(loader: _StrictLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    loader.flatten_mapping(node)
    seen: dict = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:
            raise yaml.constructor.ConstructorError(None, None, f"unhashable key {shown(key)}", key_node.start_mark) from None
        if duplicate:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate name {shown(key)}", key_node.start_mark)
        seen[key] = True
    return loader.construct_mapping(node, deep=deep)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def _check_size(data: bytes, file: str) -> None:
    """Refuse, from the parser's events and before any node is built, a document of more than
    :data:`MAX_NODES` nodes, one whose aliases would expand it by more than
    :data:`MAX_ALIAS_NODES` nodes (a "billion laughs" document), or one that refers to itself
    through an alias. Each alias counts the whole subtree of its anchor, known from the events
    between the anchor's start and end; nothing is expanded."""
    sizes: dict[str, int] = {}  # anchor -> nodes of its subtree
    open_nodes: list[tuple[str | None, int]] = []  # (anchor, count at its start) of unfinished collections
    count = added = 0
    for event in yaml.parse(data, Loader=_EventLoader):
        if isinstance(event, (yaml.ScalarEvent, yaml.CollectionStartEvent)):
            count += 1
            if isinstance(event, yaml.CollectionStartEvent):
                open_nodes.append((event.anchor, count - 1))
            elif event.anchor is not None:
                sizes[event.anchor] = 1
        elif isinstance(event, yaml.CollectionEndEvent):
            anchor, start = open_nodes.pop()
            if anchor is not None:
                sizes[anchor] = count - start
        elif isinstance(event, yaml.AliasEvent):
            line = event.start_mark.line + 1 if event.start_mark else None
            if any(anchor == event.anchor for anchor, _ in open_nodes):
                raise ModelError(file, "(file)", f"alias *{event.anchor} refers to the node that contains it (recursive document)", line)
            size = sizes.get(event.anchor, 0)  # an undefined alias: the composer names it
            count += size
            added += size
            if added > MAX_ALIAS_NODES:
                raise ModelError(
                    file, "(file)", f"aliases expand the document by more than {MAX_ALIAS_NODES:,} nodes here "
                    f"(alias *{event.anchor} alone adds {size:,}); anchors and aliases are for sharing small pieces",
                    line,
                )  # fmt: skip
        if count > MAX_NODES:
            line = event.start_mark.line + 1 if event.start_mark else None
            raise ModelError(file, "(file)", f"more than {MAX_NODES:,} YAML nodes (a 5,000-body chain has 295,000)", line)


def _entry_lines(root: yaml.Node) -> dict[str, int]:
    """Line (1-based) of every entry of the document, by the dotted path the reader names it
    with (``joints.pivot.axes[0]``); a node shared through an alias is listed once."""
    lines: dict[str, int] = {}
    seen: set[int] = set()
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    while stack:
        node, prefix = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode):
                    path = f"{prefix}.{key.value}" if prefix else str(key.value)
                    lines.setdefault(path, key.start_mark.line + 1)
                    stack.append((value, path))
        elif isinstance(node, yaml.SequenceNode):
            for index, item in enumerate(node.value):
                path = f"{prefix}[{index}]"
                lines.setdefault(path, item.start_mark.line + 1)
                stack.append((item, path))
    return lines


class ModelWarning(UserWarning):
    """Something in a model was accepted after a correction (e.g. a quaternion normalized)."""


def load(path: str | Path) -> Model:
    """Read, parse and validate the model file at ``path`` (``-``: standard input)."""
    name = "<stdin>" if str(path) == STDIN else str(path)
    try:
        raw = read_bounded(path, MAX_FILE_BYTES)
    except OSError as exc:
        raise ModelError(name, "(file)", f"cannot read: {exc.strerror or exc}{_shipped_hint(path, exc)}") from None
    return loads(raw, name)


def _shipped_hint(path: str | Path, exc: OSError) -> str:
    """For a missing file named as a shipped model is: where the shipped ones are and how to copy them."""
    import errno

    if exc.errno != errno.ENOENT or str(path) == STDIN:
        return ""
    from kinegen.examples import models_folder

    try:
        shipped = models_folder() / Path(path).name
    except KinegenError:
        return ""
    where = f" (kinegen ships {Path(path).name}: {shipped})" if shipped.is_file() else ""
    return f"{where}; `kinegen models` lists the shipped models, `kinegen models --copy DIR` copies them"


def source_digest(path: str | Path) -> str:
    """SHA-256 of the model file's bytes (``-``: standard input), as generated modules record it."""
    return hashlib.sha256(read_bounded(path, MAX_FILE_BYTES)).hexdigest()


def loads(raw: bytes | str, file: str = "<string>") -> Model:
    """Validate a model given as YAML text; ``file`` names it in error messages. The same bytes
    read under the same name before (by this kinegen) give the model kept then
    (:mod:`kinegen.model.kept`)."""
    from kinegen.model.kept import kept_model

    data = raw.encode() if isinstance(raw, str) else raw
    return kept_model(data, file, lambda: _read(data, file))


def _read(data: bytes, file: str) -> Model:
    """The model of the YAML bytes ``data`` (``file`` names it in error messages), read and validated."""
    loader = None
    try:
        _check_size(data, file)
        loader = _StrictLoader(data)
        root = loader.get_single_node()
        document = None if root is None else loader.construct_document(root)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where, line = (f"column {mark.column + 1}", mark.line + 1) if mark else ("(file)", None)
        raise ModelError(file, where, f"invalid YAML: {getattr(exc, 'problem', None) or exc}", line) from None
    except RecursionError:
        raise ModelError(file, "(file)", "YAML nested too deeply") from None
    finally:
        if loader is not None:
            loader.dispose()
    return _Reader(file, hashlib.sha256(data).hexdigest(), root).model(document)


class _Reader:
    def __init__(self, file: str, sha256: str, root: yaml.Node | None = None) -> None:
        self.file = file
        self.sha256 = sha256
        self.root = root  # the document's node graph: where each entry stands (read only for an error)
        self.parameters: dict[str, sp.Expr] = {}
        self.design: dict[str, DesignParameter] = {}
        self.nominal: dict[sp.Symbol, sp.Expr] = {}  # design symbol -> nominal value
        self.bodies: dict[str, Body] = {}
        self.ground_points: dict[str, Vector] = {}
        self.ground_vectors: dict[str, Vector] = {}
        self.joints: dict[str, Joint] = {}

    # ---- helpers ---------------------------------------------------------------------
    def fail(self, entry: str, problem: str) -> ModelError:
        return ModelError(self.file, entry, problem, self.line(entry))

    def positive(self, value: Any, entry: str, what: str) -> sp.Expr:
        """A positive constant (design parameters allowed); ``what``: its unit and name, for the error."""
        expr = self.scalar(value, entry, design=True)
        if not self.value(expr) > 0:
            raise self.fail(entry, f"{self.value(expr):g} {what} must be positive")
        return expr

    def plausible(self, value: sp.Expr, entry: str, unit: str, usual: tuple[float, float], what: str, hint: str = "") -> None:
        """A :class:`ModelWarning` naming file, line and entry when ``value`` (at the nominal design)
        lies outside the ``usual`` range for ``what``, in its ``unit``: a number typed in another
        unit (a bore of 100 m: millimetres typed as metres) is accepted but said, with ``hint``."""
        number = self.value(value)
        low, high = usual
        if low <= number <= high:
            return
        line = self.line(entry)
        where = self.file if line is None else f"{self.file}:{line}"
        warnings.warn(f"{where}: {entry}: {number:g} {unit} is outside the usual {low:g} .. {high:g} {unit} for {what}"
                      f"{' -- ' + hint if hint else ''}", ModelWarning, stacklevel=2)  # fmt: skip

    def line(self, entry: str) -> int | None:
        """Line of ``entry`` in the file, or of the nearest entry that contains it."""
        lines = _entry_lines(self.root) if self.root is not None else {}
        while entry:
            if entry in lines:
                return lines[entry]
            entry = entry[: max(entry.rfind("."), entry.rfind("["), 0)]
        return None

    def mapping(self, value: Any, entry: str, allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> dict:
        if value is None and not required:
            return {}
        if not isinstance(value, Mapping):
            raise self.fail(entry, f"expected a mapping, got {_kind(value)}")
        known = frozenset(allowed)  # a tuple's `in` made a mapping of n free keys cost n^2
        for key in value:
            if not isinstance(key, str):
                raise self.fail(entry, f"key {shown(key)} is not a string")
            if key not in known:
                shown_key = key if key.strip() else shown(key)  # an empty key still names an entry
                where = shown_key if entry == "(top level)" else f"{entry}.{shown_key}"
                raise self.fail(where, f"unknown key (allowed: {', '.join(allowed)})")
        for key in required:
            if key not in value:
                raise self.fail(entry, f"missing required key '{key}'")
        return dict(value)

    def keys(self, value: Any) -> tuple[str, ...]:
        """The string keys of a mapping (none of anything else: :meth:`mapping` then says what it is)."""
        return tuple(_keys(value))

    def name(self, value: Any, entry: str) -> str:
        if not isinstance(value, str) or not NAME_PATTERN.match(value):
            raise self.fail(entry, f"{shown(value)} is not a valid name (letter first, then letters, digits, _)")
        if value in RESERVED:
            raise self.fail(entry, f"{shown(value)} is a reserved name")
        return value

    def scalar(self, value: Any, entry: str, allow_time: bool = False, design: bool = False) -> sp.Expr:
        """A constant (or with ``allow_time`` a function of t); with ``design`` it may depend on
        the design parameters (geometry), checked at their nominal values."""
        try:
            expr = expressions.parse(value, self.parameters, allow_time=allow_time)
        except ExpressionError as exc:
            raise self.fail(entry, f"{shown(value)}: {exc}" if isinstance(value, str) else str(exc)) from None
        used = sorted(str(s)[2:] for s in expr.free_symbols & self.nominal.keys())
        if used and not design:
            raise self.fail(
                entry, f"{shown(value)} uses design parameter(s) {', '.join(used)}: design parameters may be used in the "
                "geometry (positions, orientations, points, vectors, lengths, parameters), actuator ranges and "
                "working-range inputs only",
            )  # fmt: skip
        if not allow_time:
            at_nominal = expr.xreplace(self.nominal) if used else expr
            if not at_nominal.is_number:
                raise self.fail(entry, f"{shown(value)} is not a real constant")
            try:
                expressions.float_value(at_nominal)  # bounded first: exact evaluation of a huge part never returns
            except ExpressionError:
                raise self.fail(entry, f"{shown(value)} is not a real constant (in double precision)") from None
            numeric = complex(sp.N(at_nominal))
            if numeric.imag != 0 or not abs(numeric.real) < expressions.MAX_MAGNITUDE:
                raise self.fail(entry, f"{shown(value)} is not a finite real number")
        else:
            if not _constants_real(expr):
                raise self.fail(entry, f"{shown(value)} is not a real function of t (a constant part of it is not real)")
            rate = expressions.time_derivative(expr)
            for what, e in (("", expr), (" (its first time derivative)", rate), (" (its second time derivative)", None)):
                e = expressions.time_derivative(rate) if e is None else e
                if e.has(sp.zoo, sp.oo, -sp.oo, sp.nan, sp.I):
                    raise self.fail(entry, f"{shown(value)} is not a finite real function of t{what}")
                unwritten = {type(f).__name__ for f in e.atoms(sp.Function, sp.Derivative)} - expressions.PRINTABLE
                if unwritten:
                    raise self.fail(
                        entry, f"{shown(value)}: SymPy cannot write {what.strip(' ()') or 'it'} in closed form "
                        f"({', '.join(sorted(unwritten))}); write the function so that its arguments are real for every t",
                    )  # fmt: skip
        return expr

    def vector(self, value: Any, entry: str) -> Vector:
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise self.fail(entry, f"expected a list of 3 numbers, got {_kind(value)}")
        return sp.ImmutableMatrix([self.scalar(v, f"{entry}[{i}]", design=True) for i, v in enumerate(value)])

    def value(self, expr: sp.Expr) -> float:
        """The double value of a geometry expression, design parameters at their nominal values."""
        return float(expr.xreplace(self.nominal)) if self.nominal else float(expr)

    def unit(self, value: Any, entry: str) -> Vector:
        v = self.vector(value, entry)
        norm2 = sp.expand(sum(x**2 for x in v))
        if self.value(norm2) < 1e-18:
            raise self.fail(entry, "zero-length vector")
        return _compact_matrix(v / sp.sqrt(norm2))

    # ---- sections --------------------------------------------------------------------
    def model(self, document: Any) -> Model:
        top = self.mapping(
            document,
            "(top level)",
            (
                "model",
                "description",
                "redundant",
                "design",
                "parameters",
                "ground",
                "bodies",
                "joints",
                "actuators",
                "motors",
                "tool_points",
                "loads",
                "tool_forces",
                "lift_chart",
                "gravity",
                "machine",
                "pumps",
                "drivers",
                "cases",
                "working_range",
                "studies",
            ),
            ("model", "bodies"),
        )
        name = self.name(top["model"], "model")
        self.redundant = top.get("redundant", False)
        if not isinstance(self.redundant, bool):
            raise self.fail("redundant", "expected true or false")
        description = top.get("description", "")
        if not isinstance(description, str):
            raise self.fail("description", "expected a string")
        self.read_design(top.get("design"))
        for key, value in self.mapping(top.get("parameters"), "parameters", tuple(_keys(top.get("parameters")))).items():
            if key in self.design:
                raise self.fail(f"parameters.{key}", "already a design parameter")
            self.parameters[self.name(key, f"parameters.{key}")] = self.scalar(value, f"parameters.{key}", design=True)
        ground = self.mapping(top.get("ground"), "ground", ("points", "vectors", "outline"))
        identity = Body(GROUND, sp.ImmutableMatrix([0, 0, 0]), sp.ImmutableMatrix(sp.eye(3)))
        self.ground_points = self.named_vectors(ground.get("points"), "ground.points", identity, False, False)
        self.ground_vectors = self.named_vectors(ground.get("vectors"), "ground.vectors", identity, True, False)
        ground_outline = self.outline(ground.get("outline"), "ground.outline")
        bodies = self.mapping(top["bodies"], "bodies", tuple(_keys(top["bodies"])))
        if not bodies:
            raise self.fail("bodies", "a model needs at least one moving body")
        for key, value in bodies.items():
            if key == "p" and self.design:
                raise self.fail(f"bodies.{key}", "'p' names the design parameters' symbols (p_<name>): choose another body name")
            self.bodies[key] = self.body(self.name(key, f"bodies.{key}"), value)
        joints = self.mapping(top.get("joints"), "joints", tuple(_keys(top.get("joints"))))
        for key, value in joints.items():
            self.joints[key] = self.joint(self.name(key, f"joints.{key}"), value)
        actuators = self.actuators(top.get("actuators"))
        motors = read_motors(self, top.get("motors"))
        check_actuation(self, motors, actuators)
        tool_points = read_tool_points(self, top.get("tool_points"))
        loads = read_loads(self, top.get("loads"), tool_points)
        common = self.drivers(top.get("drivers"), "drivers")
        cases = self.cases(top.get("cases"), common)
        working_range = self.working_range(top.get("working_range"), cases) if "working_range" in top else None
        tool_forces = read_tool_forces(self, top["tool_forces"], cases, actuators, tool_points, working_range) if "tool_forces" in top else None
        lift_chart = read_lift_chart(self, top["lift_chart"], cases, actuators, working_range) if "lift_chart" in top else None
        machine = read_machine(self, top.get("machine"))
        supply = read_supply(self, top["pumps"], actuators, motors) if "pumps" in top else None
        self.loads, self.tool_forces, self.lift_chart, self.machine = loads, tool_forces, lift_chart, machine  # what the studies' force quantities refer to
        self.massive = tuple(name for name, body in self.bodies.items() if body.inertia is not None)
        self.supply = supply
        studies = read_studies(self, top.get("studies"), cases, actuators, working_range) if "studies" in top else {}
        return Model(
            name=name,
            file=self.file,
            source_sha256=self.sha256,
            description=description,
            parameters=dict(self.parameters),
            bodies=tuple(self.bodies.values()),
            joints=tuple(self.joints.values()),
            cases=cases,
            actuators=actuators,
            working_range=working_range,
            redundant=self.redundant,
            ground_points=dict(self.ground_points),
            ground_outline=ground_outline,
            design=tuple(self.design.values()),
            studies=studies,
            motors=motors,
            tool_points=tool_points,
            loads=loads,
            tool_forces=tool_forces,
            lift_chart=lift_chart,
            gravity=self.lift_gravity(read_gravity(self, top.get("gravity")), lift_chart),
            machine=machine,
            supply=supply,
        )

    def lift_gravity(self, gravity: Any, lift_chart: Any) -> Any:
        """``gravity`` -- refused with a lift chart unless standard: ISO 10567 rates a lift capacity in
        kg under standard gravity along -z (its tipping loads balance masses about lines on level
        ground, its hydraulic capacity in N converts with 9.80665 m/s^2), so one g holds throughout."""
        if lift_chart is not None and tuple(gravity) != tuple(STANDARD_GRAVITY):
            raise self.fail("gravity", f"{shown([str(g) for g in gravity])} m/s^2 with a lift_chart: section: an ISO 10567 lift chart is "
                            f"rated under standard gravity {[float(g) for g in STANDARD_GRAVITY]} m/s^2 (remove gravity: or the lift chart)")  # fmt: skip
        return gravity

    def read_design(self, value: Any) -> None:
        """``design: {name: {nominal: x, bounds: [low, high], description: text}}``: parameters
        the geometry keeps as symbols ``p_<name>``."""
        for key, spec in self.mapping(value, "design", tuple(_keys(value))).items():
            entry = f"design.{key}"
            name = self.name(key, entry)
            spec = self.mapping(spec, entry, ("nominal", "bounds", "description"), ("nominal", "bounds"))
            nominal = self.scalar(spec["nominal"], f"{entry}.nominal")
            bounds = spec["bounds"]
            if not isinstance(bounds, (list, tuple)) or len(bounds) != 2:
                raise self.fail(f"{entry}.bounds", f"expected [low, high], got {_kind(bounds)}")
            low, high = (self.scalar(b, f"{entry}.bounds[{i}]") for i, b in enumerate(bounds))
            if not float(low) < float(high):
                raise self.fail(f"{entry}.bounds", f"low {shown(bounds[0])} is not below high {shown(bounds[1])}")
            if not float(low) <= float(nominal) <= float(high):
                raise self.fail(f"{entry}.nominal", f"{shown(spec['nominal'])} is outside the bounds [{bounds[0]}, {bounds[1]}]")
            description = spec.get("description", "")
            if not isinstance(description, str):
                raise self.fail(f"{entry}.description", "expected a string")
            symbol = sp.Symbol(f"p_{name}", real=True)
            self.design[name] = DesignParameter(name, symbol, nominal, low, high, description)
            self.nominal[symbol] = nominal
            self.parameters[name] = symbol

    def body(self, name: str, value: Any) -> Body:
        entry = f"bodies.{name}"
        spec = self.mapping(
            value,
            entry,
            ("position", "orientation", "points", "global_points", "vectors", "global_vectors", "outline", *MASS_KEYS),
            ("position",),
        )
        position = self.vector(spec["position"], f"{entry}.position")
        rotation = self.orientation(spec.get("orientation"), f"{entry}.orientation")
        pose = Body(name, position, rotation)
        points = self.named_vectors(spec.get("points"), f"{entry}.points", pose, False, False)
        vectors = self.named_vectors(spec.get("vectors"), f"{entry}.vectors", pose, True, False)
        for key, local in self.named_vectors(spec.get("global_points"), f"{entry}.global_points", pose, False, True).items():
            if key in points:
                raise self.fail(f"{entry}.global_points.{key}", "duplicate point name (also in points)")
            points[key] = local
        for key, local in self.named_vectors(spec.get("global_vectors"), f"{entry}.global_vectors", pose, True, True).items():
            if key in vectors:
                raise self.fail(f"{entry}.global_vectors.{key}", "duplicate vector name (also in vectors)")
            vectors[key] = local
        inertia = read_inertia(self, spec, entry, pose, points)
        return Body(name, position, rotation, points, vectors, self.outline(spec.get("outline"), f"{entry}.outline"), inertia)

    def outline(self, value: Any, entry: str) -> tuple[tuple[float, float, float], ...]:
        """``outline: [[x, y, z], ...]``: a closed polygon of at least 3 points (m, body coordinates;
        design parameters at their nominal values) -- a drawing, not part of the kinematics."""
        if value is None:
            return ()
        if not isinstance(value, (list, tuple)) or len(value) < 3:
            raise self.fail(entry, f"expected a list of at least 3 points [x, y, z], got {_kind(value)}")
        points = [self.vector(item, f"{entry}[{i}]") for i, item in enumerate(value)]
        return tuple(tuple(self.value(x) for x in point) for point in points)

    def named_vectors(self, value: Any, entry: str, pose: Body, unit: bool, is_global: bool) -> dict[str, Vector]:
        result: dict[str, Vector] = {}
        for key, item in self.mapping(value, entry, tuple(_keys(value))).items():
            key_entry = f"{entry}.{key}"
            self.name(key, key_entry)
            vec = self.unit(item, key_entry) if unit else self.vector(item, key_entry)
            if is_global:
                vec = _to_local(pose, vec, unit)
            result[key] = vec
        return result

    def orientation(self, value: Any, entry: str) -> sp.ImmutableMatrix:
        if value is None:
            return sp.ImmutableMatrix(sp.eye(3))
        spec = self.mapping(value, entry, ("quaternion", "euler", "matrix", "axis", "angle"))
        forms = [k for k in ("quaternion", "euler", "matrix") if k in spec] + (
            ["axis/angle"] if {"axis", "angle"} & spec.keys() else []
        )
        if len(forms) != 1:
            raise self.fail(entry, "give exactly one of: quaternion, euler, matrix, axis + angle")
        if "quaternion" in spec:
            q = spec["quaternion"]
            if not isinstance(q, (list, tuple)) or len(q) != 4:
                raise self.fail(f"{entry}.quaternion", f"expected [w, x, y, z], got {_kind(q)}")
            quat = [self.scalar(v, f"{entry}.quaternion[{i}]", design=True) for i, v in enumerate(q)]
            norm2 = sp.expand(sum(x**2 for x in quat))
            if self.value(norm2) < 1e-18:
                raise self.fail(f"{entry}.quaternion", "zero quaternion")
            if abs(self.value(norm2) - 1.0) > 1e-12:
                warnings.warn(
                    f"{self.file}: {entry}.quaternion: norm {self.value(sp.sqrt(norm2)):.6g} != 1, normalized",
                    ModelWarning,
                    stacklevel=2,
                )
                quat = [x / sp.sqrt(norm2) for x in quat]
            return _compact_matrix(quaternion_matrix(sp.Matrix(quat)))
        if "euler" in spec:
            euler = self.mapping(spec["euler"], f"{entry}.euler", ("sequence", "angles"), ("sequence", "angles"))
            sequence = euler["sequence"].lower() if isinstance(euler["sequence"], str) else ""
            if sequence not in SEQUENCES:
                raise self.fail(
                    f"{entry}.euler.sequence",
                    f"unknown sequence {shown(euler['sequence'])} (intrinsic, one of {', '.join(SEQUENCES)})",
                )
            angles = self.vector(euler["angles"], f"{entry}.euler.angles")
            return _compact_matrix(EulerAngles(sequence).matrix(sp.Matrix(angles)))
        if "matrix" in spec:
            rows = spec["matrix"]
            if not isinstance(rows, (list, tuple)) or len(rows) != 3:
                raise self.fail(f"{entry}.matrix", "expected 3 rows of 3 numbers")
            matrix = sp.ImmutableMatrix([list(self.vector(r, f"{entry}.matrix[{i}]")) for i, r in enumerate(rows)])
            numeric = sp.matrix2numpy(matrix.xreplace(self.nominal).evalf(), dtype=float)
            if np.abs(numeric.T @ numeric - np.eye(3)).max() > ORTHONORMAL_TOLERANCE or np.linalg.det(numeric) < 0:
                raise self.fail(f"{entry}.matrix", f"not a rotation matrix (orthonormal to {ORTHONORMAL_TOLERANCE:g}, det +1)")
            return matrix
        if "axis" not in spec or "angle" not in spec:
            raise self.fail(entry, "axis-angle needs both 'axis' and 'angle'")
        k = self.unit(spec["axis"], f"{entry}.axis")
        angle = self.scalar(spec["angle"], f"{entry}.angle", design=True)
        kx = sp.Matrix([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        rodrigues = sp.eye(3) * sp.cos(angle) + sp.sin(angle) * kx + (1 - sp.cos(angle)) * (k * k.T)
        return _compact_matrix(rodrigues)

    # ---- joints ----------------------------------------------------------------------
    def pose(self, name: str) -> Body:
        if name == GROUND:
            return Body(
                GROUND, sp.ImmutableMatrix([0, 0, 0]), sp.ImmutableMatrix(sp.eye(3)), self.ground_points, self.ground_vectors
            )
        return self.bodies[name]

    def body_name(self, value: Any, entry: str) -> str:
        if not isinstance(value, str) or (value != GROUND and value not in self.bodies):
            raise self.fail(entry, f"unknown body {shown(value)} (known: ground, {', '.join(self.bodies)})")
        return value

    def joint(self, name: str, value: Any) -> Joint:
        entry = f"joints.{name}"
        spec = self.mapping(
            value, entry, ("type", "bodies", "points", "at", "axes", "axis", "references", "length"), ("type", "bodies")
        )
        kind = spec["type"]
        if kind not in JOINT_TYPES:
            raise self.fail(f"{entry}.type", f"unknown joint type {shown(kind)} (one of {', '.join(JOINT_TYPES)})")
        pair = spec["bodies"]
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise self.fail(f"{entry}.bodies", "expected a list of two body names")
        b1 = self.body_name(pair[0], f"{entry}.bodies[0]")
        b2 = self.body_name(pair[1], f"{entry}.bodies[1]")
        if b1 == b2:
            raise self.fail(f"{entry}.bodies", f"a joint needs two different bodies, got {shown(b1)} twice")
        pose1, pose2 = self.pose(b1), self.pose(b2)
        joint_kind = JOINT_KINDS[kind]
        needs_axis = joint_kind.has_axes
        allowed = {"type", "bodies", "points", *joint_kind.keys} | ({"at"} if kind != "distance" else set())
        for key in spec:
            if key not in allowed:
                raise self.fail(f"{entry}.{key}", f"not used by a {kind} joint (allowed: {', '.join(sorted(allowed))})")
        point1, point2 = self.joint_points(spec, entry, pose1, pose2, kind)
        fields: dict[str, Any] = {"point1": point1, "point2": point2}
        if needs_axis:
            axis1, axis2 = self.joint_axes(spec, entry, pose1, pose2, kind)
            fields.update(axis1=axis1, axis2=axis2)
            if joint_kind.has_references:
                ref1, ref2 = self.references(spec, entry, pose1, pose2, axis1, axis2)
                fields.update(reference1=ref1, reference2=ref2)
                g1 = _cross(axis1, ref1)
                fields["lock2"] = tuple(_carry(pose1, pose2, v) for v in (ref1, g1, axis1))
            elif abs(self.value((_rotate(pose1, axis1).T * _rotate(pose2, axis2))[0])) > 1e-9:
                raise self.fail(f"{entry}.axes", "the two universal-joint axes must be perpendicular at the initial pose")
        if kind == "fixed":
            e = [sp.ImmutableMatrix(sp.eye(3)[:, i]) for i in range(3)]
            fields["lock2"] = tuple(_carry(pose1, pose2, v) for v in e)
        if kind == "distance":
            d = _global(pose1, point1) - _global(pose2, point2)
            initial = sp.sqrt(sp.expand((d.T * d)[0]))
            length = self.scalar(spec["length"], f"{entry}.length", design=True) if "length" in spec else initial
            if self.value(length) <= 1e-9:
                raise self.fail(
                    f"{entry}.length" if "length" in spec else f"{entry}.points",
                    "a distance joint needs a positive length (points must not coincide)",
                )
            fields["length"] = length
        return Joint(name, kind, b1, b2, **fields)

    def joint_points(self, spec: dict, entry: str, pose1: Body, pose2: Body, kind: str) -> tuple[Vector, Vector]:
        if ("points" in spec) == ("at" in spec) and kind != "fixed":
            raise self.fail(
                entry, "give exactly one of 'points' (a point name on each body) or 'at' (a global position at the initial pose)"
            )
        if kind == "distance" and "at" in spec:
            raise self.fail(f"{entry}.at", "a distance joint needs two different points: use 'points'")
        if "points" in spec:
            names = spec["points"]
            if not isinstance(names, (list, tuple)) or len(names) != 2:
                raise self.fail(f"{entry}.points", "expected two point names (one on each body)")
            return (self.point_on(pose1, names[0], f"{entry}.points[0]"), self.point_on(pose2, names[1], f"{entry}.points[1]"))
        at = self.vector(spec["at"], f"{entry}.at") if "at" in spec else pose2.position
        return _to_local(pose1, at, False), _to_local(pose2, at, False)

    def point_on(self, pose: Body, name: Any, entry: str) -> Vector:
        if not isinstance(name, str) or name not in pose.points:
            known = ", ".join(pose.points) or "none"
            raise self.fail(entry, f"unknown point {shown(name)} on body {shown(pose.name)} (known: {known})")
        return pose.points[name]

    def vector_on(self, pose: Body, name: Any, entry: str) -> Vector:
        if not isinstance(name, str) or name not in pose.vectors:
            known = ", ".join(pose.vectors) or "none"
            raise self.fail(entry, f"unknown vector {shown(name)} on body {shown(pose.name)} (known: {known})")
        return pose.vectors[name]

    def joint_axes(self, spec: dict, entry: str, pose1: Body, pose2: Body, kind: str) -> tuple[Vector, Vector]:
        if ("axes" in spec) == ("axis" in spec):
            raise self.fail(
                entry,
                "give exactly one of 'axes' (a vector name on each body) or 'axis' (a global direction at the initial pose)",
            )
        if "axes" in spec:
            names = spec["axes"]
            if not isinstance(names, (list, tuple)) or len(names) != 2:
                raise self.fail(f"{entry}.axes", "expected two vector names (one on each body)")
            axis1 = self.vector_on(pose1, names[0], f"{entry}.axes[0]")
            axis2 = self.vector_on(pose2, names[1], f"{entry}.axes[1]")
            if kind != "universal":
                g1, g2 = _rotate(pose1, axis1), _rotate(pose2, axis2)
                if self.value((_cross(g1, g2).T * _cross(g1, g2))[0]) > 1e-12:
                    raise self.fail(f"{entry}.axes", "the two axes are not parallel at the initial pose")
            return axis1, axis2
        if kind == "universal":
            axes = spec["axis"]
            if not isinstance(axes, (list, tuple)) or len(axes) != 2:
                raise self.fail(
                    f"{entry}.axis", "a universal joint needs two global directions [[...], [...]] (body 1's, body 2's)"
                )
            a1 = self.unit(axes[0], f"{entry}.axis[0]")
            a2 = self.unit(axes[1], f"{entry}.axis[1]")
            return _to_local(pose1, a1, True), _to_local(pose2, a2, True)
        axis = self.unit(spec["axis"], f"{entry}.axis")
        return _to_local(pose1, axis, True), _to_local(pose2, axis, True)

    def references(self, spec: dict, entry: str, pose1: Body, pose2: Body, axis1: Vector, axis2: Vector) -> tuple[Vector, Vector]:
        if "references" not in spec:
            return perpendicular(axis1, self.nominal), perpendicular(axis2, self.nominal)
        names = spec["references"]
        if not isinstance(names, (list, tuple)) or len(names) != 2:
            raise self.fail(f"{entry}.references", "expected two vector names (one on each body)")
        refs = []
        for i, (pose, axis) in enumerate(((pose1, axis1), (pose2, axis2))):
            ref = self.vector_on(pose, names[i], f"{entry}.references[{i}]")
            if abs(self.value((ref.T * axis)[0])) > 1e-9:
                raise self.fail(f"{entry}.references[{i}]", "a reference vector must be perpendicular to the joint axis")
            refs.append(ref)
        return refs[0], refs[1]

    def actuators(self, value: Any) -> tuple[Actuator, ...]:
        result = []
        for key, spec in self.mapping(value, "actuators", tuple(_keys(value))).items():
            entry = f"actuators.{key}"
            self.name(key, entry)
            spec = self.mapping(spec, entry, ("points", "range", "hydraulics", "parallel"), ("points",))
            refs = spec["points"]
            if not isinstance(refs, (list, tuple)) or len(refs) != 2:
                raise self.fail(f"{entry}.points", "expected two points 'body.point'")
            p1, p2 = (self.point_ref(r, f"{entry}.points[{i}]") for i, r in enumerate(refs))
            limits = None
            if "range" in spec:
                bounds = spec["range"]
                if not isinstance(bounds, (list, tuple)) or len(bounds) != 2:
                    raise self.fail(f"{entry}.range", "expected [min, max]")
                limits = tuple(self.scalar(b, f"{entry}.range[{i}]", design=True) for i, b in enumerate(bounds))
                low, high = (self.value(x) for x in limits)
                if not 0 <= low < high:
                    raise self.fail(f"{entry}.range", f"expected 0 <= min < max, got [{low}, {high}]")
            if limits is not None:
                for i, bound in enumerate(limits):
                    if self.value(bound) > 0:
                        self.plausible(bound, f"{entry}.range[{i}]", "m", (0.01, 100.0), "an actuator's length", "lengths are in m")
            hydraulics = read_hydraulics(self, spec["hydraulics"], f"{entry}.hydraulics") if "hydraulics" in spec else None
            parallel = spec.get("parallel")
            if parallel is not None:
                lead = next((a for a in result if a.name == parallel), None)
                if "hydraulics" in spec:
                    raise self.fail(f"{entry}.hydraulics", f"a cylinder parallel to {shown(parallel)} has its data: leave hydraulics out")
                if lead is None or lead.hydraulics is None or lead.parallel is not None:
                    named = [a.name for a in result if a.hydraulics is not None]
                    raise self.fail(f"{entry}.parallel", f"{shown(parallel)} is not an actuator with hydraulic data declared above this one "
                                    f"({', '.join(named) or 'none'})")  # fmt: skip
            result.append(Actuator(key, (p1, p2), limits, hydraulics, parallel))
        return tuple(result)

    def working_range(self, value: Any, cases: dict) -> WorkingRange:
        entry = "working_range"
        spec = self.mapping(value, entry, ("case", "point", "inputs", "dump_pivot", "arm_pivot", "transport", "published"), ("case", "point", "inputs"))
        case = cases.get(spec["case"]) if isinstance(spec["case"], str) else None
        if case is None:
            raise self.fail(f"{entry}.case", f"unknown case {shown(spec['case'])} (cases: {', '.join(cases)})")
        point = self.point_ref(spec["point"], f"{entry}.point")
        drivers = [d.name for d in case.drivers]
        raw = self.mapping(spec["inputs"], f"{entry}.inputs", tuple(drivers), tuple(drivers))
        inputs: dict[str, sp.Expr | tuple[sp.Expr, sp.Expr]] = {}
        for name in drivers:
            item, where = raw[name], f"{entry}.inputs.{name}"
            if isinstance(item, (list, tuple)):
                if len(item) != 2:
                    raise self.fail(where, "expected a value or [min, max]")
                bounds = tuple(self.scalar(x, f"{where}[{i}]", design=True) for i, x in enumerate(item))
                low, high = (self.value(x) for x in bounds)
                if not low < high:
                    raise self.fail(where, f"min {low} must be below max {high}")
                inputs[name] = bounds
            else:
                inputs[name] = self.scalar(item, where, design=True)
        pivot = self.point_ref(spec["dump_pivot"], f"{entry}.dump_pivot") if "dump_pivot" in spec else None
        arm_pivot = self.point_ref(spec["arm_pivot"], f"{entry}.arm_pivot") if "arm_pivot" in spec else None
        if arm_pivot is not None and pivot is None:
            raise self.fail(f"{entry}.arm_pivot", "needs dump_pivot (the arm is vertical when arm_pivot is directly above dump_pivot)")
        published = {}
        for key, item in self.mapping(spec.get("published"), f"{entry}.published", PUBLISHED_FIGURES).items():
            published[key] = float(self.scalar(item, f"{entry}.published.{key}"))
        swept = tuple(name for name in drivers if isinstance(inputs[name], tuple))
        transport = {}
        for key, item in self.mapping(spec.get("transport"), f"{entry}.transport", swept, swept if "transport" in spec else ()).items():
            transport[key] = float(self.value(self.scalar(item, f"{entry}.transport.{key}")))
            low, high = (float(self.value(x)) for x in inputs[key])
            if not low <= transport[key] <= high:
                raise self.fail(f"{entry}.transport.{key}", f"{transport[key]:g} is outside the input's range [{low:g}, {high:g}]")
        return WorkingRange(case.name, point, inputs, pivot, published, arm_pivot, transport)

    # ---- drivers and cases -------------------------------------------------------------
    def drivers(self, value: Any, entry: str) -> list[Driver]:
        return [
            self.driver(self.name(k, f"{entry}.{k}"), v, f"{entry}.{k}")
            for k, v in self.mapping(value, entry, tuple(_keys(value))).items()
        ]

    def point_ref(self, value: Any, entry: str) -> PointRef:
        if not isinstance(value, str) or value.count(".") != 1:
            raise self.fail(entry, f"expected 'body.point', got {shown(value)}")
        body, point = value.split(".")
        self.body_name(body, entry)
        return PointRef(body, point, self.point_on(self.pose(body), point, entry))

    def driver(self, name: str, value: Any, entry: str) -> Driver:
        spec = self.mapping(
            value,
            entry,
            ("type", "joint", "points", "point", "component", "body", "axis", "reference", "function"),
            ("type", "function"),
        )
        kind = spec["type"]
        if kind not in DRIVER_TYPES:
            raise self.fail(f"{entry}.type", f"unknown driver type {shown(kind)} (one of {', '.join(DRIVER_TYPES)})")
        needed, optional = DRIVER_KINDS[kind].needs, DRIVER_KINDS[kind].optional
        for key in spec:
            if key not in needed | optional | {"type", "function"}:
                raise self.fail(f"{entry}.{key}", f"not used by a {kind} driver")
        for key in sorted(needed):
            if key not in spec:
                raise self.fail(entry, f"a {kind} driver needs '{key}'")
        function = self.scalar(spec["function"], f"{entry}.function", allow_time=True)
        source = {"entry": f"{entry}.function", "text": str(spec["function"])}
        if kind in ("joint_angle", "joint_translation"):
            joint = self.joints.get(spec["joint"]) if isinstance(spec["joint"], str) else None
            if joint is None:
                raise self.fail(f"{entry}.joint", f"unknown joint {shown(spec['joint'])} (known: {', '.join(self.joints) or 'none'})")
            ok = ("revolute", "cylindrical") if kind == "joint_angle" else ("prismatic", "cylindrical")
            if joint.type not in ok:
                raise self.fail(
                    f"{entry}.joint", f"a {kind} driver needs a {' or '.join(ok)} joint, {shown(joint.name)} is {joint.type}"
                )
            return Driver(name, kind, function, joint=joint.name, **source)
        if kind == "distance":
            refs = spec["points"]
            if not isinstance(refs, (list, tuple)) or len(refs) != 2:
                raise self.fail(f"{entry}.points", "expected two points 'body.point'")
            p1, p2 = (self.point_ref(r, f"{entry}.points[{i}]") for i, r in enumerate(refs))
            if p1.body == p2.body:
                raise self.fail(f"{entry}.points", "the two points are on the same body")
            gap = _global(self.pose(p1.body), p1.local) - _global(self.pose(p2.body), p2.local)
            if self.value((gap.T * gap)[0]) < 1e-12:
                raise self.fail(
                    f"{entry}.points", "the two points coincide at the initial pose (a distance driver is singular there)"
                )
            return Driver(name, kind, function, points=(p1, p2), **source)
        if kind == "coordinate":
            point = self.point_ref(spec["point"], f"{entry}.point")
            if point.body == GROUND:
                raise self.fail(f"{entry}.point", "a coordinate driver needs a point on a moving body")
            component = spec["component"]
            if component not in ("x", "y", "z"):
                raise self.fail(f"{entry}.component", f"expected x, y or z, got {shown(component)}")
            return Driver(name, kind, function, points=(point,), component="xyz".index(component), **source)
        body = self.body_name(spec["body"], f"{entry}.body")
        if body == GROUND:
            raise self.fail(f"{entry}.body", "a body_angle driver needs a moving body")
        axis = self.unit(spec["axis"], f"{entry}.axis")
        reference = perpendicular(axis, self.nominal) if "reference" not in spec else self.unit(spec["reference"], f"{entry}.reference")
        if abs(self.value((reference.T * axis)[0])) > 1e-9:
            raise self.fail(f"{entry}.reference", "must be perpendicular to the axis")
        return Driver(name, kind, function, body=body, axis=axis, reference=reference, body_reference=reference, **source)

    def check_mobility(self, entry: str, drivers: list[Driver]) -> None:
        """Coordinates (6 per body) must equal joint equations + drivers (no redundancy allowed); an
        over-constrained model is told which joints' equations repeat each other (:meth:`over_constrained`)."""
        coordinates = 6 * len(self.bodies)
        equations = sum(JOINT_EQUATIONS[j.type] for j in self.joints.values())
        mobility = coordinates - equations
        if self.redundant and mobility <= len(drivers):
            return  # declared redundant: more equations than coordinates is intended
        where = f"{entry}.drivers" if entry != "drivers" else entry
        if mobility < len(drivers):
            raise self.over_constrained(where, len(drivers), "driver(s)")
        if mobility != len(drivers):
            raise self.fail(where, f"degree-of-freedom count does not match: {coordinates} coordinates (6 per body), "
                            f"{equations} joint equations, so mobility {mobility}, but {len(drivers)} driver(s): add a driver "
                            "for each free motion")  # fmt: skip

    def over_constrained(self, entry: str, count: int, what: str) -> OverConstrainedError:
        """The error of a model whose joints leave fewer degrees of freedom than its ``count``
        drivers or actuation elements (``what``) by count; it carries a stand-in model of the bodies
        and joints read so far, for :func:`kinegen.symbolic.rank.explain` to name the joints whose
        equations repeat each other."""
        coordinates = 6 * len(self.bodies)
        equations = sum(JOINT_EQUATIONS[j.type] for j in self.joints.values())
        stand_in = Model(name="rank", file=self.file, source_sha256=self.sha256, description="", parameters=dict(self.parameters),
                         bodies=tuple(self.bodies.values()), joints=tuple(self.joints.values()), cases={},
                         ground_points=dict(self.ground_points), design=tuple(self.design.values()))  # fmt: skip
        problem = (f"over-constrained: {equations} joint equations on {coordinates} coordinates (6 per body) leave mobility "
                   f"{coordinates - equations} for {count} {what}")  # fmt: skip
        return OverConstrainedError(self.file, entry, problem, self.line(entry), stand_in, count, what)

    def cases(self, value: Any, common: list[Driver]) -> dict:
        if value is None:
            self.check_mobility("drivers", common)
            return {"default": Case("default", tuple(common))}
        cases = {}
        for key, spec in self.mapping(value, "cases", tuple(_keys(value))).items():
            entry = f"cases.{key}"
            self.name(key, entry)
            spec = self.mapping(spec, entry, ("description", "drivers", "t0", "t1", "steps"))
            drivers = common + self.drivers(spec.get("drivers"), f"{entry}.drivers")
            seen: set[str] = set()
            for n in (d.name for d in drivers):
                if n in seen:
                    raise self.fail(f"{entry}.drivers.{n}", "duplicate driver name (also in the common drivers)")
                seen.add(n)
            t0 = float(self.scalar(spec.get("t0", 0), f"{entry}.t0"))
            t1 = float(self.scalar(spec.get("t1", 1), f"{entry}.t1"))
            if not t1 > t0:
                raise self.fail(f"{entry}.t1", f"t1 = {t1} must be greater than t0 = {t0}")
            steps = spec.get("steps", 101)
            if isinstance(steps, bool) or not isinstance(steps, int) or not 2 <= steps <= 10_000_000:
                raise self.fail(f"{entry}.steps", f"expected a whole number of time points >= 2, got {shown(steps)}")
            self.check_mobility(entry, drivers)
            cases[key] = Case(key, tuple(drivers), t0, t1, steps)
        if not cases:
            raise self.fail("cases", "no case defined")
        return cases




def _compact_matrix(matrix: sp.MatrixBase) -> sp.ImmutableMatrix:
    return sp.ImmutableMatrix(matrix.applyfunc(lambda e: compact(sp.expand(e))))


def _constants_real(expr: sp.Expr) -> bool:
    """Every constant subexpression of ``expr`` (``asin(-2)``, ``log(-1)``), at every depth, is a
    finite real number: the code printer evaluates them innermost first (``cosh(acos(3))`` is
    real, its ``acos(3)`` is not)."""
    stack = [expr]
    while stack:
        e = stack.pop()
        if e.is_number:
            try:
                expressions.float_value(e)  # every inner constant is evaluated (in doubles) on the way
            except ExpressionError:
                return False
        else:
            stack.extend(e.args)
    return True


def _keys(value: Any) -> list[str]:
    return [k for k in value if isinstance(k, str)] if isinstance(value, Mapping) else []


def _kind(value: Any) -> str:
    return f"{type(value).__name__} {shown(value)}"[:80]


def _cross(a: Vector, b: Vector) -> Vector:
    return sp.ImmutableMatrix(sp.Matrix(a).cross(sp.Matrix(b)))


def _rotate(pose: Body, local: Vector) -> Vector:
    return sp.ImmutableMatrix(pose.rotation * local)


def _global(pose: Body, local: Vector) -> Vector:
    return sp.ImmutableMatrix(pose.position + pose.rotation * local)


def _to_local(pose: Body, vec: Vector, is_direction: bool) -> Vector:
    """Body coordinates of a global point (or direction) at the initial pose."""
    relative = vec if is_direction else vec - pose.position
    return _compact_matrix(pose.rotation.T * relative)


def _carry(pose1: Body, pose2: Body, local1: Vector) -> Vector:
    """Body-2 coordinates of the vector that coincides with body-1's ``local1`` at the initial pose."""
    return _compact_matrix(pose2.rotation.T * pose1.rotation * local1)


def perpendicular(axis: Vector, nominal: Mapping[sp.Symbol, sp.Expr] | None = None) -> Vector:
    """The default unit reference vector perpendicular to ``axis``.

    It is the coordinate axis after the one ``axis`` is most aligned with (x -> y, y -> z,
    z -> x), made perpendicular by Gram-Schmidt: for axis z this is x, as in the paper. An
    axis that depends on design parameters is compared at their ``nominal`` values.
    """
    at_nominal = axis.xreplace(nominal) if nominal else axis
    k = (max(range(3), key=lambda i: (abs(float(at_nominal[i])), -i)) + 1) % 3
    e = sp.Matrix([1 if i == k else 0 for i in range(3)])
    u = e - axis * (axis.T * e)[0]
    return sp.ImmutableMatrix((u / sp.sqrt(sp.expand((u.T * u)[0]))).applyfunc(sp.expand))
