"""Fuzzed model files: every malformed or hostile model ends in a ModelError naming the file
and the entry, in bounded time and memory, with no code executed.

The quick subset runs with the test suite; ``make fuzz`` runs KINEGEN_FUZZ_EXAMPLES
(default there 10,000) and prints how many models ran, the error kinds hit, the longest
time and the largest peak memory any one took.

Models are the files of ``models/`` mutated by Hypothesis at three layers:

* the parsed tree: deleted, unknown and retyped keys, dangling references, NaN/inf/huge
  numbers, zero-length axes, coincident points, hostile expressions (attribute access,
  dunder names, lambdas, imports, deeply nested or enormous expressions);
* the YAML text: broken syntax, duplicated lines and so duplicate names, truncation, stray
  characters, explicit tags (standard ones on values not of their type, unknown ones),
  anchors, aliases and merge keys at random depths (exponential "billion laughs" ones and
  recursive ones), very long scalars, keys of every YAML type, mixed encodings;
* time functions composed of the whitelisted functions over random argument ranges, so
  that they leave their domains somewhere on the time grid: these models are also built
  and checked as ``kinegen build`` does.

Every model runs in a worker process with a limited address space (``tests/fuzzing.py``):
a blow-up fails that model instead of exhausting the machine.
"""

from __future__ import annotations

import atexit
import copy
import json
import os
import re
import shutil
import tempfile
from collections import Counter
from pathlib import Path

import pytest
import yaml
from fuzzing import Worker
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinegen.progress import Stages

MODELS = Path(__file__).resolve().parents[1] / "models"
BASES = {path.stem: path.read_text() for path in sorted(MODELS.glob("*.yaml"))}
TREES = {name: yaml.safe_load(text) for name, text in BASES.items()}
EXAMPLES = int(os.environ.get("KINEGEN_FUZZ_EXAMPLES", "150"))
TIME_LIMIT = 2.0  # CPU seconds per model (process time: other load on the machine does not count) ...
TIME_PER_MB = 2.5  # ... plus this per MB of file: YAML parsing is linear in the size (a 2 MB flow list: ~4 s)
WORK = Path(tempfile.mkdtemp(prefix="kinegen-fuzz-"))
atexit.register(shutil.rmtree, WORK, ignore_errors=True)
SENTINEL = WORK / "EXECUTED"  # hostile expressions try to create this file
PEAK_LIMIT_MB = 300  # resident memory one model may add while it is loaded (and built)
STATS: dict = {"models": 0, "accepted": 0, "kinds": Counter(), "longest": 0.0, "longest_kind": "", "peak": 0.0, "peak_kind": "",
               "layers": Counter()}  # fmt: skip
WORKER: list[Worker] = []
PROGRESS: list[Stages] = []  # `make fuzz` on a terminal: a bar over the models (none when captured or piped)


def _worker() -> Worker:
    if not WORKER:
        WORKER.append(Worker())
        atexit.register(WORKER[0].close)
    return WORKER[0]

HOSTILE_EXPRESSIONS = [
    f"__import__('pathlib').Path({str(SENTINEL)!r}).touch()",
    f"open({str(SENTINEL)!r}, 'w')",
    "t.__class__",
    "().__class__.__bases__[0].__subclasses__()",
    "__builtins__",
    "lambda: 1",
    "(lambda x: x)(t)",
    "import os",
    "exec('1')",
    "eval('1')",
    "globals()",
    "[x for x in (1, 2)]",
    "sin.__globals__",
    "9**9**9**9",
    "10**10**10",
    "(" * 400 + "t" + ")" * 400,
    "+".join(["t"] * 20000),
    "-" * 5000 + "1",
    "t" * 100000,
    "1/0",
    "sqrt(-1)",
    "log(0)",
    "nan",
    "oo",
    "zoo",
    "t if t else 0",
    "t; t",
    "sin(",
    "",
    "  ",
    "'string'",
    "b'bytes'",
    "t[0]",
    "{1: 2}",
    "f'{t}'",
    "t @ t",
    "unknown_name * 2",
    "sin(t, t)",
    "pi**1e6",
]
HOSTILE_VALUES = [
    None,
    True,
    False,
    0,
    -1,
    1e308,
    float("inf"),
    float("-inf"),
    float("nan"),
    10**400,
    -(10**30),
    "",
    "abc",
    [],
    {},
    [1, 2],
    [0, 0, 0],
    [1, 2, 3, 4],
    [[1, 2, 3]],
    ["a", "b", "c"],
    [float("nan"), 0, 0],
    [1e308, 1e308, 1e308],
    {"a": 1},
    {"quaternion": [0, 0, 0, 0]},
    {"axis": [0, 0, 0], "angle": 1},
    {"euler": {"sequence": "abc", "angles": [0, 0, 0]}},
    {"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]},
    *HOSTILE_EXPRESSIONS,
]
KEYS = ["type", "bodies", "points", "axes", "axis", "function", "joint", "position", "orientation", "cases", "drivers", "t0", "t1", "steps", "range", "length", "zzz", "__class__", "model", "redundant"]


def _hostile(draw):
    """A hostile value, copied (the list's own values must never be mutated)."""
    return copy.deepcopy(draw(st.sampled_from(HOSTILE_VALUES)))


def _paths(node, prefix=()) -> list[tuple]:
    """Every path (keys and indices) to a node of the parsed tree, the root included."""
    out = [prefix]
    if isinstance(node, dict):
        for key, value in node.items():
            out += _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            out += _paths(value, (*prefix, index))
    return out


def _get(node, path):
    for key in path:
        node = node[key]
    return node


def _names(tree) -> list[str]:
    names = ["ground", "nowhere", "", "ground.O", "a.b.c"]
    for section in ("bodies", "joints", "actuators", "cases"):
        if isinstance(tree.get(section), dict):
            names += [str(k) for k in tree[section]]
    return names


@st.composite
def tree_mutation(draw, tree):
    """Mutate a deep copy of ``tree`` in 1-3 places."""
    tree = json.loads(json.dumps(tree))  # deep copy (plain YAML types)
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(tree)
        path = draw(st.sampled_from(paths))
        operation = draw(st.sampled_from(["delete", "add", "replace", "replace", "rename", "zero", "coincide", "nest"]))
        if not path:
            if operation == "replace":
                tree = _hostile(draw)
                if not isinstance(tree, dict):
                    return tree
            continue
        parent = _get(tree, path[:-1])
        key = path[-1]
        if operation == "delete":
            del parent[key]
        elif operation == "add" and isinstance(parent[key], dict):
            parent[key][draw(st.sampled_from(KEYS))] = _hostile(draw)
        elif operation == "replace":
            parent[key] = _hostile(draw)
        elif operation == "rename":
            parent[key] = draw(st.sampled_from(_names(tree)))
        elif operation == "zero":
            parent[key] = [0, 0, 0]
        elif operation == "coincide" and isinstance(parent[key], list) and len(parent[key]) == 2:
            parent[key] = [parent[key][0], parent[key][0]]
        elif operation == "nest":
            parent[key] = {"x": {"y": {"z": [[[parent[key]]]]}}}
    return tree


@st.composite
def model_text(draw) -> str:
    name = draw(st.sampled_from(sorted(BASES)))
    kind = draw(st.sampled_from(["tree", "tree", "tree", "text"]))
    if kind == "tree":
        tree = draw(tree_mutation(TREES[name]))
        return yaml.safe_dump(tree, sort_keys=False, allow_unicode=True, width=10**9)
    text = BASES[name]
    lines = text.splitlines(keepends=True)
    operation = draw(st.sampled_from(["truncate", "insert", "duplicate", "delete_line", "tabs", "binary"]))
    position = draw(st.integers(0, len(text)))
    if operation == "truncate":
        return text[:position]
    if operation == "insert":
        return text[:position] + draw(st.sampled_from([":", "- ", "{", "]", "\t", "'", '"', "&a", "*a", "!!python/object:os.system", "%", "\x00", "\n  x: [", "\ufeff", "?"])) + text[position:]
    line = draw(st.integers(0, max(0, len(lines) - 1)))
    if operation == "duplicate":  # duplicate keys: a body, joint, point or case defined twice
        return "".join(lines[: line + 1] + lines[line:])
    if operation == "delete_line":
        return "".join(lines[:line] + lines[line + 1 :])
    if operation == "tabs":
        return text.replace("  ", "\t", draw(st.integers(1, 50)))
    return text[:position] + draw(st.binary(min_size=1, max_size=20)).decode("latin-1") + text[position:]


TAGS = [
    "!!float", "!!int", "!!bool", "!!null", "!!str", "!!timestamp", "!!binary", "!!seq", "!!map", "!!set", "!!omap",
    "!!pairs", "!!merge", "!!value", "!!yaml", "!unknown", "!<tag:yaml.org,2002:float>", "!<tag:example.com,2000:x>",
    "!!python/object/apply:os.system", "!!python/name:os.system", "!e!x", "!",
]  # fmt: skip
TAGGED_SCALARS = [
    "!!int " + "9" * 5000, "9" * 5000, "-" + "7" * 4400, "!!float 1e999", "!!float -.inf", "!!float abc", "!!int 0x",
    "!!int 0b102", "!!int 1_000_000", "!!timestamp 2001-13-45", "!!timestamp 2001-02-29", "!!binary @@@@",
    "!!binary aGVsbG8=", "!!bool maybe", "!!null x", "!!str 3", "!!set {a, b}", "!!omap [a: 1, a: 2]", "!!pairs [1, 2]",
    "!!seq {a: 1}", "!!map [1, 2]", "!!float .nan", "!!int 1:30", "!!float 1:30.5", "!unknown 3", "!!merge x",
]  # fmt: skip
ODD_KEYS = [
    "? [1, 2]\n  : x", "? {a: 1}\n  : x", "null: 1", "~: 1", "1.5: x", "2001-01-01: x", "true: x", "!!binary aGk=: x",
    "'': x", "k" * 10000 + ": x", "? |\n    block\n  : x", "0x10: x", "!!set {a}: x", ".inf: x", "- x",
]  # fmt: skip
_VALUE_LINE = re.compile(r"^(\s*(?:- )?[A-Za-z_][\w]*): (?!\||>)(\S.*?)(\s+#.*)?$", re.MULTILINE)
_KEY_LINE = re.compile(r"^(\s*)[A-Za-z_][\w]*:", re.MULTILINE)


def _replace_value(draw, text: str, fragment: str) -> str:
    """``text`` with the value of one random ``key: value`` line replaced by ``fragment``."""
    lines = list(_VALUE_LINE.finditer(text))
    if not lines:
        return text + fragment
    match = draw(st.sampled_from(lines))
    return text[: match.start(2)] + fragment + text[match.end(2) :]


def _laughs(depth: int, width: int, merge: bool) -> str:
    """An exponential alias structure (``width ** depth`` leaves) as one flow node."""
    if merge:
        items = ["&f0 {a: 1, b: 2}"] + [
            f"&f{k} {{<<: [{', '.join([f'*f{k - 1}'] * width)}], k{k}: [{', '.join([f'*f{k - 1}'] * width)}]}}"
            for k in range(1, depth + 1)
        ]
    else:
        items = ["&f0 [1, 1]"] + [f"&f{k} [{', '.join([f'*f{k - 1}'] * width)}]" for k in range(1, depth + 1)]
    return "[" + ", ".join(items) + "]"


@st.composite
def yaml_layer(draw) -> bytes:
    """Mutations below the parsed tree: tags, anchors/aliases/merges, long scalars, odd keys, encodings."""
    text = BASES[draw(st.sampled_from(sorted(BASES)))]
    operation = draw(st.sampled_from(["tag", "tagged", "laughs", "recursive", "merge", "alias", "long", "key", "encoding"]))
    if operation == "tag":  # a random tag in front of a random value
        positions = [m.start(2) for m in _VALUE_LINE.finditer(text)] + [m.end() for m in re.finditer(r"[\[,] ?", text)]
        at = draw(st.sampled_from(positions))
        return (text[:at] + draw(st.sampled_from(TAGS)) + " " + text[at:]).encode()
    if operation == "tagged":
        return _replace_value(draw, text, draw(st.sampled_from(TAGGED_SCALARS))).encode()
    if operation == "laughs":
        fragment = _laughs(draw(st.integers(1, 14)), draw(st.integers(2, 12)), draw(st.booleans()))
        if draw(st.booleans()):  # used again through a later alias too
            fragment = fragment.replace("[&f0", "&top [&f0", 1)
            text = _replace_value(draw, text, fragment)
            return _replace_value(draw, text, "*top").encode()
        return _replace_value(draw, text, fragment).encode()
    if operation == "recursive":
        return _replace_value(draw, text, draw(st.sampled_from(["&r [*r]", "&r {a: *r}", "&r [1, [2, *r]]", "&r {<<: *r}"]))).encode()
    if operation == "merge":  # a mapping merged into another (valid YAML), maybe several levels
        keys = list(_KEY_LINE.finditer(text))
        first, second = sorted(draw(st.lists(st.sampled_from(keys), min_size=2, max_size=2, unique_by=lambda m: m.start())), key=lambda m: m.start())
        indent = second.group(1)
        anchored = text[: first.end()] + " &m" + text[first.end() :]
        shift = len(" &m")
        at = second.end() + shift
        return (anchored[:at] + f"\n{indent}  <<: *m" + anchored[at:]).encode()
    if operation == "alias":  # anchor a value and use it elsewhere (shared scalars, lists, maps)
        text = _replace_value(draw, text, "&v " + draw(st.sampled_from(["[0, 0, 1]", "1.5", "{a: 1}", "t", "[[1, 2], [3, 4]]"])))
        for _ in range(draw(st.integers(1, 4))):
            text = _replace_value(draw, text, draw(st.sampled_from(["*v", "[*v, *v, *v]", "*undefined", "{<<: *v}"])))
        return text.encode()
    if operation == "long":
        size = draw(st.sampled_from([10_000, 200_000, 2_000_000]))
        fragment = draw(st.sampled_from(["x" * size, "'" + "y" * size + "'", "1" * size, "[" + "1, " * (size // 3) + "1]", "t+" * (size // 2) + "t"]))
        return _replace_value(draw, text, fragment).encode()
    if operation == "key":
        keys = list(_KEY_LINE.finditer(text))
        match = draw(st.sampled_from(keys))
        line = draw(st.sampled_from(ODD_KEYS)).replace("\n", "\n" + match.group(1))
        return (text[: match.start()] + match.group(1) + line + "\n" + text[match.start() :]).encode()
    encoding = draw(st.sampled_from(["utf-16", "utf-16-le", "utf-16-be", "utf-32", "utf-8-sig", "latin-1-text", "bom-inside", "invalid-utf8", "nul"]))
    if encoding == "latin-1-text":
        return ("# Größe µ\n" + text.replace("description:", "description: Maß é", 1)).encode("latin-1")
    if encoding == "bom-inside":
        at = draw(st.integers(0, len(text)))
        return (text[:at] + "\ufeff" + text[at:]).encode()
    if encoding == "invalid-utf8":
        at = draw(st.integers(0, len(text)))
        return text[:at].encode() + draw(st.sampled_from([b"\xff", b"\xc3\x28", b"\xed\xa0\x80", b"\xf4\x90\x80\x80"])) + text[at:].encode()
    if encoding == "nul":
        return text.encode().replace(b"\n", b"\x00\n", 1)
    return text.encode(encoding)


UNARY = ["sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log", "sqrt", "abs"]
_ARGUMENTS = st.sampled_from(["0", "1", "-1", "0.5", "-2", "3", "10", "100", "1000", "1e-9"])


@st.composite
def time_expression(draw, depth: int = 3) -> str:
    """A function of t built from the whitelisted functions over random affine arguments."""
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        return draw(st.sampled_from([f"({draw(_ARGUMENTS)}*t + {draw(_ARGUMENTS)})", "t", "(t - 1)", "(1 - t)", draw(_ARGUMENTS)]))
    form = draw(st.sampled_from(["unary", "unary", "unary", "atan2", "divide", "power", "product", "sum"]))
    a = draw(time_expression(depth - 1))
    if form == "unary":
        return f"{draw(st.sampled_from(UNARY))}({a})"
    b = draw(time_expression(depth - 1))
    if form == "atan2":
        return f"atan2({a}, {b})"
    if form == "divide":
        return f"{a}/{b}"
    if form == "power":
        return f"({a})**{draw(st.sampled_from(['2', '-1', '-2', '0.5', '-0.5', '1.5', '3', '(t-1)', '(-t)']))}"
    return f"{a}{'*' if form == 'product' else ' + '}{b}"


@st.composite
def expression_model(draw) -> bytes:
    """The paper's boom with a fuzzed driver function (and time grid), or a fuzzed parameter."""
    text = BASES["boom"]
    if draw(st.booleans()):
        constant = draw(time_expression()).replace("t", "2")  # the same shapes with constants: parameter L
        text = text.replace("L: 1.78 ", f"L: '{constant}' ", 1)
    else:
        text = text.replace("function: pi/2 + t**2", f"function: '{draw(time_expression())}'", 1)
        t0 = draw(st.sampled_from([-3, -1, 0, 0.5, 1]))
        text = text.replace("t0: 0", f"t0: {t0}").replace("t1: 2", f"t1: {t0 + draw(st.sampled_from([0.5, 1, 2, 4]))}")
        text = text.replace("steps: 201", f"steps: {draw(st.sampled_from([2, 11, 51]))}")
    return text.encode()


@st.composite
def fuzzed_model(draw) -> tuple[str, str, bytes]:
    """(layer, worker kind, file bytes) from one of the three layers."""
    layer = draw(st.sampled_from(["tree/text", "tree/text", "yaml", "yaml", "expression"]))
    if layer == "tree/text":
        return layer, "load", draw(model_text()).encode("utf-8", errors="surrogateescape")
    if layer == "yaml":
        return layer, "load", draw(yaml_layer())
    return layer, "expression", draw(expression_model())


def _kind(problem: str) -> str:
    """An error kind: the problem with names, numbers and quoted text removed."""
    problem = re.sub(r"'[^']*'|\"[^\"]*\"|`[^`]*`", "'…'", problem)
    problem = re.sub(r"[-+]?\d[\d.eE+-]*", "#", problem)
    return " ".join(problem.split()[:6])


def _progress(layer: str) -> None:
    if not PROGRESS:
        PROGRESS.append(Stages("fuzz", EXAMPLES, unit="models"))
        atexit.register(PROGRESS[0].__exit__)
    PROGRESS[0].stage(f"{layer} layer")


def check_model(layer: str, kind: str, data: bytes) -> None:
    """One fuzzed model in the worker: a clean ModelError (file, entry) or a valid model, in
    bounded time and memory; the offending model is kept in the work folder otherwise."""
    _progress(layer)
    report = _worker().run(kind, data)
    outcome = report["outcome"]
    label = outcome
    if outcome == "model-error":
        label = _kind(report["problem"])
    elif outcome == "kinegen-error":
        label = f"{report['type']} (build check)"
    STATS["models"] += 1
    STATS["layers"][layer] += 1
    STATS["accepted"] += outcome == "accepted"
    if outcome in ("model-error", "kinegen-error"):
        STATS["kinds"][label] += 1
    if report["cpu"] > STATS["longest"]:
        STATS["longest"], STATS["longest_kind"] = report["cpu"], label
    if report["peak_mb"] > STATS["peak"]:
        STATS["peak"], STATS["peak_kind"] = report["peak_mb"], label
    limit = TIME_LIMIT + TIME_PER_MB * len(data) / 1e6  # parsing is linear in the file's size (<= 5 MB)
    failed = outcome not in ("accepted", "model-error", "kinegen-error") or report["cpu"] >= limit or report["peak_mb"] > PEAK_LIMIT_MB
    if failed:
        (WORK / f"failed-{STATS['models']}.yaml").write_bytes(data)
    assert outcome in ("accepted", "model-error", "kinegen-error"), f"{layer}: {report['message']}"
    if outcome == "model-error":
        assert report["file"].endswith("fuzzed.yaml") and report["entry"], report
        assert report["message"].startswith(f"{report['file']}") and "Traceback" not in report["message"]
        assert len(report["message"]) < 1000  # one readable line
    if outcome == "kinegen-error":  # only the build's initial-pose check may end this way (exit 4)
        assert report["type"] in ("AssemblyError",), report
    assert report["cpu"] < limit, f"{report['cpu']:.2f} s CPU for one model ({label}); kept in {WORK}"
    assert report["peak_mb"] <= PEAK_LIMIT_MB, f"{report['peak_mb']:.0f} MB for one model ({label}); kept in {WORK}"
    assert not SENTINEL.exists(), "an expression in a model was executed"


#: the fuzz test and its statistics run in one test process, in this order (make test distributes
#: with --dist loadgroup): the statistics read what the fuzz test recorded in that process
FUZZ_GROUP = pytest.mark.xdist_group(name="fuzz")


@FUZZ_GROUP
@settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
)
@given(fuzzed_model())
def test_fuzzed_models_end_in_a_model_error_naming_file_and_entry(model):
    check_model(*model)


@FUZZ_GROUP
def test_fuzz_statistics():
    """Runs after the fuzz test (file order): models of every layer ran and several error kinds were hit."""
    if PROGRESS:
        PROGRESS[0].__exit__()
    kinds = STATS["kinds"]
    layers = ", ".join(f"{n} {layer}" for layer, n in sorted(STATS["layers"].items()))
    summary = (
        f"fuzz: {STATS['models']} models ({layers}), {STATS['accepted']} accepted, {sum(kinds.values())} errors of "
        f"{len(kinds)} kinds; longest {STATS['longest'] * 1000:.0f} ms CPU ({STATS['longest_kind']}); "
        f"largest peak memory {STATS['peak']:.0f} MB ({STATS['peak_kind']})"
    )
    print("\n" + summary)
    if os.environ.get("KINEGEN_FUZZ_REPORT"):
        Path(os.environ["KINEGEN_FUZZ_REPORT"]).write_text(
            summary + "\n" + "\n".join(f"{n:6d}  {k}" for k, n in kinds.most_common()) + "\n"
        )
    assert STATS["models"] >= min(EXAMPLES, 50) and len(kinds) >= 5 and len(STATS["layers"]) == 3


@settings(max_examples=25, deadline=None, database=None, suppress_health_check=list(HealthCheck))
@given(fuzzed_model())
def test_the_cli_reports_a_fuzzed_model_in_at_most_two_lines_and_keeps_generated_intact(model):
    """`kinegen build` on a fuzzed model: exit 2 (or 4: initial pose) with <= 2 lines, or a
    module; generated/ never half-written or written by a failed build."""
    from click.testing import CliRunner

    from kinegen.cli import main

    layer, _, data = model
    if layer == "yaml" and len(data) > 100_000:
        return  # long scalars: the worker test covers them (the CLI runs in this process, unlimited)
    path = WORK / "cli.yaml"
    path.write_bytes(data)
    out = WORK / "generated"
    before = {p.name: p.read_bytes() for p in out.glob("*")} if out.exists() else {}
    # (a valid mutation of the design excavator need not derive its sensitivity kernels here, ~15 s each, nor
    # compile its library, ~30 s)
    result = CliRunner().invoke(main, ["build", str(path), "--out-dir", str(out), "--no-sensitivities", "--no-compile"])
    if result.exit_code == 0:
        return  # a valid model (the mutation kept it well-formed)
    assert result.exit_code in (2, 4), result.output
    assert 1 <= len(result.output.strip().splitlines()) <= 2 and "Traceback" not in result.output
    after = {p.name: p.read_bytes() for p in out.glob("*")} if out.exists() else {}
    assert after == before  # nothing written or replaced by a failed build
