"""Model files written as an attacker would, below the parsed tree: YAML tags, aliases,
time functions that leave their domain, and valid models that used to crash later.

Each must end as a ModelError naming the file (and the line and entry where there is one),
exit 2 through the CLI with at most two lines, bounded in time and memory, nothing written.
"""

from __future__ import annotations

import re
import resource
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kinegen.cli import main
from kinegen.codegen.inmemory import lambdify_model
from kinegen.errors import ModelError, shown
from kinegen.model import loads
from kinegen.rotations import get
from kinegen.runtime import Solver, from_module, kinematics, solve
from tests.conftest import OPEN_LOOP

MODELS = Path(__file__).resolve().parents[1] / "models"
BOOM = (MODELS / "boom.yaml").read_text()


def build(tmp_path: Path, text: str | bytes, *args: str):
    """`kinegen build` of ``text``: (result, files written to the output folder)."""
    path = tmp_path / "model.yaml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    out = tmp_path / "generated"
    result = CliRunner().invoke(main, ["build", str(path), "--out-dir", str(out), *args])
    return result, sorted(p.name for p in out.glob("*")) if out.exists() else []


def assert_model_error(result, files: list[str], *fragments: str) -> str:
    """Exit 2, one or two lines, no traceback, nothing written; returns the message."""
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert 1 <= len(lines) <= 2 and "Traceback" not in result.output, result.output
    assert files == [], files
    for fragment in fragments:
        assert fragment in result.output, result.output
    return result.output


@pytest.mark.parametrize(
    ("value", "fragment"),
    [
        ("!!float abc", "!!float value 'abc' cannot be read"),
        ("!!int 12abc", "!!int value '12abc' cannot be read"),
        ("!!timestamp 2001-99-99", "!!timestamp value '2001-99-99' cannot be read"),
        ("!!bool maybe", "!!bool value 'maybe' cannot be read"),
        ("!!binary 'a'", "failed to decode base64"),
        ("9" * 5000, "!!int value of 5000 digits is too long"),
        ("!!int " + "7" * 4400, "!!int value of 4400 digits is too long"),
        ("!!python/object/apply:os.system ['id']", "could not determine a constructor"),
    ],
)
def test_explicit_tags_that_fail_to_construct_name_the_line(tmp_path, value, fragment):
    result, files = build(tmp_path, BOOM.replace("L: 1.78 ", f"L: {value} "), "--param", "quaternion")
    message = assert_model_error(result, files, fragment)
    assert re.search(r"model\.yaml:6: column \d+: invalid YAML", message), message  # L is on line 6


def laughs(depth: int, width: int = 10) -> str:
    """A 'billion laughs' value: width ** depth leaves as a tree of shared aliases."""
    items = ["&l0 [1, 1, 1]"] + [f"&l{k} [{', '.join([f'*l{k - 1}'] * width)}]" for k in range(1, depth + 1)]
    return "[" + ", ".join(items) + "]"


@pytest.mark.parametrize("where", ["position", "description", "points"])
def test_billion_laughs_is_refused_quickly_in_bounded_memory(tmp_path, where):
    value = laughs(9)  # 10^9 leaves if expanded
    text = {
        "position": BOOM.replace("position: [0, L, 0]", f"position: {value}"),
        "description": BOOM.replace("description: Boom", f"description: {value}\nx: Boom"),
        "points": BOOM.replace("tip: [L, 0, 0]", f"tip: {value}"),
    }[where]
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.process_time()
    result, files = build(tmp_path, text)
    assert time.process_time() - start < 2.0
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 100_000  # kB: no expansion
    assert_model_error(result, files, "aliases expand the document by more than 10,000 nodes here")


def test_a_document_of_too_many_nodes_is_refused_before_they_are_built(tmp_path):
    """A 2 MB flow list (667,000 nodes) within the 5 MB file limit: refused from the parser's
    events, before the ~500 bytes a node of a node graph would take."""
    text = BOOM.replace("position: [0, L, 0]", "position: [" + "1, " * 666_666 + "1]")
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.process_time()
    result, files = build(tmp_path, text)
    assert time.process_time() - start < 2.0
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 100_000  # kB
    assert_model_error(result, files, "model.yaml:12: (file): more than 500,000 YAML nodes")  # the position line


def test_recursive_alias_is_refused(tmp_path):
    result, files = build(tmp_path, BOOM.replace("position: [0, L, 0]", "position: &r [0, L, *r]"))
    assert_model_error(result, files, "recursive document")


def test_small_aliases_and_merge_keys_stay_usable():
    """Anchors for sharing pieces are fine: the same model written with an alias and a merge key."""
    text = BOOM.replace("vectors: {z: [0, 0, 1]}", "vectors: {z: &up [0, 0, 1]}", 1).replace(
        "    vectors:\n      z: [0, 0, 1]", "    vectors:\n      z: *up"
    )
    text = text.replace(
        "      phi1: {type: joint_angle, joint: pivot, function: pi/2 + t**2}",
        "      phi1:\n        <<: &driver {type: joint_angle, joint: pivot}\n        function: pi/2 + t**2",
    )
    aliased, plain = loads(text, "aliased.yaml"), loads(BOOM, "boom.yaml")
    assert aliased.bodies[0].vectors == plain.bodies[0].vectors
    assert aliased.cases["swing"].drivers[0].function == plain.cases["swing"].drivers[0].function


def test_echoed_values_are_bounded_in_work_and_length():
    big: list = [1]
    for _ in range(40):  # 2^40 leaves as a shared tree: repr() would never finish
        big = [big, big]
    start = time.process_time()
    text = shown(big) + shown(10**20000) + shown("x" * 10**7) + shown({str(k): k for k in range(10**5)})
    assert time.process_time() - start < 0.5 and len(text) < 1000
    assert "integer of 20001 digits" in text


def test_error_messages_name_the_line_of_the_entry(tmp_path):
    result, files = build(tmp_path, BOOM.replace("axes: [z, z]", "axes: [z, y]"))
    assert_model_error(result, files, "model.yaml:24: joints.pivot.axes[1]: unknown vector 'y' on body 'boom'")


@pytest.mark.parametrize(
    ("function", "what", "at"),
    [
        ("sqrt(t - 1)", "its value", "t = 0 (nan)"),
        ("log(t - 1)", "its value", "t = 0 (nan)"),
        ("asin(t)", "its first time derivative", "t = 1 (inf)"),
        ("acos(t/2 + 0.5)", "its first time derivative", "t = 1 (-inf)"),
        ("1/(t - 1)", "its value", "t = 1 (inf)"),
        ("(t - 1)**(-2)", "its value", "t = 1 (inf)"),
        ("exp(1000*t)", "its second time derivative", "t = 0.7 (inf)"),
        ("sqrt(t)", "its first time derivative", "t = 0 (inf)"),
    ],
)
def test_a_time_function_leaving_its_domain_is_a_model_error_at_build(tmp_path, function, what, at):
    """Checked on the case's time grid before the module is written: entry, expression, first time."""
    result, files = build(tmp_path, BOOM.replace("function: pi/2 + t**2", f"function: {function}"))
    assert_model_error(result, files, "cases.swing.drivers.phi1.function", repr(function), what, at)


def test_functions_whose_derivative_is_not_finite_are_refused_at_load():
    with pytest.raises(ModelError, match=r"boom.yaml:29: cases.swing.drivers.phi1.function: .* \(its first time derivative\)"):
        loads(BOOM.replace("function: pi/2 + t**2", "function: 0**(t - 3)"), "boom.yaml")


def test_a_time_function_checked_on_the_grid_actually_solved():
    """Valid on the case's own grid (t > 1), refused on a grid that starts earlier."""
    text = BOOM.replace("function: pi/2 + t**2", "function: sqrt(t - 1)").replace("t0: 0", "t0: 1.5").replace("t1: 2", "t1: 3")
    system = from_module(lambdify_model(loads(text, "boom.yaml"), get("quaternion")))
    results = solve(system)
    angle = np.arctan2(kinematics.point_position(results, "boom", "tip")[:, 1], kinematics.point_position(results, "boom", "tip")[:, 0])
    assert np.allclose(np.unwrap(angle), np.sqrt(results.times - 1), atol=1e-10)  # tip angle = driver angle
    with pytest.raises(ModelError, match=r"'sqrt\(t - 1\)': its value is not a finite real number at t = 0 \(nan\)"):
        Solver(system).solve(np.linspace(0, 2, 21))


def test_abs_kinks_are_drivable():
    """abs() has an impulse in its second derivative: dropped, the run matches |t - 1| exactly."""
    text = BOOM.replace("function: pi/2 + t**2", "function: 0.5 + abs(t - 1)")
    system = from_module(lambdify_model(loads(text, "boom.yaml"), get("quaternion")))
    u, ud, udd = system.driver_inputs(np.array([0.5, 1.0, 1.5]))
    assert np.allclose(u[0], [1.0, 0.5, 1.0]) and np.allclose(ud[0], [-1, 0, 1]) and np.allclose(udd[0], 0)


ACTUATED = """\
model: lever
ground:
  points: {O: [0, 0, 0], P: [0, -1, 0]}
  vectors: {z: [0, 0, 1]}
bodies:
  lever:
    position: [1, 0, 0]
    points: {O: [-1, 0, 0], tip: [1, 0, 0]}
    vectors: {z: [0, 0, 1]}
joints:
  pivot: {type: revolute, bodies: [ground, lever], points: [O, O], axes: [z, z]}
actuators:
  cylinder: {points: [ground.P, lever.tip], range: [1.5, 2.5]}
cases:
  swing:
    drivers:
      angle: {type: joint_angle, joint: pivot, function: t}
    t1: 1.5
    steps: 31
"""


def test_an_actuator_anchored_on_the_ground_is_reported(tmp_path):
    """Length, rate and range violations of a cylinder from a ground point, against the closed form
    |P - tip| with tip = 2 (cos t, sin t): L^2 = 5 + 4 sin t."""
    path = tmp_path / "lever.yaml"
    path.write_text(ACTUATED)
    result = CliRunner().invoke(main, ["solve", str(path), "--generated-dir", str(tmp_path), "--out", str(tmp_path / "lever.csv")])
    assert result.exit_code == 0, result.output
    data = np.genfromtxt(tmp_path / "lever.csv", delimiter=",", names=True)
    t = data["t"]
    assert np.allclose(data["cylinderlength"], np.sqrt(5 + 4 * np.sin(t)), atol=1e-12)
    assert np.allclose(data["cylinderrate"], 2 * np.cos(t) / np.sqrt(5 + 4 * np.sin(t)), atol=1e-10)
    system = from_module(lambdify_model(loads(ACTUATED, "lever.yaml"), get("quaternion")))
    violations = kinematics.range_violations(solve(system))
    assert violations and all(length > 2.5 for _, name, length, _ in violations if name == "cylinder")
    assert min(time for time, *_ in violations) == pytest.approx(t[np.sqrt(5 + 4 * np.sin(t)) > 2.5][0])


def test_without_a_compiler_the_solve_says_so_and_uses_python(tmp_path, monkeypatch):
    """The compiled path is the default; without a usable compiler (CC naming a missing program,
    or none on PATH) one warning line, then the Python functions solve (exit 0)."""
    for variables in ({"CC": str(tmp_path / "no-such-compiler")}, {"CC": "", "PATH": str(tmp_path)}):
        for name, value in variables.items():
            monkeypatch.setenv(name, value)
        monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
        out = tmp_path / "boom.csv"
        result = CliRunner().invoke(main, ["solve", str(MODELS / "boom.yaml"), "--out", str(out)])
        assert result.exit_code == 0, result.output
        warning = [line for line in result.output.splitlines() if line.startswith("warning:")]
        assert len(warning) == 1 and "with the Python functions" in warning[0] and out.exists()


def test_a_build_whose_initial_pose_cannot_be_assembled_writes_nothing(tmp_path):
    """A four-bar whose links cannot close: exit 4 (AssemblyError), generated/ untouched."""
    result, files = build(tmp_path, OPEN_LOOP)
    assert result.exit_code == 4, result.output
    assert "initial pose cannot be assembled" in result.output and "coupler.length" in result.output
    assert len(result.output.strip().splitlines()) <= 2 and files == []
