"""One table of exit codes (issue 26): every error class takes its code from
``kinegen.errors.ExitCode``; classes not derived from one another end differently (but for the
two of exit 3, which both say that the motion cannot go on); docs/errors.md lists every code; the
command really ends with them."""

from __future__ import annotations

import importlib
import pkgutil
import re
import subprocess
import sys

import kinegen
from kinegen.errors import BranchError, ExitCode, KinegenError, SingularJacobianError
from tests.conftest import MODELS, ROOT

SHARED = {frozenset({SingularJacobianError, BranchError})}  # documented: exit 3 for both


def _error_classes() -> list[type]:
    for module in pkgutil.walk_packages(kinegen.__path__, "kinegen."):
        if not module.name.startswith(("kinegen.bench", "kinegen.demo")):
            importlib.import_module(module.name)
    found, pending = [], [KinegenError]
    while pending:
        cls = pending.pop()
        found.append(cls)
        pending += cls.__subclasses__()
    return found


def test_every_error_class_takes_a_code_of_the_table_and_unrelated_classes_differ():
    classes = _error_classes()
    assert len(classes) >= 10
    for cls in classes:
        assert isinstance(cls.exit_code, ExitCode), cls
    own = [cls for cls in classes if "exit_code" in cls.__dict__]  # the classes that choose a code
    for i, a in enumerate(own):
        for b in own[i + 1 :]:
            related = issubclass(a, b) or issubclass(b, a) or frozenset({a, b}) in SHARED
            assert related or a.exit_code != b.exit_code, f"{a.__name__} and {b.__name__} both exit {a.exit_code}"


def test_the_docs_list_every_code():
    text = (ROOT / "docs" / "errors.md").read_text()
    table = text[text.index("| exit | error |") :].split("\n\n", 1)[0]
    listed = {int(code) for code in re.findall(r"^\| (\d+) \|", table, re.MULTILINE)}
    assert listed == {int(code) for code in ExitCode if code != ExitCode.OK}


def test_the_command_ends_with_the_table_s_codes(tmp_path):
    def code(*args: str) -> int:
        return subprocess.run([sys.executable, "-m", "kinegen.cli", *args], capture_output=True, text=True, timeout=300).returncode

    assert code("solve", str(MODELS / "four_bar.yaml"), "--no-such-option") == ExitCode.USAGE
    assert code("no-such-command") == ExitCode.USAGE
    assert code("build", str(tmp_path / "missing.yaml")) == ExitCode.MODEL
    assert code("solve", str(MODELS / "four_bar.yaml"), "--out", "/dev/full", "--generated-dir", str(tmp_path)) == ExitCode.IO
