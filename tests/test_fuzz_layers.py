"""`make fuzz`, the layers of issue 25: what an attacker or a careless user does to a file name, a
generated file, the inputs of a solve and the command line.

* **names**: hostile file names and descriptions (quotes, triple quotes, backslashes, newlines,
  ``*/``, ``#define``, trigraphs, non-ASCII) through `kinegen build`, the standalone C target
  (compiled with the machine's ``cc``), `kinegen solve` and `kinegen view`: the module parses to
  the harmless name's AST, the C header comment ends where the harmless one does, nothing runs;
  hostile entity names (bodies, points, cases) end in one model-error line;
* **tampered**: a generated module, its C and a cached library with bytes flipped, cut, inserted
  (with a payload) or a seal over the damaged text: refused before anything runs (exit 5), the library rebuilt
  and never loaded; a module of another model version is stale;
* **signals**: random input signals (random amplitudes, frequencies up to the grid's Nyquist rate,
  phases) on the excavator: every returned row equals a 1000x finer solve's to 1e-9 m, or the
  solve refuses;
* **functions** (issue 38): the excavator's own time functions with all four inputs fast (the
  oscillation case, 270-330 rad/s) on random grids of 0.3 to 7 rad of phase a step -- below and
  above the grid's Nyquist rate (pi) -- from random start times, compiled and in Python: every
  returned row equals the 2/42000 s solve's to 1e-9 m, or the solve refuses;
* **sections** (issue 38): the excavator's force, lift, study, load, motor and machine sections with
  a random entry replaced by a list, a mapping, nothing, a number, a ground point or another name:
  the model loads, or the loader refuses it with a ModelError naming file and entry -- no other
  exception (a list where a name belonged was a TypeError traceback);
* **cli**: random argument lists from the commands' own options and hostile values (non-numbers,
  NaN, huge numbers, broken JSON and expressions, devices, directories, unknown suffixes): each
  ends with an exit code of the table (kinegen.errors.ExitCode), no traceback, at most a few lines of error.

The quick subset runs with the test suite; ``make fuzz`` runs KINEGEN_FUZZ_EXAMPLES / 200 name,
/ 20 tamper, / 500 signal, / 500 function, / 20 section and / 10 command-line examples and appends the counts to its report.
"""

from __future__ import annotations

import atexit
import copy
import hashlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import threading
from collections import Counter
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from kinegen.cli import main
from kinegen.codegen import build
from kinegen.errors import ExitCode, GeneratedModuleError
from kinegen.runtime import from_module, load_module
from kinegen.runtime import native as native_module
from tests.conftest import GENERATED, MODELS
from tests.test_trust import _normalized

EXAMPLES = int(os.environ.get("KINEGEN_FUZZ_EXAMPLES", "150"))
COUNTS = {"names": max(3, EXAMPLES // 200), "tampered": max(12, EXAMPLES // 20), "signals": max(2, EXAMPLES // 500),
          "functions": max(2, EXAMPLES // 500), "sections": max(20, EXAMPLES // 20), "cli": max(25, EXAMPLES // 10)}  # fmt: skip
SEEN: Counter = Counter()  # layer -> examples run
OUTCOMES: Counter = Counter()  # (layer, outcome) -> count
CC = shutil.which("cc") or shutil.which("gcc")
WORK = Path(tempfile.mkdtemp(prefix="kinegen-fuzz-layers-"))
atexit.register(shutil.rmtree, WORK, ignore_errors=True)
MARKER = "KINEGEN_RAN"  # every payload tries to create a file of this name
SLIDER_CRANK = (MODELS / "slider_crank.yaml").read_text()
EXIT_CODES = {code for code in ExitCode if code not in (ExitCode.ERROR, ExitCode.BROKEN_PIPE)}
FUZZ = settings(deadline=None, database=None, suppress_health_check=list(HealthCheck))
#: examples that build, compile or solve for seconds: found, not shrunk (the failing example is printed as found)
COSTLY = settings(FUZZ, phases=[Phase.explicit, Phase.reuse, Phase.generate])


def _ran(folder: Path) -> bool:
    return any(p.name.startswith(MARKER) for p in folder.rglob("*")) or Path(MARKER).exists()


PAYLOADS = [
    f'"""; open("{MARKER}", "w"); """', f"'''; open('{MARKER}', 'w'); '''", "*/ int evil = 1; /*", "\n#define phi_jac evil\n",
    "??/ ??= ??'", "\\", "\\n\\x00", "\r\n", "\u00e9\u2603\U0001f40d", "${x}", "{{ x }}", "</script><script>alert(1)</script>",
]  # fmt: skip
hostile_text = st.lists(st.one_of(st.sampled_from(PAYLOADS), st.text(min_size=1, max_size=12)), min_size=1, max_size=4).map("".join)


def _file_name(text: str) -> str:
    name = "".join(c for c in text if c not in "/\x00" and not 0xD800 <= ord(c) <= 0xDFFF)[:60] or "x"
    return name if name not in (".", "..") else f"{name}x"


# ---- hostile names -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def harmless(tmp_path_factory):
    folder = tmp_path_factory.mktemp("harmless")
    model = folder / "plain.yaml"
    model.write_text(SLIDER_CRANK)
    module = build(model, "quaternion", folder)
    return _Reference(_normalized(module.read_text()), module.with_suffix(".c").read_text())


class _Reference(tuple):
    """The harmless build's normalized AST and C text (shown short in Hypothesis' reports)."""

    def __new__(cls, ast_dump: str, c_text: str):
        return super().__new__(cls, (ast_dump, c_text))

    def __repr__(self) -> str:
        return "<the harmless name's module>"


@settings(COSTLY, max_examples=COUNTS["names"])
@given(name=hostile_text, description=hostile_text)
def test_hostile_names_build_solve_compile_and_show_as_text(harmless, name, description):
    expected, c_reference = harmless
    SEEN["names"] += 1
    folder = Path(tempfile.mkdtemp(dir=WORK))
    model = folder / f"{_file_name(name)}.yaml"
    text = SLIDER_CRANK.replace("description: Centred", f"description: {json.dumps(description, ensure_ascii=False)} # Centred", 1)
    model.write_text(text)
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        runner = CliRunner()
        built = runner.invoke(main, ["build", str(model), "--generated-dir", str(folder / "generated")])
        if built.exit_code == 2 and "invalid YAML" in built.output:  # a character YAML does not allow in the description
            assert len(built.output.strip().splitlines()) == 1 and not _ran(folder)
            OUTCOMES[("names", "description refused by YAML (exit 2)")] += 1
            return
        assert built.exit_code == 0, built.output
        module = folder / "generated" / "slider_crank_quaternion.py"
        assert _normalized(module.read_text()) == expected
        c_text = module.with_suffix(".c").read_text()
        assert c_text.split("*/", 2)[1].count("\n") == c_reference.split("*/", 2)[1].count("\n")
        assert "??" not in c_text and not any(line.startswith("#define phi_jac") for line in c_text.splitlines())
        solved = runner.invoke(main, ["solve", str(model), "--steps", "11", "--generated-dir", str(folder / "generated"),
                                      "--out", str(folder / "out.csv")])  # fmt: skip
        assert solved.exit_code == 0, solved.output
        page = folder / "page.html"
        shown = runner.invoke(main, ["view", str(model), "--out", str(page), "--generated-dir", str(folder / "generated")])
        assert shown.exit_code == 0, shown.output
        assert "<script>alert(1)" not in page.read_text()  # the page holds no user text as markup
        if CC is not None:  # the standalone directory compiles (its header comment holds the file name)
            c_folder = folder / "c"
            target = runner.invoke(main, ["build", str(model), "--target", "c", "--out-dir", str(c_folder)])
            assert target.exit_code == 0, target.output
            stem = "slider_crank_quaternion"
            compiled = subprocess.run([CC, "-std=c99", "-fsyntax-only", "-Wall", "-Werror", f"-I{c_folder}", str(c_folder / f"{stem}.c")],
                                      capture_output=True, text=True)  # fmt: skip
            assert compiled.returncode == 0, compiled.stderr
        assert not _ran(folder)
        OUTCOMES[("names", "built, solved, shown")] += 1
    finally:
        os.chdir(cwd)
        shutil.rmtree(folder, ignore_errors=True)


@settings(FUZZ, max_examples=COUNTS["names"] * 4)
@given(name=hostile_text, where=st.sampled_from(["body", "point", "case"]))
def test_hostile_entity_names_are_one_model_error_line(tmp_path_factory, name, where):
    SEEN["names"] += 1
    folder = tmp_path_factory.mktemp("entity")
    quoted = json.dumps(name)
    text = {"body": SLIDER_CRANK.replace("  crank:\n", f"  {quoted}:\n", 1),
            "point": SLIDER_CRANK.replace("points: {A: [0, 0, 0], B: [r, 0, 0]}", f"points: {{A: [0, 0, 0], {quoted}: [r, 0, 0]}}", 1),
            "case": SLIDER_CRANK.replace("  run:\n", f"  {quoted}:\n", 1)}[where]  # fmt: skip
    model = folder / "entity.yaml"
    model.write_text(text)
    result = CliRunner().invoke(main, ["build", str(model), "--generated-dir", str(folder)])
    assert result.exit_code in (0, 2), result.output
    assert "Traceback" not in result.output and not _ran(folder)
    if result.exit_code == 2:
        assert len(result.output.strip().splitlines()) == 1 and result.output.startswith("error: ")
    OUTCOMES[("names", "entity accepted" if result.exit_code == 0 else "entity refused (exit 2)")] += 1


# ---- tampered and stale files ------------------------------------------------------------------
@pytest.fixture(scope="module")
def sealed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sealed")
    model = folder / "four_bar.yaml"
    shutil.copy(MODELS / "four_bar.yaml", model)
    path = build(model, "quaternion", folder / "generated")
    return model, path, path.read_bytes(), path.with_suffix(".c").read_bytes()


@st.composite
def damage(draw, data: bytes) -> bytes:
    """``data`` with one damage: a byte changed, a range cut, bytes inserted (a payload among
    them), a seal over the damaged text put first (a digest beside the text, which proves nothing),
    the version edited, or the file truncated."""
    kind = draw(st.sampled_from(["flip", "cut", "insert", "seal", "version", "truncate"]))
    at = draw(st.integers(0, len(data) - 1))
    if kind == "flip":
        return data[:at] + bytes([data[at] ^ draw(st.integers(1, 255))]) + data[at + 1 :]
    if kind == "cut":
        return data[:at] + data[at + draw(st.integers(1, 200)) :]
    if kind == "insert":
        extra = draw(st.sampled_from([f"\nopen({MARKER!r}, 'w')\n".encode(), b"\n", b" ", b"0", draw(st.binary(min_size=1, max_size=20))]))
        return data[:at] + extra + data[at:]
    if kind == "seal":
        payload = data + f"\nopen({MARKER!r}, 'w')\n".encode()
        return f"# kinegen: sha256 of the rest of this file: {hashlib.sha256(payload).hexdigest()}\n".encode() + payload
    if kind == "version":
        return data.replace(b"kinegen version: ", b"kinegen version: 9", 1)
    return data[:at]


@settings(FUZZ, max_examples=COUNTS["tampered"])
@given(data=st.data(), which=st.sampled_from(["module", "c"]))
def test_a_damaged_module_or_c_file_is_refused_before_it_runs(sealed, data, which):
    model, path, module_bytes, c_bytes = sealed
    SEEN["tampered"] += 1
    original = module_bytes if which == "module" else c_bytes
    damaged = data.draw(damage(original))
    if damaged == original:
        return
    target = path if which == "module" else path.with_suffix(".c")
    cwd = os.getcwd()
    os.chdir(path.parent)
    try:
        target.write_bytes(damaged)
        with pytest.raises(GeneratedModuleError) as caught:
            module = load_module(path, model)
            if CC is None:
                raise GeneratedModuleError("no C compiler: the C file is not read")
            from_module(module, compiled=True)
        assert caught.value.exit_code == 5
        assert not _ran(path.parent)
        OUTCOMES[("tampered", f"{which} refused (exit 5)")] += 1
    finally:
        target.write_bytes(original)
        os.chdir(cwd)


@pytest.mark.skipif(CC is None, reason="no C compiler")
@settings(COSTLY, max_examples=max(2, COUNTS["tampered"] // 6))
@given(data=st.data())
def test_a_damaged_cached_library_is_rebuilt_never_loaded(sealed, data):
    model, path, _, _ = sealed
    SEEN["tampered"] += 1
    with pytest.MonkeyPatch.context() as patch:  # a cache of its own: the library it damages is no other test's
        patch.setenv("KINEGEN_CACHE", str(path.parent.parent / "kinegen-cache"))
        sources = native_module._model_sources(load_module(path, model))
        library = native_module.build_library(sources)
        original = library.read_bytes()
        damaged = data.draw(damage(original))
        if damaged == original:
            return
        library.write_bytes(damaged)
        assert native_module.build_library(sources) == library and library.read_bytes() == original
    OUTCOMES[("tampered", "library rebuilt")] += 1


def test_a_module_of_another_model_version_is_stale(sealed):
    model, path, _, _ = sealed
    SEEN["tampered"] += 1
    edited = model.with_name("edited.yaml")
    edited.write_text(model.read_text().replace("four_bar", "four_bar", 1) + "\n# edited\n")
    with pytest.raises(GeneratedModuleError, match="stale"):
        load_module(path, edited)
    OUTCOMES[("tampered", "stale refused (exit 5)")] += 1


# ---- random input signals against a fine reference ---------------------------------------------
@pytest.mark.skipif(CC is None, reason="no C compiler")
@settings(COSTLY, max_examples=COUNTS["signals"])
@given(
    amplitudes=st.tuples(*[st.floats(0.0, 0.2)] * 3),
    cycles=st.tuples(*[st.floats(0.0, 20.0)] * 3),  # up to the Nyquist rate of the 41-point grid
    phases=st.tuples(*[st.floats(0.0, 6.3)] * 3),
)
def test_random_signals_come_back_right_or_not_at_all(amplitudes, cycles, phases):
    from tests.test_trust import TIGHT, _rows_equal_the_fine_solve_or_refuse, _signal

    SEEN["signals"] += 1
    system = from_module(load_module(GENERATED / "excavator_quaternion.py", MODELS / "excavator.yaml"), "digging")
    inputs = _signal(system, amplitudes, tuple(2 * np.pi * c for c in cycles), phases)
    accepted = _rows_equal_the_fine_solve_or_refuse(system, inputs, 41, TIGHT)
    OUTCOMES[("signals", {True: "equal to the fine solve", False: "refused (BranchError)", None: "no fine reference"}[accepted])] += 1


# ---- the case's own fast time functions on random grids -------------------------------------------
@pytest.fixture(scope="module")
def oscillation():
    """The excavator's oscillation case and its 2/42000 s solve (stored coordinates, body points)."""
    from kinegen.runtime import Solver
    from tests.test_trust import FINE_STEPS, TIGHT, _points

    module = load_module(GENERATED / "excavator_quaternion.py", MODELS / "excavator.yaml")
    system = from_module(module, "oscillation")
    fine = Solver(system, TIGHT).solve(np.linspace(0.0, 2.0, FINE_STEPS + 1))
    return module, fine.q, _points(system, fine.q)


@pytest.mark.skipif(CC is None, reason="no C compiler")
@settings(COSTLY, max_examples=COUNTS["functions"])
@given(stride=st.integers(20, 450), count=st.integers(3, 12), start=st.floats(0.0, 1.0), compiled=st.booleans())
def test_fast_time_functions_on_random_grids_come_back_right_or_not_at_all(oscillation, stride, count, start, compiled):
    from kinegen.errors import BranchError
    from kinegen.runtime import Solver, SolverOptions
    from tests.test_trust import FINE_STEPS, _points

    SEEN["functions"] += 1
    module, q, points = oscillation
    if not compiled:
        count = min(count, 4)  # the Python runtime halves the steps of these grids thousands of times: a few steps
    first = int(start * (FINE_STEPS - stride * (count - 1)))
    rows = np.arange(first, first + stride * count, stride)  # the grid's points among the fine solve's
    times = rows * (2.0 / FINE_STEPS)
    system = from_module(module, "oscillation", compiled=compiled)
    phase = 330.0 * (times[1] - times[0])
    try:
        results = Solver(system, SolverOptions(compiled=compiled)).solve(times, q0=q[first])
    except BranchError:
        OUTCOMES[("functions", f"refused (BranchError), {'above' if phase > np.pi else 'below'} Nyquist")] += 1
        return
    deviation = np.abs(_points(system, results.q) - points[rows]).max()
    assert deviation <= 1e-9, f"a row {deviation:.3g} m from the fine solve came back ({phase:.2f} rad a step, {'C' if compiled else 'Python'})"
    OUTCOMES[("functions", f"equal to the fine solve, {'above' if phase > np.pi else 'below'} Nyquist, {'C' if compiled else 'Python'}")] += 1


# ---- the force, lift and study sections with hostile entries ---------------------------------------
EXCAVATOR_DOCUMENT = yaml.safe_load((MODELS / "excavator.yaml").read_text())
SECTIONS = ("tool_forces", "lift_chart", "studies", "loads", "tool_points", "motors", "machine", "gravity")


def _entries(node, path):
    """Every entry (a path of keys and indices) below ``node``, containers and leaves."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _entries(value, (*path, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from _entries(value, (*path, index))
    if len(path) > 1:
        yield path


SECTION_ENTRIES = [path for section in SECTIONS for path in _entries(EXCAVATOR_DOCUMENT.get(section), (section,))] + [("gravity",)]
HOSTILE_VALUES = st.one_of(
    st.sampled_from([["boom_cylinder_left"], {"name": "x"}, None, 0, -1.0, 1e300, "ground.O", "bucket.Q", "nobody.x", "", [],
                     ["digging", "digging"], [0, 0, -9.7], "nan", "sqrt(t - 20)"]),
    st.text(max_size=12), st.integers(-10, 10), st.lists(st.text(max_size=6), max_size=3),
)  # fmt: skip


@settings(FUZZ, max_examples=COUNTS["sections"])
@given(path=st.sampled_from(SECTION_ENTRIES), value=HOSTILE_VALUES)
def test_hostile_section_entries_end_in_a_model_error_naming_file_and_entry(path, value):
    from kinegen.errors import ModelError
    from kinegen.model import loads

    SEEN["sections"] += 1
    document = copy.deepcopy(EXCAVATOR_DOCUMENT)
    node = document
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    try:
        loads(yaml.safe_dump(document, sort_keys=False), "excavator.yaml")
    except ModelError as error:
        assert str(error).startswith("excavator.yaml") and error.entry, error
        OUTCOMES[("sections", "refused: a model error naming file and entry")] += 1
        return
    OUTCOMES[("sections", "accepted")] += 1


# ---- command-line arguments --------------------------------------------------------------------
VALUES = st.one_of(
    st.sampled_from(["0", "-1", "1e308", "nan", "inf", "-inf", "1/0", "foo(", "pi/4", "sqrt(-1)", "[1,2", "{}", '{"a": 1}', "[]",
                     "2,2", "0,0,0", "1000000,1000000,1000000", "x.xyz", "/dev/full", "/dev/null", "/", ".", "-", "", " ",
                     "quaternion", "euler:zxz", "euler:abc", "dual-quaternion", "crank", "crank.B", "nobody.x", "r=0.3", "=", "r=nan"]),
    st.text(max_size=20),
    st.integers(-10**6, 10**6).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
)  # fmt: skip
OPTIONS = {
    "build": ["--param", "--target", "--generated-dir"],
    "solve": ["--case", "--param", "--t0", "--t1", "--steps", "--out", "--plot", "--frame", "--design", "--sensitivities", "--generated-dir"],
    "inspect": ["--param", "--case", "--at", "--q", "--budget", "--det-file"],
    "scan": ["--case", "--param", "--warn", "--horizon", "--plot"],
    "info": ["--param"],
    "view": ["--case", "--param", "--out", "--track", "--condition-warning", "--frame", "--design"],
    "envelope": ["--param", "--grid", "--plot", "--boundary"],
}  # fmt: skip
FLAGS = ["--keep-going", "--no-compile", "--json", "--latex", "--full", "--no-sensitivities", "--help"]


@contextmanager
def _time_limit(seconds: float):
    """An AssertionError when the block runs longer than ``seconds`` (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(_signum, _frame):
        raise AssertionError(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@st.composite
def command_line(draw) -> list[str]:
    command = draw(st.sampled_from(sorted(OPTIONS)))
    model = draw(st.sampled_from([str(MODELS / "four_bar.yaml"), str(MODELS / "slider_crank.yaml"), str(MODELS / "boom.yaml"),
                                  "/dev/null", "no-such.yaml", str(MODELS), "-"]))  # fmt: skip
    args = [command, model]
    for _ in range(draw(st.integers(0, 4))):
        if draw(st.booleans()):
            args += [draw(st.sampled_from(OPTIONS[command])), draw(VALUES)]
        else:
            args.append(draw(st.sampled_from(FLAGS)))
    args = [a.replace("\x00", "") for a in args]  # a process's arguments cannot hold NUL
    if "--steps" in args:  # a long solve is not an error: keep each run short (every --steps: the last one counts)
        for at in (i + 1 for i, a in enumerate(args) if a == "--steps"):
            if at < len(args) and args[at].strip().isdigit() and int(args[at]) > 2000:
                args[at] = "2000"
    elif command == "solve":
        args += ["--steps", "21"]
    if command == "inspect" and "--budget" not in args:
        args += ["--budget", "10"]
    return args


@settings(COSTLY, max_examples=COUNTS["cli"])
@given(args=command_line())
def test_random_command_lines_end_with_a_known_exit_code_and_no_traceback(tmp_path_factory, args):
    SEEN["cli"] += 1
    folder = tmp_path_factory.mktemp("cli")
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        with _time_limit(120):
            result = CliRunner().invoke(main, [*args, *(["--generated-dir", str(folder / "generated")] if args[0] in ("build", "solve") and "--generated-dir" not in args else [])], input="")
    finally:
        os.chdir(cwd)
    output = result.output
    assert result.exit_code in EXIT_CODES, f"{args}: exit {result.exit_code}\n{output}\n{result.exception!r}"
    assert "Traceback" not in output, f"{args}\n{output}"
    if result.exit_code != 0:
        errors = [line for line in output.splitlines() if line.startswith(("error:", "Error:"))]
        assert errors, f"{args}: exit {result.exit_code} without an error line\n{output}"
    OUTCOMES[("cli", f"exit {result.exit_code}")] += 1


def test_fuzz_layers_report():
    """Runs last in this file: every layer ran; the counts go into `make fuzz`'s report."""
    lines = [f"fuzz layers (issue 25): {sum(SEEN.values())} examples ({', '.join(f'{n} {layer}' for layer, n in sorted(SEEN.items()))})"]
    lines += [f"{n:6d}  {layer}: {outcome}" for (layer, outcome), n in sorted(OUTCOMES.items())]
    print("\n" + "\n".join(lines))
    if os.environ.get("KINEGEN_FUZZ_REPORT"):
        with open(os.environ["KINEGEN_FUZZ_REPORT"], "a", encoding="utf-8") as report:
            report.write("\n".join(lines) + "\n")
    if SEEN and os.environ.get("PYTEST_XDIST_WORKER") is None:  # (a selection, or xdist, runs some layers elsewhere)
        assert {"names", "tampered", "cli"} <= set(SEEN), SEEN
