"""Checks of a request shared by the services (:mod:`kinegen.service`)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from kinegen.api import Session
from kinegen.errors import RequestError


def case_system(session: Session, model_file: Any, case: str | None, parametrization: str, compiled: bool | None,
                design: dict[str, float] | None = None) -> tuple[Any, Any]:  # fmt: skip
    """The model and the numeric system of ``case`` (:meth:`kinegen.api.Session.system`); an
    unknown case (or design parameter, or a value outside its bounds) is a :class:`RequestError`
    of ``--case`` (``--design``)."""
    session.module(model_file, parametrization)  # a rebuild's errors before the system's
    try:
        return session.model(model_file), session.system(model_file, case, parametrization, compiled, design or None)
    except (KeyError, ValueError) as exc:
        raise RequestError("--design" if design else "--case", str(exc.args[0])) from None


def check_loads(model: Any, loads: Iterable[str]) -> tuple[str, ...]:
    """The named loads of ``model``, each once; a :class:`RequestError` of ``--load`` for a name the
    model does not declare or one named twice."""
    loads = tuple(loads)
    unknown = [name for name in loads if name not in model.loads]
    if unknown:
        raise RequestError("--load", f"no load {', '.join(map(repr, unknown))} (loads: {', '.join(model.loads) or 'none'})")
    twice = sorted({name for name in loads if loads.count(name) > 1})
    if twice:
        raise RequestError("--load", f"{', '.join(twice)} named more than once (each load is held once)")
    return loads


def named_point(system: Any, text: str | None) -> tuple[str, str] | None:
    """``BODY.POINT`` as (body, point) of a named point of the system's model (None for None); any
    other text is a :class:`RequestError` of ``--point`` listing the known points."""
    if text is None:
        return None
    body, _, name = text.partition(".")
    if body not in system.points or name not in system.points[body]:
        known = ", ".join(f"{b}.{p}" for b, points in system.points.items() for p in points)
        raise RequestError("--point", f"{text!r} is not a named point BODY.POINT of the model (known: {known})")
    return body, name


def check_frame(system: Any, frame_body: str | None) -> None:
    """A picture's frame names a body of the model (None: chosen later); another name is a
    :class:`RequestError` of ``--frame``."""
    if frame_body is not None and frame_body not in system.bodies:
        raise RequestError("--frame", f"no body {frame_body!r} (bodies: {', '.join(system.bodies)})")
