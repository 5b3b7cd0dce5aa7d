"""The in-memory path: ``sympy.lambdify`` of the symbolic system, no file written.

It returns an object with the same attributes as a generated module, so the runtime
treats both alike. Building is quicker (no printing); evaluation is slower. A case's
functions are made when the case is first read (``CASES[name]``), their common
subexpressions eliminated by SymEngine (:func:`kinegen.symbolic.engine.eliminate`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import sympy as sp

from kinegen.codegen.backends.python.intervals import evaluate
from kinegen.codegen.intervals import interval_program
from kinegen.codegen.kernels import initial_q
from kinegen.errors import ModelError
from kinegen.model import Model
from kinegen.model.expressions import T
from kinegen.rotations import Parametrization
from kinegen.symbolic import build_systems
from kinegen.symbolic.engine import eliminate


def _stacked(function, m: int, batch_args: tuple[int, ...] = (0,)):
    """Wrap a lambdified list-returning function into one returning an (m, ...) array."""

    def evaluate(*args):
        values = function(*args)
        shapes = [np.shape(args[i][0]) if len(args[i]) else () for i in batch_args if i < len(args)]
        out = np.zeros((m,) + np.broadcast_shapes(*shapes))
        for i, value in enumerate(values):
            out[i] = value
        return out

    return evaluate


def _inputs(functions, t_symbol, m: int):
    compiled = sp.lambdify([t_symbol], list(functions), modules="numpy")

    def evaluate(t):
        out = np.zeros((m,) + np.shape(t))
        for i, value in enumerate(compiled(t)):
            out[i] = value
        return out

    return evaluate


class _Cases(Mapping):
    """A generated module's CASES, each case's functions made on first reading."""

    def __init__(self, names: tuple[str, ...], make: Callable[[str], dict]) -> None:
        self._names, self._make, self._made = names, make, {}

    def __getitem__(self, name: str) -> dict:
        if name not in self._names:
            raise KeyError(name)
        if name not in self._made:
            self._made[name] = self._make(name)
        return self._made[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)


def lambdify_model(model: Model, parametrization: Parametrization) -> SimpleNamespace:
    """A module-like namespace with every case of ``model``, each compiled by ``lambdify`` when it
    is first read (a model with design parameters: ``model.at(values)`` fixes them; generated
    modules take them)."""
    if model.design:
        raise ModelError(model.file, "design", "lambdify_model takes numbers: use model.at(values), or a generated module")
    systems = build_systems(model, parametrization)
    first = next(iter(systems.values()))
    coords = first.coordinates
    q, v = coords.stored_symbols, coords.velocity_symbols
    definitions = coords.frame_definitions

    def compile_(args, exprs, size):
        exprs = [e.xreplace(definitions) for e in exprs]
        return _stacked(sp.lambdify(args, exprs, modules="numpy", cse=eliminate), size, (0, 1))

    def case(name: str) -> dict:
        system = systems[name]
        rows, entries = system.rows, system.jacobian_entries
        m = len(rows)
        inputs = system.inputs
        u, ud, udd = list(inputs.u), list(inputs.ud), list(inputs.udd)
        functions = inputs.stacked()
        return {
            "constraints": tuple(r.name for r in rows),
            "drivers": inputs.names,
            "jac_rows": tuple(i for i, _, _ in entries),
            "jac_cols": tuple(j for _, j, _ in entries),
            "t0": system.case.t0,
            "t1": system.case.t1,
            "steps": system.case.steps,
            "driver_sources": inputs.sources,
            "outputs": {  # the outputs of the kernels a generated module's case declares (no plain-float ones)
                "inputs": _inputs(functions, T, len(functions)),
                "input_ranges": functools.partial(evaluate, interval_program(functions)),
                "phi": compile_([q, u], [r.phi for r in rows], m),
                "jac": compile_([q, u], [e for _, _, e in entries], len(entries)),
                "nu": compile_([q, u, ud], [r.nu for r in rows], m),
                "gamma": compile_([q, v, u, ud, udd], [r.gamma for r in rows], m),
            },
            "scalar": {},
            "patterns": {},
        }

    return SimpleNamespace(
        MODEL=model.name,
        PARAMETRIZATION=parametrization.name,
        SOURCE=Path(model.file).name,
        SOURCE_SHA256=model.source_sha256,
        STORED_NAMES=tuple(coords.stored_names),
        VELOCITY_NAMES=tuple(coords.velocity_names),
        BODIES={b.name: (b.stored_offset, b.velocity_offset) for b in coords.bodies},
        POINTS={b.name: {k: tuple(float(sp.N(x, 30)) for x in p) for k, p in b.points.items()} for b in model.bodies},
        GROUND_POINTS={k: tuple(float(sp.N(x, 30)) for x in p) for k, p in model.ground_points.items()},
        INITIAL_Q=tuple(initial_q(model, parametrization)),
        ACTUATORS={
            a.name: ((a.points[0].body, a.points[0].name), (a.points[1].body, a.points[1].name), a.limits()) for a in model.actuators
        },
        CASES=_Cases(tuple(systems), case),
    )
