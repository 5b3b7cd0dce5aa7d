"""Building a model into a generated module file, written atomically."""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterator
from pathlib import Path

import kinegen.codegen.backends as backends
import kinegen.codegen.kept as kept
from kinegen.codegen.forked import may_fork
from kinegen.codegen.kernels import ModuleDescription, describe
from kinegen.codegen.templates import python_literal
from kinegen.collector import collector_paused
from kinegen.errors import ModelError
from kinegen.files import write_atomic
from kinegen.integrity import digest, expected, expected_key, locked, remember, remember_expected
from kinegen.model import Model, load
from kinegen.naming import module_name
from kinegen.rotations import Parametrization, get
from kinegen.textcache import code_fingerprint

#: What ``kinegen build`` writes into generated/: the Python module and the model's C (which
#: the runtime compiles with kinegen's C solver on first use).
DEFAULT_TARGETS = ("python", "c-model")


@collector_paused()
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
    :func:`kinegen.codegen.kernels.describe`).

    Every statement the targets print is eliminated and printed first, every other group in a
    forked process when this process may fork (:func:`kinegen.codegen.forked.may_fork`), and the
    sensitivity kernels derived and printed in another from the start of the description
    (:func:`kinegen.codegen.kernels.describe`'s ``printers``): the same texts, so the same bytes,
    as one process prints. Python's garbage collector is paused meanwhile (:mod:`kinegen.collector`)."""
    # the sensitivity kernels are derived and printed in a forked process by the targets' printers while
    # this one describes the rest and prints it (meanwhile), with one more forked process where it may fork
    fork = may_fork()
    printers = tuple(p for backend in _backends(targets) for p in backends.printers(backend)) if fork else ()

    def meanwhile(partial: ModuleDescription) -> None:
        partial.shapes.prepare([job for backend in _backends(targets, partial) for job in backends.jobs(backend, partial)], fork=fork)

    description = describe(model, parametrization, sensitivities=sensitivities, printers=printers, meanwhile=meanwhile)
    stem = module_name(model, parametrization)
    files: dict[str, dict[str, str]] = {}
    irregular = _irregular(description)
    c_targets = [t for t in targets if t.startswith("c")]
    if irregular:  # the C solver factorizes a square, structurally regular Phi_q
        if "c" in c_targets:
            raise ModelError(
                model.file, "redundant" if model.redundant else "joints",
                f"the standalone C target needs a square, structurally regular Phi_q; case(s) {', '.join(irregular)} "
                "have " + ("redundant constraints (solved by least squares in Python: build with --target python)"
                           if model.redundant else "a structurally singular one"),
            )  # fmt: skip
        files.update({target: {} for target in c_targets})  # generated/ holds no C for it: the runtime solves it in Python
        c_targets = []
    others = [t for t in targets if not t.startswith("c")]
    description.shapes.prepare([job for backend in _backends(targets, description) for job in backends.jobs(backend, description)], fork=fork)
    for target, made in _rendered(description, stem, c_targets, others, fork):
        files[target] = made
        if ready is not None:
            ready(target, made)
    return {target: files[target] for target in targets}


def _rendered(description: ModuleDescription, stem: str, c_targets: list[str], others: list[str], fork: bool) -> Iterator[tuple[str, dict[str, str]]]:
    """(target, its files) of every target, the C ones first: the Python module names the model's C by
    its digests (:func:`_render_c`). Where this process may fork and the model's C and the Python module
    are both made, the Python is rendered in a forked process while this one renders the C (what the
    runtime's compile waits for), its digests then put in at the place the Python holds for them
    (:class:`_PendingDigests`): the same text."""
    if fork and c_targets == ["c-model"] and others == ["python"] and may_fork():
        from kinegen.codegen.forked import Child

        pending, description.c_files = description.c_files, _PendingDigests()
        child = Child(backends.get("python"), description, stem)
        description.c_files = pending
        c_files = _render_c(description, stem, "c-model")
        yield "c-model", c_files
        yield "python", {name: _PendingDigests.filled(text, description.c_files) for name, text in child.result().items()}
        return
    for target in [*c_targets, *others]:
        yield target, _render_c(description, stem, target) if target in c_targets else backends.get(target)(description, stem)


class _PendingDigests(dict):
    """``description.c_files`` where the Python module is rendered before the model's C: empty, and
    printed (``repr``) as a token that :meth:`filled` replaces with the digests' own literal."""

    TOKEN = "__kinegen_c_files_still_being_rendered__"

    def __repr__(self) -> str:
        return self.TOKEN

    @classmethod
    def filled(cls, text: str, c_files: dict[str, str]) -> str:
        """``text`` with its one token replaced by ``c_files``' literal (as the template prints it)."""
        if text.count(cls.TOKEN) != 1:
            raise RuntimeError(f"the Python module holds {text.count(cls.TOKEN)} places for its C files' digests, not one")
        return text.replace(cls.TOKEN, python_literal(c_files))


def _irregular(description: ModuleDescription) -> list[str]:
    """The cases whose Phi_q is not square and structurally regular (no C for them)."""
    return [name for name, case in description.cases.items() if case.plan is None]


def _backends(targets: tuple[str, ...], description: ModuleDescription | None = None) -> list[str]:
    """The backends that print ``targets`` ("c" for the C targets, unless ``description`` has a case
    without C: :func:`_irregular`), in the order :func:`generate` prints them."""
    with_c = any(t.startswith("c") for t in targets) and not (description is not None and _irregular(description))
    return list(dict.fromkeys(["c"] * with_c + [t for t in targets if not t.startswith("c")]))


def _render_c(description: ModuleDescription, stem: str, target: str) -> dict[str, str]:
    """A C target's files; the model's C (``c-model``) also sets ``description.c_files``: the
    Python module names the C beside it by its bytes' hash (runtime.native)."""
    files = backends.get("c")(description, stem, standalone=target == "c")
    if target == "c-model":
        description.c_files = {name: hashlib.sha256(text.encode("utf-8")).hexdigest() for name, text in files.items()}
    return files


def module_key(model: Model, parametrization: str, sensitivities: bool, with_c: bool) -> str:
    """The trust store's name for the module kinegen writes for a model version (its file's name
    and digest: the module names both), parametrization and options
    (:func:`kinegen.integrity.expected_key`), by this kinegen (its code's fingerprint: a changed
    generator writes other bytes under the same version)."""
    return expected_key(Path(model.file).name, model.source_sha256, parametrization, str(sensitivities if model.design else None),
                        str(with_c), _generator_fingerprint())  # fmt: skip


def _generator_fingerprint() -> str:
    """What the generated bytes depend on besides the model: kinegen's code (every source, template
    and C file of the package) and SymPy's version (:func:`kinegen.textcache.code_fingerprint`)."""
    return code_fingerprint(kept.GENERATOR_SUFFIXES)


def write_files(out_dir: str | Path, files: dict[str, str], module: tuple[str, str] | None = None) -> None:
    """Write generated ``files`` (name -> text) into ``out_dir``, each atomically, and record them
    as kinegen's own in the trust store (:mod:`kinegen.integrity`). ``module`` = (the Python
    module's file name, its :func:`module_key`): also recorded as what kinegen writes for that key."""
    out = Path(out_dir)
    for name, text in files.items():
        data = text.encode("utf-8")
        write_atomic(out / name, data)
        written = remember(data)
        if module is not None and name == module[0]:
            remember_expected(module[1], written)


def regenerates(data: bytes, model_path: str | Path, parametrization: str, sensitivities: bool | None, with_c: bool) -> bool:
    """Whether kinegen, building ``model_path`` in ``parametrization`` (with the sensitivity kernels
    as ``sensitivities`` says; with the model's C when ``with_c``), writes exactly ``data`` as the
    Python module. What it writes is recorded (:func:`module_key`): another copy is compared with
    that digest without building again. When it is ``data``, the module and its C are remembered
    as kinegen's own."""
    model = load(model_path)
    param = get(parametrization)
    key = module_key(model, param.name, sensitivities is not False, with_c)
    with locked(key):  # (processes verifying the same module at once: one builds, the others read what it found)
        return _regenerates(data, model, param, sensitivities, with_c, key)


def _regenerates(data: bytes, model: Model, param: Parametrization, sensitivities: bool | None, with_c: bool, key: str) -> bool:
    known = expected(key)
    if known is not None:
        if known == digest(data):
            remember(data)
            return True
        return False
    made = generate(model, param, ("python", "c-model") if with_c else ("python",), sensitivities=sensitivities is not False)
    python = made["python"][f"{module_name(model, param)}.py"].encode("utf-8")
    remember_expected(key, digest(python))
    if python != data:
        return False
    for files in made.values():
        for text in files.values():
            remember(text.encode("utf-8"))
    return True


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
    keep: bool = True,
) -> Path:
    """Build ``model_path`` in ``parametrization`` into ``out_dir``: by default
    ``<model>_<param>.py`` and the model's C (``.c``, ``.h``); ``targets=("c",)``: a standalone C
    directory. Returns the Python module's path (without the python target: ``out_dir``).

    ``check(source, model_path)`` (e.g. :func:`kinegen.runtime.check_source`) runs on the
    Python module's text (made for it whatever the targets) before anything is written; if it
    raises, nothing is written. ``ready`` and ``sensitivities`` as for :func:`generate`. Everything that can fail happens before the (atomic, file by
    file) writes. ``model``: the model of ``model_path`` when the caller has read it already.

    The files are kept in kinegen's cache (:mod:`kinegen.codegen.kept`): the same build asked for
    again (the same model bytes, parametrization, options and targets, this kinegen) takes them
    from there, checked and written as a derived build's; ``keep=False`` derives and keeps nothing.
    """
    from kinegen.progress import Stages

    model = model if model is not None else load(model_path)
    param = get(parametrization)
    made_targets = tuple(dict.fromkeys((*targets, "python"))) if check is not None else targets
    with Stages(f"build {model.name} ({param.name})", 3) as stages:
        cache_key = kept.build_key(model, param, made_targets, sensitivities)
        made = kept.kept(cache_key, made_targets) if keep else None
        derived = made is None
        if derived:
            stages.stage("deriving and printing")
            made = generate(model, param, made_targets, ready, sensitivities)
        else:
            stages.stage("kept from an earlier build")
            for target in sorted(made, key=lambda name: not name.startswith("c")):  # (the C first, as generate calls it)
                if ready is not None and made[target]:
                    ready(target, made[target])
        python = f"{module_name(model, param)}.py"
        stages.stage("checking")
        if check is not None:
            check(made["python"][python], model_path)
        stages.stage("writing")
        out = Path(out_dir)
        written = {name: text for target in targets for name, text in made[target].items()}
        key = module_key(model, param.name, sensitivities, bool(made.get("c-model")))
        write_files(out, written, (python, key))
        if keep and derived:
            kept.keep(cache_key, made)
    return out / python if "python" in targets else out
