"""The kinds of joint and driver a model may use: the one list of each.

The loader reads here which kinds exist, which keys each takes in a model file and how many
equations a joint gives; the equations themselves are written once per kind in
:mod:`kinegen.constraints.joints` and :mod:`kinegen.constraints.drivers`, registered under
these names (each module checks on import that it builds every kind listed here and no other).
Adding a kind: list it here, register its equations there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

_F = TypeVar("_F", bound=Callable)


@dataclass(frozen=True)
class JointKind:
    """A joint type: its name in model files, its scalar equations, the keys it takes besides
    ``type``, ``bodies`` and where its points are (``points`` or ``at``)."""

    name: str
    equations: int
    keys: frozenset[str]
    doc: str

    @property
    def has_axes(self) -> bool:
        """Whether it takes an axis per body (``axes`` or ``axis``)."""
        return "axis" in self.keys

    @property
    def has_references(self) -> bool:
        """Whether it takes a reference direction per body, perpendicular to its axis (``references``)."""
        return "references" in self.keys


@dataclass(frozen=True)
class DriverKind:
    """A driver type: its name in model files, the keys it needs and may take besides ``type``
    and ``function``."""

    name: str
    needs: frozenset[str]
    optional: frozenset[str]
    doc: str


_AXIS = frozenset({"axes", "axis"})

#: every joint kind, in the order model files' error messages list them
JOINT_KINDS: dict[str, JointKind] = {
    kind.name: kind
    for kind in (
        JointKind("spherical", 3, frozenset(), "the two points coincide"),
        JointKind("revolute", 5, _AXIS | {"references"}, "points coincide, axes aligned: rotation about the axis"),
        JointKind("cylindrical", 4, _AXIS | {"references"}, "axes on one line: rotation about and translation along it"),
        JointKind("prismatic", 5, _AXIS | {"references"}, "axes on one line, no rotation: translation along it"),
        JointKind("universal", 4, _AXIS, "points coincide, the two axes perpendicular"),
        JointKind("fixed", 6, frozenset(), "the two bodies welded at their initial relative pose"),
        JointKind("distance", 1, frozenset({"length"}), "a constant distance between two points"),
    )
}

#: every driver kind
DRIVER_KINDS: dict[str, DriverKind] = {
    kind.name: kind
    for kind in (
        DriverKind("joint_angle", frozenset({"joint"}), frozenset(), "the rotation of a revolute or cylindrical joint [rad]"),
        DriverKind("joint_translation", frozenset({"joint"}), frozenset(), "the translation of a prismatic or cylindrical joint [m]"),
        DriverKind("distance", frozenset({"points"}), frozenset(), "the distance between two body points [m] (an actuator)"),
        DriverKind("coordinate", frozenset({"point", "component"}), frozenset(), "a global coordinate of a body point [m]"),
        DriverKind("body_angle", frozenset({"body", "axis"}), frozenset({"reference"}), "a body's rotation about a global axis [rad]"),
    )
}


def check_registered(what: str, listed: dict, built: dict) -> None:
    """Raise unless ``built`` (the kinds a constraints module builds) are exactly ``listed``."""
    if set(listed) != set(built):
        missing, extra = sorted(set(listed) - set(built)), sorted(set(built) - set(listed))
        raise ImportError(f"{what}: kinds without equations {missing}, equations of unlisted kinds {extra}")


def registrar(table: dict[str, _F]) -> Callable[[str], Callable[[_F], _F]]:
    """``@builds(kind)`` for a module's builders: records the decorated function in ``table`` under ``kind``."""

    def builds(kind: str) -> Callable[[_F], _F]:
        def register(builder: _F) -> _F:
            table[kind] = builder
            return builder

        return register

    return builds
