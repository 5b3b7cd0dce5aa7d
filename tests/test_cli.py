"""The `kinegen` command: build, solve, inspect, and readable errors with distinct exit codes."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kinegen.cli import main
from kinegen.errors import ExitCode
from kinegen.runtime import kinematics
from tests.conftest import MODELS, cache_with_solver

BOOM = str(MODELS / "boom.yaml")


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def test_build_writes_the_module_and_checks_the_initial_pose(tmp_path):
    result = run("build", BOOM, "--param", "quaternion", "--param", "euler:zxz", "--generated-dir", str(tmp_path))
    assert result.exit_code == 0, result.output
    assert (tmp_path / "boom_quaternion.py").is_file() and (tmp_path / "boom_euler_zxz.py").is_file()
    assert "initial pose satisfies Phi" in result.output


def test_a_build_without_compiling_writes_the_same_files_and_the_first_compiled_solve_compiles_them(tmp_path, monkeypatch):
    """`kinegen build --no-compile`: the same files as a build that compiles, nothing compiled into the
    cache (not even kinegen's C solver); the first compiled solve compiles the library, and it solves
    as the Python functions do (to 1e-9 m)."""
    from kinegen.runtime import Solver, from_module, load_module

    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    result = run("build", BOOM, "--no-compile", "--generated-dir", str(tmp_path / "a"))
    assert result.exit_code == 0, result.output
    assert not list((tmp_path / "cache").rglob("*.o")) and not list((tmp_path / "cache").rglob("*.so"))
    assert run("build", BOOM, "--generated-dir", str(tmp_path / "b")).exit_code == 0
    assert list((tmp_path / "cache").rglob("*.so"))
    assert {p.name: p.read_bytes() for p in (tmp_path / "a").iterdir()} == {p.name: p.read_bytes() for p in (tmp_path / "b").iterdir()}
    monkeypatch.setenv("KINEGEN_CACHE", str(cache_with_solver(tmp_path / "cache2")))  # (this cache's own first compile: the model's)
    module = load_module(tmp_path / "a" / "boom_quaternion.py", BOOM)
    compiled, python = (Solver(from_module(module, compiled=flag)).solve() for flag in (True, False))
    assert list((tmp_path / "cache2").rglob("*.so")) and compiled.system.native is not None
    assert np.abs(compiled.q - python.q).max() < 1e-9


def test_solve_writes_csv_with_poses_rates_and_points(tmp_path):
    out = tmp_path / "boom.csv"
    result = run(
        "solve", BOOM, "--param", "quaternion", "--t1", "1", "--steps", "11", "--out", str(out), "--generated-dir", str(tmp_path)
    )
    assert result.exit_code == 0, result.output
    assert "11 time points" in result.output
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 11
    last = rows[-1]
    assert float(last["t"]) == 1.0
    assert abs(float(last["boom.omega_z"]) - 2.0) < 1e-10  # omega = 2t
    tip = np.array([float(last[f"boom.tip.{c}"]) for c in "xyz"])
    assert np.allclose(tip, 3.56 * np.array([np.cos(np.pi / 2 + 1), np.sin(np.pi / 2 + 1), 0]), atol=1e-10)


def test_solve_with_euler_zxz_exits_with_the_singular_code(tmp_path):
    result = run("solve", BOOM, "--param", "euler:zxz", "--generated-dir", str(tmp_path))
    assert result.exit_code == 3
    assert "singular Jacobian at t = 0" in result.output
    assert "boom.alpha - boom.gamma" in result.output
    assert "Traceback" not in result.output


def test_inspect_proves_the_euler_singularity():
    result = run("inspect", BOOM, "--param", "euler:zxz", "--at", "0", "--latex")
    assert result.exit_code == 0, result.output
    assert "exact rank 5 (singular)" in result.output
    assert "vanishing factor: sin(boom_beta)" in result.output
    assert "boom.alpha - boom.gamma" in result.output
    assert r"\det \Phi_q" in result.output
    assert "boom.y = 89/50 (1.78)" in result.output and "boom.alpha = pi/2 (1.5708)" in result.output
    assert "**2 + cos(" not in result.output  # sin(x)**2 + cos(x)**2 simplified out of the determinant


def test_inspect_json_for_tools():
    result = run("inspect", BOOM, "--param", "quaternion", "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    assert report["rank"] == 6 and report["determinant_value"] in ("1", "-1")
    assert report["jacobian"][0] == ["-1", "0", "0", "0", "0", "-89/50"]


def test_model_error_is_one_readable_line_with_its_own_exit_code(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text((MODELS / "boom.yaml").read_text().replace("function: pi/2 + t**2", "function: __import__('os').system('id')"))
    result = run("build", str(bad), "--out-dir", str(tmp_path / "gen"))
    assert result.exit_code == 2
    assert result.output.startswith(f"error: {bad}:29: cases.swing.drivers.phi1.function: ")  # file:line: entry
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "gen").exists() or not any((tmp_path / "gen").iterdir())


def test_missing_file_and_unknown_parametrization():
    assert run("build", "no/such/model.yaml").exit_code == 2
    result = run("build", BOOM, "--param", "euler:abc")
    assert result.exit_code == ExitCode.USAGE and "unknown Euler sequence" in result.output


def test_keep_going_writes_the_results_so_far_and_exits_with_the_error_code(tmp_path):
    """bucket_toggle passes the linkage's toggle: the CSV ends with the failed step marked."""
    out = tmp_path / "toggle.csv"
    model_file = str(MODELS / "excavator.yaml")
    result = run("solve", model_file, "--case", "bucket_toggle", "--keep-going", "--out", str(out))
    assert result.exit_code in (3, 4), result.output
    lines = result.output.strip().splitlines()
    assert lines[0].startswith("excavator/bucket_toggle [quaternion]: ") and " of 301 time points" in lines[0]
    assert lines[-1].startswith("error: ")
    rows = list(csv.DictReader(out.open()))
    assert [float(r["converged"]) for r in rows[-2:]] == [1.0, 0.0]
    assert 2.2 < float(rows[-1]["t"]) < 2.4
    assert run("solve", model_file, "--case", "bucket_toggle").exit_code in (3, 4)


def test_info_counts_what_the_built_modules_have():
    """kinegen info counts coordinates and equations without building: against the committed
    excavator modules of every parametrization."""
    from kinegen.runtime import load_module
    from tests.conftest import GENERATED

    result = run("info", str(MODELS / "excavator.yaml"), "--param", "quaternion", "--param", "euler-parameters",
                 "--param", "dual-quaternion", "--param", "dual-euler-parameters", "--param", "euler:zxz")  # fmt: skip
    assert result.exit_code == 0, result.output
    for case in ("digging", "level_cut", "trench_wall", "bucket_toggle", "bucket_stroke", "bucket_near_toggle"):
        assert f"  {case} " in result.output
    assert "bucket_cylinder" in result.output and "[1.6529, 2.6613] m" in result.output
    for name, tag in (("quaternion", "quaternion"), ("euler-parameters", "euler_parameters"), ("dual-quaternion", "dual_quaternion"),
                      ("dual-euler-parameters", "dual_euler_parameters"), ("euler:zxz", "euler_zxz")):  # fmt: skip
        module = load_module(GENERATED / f"excavator_{tag}.py")
        equations = len(module.CASES["digging"]["constraints"])
        line = next(x for x in result.output.splitlines() if x.split() and x.split()[0] == name)
        numbers = line.split()
        assert (int(numbers[1]), int(numbers[3])) == (len(module.STORED_NAMES), len(module.VELOCITY_NAMES)), line
        assert int(numbers[numbers.index("=") + 1]) == equations, line


def test_solve_reports_an_actuator_leaving_its_range():
    result = run("solve", str(MODELS / "excavator.yaml"), "--case", "bucket_near_toggle")
    assert result.exit_code == 0, result.output
    # the case drives the bucket cylinder to 1.6 mm short of its toggle at 2.7366 m, past its 2.6613 m end
    assert "RANGE: bucket_cylinder outside [1.6529, 2.6613] m at 5 of 9 time points" in result.output
    assert "farthest 2.7350 m at t = 1 s" in result.output


def test_solve_refuses_non_finite_times_and_results_larger_than_memory():
    for option in ("--t0", "--t1"):
        for value in ("nan", "inf", "-inf"):
            result = run("solve", str(MODELS / "boom.yaml"), option, value)
            assert result.exit_code == ExitCode.USAGE and "finite number" in result.output, result.output
    result = run("solve", str(MODELS / "boom.yaml"), "--steps", "10000000000")
    assert result.exit_code == ExitCode.USAGE and "--force" in result.output and "GiB" in result.output


@pytest.mark.skipif(not Path("/proc/meminfo").exists(), reason="Linux's /proc/meminfo")
def test_the_memory_check_counts_the_cache_the_kernel_would_give_back():
    """The CI machine once had 0.3 GiB of free pages and refused a 0.2 GiB solve: free pages
    leave out the page cache. Available memory is psutil's (Dask's own reading of it, an
    independent one), to the little that moves between the two readings; at least the free pages
    less the kernel's reserve (a few percent of the total) and at most the physical memory."""
    psutil = pytest.importorskip("psutil")
    from kinegen.service.solve import available_memory

    page = os.sysconf("SC_PAGE_SIZE")
    free, total = os.sysconf("SC_AVPHYS_PAGES") * page, os.sysconf("SC_PHYS_PAGES") * page
    mine, theirs = available_memory(), psutil.virtual_memory().available
    assert abs(mine - theirs) <= 0.02 * total, (mine, theirs)
    assert free - 0.1 * total <= mine <= total


def test_the_solve_plot_draws_each_mechanism_in_the_plane_that_shows_it(tmp_path):
    """The boom turns about global z: drawn in the x-y plane (its old side view had zero height);
    the excavator swings: drawn in its upper structure's x-z plane, where the front stays."""
    from kinegen.analysis.plots import best_frame, drawing_plane, tracked_point
    from kinegen.runtime import solve
    from tests.conftest import generated_system

    boom = solve(generated_system("boom_quaternion"))
    assert tracked_point(boom) == ("boom", "tip") and best_frame(boom, ("boom", "tip")) is None
    basis, labels, _ = drawing_plane(boom, None)
    assert labels == ("x, global [m]", "y, global [m]") and np.array_equal(basis, np.eye(3)[:2])
    tip = kinematics.point_position(boom, "boom", "tip")
    assert np.abs(tip[:, 2]).max() < 1e-12  # the motion is in that plane: nothing is lost drawing it there
    excavator = solve(generated_system("excavator_quaternion", "digging"))
    assert best_frame(excavator, ("bucket", "T")) == "upper"
    for model, extra in (("boom", ()), ("excavator", ()), ("four_bar", ("--frame", "crank"))):
        png = tmp_path / f"{model}.png"
        result = run("solve", str(MODELS / f"{model}.yaml"), "--plot", str(png), *extra)
        assert result.exit_code == 0, result.output
        assert png.stat().st_size > 20_000
    result = run("solve", str(MODELS / "boom.yaml"), "--plot", str(tmp_path / "x.png"), "--frame", "nothing")
    assert result.exit_code == ExitCode.USAGE and "no body 'nothing'" in result.output


def test_a_solve_of_a_fresh_module_imports_neither_the_generator_nor_scipys_linear_algebra():
    """`kinegen solve` of a model whose module is fresh, solved in C: the code generator (SymPy's
    printers), SciPy's linear algebra and sparse graphs stay unimported (~0.7 s of a command's
    start-up); the model comes from kinegen's cache when read before (kinegen.model.kept)."""
    import subprocess
    import sys

    from tests.conftest import ROOT

    script = (
        "import sys; from kinegen.cli import main\n"
        "try:\n    main(['solve', 'models/excavator.yaml', '--case', 'bucket_near_toggle'], standalone_mode=False)\n"
        "finally:\n    print('IMPORTED', *sorted(m for m in sys.modules if m.startswith(('kinegen.codegen.', 'scipy.'))))\n"
    )
    for _ in range(2):  # the second run reads the model kept by the first
        done = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr[-2000:]
        assert "9 of 9 time points" in done.stdout, done.stdout
        imported = done.stdout.split("IMPORTED")[-1].split()
        assert not [m for m in imported if m.startswith(("scipy.linalg", "scipy.sparse", "kinegen.codegen.kernels", "kinegen.codegen.writer"))], imported
        assert "kinegen.codegen.backends.c.config" in imported  # (the runtime reads the C backend's settings only)
