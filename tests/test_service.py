"""The work behind ``kinegen solve`` and ``kinegen cycle`` (:mod:`kinegen.service`) used as a
library: a request the model cannot answer is refused before anything is solved, naming the
command line's option; a report holds the same motion, forces and flows as the library's own
calls on the same case."""

from __future__ import annotations

import numpy as np
import pytest

from kinegen.api import Session
from kinegen.errors import RequestError
from kinegen.forces import forces
from kinegen.forces.supply import flows
from kinegen.runtime import SolverOptions
from kinegen.service import solve as solving
from tests.conftest import GENERATED, MODELS

EXCAVATOR = MODELS / "excavator.yaml"


@pytest.fixture(scope="module")
def session():
    return Session(GENERATED)


@pytest.mark.parametrize(
    ("request_", "option", "says"),
    [
        ({"loads": ("gravel",)}, "--load", "no load 'gravel' (loads: payload, cutting)"),
        ({"loads": ("payload", "payload")}, "--load", "payload named more than once"),
        ({"weight": False}, "--no-weight", "goes with --load"),
        ({"weight": False, "dynamics": True}, "--no-weight", "--dynamics holds the weight with the inertia"),
        ({"case": "nowhere"}, "--case", "has no case 'nowhere'"),
        ({"design": {"counterweight": 1e9}}, "--design", "outside its bounds"),
        ({"steps": 10**12}, "--steps", "GiB of results"),
    ],
)
def test_a_request_the_model_cannot_answer_is_refused_naming_its_option(session, request_, option, says):
    request = {"compiled": False, **request_}
    case = request.pop("case", "digging")
    with pytest.raises(RequestError) as refused:
        solving.plan(session, EXCAVATOR, case, "quaternion", **request)
    assert refused.value.option == option and says in refused.value.problem
    assert refused.value.exit_code == 64


def test_a_report_holds_what_the_library_computes_on_the_same_case(session):
    plan = solving.plan(session, EXCAVATOR, "digging", "quaternion", steps=101, loads=("payload",), compiled=False)
    assert plan.times.tolist() == np.linspace(plan.system.t0, plan.system.t1, 101).tolist()
    report = solving.run(plan)
    direct = session.solve(EXCAVATOR, "digging", "quaternion", plan.times, SolverOptions(compiled=False))
    assert np.array_equal(report.results.q, direct.q) and np.array_equal(report.results.a, direct.a)
    model = session.model(EXCAVATOR)
    held = forces(direct, model, ("payload",), inertia=False, weight=bool(model.massive))
    names, values = held.table()
    assert report.held.table()[0] == names and np.array_equal(report.held.table()[1], values)
    supplied = flows(direct, model, held)
    assert np.array_equal(report.supplied.table()[1], supplied.table()[1])
    assert not report.forces_missed and report.elapsed > 0


def test_a_cycle_request_is_checked_and_its_report_is_the_library_s_own_retiming(session):
    from kinegen.forces.cycle import fastest, shares
    from kinegen.service import cycle

    with pytest.raises(RequestError) as refused:
        cycle.plan(session, EXCAVATOR, "digging", "quaternion", speed_limits={"boom_cylinder_left": 0.0}, compiled=False)
    assert refused.value.option == "--max-speed" and "a speed > 0" in refused.value.problem
    with pytest.raises(RequestError, match="payload named more than once"):
        cycle.plan(session, EXCAVATOR, "digging", "quaternion", loads=("payload", "payload"), compiled=False)
    plan = cycle.plan(session, EXCAVATOR, "digging", "quaternion", steps=201, compiled=False)
    report = cycle.run(plan)
    path = session.solve(EXCAVATOR, "digging", "quaternion", plan.times, SolverOptions(compiled=False))
    found = fastest(path, plan.model, ())
    assert np.array_equal(report.found.times, found.times) and report.share == shares(found)
    assert report.held == ["the machine's weight and inertia"]


def test_an_envelope_request_is_checked_and_its_report_is_the_library_s_own_range(session):
    from kinegen.analysis.envelope import working_range
    from kinegen.service import envelope

    for counts, says in (((5, 5), "2 count(s) for the 3 swept input(s)"), ((5, 1, 5), "at least 2 samples"),
                         ((100, 100, 101), "100,100,101 is 1,010,000 samples; at most 1,000,000")):  # fmt: skip
        with pytest.raises(RequestError) as refused:
            envelope.plan(session, EXCAVATOR, "quaternion", counts)
        assert refused.value.option == "--grid" and says in refused.value.problem
    plan = envelope.plan(session, EXCAVATOR, "quaternion", (5, 4, 5))
    report = envelope.run(plan)
    direct = working_range(plan.system, plan.model.working_range, (5, 4, 5))
    assert report.result.figures == direct.figures and report.boundary is None
    assert report.document()["figures"] == direct.figures and len(report.sensitivities) == len(direct.figures)
    quiet = envelope.run(envelope.plan(session, EXCAVATOR, "quaternion", (5, 4, 5), sensitivities=False))  # the main job's
    assert quiet.result.figures == direct.figures and quiet.sensitivities == {} and "sensitivities" not in quiet.document()


def test_an_inspection_request_is_checked_before_any_exact_work(session):
    from kinegen.service import inspection

    four_bar = MODELS / "four_bar.yaml"
    for request, option, says in (({"at": "99"}, "--at", "outside the time range"), ({"case": "nope"}, "--case", "no case 'nope'"),
                                  ({"q": [1, 2]}, "--q", "a list needs 21 values"),
                                  ({"q": {"crank.x": float("nan")}}, "--q", "lacks crank.y")):  # fmt: skip
        with pytest.raises(RequestError) as refused:
            inspection.plan(session, four_bar, "quaternion", **request)
        assert refused.value.option == option and says in refused.value.problem
    found = inspection.run(inspection.plan(Session(GENERATED), MODELS / "boom.yaml", "euler:zxz"))
    assert found.inspection.singular and found.document()["classification"]["kind"] == found.verdict.kind


def test_a_study_request_is_checked_before_any_optimization(session):
    from kinegen.service import study

    for request, option, says in (({"study": "nope"}, "--study", "no study 'nope' (studies: "),
                                  ({"study": "bucket_linkage", "out": EXCAVATOR}, "--out", "is the model file itself")):  # fmt: skip
        name = request.pop("study")
        with pytest.raises(RequestError) as refused:
            study.plan(session, EXCAVATOR, name, "quaternion", **request)
        assert refused.value.option == option and says in refused.value.problem
    plan = study.plan(session, EXCAVATOR, "bucket_linkage", "quaternion", compare_fd=True, out="elsewhere.yaml")
    assert plan.gradients == ("exact", "fd") and plan.target.name == "elsewhere.yaml"


def test_the_charts_need_their_sections_and_equal_the_library_s_own(session):
    from kinegen.errors import ModelError
    from kinegen.forces.lift import lift_chart
    from kinegen.service import charts

    boom = MODELS / "boom.yaml"
    for call, section in ((charts.tool_forces, "tool_forces"), (charts.lift, "lift_chart")):
        with pytest.raises(ModelError, match=f"{section}: the model has no {section} section"):
            call(session, boom, "quaternion", False)
    found = charts.lift(session, EXCAVATOR, "quaternion", False)
    model = session.model(EXCAVATOR)
    direct = lift_chart(session.system(EXCAVATOR, model.lift_chart.case, "quaternion", False), model)
    assert found.chart.document() == direct.document() and found.boundary is None


def test_the_scan_and_compare_services_refuse_an_unknown_case_and_report_the_library_s_own_work(session):
    from kinegen import rotations
    from kinegen.analysis.compare import table
    from kinegen.analysis.scan import scan as library_scan
    from kinegen.service import parametrizations

    four_bar = MODELS / "four_bar.yaml"
    for service in (parametrizations.scan, parametrizations.compare):
        with pytest.raises(RequestError) as refused:
            service(session, four_bar, "nope", ("quaternion",))
        assert refused.value.option == "--case" and "no case 'nope'" in refused.value.problem
    names = ("quaternion", "dual-quaternion")  # committed modules: nothing is built into generated/
    report = parametrizations.scan(session, four_bar, None, names)
    physical = session.system(four_bar, None, rotations.REFERENCE)
    direct = library_scan(physical, {name: session.system(four_bar, None, name) for name in names})
    assert report.title == f"four_bar / {physical.case}" and report.text() == f"four_bar/{physical.case}: {direct.text()}"
    compared = parametrizations.compare(session, four_bar, None, ("quaternion",), compiled=False)
    assert compared.case == physical.case and [row.parametrization for row in compared.rows] == ["quaternion"]
    assert compared.rows[0].coordinates == 7 * 3 and compared.rows[0].failure is None  # three moving links, 7 stored coordinates each
    assert compared.text() == table(compared.rows, "four_bar", physical.case)
    assert compared.document()["rows"][0]["coordinates"] == 21


def test_a_view_request_is_checked_before_solving_and_its_motion_is_the_solver_s_own(session):
    from kinegen.runtime import Solver
    from kinegen.service import view

    four_bar = MODELS / "four_bar.yaml"
    for request, option, says in (({"point": "crank.Q"}, "--point", "'crank.Q' is not a named point"),
                                  ({"frame_body": "wheel"}, "--frame", "no body 'wheel' (bodies: crank, coupler, rocker)"),
                                  ({"case": "nope"}, "--case", "no case 'nope'")):  # fmt: skip
        with pytest.raises(RequestError) as refused:
            view.plan(session, four_bar, "quaternion", **request)
        assert refused.value.option == option and says in refused.value.problem
    plan = view.plan(session, four_bar, "quaternion", point="coupler.M", frame_body="rocker")
    assert plan.point == ("coupler", "M") and plan.frame_body == "rocker"
    report = view.run(plan)
    direct = Solver(plan.system, SolverOptions(on_failure="stop")).solve()
    assert report.results.failure is None and np.array_equal(report.results.q, direct.q)


def test_the_build_service_writes_the_committed_bytes_and_reports_each_cases_check(tmp_path):
    from kinegen.service.build import build

    report = build(MODELS / "four_bar.yaml", "quaternion", out_dir=tmp_path / "py")
    assert report.path == tmp_path / "py" / "four_bar_quaternion.py" and report.program is None and report.seconds > 0
    assert report.path.read_bytes() == (GENERATED / "four_bar_quaternion.py").read_bytes()
    assert [line.split(":")[0] for line in report.checks] == ["case crank_turn"]
    standalone = build(MODELS / "four_bar.yaml", "quaternion", target="c", out_dir=tmp_path / "c")
    assert standalone.program == "four_bar_quaternion_example" and (tmp_path / "c" / "Makefile").is_file()
    assert standalone.checks == report.checks


def test_an_exploration_request_names_an_unknown_study_and_settles_its_settings(session):
    from kinegen.explore.run import PARTITION_SIZE
    from kinegen.service import exploration

    with pytest.raises(RequestError) as refused:
        exploration.plan(session, EXCAVATOR, "nope")
    assert refused.value.option == "--study" and "no study 'nope' (studies: calibration," in refused.value.problem
    plan = exploration.plan(session, EXCAVATOR, "calibration", seed=7)
    explored = plan.exploration
    assert (explored.samples, explored.sampler, explored.seed, explored.partition_size) == (1024, "sobol", 7, PARTITION_SIZE)
    assert plan.target.as_posix() == "out/excavator_calibration.parquet" and explored.study == "calibration"
    assert explored.module_file == (GENERATED / "excavator_quaternion.py").resolve() and not plan.resume
