"""The main job (``make run``): the ZX200 excavator, built and solved in every case.

Builds every model of :data:`MAIN_JOB` (skipping modules that are already fresh), solves
the excavator's cases, prints a summary table (time steps, Newton iterations, residual,
cylinder ranges used against their limits, peak extension rates, solve time), checks
the other parametrizations against the quaternion run, and writes a CSV and a PNG per
case into the output folder. ``--regenerate-only`` just rebuilds ``generated/``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from kinegen.api import Session
from kinegen.errors import KinegenError, SingularJacobianError
from kinegen.runtime import Solver, SolverOptions, export, from_module, kinematics, solve

#: The excavator's operating cases (``bucket_toggle`` is for `kinegen scan`).
OPERATING_CASES = ("digging", "level_cut", "trench_wall")

#: What the main job builds: model file -> parametrizations (committed in generated/).
MAIN_JOB: dict[str, tuple[str, ...]] = {
    "boom.yaml": ("quaternion", "euler-parameters", "euler:zxz", "dual-quaternion", "dual-euler-parameters"),
    "slider_crank.yaml": ("quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters"),
    "four_bar.yaml": ("quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters"),
    "rssr.yaml": ("quaternion", "euler-parameters", "dual-quaternion", "dual-euler-parameters"),
    "excavator.yaml": ("quaternion", "euler-parameters", "euler:zxz", "euler:zxy", "dual-quaternion", "dual-euler-parameters"),
}
#: The parametrization whose committed module of a model with design parameters holds the
#: sensitivity kernels (the others are built with ``sensitivities=False``: they solve designs,
#: and their builds stay short).
SENSITIVITIES = "quaternion"


#: the digging case's phases in its own time, as its description gives them
DIGGING_PHASES = [("penetrate (boom down, arm in)", 0, 3), ("curl (arm and bucket in)", 3, 6), ("lift (boom up)", 6, 8),
                  ("swing 90 deg loaded", 8, 10), ("dump (arm out, bucket open)", 10, 13), ("swing back and return", 13, 17)]  # fmt: skip


def regenerate(models: Path, generated: Path, force: bool = True) -> Session:
    """Every module of :data:`MAIN_JOB` through one session (:class:`kinegen.api.Session`): built
    anew (``force``: derived, nothing taken from the cache), or only where missing or stale -- the
    rule every command follows."""
    # euler:zxz modules are singular at their initial pose on purpose; built anew, every module is derived
    session = Session(generated, check=False, reuse=not force)
    for name, params in MAIN_JOB.items():
        for param in params:
            if force:
                session.build(models / name, param, sensitivities=param == SENSITIVITIES)
            else:
                session.module(models / name, param, sensitivities=param == SENSITIVITIES)
    return session


def _excavator(session: Session, models: Path, module, excavator_model, out: Path) -> int:
    """The excavator's operating cases from its quaternion ``module`` (of the loaded ``excavator_model``),
    then the other parametrizations' modules of ``session`` against it."""
    print("solve times include an exact 2-norm condition number (SVD) at every step\n")
    header = (
        f"{'case':<12} {'steps':>5} {'Newton':>6} {'max|Phi|':>8} {'solve s':>7}  "
        f"{'cylinder':<20} {'used [m]':>13} {'limits [m]':>15} {'peak rate':>10}"
    )
    print(header)
    print("-" * len(header))
    failures = 0
    runs = {}
    from kinegen.analysis.view import motion_view

    for case in OPERATING_CASES:
        system = from_module(module, case)
        start = time.perf_counter()
        results = Solver(system, SolverOptions(condition="exact")).solve()
        elapsed = time.perf_counter() - start
        runs[case] = results
        for i, (name, (_, _, limits)) in enumerate(system.actuators.items()):
            length, rate = kinematics.actuator_length(results, name), kinematics.actuator_rate(results, name)
            lead = (
                f"{case:<12} {len(results.times):>5} {results.iterations.mean():>6.2f} {results.residuals.max():>8.1e} {elapsed:>7.2f}"
                if i == 0
                else " " * 43
            )
            print(
                f"{lead}  {name:<20} {length.min():>6.3f}-{length.max():<6.3f} {limits[0]:>7.4f}-{limits[1]:<7.4f} "
                f"{np.abs(rate).max():>6.3f} m/s"
            )
        for t, name, value, limits in kinematics.range_violations(results):
            failures += 1
            print(f"  RANGE: t = {t:.3f} s, {name} = {value:.4f} m outside [{limits[0]}, {limits[1]}]")
        tip = kinematics.point_position(results, "bucket", "T")
        print(
            f"{'':<12} tip T from ({tip[0, 0]:.3f}, {tip[0, 1]:.3f}, {tip[0, 2]:.3f}) to ({tip[-1, 0]:.3f}, {tip[-1, 1]:.3f}, {tip[-1, 2]:.3f}) m, cond(Phi_q) <= {results.conditions.max():.0f}"
        )
        stem = f"excavator_{case}"
        export.to_csv(results, out / f"{stem}.csv")
        from kinegen.analysis.plots import plot_case

        plot_case(results, out / f"{stem}.png", frame_body="upper", trace=("bucket", "T"), model=excavator_model)
        motion_view(results, excavator_model, out / f"{stem}.html", title=f"excavator / {case}")
    print(f"3-D views (kinegen view): {', '.join(f'excavator_{c}.html' for c in runs)} in {out}")
    print()
    for param in ("euler-parameters", "dual-quaternion", "dual-euler-parameters", "euler:zxy", "euler:zxz"):
        other = session.module(models / "excavator.yaml", param)
        worst = 0.0
        try:
            for case, reference in runs.items():
                results = solve(from_module(other, case))
                for body, points in results.system.points.items():
                    for point in points:
                        worst = max(
                            worst,
                            float(np.abs(kinematics.point_position(results, body, point) - kinematics.point_position(reference, body, point)).max()),
                        )
            verdict = "agrees" if worst < 1e-9 else "DISAGREES"
            failures += worst >= 1e-9
            print(f"{param:<17} {verdict} with quaternion on every point of every case: max difference {worst:.1e} m")
        except SingularJacobianError as exc:
            expected = param == "euler:zxz"
            failures += not expected
            print(
                f"{param:<17} {'singular, as expected' if expected else 'FAILED'}: t = {exc.t:g}, bodies {', '.join(exc.bodies)}, null space {'; '.join(exc.null_space)}"
            )
    return failures


def _branch_keeping(module) -> int:
    """bucket_near_toggle on its coarse grid, with and without branch keeping, against a 1 ms grid."""
    from kinegen.runtime import Solver, SolverOptions

    system = from_module(module, "bucket_near_toggle")
    fine = np.linspace(system.t0, system.t1, 2001)
    reference = Solver(system).solve(fine)

    def deviation(results) -> float:
        def angle(r):
            rotation = kinematics.rotation_matrix(r, "bucket")
            return np.arctan2(rotation[:, 2, 0], rotation[:, 0, 0])

        difference = angle(results) - np.interp(results.times, fine, angle(reference))
        return float(np.abs(np.angle(np.exp(1j * difference))).max())

    step = (system.t1 - system.t0) / (system.steps - 1)
    kept, jumped = deviation(Solver(system).solve()), deviation(Solver(system, SolverOptions(keep_branch=False)).solve())
    print(f"\nbucket_near_toggle (cylinder 1.6 mm short of the toggle and back, {step:g} s steps), bucket angle vs a 1 ms grid:")
    print(f"  with branch keeping {kept:.1e} rad; without it {jumped:.2f} rad (the other assembly branch)")
    return 0 if kept < 1e-9 else 1


def models_folder_of_package() -> Path | None:
    """The shipped models' folder, resolved (None where kinegen's models are not installed)."""
    from kinegen.examples import models_folder

    try:
        return models_folder().resolve()
    except KinegenError:
        return None


def folders(models: Path | None, generated: Path | None, out: Path) -> tuple[Path, Path]:
    """The models folder and the generated-modules folder of a run. Defaults: in a clone (a
    ``models/`` folder with the excavator in the working directory) ``models/`` and the committed
    ``generated/``; elsewhere (kinegen installed from a wheel) the models shipped with kinegen and
    ``out/generated``, so that a run outside a clone writes into its output folder only."""
    from kinegen.examples import MARKER, models_folder

    local = Path("models")
    if models is None:
        models = local if (local / MARKER).is_file() else models_folder()
    if not (models / MARKER).is_file():
        raise KinegenError(f"no {models / MARKER}: --models must name a folder holding kinegen's models (kinegen models --copy DIR writes one)")
    if generated is None:
        generated = Path("generated") if models == local else out / "generated"
    return models, generated


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m kinegen.demo", description=__doc__)
    parser.add_argument("--models", type=Path, help="the models folder (default: ./models in a clone, else the models shipped with kinegen)")
    parser.add_argument("--generated", type=Path, help="where the modules are built (default: ./generated in a clone, else OUT/generated)")
    parser.add_argument("--out", default="out", type=Path)
    parser.add_argument("--regenerate-only", action="store_true")
    args = parser.parse_args(argv)
    try:
        args.models, args.generated = folders(args.models, args.generated, args.out)
    except KinegenError as exc:
        parser.error(str(exc))
    print(f"models from {args.models}")
    start = time.perf_counter()
    if not args.regenerate_only and args.models.resolve() == models_folder_of_package():
        from kinegen.examples import place_shipped_modules

        placed = place_shipped_modules(args.generated)
        if placed:
            print(f"{placed} generated files shipped with kinegen placed in {args.generated}/ (not built again)")
    session = regenerate(args.models, args.generated, force=args.regenerate_only)
    print(f"{sum(map(len, MAIN_JOB.values()))} generated modules ready in {args.generated}/ ({time.perf_counter() - start:.1f} s)")
    if args.regenerate_only:
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    print("\nHitachi ZX200 excavator (models/excavator.yaml, quaternion)\n")

    excavator_file = args.models / "excavator.yaml"
    excavator_model = session.model(excavator_file)
    excavator_module = session.module(excavator_file, "quaternion")
    try:
        failures = _excavator(session, args.models, excavator_module, excavator_model, args.out)
    except KinegenError as exc:
        print(f"FAILED: {exc}")
        return 1
    from kinegen.analysis.chart import outlines, plot_envelope
    from kinegen.files import write_atomic
    from kinegen.service import charts, envelope

    ranged = envelope.run(envelope.plan(session, excavator_file, "quaternion", boundary=True, sensitivities=False))
    result, boundary, excavator = ranged.result, ranged.boundary, ranged.plan.system
    print(
        f"\nworking range (kinegen envelope models/excavator.yaml): {len(result.samples)} configurations, {result.seconds:.1f} s"
    )
    print(result.table())
    print(
        f"exact boundary: {len(boundary.points) - 1} points on {len(set(boundary.curve.tolist()))} curves (inputs at limits, folds), "
        f"{len(boundary.switching)} switching points, chord error {1e3 * boundary.chord_error:.3f} mm, {boundary.seconds:.1f} s "
        f"-> excavator_envelope.png, excavator_envelope_boundary.csv"
    )
    write_atomic(args.out / "excavator_envelope_boundary.csv", boundary.to_csv())
    plot_envelope(result, excavator, args.out / "excavator_envelope.png", boundary, outlines(excavator_model))
    if excavator_model.tool_forces is not None:
        from kinegen.forces.iso6015 import report

        print("\nkinegen forces models/excavator.yaml (ESTIMATED hydraulic data; docs/forces.md):")
        print(report(charts.tool_forces(session, excavator_file, "quaternion").found, excavator_model))
        from kinegen.forces.maps import plot_force_map, reach_map

        found = reach_map(excavator, excavator_model, "tangent")  # the picture only: the envelope's boundary is drawn
        i, j = np.unravel_index(np.nanargmax(found.force), found.force.shape)
        picture = plot_force_map(found, args.out / "excavator_force_map.png", boundary)
        print(f"force map (kinegen forces --map tangent --plot): {found.poses:,} poses in {found.seconds:.1f} s, up to "
              f"{found.force[i, j] / 1e3:.1f} kN along the lip's tangent over the bucket's attitude, at x {found.radius[j]:.2f}, "
              f"z {found.height[i]:.2f} m (limited by {found.regions[found.limiting[i, j]]}) -> {picture.name}")  # fmt: skip
    if excavator_model.lift_chart is not None:
        from kinegen.forces.lift import plot_lift_chart

        print("\nkinegen lift models/excavator.yaml (ESTIMATED masses and hydraulic data; docs/dynamics.md):")
        chart = charts.lift(session, excavator_file, "quaternion").chart
        print(chart.table())
        print(f"-> {plot_lift_chart(chart, args.out / 'excavator_lift_chart.png', boundary).name}")
    if excavator_model.massive and "payload" in excavator_model.loads:
        from kinegen.forces import forces
        from kinegen.runtime import solve

        for case in (c for c in ("digging", "digging_fast", "digging_paced") if c in excavator_model.cases):
            moving = forces(solve(from_module(excavator_module, case)), excavator_model, ["payload"], inertia=True)
            peaks = ", ".join(f"{name} {p.pressure.max() / 1e6:.1f} MPa" for name, p in moving.pressures.items())
            line = f"dynamics (kinegen solve --case {case} --dynamics --load payload): peak pressures {peaks}"
            if moving.tipping is not None:
                k = int(np.argmin(moving.tipping.margin))
                line += f"; tipping margin down to {moving.tipping.margin[k] / 1e3:.1f} kN m ({moving.tipping.line[k]} line, t = {moving.results.times[k]:g} s)"
            if excavator_model.supply is not None:  # the oil it asks of the pumps (docs/supply.md)
                from kinegen.forces.supply import LITRES_PER_MINUTE, flows

                supplied = flows(moving.results, excavator_model, moving)
                p, k = np.unravel_index(np.argmax(supplied.flow / supplied.max_flow[:, None]), supplied.flow.shape)
                line += (f"; pumps up to {supplied.flow[p, k] * LITRES_PER_MINUTE:.0f} L/min ({supplied.pumps[p]}, "
                         f"{supplied.flow[p, k] / supplied.max_flow[p]:.2f} times its {supplied.max_flow[p] * LITRES_PER_MINUTE:.0f}), "
                         f"{supplied.power.sum(axis=0).max() / 1e3:.0f} of the engine's {supplied.engine_power / 1e3:.0f} kW")  # fmt: skip
            print(line)
        if excavator_model.supply is not None:  # the fastest timing of each working path (docs/cycle.md)
            from kinegen.analysis.cycleplot import plot_cycle
            from kinegen.forces.cycle import window_limits
            from kinegen.service import cycle

            print(
                "\nkinegen cycle models/excavator.yaml --load payload (the fastest timing of each path; ESTIMATED pumps and engine):"
            )
            for case in (c for c in ("digging", "level_cut", "trench_wall", "digging_paced") if c in excavator_model.cases):
                timed = cycle.run(cycle.plan(session, excavator_file, case, "quaternion", loads=("payload",)))
                found, checked = timed.found, timed.checked
                failures += bool(checked.exceeded())
                picture = plot_cycle(found, args.out / f"excavator_cycle_{case}.png", checked.flows)
                print(f"  {case:<14} {found.duration:6.2f} s (its own {found.own_duration:g} s), the re-timed case solved again: "
                      f"{'no limit exceeded' if not checked.exceeded() else 'EXCEEDED ' + ', '.join(checked.exceeded())} -> {picture.name}")  # fmt: skip
                if case == "digging":  # its phases as its description gives them, in its own time
                    for label, spent, name, share in window_limits(found, DIGGING_PHASES):
                        print(f"    {label:<28} {spent:5.2f} s, limited by {name} ({100 * share:.0f} % of it)")
    from kinegen.analysis.scan import plot_scan, scan

    toggle = from_module(excavator_module, "bucket_toggle")
    scanned = scan(toggle, {})
    plot_scan(scanned, args.out / "excavator_bucket_toggle_scan.png", "excavator / bucket_toggle")
    print("\nkinegen scan models/excavator.yaml --case bucket_toggle (bucket cylinder towards its toggle at 2.7366 m):")
    print(f"  {scanned.ahead}\n  {scanned.stopped}")
    failures += _branch_keeping(excavator_module)
    print()
    from kinegen.analysis.view import motion_view

    boom_model = session.model(args.models / "boom.yaml")
    boom_run = solve(from_module(session.module(args.models / "boom.yaml", "quaternion")))
    print(f"3-D view of the paper's boom: {motion_view(boom_run, boom_model, args.out / 'boom_swing.html', title='boom (paper) / swing')}")
    boom = session.module(args.models / "boom.yaml", "euler:zxz")
    try:
        solve(from_module(boom))
        print("boom (paper)      euler:zxz unexpectedly solved")
        failures += 1
    except SingularJacobianError as exc:
        print(f"boom (paper)      euler:zxz singular at t = {exc.t:g} as the paper shows: null space {'; '.join(exc.null_space)}")
    print("\nkinegen compare models/excavator.yaml (every parametrization built and solved; the paper's question):\n")
    from kinegen.analysis.compare import compare, table

    rows = compare(excavator_model, "digging")
    failures += sum(r.failure is not None for r in rows if not r.parametrization.startswith("euler:zx"))
    print(table(rows, excavator_model.name, "digging"))
    failures += _studies(session, excavator_file, excavator_model, args.out)
    failures += _exploration(excavator_file, session.module_path(excavator_file, "quaternion"), args.out)
    print(f"\noutputs (CSV + PNG per case, optimized models, the exploration's Parquet) in {args.out.resolve()}")
    return 1 if failures else 0


def _studies(session: Session, model_file: Path, model, out: Path) -> int:
    """The excavator's design studies (kinegen optimize), exact gradients; the optimized models into ``out``."""
    from kinegen.analysis.studies import write_optimized
    from kinegen.service import study

    failures = 0
    for name in model.studies:
        print(f"\nkinegen optimize {model_file.name} --study {name} (SLSQP on the exact gradients):\n")
        plan = study.plan(session, model_file, name, "quaternion", out=out / f"{model.name}_{name}.yaml")
        result = study.run(plan).best
        print(result.table(model.working_range.published if model.working_range else None))
        print(f"  wrote {write_optimized(model_file, model, result, plan.target)}")
        failures += not result.success
    return failures


def _exploration(model_file: Path, module_path: Path, out: Path, samples: int = 256) -> int:
    """kinegen explore of the calibration study on a LocalCluster: Parquet, ranking, Pareto front."""
    import shutil

    try:
        from kinegen.explore.plots import plot_exploration, ranking_of
        from kinegen.explore.run import Exploration, explore
        from kinegen.explore.store import Store
    except ImportError as exc:
        print(f"\nkinegen explore left out ({exc}): pip install 'kinegen[explore]'")
        return 0
    target = out / f"excavator_calibration_{samples}.parquet"  # not kinegen explore's default: the tour runs that next
    shutil.rmtree(target, ignore_errors=True)  # this job's own output of an earlier run
    print(f"\nkinegen explore {model_file.name} --study calibration --samples {samples} (Sobol', Dask LocalCluster):\n")
    exploration = Exploration(model_file.resolve(), module_path.resolve(), "calibration", samples, partition_size=32)
    report = explore(exploration, target, progress=False, say=lambda line: print(f"  {line}"))
    print(report.summary())
    store = Store(target)
    table, provenance = store.read(), store.provenance()
    result = ranking_of(table, provenance)
    if result is None:
        print("  too few variants could be measured to rank the parameters")
        return 1
    print(result.table())
    picture = plot_exploration(table, provenance, ("max_reach", "max_depth"), (True, True), out / "excavator_calibration_explore.png")
    print(f"  wrote {picture}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
