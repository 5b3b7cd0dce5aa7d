"""Building a model into a generated module file, written atomically."""

from __future__ import annotations

import hashlib
import multiprocessing
import threading
from collections.abc import Callable
from pathlib import Path

import kinegen.codegen.backends as backends
from kinegen.codegen.kernels import ModuleDescription, describe
from kinegen.errors import ModelError
from kinegen.files import write_atomic
from kinegen.integrity import digest, expected, expected_key, locked, remember, remember_expected
from kinegen.model import Model, load
from kinegen.rotations import Parametrization, get
from kinegen.textcache import code_fingerprint

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
    :func:`kinegen.codegen.kernels.describe`).

    With the Python module and C to print, and a process that may fork (no other thread running),
    the C is printed in a forked process while this one prints the Python (each eliminates the
    common subexpressions it needs: the same statements, so the same bytes as one process prints)."""
    description = describe(model, parametrization, sensitivities=sensitivities)
    stem = module_name(model, parametrization)
    files: dict[str, dict[str, str]] = {}
    irregular = [name for name, case in description.cases.items() if case.plan is None]
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
    if "python" in targets and c_targets and _may_fork():
        printing = _CInAnotherProcess(description, stem, c_targets, ready)
        files["python"] = backends.get("python")(description, stem, before_template=lambda: files.update(printing.wait()))
        if ready is not None:
            ready("python", files["python"])
        return {target: files[target] for target in targets}
    for target in [*c_targets, *(t for t in targets if not t.startswith("c"))]:
        if target in c_targets:
            files[target] = _render_c(description, stem, target)
        else:
            files[target] = backends.get(target)(description, stem)
        if ready is not None:
            ready(target, files[target])
    return {target: files[target] for target in targets}


def _render_c(description: ModuleDescription, stem: str, target: str) -> dict[str, str]:
    """A C target's files; the model's C (``c-model``) also sets ``description.c_files``: the
    Python module names the C beside it by its bytes' hash (runtime.native)."""
    return _named_c(description, target, backends.get("c")(description, stem, standalone=target == "c"))


def _named_c(description: ModuleDescription, target: str, files: dict[str, str]) -> dict[str, str]:
    """``files`` of a C target; for the model's C, its bytes' hashes set in ``description.c_files``."""
    if target == "c-model":
        description.c_files = {name: hashlib.sha256(text.encode("utf-8")).hexdigest() for name, text in files.items()}
    return files


def _may_fork() -> bool:
    """Whether this process may print in a forked child: fork exists, no other thread runs (a
    fork copies only the calling thread: a lock another one holds would stay held), and it is
    not a daemonic process (which may not have children)."""
    return ("fork" in multiprocessing.get_all_start_methods() and threading.active_count() == 1
            and not multiprocessing.current_process().daemon)  # fmt: skip


class _CInAnotherProcess:
    """The C targets printed in a forked child process; their files come back through a pipe,
    received by a thread here that also sets ``description.c_files`` and calls ``ready`` for each
    (so the C compiles while the Python is still printed)."""

    def __init__(self, description: ModuleDescription, stem: str, targets: list[str], ready) -> None:
        context = multiprocessing.get_context("fork")
        receiving, sending = context.Pipe(duplex=False)
        self._child = context.Process(target=_print_c, args=(description, stem, targets, sending), name="kinegen-print-c", daemon=True)
        self._child.start()
        sending.close()
        self._files: dict[str, dict[str, str]] = {}
        self._error: BaseException | None = None

        def receive() -> None:
            try:
                try:
                    outcome, value = receiving.recv()
                except EOFError:
                    ended = f"the process printing the C ended without its files (exit code {self._child.exitcode})"
                    outcome, value = "error", (RuntimeError, (ended,), {})
                finally:
                    receiving.close()
                if outcome == "error":
                    raise _exception(*value)
                for target in targets:
                    self._files[target] = _named_c(description, target, value[target])
                    if ready is not None:
                        ready(target, value[target])
            except BaseException as exc:  # handed to wait()
                self._error = exc

        self._receiver = threading.Thread(target=receive, name="kinegen-receive-c", daemon=True)
        self._receiver.start()

    def wait(self) -> dict[str, dict[str, str]]:
        """The C targets' files, once printed (and ``ready`` called for them); the child's error raised here."""
        self._receiver.join()
        self._child.join()
        if self._error is not None:
            raise self._error
        return self._files


def _print_c(description: ModuleDescription, stem: str, targets: list[str], sending) -> None:
    """In the forked child: print the C targets, send ("files", {target: files}) or ("error", exception)."""
    try:
        made = {target: _render_c(description, stem, target) for target in targets}
        sending.send(("files", made))
    except BaseException as exc:  # every failure goes back to the parent, as its class, args and attributes
        try:
            sending.send(("error", (type(exc), exc.args, dict(vars(exc)))))
        except Exception:  # one that does not pickle: its text
            sending.send(("error", (RuntimeError, (f"{type(exc).__name__}: {exc}",), {})))
    finally:
        sending.close()


def _exception(kind: type[BaseException], args: tuple, attributes: dict) -> BaseException:
    """An exception of ``kind`` with these ``args`` and attributes, its ``__init__`` not called
    again (kinegen's errors take other arguments than the message they keep in ``args``)."""
    exc = kind.__new__(kind)
    exc.args = args
    exc.__dict__.update(attributes)
    return exc


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
    return code_fingerprint((".py", ".jinja", ".c", ".h"))


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
        written = {name: text for target in targets for name, text in made[target].items()}
        key = module_key(model, param.name, sensitivities, bool(made.get("c-model")))
        write_files(out, written, (python, key))
    return out / python if "python" in targets else out
