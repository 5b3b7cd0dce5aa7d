"""Issue 38, parts 3 and 4: the force, lift and study sections and the command line refuse bad data
in one line naming file and entry (exit 2), or a usage line (exit 64), or say what they did --
never a traceback, NaN output with exit 0 or a silently wrong chart; and a model too large for
its units says so."""

from __future__ import annotations

import copy
import shutil
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from kinegen.cli import main
from kinegen.errors import AssemblyError, ExitCode, ModelError, PrecisionError
from kinegen.model import load, loads
from kinegen.runtime import from_module, load_module
from kinegen.runtime.solver import check_initial_pose
from tests.conftest import GENERATED, MODELS

SLIDER = (MODELS / "slider_crank.yaml").read_text()
EXCAVATOR = yaml.safe_load((MODELS / "excavator.yaml").read_text())


def _one_error_line(result, *fragments: str) -> str:
    lines = [line for line in result.output.strip().splitlines() if line.strip()]
    assert "Traceback" not in result.output, result.output
    errors = [line for line in lines if line.startswith("error:")]
    assert len(errors) == 1, result.output
    for fragment in fragments:
        assert fragment in errors[0], errors[0]
    return errors[0]


@pytest.fixture(scope="module")
def slider(tmp_path_factory):
    """The slider-crank copied with extra loads (one per time function leaving its domain) and built once."""
    folder = tmp_path_factory.mktemp("slider")
    text = SLIDER.replace(
        "  gas: {point: slider.C, force: [-1000, 0, 0]}",
        "  gas: {point: slider.C, force: [-1000, 0, 0]}\n"
        '  root: {point: slider.C, force: ["-1000*sqrt(t - 20)", 0, 0]}\n'
        '  pole: {point: slider.C, force: ["1/(t - 0.75)", 0, 0]}\n'
        '  logarithm: {point: slider.C, moment: [0, 0, "log(t)"]}\n'
        '  blowup: {point: slider.C, force: ["exp(1000*t)", 0, 0]}',
    )
    model = folder / "slider_crank.yaml"
    model.write_text(text)
    result = CliRunner().invoke(main, ["build", str(model), "--generated-dir", str(folder / "generated")])
    assert result.exit_code == 0, result.output
    return model, folder / "generated"


@pytest.mark.parametrize(("load", "entry"), [("root", "loads.root.force[0]"), ("pole", "loads.pole.force[0]"),
                                            ("logarithm", "loads.logarithm.moment[2]"), ("blowup", "loads.blowup.force[0]")])  # fmt: skip
def test_a_loads_time_function_outside_its_domain_is_a_model_error(slider, load, entry):
    model, generated = slider
    result = CliRunner().invoke(main, ["solve", str(model), "--load", load, "--generated-dir", str(generated)])
    assert result.exit_code == ExitCode.MODEL
    _one_error_line(result, "slider_crank.yaml", entry, "not a finite real number at t =", "leaves its domain")


def test_the_same_load_twice_or_a_chart_twice_is_a_usage_error(slider):
    model, generated = slider
    twice = CliRunner().invoke(main, ["solve", str(model), "--load", "gas", "--load", "gas", "--generated-dir", str(generated)])
    assert twice.exit_code == ExitCode.USAGE
    _one_error_line(twice, "--load", "gas named more than once")
    both = CliRunner().invoke(main, ["forces", str(MODELS / "excavator.yaml"), "--lift", "--map", "up"])
    assert both.exit_code == ExitCode.USAGE
    _one_error_line(both, "--lift and --map")


def test_usage_errors_are_one_line(slider):
    model, generated = slider
    result = CliRunner().invoke(main, ["solve", str(model), "--steps", "abc", "--generated-dir", str(generated)])
    assert result.exit_code == ExitCode.USAGE
    line = _one_error_line(result, "--steps", "abc", "solve --help")
    assert len(result.output.strip().splitlines()) == 1, result.output
    assert line.startswith("error: ")


def test_an_output_that_cannot_be_written_is_refused_before_any_work(slider, tmp_path):
    model, generated = slider
    (tmp_path / "a-file").write_text("")
    result = CliRunner().invoke(main, ["solve", str(model), "--out", str(tmp_path / "a-file" / "x.csv"), "--generated-dir", str(generated)])
    assert result.exit_code == ExitCode.USAGE
    _one_error_line(result, "--out", "is a file, not a folder")
    assert "time points" not in result.output  # nothing solved
    if Path("/dev/full").exists():
        full = CliRunner().invoke(main, ["solve", str(model), "--out", "/dev/full", "--generated-dir", str(generated)])
        assert full.exit_code == ExitCode.IO
        _one_error_line(full, "/dev/full", "No space left")


def test_keep_going_says_the_forces_were_not_computed(tmp_path):
    """The slider driven through its dead centre stops; with --load and --keep-going the rows so far are
    written and the output says why they hold no forces."""
    model = tmp_path / "slider_crank.yaml"
    model.write_text(SLIDER)
    out = tmp_path / "rows.csv"
    result = CliRunner().invoke(main, ["solve", str(model), "--case", "dead_centre", "--load", "gas", "--keep-going", "--out", str(out),
                                       "--generated-dir", str(tmp_path / "generated")])  # fmt: skip
    assert result.exit_code != 0 and out.is_file()
    assert "forces: not computed" in result.output and "no force columns" in result.output


def _excavator_text(change) -> str:
    document = copy.deepcopy(EXCAVATOR)
    change(document)
    return yaml.safe_dump(document, sort_keys=False)


def _refused(text: str, entry: str, *fragments: str) -> None:
    with pytest.raises(ModelError) as caught:
        loads(text, "excavator.yaml")
    assert caught.value.entry == entry, caught.value
    for fragment in fragments:
        assert fragment in str(caught.value), caught.value


@pytest.mark.parametrize("value", [["bucket_cylinder"], {"name": "bucket_cylinder"}, None, 3])
def test_a_list_or_mapping_where_a_name_is_expected_is_a_model_error(value):
    def tool_actuator(d):
        d["tool_forces"]["bucket"]["actuator"] = value

    def lifting(d):
        d["lift_chart"]["lifting"] = value

    def study_load(d):
        d["studies"]["digging_force"]["constraints"].append({"cylinder_pressure": "boom_cylinder_left", "case": "digging", "load": value,
                                                             "at_most": 30})  # fmt: skip

    _refused(_excavator_text(tool_actuator), "tool_forces.bucket.actuator", "not an actuator with hydraulic data")
    _refused(_excavator_text(lifting), "lift_chart.lifting", "not an actuator with hydraulic data")
    study = EXCAVATOR["studies"]["digging_force"]
    _refused(_excavator_text(study_load), f"studies.digging_force.constraints[{len(study.get('constraints', []))}].load",
             "holds one of the model's loads")  # fmt: skip


def test_a_pivot_on_the_ground_an_input_placed_twice_and_another_gravity_are_refused():
    def pivot(d):
        d["tool_forces"]["bucket"]["pivot"] = "ground.O"

    def twice(d):
        d["lift_chart"]["place"] = [d["lift_chart"]["place"][0]] * 2

    def gravity(d):
        d["gravity"] = [0, 0, -9.7]

    _refused(_excavator_text(pivot), "tool_forces.bucket.pivot", "a point of a moving body")
    _refused(_excavator_text(twice), "lift_chart.place", "named twice")
    _refused(_excavator_text(gravity), "gravity", "standard gravity")


def test_a_machine_that_tips_unloaded_says_so_in_the_table():
    from kinegen.forces.lift import TIPS, UNREACHED, lift_chart

    def forward(d):  # the undercarriage's 7.3 t centred 6 m ahead of the swing axis, beyond the front tipping line
        d["machine"]["undercarriage"]["center_of_mass"] = [6.0, 0.0, 0.5]

    text = _excavator_text(forward)
    model = loads(text, "excavator.yaml")
    module = load_module(GENERATED / "excavator_quaternion.py", MODELS / "excavator.yaml")
    chart = lift_chart(from_module(module, model.lift_chart.case), model)
    table = chart.table()
    assert "tips" in table and TIPS in table
    assert ("-" in table.split("\n", 3)[3]) == (UNREACHED in table)


def test_a_model_too_large_for_its_units_says_so(tmp_path):
    """A 10^12 m boom: 1e-10 absolute is below the coordinates' rounding there (2e-4 m)."""
    model = tmp_path / "boom.yaml"
    model.write_text((MODELS / "boom.yaml").read_text().replace("  L: 1.78 ", "  L: 999999999999.0 "))
    from kinegen.codegen.inmemory import lambdify_model
    from kinegen.rotations import get

    system = from_module(lambdify_model(load(model), get("quaternion")), "swing", compiled=False)
    with pytest.raises(AssemblyError) as caught:  # the assembly's cause, in its words
        check_initial_pose(system)
    assert isinstance(caught.value.__cause__, PrecisionError) and caught.value.exit_code == ExitCode.NO_CONVERGENCE
    assert "rounding the coordinates alone" in str(caught.value) and "larger units" in str(caught.value)
    shutil.rmtree(tmp_path, ignore_errors=True)
