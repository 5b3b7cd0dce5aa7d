"""Issue 40, parts 1 and 2: the hydraulic supply (``pumps:``) and the oil and power a motion asks of
it -- each cylinder's flow from its areas and rate, the pumps' shares, their pressure and power --
against hand computations on closed-form kinematics and against the power balance."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from kinegen.cli import main
from kinegen.errors import ModelError
from kinegen.forces import forces
from kinegen.forces.supply import flows
from kinegen.model import loads as read
from kinegen.runtime import from_module, kinematics, load_module, solve
from tests.conftest import generated_system, model
from tests.test_mistakes import CRANE

SUPPLY = """\
pumps:
  pumps: {main: {max_flow: 60/60000, max_pressure: 25e6}}
  engine_power: 20e3
  circuits: {lift: [main]}
"""
#: the crane raising and lowering its boom: the lift cylinder extends, then retracts
SWINGING = CRANE.replace("function: -0.2 - 0.5*t}", "function: -0.2 - 0.6*sin(2*t)}").replace("t1: 1", "t1: 3").replace("steps: 11", "steps: 61")


@pytest.fixture(scope="module")
def crane(tmp_path_factory):
    folder = tmp_path_factory.mktemp("crane")
    path = folder / "crane.yaml"
    path.write_text(SWINGING.replace("BORE", "0.1").replace("ROD", "0.06") + SUPPLY)
    built = CliRunner().invoke(main, ["build", str(path), "--param", "quaternion", "--out-dir", str(folder)])
    assert built.exit_code == 0, built.output
    return path, folder


def _closed_form_length(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lift cylinder's length and rate from the crane's geometry: the boom turns about global y
    by theta = -0.2 - 0.6 sin 2t; its point C (1.5, 0, 0) against the ground point B (0.6, 0, -0.8)."""
    theta = -0.2 - 0.6 * np.sin(2 * t)
    rate = -1.2 * np.cos(2 * t)
    c = np.stack([1.5 * np.cos(theta), -1.5 * np.sin(theta)], axis=1)  # (x, z): a turn about +y takes x toward -z
    dc = np.stack([-1.5 * np.sin(theta), -1.5 * np.cos(theta)], axis=1) * rate[:, None]
    gap = c - np.array([0.6, -0.8])
    length = np.linalg.norm(gap, axis=1)
    return length, np.einsum("ki,ki->k", gap, dc) / length


def test_a_cylinders_flow_is_its_area_times_its_rate_cap_side_out_rod_side_in(crane):
    """Flow = pi/4 D^2 x L' while the cylinder extends, pi/4 (D^2 - d^2) x |L'| while it retracts, L'
    from the closed-form geometry, to 1e-12 of the largest flow; the one pump takes it all."""
    path, folder = crane
    m = read(path.read_text(), str(path))
    results = solve(from_module(load_module(folder / "crane_quaternion.py"), "raise"))
    supplied = flows(results, m)
    _, rate = _closed_form_length(results.times)
    assert (rate > 0).any() and (rate < 0).any()
    cap, annulus = np.pi / 4 * 0.1**2, np.pi / 4 * (0.1**2 - 0.06**2)
    expected = np.where(rate > 0, cap * rate, -annulus * rate)
    np.testing.assert_allclose(supplied.flow[0], expected, rtol=0, atol=1e-12 * expected.max())
    np.testing.assert_allclose(supplied.elements["lift"], expected, rtol=0, atol=1e-12 * expected.max())


def test_the_pumps_power_is_the_work_the_cylinder_does_on_the_loads(crane):
    """With the hook load and the boom's weight held: where the cylinder extends pushing, the pump's
    power p Q equals the power the cylinder delivers, minus the loads' and gravity's power on the
    boom (the power balance, from the motion alone), to 1e-9; where the load pulls it or it
    retracts pushing (oil metered out), the pump delivers at no pressure."""
    path, folder = crane
    m = read(path.read_text(), str(path))
    results = solve(from_module(load_module(folder / "crane_quaternion.py"), "raise"))
    held = forces(results, m, ["hook"], weight=True)
    supplied = flows(results, m, held)
    velocity_tip = kinematics.point_velocity(results, "boom", "tip")
    center = kinematics.position(results, "boom") + kinematics.rotation_matrix(results, "boom") @ np.array([2.0, 0.0, 0.0])
    velocity_center = kinematics.velocity(results, "boom") + np.cross(kinematics.omega(results, "boom"), center - kinematics.position(results, "boom"))
    loads_power = velocity_tip @ np.array([0.0, 0.0, -5000.0]) + 300 * velocity_center @ np.array([0.0, 0.0, -9.80665])
    _, rate = _closed_form_length(results.times)
    force = held.element_force("lift")
    pushing_out = (rate > 0) & (force > 0)
    assert pushing_out.sum() > 5
    np.testing.assert_allclose(supplied.power[0][pushing_out], -loads_power[pushing_out], rtol=1e-9)
    np.testing.assert_allclose(supplied.pressure[0][pushing_out], force[pushing_out] / (np.pi / 4 * 0.1**2), rtol=1e-12)
    assert (supplied.pressure[0][(rate < 0) & (force > 0)] == 0).all()


def test_the_excavators_pumps_share_the_merged_circuits_and_the_digging_cycle_asks_too_much_oil(tmp_path):
    """The excavator's front pump feeds half the boom's and the arm's flow and all the bucket's, the
    rear pump half the boom's and the arm's and the swing motor's (displacement x turn rate), each
    flow from the areas and rates by hand to 1e-12; `kinegen solve` names every span where a pump is
    asked more than its 212 L/min (FLOW:) and where the pumps need more than the engine's 110 kW
    (POWER:), and the CSV carries the columns. Its paced sibling, the same path 3.5 times slower,
    asks no more than either and holds without a PRESSURE or TIPPING line."""
    excavator = model("excavator")
    results = solve(generated_system("excavator_quaternion", "digging"))
    supplied = flows(results, excavator)

    def flow(bore: float, rod: float, members: tuple[str, ...]) -> np.ndarray:
        total = np.zeros(len(results.times))
        for member in members:
            rate = kinematics.actuator_rate(results, member)
            total += np.where(rate > 0, np.pi / 4 * bore**2 * rate, -np.pi / 4 * (bore**2 - rod**2) * rate)
        return total

    boom = flow(0.120, 0.085, ("boom_cylinder_left", "boom_cylinder_right"))
    arm = flow(0.135, 0.095, ("arm_cylinder",))
    bucket = flow(0.115, 0.080, ("bucket_cylinder",))
    swing = 2.6e-3 * np.abs(kinematics.omega(results, "upper")[:, 2])  # the upper turns about the global z axis
    front, rear = supplied.flow[supplied.pumps.index("front")], supplied.flow[supplied.pumps.index("rear")]
    scale = max(front.max(), rear.max())
    np.testing.assert_allclose(front, boom / 2 + arm / 2 + bucket, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(rear, boom / 2 + arm / 2 + swing, rtol=0, atol=1e-12 * scale)
    out = tmp_path / "digging.csv"
    done = CliRunner().invoke(main, ["solve", "models/excavator.yaml", "--case", "digging", "--dynamics", "--load", "payload", "--out", str(out)])
    assert done.exit_code == 0, done.output
    assert "FLOW: pump front asked more than its 212 L/min" in done.output and "POWER: the pumps need more than the engine's 110 kW" in done.output
    header = out.read_text().splitlines()[0].split(",")
    assert {"pump.front.flow", "pump.front.max_flow", "pump.rear.pressure", "pump.rear.power", "engine.power", "engine.power_limit"} <= set(header)
    paced = CliRunner().invoke(main, ["solve", "models/excavator.yaml", "--case", "digging_paced", "--dynamics", "--load", "payload"])
    assert paced.exit_code == 0, paced.output
    assert not any(line.startswith(("FLOW:", "POWER:", "PRESSURE:", "TIPPING:")) for line in paced.output.splitlines()), paced.output


@pytest.mark.parametrize(
    ("old", "new", "entry", "problem"),
    [
        ("circuits: {lift: [main]}", "circuits: {lift: [second]}", "pumps.circuits.lift", "unknown or repeated pump"),
        ("circuits: {lift: [main]}", "circuits: {hook: [main]}", "pumps.circuits.hook", "no actuator with hydraulic data"),
        ("circuits: {lift: [main]}", "circuits: {}", "pumps.circuits", "no pump feeds lift"),
        ("engine_power: 20e3", "engine_power: 0", "pumps.engine_power", "must be positive"),
    ],
)
def test_a_malformed_pumps_section_names_the_entry(old, new, entry, problem):
    text = SWINGING.replace("BORE", "0.1").replace("ROD", "0.06") + SUPPLY
    with pytest.raises(ModelError) as caught:
        read(text.replace(old, new), "crane.yaml")
    assert caught.value.entry == entry and problem in caught.value.problem, str(caught.value)


def test_a_flow_typed_in_litres_per_minute_is_warned_about_in_its_units():
    from kinegen.model import ModelWarning

    text = SWINGING.replace("BORE", "0.1").replace("ROD", "0.06") + SUPPLY.replace("max_flow: 60/60000", "max_flow: 60")
    with pytest.warns(ModelWarning, match=r"pumps\.pumps\.main\.max_flow: 60 m\^3/s is outside the usual"):
        read(text, "crane.yaml")
