"""The in-memory path: ``sympy.lambdify`` of the kernel declaration, no file written.

It returns an object with the same attributes as a generated module, so the runtime
treats both alike. Building is quicker (no printing); evaluation is slower. The functions are
those the case's kernels declare (:func:`kinegen.codegen.kernels.describe`): each output the
concatenation of its sections' groups (renamed from their shape's placeholders, as a backend
prints them) or zeros, the input enclosures through the declared interval program -- the
same source the Python and C backends print. A case's functions are made when each is first
called (the case's outputs when it is first read, ``CASES[name]``), their common subexpressions
eliminated by SymEngine (:func:`kinegen.symbolic.engine.eliminate`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Mapping
from types import SimpleNamespace

import numpy as np
import sympy as sp

from kinegen.codegen.backends.python.intervals import evaluate
from kinegen.codegen.kernels import CaseDescription, Kernel, ModuleDescription, Output, Zeros, describe
from kinegen.errors import ModelError
from kinegen.model import Model
from kinegen.rotations import Parametrization
from kinegen.symbolic.engine import eliminate


def _stacked(function, m: int, batch_args: tuple[int, ...]):
    """Wrap a lambdified list-returning function into one returning an (m, ...) array, the batch
    shape broadcast from the first value of the arguments ``batch_args`` (none: one value)."""

    def evaluate(*args):
        values = function(*args)
        shapes = [np.shape(args[i][0]) if len(args[i]) else () for i in batch_args if i < len(args)]
        out = np.zeros((m,) + np.broadcast_shapes(*shapes))
        for i, value in enumerate(values):
            out[i] = value
        return out

    return evaluate


def _time_function(function, m: int):
    """Wrap a lambdified function of the time t (a number or an array) into one returning (m, ...)."""

    def evaluate(t):
        out = np.zeros((m,) + np.shape(t))
        for i, value in enumerate(function(t)):
            out[i] = value
        return out

    return evaluate


def _expressions(description: ModuleDescription, output: Output) -> list[sp.Expr]:
    """An output's values as expressions of the kernel's slots: each part's groups renamed from
    their shape's placeholders to their own symbols (or the part's zeros), then every rotation-matrix
    symbol replaced by its definition in the stored coordinates."""
    definitions = {s: v for _, symbols, values in description.definitions.bodies for s, v in zip(symbols, values)}
    values: list[sp.Expr] = []
    for part in output.parts:
        if isinstance(part, Zeros):
            values += [sp.Integer(0)] * part.size
            continue
        for group in description.sections[part].groups:
            values += [e.xreplace(group.rename) for e in group.expressions()]
    return [e.xreplace(definitions) for e in values]


def _output_function(description: ModuleDescription, case: CaseDescription, kernel: Kernel, output: Output) -> Callable:
    """One output of a case's kernel as a NumPy function of the kernel's slots (``t``: a number or an
    array of times; the others: sequences of values, each a number or an array of one batch shape)."""
    if len(output.parts) == 1 and output.parts[0] in description.enclosures:
        return functools.partial(evaluate, description.enclosures[output.parts[0]].program)
    slots = {**description.slots, **case.slots}
    arguments = [slots[s][0] if s == "t" else list(slots[s]) for s in kernel.slots]
    function = sp.lambdify(arguments, _expressions(description, output), modules="numpy", cse=eliminate)
    if kernel.slots == ("t",):
        return _time_function(function, output.size)
    return _stacked(function, output.size, tuple(i for i, s in enumerate(kernel.slots) if s != "t"))


class _Lazy:
    """An output's NumPy function, lambdified when first called: a case's gamma is most of the
    lambdify time (the truss of tests/test_bounded_inputs.py in euler:zxz: 2.8 of its 3.8 s), and an
    inspection or a classification asks for Phi and Phi_q alone."""

    __slots__ = ("_function", "_make")

    def __init__(self, make: Callable[[], Callable]) -> None:
        self._make, self._function = make, None

    def __call__(self, *args):
        if self._function is None:
            self._function = self._make()
        return self._function(*args)


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
    modules take them): the outputs of every kernel the case declares, the force and sensitivity
    kernels aside (:func:`~kinegen.codegen.kernels.describe` with ``forces`` and ``sensitivities``
    False)."""
    if model.design:
        raise ModelError(model.file, "design", "lambdify_model takes numbers: use model.at(values), or a generated module")
    d = describe(model, parametrization, sensitivities=False, forces=False)

    def case(name: str) -> dict:
        c = d.cases[name]
        return {
            "constraints": c.constraints,
            "drivers": c.drivers,
            "jac_rows": c.jac_rows,
            "jac_cols": c.jac_cols,
            "t0": c.t0,
            "t1": c.t1,
            "steps": c.steps,
            "driver_sources": c.driver_sources,
            "outputs": {  # the outputs of the kernels the case declares (no plain-float ones), each made when first called
                output.name: _Lazy(functools.partial(_output_function, d, c, kernel, output))
                for kernel in c.kernels.values() for output in kernel.outputs
            },
            "scalar": {},
            "patterns": {},
        }

    return SimpleNamespace(
        MODEL=d.model,
        PARAMETRIZATION=parametrization.name,
        SOURCE=d.source,
        SOURCE_SHA256=d.sha256,
        STORED_NAMES=d.stored_names,
        VELOCITY_NAMES=d.velocity_names,
        BODIES={name: (stored, velocity) for name, stored, velocity in d.bodies},
        POINTS=d.points,
        GROUND_POINTS=d.ground_points,
        INITIAL_Q=d.initial_q,
        ACTUATORS={name: (first, second, limits) for name, first, second, limits in d.actuators},
        CASES=_Cases(tuple(d.cases), case),
    )
