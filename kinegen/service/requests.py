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
