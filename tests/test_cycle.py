"""Issue 40, parts 3 and 4: the fastest timing of a case's path (``kinegen cycle``) against closed
forms (a cylinder under a flow limit, a turntable under a torque limit), against toppra's
reachability analysis, and against the limits it was timed to when the re-timed case is solved."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from kinegen.cli import main
from kinegen.forces.cycle import MARGIN, check_retimed, fastest, path_constraints, read_timing
from kinegen.forces.reachability import Reachability
from kinegen.model import loads as read
from kinegen.runtime import from_module, load_module, solve
from tests.conftest import generated_system, model
from tests.test_mistakes import CRANE

#: the file's tests in one test process (make test distributes with --dist loadgroup): the fastest digging cycle and the module, computed once
pytestmark = pytest.mark.xdist_group(name="cycle")

#: the crane without masses, one pump: only the pump's flow limits how fast it raises its boom
LIGHT_CRANE = "\n".join(line for line in CRANE.replace("BORE", "0.1").replace("ROD", "0.06").splitlines()
                        if not line.strip().startswith(("mass:", "center_of_mass:", "inertia:"))) + """
pumps:
  pumps: {main: {max_flow: 60/60000, max_pressure: 25e6}}
  engine_power: 20e3
  circuits: {lift: [main]}
"""  # fmt: skip

#: a turntable turning a quarter turn about the vertical (no gravity torque) by a hydraulic motor:
#: its torque limit (displacement x the pump's pressure: 1e-4 x 30e6 = 3000 N m) is the only one that binds
TURNTABLE = """\
model: turntable
ground:
  points: {O: [0, 0, 0]}
  vectors: {z: [0, 0, 1]}
bodies:
  table:
    position: [0, 0, 0]
    mass: 500
    center_of_mass: [0, 0, 0]
    inertia: [80, 80, 100]
    points: {O: [0, 0, 0], rim: [1, 0, 0]}
    vectors: {z: [0, 0, 1]}
joints:
  spin: {type: revolute, bodies: [ground, table], points: [O, O], axes: [z, z]}
motors:
  drive: {joint: spin, displacement: 1e-4}
pumps:
  pumps: {main: {max_flow: 0.09, max_pressure: 30e6}}
  engine_power: 1.9e6
  circuits: {drive: [main]}
cases:
  quarter:
    drivers:
      angle: {type: joint_angle, joint: spin, function: pi/2*t}
    t0: 0
    t1: 1
    steps: 11
"""


def _built(tmp_path_factory, text: str, name: str):
    folder = tmp_path_factory.mktemp(name)
    path = folder / f"{name}.yaml"
    path.write_text(text)
    built = CliRunner().invoke(
        main, ["build", str(path), "--param", "quaternion", "--out-dir", str(folder), "--target", "python"]
    )
    assert built.exit_code == 0, built.output
    return read(text, str(path)), folder / f"{name}_quaternion.py"


@pytest.fixture(scope="module")
def light_crane(tmp_path_factory):
    return _built(tmp_path_factory, LIGHT_CRANE, "crane")


@pytest.fixture(scope="module")
def turntable(tmp_path_factory):
    return _built(tmp_path_factory, TURNTABLE, "turntable")


def _crane_length(theta: float) -> float:
    """The lift cylinder's length from the crane's geometry: the boom point C (1.5, 0, 0) turned by
    theta about +y, against the ground point B (0.6, 0, -0.8)."""
    return float(np.hypot(1.5 * np.cos(theta) - 0.6, -1.5 * np.sin(theta) + 0.8))


def test_a_cylinder_under_a_flow_limit_moves_its_stroke_in_stroke_times_area_over_flow(light_crane):
    """The boom raised from -0.2 to -0.7 rad: the cylinder's stroke L(-0.7) - L(-0.2) from the closed-form
    geometry, its cap area, the pump's 60 L/min. At every point between the ends the pump gives its
    whole flow (to 1e-9); the cycle time, extrapolated over the grid (Richardson, N = 1000 and 2000:
    the rest-to-rest ends cost O(1/N)), is stroke x A / Q to 1e-6."""
    m, module = light_crane
    system = from_module(load_module(module), "raise")
    stroke = _crane_length(-0.7) - _crane_length(-0.2)
    assert stroke > 0  # the cylinder extends all the way: cap side
    area, flow = np.pi / 4 * 0.1**2, 60 / 60000 * (1 - MARGIN)
    durations = []
    for count in (1001, 2001):
        found = fastest(solve(system, np.linspace(0, 1, count)), m)
        rate = np.abs(found.constraints.speed_bound[:, 0] ** -1) * found.speed  # the pump's share used: flow per its limit
        np.testing.assert_allclose(rate[1:-1], 1.0, rtol=1e-9)
        assert set(found.limiting[1:-1]) == {"pump main flow"}
        durations.append(found.duration)
    extrapolated = 2 * durations[1] - durations[0]
    assert extrapolated == pytest.approx(stroke * area / flow, rel=1e-6)
    assert durations[0] > durations[1] > extrapolated  # the grid's ends only ever cost time


def test_a_turntable_under_a_torque_limit_follows_the_bang_bang_time(turntable):
    """A quarter turn (a path at constant rate in s) with inertia J = 100 kg m^2 and the motor's
    torque limit 3000 N m: full torque to the middle, full braking after (bang-bang), T = 2 sqrt(J
    Theta / tau) -- exact on the grid, where the speed squared is linear in s -- to 1e-12; the torque
    touches its limit at every point."""
    m, module = turntable
    system = from_module(load_module(module), "quarter")
    found = fastest(solve(system, np.linspace(0, 1, 1001)), m)
    torque = 1e-4 * 30e6 * (1 - MARGIN)
    assert found.duration == pytest.approx(2 * np.sqrt(100 * (np.pi / 2) / torque), rel=1e-12)
    assert set(found.limiting[:500]) == {"drive torque (positive)"} and set(found.limiting[500:-1]) == {"drive torque (negative)"}
    check = check_retimed(system, m, found)
    np.testing.assert_allclose(np.abs(check_torque(check, m)).max(), torque, rtol=1e-9)


def check_torque(check, m):
    from kinegen.forces import forces

    return forces(check.results, m, (), inertia=True).element_force("drive")


@pytest.fixture(scope="module")
def digging():
    system = generated_system("excavator_quaternion", "digging")
    path = solve(system)
    return system, path, fastest(path, model("excavator"), ("payload",))


def test_the_fastest_digging_cycle_has_a_limit_active_at_every_point(digging):
    """Optimality: at every point some limit is active (within 2 x the margin) -- or the point is where
    the profile joins the braking curve (its next speed is the highest controllable one) or the end."""
    _, _, found = digging
    inactive = np.flatnonzero(found.room > 2 * MARGIN)
    x = found.speed**2
    for i in inactive:
        if i == len(x) - 1:
            continue
        assert x[i + 1] == pytest.approx(found.controllable[i + 1, 1], rel=1e-9), (i, found.room[i], found.limiting[i])
    assert len(inactive) < 0.05 * len(x)


def test_the_controllable_sets_agree_with_toppras_where_the_limits_are_linear(digging):
    """Without the power limit (which toppra cannot take: not linear in s-dot squared), the controllable
    sets of kinegen's reachability analysis equal toppra's (seidel solver) to 1e-7."""
    import toppra

    _, path, _ = digging
    limits = path_constraints(path, model("excavator"), ("payload",))
    x_max = np.min(limits.speed_bound**2, axis=1, initial=np.inf)
    ours = Reachability(limits.s, limits.rows_u, limits.rows_x, limits.rows_bound, x_max).controllable_sets()
    m = limits.rows_u.shape[1]
    bounds = np.column_stack([np.zeros(len(limits.s)), x_max])

    class Rows(toppra.constraint.LinearConstraint):
        def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
            return limits.rows_u, limits.rows_x, -limits.rows_bound, np.eye(m), np.zeros(m), None, bounds

    class Path(toppra.interpolator.AbstractGeometricPath):
        dof, path_interval = 1, np.array([limits.s[0], limits.s[-1]])

        def __call__(self, positions, order=0):
            return np.zeros((np.size(positions), 1))

    rows = Rows()
    rows.identical = True
    theirs = toppra.algorithm.TOPPRA([rows], Path(), gridpoints=limits.s, solver_wrapper="seidel").compute_controllable_sets(
        0.0, 0.0
    )
    np.testing.assert_allclose(ours[:, 1], theirs[:, 1], rtol=1e-7, atol=1e-9 * ours[:, 1].max())


def test_the_retimed_digging_cycle_solved_again_touches_its_limits_and_never_exceeds_them(tmp_path):
    """kinegen cycle --out, then kinegen solve --timing --dynamics: no FLOW, POWER, PRESSURE or TIPPING
    line, and each pump's flow, the engine's power and the pressures reach 1 - 1e-5 of their limits
    (touching: the cycle is timed 1e-6 inside them)."""
    timing = tmp_path / "digging.csv"
    runner = CliRunner()
    done = runner.invoke(
        main, ["cycle", "models/excavator.yaml", "--case", "digging", "--load", "payload", "--out", str(timing), "--json"]
    )
    assert done.exit_code == 0, done.output
    report = json.loads(done.stdout)
    assert report["cycle_time"] < report["own_duration"] and report["check"]["exceeded"] == []
    for name, used in report["check"]["largest_share_used"].items():
        assert 1 - 1e-5 <= used <= 1.0, (name, used)
    assert read_timing(timing).times[-1] == pytest.approx(report["cycle_time"], rel=1e-12)
    solved = runner.invoke(
        main, ["solve", "models/excavator.yaml", "--case", "digging", "--timing", str(timing), "--load", "payload", "--dynamics"]
    )
    assert solved.exit_code == 0, solved.output
    assert not any(line.startswith(("FLOW:", "POWER:", "PRESSURE:", "TIPPING:")) for line in solved.output.splitlines()), (
        solved.output
    )
    wrong = runner.invoke(main, ["solve", "models/excavator.yaml", "--case", "level_cut", "--timing", str(timing)])
    assert wrong.exit_code != 0 and "re-times excavator/digging, not excavator/level_cut" in wrong.output


@pytest.mark.parametrize("case", ["level_cut", "trench_wall", "bucket_stroke", "bucket_near_toggle", "digging_fast", "digging_paced", "oscillation"])
def test_every_shipped_excavator_case_can_be_retimed_within_its_limits(case):
    """Every excavator case with a path (bucket_toggle has none: its linkage cannot assemble past the
    toggle it runs into): a finite cycle time, and the re-timed case solved again exceeds no limit.
    Through the compiled solver, the default a user gets (the Python solver's own oscillation
    took 57 s of the suite; the digging fixture's cases keep the Python path under test here)."""
    system = generated_system("excavator_quaternion", case, compiled=True)
    m = model("excavator")
    found = fastest(solve(system), m, ("payload",))
    assert 0 < found.duration < np.inf
    check = check_retimed(system, m, found)
    assert check.exceeded() == [] and max(check.used.values()) >= 1 - 1e-5, check.used


def test_retiming_depends_on_the_path_not_on_the_cases_own_pace(digging):
    """digging_paced is digging's path at 1/3.5 of its pace on the same number of points: the same
    poses, so the same fastest cycle (to 1e-9 s), though its own duration is 3.5 times longer."""
    _, _, found = digging
    paced = fastest(solve(generated_system("excavator_quaternion", "digging_paced")), model("excavator"), ("payload",))
    assert paced.own_duration == pytest.approx(3.5 * found.own_duration)
    assert paced.duration == pytest.approx(found.duration, abs=1e-9)



@pytest.fixture(scope="module")
def excavator_module():
    from tests.conftest import GENERATED

    return load_module(GENERATED / "excavator_quaternion.py")


@pytest.mark.parametrize("parameter", ["bucket_bore", "C_z", "K_x", "counterweight_x"])
def test_the_cycle_times_exact_gradient_equals_central_differences_of_the_discretized_problem(excavator_module, parameter):
    """cycle_time (the digging path holding the payload, on its 341 points): its exact derivative by a
    cylinder bore (the flows and pressures), a boom-cylinder pin (the path's forces), a bucket-link pin
    (the bucket's inertia) and the counterweight's place (tipping) equals central differences of the
    same discretized problem (h = 1e-6 of the parameter's scale) to 1e-6."""
    from kinegen.forces.cycle import cycle_time

    m = model("excavator")
    nominal = from_module(excavator_module, "digging").design
    value, gradient = cycle_time(solve(from_module(excavator_module, "digging")), m, ("payload",))
    h = 1e-6 * max(1.0, abs(nominal[parameter]))

    def at(shift: float) -> float:
        design = {**nominal, parameter: nominal[parameter] + shift}
        return cycle_time(solve(from_module(excavator_module, "digging", None, design)), m, ("payload",), gradient=False)[0]

    central = (at(h) - at(-h)) / (2 * h)
    assert value == pytest.approx(fastest(solve(from_module(excavator_module, "digging")), m, ("payload",)).duration, rel=1e-12)
    assert abs(central) > 1e-6  # the parameter moves the cycle time
    assert gradient[list(nominal).index(parameter)] == pytest.approx(central, rel=1e-6)


def test_the_bucket_cylinder_study_measures_digging_force_against_cycle_time(excavator_module):
    """The trade-off study (models/excavator.yaml, bucket_cylinder): a larger bore digs harder and
    cycles slower -- both derivatives by the bore positive, exact, through kinegen's study measure;
    the nominal 115 mm meets the 15 s cycle."""
    from kinegen.analysis.studies import StudyProblem

    m = model("excavator")
    problem = StudyProblem(m, excavator_module, m.studies["bucket_cylinder"])
    measured = problem.measure(np.array([0.115]))
    force, cycle = "digging_force(bucket_cylinder, bucket_stroke)", "cycle_time(digging holding payload)"
    assert measured.values[cycle] < 15.0 and measured.values[force] > 100
    assert measured.gradients[force][0] > 0 and measured.gradients[cycle][0] > 0


def test_a_speed_limit_holds_the_retimed_level_cut_and_is_touched():
    """--max-speed arm_cylinder=0.2: the re-timed level cut, solved again, moves the arm cylinder at
    most 0.2 m/s and reaches it (1 - 1e-5); the cut takes longer than its own 4 s."""
    system = generated_system("excavator_quaternion", "level_cut")
    m = model("excavator")
    found = fastest(solve(system), m, ("payload",), speed_limits={"arm_cylinder": 0.2})
    used = check_retimed(system, m, found).used["arm_cylinder speed"]
    assert 1 - 1e-5 <= used <= 1.0 and found.duration > found.own_duration
