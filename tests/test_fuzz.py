"""Fuzzed model files: every malformed or hostile model ends in a ModelError naming the file
and the entry, in bounded time, with no code executed.

The quick subset runs with the test suite; ``make fuzz`` runs KINEGEN_FUZZ_EXAMPLES
(default there 10,000) and prints how many models ran, the error kinds hit and the
longest time any one took.

Models are the files of ``models/`` mutated by Hypothesis: on the parsed tree (deleted,
unknown and retyped keys, dangling references, NaN/inf/huge numbers, zero-length axes,
coincident points, hostile expressions: attribute access, dunder names, lambdas, imports,
deeply nested or enormous expressions) and on the text (broken YAML, duplicated lines
and so duplicate names, truncation, stray characters).
"""

from __future__ import annotations

import atexit
import copy
import json
import os
import re
import shutil
import tempfile
import time
import warnings
from collections import Counter
from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinegen.errors import ModelError
from kinegen.model import load

MODELS = Path(__file__).resolve().parents[1] / "models"
BASES = {path.stem: path.read_text() for path in sorted(MODELS.glob("*.yaml"))}
TREES = {name: yaml.safe_load(text) for name, text in BASES.items()}
EXAMPLES = int(os.environ.get("KINEGEN_FUZZ_EXAMPLES", "150"))
TIME_LIMIT = 2.0  # CPU seconds per model (process time: other load on the machine does not count)
WORK = Path(tempfile.mkdtemp(prefix="kinegen-fuzz-"))
atexit.register(shutil.rmtree, WORK, ignore_errors=True)
SENTINEL = WORK / "EXECUTED"  # hostile expressions try to create this file
STATS: dict = {"models": 0, "accepted": 0, "kinds": Counter(), "longest": 0.0, "longest_kind": ""}

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


def _kind(error: ModelError) -> str:
    """An error kind: the problem with names, numbers and quoted text removed."""
    problem = re.sub(r"'[^']*'|\"[^\"]*\"|`[^`]*`", "'…'", error.problem)
    problem = re.sub(r"[-+]?\d[\d.eE+-]*", "#", problem)
    return " ".join(problem.split()[:6])


def check_model(text: str) -> None:
    """Load one fuzzed model: a clean ModelError (file, entry) or a valid model, in bounded time."""
    path = WORK / "fuzzed.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogateescape")
    start = time.process_time()
    kind = "accepted"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            load(path)
        STATS["accepted"] += 1
    except ModelError as error:
        assert error.file == str(path) or error.file.endswith("fuzzed.yaml"), error
        assert str(error).startswith(f"{error.file}: ") and error.entry, error
        assert "Traceback" not in str(error) and len(str(error)) < 1000  # one readable line
        kind = _kind(error)
        STATS["kinds"][kind] += 1
    elapsed = time.process_time() - start
    STATS["models"] += 1
    if elapsed > STATS["longest"]:
        STATS["longest"], STATS["longest_kind"] = elapsed, kind
    if elapsed >= TIME_LIMIT:
        (WORK / "slow.yaml").write_text(text, encoding="utf-8", errors="surrogateescape")
    assert elapsed < TIME_LIMIT, f"{elapsed:.2f} s for one model ({kind}); kept in {WORK / 'slow.yaml'}"
    assert not SENTINEL.exists(), "an expression in a model was executed"


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
)
@given(model_text())
def test_fuzzed_models_end_in_a_model_error_naming_file_and_entry(text):
    check_model(text)


def test_fuzz_statistics():
    """Runs after the fuzz test (file order): at least one model ran and several error kinds were hit."""
    kinds = STATS["kinds"]
    summary = (
        f"fuzz: {STATS['models']} models, {STATS['accepted']} accepted, {sum(kinds.values())} ModelErrors of "
        f"{len(kinds)} kinds; longest {STATS['longest'] * 1000:.0f} ms ({STATS['longest_kind']})"
    )
    print("\n" + summary)
    if os.environ.get("KINEGEN_FUZZ_REPORT"):
        Path(os.environ["KINEGEN_FUZZ_REPORT"]).write_text(
            summary + "\n" + "\n".join(f"{n:6d}  {k}" for k, n in kinds.most_common()) + "\n"
        )
    assert STATS["models"] >= min(EXAMPLES, 50) and len(kinds) >= 5


@settings(max_examples=25, deadline=None, database=None, suppress_health_check=list(HealthCheck))
@given(model_text())
def test_the_cli_reports_a_fuzzed_model_in_at_most_two_lines_and_keeps_generated_intact(text):
    """`kinegen build` on a fuzzed model: exit 2 with <= 2 lines, or a module; generated/ never half-written."""
    from click.testing import CliRunner

    from kinegen.cli import main

    path = WORK / "cli.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogateescape")
    out = WORK / "generated"
    before = {p.name: p.read_bytes() for p in out.glob("*")} if out.exists() else {}
    result = CliRunner().invoke(main, ["build", str(path), "--out-dir", str(out)])
    if result.exit_code == 0:
        return  # a valid model (the mutation kept it well-formed)
    assert result.exit_code in (2, 3, 4, 6), result.output
    assert 1 <= len(result.output.strip().splitlines()) <= 2 and "Traceback" not in result.output
    after = {p.name: p.read_bytes() for p in out.glob("*")} if out.exists() else {}
    assert after == before  # nothing written or replaced by a failed build
