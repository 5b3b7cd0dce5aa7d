"""The C backend as the runtime's fast path: a generated module's C (``<stem>.c`` beside its
``.py``) compiled with kinegen's C solver (``kinegen_solver.c``) into a shared library, loaded
with ctypes.

* The library is built once and cached (``$KINEGEN_CACHE``, default ``~/.cache/kinegen``) under
  a key that covers the C sources, the compiler (its path and ``--version``) and the flags.
* The kernels are called through the function pointers of the case's ``kinegen_model``; their
  ctypes signatures come from the module's kernel description (``KERNELS``: argument slots and
  outputs), not from a hand-written list.
* :class:`NativeCase` evaluates the kernels at one configuration, runs the solver's step loop
  in C (:meth:`NativeCase.trajectory`, handing any step it cannot take back to Python) and
  Newton on many configurations (:meth:`NativeCase.solve_batch`).

Without a C compiler :func:`native_case` says so once (a warning) and returns None: the
pure-Python functions remain.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import re
import shutil
import subprocess
import tempfile
import threading
import time
import warnings
import weakref
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager, suppress
from functools import cache, cached_property
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from kinegen.codegen.backends.c.config import RUNTIME, has_sensitivity_parts, sensitivity_parts, source_parts
from kinegen.errors import ExitCode, KinegenError
from kinegen.files import cache_folder
from kinegen.integrity import remember, trusted
from kinegen.runtime.abi import Abi, AbiError, bind_functions

SOLVER_SOURCES = Path(__file__).resolve().parents[1] / "codegen" / "backends" / "c" / "solver"
#: flags of the runtime's library (the standalone target's Makefile has its own). The library
#: is built on the machine that runs it, so the solver and the model may use that machine's
#: instructions (-march=native: the solver ~20 % faster; the model's kernels and written-out
#: solves take the three-operand scalar forms, a compiled step 5-13 % faster, docs/performance.md).
#: No floating-point contraction (-ffp-contract=off: GCC's default under -std=c99, not Clang's) or
#: reassociation is allowed, and -O1 does not vectorize, so the results are the same to the bit. The
#: model's straight-line kernels compile at -O1 without the second scheduling pass: half the compile
#: time of -O2 for kernels ~10 % slower, a few percent of a step. Both compile in parallel, then link.
PORTABLE = "-march=native"  # dropped where the compiler refuses it
NO_CONTRACTION = "-ffp-contract=off"  # dropped too where the compiler refuses it
#: the flags a compiler may not know, dropped in this order from a command it refuses (_run_all)
OPTIONAL_FLAGS = (PORTABLE, NO_CONTRACTION)
COMMON_FLAGS = ("-std=c99", NO_CONTRACTION, "-fPIC")
SOLVER_FLAGS = ("-O2", PORTABLE)
MODEL_FLAGS = ("-O1", "-fno-schedule-insns2", PORTABLE)
_WARNED: set[str] = set()


class CompileError(KinegenError):
    """No usable C compiler, or the generated C did not compile."""

    exit_code = ExitCode.COMPILE


class Options(dict):
    """Settings of ``kinegen_options`` (kinegen_solver.h) by field name; the rest keep
    ``kinegen_default_options``'. Laid into the library's own struct when a solver is made."""

    @classmethod
    def newton_only(cls, tolerance: float, singular_tolerance: float, max_iterations: int = 25) -> Options:
        """Options for plain Newton on configurations (no predictor, certificate, polish or condition)."""
        return cls(tolerance=tolerance, singular_tolerance=singular_tolerance, max_iterations=max_iterations,
                   predictor=0, chord=0, polish=0, keep_branch=0, condition=0, max_refinements=0)  # fmt: skip


def c_compiler() -> str:
    """The machine's C compiler: ``$CC``, else ``cc``, else ``gcc``; CompileError if none."""
    chosen = os.environ.get("CC")
    if chosen:
        compiler = shutil.which(chosen)
        if compiler is None:
            raise CompileError(f"CC={chosen!r} is not an executable C compiler")
        return compiler
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise CompileError("no C compiler found (set CC, or install gcc)")
    return compiler


@cache
def _compiler_identity(compiler: str) -> str:
    """The compiler's path and version, and this machine's processor (for -march=native)."""
    try:
        done = subprocess.run([compiler, "--version"], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError) as exc:
        raise CompileError(f"the C compiler {compiler} cannot be run: {exc}") from None
    cpu = ""
    if Path("/proc/cpuinfo").is_file():
        lines = Path("/proc/cpuinfo").read_text(errors="replace").splitlines()
        cpu = "\n".join(sorted({line for line in lines if line.startswith(("model name", "flags", "Features", "CPU part"))}))
    return f"{compiler}\n{done.stdout}\n{platform.machine()}\n{cpu}"


def build_library(sources: dict[str, str], sensitivities: bool = True) -> Path:
    """The shared library of the C ``sources`` (file name -> text), compiled once: cached by a
    key over the sources, the compiler and the flags, its bytes recorded in the user's trust store
    (:mod:`kinegen.integrity`), which :func:`_load` checks before it loads it. Each object file is
    cached too (:func:`_objects`): the solver's object is built once per machine and shared by
    every model. Builds are atomic (a private folder, then ``os.replace``): a concurrent or
    interrupted build leaves a whole library or none, and a cached library whose bytes kinegen did
    not write (tampered, truncated, planted) is built again, never loaded. ``sensitivities`` False:
    without the parts of a model's C that only its sensitivity kernels need
    (:func:`~kinegen.codegen.backends.c.config.sensitivity_parts`; its part 0 with ``-DKINEGEN_NO_SENSITIVITIES``),
    the library a solve loads first (:func:`case_library`)."""
    compiler = c_compiler()
    key = hashlib.sha256()
    for part in (_compiler_identity(compiler), " ".join((*COMMON_FLAGS, *SOLVER_FLAGS, *MODEL_FLAGS)),
                 *([] if sensitivities else [NO_SENSITIVITIES]), *(f"{n}\n{t}" for n, t in sorted(sources.items()))):  # fmt: skip
        key.update(part.encode())
    folder = cache_folder()
    library = folder / f"kinegen_{key.hexdigest()[:24]}.so"
    if _intact(library):
        return library
    objects = _objects(compiler, sources, sorted(n for n in sources if n.endswith(".c")), sensitivities)
    with _work_folder(folder) as work:
        built = work / library.name
        _run_all(compiler, [[compiler, "-shared", "-o", str(built), *map(str, objects), "-lm"]])
        _publish(built, library)
    return library


def _publish(built: Path, cached: Path) -> None:
    """Record a built file's bytes as kinegen's own, then move it into the cache."""
    remember(built.read_bytes())
    os.replace(built, cached)


def _intact(path: Path) -> bool:
    """Whether a cached file exists and its bytes are kinegen's own (in the trust store)."""
    try:
        return trusted(path.read_bytes())
    except OSError:
        return False


@contextmanager
def _work_folder(parent: Path) -> Iterator[Path]:
    """A private folder in ``parent`` for one build, removed afterwards whatever happens (no
    finalizer at interpreter exit: a build still compiling in a background thread then must not
    have its folder removed under it). Folders that an interrupted process left are swept after a day."""
    parent.mkdir(parents=True, exist_ok=True)
    for stale in parent.glob("tmp*"):
        with suppress(OSError):
            if time.time() - stale.stat().st_mtime > 86_400:
                shutil.rmtree(stale, ignore_errors=True)
    work = Path(tempfile.mkdtemp(dir=parent))
    try:
        yield work
    finally:
        shutil.rmtree(work, ignore_errors=True)


def build_solver_object() -> Path:
    """The C solver's object file, compiled once per machine and compiler into the cache
    (:func:`build_library` takes it from there for every model)."""
    return _objects(c_compiler(), with_solver({}), ["kinegen_solver.c"])[0]


def copy_solver_object(cache: Path) -> Path:
    """Put the current cache's C solver object (:func:`build_solver_object`: compiled there first if it
    is not) into the kinegen cache folder ``cache``, as a machine that built any model has it: a fresh
    cache (the benchmark's, a test's) that should not spend its first build on the solver. The trust
    store knows the copy's bytes. CompileError without a usable compiler."""
    kept = build_solver_object()
    (cache / "objects").mkdir(parents=True, exist_ok=True)
    shutil.copy2(kept, cache / "objects" / kept.name)
    return cache / "objects" / kept.name


def _objects(compiler: str, sources: dict[str, str], names: list[str], sensitivities: bool = True) -> list[Path]:
    """The object files of the C files ``names`` among ``sources``, from the cache
    (``objects/``, keyed by :func:`_object_key`); the missing ones compiled in parallel, a large
    model's C in its ``KINEGEN_PART`` parts (see backends.c.backend), and moved in atomically.
    Without ``sensitivities``, a model's parts that only its sensitivity kernels need are left out and
    its part 0 is compiled with ``-DKINEGEN_NO_SENSITIVITIES`` (the other parts' objects are shared)."""
    store, planned = _planned(compiler, sources, names, sensitivities)
    objects = [cached for _, _, _, cached in planned]
    missing = [p for p in planned if not _intact(p[3])]
    if not missing:
        return objects
    for _, _, _, cached in missing:  # this process's own compiler of it (start_solver_object) holds its lock: finished first
        started = _STARTED.get(cached)
        if started is not None:
            started.finish()
    with _compiling(store, [cached for _, _, _, cached in missing]):
        missing = [m for m in missing if not _intact(m[3])]  # compiled by another process while this one waited
        if missing:
            _compile(compiler, store, sources, missing)
    return objects


def _planned(compiler: str, sources: dict[str, str], names: list[str], sensitivities: bool = True) -> tuple[Path, list[tuple[str, int | None, list[str], Path]]]:
    """The cache's object folder, and the objects :func:`_objects` makes of ``names``: (file name, part
    or None, the compiler's flags, the cached object's path, keyed by :func:`_object_key`)."""
    identity = _compiler_identity(compiler)
    store = cache_folder() / "objects"
    store.mkdir(parents=True, exist_ok=True)
    planned = []
    for name in names:
        flags = SOLVER_FLAGS if name == "kinegen_solver.c" else MODEL_FLAGS
        left_out = set() if sensitivities or name == "kinegen_solver.c" else set(sensitivity_parts(sources[name]))
        for part in source_parts(sources[name]) or [None]:
            if part in left_out:
                continue
            without = [f"-D{NO_SENSITIVITIES}"] if left_out and part == 0 else []
            command = [*COMMON_FLAGS, *flags, *([] if part is None else [f"-DKINEGEN_PART={part}"]), *without]
            planned.append((name, part, command, store / f"{_object_key(identity, command, name, sources)}.o"))
    return store, planned


@contextmanager
def _compiling(store: Path, objects: list[Path]) -> Iterator[None]:
    """Held while this process compiles ``objects``: a process that needs any of the same ones
    waits, then finds them in the cache, instead of compiling them a second time beside it (test
    workers, Dask workers or two commands asking for one model's library at once). One advisory
    lock (``flock``) per object, taken in the objects' name order (so two processes never wait on
    each other), released when the block ends or the process does; without ``fcntl``, no lock."""
    try:
        import fcntl
    except ImportError:  # (not on this platform: concurrent builds stay correct, they may only repeat work)
        yield
        return
    locks = store / "locks"
    locks.mkdir(exist_ok=True)
    with ExitStack() as held:
        for name in sorted(o.name for o in objects):
            handle = held.enter_context(open(locks / name, "a"))
            fcntl.flock(handle, fcntl.LOCK_EX)  # (closing the file releases it)
        yield


def _compile(compiler: str, store: Path, sources: dict[str, str], missing: list[tuple[str, int | None, list[str], Path]]) -> None:
    """Compile the ``missing`` objects (name, part, flags, cached path) in parallel into the cache."""
    with _work_folder(store) as work:
        made, commands = _commands(compiler, work, sources, missing)
        _run_all(compiler, commands)
        for o, (_, _, _, cached) in zip(made, missing):
            _publish(o, cached)


def _commands(compiler: str, work: Path, sources: dict[str, str], missing: list[tuple[str, int | None, list[str], Path]]) -> tuple[list[Path], list[list[str]]]:
    """``sources`` written into ``work``, and the objects ``missing`` (as :func:`_planned` gives them)
    will be compiled to there, with the compiler commands that make them."""
    for name, text in sources.items():
        (work / name).write_text(text)
    made = [work / f"{Path(name).stem}{'' if part is None else f'_part{part}'}.o" for name, part, _, _ in missing]
    return made, [[compiler, *command, "-c", "-o", str(o), str(work / name)] for o, (name, _, command, _) in zip(made, missing)]


def _object_key(identity: str, command: list[str], name: str, sources: dict[str, str]) -> str:
    """Cache key of one object: compiler, flags, the source and the headers it includes (transitively)."""
    key = hashlib.sha256(f"{identity}\n{' '.join(command)}".encode())
    pending, seen = [name], set()
    while pending:
        file = pending.pop()
        if file in seen or file not in sources:
            continue
        seen.add(file)
        key.update(f"\n{file}\n{sources[file]}".encode())
        pending += _INCLUDE.findall(sources[file])
    return key.hexdigest()[:32]


_INCLUDE = re.compile(r'^#include "([^"]+)"', re.MULTILINE)


#: the macro that leaves a model's sensitivity kernels out of its C (see backends.c.backend)
NO_SENSITIVITIES = "KINEGEN_NO_SENSITIVITIES"


def deferred_sensitivities(sources: dict[str, str]) -> bool:
    """Whether a model's C has parts only its sensitivity kernels need: its first library is then
    compiled without them, and the complete one when they are first asked for."""
    return any(has_sensitivity_parts(text) for name, text in sources.items() if name.endswith(".c") and name not in RUNTIME)


def case_library(sources: dict[str, str]) -> Path:
    """The library a solve of the model loads (:func:`build_library`): without the parts only the
    sensitivity kernels need when the model's C has them apart (:func:`deferred_sensitivities`), the
    sensitivities' kernels then compiled when first asked for (:meth:`NativeCase.sensitivities`)."""
    return build_library(sources, sensitivities=not deferred_sensitivities(sources))


def with_solver(model_files: dict[str, str]) -> dict[str, str]:
    """A model's C files (``<stem>.c``, ``<stem>.h``) and kinegen's C solver: what a library is built from."""
    return {**model_files, **{name: (SOLVER_SOURCES / name).read_text() for name in RUNTIME}}


def compile_in_background(model_files: dict[str, str], first: Callable[[], None] | None = None) -> threading.Thread:
    """Start building the library of a model's C (cached, see :func:`build_library`) in a thread,
    so that it compiles while other work goes on; ``first`` is called in the thread before (e.g. what
    :func:`start_solver_object` returned). A failure is left for the first use to report."""

    def build() -> None:
        try:
            if first is not None:
                first()
            case_library(with_solver(model_files))
        except (KinegenError, OSError):  # left for the first use to report
            pass

    thread = threading.Thread(target=build, name="kinegen-compile", daemon=True)
    thread.start()
    return thread


def start_solver_object() -> Callable[[], None]:
    """Start compiling kinegen's C solver object (:func:`build_solver_object`, cached) if the cache
    lacks it, as a compiler process and no thread: a build starts it first, so that it compiles while
    the model is loaded and derived, and this process may still fork for that (a thread would forbid
    it: :func:`kinegen.codegen.forked.may_fork`). Returns what finishes it -- waits for the compiler,
    moves the object into the cache -- called before the model's library is built (a process that
    needs the object meanwhile waits on its lock); a compile never finished is stopped when this
    process exits. A failure is left for the first use to report."""
    try:
        compiler = c_compiler()
        sources = with_solver({})
        store, (planned,) = _planned(compiler, sources, ["kinegen_solver.c"])  # (the object build_solver_object makes)
        if _intact(planned[3]):
            return lambda: None
        return _Started(compiler, store, sources, planned).finish
    except (KinegenError, OSError):
        return lambda: None


class _Started:
    """One object's compiler process, started by :func:`start_solver_object` with the object's lock held
    (:func:`_compiling`) and its sources in a private folder; :meth:`finish` waits for it, moves the object
    into the cache (a refused optional flag compiled again without it, as :func:`_run_all` does) and lets
    the lock and the folder go. Stopped at this process's exit if never finished."""

    def __init__(self, compiler: str, store: Path, sources: dict[str, str], planned: tuple[str, int | None, list[str], Path]) -> None:
        self._lock = threading.Lock()
        self._held = ExitStack()
        self._cached = cached = planned[3]
        self._held.enter_context(_compiling(store, [cached]))
        self._process: subprocess.Popen | None = None
        if _intact(cached):  # (compiled by another process while this one waited for the lock)
            self._finalizer = weakref.finalize(self, self._held.close)
            return
        try:
            work = self._held.enter_context(_work_folder(store))
            (self._made,), (self._command,) = _commands(compiler, work, sources, [planned])
            self._process = subprocess.Popen(self._command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        except BaseException:  # (no compiler process: the folder and the lock let go now)
            self._held.close()
            raise
        self._finalizer = weakref.finalize(self, _stopped, self._process, self._held)
        _STARTED[cached] = self  # (this process's own use of the object finishes it first: _objects)

    def finish(self) -> None:
        """Wait for the compiler and move the object in (once; a failure is left for the first use)."""
        with self._lock:
            if self._finalizer.detach() is not None:
                if _STARTED.get(self._cached) is self:
                    del _STARTED[self._cached]
                self._finished()

    def _finished(self) -> None:
        try:
            if self._process is not None:
                self._process.communicate()
                if self._process.returncode != 0:
                    _run_all(self._command[0], [self._command])  # (again, for an optional flag's refusal or the error)
                _publish(self._made, self._cached)
        except (KinegenError, OSError):
            pass
        finally:
            self._held.close()


#: the objects this process has a compiler process of :func:`start_solver_object` for, not finished yet
_STARTED: weakref.WeakValueDictionary[Path, _Started] = weakref.WeakValueDictionary()


def _stopped(process: subprocess.Popen, held: ExitStack) -> None:
    """A compile never finished, at this process's exit: the compiler stopped, its folder and lock let go."""
    with suppress(OSError):
        process.kill()
        process.wait()
        process.stderr.close()  # (its pipe, which no one reads now: no ResourceWarning at exit)
    held.close()


def _run_all(compiler: str, commands: list[list[str]]) -> None:
    """Run the compiler commands in parallel; a refused command is tried again without its
    :data:`OPTIONAL_FLAGS`, one at a time (-march=native first, then -ffp-contract=off); the error
    reported is the last try's."""
    try:
        running = [subprocess.Popen(c, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for c in commands]
        results = [(c, *p.communicate(), p.returncode) for c, p in zip(commands, running)]
        for command, _, error, code in results:
            for flag in OPTIONAL_FLAGS:
                if code != 0 and flag in command:
                    command = [a for a in command if a != flag]
                    retry = subprocess.run(command, capture_output=True, text=True)
                    error, code = retry.stderr, retry.returncode
            if code != 0:
                last = error.strip().splitlines()[-1] if error.strip() else f"exit {code}"
                raise CompileError(f"the C compiler failed: {last}")
    except OSError as exc:
        raise CompileError(f"the C compiler {compiler} cannot be run: {exc.strerror or exc}") from None


def _model_sources(module: ModuleType) -> dict[str, str] | None:
    """The module's C and the solver's, if the C files the module names (``C_FILES``: file ->
    SHA-256 of its bytes, recorded when both were generated) lie beside it with exactly those
    bytes; None otherwise (none named, missing, or another build's C, which kinegen wrote too). A C
    file whose bytes kinegen never wrote (edited, planted) is a :class:`ChangedFileError`."""
    from kinegen.errors import ChangedFileError

    path = Path(getattr(module, "__file__", "") or "")
    named = getattr(module, "C_FILES", None) or {}
    files = {name: path.with_name(name) for name in named}
    if path.suffix != ".py" or not files or not all(f.is_file() for f in files.values()):
        return None
    texts = {}
    for name, file in files.items():
        data = file.read_bytes()
        if hashlib.sha256(data).hexdigest() != named[name]:
            if trusted(data):
                return None  # another build's C (another model version or parametrization): not this module's kernels
            raise ChangedFileError(
                f"{file} was changed since kinegen wrote it: its bytes are neither the C its module names nor any kinegen wrote; "
                f"nothing of it was compiled. Rebuild it with `kinegen build <model>.yaml --param {module.PARAMETRIZATION}` (which replaces it)"
            )
        texts[name] = data.decode("utf-8")
    return with_solver(texts)


@cache
def _library(path: str) -> ctypes.CDLL:
    """The cached library at ``path``, loaded after its bytes were checked against their record."""
    library = _load(Path(path))
    bind_functions(library)  # every signature from the library's own table (kinegen_functions)
    return library


@cache
def _abi(path: str) -> Abi:
    """The structs and status codes of the cached library at ``path``, from its own tables."""
    return Abi(_library(path))


def _load(path: Path) -> ctypes.CDLL:
    """dlopen of a cached library whose bytes kinegen wrote (in the trust store; else CompileError).
    (It guards against damaged, stale and planted files, not against a process of the same user
    that swaps the file between the check and the load.)"""
    if not trusted(path.read_bytes()):
        raise CompileError(f"{path}: the cached library is not one kinegen compiled (tampered, truncated or planted); not loaded")
    return ctypes.CDLL(str(path))


#: per loaded module object and compiler: its C sources (:func:`_model_sources`) and the library a solve
#: loads (:func:`case_library`), found once -- the C files read and hashed, the library's key computed and
#: its bytes checked -- not again for every system a study or an exploration makes of each design
_RESOLVED: weakref.WeakKeyDictionary[ModuleType, dict[str, tuple[dict[str, str], Path]]] = weakref.WeakKeyDictionary()
#: the same for the complete library (with the sensitivity kernels), once built
_COMPLETE: weakref.WeakKeyDictionary[ModuleType, dict[str, Path]] = weakref.WeakKeyDictionary()


def module_library(module: ModuleType) -> tuple[dict[str, str], Path] | None:
    """The C sources of a generated module and the library a solve of it loads, compiled if needed
    (:func:`case_library`); None where no fresh C lies beside it (:func:`_model_sources`). Found once
    per module object and compiler: the library then serves the kernels that module was generated
    with, whatever is later written beside it (a rebuild is a new module). CompileError without a
    usable compiler."""

    def find() -> tuple[dict[str, str], Path] | None:
        sources = _model_sources(module)
        return None if sources is None else (sources, case_library(sources))

    return _once_per_compiler(_RESOLVED, module, find)


def _complete_library(module: ModuleType, sources: dict[str, str]) -> Path:
    """The library of a module's C with its sensitivity kernels (:func:`build_library`), found once per
    module object and compiler."""
    return _once_per_compiler(_COMPLETE, module, lambda: build_library(sources))


def _once_per_compiler(table: weakref.WeakKeyDictionary, module: ModuleType, find: Callable[[], Any]) -> Any:
    """``find()`` for ``module`` and the compiler in use (:func:`c_compiler`), kept in ``table``; None is not kept."""
    found = table.setdefault(module, {})
    compiler = c_compiler()
    if compiler not in found:
        made = find()
        if made is None:
            return None
        found[compiler] = made
    return found[compiler]


def native_case(module: ModuleType, case: str, quiet: bool = False, design: np.ndarray | None = None) -> NativeCase | None:
    """The compiled kernels and C solver of ``case`` of a generated module, or None (no C beside
    the module, or no usable compiler: said once per reason as a warning unless ``quiet``);
    ``design``: the values of a model's design parameters (default: nominal)."""
    try:
        found = module_library(module)
        if found is None:
            return None
        sources, library = found
    except CompileError as exc:
        reason = str(exc)
        if not quiet and reason not in _WARNED:
            _WARNED.add(reason)
            warnings.warn(f"no compiled code ({reason}); kinegen solves with the Python functions", RuntimeWarning, stacklevel=2)
        return None
    stem = Path(module.__file__).stem
    abi = _abi(str(library))
    abi.check_frames(tuple(tuple(f) for f in module.FRAME_FIELDS))
    native = NativeCase(abi, f"{stem}_{case}", design)
    if deferred_sensitivities(sources):
        native.complete = lambda: NativeCase(_abi(str(_complete_library(module, sources))), f"{stem}_{case}", native.design)
    return native


class NativeCase:
    """One case's compiled kernels and C solver (see the module docstring)."""

    def __init__(self, abi: Abi, symbol: str, design: np.ndarray | None = None) -> None:
        self.abi = abi
        self.library = library = abi.library
        self.model = m = abi.struct("kinegen_model").in_dll(library, symbol)
        self.address = ctypes.addressof(m)
        self.n_q, self.n_v, self.n_inputs, self.n_jac = m.n_q, m.n_v, m.n_inputs, m.n_jac
        #: the design parameters the kernels and solvers take (None without them)
        self.design = None
        self.sensitivity_doubles = 0  #: work of kinegen_sensitivities (0: the model has no sensitivity kernels)
        #: the same case in the complete library, when this one was compiled without the sensitivity kernels
        #: (called when they are first asked for: :meth:`sensitivities`)
        self.complete: Callable[[], NativeCase] | None = None
        self._complete: NativeCase | None = None
        if m.design:  # a model with design parameters: its kernels take them last
            owner = abi.struct("kinegen_design").from_address(m.design)
            self.sensitivity_doubles = owner.sensitivity_doubles
            nominal = np.ctypeslib.as_array(owner.nominal, (owner.n_design,))
            self.design = np.array(nominal if design is None else design, dtype=float)
        #: every kernel of the case and of the model's layout (frames, ...), as their tables in the library declare them
        layout = abi.struct("kinegen_layout").from_address(m.layout)
        self.kernels = {**abi.kernels(layout.n_kernels, layout.kernels), **abi.kernels(m.n_kernels, m.kernels)}
        # buffers for one configuration, and the kernels bound to them once
        self._arrays = {"q": np.zeros(m.n_q), "v": np.zeros(m.n_v), "a": np.zeros(m.n_v), "t": np.zeros(1), "span": np.zeros(2),
                        **{s: np.zeros(max(1, m.n_inputs)) for s in ("u", "ud", "udd")}, **{s: np.zeros(m.n_v) for s in "wyz"}}  # fmt: skip
        if self.design is not None:
            self._arrays["p"] = self.design
        sizes: dict[str, int] = {}  # an output's buffer: the largest of that name
        for kernel in self.kernels.values():
            for output, size in zip(kernel.outputs, kernel.sizes):
                sizes[output] = max(size, sizes.get(output, 0))
        self._out = {output: np.zeros(size) for output, size in sizes.items()}
        self._pointers: dict[str, int] = {}  # kernel name -> its kinegen_kernel in the library
        self._calls = {
            name: kernel.bind(self._arrays, self._out)
            for name, kernel in self.kernels.items() if set(kernel.slots) <= set(self._arrays)
        }  # fmt: skip

    def run(self, kernel: str, **arguments: np.ndarray) -> tuple[np.ndarray, ...]:
        """The outputs (copies) of any kernel the library declares, at these arguments by slot
        name (one configuration; slots not given keep their last values, ``p`` the case's design)."""
        for slot, value in arguments.items():
            self._arrays[slot][: np.size(value)] = value
        self._calls[kernel]()
        k = self.kernels[kernel]
        return tuple(self._out[o][:size].copy() for o, size in zip(k.outputs, k.sizes))

    def each(self, kernel: str, **arguments: np.ndarray) -> tuple[np.ndarray, ...]:
        """The outputs of a kernel the library declares at many configurations, in one C call
        (``kinegen_kernel_each``), as the Python module's functions take and give them: each argument
        by slot name, (n,) for every configuration or (n, K) one column each (``t``: a value or (K,)
        values; ``p``: the case's design when not given); each output (size, K), or (size,) when no
        argument has columns. An argument of another length than its slot's is a ValueError."""
        declared = self.kernels[kernel]
        arguments.setdefault("p", self.design)
        sizes = self._slot_sizes
        count, rows, strides = None, [], []
        for slot in declared.slots:
            x = np.atleast_1d(np.asarray(arguments[slot], dtype=float))
            if slot == "t":
                x = x.reshape(1, -1) if x.size > 1 else x.reshape(1)
            if x.shape[0] != sizes[slot] or x.ndim > 2:
                raise ValueError(f"kernel {kernel}: argument {slot} of shape {x.shape}, its slot holds {sizes[slot]} values")
            if x.ndim == 2:
                if count is not None and x.shape[1] != count:
                    raise ValueError(f"kernel {kernel}: argument {slot} has {x.shape[1]} columns, another {count}")
                count = x.shape[1]
                x = x.T
            x = np.ascontiguousarray(x)  # (a column of a batch is a strided view)
            rows.append(x if x.size else np.zeros(1))
            strides.append(x.shape[1] if x.ndim == 2 else 0)
        outputs = tuple(np.empty((count or 1, size)) for size in declared.sizes)
        pointers = (ctypes.c_void_p * max(1, len(rows)))(*(x.ctypes.data for x in rows))
        steps = (ctypes.c_int * max(1, len(rows)))(*strides)
        targets = (ctypes.c_void_p * max(1, len(outputs)))(*(y.ctypes.data for y in outputs))
        status = self.library.kinegen_kernel_each(self._kernel_pointer(kernel), count or 1, pointers, steps, targets)
        if status != self.abi.status["ok"]:
            raise ValueError(f"kernel {kernel}: {self.abi.status_name(status)} from kinegen_kernel_each")
        return tuple(y[0] if count is None else y.T for y in outputs)

    @cached_property
    def _slot_sizes(self) -> dict[str, int]:
        """How many values each argument slot holds."""
        n_v, n_inputs = self.n_v, self.n_inputs
        return {"q": self.n_q, "v": n_v, "a": n_v, "w": n_v, "y": n_v, "z": n_v, "u": n_inputs, "ud": n_inputs, "udd": n_inputs,
                "t": 1, "span": 2, "p": 0 if self.design is None else len(self.design),
                "f": 0 if self.statics is None else self.statics.n_elements}  # fmt: skip

    def _kernel_pointer(self, kernel: str) -> int:
        found = self._pointers.get(kernel)
        if found is None:
            found = self._pointers[kernel] = self.library.kinegen_find_kernel(self.address, kernel.encode())
        return found

    def evaluate(self, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Phi and the Phi_q values at one configuration."""
        phi, jac = self.run("phi_jac", q=q, u=u)
        return phi, jac

    def nu(self, q: np.ndarray, u: np.ndarray, ud: np.ndarray) -> np.ndarray:
        return self.run("nu", q=q, u=u, ud=ud)[0]

    def gamma(self, q: np.ndarray, v: np.ndarray, u: np.ndarray, ud: np.ndarray, udd: np.ndarray) -> np.ndarray:
        return self.run("gamma", q=q, v=v, u=u, ud=ud, udd=udd)[0]

    def sensitivities(self, q, v, a, u, ud, udd) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """dq/dp, dv/dp, da/dp (each (K, n_v, n_design)) at the K columns of q (n_q, K), v, a
        (n_v, K) and the inputs u, ud, udd (n_inputs, K), by ``kinegen_sensitivities`` (one LU of
        Phi_q per time point); NaN where Phi_q is singular. A library compiled without the
        sensitivity kernels has the complete one compiled (cached) and loaded on the first call;
        None when that cannot be compiled (said once as a warning: the caller computes them in Python)."""
        if "dvel" not in self.kernels:
            complete = self.sensitivity_case()
            return None if complete is None else complete.sensitivities(q, v, a, u, ud, udd)
        rows = [np.ascontiguousarray(np.asarray(x, dtype=float).T) for x in (q, v, a, u, ud, udd)]
        count = rows[0].shape[0]
        out = tuple(np.empty((count, self.n_v, len(self.design))) for _ in range(3))
        work = np.empty(self.sensitivity_doubles)
        solver = self.solver(Options.newton_only(1e-10, 1e-14))
        self.library.kinegen_sensitivities(solver.pointer, count, *(x.ctypes.data for x in (*rows, *out, work)))
        return out

    def sensitivity_case(self) -> NativeCase | None:
        """This case with its sensitivity kernels (``dvel``, ...) compiled: itself, or the same case in
        the complete library (compiled, cached and loaded on the first call); None when the model has
        none or they cannot be compiled (said once as a warning: the caller uses the Python functions)."""
        if "dvel" in self.kernels:
            return self
        if self.complete is None:
            return None
        if self._complete is None:
            try:
                self._complete = self.complete()
            except CompileError as exc:
                if str(exc) not in _WARNED:
                    _WARNED.add(str(exc))
                    warnings.warn(f"no compiled sensitivity kernels ({exc}); kinegen computes them with the Python functions",
                                  RuntimeWarning, stacklevel=3)  # fmt: skip
                self.complete = None
                return None
        return self._complete

    def function(self, kernel: str, slots: Sequence[str] | None = None, sensitivity: bool = False) -> Callable[..., tuple]:
        """A kernel as the Python module's functions are called: positional arguments in the order
        of ``slots`` (default: the kernel's own, p left out: the case's design), each a value or a
        batch of columns (:meth:`each`), returning its outputs as a tuple. ``sensitivity``: a kernel
        of the complete library (:meth:`sensitivity_case`), found on the first call."""
        names = tuple(s for s in self.kernels[kernel].slots if s != "p") if slots is None else tuple(slots)

        def call(*arguments: np.ndarray) -> tuple[np.ndarray, ...]:
            case = self.sensitivity_case() if sensitivity else self
            if case is None:
                raise CompileError(f"no compiled kernel {kernel}")
            return case.each(kernel, **dict(zip(names, arguments)))

        return call

    @property
    def statics(self) -> ctypes.Structure | None:
        """The model's ``kinegen_statics`` (its force solve), or None (no loads, no actuation elements)."""
        layout = self.abi.struct("kinegen_layout").from_address(self.model.layout)
        return self.abi.struct("kinegen_statics").from_address(layout.statics) if layout.statics else None

    def forces(self, times: np.ndarray, q: np.ndarray, u: np.ndarray, weights: np.ndarray,
               motion: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """The multipliers (K, n_v) and element forces (K, n_elements, or the case's n_inputs without
        elements) holding the loads weighted by ``weights`` (one per load of the model, in its order) at
        the K configurations q (K, n_q) with inputs u (K, n_inputs) at ``times`` (K,), by
        ``kinegen_forces``; with ``motion`` = (v, a), each (K, n_v), also the bodies' weight and inertia
        (inverse dynamics). NaN rows where the matrix is singular."""
        statics = self.statics
        if statics is None:
            raise ValueError("the model has no loads and no actuation elements")
        count = len(times)
        times, q, u = (np.ascontiguousarray(np.asarray(x, dtype=float).reshape(count, -1)) for x in (times, q, u))
        v, a = (None, None) if motion is None else (np.ascontiguousarray(np.asarray(x, dtype=float).reshape(count, -1)) for x in motion)
        weights = np.ascontiguousarray(weights, dtype=float)
        if len(weights) != statics.n_loads:
            raise ValueError(f"{len(weights)} load weights for {statics.n_loads} loads")
        if motion is not None and "inertia" not in self.kernels:
            raise ValueError("the model has no masses: no inertia to add")
        multipliers = np.empty((count, self.n_v))
        force = np.empty((count, statics.n_elements or self.n_inputs))
        work, iwork = np.empty(statics.work_doubles), np.empty(max(1, statics.work_ints), dtype=np.intc)
        solver = self.solver(Options.newton_only(1e-10, 1e-10))

        def pointer(x: np.ndarray | None) -> int | None:
            return None if x is None else x.ctypes.data

        self.library.kinegen_forces(solver.pointer, count, *(pointer(x) for x in (times, q, v, a, u, weights)), 0.0 if motion is None else 1.0,
                                    *(x.ctypes.data for x in (multipliers, force, work, iwork)))  # fmt: skip
        return multipliers, force

    def solver(self, options: Options) -> NativeSolver:
        """A C solver instance of this case (its own workspace)."""
        return NativeSolver(self, options)

    def solve_batch(self, u: np.ndarray, q0: np.ndarray, options: Options) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Newton on every column of ``q0`` (n_q, K) for inputs ``u`` (n_inputs, K): (q, converged,
        iterations, residuals)."""
        q = np.ascontiguousarray(np.asarray(q0, dtype=float).T)  # configuration by configuration
        u = np.ascontiguousarray(np.asarray(u, dtype=float).reshape(self.n_inputs, -1).T)
        k = q.shape[0]
        converged, iterations, residuals = np.zeros(k, dtype=np.intc), np.zeros(k, dtype=np.intc), np.zeros(k)

        solver = self.solver(options)
        self.library.kinegen_solve_batch(
            solver.pointer, k, u.ctypes.data, q.ctypes.data, converged.ctypes.data, iterations.ctypes.data, residuals.ctypes.data
        )
        return q.T.copy(), converged.astype(bool), iterations.astype(int), residuals

    def input_effects(self, q: np.ndarray, u: np.ndarray) -> np.ndarray:
        """dq/du = Phi_q^-1 nu(q, u, e_j) at the solved configurations q (n_q, K) with inputs u
        (n_inputs, K), by ``kinegen_input_effects``: (K, n_v, n_inputs), NaN where Phi_q is singular."""
        q = np.ascontiguousarray(np.asarray(q, dtype=float).reshape(self.n_q, -1).T)
        count = q.shape[0]
        u = np.ascontiguousarray(np.broadcast_to(np.asarray(u, dtype=float).reshape(self.n_inputs, -1), (self.n_inputs, count)).T)
        out = np.empty((count, self.n_v, self.n_inputs))
        solver = self.solver(Options.newton_only(1e-10, 1e-10))
        self.library.kinegen_input_effects(solver.pointer, count, q.ctypes.data, u.ctypes.data, out.ctypes.data)
        return out


class Newton:
    """Full Newton on one configuration in C, with one solver kept for it (the Python solver's
    first try at a position; its fallbacks stay in Python)."""

    def __init__(self, case: NativeCase, options: Options) -> None:
        self.solver = case.solver(options)
        self._abi = case.abi  # status names from the library's own table
        self._q = np.zeros(case.n_q)
        self._u = np.zeros(case.n_inputs)
        self._out = (ctypes.c_int(0), ctypes.c_double(0.0), ctypes.c_double(0.0))
        self._args = (self.solver.pointer, self._q.ctypes.data, self._u.ctypes.data, *(ctypes.addressof(x) for x in self._out))

    def __call__(self, q0: np.ndarray, u: np.ndarray) -> tuple[str, np.ndarray, int, float]:
        """(status by its name in the library's kinegen_status_names: "ok", "not_converged",
        "singular", ...; q, iterations, max |Phi|)."""
        self._q[:], self._u[:] = q0, u
        code = self.solver.library.kinegen_newton(*self._args)
        iterations, residual, _ = (x.value for x in self._out)
        return self._abi.status_name(code), self._q.copy(), iterations, residual


class NativeSolver:
    """A ``kinegen_solver`` with its workspace, for one trajectory."""

    def __init__(self, case: NativeCase, options: Options) -> None:
        self.case = case
        self.library = case.library
        abi = case.abi
        self.state = abi.struct("kinegen_solver")()
        self.pointer = ctypes.addressof(self.state)
        self._doubles = np.zeros(case.model.work_doubles)
        self._ints = np.zeros(case.model.work_ints, dtype=np.intc)
        self._options = abi.struct("kinegen_options")()
        self.library.kinegen_default_options(ctypes.addressof(self._options))
        abi.assign(self._options, options)
        code = self.library.kinegen_init(self.pointer, case.address, ctypes.addressof(self._options), self._doubles.ctypes.data,
                                         self._ints.ctypes.data)  # fmt: skip
        if code != abi.status["ok"]:  # the C solver found a kernel it calls by role missing or declared otherwise
            role = self.state.role.decode() if self.state.role else "?"
            raise AbiError(f"{case.model.case_name.decode()}: {self.library.kinegen_status_text(code).decode()} (role {role!r})")
        if case.design is not None:  # the case's array, alive as long as the case
            self.library.kinegen_set_design(self.pointer, case.design.ctypes.data)

    def start(self, t: float, q0: np.ndarray, u: np.ndarray, ud: np.ndarray, udd: np.ndarray) -> str:
        """kinegen_start; its status by name (the library's kinegen_status_names: "ok", "singular", ...)."""
        arrays = [np.ascontiguousarray(x, dtype=float) for x in (q0, u, ud, udd)]
        code = self.library.kinegen_start(self.pointer, t, *(x.ctypes.data for x in arrays))
        return self.case.abi.status_name(code)

    def resume(self, t: float, q: np.ndarray, v: np.ndarray, a: np.ndarray, u: np.ndarray, ud: np.ndarray,
               previous: tuple[np.ndarray, float] | None = None) -> int:  # fmt: skip
        """kinegen_resume: (t, q, v, a) solved elsewhere; ``previous``: the acceleration at the start of the
        step that ended there and its length (the next step's third-order predictor term), None: none."""
        arrays = [np.ascontiguousarray(x, dtype=float) for x in (q, v, a, u, ud)]
        before = None if previous is None else np.ascontiguousarray(previous[0], dtype=float)
        h = 0.0 if previous is None else float(previous[1])
        return self.library.kinegen_resume(self.pointer, t, *(x.ctypes.data for x in arrays), None if before is None else before.ctypes.data, h)

    def state_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of the solver's q, v, a."""
        c = self.case
        return (np.ctypeslib.as_array(self.state.q, (c.n_q,)).copy(), np.ctypeslib.as_array(self.state.v, (c.n_v,)).copy(),
                np.ctypeslib.as_array(self.state.a, (c.n_v,)).copy())  # fmt: skip

    def trajectory(self, times: np.ndarray, inputs: tuple[np.ndarray, ...], out: tuple[np.ndarray, ...]) -> tuple[int, int]:
        """Steps at ``times`` (after a start or resume), inputs (u, ud, udd) each (steps, n_inputs)
        C-contiguous, into ``out`` = (q, v, a, iterations (C int), residuals, conditions), rows per
        step. Returns (steps solved, status of the first one not solved)."""
        status = ctypes.c_int(0)
        done = self.library.kinegen_trajectory(
            self.pointer, len(times), times.ctypes.data, *(x.ctypes.data for x in inputs), *(o.ctypes.data for o in out),
            ctypes.addressof(status),
        )
        return done, status.value
