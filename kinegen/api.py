"""kinegen as a library: open a model, get its generated module by one rule, solve.

The command line (:mod:`kinegen.cli`), the main job (:mod:`kinegen.demo`) and the benchmarks go
through :class:`Session`, so that a model file is read once per session and every caller
rebuilds a missing or stale module the same way:

* a module is **fresh** when kinegen wrote its bytes (or regenerates them: :mod:`kinegen.integrity`),
  it was built by this kinegen and from the model file's current bytes
  (:func:`kinegen.runtime.load_module`);
* a **missing or stale** one is **rebuilt** into the same folder -- with the sensitivity kernels if
  the model has design parameters and the stale module had them (or none was there), unless the
  caller says otherwise -- checked (time functions finite, initial pose assembles;
  ``Session.check``) before anything is written, and loaded;
* a **changed** one (bytes kinegen did not write: edited or planted, Python or C) is refused with
  :class:`~kinegen.errors.ChangedFileError` (exit 5), never rebuilt over silently.

Example::

    from kinegen.api import Session
    from kinegen.runtime import kinematics

    session = Session("generated")
    results = session.solve("models/excavator.yaml", case="digging")
    print(kinematics.point_position(results, "bucket", "T")[-1])
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from pathlib import Path
from types import ModuleType

import numpy as np

from kinegen import rotations
from kinegen.errors import ChangedFileError, GeneratedModuleError


@dataclasses.dataclass
class Session:
    """Models and generated modules of one folder (``generated_dir``), each read or built once.

    ``announce``: called with one line when a module is (re)built (the CLI prints it on stderr).
    ``check``: a build is checked before it is written (time functions finite on their grids,
    initial poses assemble); the main job turns it off, as it builds Euler-angle modules that are
    singular at their initial pose on purpose. ``reuse``: a build asked for again takes what it
    wrote before from kinegen's cache (:mod:`kinegen.codegen.kept`); ``make generate`` derives every one."""

    generated_dir: str | Path = "generated"
    announce: Callable[[str], None] | None = None
    check: bool = True
    reuse: bool = True
    _models: dict = dataclasses.field(default_factory=dict, repr=False)
    _modules: dict = dataclasses.field(default_factory=dict, repr=False)

    def model(self, model_file: str | Path):
        """The model of ``model_file`` (:class:`kinegen.model.Model`), read once per session; an
        over-constrained one is refused naming the joints whose equations repeat each other."""
        from kinegen.errors import OverConstrainedError
        from kinegen.model import load

        key = str(model_file)
        if key not in self._models:
            try:
                self._models[key] = load(model_file)
            except OverConstrainedError as error:
                from kinegen.symbolic.rank import explain

                raise explain(error) from None
        return self._models[key]

    def module_path(self, model_file: str | Path, parametrization: str = rotations.REFERENCE) -> Path:
        """Where the generated module of ``model_file`` in ``parametrization`` lives."""
        from kinegen.naming import module_name

        return Path(self.generated_dir) / f"{module_name(self.model(model_file), rotations.get(parametrization))}.py"

    def module(self, model_file: str | Path, parametrization: str = rotations.REFERENCE, sensitivities: bool | None = None) -> ModuleType:
        """The generated module of ``model_file`` in ``parametrization``: loaded if fresh, else
        rebuilt (see the module docstring); ``sensitivities`` None keeps what the stale module had."""
        key = (str(model_file), rotations.get(parametrization).name)
        if key in self._modules:
            return self._modules[key]
        from kinegen.runtime import load_module

        path = self.module_path(model_file, parametrization)
        try:
            module = load_module(path, model_file)
        except ChangedFileError:
            raise
        except GeneratedModuleError:
            module = load_module(self.build(model_file, parametrization, sensitivities, reason="missing or stale"), model_file)
        self._modules[key] = module
        return module

    def build(self, model_file: str | Path, parametrization: str = rotations.REFERENCE, sensitivities: bool | None = None,
              reason: str = "") -> Path:  # fmt: skip
        """Build the module (Python and the model's C) into ``generated_dir``, checked before it is
        written; returns its path. ``sensitivities`` None: as the module there had them (default yes)."""
        from kinegen.codegen import build, built_with_sensitivities
        from kinegen.runtime import check_source

        name = rotations.get(parametrization).name
        path = self.module_path(model_file, name)
        if self.announce is not None:
            self.announce(f"building {path}{f' ({reason})' if reason else ''}")
        keep = built_with_sensitivities(path) is not False if sensitivities is None else sensitivities
        self._modules.pop((str(model_file), name), None)
        return build(model_file, name, self.generated_dir, check=check_source if self.check else None, sensitivities=keep,
                     model=self.model(model_file), keep=self.reuse)

    def system(self, model_file: str | Path, case: str | None = None, parametrization: str = rotations.REFERENCE,
               compiled: bool | None = None, design: Mapping[str, float] | None = None):  # fmt: skip
        """The numeric system (:class:`kinegen.runtime.NumericSystem`) of ``case`` (default: the
        first), compiled when a C compiler is there (``compiled`` None), design parameters at
        ``design`` (the others nominal). KeyError for an unknown case or parameter, ValueError for
        a value outside its bounds."""
        from kinegen.runtime import from_module

        system = from_module(self.module(model_file, parametrization), case, compiled, design)
        return dataclasses.replace(system, source=str(model_file))

    def solve(self, model_file: str | Path, case: str | None = None, parametrization: str = rotations.REFERENCE,
              times: np.ndarray | None = None, options=None, design: Mapping[str, float] | None = None):  # fmt: skip
        """Position, velocity and acceleration of ``case`` over ``times`` (default: the case's grid):
        :class:`kinegen.runtime.Results`."""
        from kinegen.runtime import SolverOptions, solve

        options = options or SolverOptions()
        return solve(self.system(model_file, case, parametrization, None if options.compiled else False, design), times, options)
