"""The README is a promise the tests keep (issue 27): its command blocks (and the controller's, in
docs/controller.md) are extracted and run as printed, in order, in a fresh folder holding copies
of the shipped models (``kinegen models --copy models``, as the README tells a user without a
clone), and what its comments say a command prints is in that command's output."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
CONTROLLER = (ROOT / "docs" / "controller.md").read_text()
#: tour steps that take minutes as printed (every parametrization built; 1,024 Dask variants): run
#: here as printed plus options that make them small (make run's main job runs them in full)
REDUCED = {
    "kinegen compare": " --param quaternion --param euler:zxz --case level_cut --no-compile",
    "kinegen explore": " --samples 32",
}
SLOW = tuple(REDUCED)
#: the tour's analysis steps (working range, scan, studies: ~20 s), a test of their own so that they
#: run beside the rest
ANALYSES = ("kinegen envelope", "kinegen scan", "kinegen optimize")
#: the tour's force steps and its 3-D view (~20 s together): a test of their own too
FORCES_AND_VIEW = ("kinegen forces", "kinegen lift", "kinegen view")


def _block(heading: str, language: str = "sh", text: str = README) -> str:
    """The first ``language`` code block after ``heading`` in ``text`` (the README)."""
    section = text[text.index(heading) :]
    start = section.index(f"```{language}\n") + len(language) + 4
    return section[start : section.index("```", start)]


def _commands(block: str) -> list[tuple[str, int]]:
    """(command line as printed, expected exit code) of each command of a shell block; a comment
    ``exit N`` after a command is its expected code (0 otherwise)."""
    out = []
    for line in block.splitlines():
        text = line.strip()
        if not text or text.startswith(("#", ". ")):
            continue
        command, _, comment = text.partition("  #")
        expected = re.search(r"\bexit (\d+)", comment)
        out.append((command.strip(), int(expected.group(1)) if expected else 0))
    return out


#: what the tour's comments say a command prints (its figures), checked in its output
STATED = {
    "kinegen solve models/excavator.yaml --case bucket_near_toggle": ("RANGE: bucket_cylinder", "[1.6529, 2.6613] m at 5 of 9 time points"),
    "kinegen solve models/excavator.yaml --case level_cut --load payload": ("the machine's own weight", "--no-weight leaves it out"),
    "kinegen solve models/excavator.yaml --case digging --dynamics": ("TIPPING:", "FLOW: pump front asked more than its 212 L/min", "(3.43 times)"),
    "kinegen cycle models/excavator.yaml --case digging --load payload": ("fastest timing 14.68 s", "no limit exceeded"),
    "kinegen solve models/boom.yaml --param euler:zxz": ("singular", "t = 0", "boom.alpha - boom.gamma"),
    "kinegen inspect models/boom.yaml --param euler:zxz --at 0": ("rank 5", "sin(boom_beta)"),
    "kinegen inspect models/boom.yaml --param quaternion --at 0": ("det Phi_q at this configuration = 1\n",),
    "kinegen inspect models/boom.yaml --param dual-quaternion --at 0": ("det Phi_q at this configuration = -1\n",),
    "kinegen inspect models/excavator.yaml --param euler:zxz --at 0": ("upper", "sin(upper_beta)"),
}


def _run(commands: list[tuple[str, int]], folder: Path) -> list[str]:
    """Run each command in ``folder`` (this Python's kinegen first on PATH), checking its exit code
    and what :data:`STATED` says it prints; their outputs."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}", "MPLBACKEND": "Agg"}
    outputs = []
    for command, expected in commands:
        done = subprocess.run(command, shell=True, cwd=folder, env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == expected, f"{command}\nexit {done.returncode}, expected {expected}\n{done.stderr[-2000:]}"
        for fragment in next((said for start, said in STATED.items() if command.startswith(start)), ()):
            assert fragment in done.stdout + done.stderr, f"{command}: the README says it prints {fragment!r}\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
        outputs.append(done.stdout)
    return outputs


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory) -> Path:
    """A folder as the tour expects it after `make run`: the shipped models copied into models/
    (as a user without a clone makes it) and the generated modules the main job leaves (copies of
    the committed ones: fresh for these models, so nothing is rebuilt that the tour does not build)."""
    folder = tmp_path_factory.mktemp("user")
    _run([("kinegen models --copy models", 0)], folder)
    assert (folder / "models" / "excavator.yaml").is_file()
    shutil.copytree(ROOT / "generated", folder / "generated")
    return folder


def test_the_tours_commands_run_as_printed(user_folder: Path) -> None:
    commands = _commands(_block("## A 5-minute tour"))
    assert len(commands) >= 15 and any(expected == 3 for _, expected in commands)
    assert all(any(c.startswith(start) for c, _ in commands) for start in STATED)  # every stated figure still in the tour
    _run([(c, e) for c, e in commands if not c.startswith(SLOW + ANALYSES + FORCES_AND_VIEW)], user_folder)
    for written in ("out/boom.csv", "out/boom.png", "out/boom.html"):
        assert (user_folder / written).stat().st_size > 0, written


def test_the_tours_force_and_view_steps_run_as_printed(user_folder: Path) -> None:
    steps = [(c, e) for c, e in _commands(_block("## A 5-minute tour")) if c.startswith(FORCES_AND_VIEW)]
    assert [c.split()[1] for c, _ in steps] == ["forces", "lift", "forces", "view"]
    printed = _run(steps, user_folder)
    assert "bucket digging force" in printed[0] and "75 % of the tipping load" in printed[1]
    for written in ("out/digging_map.csv", "out/excavator_digging.html", "out/digging.gif"):
        assert (user_folder / written).stat().st_size > 0, written


def test_the_tours_analysis_steps_run_as_printed(user_folder: Path) -> None:
    steps = [(c, e) for c, e in _commands(_block("## A 5-minute tour")) if c.startswith(ANALYSES)]
    assert len(steps) == 4
    _run(steps, user_folder)
    for written in ("out/envelope.png", "out/boundary.csv", "out/scan.png", "out/excavator_calibration.yaml", "out/excavator_bucket_linkage.yaml"):
        assert (user_folder / written).stat().st_size > 0, written


def test_the_tours_slow_steps_run_as_printed_in_a_reduced_form(user_folder: Path) -> None:
    steps = [(c, e) for c, e in _commands(_block("## A 5-minute tour")) if c.startswith(SLOW)]
    assert [c.split()[1] for c, _ in steps] == ["compare", "explore"]
    compared, _ = _run([(c + REDUCED[" ".join(c.split()[:2])], e) for c, e in steps], user_folder)
    assert "quaternion" in compared and "euler:zxz" in compared and "singular where beta = 0 or pi" in compared
    # the generated lines docs/parametrizations.md states for the excavator are these (a module's lines do not depend on the case)
    stated = (ROOT / "docs" / "parametrizations.md").read_text()
    table = stated[stated.index("parametrization        q") :].split("```", 1)[0]
    for name in ("quaternion", "euler:zxz"):
        mine = next(line.split() for line in compared.splitlines() if line.startswith(name + " "))
        theirs = next(line.split() for line in table.splitlines() if line.startswith(name + " "))
        assert mine[7] == theirs[7], (name, mine[7], theirs[7])
    import pyarrow.dataset as ds

    table = ds.dataset(user_folder / "out" / "excavator_calibration.parquet").to_table()
    assert table.num_rows == 32 and "max_reach" in table.column_names
    assert (user_folder / "out" / "explore.png").stat().st_size > 0


def test_the_controllers_commands_build_and_run_the_standalone_c_as_printed(user_folder: Path) -> None:
    commands = _commands(_block("## Using kinegen in a controller", text=CONTROLLER))
    program = "out/excavator_c/excavator_quaternion_example"
    assert [shlex.split(c)[0] for c, _ in commands] == ["kinegen", "make", program, program]
    _run(commands, user_folder)
    header, *rows = (user_folder / "out" / "level_cut.csv").read_text().splitlines()
    assert header.startswith("t,converged,newton_iterations") and len(rows) > 10
    assert all(row.split(",")[1] == "1" for row in rows)
    header, *rows = (user_folder / "out" / "level_cut_forces.csv").read_text().splitlines()
    names = header.split(",")
    assert len(rows) == 101 and {"swing_motor.force", "arm_cylinder.force", "bucket_cylinder.force", "lambda.swing.x"} <= set(names)
    arm = names.index("arm_cylinder.force")
    assert all(float(row.split(",")[arm]) > 0 for row in rows)  # the arm cylinder pushes along the level cut (docs/forces.md)


def test_the_readme_is_a_short_page_and_every_link_in_it_and_in_docs_resolves() -> None:
    """The README is the five-minute page (issue 39: under 200 lines, the theory and reference in
    docs/); every relative link of it and of docs/*.md names a file that exists (an anchor, a
    heading of that file)."""
    assert len(README.splitlines()) < 200
    pages = {ROOT / "README.md": README, **{p: p.read_text() for p in (ROOT / "docs").glob("*.md")}}
    for page, text in pages.items():
        for target in re.findall(r"\]\(([^)#\s]+\.md)(#[^)]*)?\)", text):
            file, anchor = target
            path = (page.parent / file).resolve()
            assert path.is_file(), f"{page.name}: link to {file}, no such file"
            if anchor:
                headings = {re.sub(r"[^\w\- ]", "", h).strip().lower().replace(" ", "-") for h in re.findall(r"^#+ (.+)$", path.read_text(), re.M)}
                assert anchor[1:] in headings, f"{page.name}: link to {file}{anchor}, no such heading"
