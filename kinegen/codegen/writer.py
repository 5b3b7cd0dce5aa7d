"""Building a model into a generated module file, written atomically."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path

import kinegen.codegen.backends as backends
from kinegen.codegen.kernels import describe
from kinegen.errors import ModelError
from kinegen.files import write_atomic
from kinegen.integrity import seal, sealed
from kinegen.model import Model, load
from kinegen.rotations import Parametrization, get

#: What ``kinegen build`` writes into generated/: the Python module and the model's C (which
#: the runtime compiles with kinegen's C solver on first use).
DEFAULT_TARGETS = ("python", "c-model")


def module_name(model: Model, parametrization: Parametrization) -> str:
    """File stem of the generated module, e.g. ``boom_quaternion``."""
    return f"{model.name}_{parametrization.file_tag}"


def generate(
    model: Model,
    parametrization: Parametrization,
    targets: tuple[str, ...] = DEFAULT_TARGETS,
    ready: Callable[[str, dict[str, str]], None] | None = None,
    sensitivities: bool = True,
) -> dict[str, dict[str, str]]:
    """Per target, file name -> text of what it makes for ``model`` (all cases) in
    ``parametrization``: ``python`` (the module), ``c`` (a standalone C directory), ``c-model``
    (only the model's C, as generated/ holds it). The kernel description is made once; the C
    targets are printed first, and ``ready(target, files)`` is called as each target is done
    (e.g. to start compiling the C while the Python is printed). ``sensitivities``: a model with
    design parameters gets the kernels of its exact sensitivities (see
    :func:`kinegen.codegen.kernels.describe`)."""
    description = describe(model, parametrization, sensitivities=sensitivities)
    stem = module_name(model, parametrization)
    files: dict[str, dict[str, str]] = {}
    irregular = [name for name, case in description.cases.items() if case.plan is None]
    for target in sorted(targets, key=lambda t: not t.startswith("c")):
        if target.startswith("c") and irregular:  # the C solver factorizes a square, structurally regular Phi_q
            if target == "c":
                raise ModelError(
                    model.file, "redundant" if model.redundant else "joints",
                    f"the standalone C target needs a square, structurally regular Phi_q; case(s) {', '.join(irregular)} "
                    "have " + ("redundant constraints (solved by least squares in Python: build with --target python)"
                               if model.redundant else "a structurally singular one"),
                )  # fmt: skip
            files[target] = {}  # generated/ holds no C for it: the runtime solves it in Python
            continue
        if target == "c-model":
            made = backends.get("c")(description, stem, standalone=False)
        else:
            made = backends.get(target)(description, stem)
        # the model's own files carry a seal over their text (kinegen.integrity), checked before they run
        files[target] = {name: seal(name, text) if Path(name).stem == stem and sealed(name) else text for name, text in made.items()}
        if target == "c-model":  # the Python module names the C beside it by its bytes' hash (runtime.native)
            description.c_files = {name: hashlib.sha256(text.encode("utf-8")).hexdigest() for name, text in files[target].items()}
        if ready is not None:
            ready(target, files[target])
    return {target: files[target] for target in targets}


def generate_source(model: Model, parametrization: Parametrization) -> str:
    """Source of the generated Python module for ``model`` (all cases) in ``parametrization``."""
    return generate(model, parametrization, ("python",))["python"][f"{module_name(model, parametrization)}.py"]


def built_with_sensitivities(path: str | Path) -> bool | None:
    """Whether the generated module at ``path`` (Python or C) holds sensitivity kernels, as its
    header says: True or False for a model with design parameters, None for one without (or
    no such file)."""
    try:
        with Path(path).open(encoding="utf-8") as handle:
            head = [next(handle, "") for _ in range(14)]
    except OSError:
        return None
    for line in head:
        if "sensitivities:" in line:
            return line.split("sensitivities:")[1].strip() == "yes"
    return None


def build(
    model_path: str | Path,
    parametrization: str,
    out_dir: str | Path = "generated",
    check: Callable[[str, str | Path], list[str]] | None = None,
    targets: tuple[str, ...] = DEFAULT_TARGETS,
    ready: Callable[[str, dict[str, str]], None] | None = None,
    sensitivities: bool = True,
    model: Model | None = None,
) -> Path:
    """Build ``model_path`` in ``parametrization`` into ``out_dir``: by default
    ``<model>_<param>.py`` and the model's C (``.c``, ``.h``); ``targets=("c",)``: a standalone C
    directory. Returns the Python module's path (without the python target: ``out_dir``).

    ``check(source, model_path)`` (e.g. :func:`kinegen.runtime.check_source`) runs on the
    Python module's text (made for it whatever the targets) before anything is written; if it
    raises, nothing is written. ``ready`` and ``sensitivities`` as for :func:`generate`. Everything that can fail happens before the (atomic, file by
    file) writes. ``model``: the model of ``model_path`` when the caller has read it already.
    """
    from kinegen.progress import Stages

    model = model if model is not None else load(model_path)
    param = get(parametrization)
    with Stages(f"build {model.name} ({param.name})", 3) as stages:
        stages.stage("deriving and printing")
        made = generate(model, param, tuple(dict.fromkeys((*targets, "python"))) if check is not None else targets, ready, sensitivities)
        python = f"{module_name(model, param)}.py"
        stages.stage("checking")
        if check is not None:
            check(made["python"][python], model_path)
        stages.stage("writing")
        out = Path(out_dir)
        for target in targets:
            for name, text in made[target].items():
                write_atomic(out / name, text)
    return out / python if "python" in targets else out
