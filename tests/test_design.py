"""Design parameters (issue 13, part 1): the ``design:`` section keeps geometry symbolic.

* the geometry that uses a design parameter is an expression of its symbol ``p_<name>``;
* ``Model.at(values)`` is the model as if its file had been written with those numbers
  (compared with such a file, and solved against the slider-crank's closed form);
* malformed design sections and design parameters used outside the geometry name the file
  and the entry.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import sympy as sp

from kinegen import rotations
from kinegen.codegen.inmemory import lambdify_model
from kinegen.errors import ExitCode, ModelError
from kinegen.model import load, loads
from kinegen.runtime import from_module, kinematics, solve
from kinegen.runtime.sensitivity import (
    point_sensitivity,
    relative_angle_sensitivity,
    smallest_singular_value_sensitivity,
    state_sensitivities,
)
from tests.conftest import GENERATED, MODELS

PLAIN = (MODELS / "slider_crank.yaml").read_text()
PARAMETERS = "parameters:\n  r: 0.2    # crank A-B\n  l: 0.6    # connecting rod B-C\n"
DESIGN = "design:\n  r: {nominal: 0.2, bounds: [0.15, 0.25], description: crank}\n  l: {nominal: 0.6, bounds: [0.5, 0.7]}\n"


def design_model(design: str = DESIGN, extra: str = "") -> str:
    assert PARAMETERS in PLAIN
    return PLAIN.replace(PARAMETERS, design + extra)


def written_with(crank: str, rod: str) -> str:
    return PLAIN.replace(PARAMETERS, f"parameters:\n  r: {crank}\n  l: {rod}\n")


def same_model(a, b) -> bool:
    """Equal up to the file they were read from."""
    return a.__class__(**{**a.__dict__, "file": b.file, "source_sha256": b.source_sha256}) == b


def test_design_parameters_stay_symbols_in_the_geometry():
    model = loads(design_model(), "slider_crank_design.yaml")
    crank, rod = (d.symbol for d in model.design)
    assert [(d.name, d.nominal, d.lower, d.upper) for d in model.design] == [
        ("r", sp.Rational(1, 5), sp.Rational(3, 20), sp.Rational(1, 4)),
        ("l", sp.Rational(3, 5), sp.Rational(1, 2), sp.Rational(7, 10)),
    ]
    assert model.body("crank").points["B"] == sp.ImmutableMatrix([crank, 0, 0])
    assert model.body("rod").points["C"] == sp.ImmutableMatrix([rod, 0, 0])
    assert model.design[0].description == "crank"


def test_a_model_at_given_values_is_the_model_written_with_them():
    model = loads(design_model(), "slider_crank_design.yaml")
    assert same_model(model.at(), load(MODELS / "slider_crank.yaml"))  # nominal
    assert same_model(model.at({"r": 0.21, "l": 0.65}), loads(written_with("0.21", "0.65"), "x.yaml"))
    assert same_model(model.at({"l": 0.55}), loads(written_with("0.2", "0.55"), "x.yaml"))
    with pytest.raises(KeyError, match="not design parameters of slider_crank: q"):
        model.at({"q": 1.0})


def test_a_model_at_other_values_solves_to_the_closed_form():
    """The slider at x = r cos θ + sqrt(l² − r² sin² θ) with r = 0.21, l = 0.65 (not the nominal)."""
    model = loads(design_model(), "slider_crank_design.yaml").at({"r": 0.21, "l": 0.65})
    results = solve(from_module(lambdify_model(model, rotations.get("quaternion")), "run"))
    t = results.times
    theta = 0.3 + 2 * np.pi * t + 0.5 * t**2
    x = 0.21 * np.cos(theta) + np.sqrt(0.65**2 - 0.21**2 * np.sin(theta) ** 2)
    assert np.abs(kinematics.point_position(results, "slider", "C")[:, 0] - x).max() < 1e-10


@pytest.mark.parametrize(
    ("design", "extra", "entry", "problem"),
    [
        ("design:\n  r: {nominal: 0.3, bounds: [0.15, 0.25]}\n  l: 0.6\n", "", "design.r.nominal", "outside the bounds"),
        ("design:\n  r: {nominal: 0.2, bounds: [0.25, 0.15]}\n", "parameters:\n  l: 0.6\n", "design.r.bounds", "not below"),
        ("design:\n  r: {nominal: 0.2, bounds: 0.25}\n", "parameters:\n  l: 0.6\n", "design.r.bounds", "expected [low, high]"),
        ("design:\n  r: {nominal: 0.2}\n", "parameters:\n  l: 0.6\n", "design.r", "missing required key 'bounds'"),
        ("design:\n  r: {nominal: 0.2, bounds: [0, 1], unit: m}\n", "parameters:\n  l: 0.6\n", "design.r.unit", "unknown key"),
        (DESIGN, "parameters:\n  r: 0.3\n", "parameters.r", "already a design parameter"),
    ],
)
def test_a_malformed_design_section_names_the_entry(design, extra, entry, problem):
    with pytest.raises(ModelError) as error:
        loads(design_model(design, extra), "bad.yaml")
    assert error.value.file == "bad.yaml" and error.value.entry == entry and problem in error.value.problem


def test_design_parameters_are_geometry_only():
    text = design_model().replace("function: 0.3 + 2*pi*t + 0.5*t**2", "function: 0.3 + 2*pi*t + r*t**2")
    with pytest.raises(ModelError) as error:
        loads(text, "bad.yaml")
    assert error.value.entry == "cases.run.drivers.crank_angle.function"
    assert "uses design parameter(s) r" in error.value.problem and "geometry" in error.value.problem
    with pytest.raises(ModelError, match="'p' names the design parameters' symbols"):
        loads(design_model().replace("\n  crank:\n", "\n  p:\n").replace("[ground, crank]", "[ground, p]").replace("[crank, rod]", "[p, rod]"), "bad.yaml")


def _slider_x(crank: float, rod: float, t: np.ndarray) -> np.ndarray:
    theta = 0.3 + 2 * np.pi * t + 0.5 * t**2
    return crank * np.cos(theta) + np.sqrt(rod**2 - crank**2 * np.sin(theta) ** 2)


@pytest.mark.parametrize(("param", "compiled"), [("quaternion", False), ("quaternion", True), ("euler-parameters", True), ("dual-quaternion", False)])
def test_one_generated_module_solves_any_design_without_a_rebuild(tmp_path, param, compiled):
    """The module takes p (its Python functions, or its C compiled with kinegen's C solver): at
    the nominal and at two other designs the slider follows the closed form, and every named
    point agrees with the model rebuilt at those numbers."""
    from kinegen.codegen import generate, write_files
    from kinegen.runtime import load_module

    model = loads(design_model(), "slider_crank_design.yaml")
    made = generate(model, rotations.get(param))
    write_files(tmp_path, {file: text for files in made.values() for file, text in files.items()})
    module = load_module(tmp_path / next(iter(made["python"])))
    assert module.DESIGN == {"r": (0.2, 0.15, 0.25), "l": (0.6, 0.5, 0.7)}
    assert all(slots[-1] == "p" for kernel, (slots, _) in module.KERNELS.items() if kernel not in ("inputs", "input_ranges", "frames", "frames_d"))
    for values in ({}, {"r": 0.21, "l": 0.65}, {"r": 0.16}):
        system = from_module(module, "run", compiled=compiled, design=values)
        assert (system.native is not None) == compiled
        results = solve(system)
        crank, rod = values.get("r", 0.2), values.get("l", 0.6)
        assert system.design == {"r": crank, "l": rod}
        assert np.abs(kinematics.point_position(results, "slider", "C")[:, 0] - _slider_x(crank, rod, results.times)).max() < 1e-10
        rebuilt = solve(from_module(lambdify_model(model.at(values), rotations.get(param)), "run"))
        for body, point in (("crank", "B"), ("rod", "C"), ("slider", "C")):
            assert np.abs(kinematics.point_position(results, body, point) - kinematics.point_position(rebuilt, body, point)).max() < 1e-12


def test_design_values_are_checked_against_the_module():
    from kinegen.codegen import generate
    from kinegen.runtime.system import module_from_source

    model = loads(design_model(), "slider_crank_design.yaml")
    module = module_from_source(generate(model, rotations.get("quaternion"), ("python",))["python"]["slider_crank_quaternion.py"])
    with pytest.raises(ValueError, match=r"design parameter r = 0.3 is outside its bounds \[0.15, 0.25\]"):
        from_module(module, "run", design={"r": 0.3})
    with pytest.raises(KeyError, match="not design parameters of 'slider_crank': s"):
        from_module(module, "run", design={"s": 0.3})
    plain = module_from_source(generate(load(MODELS / "slider_crank.yaml"), rotations.get("quaternion"), ("python",))["python"]["slider_crank_quaternion.py"])
    with pytest.raises(KeyError, match="has no design parameters"):
        from_module(plain, "run", design={"r": 0.2})


def test_in_memory_lambdify_asks_for_numbers():
    with pytest.raises(ModelError, match=r"lambdify_model takes numbers: use model.at\(values\)"):
        lambdify_model(loads(design_model(), "slider_crank_design.yaml"), rotations.get("quaternion"))


@pytest.mark.parametrize("sensitivities", [True, False])
def test_the_c_of_a_design_model_compiles_strictly(tmp_path, sensitivities):
    """The model's C with the kernels taking p and its kinegen_design (with the sensitivity
    kernels, or built without them), and the solver, with the machine's cc: C99, every warning
    an error."""
    import shutil
    import subprocess

    from kinegen.codegen import generate
    from kinegen.runtime.native import with_solver

    compiler = shutil.which("cc")
    if compiler is None:
        pytest.skip("no C compiler (cc) on this machine")
    model = loads(design_model(), "slider_crank_design.yaml")
    files = with_solver(generate(model, rotations.get("quaternion"), ("c-model",), sensitivities=sensitivities)["c-model"])
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    for name in (n for n in files if n.endswith(".c")):
        flags = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-c", "-o", str(tmp_path / f"{name}.o")]
        done = subprocess.run([compiler, *flags, str(tmp_path / name)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    # one case type, design parameters or not: the case's model points to its design
    assert "const kinegen_model slider_crank_quaternion_run = {" in files["slider_crank_quaternion.c"]
    assert "&design_run," in files["slider_crank_quaternion.c"]
    assert ("dacc_run(" in files["slider_crank_quaternion.c"]) == sensitivities
    assert f"sensitivities:   {'yes' if sensitivities else 'no'}" in files["slider_crank_quaternion.h"]


@pytest.mark.parametrize("compiled", [False, True])
def test_a_module_built_without_sensitivity_kernels_solves_designs_and_says_what_it_lacks(tmp_path, compiled):
    """``kinegen build --no-sensitivities``: the same solutions at any design as the full module,
    its header says so, and asking it for sensitivities names the way out."""
    from kinegen.codegen import built_with_sensitivities, generate, write_files
    from kinegen.runtime import load_module

    model = loads(design_model(), "slider_crank_design.yaml")
    for folder, sensitivities in ((tmp_path / "full", True), (tmp_path / "lean", False)):
        folder.mkdir()
        made = generate(model, rotations.get("quaternion"), sensitivities=sensitivities)
        write_files(folder, {file: text for files in made.values() for file, text in files.items()})
        assert built_with_sensitivities(folder / "slider_crank_quaternion.py") is sensitivities
        assert built_with_sensitivities(folder / "slider_crank_quaternion.c") is sensitivities
    full, lean = (load_module(tmp_path / f / "slider_crank_quaternion.py") for f in ("full", "lean"))
    assert "dvel_run" in dir(full) and "dvel_run" not in dir(lean)
    design = {"r": 0.22, "l": 0.57}
    a, b = (solve(from_module(m, "run", compiled=compiled, design=design)) for m in (full, lean))
    assert np.abs(a.q - b.q).max() == 0.0
    with pytest.raises(ValueError, match=r"has no sensitivity kernels .*--no-sensitivities.*rebuild it"):
        point_sensitivity(b, "slider", "C", parameter="r")
    assert built_with_sensitivities(MODELS / "slider_crank.yaml") is None


def test_the_standalone_c_of_a_design_model_matches_python_at_the_nominal(tmp_path):
    """``kinegen build --target c``: the controller's C solves the nominal design (its solver's
    kinegen_set_design takes others), every row as the Python runtime's."""
    from tests.test_c_target import _compare, _compile, _standalone

    model = tmp_path / "slider_crank_design.yaml"
    model.write_text(design_model())
    folder = _standalone(tmp_path, model, "quaternion")
    program = _compile(folder, "slider_crank_quaternion", ["-O2"])
    from kinegen.codegen import generate
    from kinegen.runtime.system import module_from_source

    text = generate(loads(design_model(), str(model)), rotations.get("quaternion"), ("python",))["python"]["slider_crank_quaternion.py"]
    _compare(program, from_module(module_from_source(text), "run", compiled=False), "run")


def _design_module(tmp_path, text: str, param: str = "quaternion", name: str = "design.yaml"):
    from kinegen.codegen import generate, write_files
    from kinegen.runtime import load_module

    made = generate(loads(text, name), rotations.get(param))
    write_files(tmp_path, {file: content for files in made.values() for file, content in files.items()})
    return load_module(tmp_path / next(iter(made["python"])))


@pytest.mark.parametrize(("param", "compiled"), [("quaternion", True), ("euler-parameters", False), ("dual-quaternion", True)])
def test_slider_sensitivities_are_the_closed_form_derivatives(tmp_path, param, compiled):
    """x = r cos θ + sqrt(l² − r² sin² θ): dx/dr = cos θ − r sin² θ / w, dx/dl = l / w with
    w = sqrt(l² − r² sin² θ), at r = 0.21, l = 0.65, to 1e-10."""
    module = _design_module(tmp_path, design_model(), param)
    results = solve(from_module(module, "run", compiled=compiled, design={"r": 0.21, "l": 0.65}))
    t = results.times
    theta = 0.3 + 2 * np.pi * t + 0.5 * t**2
    w = np.sqrt(0.65**2 - 0.21**2 * np.sin(theta) ** 2)
    by_r, by_l = point_sensitivity(results, "slider", "C", parameter="r"), point_sensitivity(results, "slider", "C", parameter="l")
    assert np.abs(by_r[:, 0] - (np.cos(theta) - 0.21 * np.sin(theta) ** 2 / w)).max() < 1e-10
    assert np.abs(by_l[:, 0] - 0.65 / w).max() < 1e-10
    assert np.abs(by_r[:, 1:]).max() < 1e-12 and np.abs(by_l[:, 1:]).max() < 1e-12
    # the crank pin B = r (cos θ, sin θ): d/dr = (cos θ, sin θ) whatever the rod
    assert np.abs(point_sensitivity(results, "crank", "B", parameter="r")[:, :2] - np.c_[np.cos(theta), np.sin(theta)]).max() < 1e-10
    assert np.abs(point_sensitivity(results, "crank", "B", parameter="l")).max() < 1e-12


@pytest.mark.parametrize("compiled", [True, False])
def test_a_run_stopped_early_has_nan_sensitivities_at_its_failed_point_and_the_full_runs_elsewhere(tmp_path, compiled):
    """The point a run could not solve (converged False, q, v, a NaN, as ``on_failure="stop"`` leaves it)
    gets NaN sensitivities; every other point the same as when all converged (C: the same bits, one
    time point at a time; Python: batches of points, to 1e-12)."""
    module = _design_module(tmp_path, design_model(), "quaternion")
    full = solve(from_module(module, "run", compiled=compiled, design={"r": 0.21, "l": 0.65}))
    converged = np.ones(len(full.times), dtype=bool)
    converged[-1] = False
    nan_last = {name: np.where(converged[:, None], getattr(full, name), np.nan) for name in ("q", "v", "a")}
    stopped = dataclasses.replace(full, converged=converged, **nan_last)
    for whole, part in zip(state_sensitivities(full), state_sensitivities(stopped)):
        assert whole.shape == part.shape and np.isfinite(whole).all()
        assert np.isnan(part[-1]).all()
        if compiled:
            assert np.array_equal(part[:-1], whole[:-1])
        else:
            assert np.abs(part[:-1] - whole[:-1]).max() <= 1e-12 * np.abs(whole).max()


FOUR_BAR_PARAMETERS = "parameters:\n  a: 0.3    # crank A-B\n  b: 0.9    # coupler B-C\n  c: 0.7    # rocker D-C\n  d: 1.0    # ground A-D\n"
FOUR_BAR_DESIGN = (
    "design:\n  a: {nominal: 0.3, bounds: [0.25, 0.35]}\n  b: {nominal: 0.9, bounds: [0.85, 0.95]}\n"
    "  c: {nominal: 0.7, bounds: [0.65, 0.75]}\n  d: {nominal: 1.0, bounds: [0.95, 1.05]}\n"
)


FOUR_BAR_AT = {"a": 0.31, "b": 0.88, "c": 0.72, "d": 1.01}


def _four_bar_design(tmp_path, param: str, compiled: bool = False):
    """The four-bar with its four lengths as design parameters: (model, results of its crank
    turn solved at FOUR_BAR_AT from the generated module)."""
    plain = (MODELS / "four_bar.yaml").read_text()
    assert FOUR_BAR_PARAMETERS in plain
    text = plain.replace(FOUR_BAR_PARAMETERS, FOUR_BAR_DESIGN)
    module = _design_module(tmp_path, text, param, "four_bar_design.yaml")
    return loads(text, "four_bar_design.yaml"), solve(from_module(module, "crank_turn", compiled=compiled, design=FOUR_BAR_AT))


def test_four_bar_sensitivities_match_central_differences_of_rebuilt_models(tmp_path):
    """Every design parameter (the ground pivot D among them), the positions, velocities and
    accelerations of the coupler point M and the rocker pin C over a crank turn: against
    central differences (h = 1e-5) of the model rebuilt at p ± h (a different code path:
    numbers in the model, lambdified), to 1e-7 of the largest derivative (measured: 1e-10
    to 8e-10; with h = 1e-4 the differences move away as h², 1e-8 to 5e-8)."""
    model, results = _four_bar_design(tmp_path, "quaternion", compiled=True)
    at = FOUR_BAR_AT
    h = 1e-5
    for name in at:
        shifted = []
        for sign in (1, -1):
            values = dict(at, **{name: at[name] + sign * h})
            rebuilt = solve(from_module(lambdify_model(model.at(values), rotations.get("quaternion")), "crank_turn"))
            shifted.append({
                (b, p, kind): getattr(kinematics, f"point_{kind}")(rebuilt, b, p)
                for b, p in (("coupler", "M"), ("rocker", "C")) for kind in ("position", "velocity", "acceleration")
            })  # fmt: skip
        for body, point, kind in shifted[0]:
            exact = point_sensitivity(results, body, point, parameter=name, kind=kind)
            central = (shifted[0][body, point, kind] - shifted[1][body, point, kind]) / (2 * h)
            assert np.abs(exact - central).max() < 1e-7 * np.abs(exact).max(), (name, body, point, kind)


def test_the_cli_solves_a_design_and_writes_its_sensitivities(tmp_path):
    import csv

    from click.testing import CliRunner

    from kinegen.cli import main

    model = tmp_path / "slider_crank_design.yaml"
    model.write_text(design_model())
    out = tmp_path / "sensitivities.csv"
    arguments = ["solve", str(model), "--design", "r=0.21", "--sensitivities", str(out), "--generated-dir", str(tmp_path / "g")]
    result = CliRunner().invoke(main, arguments)
    assert result.exit_code == 0, result.output
    assert "design: r = 0.21, l = 0.6" in result.output
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    theta = 0.3
    w = np.sqrt(0.6**2 - 0.21**2 * np.sin(theta) ** 2)
    assert abs(float(rows[0]["d(slider.C_x)/d(r)"]) - (np.cos(theta) - 0.21 * np.sin(theta) ** 2 / w)) < 1e-10
    assert abs(float(rows[0]["d(slider.C_x)/d(l)"]) - 0.6 / w) < 1e-10
    as_json = tmp_path / "sensitivities.json"
    result = CliRunner().invoke(main, [*arguments[:4], "--sensitivities", str(as_json), *arguments[6:]])
    assert result.exit_code == 0, result.output
    import json

    document = json.loads(as_json.read_text())
    assert document["design"] == {"r": 0.21, "l": 0.6} and document["case"] == "run"
    assert document["columns"]["d(slider.C_x)/d(l)"][0] == float(rows[0]["d(slider.C_x)/d(l)"])
    result = CliRunner().invoke(main, [*arguments[:2], "--design", "r=0.3", *arguments[4:]])
    assert result.exit_code == ExitCode.USAGE and "outside its bounds" in result.output


@pytest.mark.parametrize(("param", "compiled"), [("quaternion", True), ("euler-parameters", False), ("dual-quaternion", False)])
def test_slider_velocity_and_acceleration_sensitivities_are_the_closed_form_derivatives(tmp_path, param, compiled):
    """d/dr and d/dl of the slider's velocity and acceleration (the closed form x(t; r, l)
    differentiated by SymPy, in t and then in the parameter), at r = 0.21, l = 0.65."""
    t, r, rod = sp.symbols("t r l", real=True)
    theta = sp.Rational(3, 10) + 2 * sp.pi * t + t**2 / 2
    x = r * sp.cos(theta) + sp.sqrt(rod**2 - r**2 * sp.sin(theta) ** 2)
    module = _design_module(tmp_path, design_model(), param)
    results = solve(from_module(module, "run", compiled=compiled, design={"r": 0.21, "l": 0.65}))
    for kind, order, tolerance in (("position", 0, 1e-10), ("velocity", 1, 1e-9), ("acceleration", 2, 1e-8)):
        for name, symbol in (("r", r), ("l", rod)):
            exact = sp.lambdify(t, sp.diff(x, t, order).diff(symbol).subs({r: 0.21, rod: 0.65}))(results.times)
            computed = point_sensitivity(results, "slider", "C", parameter=name, kind=kind)
            assert np.abs(computed[:, 0] - exact).max() < tolerance * max(1.0, np.abs(exact).max()), (kind, name)
            assert np.abs(computed[:, 1:]).max() < tolerance, (kind, name)


def test_excavator_sensitivities_match_central_differences_of_rebuilt_models():
    """The shipped excavator's module, two of its design parameters (the boom-cylinder rod pin's x
    on the boom, the side link's length), away from the nominal design, over the digging cycle
    (with its swing: rotations about more than one axis) on 69 time points: the bucket tip's
    position, velocity and acceleration sensitivities against central differences (h = 1e-5) of
    the model rebuilt at p ± h, to 1e-7 of the largest (measured ~1e-9). Compiled."""
    from kinegen.codegen import generate
    from kinegen.runtime import load_module
    from kinegen.runtime.system import module_from_source

    model = load(MODELS / "excavator.yaml")
    module = load_module(GENERATED / "excavator_quaternion.py", MODELS / "excavator.yaml")
    times = np.linspace(0.0, 17.0, 69)
    at = {"C_x": 1.40, "side_link": 0.59}
    results = solve(from_module(module, "digging", compiled=True, design=at), times)
    h = 1e-5
    for name in at:
        shifted = []
        for sign in (1, -1):
            rebuilt_model = model.at(dict(at, **{name: at[name] + sign * h}))
            source = generate(rebuilt_model, rotations.get("quaternion"), ("python",))["python"]["excavator_quaternion.py"]
            rebuilt = solve(from_module(module_from_source(source), "digging", compiled=False), times)
            shifted.append({kind: getattr(kinematics, f"point_{kind}")(rebuilt, "bucket", "T") for kind in ("position", "velocity", "acceleration")})
        for kind in shifted[0]:
            exact = point_sensitivity(results, "bucket", "T", parameter=name, kind=kind)
            central = (shifted[0][kind] - shifted[1][kind]) / (2 * h)
            assert np.abs(exact - central).max() < 1e-7 * np.abs(exact).max(), (name, kind)


def test_global_points_stay_expressions_of_the_design_parameters(tmp_path):
    """The crank pin given in global coordinates at the initial pose (r (cos 0.3, sin 0.3, 0)):
    its body coordinates are an expression of r, and the slider's sensitivities are still the
    closed form's."""
    text = design_model().replace("    points: {A: [0, 0, 0], B: [r, 0, 0]}", "    points: {A: [0, 0, 0]}\n    global_points: {B: [r*cos(0.3), r*sin(0.3), 0]}")
    model = loads(text, "slider_crank_global.yaml")
    local = model.body("crank").points["B"]
    r = model.design[0].symbol
    assert local.free_symbols == {r}
    assert abs(float(local[0].subs(r, 0.21)) - 0.21) < 1e-15 and abs(float(local[1].subs(r, 0.21))) < 1e-15
    module = _design_module(tmp_path, text)
    results = solve(from_module(module, "run", design={"r": 0.21, "l": 0.65}))
    theta = 0.3 + 2 * np.pi * results.times + 0.5 * results.times**2
    w = np.sqrt(0.65**2 - 0.21**2 * np.sin(theta) ** 2)
    assert np.abs(point_sensitivity(results, "slider", "C", parameter="r")[:, 0] - (np.cos(theta) - 0.21 * np.sin(theta) ** 2 / w)).max() < 1e-10


def test_joint_angle_sensitivities_match_central_differences(tmp_path):
    """The four-bar's rocker angle (about the ground pivot's z) and the coupler's angle relative
    to the crank (about the crank's z): exact derivatives by each length against central
    differences (h = 1e-5) of the angles of rebuilt models, to 1e-7 of the largest."""
    model, results = _four_bar_design(tmp_path, "euler-parameters")
    at = FOUR_BAR_AT

    def angles(r):
        rocker, crank, coupler = (kinematics.rotation_matrix(r, b) for b in ("rocker", "crank", "coupler"))
        relative = np.swapaxes(crank, 1, 2) @ coupler
        return np.unwrap(np.arctan2(rocker[:, 1, 0], rocker[:, 0, 0])), np.unwrap(np.arctan2(relative[:, 1, 0], relative[:, 0, 0]))

    h = 1e-5
    for name in at:
        plus, minus = (
            angles(solve(from_module(lambdify_model(model.at(dict(at, **{name: at[name] + sign * h})), rotations.get("quaternion")), "crank_turn")))
            for sign in (1, -1)
        )
        exact = (relative_angle_sensitivity(results, "ground", "rocker", (0, 0, 1), parameter=name),
                 relative_angle_sensitivity(results, "crank", "coupler", (0, 0, 1), parameter=name))  # fmt: skip
        for e, p_, m_ in zip(exact, plus, minus):
            central = (p_ - m_) / (2 * h)
            assert np.abs(e - central).max() < 1e-7 * np.abs(e).max(), name


def test_the_distance_to_a_singular_pose_has_exact_sensitivities(tmp_path):
    """σ_min of the four-bar's Φ_q over a crank turn and its derivative by each length: against
    central differences of σ_min of models rebuilt at p ± 1e-5 (to 1e-6 of the largest)."""
    model, results = _four_bar_design(tmp_path, "quaternion")
    at = FOUR_BAR_AT
    sigma, _ = smallest_singular_value_sensitivity(results)
    assert 0 < np.nanmin(sigma) and np.isfinite(sigma).all()

    def smallest(r):
        system = r.system
        jacobian = np.zeros((len(r.times), len(system.constraint_names), system.n_velocity))
        jacobian[:, system.jac_rows, system.jac_cols] = np.asarray(system.jac(r.q.T, r.inputs.T)).T
        return np.linalg.svd(jacobian, compute_uv=False)[:, -1]

    h = 1e-5
    for name in at:
        plus, minus = (
            smallest(solve(from_module(lambdify_model(model.at(dict(at, **{name: at[name] + sign * h})), rotations.get("quaternion")), "crank_turn")))
            for sign in (1, -1)
        )
        _, exact = smallest_singular_value_sensitivity(results, parameter=name)
        central = (plus - minus) / (2 * h)
        assert np.abs(exact - central).max() < 1e-6 * np.abs(exact).max(), (name, np.abs(exact - central).max() / np.abs(exact).max())


def test_actuator_ranges_and_working_range_inputs_may_use_design_parameters(tmp_path):
    """A cylinder's retracted length is a design figure too: an actuator range and a working-range
    input range written with a design parameter stay expressions of it; the generated module gives
    the range at any design (so range reports follow it), the working range's inputs are numbers
    at the design asked for, and model.at() is the model written with that number."""
    stroke = (
        "actuators:\n  stroke: {points: [ground.A, slider.C], range: [s_min, 0.79]}\n"
        "working_range:\n  case: run\n  point: rod.C\n  inputs: {crank_angle: [0, 2*s_min]}\n"
    )
    text = design_model(DESIGN.replace("design:\n", "design:\n  s_min: {nominal: 0.45, bounds: [0.40, 0.50]}\n")) + stroke
    model = loads(text, "slider_crank_design.yaml")
    s_min = model.design[0].symbol
    assert model.actuators[0].range == (s_min, sp.Rational(79, 100))
    assert model.actuators[0].limits({"s_min": 0.42}) == (0.42, 0.79)
    assert model.working_range.numbers({"s_min": 0.42, "r": 0.2, "l": 0.6}) == {"crank_angle": (0.0, 0.84)}
    with pytest.raises(KeyError, match=r"no value given for design parameter.* s_min"):
        model.working_range.numbers({})
    assert model.at({"s_min": 0.42}).actuators[0].range == (sp.Rational(21, 50), sp.Rational(79, 100))
    module = _design_module(tmp_path, text)
    for value in (0.45, 0.48):
        results = solve(from_module(module, "run", design={"s_min": value}))
        assert results.system.actuators["stroke"][2] == pytest.approx((value, 0.79), abs=1e-15)
        length = kinematics.actuator_length(results, "stroke")  # x = r cos θ + sqrt(l² − r² sin² θ): 0.4 .. 0.8
        expected = sorted({(float(t), "stroke", float(x)) for t, x in zip(results.times, length) if not value <= x <= 0.79})
        assert [(t, n, x) for t, n, x, _ in kinematics.range_violations(results)] == expected and expected
    with pytest.raises(ModelError) as error:
        loads(text.replace("range: [s_min, 0.79]", "range: [s_min, 0.3]"), "bad.yaml")
    assert error.value.entry == "actuators.stroke.range" and "min < max" in error.value.problem


@pytest.mark.parametrize("compiled", [False, True])
def test_configuration_sensitivities_by_inputs_and_design_are_the_closed_form(tmp_path, compiled):
    """At solved configurations (not a trajectory): the slider x = r cos θ + sqrt(l² − r² sin² θ)
    differentiated by the crank angle θ (a driver input) and by r and l, to 1e-10."""
    from kinegen.runtime.sensitivity import point_position_sensitivities

    module = _design_module(tmp_path, design_model())
    system = from_module(module, "run", compiled=compiled, design={"r": 0.21, "l": 0.65})
    results = solve(system)
    pick = slice(None, None, 30)
    q, u = results.q[pick].T, results.inputs[pick].T
    theta = u[0]
    w = np.sqrt(0.65**2 - 0.21**2 * np.sin(theta) ** 2)
    positions, by_design, by_input = point_position_sensitivities(system, q, u, [("slider", "C"), ("crank", "B")])
    assert np.abs(positions[:, 0, 0] - (0.21 * np.cos(theta) + w)).max() < 1e-10
    dx_dtheta = -0.21 * np.sin(theta) - 0.21**2 * np.sin(theta) * np.cos(theta) / w
    assert np.abs(by_input[:, 0, 0, 0] - dx_dtheta).max() < 1e-10
    assert np.abs(by_design[:, 0, 0, 0] - (np.cos(theta) - 0.21 * np.sin(theta) ** 2 / w)).max() < 1e-10
    assert np.abs(by_design[:, 0, 0, 1] - 0.65 / w).max() < 1e-10
    # the crank pin B = r (cos θ, sin θ, 0)
    assert np.abs(by_input[:, 1, :2, 0] - 0.21 * np.c_[-np.sin(theta), np.cos(theta)]).max() < 1e-12
    assert np.abs(by_design[:, 1, :2, 0] - np.c_[np.cos(theta), np.sin(theta)]).max() < 1e-12
    # one configuration, inputs only (any module: the envelope's refinement uses it)
    one = point_position_sensitivities(system, q[:, :1], u[:, :1], [("slider", "C")], design=False)
    assert one[1] is None and abs(one[2][0, 0, 0, 0] - dx_dtheta[0]) < 1e-10


def test_the_critical_blocks_distance_to_the_toggle_has_exact_sensitivities():
    """The bucket linkage over the bucket cylinder's stroke (excavator, bucket_stroke), away from
    the nominal design: at every time point the smallest σ_min of the diagonal blocks of Φ_q that
    hold the linkage's bodies, and its derivative by the side-link length and the pin K, against
    central differences (h = 1e-6) of the same σ on excavators rebuilt at p ± h (SVD of their
    blocks of Φ_q). Measured: 3e-9 (side link) and 9e-10 (K_x) of the largest derivative."""
    from kinegen.codegen import generate
    from kinegen.runtime import load_module
    from kinegen.runtime.sensitivity import body_blocks
    from kinegen.runtime.system import module_from_source

    bodies = ("side_link", "bucket_link", "bucket")
    model = load(MODELS / "excavator.yaml")
    module = load_module(GENERATED / "excavator_quaternion.py", MODELS / "excavator.yaml")
    at = {"side_link": 0.575, "K_x": -0.31}
    times = np.linspace(0, 1, 21)
    results = solve(from_module(module, "bucket_stroke", compiled=True, design=at), times)
    sigma, derivative = smallest_singular_value_sensitivity(results, bodies=bodies)

    def critical(values: dict[str, float]) -> np.ndarray:
        rebuilt = model.at(values)
        source = generate(rebuilt, rotations.get("quaternion"), ("python",))["python"]["excavator_quaternion.py"]
        solved = solve(from_module(module_from_source(source), "bucket_stroke", compiled=False), times)
        blocks = body_blocks(solved.system, bodies)
        return np.array([min(np.linalg.svd(solved.system.jacobian(q, u)[np.ix_(r, c)], compute_uv=False)[-1] for r, c in blocks)
                         for q, u in zip(solved.q, solved.inputs)])  # fmt: skip

    assert np.abs(sigma - critical(at)).max() < 1e-12
    h = 1e-6
    for name in at:
        central = (critical(dict(at, **{name: at[name] + h})) - critical(dict(at, **{name: at[name] - h}))) / (2 * h)
        exact = derivative[:, list(results.system.design).index(name)]
        assert np.abs(exact - central).max() < 1e-7 * np.abs(exact).max(), name


def test_the_transmission_angle_and_its_sensitivities_are_the_four_bars_closed_form(tmp_path):
    """The angle μ at C between coupler (C→B) and rocker (C→D): cos μ = (b² + c² − BD²)/(2bc),
    BD² = a² + d² − 2ad cos φ (φ the crank angle), and dμ/d(a, b, c, d) at fixed φ by SymPy, at
    a = 0.31, b = 0.88, c = 0.72, d = 1.01, every time point, to 1e-10; the study quantity is the
    smallest of μ and π − μ over the crank turn."""
    from kinegen.analysis.studies import _transmission_angle
    from kinegen.model.schema import Quantity

    _, results = _four_bar_design(tmp_path, "quaternion", compiled=True)
    quantity = Quantity("transmission_angle", "crank_turn", points=(("coupler", "B"), ("coupler", "C"), ("ground", "D")))
    value, gradient, (points, derivatives) = _transmission_angle(None, results, quantity, True)
    a, b, c, d, phi = sp.symbols("a b c d phi", positive=True)
    mu = sp.acos((b**2 + c**2 - (a**2 + d**2 - 2 * a * d * sp.cos(phi))) / (2 * b * c))
    closed = sp.lambdify((a, b, c, d, phi), [mu, *(mu.diff(x) for x in (a, b, c, d))], "numpy")
    values = np.array(closed(*FOUR_BAR_AT.values(), results.inputs[:, 0]), dtype=float)  # (5, K)
    count = len(results.times)
    assert np.abs(points[:count] - values[0]).max() < 1e-10 and np.abs(points[count:] - (np.pi - values[0])).max() < 1e-10
    assert np.abs(derivatives[:count] - values[1:].T).max() < 1e-10
    assert abs(value - min(values[0].min(), np.pi - values[0].max())) < 1e-12
    assert np.array_equal(gradient, derivatives[int(np.argmin(points))])
