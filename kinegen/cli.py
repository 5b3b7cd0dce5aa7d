"""The ``kinegen`` command: thin over the package.

Exit codes: :class:`kinegen.errors.ExitCode` (a usage error is 64, not click's 2, which is a
model error's).
"""

from __future__ import annotations

import json
import math
import os
import sys
import traceback
import warnings
from collections.abc import Callable
from pathlib import Path

import click

from kinegen import __version__, rotations
from kinegen.errors import ExitCode, KinegenError, OverConstrainedError, RequestError, printable
from kinegen.files import MAX_MODEL_BYTES, STDIN, STDOUT, read_bounded
from kinegen.lazy import lazy_import

np = lazy_import("numpy")  # imported at its first use: `kinegen --help` and `kinegen models` do not need it


def _number_check(accepts: Callable[[float], bool], expected: str) -> Callable[[click.Context, click.Parameter, float | None], float | None]:
    """An option callback refusing, as a usage error of that option, a number ``accepts`` rejects
    (click reads 'nan' and 'inf' as floats; NaN, which passes no comparison, is rejected by each)."""

    def check(_ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
        if value is not None and not accepts(value):
            raise click.BadParameter(f"expected {expected}, got {value}", param_hint=param.opts[0])
        return value

    return check


#: a threshold: a number not below 0 (infinity allowed)
_not_negative = _number_check(lambda value: value >= 0, "a number not below 0")
#: a time: a finite number
_finite = _number_check(math.isfinite, "a finite number of seconds")


class _Group(click.Group):
    """Turns kinegen errors into one or two readable lines and a distinct exit code."""

    def make_context(self, info_name, args, parent=None, **extra):
        try:
            return super().make_context(info_name, args, parent, **extra)
        except click.UsageError as exc:
            self._usage(exc)

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:  # a subcommand's argument (click's own code, 2, is a model error's here)
            self._usage(exc)
        except RequestError as exc:  # the service layer refused an option: the same usage error as click's own
            self._usage(click.BadParameter(exc.problem, param_hint=exc.option), f"{ctx.command_path} {ctx.invoked_subcommand}")
        except KinegenError as exc:
            if isinstance(exc, OverConstrainedError):  # which joints' equations repeat: the rank at the initial pose
                from kinegen.symbolic.rank import explain

                exc = explain(exc)
            self._fail(ctx, f"error: {exc}", exc.exit_code)
        except BrokenPipeError:  # the reader stopped early (| head): quiet, as Unix tools are
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())  # Python's flush at exit must not fail again
            ctx.exit(ExitCode.BROKEN_PIPE)
        except OSError as exc:
            self._fail(ctx, f"error: {exc}", ExitCode.IO)

    @staticmethod
    def _usage(exc: click.UsageError, command: str | None = None) -> None:
        """A usage error as one line, like every other error (exit 64); kinegen alone shows the help.
        ``command``: the command's path, where the error carries no context."""
        exc.exit_code = ExitCode.USAGE
        if isinstance(exc, click.exceptions.NoArgsIsHelpError):
            raise exc
        command = command or (exc.ctx.command_path if exc.ctx is not None else "kinegen")
        click.echo(printable(f"error: {exc.format_message()} ('{command} --help' lists the options)"), err=True)
        sys.exit(ExitCode.USAGE)

    @staticmethod
    def _fail(ctx: click.Context, message: str, code: int) -> None:
        if ctx.obj and ctx.obj.get("debug"):
            traceback.print_exc()
        # file names and model text reach the terminal as text: no control character acts on it
        click.echo("\n".join(printable(line) for line in message.split("\n")), err=True)
        ctx.exit(code)


@click.group(cls=_Group)
@click.version_option(__version__, prog_name="kinegen")
@click.option("--debug", is_flag=True, help="Show Python tracebacks of errors.")
@click.pass_context
def main(ctx: click.Context, debug: bool) -> None:
    """kinegen: mechanism YAML -> exact symbolic kinematics -> generated solvers."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug
    warnings.simplefilter("always")
    warnings.showwarning = lambda message, category, *_args, **_kw: click.echo(f"warning: {message}", err=True)


PARAM_HELP = (
    f"Orientation parametrization: {', '.join(n for n in rotations.NAMES if not n.startswith('euler:'))} "
    "or euler:<seq> (e.g. euler:zxz)."
)
#: the options most commands share, declared once
PARAM = click.option("--param", default="quaternion", show_default=True, help=PARAM_HELP)
PARAMS = click.option("--param", "params", multiple=True, default=("quaternion",), show_default=True, help=PARAM_HELP + " Repeatable.")
GENERATED_DIR = click.option("--generated-dir", default="generated", show_default=True, help="Where generated modules live.")


def _output_file(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """An output file name checked before any work: it can be written (- is standard output)."""
    if value is None or value == STDOUT:
        return value
    from kinegen.files import writable

    problem = writable(value)
    if problem is not None:
        raise click.BadParameter(f"cannot write {value}: {problem}", ctx=ctx, param=param)
    return value


def _image_file(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """A --plot file name checked before any work: matplotlib can write its type (its suffix), and it can be written."""
    if value is None:
        return None
    from kinegen.figures import image_format

    try:
        image_format(value)
    except ValueError as exc:
        raise click.BadParameter(str(exc), ctx=ctx, param=param) from None
    return _output_file(ctx, param, value)


def _parametrization(name: str) -> rotations.Parametrization:
    try:
        return rotations.get(name)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--param") from None


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@PARAMS
@click.option(
    "--target",
    type=click.Choice(["python", "c"]),
    default="python",
    show_default=True,
    help="python: the importable module and the model's C (compiled by the runtime on first use); "
    "c: a standalone C directory (model, kinegen's C solver, Makefile, CMakeLists.txt, example_main.c).",
)
@click.option(
    "--generated-dir",
    "--out-dir",
    "out_dir",
    default=None,
    type=click.Path(file_okay=False),
    help="Where files are written (default: generated/ for python, as every command's --generated-dir; "
    "<model>_<param>_c/ for c). --out-dir is the same option.",
)
@click.option(
    "--no-sensitivities",
    is_flag=True,
    help="A model with design parameters: leave out the kernels of its exact sensitivities (the larger part of "
    "such a build); the module still solves any design.",
)
@click.option(
    "--derive",
    is_flag=True,
    help="Derive and print the files even when the same build (model bytes, parametrization, options, this kinegen) "
    "was kept in kinegen's cache (docs/generated-modules.md); the bytes are the same either way.",
)
@click.option(
    "--no-compile",
    is_flag=True,
    help="Write the files without compiling the runtime's library of the model's C meanwhile (by default the build "
    "waits for it, cached in ~/.cache/kinegen); a compiled solve then compiles it when first needed.",
)
def build(model_file: str, params: tuple[str, ...], target: str, out_dir: str | None, no_sensitivities: bool, derive: bool,
          no_compile: bool) -> None:  # fmt: skip
    """Build MODEL_FILE into generated/<model>_<param>.py (and .c/.h), or a standalone C directory.

    Before anything is written, every case's time functions are checked on its time grid
    and its initial pose is checked (assembled if needed): a build that fails either check
    writes nothing. The same build asked for again is taken from kinegen's cache (--derive: not)."""
    from kinegen.service.build import build as run

    for name in params:
        report = run(model_file, _parametrization(name).name, target, out_dir, sensitivities=not no_sensitivities, reuse=not derive,
                     compile_library=not no_compile)  # fmt: skip
        click.echo(f"wrote {report.path} ({report.parametrization}, {report.seconds:.2f} s)")
        for line in report.checks:
            click.echo("  " + line)
        if report.program is not None:
            click.echo(f"  build and run it: make -C {report.path} && {report.path}/{report.program} > out.csv")


def _nominal(model):
    """A model with design parameters as numbers: their nominal values (said once on stderr)."""
    if not model.design:
        return model
    click.echo(f"design parameters at their nominal values: {', '.join(f'{d.name} = {float(d.nominal):g}' for d in model.design)}", err=True)
    return model.at()


def _design_values(pairs: tuple[str, ...]) -> dict[str, float]:
    """``--design NAME=VALUE`` options as a mapping."""
    values = {}
    for pair in pairs:
        name, sep, text = pair.partition("=")
        try:
            values[name.strip()] = float(text)
        except ValueError:
            raise click.BadParameter(f"{pair!r} is not NAME=VALUE with a number", param_hint="--design") from None
        if not sep:
            raise click.BadParameter(f"{pair!r} is not NAME=VALUE", param_hint="--design")
    return values


def _session(generated_dir: str):
    """The service layer (:class:`kinegen.api.Session`) of this command over ``generated_dir``:
    one per folder and command, rebuilds said on standard error."""
    from kinegen.api import Session

    sessions = click.get_current_context().meta.setdefault("kinegen.sessions", {})
    if generated_dir not in sessions:
        sessions[generated_dir] = Session(generated_dir, announce=lambda line: click.echo(line, err=True))
    return sessions[generated_dir]


def _system(
    model_file: str,
    param: rotations.Parametrization,
    case: str | None,
    generated_dir: str,
    compiled: bool | None = None,
    design: dict[str, float] | None = None,
):
    """The model and the numeric system of a case (:func:`kinegen.service.requests.case_system`): its
    compiled C when there is a compiler (``compiled`` None), or not (False); a model's design
    parameters at ``design`` (nominal for those not given)."""
    from kinegen.service.requests import case_system

    return case_system(_session(generated_dir), model_file, case, param.name, compiled, design)


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.option("--case", default=None, help="Case to solve (default: the first).")
@PARAM
@click.option("--t0", type=float, default=None, callback=_finite, help="Start time [s] (default: the case's).")
@click.option("--t1", type=float, default=None, callback=_finite, help="End time [s] (default: the case's).")
@click.option("--steps", type=click.IntRange(min=2), default=None, help="Number of time points (default: the case's).")
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=_output_file, help="CSV file for all time histories (- for standard output; the summary then goes to standard error).")
@click.option("--plot", type=click.Path(dir_okay=False), default=None, callback=_image_file,
              help="PNG: the mechanism at six instants in the plane that shows it, with a tip's path; actuator lengths and rates "
              "(or angular speeds), condition number.")
@click.option("--track", "--point", "track", default=None, metavar="BODY.POINT",
              help="--plot: the point whose path is drawn (default: the working range's point, else the farthest named point).")
@click.option("--frame", "frame_body", default=None,
              help="--plot: draw in the x-z plane of this body's frame (default: the first body's when the motion is flatter there, "
              "else the global plane of largest spread).")
@click.option(
    "--keep-going",
    is_flag=True,
    help="On a failed step, stop there but still write the results so far (the failed step marked "
    "converged = 0), then report the error and exit with its code.",
)
@click.option(
    "--no-compile",
    is_flag=True,
    help="Solve with the generated Python functions only (by default the module's C is compiled once with "
    "the machine's C compiler, cached in ~/.cache/kinegen, and solves; without a compiler kinegen says so and uses Python).",
)
@click.option(
    "--design",
    "design",
    multiple=True,
    metavar="NAME=VALUE",
    help="A design parameter's value (repeatable; the others at their nominal values): no rebuild.",
)
@click.option(
    "--sensitivities",
    type=click.Path(dir_okay=False),
    default=None,
    help="CSV file (JSON if it ends in .json) of the exact derivatives of every named point's position, velocity and "
    "acceleration and every actuator length by every design parameter.",
)
@click.option("--view", is_flag=True, help="Also write the motion in 3-D as a self-contained HTML page, beside --out (or in out/).")
@click.option("--force", is_flag=True, help="Solve even when the results would take more than half the memory available.")
@click.option("--load", "loads", multiple=True, metavar="NAME",
              help="A load of the model the machine holds (repeatable): report the actuation forces, the cylinder pressures "
              "against their relief and holding settings, and the joint reactions (columns added to --out).")  # fmt: skip
@click.option("--dynamics", is_flag=True,
              help="Add the bodies' weight and inertia along the motion (inverse dynamics; a model with masses): the forces "
              "that move the machine, with --load also holding the loads, and its kinetic and potential energy (columns added to --out).")  # fmt: skip
@click.option("--no-weight", is_flag=True,
              help="With --load on a model with masses: hold the loads alone, without the bodies' own weight "
              "(by default the weight is held too, and the output says so).")  # fmt: skip
@click.option("--timing", type=click.Path(dir_okay=False, exists=True), default=None,
              help="A re-timing of the case written by `kinegen cycle --out`: solve the case's path at that timing, at its points.")  # fmt: skip
@GENERATED_DIR
def solve(
    model_file: str,
    case: str | None,
    param: str,
    t0: float | None,
    t1: float | None,
    steps: int | None,
    out: str | None,
    plot: str | None,
    track: str | None,
    frame_body: str | None,
    keep_going: bool,
    no_compile: bool,
    design: tuple[str, ...],
    sensitivities: str | None,
    view: bool,
    force: bool,
    loads: tuple[str, ...],
    dynamics: bool,
    no_weight: bool,
    timing: str | None,
    generated_dir: str,
) -> None:
    """Solve position, velocity and acceleration of a case over time; every time point where an
    actuator leaves its range is reported. With --load, also the forces that hold the loads (and the
    machine's own weight, where the model declares masses); with --dynamics, the forces that move the
    machine (its weight and inertia) and its energies."""
    from kinegen.service import solve as service
    from kinegen.service.requests import check_frame, named_point

    parametrization = _parametrization(param)
    plan = service.plan(
        _session(generated_dir), model_file, case, parametrization.name, t0=t0, t1=t1, steps=steps, loads=loads,
        dynamics=dynamics, weight=not no_weight, timing=timing, keep_going=keep_going, compiled=False if no_compile else None,
        design=_design_values(design), force=force,
    )  # fmt: skip
    model, system, times = plan.model, plan.system, plan.times
    point = named_point(system, track)
    if plot:
        check_frame(system, frame_body)
    report = service.run(plan)
    results, elapsed, held, supplied = report.results, report.elapsed, report.held, report.supplied
    done = results.converged
    piped = out == STDOUT  # the CSV on standard output: everything else on standard error
    if design:
        click.echo("design: " + ", ".join(f"{name} = {value:g}" for name, value in system.design.items()), err=piped)
    click.echo(
        f"{system.model}/{system.case} [{parametrization.name}]: {int(done.sum())} of {len(times)} time points, "
        f"t = {times[0]:g} .. {results.times[-1]:g} s, Newton iterations mean {results.iterations[done].mean():.2f} "
        f"max {results.iterations[done].max()}, max |Phi| {results.residuals[done].max():.1e}, {elapsed:.3f} s",
        err=piped,
    )
    if held is not None:
        _report_forces(held, model, piped)
    elif report.forces_missed:
        click.echo(f"forces: not computed -- the solve stopped at t = {results.times[-1]:g} s and forces need every time point; "
                   "the CSV has no force columns", err=True)  # fmt: skip
    if supplied is not None:
        _report_supply(supplied, piped)
    if out:
        extra = [t for t in (held.table() if held is not None else None, supplied.table() if supplied is not None else None) if t]
        joined = ([n for names, _ in extra for n in names], np.hstack([values for _, values in extra])) if extra else None
        from kinegen.runtime.export import to_csv

        written = to_csv(results, out, joined)
        if not piped:
            click.echo(f"wrote {written}")
    if sensitivities:
        if not system.design:
            raise click.BadParameter("the model has no design parameters (a design: section)", param_hint="--sensitivities")
        from kinegen.runtime.sensitivity import sensitivities_to_csv, sensitivities_to_json

        write = sensitivities_to_json if sensitivities.endswith(".json") else sensitivities_to_csv
        click.echo(f"wrote {write(results, sensitivities)}", err=piped)
    if plot:
        from kinegen.analysis.plots import plot_case

        trace, frame = _picture_plane(results, model, frame_body, point)
        click.echo(f"wrote {plot_case(results, plot, frame, trace, model=model)}", err=piped)
    _report_ranges(results)
    if view:
        from kinegen.analysis.view import motion_view

        page = Path(out).with_suffix(".html") if out and not piped else Path("out") / f"{system.model}_{system.case}.html"
        click.echo(f"wrote {motion_view(results, model, page, title=f'{system.model} / {system.case}')}", err=piped)
    if results.failure is not None:
        raise results.failure


def _picture_plane(results, model, frame_body: str | None, point: tuple[str, str] | None = None) -> tuple[tuple[str, str] | None, str | None]:
    """The point a picture traces (``point``, else the model's tracked point) and the body whose
    x-z plane it is drawn in (``frame_body``, else the one that shows the motion best)."""
    from kinegen.analysis.plots import best_frame, tracked_point

    track = point or tracked_point(results, model)
    return track, frame_body if frame_body is not None else best_frame(results, track)


def _pressure_text(pressure: float) -> str:
    """A pressure [Pa] in MPa to 0.1 from 1 bar up, in kPa to 3 figures below (no "0.0 MPa")."""
    return f"{pressure / 1e6:.1f} MPa" if pressure >= 1e5 else f"{pressure / 1e3:.3g} kPa"


def _report_forces(held, model, piped: bool) -> None:
    """What the forces hold (the loads, the machine's weight, its inertia), the peak of every
    actuation force and cylinder pressure, the largest pin reactions, and every pressure beyond its
    relief or holding setting."""
    from kinegen.model.schema import design_value

    times = held.results.times
    design = held.results.system.design
    mass = sum(design_value(b.inertia.mass, design) for b in model.massive)
    bodies = f"{len(model.massive)} bod{'ies' if len(model.massive) != 1 else 'y'}, {mass:,.0f} kg"
    held_parts = list(held.loads)
    if held.inertia:
        held_parts.insert(0, f"moving the machine (its weight and inertia: {bodies})")
    elif held.weight:
        held_parts.append(f"the machine's own weight ({bodies}; --no-weight leaves it out)")
    elif model.massive:
        held_parts.append("not the machine's weight (--no-weight)")
    words = held_parts[0] if held.inertia else "holding " + held_parts[0]
    if len(held_parts) > 1:
        words += (" and holding " if held.inertia else ", ") + ", ".join(held_parts[1:])
    click.echo(f"forces {words}:", err=piped)
    rounding = 1e-9 * max(1.0, float(np.abs(held.force).max()))  # a force this small is the solve's rounding
    for k, element in enumerate(held.elements):
        values = held.force[:, k]
        i = int(np.argmax(np.abs(values)))
        peak = float(np.abs(values).max())
        kilo = peak >= 1e3  # kN (kN m) from 1 kN up, N (N m) below: no "0.00 .. 0.00 kN"
        scale, unit = (1e3, "k" + element.unit) if kilo else (1.0, element.unit)
        low, high = (round(float(x) / scale, 2) + 0.0 for x in (values.min(), values.max()))  # + 0.0: no "-0.00"
        if peak <= rounding:
            line = f"  {element.name:<20} {'0':>10} {element.unit}: carries nothing here (|f| <= {peak:.0e} {element.unit}, rounding)"
        else:
            line = f"  {element.name:<20} {low:10.2f} .. {high:8.2f} {unit}, peak at t = {times[i]:g} s"
        parallel = [name for name, lead in held.parallel.items() if lead == element.name]
        if parallel:
            line += f" (each of {', '.join([element.name, *parallel])})"
        pressure = held.pressures.get(element.name)
        if pressure is not None and peak > rounding:
            j = int(np.argmax(pressure.pressure / pressure.limit))
            line += (f"; pressure up to {_pressure_text(pressure.pressure[j])} ({'cap' if pressure.cap_side[j] else 'rod'} side) "
                     f"of {_pressure_text(pressure.limit[j])} {'relief' if pressure.working[j] else 'holding'}")  # fmt: skip
        click.echo(line, err=piped)
    peaks = sorted(((float(np.linalg.norm(r.force, axis=1).max()), name) for name, r in held.reactions.items()), reverse=True)
    click.echo("  largest pin forces: " + ", ".join(f"{name} {value / 1e3:.1f} kN" if value >= 1e3 else f"{name} {value:.1f} N"
                                                    for value, name in peaks[:4]), err=piped)  # fmt: skip
    if held.energies is not None:
        e = held.energies
        click.echo(f"  energy: kinetic up to {e.kinetic.max() / 1e3:.2f} kJ, potential {e.potential.min() / 1e3:.1f} .. "
                   f"{e.potential.max() / 1e3:.1f} kJ", err=piped)  # fmt: skip
    if held.tipping is not None:
        k = int(np.argmin(held.tipping.margin))
        margin = held.tipping.margin[k]
        click.echo(f"  tipping margin: smallest {margin / 1e3:.1f} kN m about the {held.tipping.line[k]} tipping line at t = {times[k]:g} s",
                   err=piped)  # fmt: skip
        if margin < 0:
            unstable = held.tipping.margin < 0
            click.echo(f"TIPPING: the machine would tip about its {held.tipping.line[k]} tipping line at {int(unstable.sum())} of "
                       f"{len(times)} time points, t = {times[unstable][0]:g} .. {times[unstable][-1]:g} s", err=piped)  # fmt: skip
    by_actuator: dict[str, list] = {}
    for t, name, value, limit, what in held.violations():
        by_actuator.setdefault(name, []).append((t, value, limit, what))
    for name, hits in by_actuator.items():
        worst = max(hits, key=lambda h: h[1] / h[2])
        click.echo(
            f"PRESSURE: {name} beyond its setting at {len(hits)} of {len(times)} time points, t = {hits[0][0]:g} .. {hits[-1][0]:g} s; "
            f"worst {worst[1] / 1e6:.1f} MPa against {worst[2] / 1e6:.1f} MPa ({worst[3]}) at t = {worst[0]:g} s",
            err=piped,
        )


def _report_supply(supplied, piped: bool) -> None:
    """Each pump's largest demanded flow against its limit (and, with forces, its pressure and power),
    then a FLOW: line per span where a pump's demand exceeds its largest flow and a POWER: line per
    span where the pumps need more than the engine gives."""
    from kinegen.forces.supply import LITRES_PER_MINUTE as LPM

    click.echo("pumps:", err=piped)
    for p, name in enumerate(supplied.pumps):
        k = int(np.argmax(supplied.flow[p]))
        line = f"  {name:<20} flow up to {supplied.flow[p, k] * LPM:7.0f} L/min of {supplied.max_flow[p] * LPM:.0f} L/min (t = {supplied.times[k]:g} s)"
        if supplied.power is not None:
            j = int(np.argmax(supplied.power[p]))
            line += f"; power up to {supplied.power[p, j] / 1e3:.1f} kW at {supplied.pressure[p, j] / 1e6:.1f} MPa (t = {supplied.times[j]:g} s)"
        click.echo(line, err=piped)
    if supplied.power is not None:
        total = supplied.power.sum(axis=0)
        k = int(np.argmax(total))
        click.echo(f"  engine: the pumps take up to {total[k] / 1e3:.1f} kW of {supplied.engine_power / 1e3:.0f} kW (t = {supplied.times[k]:g} s)",
                   err=piped)  # fmt: skip
    for name, t0, t1, largest, at in supplied.flow_excesses():
        limit = supplied.max_flow[supplied.pumps.index(name)]
        click.echo(f"FLOW: pump {name} asked more than its {limit * LPM:.0f} L/min, t = {t0:g} .. {t1:g} s; up to {largest * LPM:.0f} L/min "
                   f"({largest / limit:.2f} times) at t = {at:g} s")  # fmt: skip
    for t0, t1, largest, at in supplied.power_excesses():
        click.echo(f"POWER: the pumps need more than the engine's {supplied.engine_power / 1e3:.0f} kW, t = {t0:g} .. {t1:g} s; up to "
                   f"{largest / 1e3:.1f} kW at t = {at:g} s")  # fmt: skip


def _report_ranges(results) -> None:
    """Each actuator that leaves its range: how often, when, and how far."""
    from kinegen.runtime.kinematics import range_violations

    by_actuator: dict[str, list] = {}
    for t, name, value, limits in range_violations(results):
        by_actuator.setdefault(name, []).append((t, value, limits))
    for name, hits in by_actuator.items():
        limits = hits[0][2]
        worst = max(hits, key=lambda h: max(limits[0] - h[1], h[1] - limits[1]))
        click.echo(
            f"RANGE: {name} outside [{limits[0]:g}, {limits[1]:g}] m at {len(hits)} of {len(results.times)} time points, "
            f"t = {hits[0][0]:g} .. {hits[-1][0]:g} s; farthest {worst[1]:.4f} m at t = {worst[0]:g} s"
        )


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@PARAM
@click.option("--case", default=None, help="Case whose drivers are used (default: the first).")
@click.option("--at", "at", default=None, help="Time within the case's range, exact expression allowed (e.g. 0, 1/2, pi/4). Default: the case start.")
@click.option(
    "--q",
    "q_file",
    type=click.Path(dir_okay=False),
    default=None,
    help="Stored coordinates: a JSON file {coordinate name: value}, or the JSON itself ({...}, or [...] in stored order).",
)
@click.option("--latex", is_flag=True, help="Also print the determinant in LaTeX.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON report instead of text.")
@click.option("--budget", type=click.FloatRange(min=0, min_open=True, max=86_400), default=60.0, show_default=True,
              help="Seconds of exact symbolic work allowed (the determinant is left out, or the inspection stops naming Phi_q's blocks, when they run out).")  # fmt: skip
@click.option("--full", is_flag=True, help="Print long determinants in full (by default one longer than 600 characters is summarised).")
@click.option("--det-file", type=click.Path(dir_okay=False), default=None, callback=_output_file, help="Write every symbolic determinant in full into this file.")
@GENERATED_DIR
def inspect(
    model_file: str,
    param: str,
    case: str | None,
    at: str | None,
    q_file: str | None,
    latex: bool,
    as_json: bool,
    budget: float,
    full: bool,
    det_file: str | None,
    generated_dir: str,
) -> None:
    """Exact rank, null spaces and symbolic determinant of Phi_q at one configuration."""
    from kinegen.service import inspection as service

    session = _session(generated_dir)
    _nominal(session.model(model_file))  # said once
    q, where = _configuration(q_file) if q_file else (None, "")
    plan = service.plan(session, model_file, _parametrization(param).name, case, at, q, where, budget, every_block=as_json or bool(det_file))
    found = service.run(plan)
    report, verdict = found.inspection, found.verdict
    if det_file:
        from kinegen.files import write_atomic

        write_atomic(Path(det_file), report.determinants())
    if as_json:
        click.echo(json.dumps(found.document(), indent=2))
        return
    click.echo(report.text(full=full))
    if verdict:
        click.echo(verdict.text())
    if latex:
        click.echo(report.latex())
    if det_file:
        click.echo(f"wrote {det_file}")


def _configuration(q: str) -> tuple[object, str]:
    """``--q``: inline JSON (an object {name: value} or a list in stored order) or a JSON file of
    the object, parsed; and how errors name it (kinegen.service.inspection checks the values)."""
    text = q.strip()
    inline = text.startswith(("{", "["))
    if not inline:
        try:
            text = read_bounded(q, 10_000_000).decode("utf-8", errors="replace")
        except OSError as exc:
            raise click.BadParameter(f"cannot read {q!r}: {exc.strerror or exc} (give a JSON file, or the JSON itself)", param_hint="--q") from None
    where = "the inline JSON" if inline else q
    try:
        return json.loads(text), where
    except (ValueError, RecursionError) as exc:
        raise click.BadParameter(f"{where} is not valid JSON: {exc}", param_hint="--q") from None


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.option("--case", default=None, help="Case to solve (default: the first).")
@click.option(
    "--param", "params", multiple=True, default=None,
    help="Parametrizations to compare (repeatable; default: quaternion, euler-parameters, dual-quaternion, "
    "dual-euler-parameters, euler:zxz, euler:zxy).",
)  # fmt: skip
@click.option("--no-compile", is_flag=True, help="Leave out the compiled solve time.")
@click.option("--json", "as_json", is_flag=True, help="Print the table as JSON.")
def compare(model_file: str, case: str | None, params: tuple[str, ...], no_compile: bool, as_json: bool) -> None:
    """Build and solve one case in every parametrization; one table of sizes, build and solve
    costs, Newton iterations, scaled condition numbers, the largest converging step, and where
    each parametrization is singular."""
    from kinegen.service import parametrizations

    session = _session("generated")  # (each parametrization is built in a folder of its own)
    _nominal(session.model(model_file))  # said first: the design parameters are held at their nominal values
    names = tuple(_parametrization(p).name for p in params) or None
    report = parametrizations.compare(session, model_file, case, names, compiled=not no_compile)
    click.echo(json.dumps(report.document(), indent=2) if as_json else report.text())


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.option("--case", default=None, help="Case to show (default: the first).")
@PARAM
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=_output_file, help="The HTML page (default: out/<model>_<case>.html).")
@click.option("--track", "--point", "track", default=None, metavar="BODY.POINT", help="The point whose path is drawn (default: the working range's point).")
@click.option("--condition-warning", type=float, default=1e6, show_default=True, callback=_not_negative,
              help="Bodies turn orange where cond(Phi_q) exceeds this.")
@click.option("--animate", type=click.Path(dir_okay=False), default=None, help="Also a .gif (or .mp4, with ffmpeg) of the motion in one plane.")
@click.option("--frame", "frame_body", default=None, help="--animate: draw in the x-z plane of this body's frame (default: as solve --plot chooses).")
@click.option("--design", "design", multiple=True, metavar="NAME=VALUE", help="A design parameter's value (repeatable).")
@GENERATED_DIR
def view(
    model_file: str,
    case: str | None,
    param: str,
    out: str | None,
    track: str | None,
    condition_warning: float,
    animate: str | None,
    frame_body: str | None,
    design: tuple[str, ...],
    generated_dir: str,
) -> None:
    """Solve a case and write its motion in 3-D as one self-contained HTML page (orbit and zoom
    with the mouse, a time slider, play/pause; no network needed to open it)."""
    from kinegen.analysis.view import motion_view
    from kinegen.service import view as service

    plan = service.plan(_session(generated_dir), model_file, _parametrization(param).name, case, track, frame_body, _design_values(design))
    model, system, point, results = plan.model, plan.system, plan.point, service.run(plan).results
    page = Path(out) if out else Path("out") / f"{system.model}_{system.case}.html"
    click.echo(f"wrote {motion_view(results, model, page, f'{system.model} / {system.case}', point, condition_warning)}")
    if animate:
        from kinegen.analysis.animation import animate as write_animation

        track_point, frame = _picture_plane(results, model, frame_body, point)
        try:
            click.echo(f"wrote {write_animation(results, animate, frame, track_point, model=model)}")
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="--animate") from None
    _report_ranges(results)
    if results.failure is not None:
        raise results.failure


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@PARAM
@click.option("--json", "as_json", is_flag=True, help="Print the tool forces (or the lift chart) as JSON.")
@click.option("--lift", is_flag=True, help="The hydraulic lift capacity at the arm's end over the model's lift_chart grid instead "
              "(the hydraulic half of an ISO 10567 lift chart).")  # fmt: skip
@click.option("--map", "direction", type=click.Choice(["pull", "push", "up", "down", "tangent"]), default=None,
              help="A force map instead: over a grid of the working range, the largest force the tool point can exert in this "
              "direction and the cylinder that limits it (tangent: the bucket digging direction).")  # fmt: skip
@click.option("--plot", type=click.Path(dir_okay=False), default=None, callback=_image_file, help="--map: PNG of the map on the working range.")
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=_output_file, help="--map: CSV of every pose (inputs, tool point, force, limiting cylinder).")
@click.option("--no-compile", is_flag=True, help="Use the generated Python functions only.")
@GENERATED_DIR
def forces(model_file: str, param: str, as_json: bool, lift: bool, direction: str | None, plot: str | None, out: str | None,
           no_compile: bool, generated_dir: str) -> None:  # fmt: skip
    """ISO 6015 tool forces (hydraulic limit) of the model's `tool_forces` section: the bucket digging
    force and the arm crowd force at the lip, each at the position of the front that gives the
    largest, with the circuit that limits it (the working cylinder's relief setting or another's
    holding setting) and the published figures beside them; --lift: the hydraulic lift capacity
    table (docs/forces.md)."""
    from kinegen.forces.iso6015 import document, report
    from kinegen.service import charts

    if lift and direction is not None:
        raise click.BadParameter("--lift and --map are two different charts: give one", param_hint="--map")
    if lift and (plot or out):
        raise click.BadParameter("--plot and --out go with --map here (the lift chart's: `kinegen lift --plot/--out`)",
                                 param_hint="--plot" if plot else "--out")  # fmt: skip
    if direction is None and (plot or out):
        raise click.BadParameter("--plot and --out go with --map", param_hint="--plot" if plot else "--out")
    session, name, compiled = _session(generated_dir), _parametrization(param).name, False if no_compile else None
    if lift:
        _lift(charts.lift(session, model_file, name, compiled), as_json)
        return
    if direction is not None:
        _force_map(charts.force_map(session, model_file, direction, name, compiled, picture=bool(plot)), plot, out)
        return
    found = charts.tool_forces(session, model_file, name, compiled)
    if as_json:
        click.echo(json.dumps(document(found.found, found.model, found.seconds), indent=2))
        return
    click.echo(report(found.found, found.model, found.seconds))


def _force_map(report, plot: str | None, out: str | None) -> None:
    """kinegen forces --map: the map's summary, its CSV and its picture (a ForceMapReport)."""
    from kinegen.files import write_atomic
    from kinegen.forces.maps import MEANING, plot_force_map

    found, model, direction = report.found, report.model, report.direction
    best = int(np.argmax(found.force))
    shares = ", ".join(f"{name} {np.mean(found.limiting == name):.0%}" for name in sorted(set(found.limiting)))
    click.echo(f"{model.name}: the largest force at {found.point} {MEANING[direction]}, every cylinder at most at its relief setting: "
               f"{len(found.force):,} poses in {found.seconds:.2f} s")  # fmt: skip
    click.echo(f"  up to {found.force[best] / 1e3:.1f} kN, at x {found.points[best, 0]:.2f}, z {found.points[best, 2]:.2f} m "
               f"(limited by {found.limiting[best]}); limited by: {shares}")  # fmt: skip
    if out:
        write_atomic(Path(out), found.to_csv())
        click.echo(f"wrote {out}")
    if plot:  # the picture: the largest force at each place over the tool's attitude, a smooth function of the place
        smooth = report.smooth
        i, j = np.unravel_index(np.nanargmax(smooth.force), smooth.force.shape)
        click.echo(f"  over the tool's attitude ({smooth.attitude_input}; {smooth.poses:,} poses in {smooth.seconds:.1f} s): up to "
                   f"{smooth.force[i, j] / 1e3:.1f} kN, at x {smooth.radius[j]:.2f}, z {smooth.height[i]:.2f} m")  # fmt: skip
        click.echo(f"wrote {plot_force_map(smooth, plot, report.boundary)}")


def _lift(report, as_json: bool, out: str | None = None, plot: str | None = None) -> None:
    """kinegen lift (and kinegen forces --lift): the lift chart's table, or its JSON; its CSV to
    ``out``, its picture to ``plot`` (a LiftReport)."""
    from kinegen.files import write_atomic

    chart = report.chart
    if out:
        write_atomic(Path(out), chart.csv_text())
    if plot:
        from kinegen.forces.lift import plot_lift_chart

        plot_lift_chart(chart, plot, report.boundary)
    if not as_json:
        click.echo(chart.table())
        wrote = ", ".join(x for x in (out, plot) if x)
        click.echo(f"[{report.seconds:.2f} s]" + (f"; wrote {wrote}" if wrote else ""))
        return
    click.echo(json.dumps({"model": report.model.name, **chart.document()}, indent=2))


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.option("--case", default=None, help="The case whose path is re-timed (default: the first).")
@PARAM
@click.option("--load", "loads", multiple=True, metavar="NAME", help="A load of the model held along the path (repeatable), "
              "besides the machine's weight and inertia.")  # fmt: skip
@click.option(
    "--steps",
    type=click.IntRange(min=3),
    default=None,
    help="Points along the path where every limit is met (default: the case's).",
)
@click.option(
    "--no-tipping",
    is_flag=True,
    help="Leave the tipping margin out (by default it stays >= 0 where the model has a machine: section).",
)
@click.option("--max-speed", "speed_limits", multiple=True, metavar="ACTUATOR=VALUE",
              help="An actuator's largest speed [m/s; a motor's joint: rad/s] (repeatable).")  # fmt: skip
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=_output_file,
              help="CSV of the re-timing (t, s, ds/dt, d2s/dt2 and the limit per point): `kinegen solve --timing` solves it.")  # fmt: skip
@click.option("--plot", type=click.Path(dir_okay=False), default=None, callback=_image_file,
              help="PNG: the path speed along the path coloured by its limit; the pumps' flows and the engine's power along the cycle.")  # fmt: skip
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--no-compile", is_flag=True, help="Use the generated Python functions only.")
@GENERATED_DIR
def cycle(model_file: str, case: str | None, param: str, loads: tuple[str, ...], steps: int | None, no_tipping: bool,
          speed_limits: tuple[str, ...], out: str | None, plot: str | None, as_json: bool, no_compile: bool, generated_dir: str) -> None:  # fmt: skip
    """The fastest timing of a case's path (the same poses, re-timed): every pump's flow and the
    engine's power, every cylinder's pressure within its relief or holding setting and the motors'
    torque within their pumps' pressure (with the machine's weight and inertia and the --load), the
    tipping margin >= 0, and --max-speed -- met at every point of the path (docs/cycle.md)."""
    from kinegen.forces.cycle import write_timing
    from kinegen.service import cycle as service

    parametrization = _parametrization(param)
    limits = {}
    for pair in speed_limits:
        name, _, value = pair.partition("=")
        try:
            limits[name] = float(value)
        except ValueError:
            raise click.BadParameter(f"expected ACTUATOR=VALUE, got {pair!r}", param_hint="--max-speed") from None
    plan = service.plan(_session(generated_dir), model_file, case, parametrization.name, loads=loads, steps=steps,
                        tipping=not no_tipping, speed_limits=limits, compiled=False if no_compile else None)  # fmt: skip
    report = service.run(plan)
    model, system, times, found, checked, elapsed = plan.model, plan.system, plan.times, report.found, report.checked, report.elapsed
    say = (lambda line: click.echo(line, err=True)) if as_json else click.echo
    held = report.held
    say(f"{system.model}/{system.case} [{parametrization.name}]: fastest timing {found.duration:.2f} s, the case's own "
        f"{found.own_duration:.2f} s ({found.duration / found.own_duration:.2f} times){'; holding ' + ', '.join(held) if held else ''}; "
        f"{len(times)} points, {elapsed:.2f} s")  # fmt: skip
    share = report.share
    say(
        "  limits (share of the cycle time): "
        + ", ".join(f"{name} {100 * value:.0f} %" for name, value in share.items() if value >= 0.005)
    )
    say("  phases (re-timed t, the case's own s):")
    for name, s0, s1, t0, t1 in report.phases:
        say(f"    t {t0:6.2f} .. {t1:6.2f} s   s {s0:6.2f} .. {s1:6.2f} s   {name}")
    for line in checked.lines():
        say("  " + line)
    if out:
        write_timing(found, out)
        solve_line = (f"kinegen solve {model_file} --case {system.case} --timing {out}" + "".join(f" --load {n}" for n in found.loads)
                      + (" --dynamics" if model.massive else "") + (f" --param {param}" if param != "quaternion" else ""))  # fmt: skip
        say(f"wrote {out} (solve the re-timed case: {solve_line})")
    if plot:
        from kinegen.analysis.cycleplot import plot_cycle

        say(f"wrote {plot_cycle(found, plot, checked.flows)}")
    if as_json:
        click.echo(json.dumps(checked.document(found, parametrization.name, share, report.phases), indent=2))


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@PARAM
@click.option("--json", "as_json", is_flag=True, help="Print the chart as JSON.")
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=_output_file, help="CSV of every grid point (capacities, ratings, limits).")
@click.option("--plot", type=click.Path(dir_okay=False), default=None, callback=_image_file,
              help="PNG of the chart over the working range's outline.")  # fmt: skip
@click.option("--no-compile", is_flag=True, help="Use the generated Python functions only.")
@GENERATED_DIR
def lift(model_file: str, param: str, as_json: bool, out: str | None, plot: str | None, no_compile: bool, generated_dir: str) -> None:
    """ISO 10567 lift chart of the model's `lift_chart` section: at the arm's end, over its grid of
    heights and radii, over the front and over the side, the rated lift capacity -- the smaller of
    87 % of the hydraulic lift capacity (the lifting cylinder at its relief setting, the others
    holding, the front's own weight held) and 75 % of the tipping load (a model with masses and a
    machine: section) -- with the limit that applies (docs/dynamics.md)."""
    from kinegen.service import charts

    found = charts.lift(_session(generated_dir), model_file, _parametrization(param).name, False if no_compile else None, bool(plot))
    _lift(found, as_json, out, plot)


@main.command()
@click.option("--copy", "destination", type=click.Path(file_okay=False), help="Copy the example models into this folder.")
@click.option("--force", is_flag=True, help="With --copy: replace files that are already there and differ.")
def models(destination: str | None, force: bool) -> None:
    """The example models shipped with kinegen (the paper's boom, the ZX200 excavator, closed-form
    mechanisms): where they are installed, what each holds; --copy DIR to get editable copies."""
    from kinegen.examples import copy_models, example_models, models_folder, summary

    if destination is not None:
        copied = copy_models(Path(destination), overwrite=force)
        for c in copied:
            click.echo(f"{c.outcome:<8} {c.path}")
        kept = [c for c in copied if c.outcome == "kept"]
        if kept:
            click.echo(f"{len(kept)} file(s) already there and different, left alone (--force replaces them)", err=True)
        return
    click.echo(f"example models of kinegen {__version__} in {models_folder()}:")
    for path in example_models():
        model = summary(path)
        cases = ", ".join(model.cases)
        bodies = f"{model.bodies} bod{'y' if model.bodies == 1 else 'ies'}"
        click.echo(f"  {path.name:<18} {bodies:>9}; cases: {cases}")
        click.echo(f"  {'':<18} {model.description}")
    click.echo("kinegen models --copy DIR copies them; kinegen info FILE tells more of one")


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.option("--param", "params", multiple=True, help=PARAM_HELP + f" Repeatable (default: {', '.join(rotations.SHOWN)}).")
def info(model_file: str, params: tuple[str, ...]) -> None:
    """What MODEL_FILE holds: bodies, joints, cases and their time grids, actuators and ranges,
    design parameters and studies, coordinates and equations per parametrization."""
    from kinegen.textcache import cached_text

    names = tuple(_parametrization(p).name for p in params) or rotations.SHOWN
    try:
        source = read_bounded(model_file, MAX_MODEL_BYTES)
    except OSError:
        source = None  # the loader names the file and what is wrong

    def describe() -> str:
        from kinegen.analysis.info import describe
        from kinegen.model import load, loads

        # the bytes read once: the cache's key is what is described
        model = load(model_file) if source is None else loads(source, "<stdin>" if model_file == STDIN else model_file)
        return describe(model, names)

    # the same bytes described by the same kinegen: from the cache (no SymPy to import)
    click.echo(describe() if source is None else cached_text("info", source, ",".join(names), describe))


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@PARAM
@click.option("--grid", default=None, help="Samples per swept input, e.g. 25,13,25 (default: 21,11,21).")
@click.option("--plot", type=click.Path(dir_okay=False), default=None, callback=_image_file, help="PNG of the working-range chart (exact boundary, dimensions).")
@click.option("--boundary", "boundary_file", type=click.Path(dir_okay=False), default=None, callback=_output_file,
              help="Write the exact boundary's points: CSV (.csv) or JSON (.json).")
@click.option("--json", "as_json", is_flag=True, help="Print the figures (and the boundary) as JSON.")
@GENERATED_DIR
def envelope(model_file: str, param: str, grid: str | None, plot: str | None, boundary_file: str | None, as_json: bool, generated_dir: str) -> None:
    """Working range of the model's `working_range` point over its input ranges: its figures (and, for a
    model with design parameters, their exact sensitivities), its exact boundary (--boundary, --json,
    --plot)."""
    from kinegen.analysis.chart import outlines, plot_envelope
    from kinegen.files import write_atomic
    from kinegen.service import envelope as service

    counts = None
    if grid:
        try:
            counts = tuple(int(x) for x in grid.split(","))
        except ValueError:
            raise click.BadParameter("expected whole numbers separated by commas", param_hint="--grid") from None
    if boundary_file and Path(boundary_file).suffix.lower() not in (".csv", ".json"):
        raise click.BadParameter("expected a .csv or .json file name", param_hint="--boundary")
    plan = service.plan(_session(generated_dir), model_file, _parametrization(param).name, counts,
                        boundary=bool(plot or boundary_file or as_json))  # fmt: skip
    report = service.run(plan)
    model, system, result, boundary, sensitivities = plan.model, plan.system, report.result, report.boundary, report.sensitivities
    if as_json:
        click.echo(json.dumps(report.document(), indent=2))
    else:
        click.echo(result.table())
        click.echo(
            f"{len(result.samples)} configurations sampled in batches ({result.grid_seconds:.2f} s), "
            f"{result.solves} Newton solves, {result.seconds:.1f} s in all"
        )
        if sensitivities:
            names = list(system.design)
            click.echo("\nexact sensitivities of the figures (envelope theorem), m per unit of each design parameter:")
            click.echo(f"{'figure':<22}" + "".join(f" {n:>14}" for n in names))
            scale = max((abs(v) for values in sensitivities.values() for v in values.values()), default=0.0)
            for figure, values in sensitivities.items():
                click.echo(f"{figure:<22}" + "".join(f" {_table_number(values[n], scale):>14}" for n in names))
        if result.front is not None:
            click.echo(f"min_front_swing_radius {result.front.radius:.3f} m, at {', '.join(result.front.farthest)} (a min-max: its "
                       "sensitivity is not computed, it is not differentiable where points tie)")
        if boundary is not None:
            click.echo(
                f"exact boundary: {len(boundary.points) - 1} points on {len(set(boundary.curve.tolist()))} curves, "
                f"{len(boundary.switching)} switching points, chord error {1e3 * boundary.chord_error:.3f} mm, {boundary.seconds:.1f} s"
            )
    if boundary_file:
        text = boundary.to_csv() if Path(boundary_file).suffix.lower() == ".csv" else json.dumps(boundary.document(), indent=1)
        write_atomic(Path(boundary_file), text)
        click.echo(f"wrote {boundary_file}", err=as_json)
    if plot:
        click.echo(f"wrote {plot_envelope(result, system, plot, boundary, outlines(model))}", err=as_json)


def _table_number(value: float, scale: float) -> str:
    """A table entry: what is zero to rounding against the table's largest entry (1e-10 of it) as 0."""
    return "0" if abs(value) <= 1e-10 * scale else f"{value:.6g}"


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.option("--case", default=None, help="Case to scan (default: the first).")
@PARAMS
@click.option(
    "--warn",
    "warn_ratio",
    type=float,
    default=1e-3,
    show_default=True,
    callback=_not_negative,
    help="Warn when a diagonal block's sigma_min/sigma_max falls below this.",
)
@click.option(
    "--horizon",
    type=click.IntRange(min=1),
    default=20,
    show_default=True,
    help="Warn when the trend reaches a singularity within this many steps.",
)
@click.option(
    "--plot", type=click.Path(dir_okay=False), default=None, callback=_image_file, help="PNG of sigma_min/sigma_max and condition number against time."
)
@GENERATED_DIR
def scan(
    model_file: str,
    case: str | None,
    params: tuple[str, ...],
    warn_ratio: float,
    horizon: int,
    plot: str | None,
    generated_dir: str,
) -> None:
    """Smallest singular value and condition of Phi_q along a case, per parametrization."""
    from kinegen.analysis.scan import plot_scan
    from kinegen.service import parametrizations

    names = tuple(_parametrization(name).name for name in params)
    report = parametrizations.scan(_session(generated_dir), model_file, case, names, warn_ratio, horizon)
    click.echo(report.text())
    if plot:
        click.echo(f"wrote {plot_scan(report.result, plot, report.title)}")


@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.option("--study", "study_name", required=True, help="The design study to run (the model's studies: section).")
@PARAM
@click.option("--method", type=click.Choice(["SLSQP", "trust-constr"]), default="SLSQP", show_default=True, help="SciPy's optimizer.")
@click.option(
    "--gradients",
    type=click.Choice(["exact", "fd"]),
    default="exact",
    show_default=True,
    help="exact: the generated sensitivities (and the envelope theorem for working-range figures); fd: SciPy's finite differences.",
)
@click.option("--compare-fd", is_flag=True, help="Run the study again with finite-difference gradients and compare the two runs.")
@click.option("--max-iterations", type=click.IntRange(min=1), default=100, show_default=True)
@click.option(
    "--out",
    type=click.Path(dir_okay=False),
    default=None,
    help="Where the optimized model is written (default: out/<model>_<study>.yaml); never over the input.",
)
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON (progress goes to stderr).")
@GENERATED_DIR
def optimize(
    model_file: str,
    study_name: str,
    param: str,
    method: str,
    gradients: str,
    compare_fd: bool,
    max_iterations: int,
    out: str | None,
    as_json: bool,
    generated_dir: str,
) -> None:
    """Run a design study declared in MODEL_FILE (studies:) with SciPy on exact gradients: prints
    the iterations, the optimum beside the nominal design, the active constraints; writes the
    optimized model as a new YAML file."""
    from kinegen.analysis.studies import write_optimized
    from kinegen.service import study as service

    plan = service.plan(_session(generated_dir), model_file, study_name, _parametrization(param).name, method=method,
                        gradients=gradients, compare_fd=compare_fd, max_iterations=max_iterations, out=out)  # fmt: skip
    model = plan.model
    say = (lambda line: click.echo(line, err=True)) if as_json else click.echo
    published = model.working_range.published if model.working_range else {}
    report = service.run(plan, progress=say, finished=None if as_json else lambda result: click.echo(result.table(published)))
    runs, best = report.runs, report.best
    if report.comparison():
        say(report.comparison())
    written = write_optimized(model_file, model, best, plan.target)
    say(f"wrote {written} (the optimum as the design parameters' nominal values; model {model.name}_{study_name})")
    if as_json:
        click.echo(json.dumps({"model": model.name, "runs": [r.to_json() for r in runs], "written": str(written)}, indent=2))
    if not best.success:
        raise KinegenError(f"study {study_name}: {best.message}")



@main.command()
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.option("--study", "study_name", required=True, help="The study (studies:) whose parameters are sampled and whose quantities are measured.")
@click.option("--samples", type=click.IntRange(min=1), default=None, help="Variants to measure (default 1024; when resuming, the run's own).")
@click.option("--sampler", type=click.Choice(["sobol", "lhs"]), default=None, help="Scrambled Sobol' or Latin hypercube (scipy.stats.qmc); default sobol.")
@click.option("--seed", type=int, default=None, help="The sampler's seed: the same command gives the same variants (default 0).")
@click.option("--partition-size", type=click.IntRange(min=1), default=None, help="Variants per Dask task and Parquet file (default 200).")
@click.option("--out", type=click.Path(), default=None, help="The Parquet dataset (a folder; default out/<model>_<study>.parquet).")
@click.option("--resume", is_flag=True, help="Continue the run held in --out: only the partitions not written yet are computed.")
@click.option("--scheduler", default=None, help="A Dask scheduler's address (tcp://host:8786); default: a LocalCluster here.")
@click.option("--workers", type=click.IntRange(min=1), default=None, help="LocalCluster worker processes (default: one per core).")
@click.option("--plot", type=click.Path(dir_okay=False), default=None, callback=_image_file, help="PNG of the Pareto front and the parameters' sensitivity ranking.")
@click.option("--pareto", multiple=True, help="The front's two quantities (a column or a unique start of one; repeat twice). Default: the study's first two.")
@click.option("--minimize", multiple=True, help="A --pareto quantity to minimize (the front maximizes by default). Repeatable.")
@PARAM
@click.option("--no-compile", is_flag=True, help="Measure with the generated Python functions instead of the module's C.")
@GENERATED_DIR
def explore(
    model_file: str,
    study_name: str,
    samples: int | None,
    sampler: str | None,
    seed: int | None,
    partition_size: int | None,
    out: str | None,
    resume: bool,
    scheduler: str | None,
    workers: int | None,
    plot: str | None,
    pareto: tuple[str, ...],
    minimize: tuple[str, ...],
    param: str,
    no_compile: bool,
    generated_dir: str,
) -> None:
    """Sample a study's design parameters in their bounds and measure every variant's quantities
    on Dask, written to Parquet partition by partition (resumable); optionally plot the Pareto front
    of two quantities and the parameters' sensitivity ranking."""
    from kinegen.explore.plots import plot_exploration
    from kinegen.service import exploration

    plan = exploration.plan(_session(generated_dir), model_file, study_name, _parametrization(param).name, samples=samples,
                            sampler=sampler, seed=seed, partition_size=partition_size, out=out, resume=resume,
                            compiled=not no_compile)  # fmt: skip
    report = exploration.run(plan, scheduler, workers, say=lambda line: click.echo(line, err=True))
    click.echo(report.done.summary())
    if report.ranking is not None:
        click.echo("sensitivity ranking over the ok variants:")
        click.echo(report.ranking.table())
    if plot:
        columns = report.provenance["quantities"]
        pair = _pareto_pair(pareto, columns)
        maximize = tuple(label not in {_column(m, columns, "--minimize") for m in minimize} for label in pair)
        click.echo(f"wrote {plot_exploration(report.table, report.provenance, pair, maximize, plot)}")


def _column(name: str, columns: list[str], option: str) -> str:
    """The column ``name`` names: itself, or the one column it begins."""
    if name in columns:
        return name
    matches = [c for c in columns if c.startswith(name)]
    if len(matches) != 1:
        raise click.BadParameter(f"{name!r} names {'no' if not matches else 'more than one'} quantity (quantities: {', '.join(columns)})", param_hint=option)
    return matches[0]


def _pareto_pair(names: tuple[str, ...], columns: list[str]) -> tuple[str, str]:
    if not names:
        if len(columns) < 2:
            raise click.BadParameter("the study measures one quantity: a front needs two", param_hint="--pareto")
        return columns[0], columns[1]
    if len(names) != 2:
        raise click.BadParameter("give --pareto twice (the two quantities of the front)", param_hint="--pareto")
    return _column(names[0], columns, "--pareto"), _column(names[1], columns, "--pareto")


def run() -> None:
    """The ``kinegen`` executable (``[project.scripts]``, ``python -m kinegen.cli``): :func:`main`, whose
    exit then ends the process as :func:`kinegen.exiting.exit_process` does (the heap a build leaves is
    not freed object by object). Called in-process, as click's test runner calls it, use :func:`main`."""
    from kinegen.exiting import exit_process

    try:
        main()
    except SystemExit as exc:
        exit_process(exc.code)
    exit_process(0)


if __name__ == "__main__":  # pragma: no cover
    run()
