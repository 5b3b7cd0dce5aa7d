"""``make bench``: kinegen and its baselines, one fresh process per row, ratios in one run.

Usage: python -m kinegen.bench [--sizes 3 14] [--excavator digging level_cut] [--quick] [--only NAME ...] [--repeats N]

Workloads: chain-N (``docs/chain-N.md``) and the excavator's cases, 1000 time
points each, Newton to max|Phi| < 1e-10 from the previous solution, then velocity and
acceleration. Every row: build time, trajectory time, Newton iterations per step, the
largest error of the tracked point (the run fails if any exceeds 1e-9 m) and the ratio of
its trajectory time to kinegen's on the same previous-q workload. The machines are shared
and noisy: ratios measured in one run are what counts. Then the working-range sweep rate,
the C target's memory per solver instance, and the targets (issues 5 and 11), each checked
on this run's figures.
``--quick`` leaves out the slow baselines (SciPy finite differences, naive SymPy); ``--only`` runs
only the contenders whose names contain one of the given words (e.g. ``--only casadi "own predictor"``).
Each contender's trajectory is timed up to ``--repeats`` times (5) in its process, fewer once they took
2 s, and the shortest counts.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

from kinegen.progress import Stages

KINEGEN_OWN = "kinegen (own predictor)"
KINEGEN = "kinegen (previous q, as specified)"
CASADI = "CasADi SX, Python Newton loop"
KINEGEN_C = "kinegen compiled C (previous q)"
KINEGEN_C_OWN = "kinegen compiled C (own predictor)"
CASADI_C = "CasADi generated C, whole trajectory"
#: the chains issue 41's 0.2x CasADi target names (with the excavator's cases)
ISSUE_41_CHAINS = ("chain-14", "chain-50", "chain-100")
CONTENDERS = {  # name -> (call, largest chain N it runs on, runs on the excavator, slow)
    KINEGEN_OWN: ("kinegen_run({w!r}, True)", 10**6, True, False),
    KINEGEN: ("kinegen_run({w!r}, False)", 10**6, True, False),
    "kinegen quaternion (own predictor)": ("kinegen_run({w!r}, True, 'quaternion')", 0, True, False),
    "kinegen dual-quaternion (own)": ("kinegen_run({w!r}, True, 'dual-quaternion')", 0, True, False),
    "kinegen dual-euler-parameters (own)": ("kinegen_run({w!r}, True, 'dual-euler-parameters')", 0, True, False),
    "kinegen quaternion compiled C (own)": ("kinegen_run({w!r}, True, 'quaternion', compiled=True)", 0, True, False),
    "kinegen dual-quaternion compiled C": ("kinegen_run({w!r}, True, 'dual-quaternion', compiled=True)", 0, True, False),
    "kinegen dual-euler-params compiled C": ("kinegen_run({w!r}, True, 'dual-euler-parameters', compiled=True)", 0, True, False),
    KINEGEN_C: ("kinegen_run({w!r}, False, compiled=True)", 10**6, True, False),
    KINEGEN_C_OWN: ("kinegen_run({w!r}, True, compiled=True)", 10**6, True, False),
    CASADI: ("casadi_run({w!r}, False)", 10**6, True, False),
    "CasADi SX, rootfinder('newton')": ("casadi_run({w!r}, True)", 14, True, False),
    CASADI_C: ("casadi_c_run({w!r})", 100, True, False),
    "SymEngine Lambdify (LLVM, sparse)": ("symengine_run({w!r})", 50, True, False),
    "naive SymPy lambdify (cse)": ("naive_sympy_run({w!r}, True)", 50, False, True),
    "naive SymPy lambdify": ("naive_sympy_run({w!r}, False)", 14, False, True),
    "SciPy hybr + finite differences": ("scipy_hybr_run({w!r})", 14, True, True),
}
TOLERANCE = 1e-9
PRELUDE = (
    "import json, resource\n"
    "from kinegen.bench.contenders import *\n"
    "row = {call}\n"
    "row['peak_mb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024\n"
    "print(json.dumps(row))\n"
)


def run_contender(call: str) -> dict:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    done = subprocess.run(
        [sys.executable, "-c", PRELUDE.format(call=call)], env=env, capture_output=True, text=True, timeout=3600
    )
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines()
        return {"failed": lines[-1] if lines else f"exit {done.returncode}"}
    return json.loads(done.stdout.strip().splitlines()[-1])


def sweep_rate(repeats: int = 5) -> dict:
    """The excavator working range (models/excavator.yaml), quaternion: configurations solved
    per second by the batched grid, median of ``repeats`` runs in one fresh process (and the
    first, cold run on its own: it pays for first calls into NumPy and LAPACK)."""
    code = (
        "import json, statistics\n"
        "from kinegen.bench.contenders import ROOT\n"
        "from kinegen.model import load\n"
        "from kinegen.runtime import from_module, load_module\n"
        "from kinegen.analysis.envelope import working_range\n"
        "model = load(ROOT / 'models' / 'excavator.yaml')\n"
        "module = load_module(ROOT / 'generated' / 'excavator_quaternion.py', ROOT / 'models' / 'excavator.yaml')\n"
        "system = from_module(module, model.working_range.case)\n"
        f"runs = [working_range(system, model.working_range) for _ in range({repeats})]\n"
        "e = runs[0]\n"
        "print(json.dumps({'solves': e.solves, 'seconds': e.seconds, 'grid': e.grid_solved, 'cold_seconds': e.grid_seconds,\n"
        "    'grid_seconds': statistics.median(r.grid_seconds for r in runs)}))\n"
    )
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=3600)
    if done.returncode != 0:
        return {"failed": done.stderr.strip().splitlines()[-1]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m kinegen.bench", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sizes", type=int, nargs="*", default=[3, 14])
    parser.add_argument("--excavator", nargs="*", default=["digging", "level_cut"], help="excavator cases")
    parser.add_argument("--quick", action="store_true", help="leave out SciPy finite differences and naive SymPy")
    parser.add_argument("--no-sweep", action="store_true", help="leave out the working-range sweep")
    parser.add_argument("--no-studies", action="store_true", help="leave out the design studies (exact vs finite-difference gradients)")
    parser.add_argument("--no-explore", action="store_true", help="leave out kinegen explore on Dask (1 and 2 workers vs one process)")
    parser.add_argument("--repeats", type=int, default=None, metavar="N",
                        help="time each contender's trajectory up to N times in its process, the shortest counting (default 5, "
                             "fewer once they took 2 s)")  # fmt: skip
    parser.add_argument("--only", nargs="+", metavar="NAME", default=None,
                        help="only the contenders whose names contain one of these words (any case)")  # fmt: skip
    args = parser.parse_args(argv)
    if args.repeats is not None:
        if args.repeats < 1:
            parser.error(f"--repeats {args.repeats}: at least 1")
        os.environ["KINEGEN_BENCH_REPEATS"] = str(args.repeats)  # read by each contender's process (contenders.REPEATS)
    repeats = os.environ.get("KINEGEN_BENCH_REPEATS", "5")
    chosen = [name for name in CONTENDERS if args.only is None or any(word.lower() in name.lower() for word in args.only)]
    if not chosen:
        parser.error(f"--only {' '.join(args.only)}: no contender's name contains these; the contenders: {', '.join(CONTENDERS)}")
    workloads = [f"chain-{n}" for n in args.sizes] + [f"excavator-{c}" for c in args.excavator]
    failures = 0
    rows: dict[tuple[str, str], dict] = {}
    header = (
        f"{'workload':<19} {'contender':<36} {'build s':>8} {'traj. s':>8} {'x kinegen':>9} {'it/step':>7} "
        f"{'error m':>8} {'peak MB':>7}"
    )
    print("1000 time points, Newton to max|Phi| < 1e-10, velocity + acceleration; Euler parameters unless named")
    print(f"x kinegen = trajectory time / kinegen's on the same previous-q workload (one process per row, the shortest of up to "
          f"{repeats} trajectories there)")
    print(header)
    print("-" * len(header))
    plan = [
        (w, name, call)
        for w in workloads
        for name, (call, largest, excavator, slow) in CONTENDERS.items()
        if name in chosen and not ((w.startswith("chain") and int(w.split("-")[1]) > largest) or (w.startswith("excavator") and not excavator) or (args.quick and slow))
    ]
    design = "__import__('kinegen.bench.design', fromlist=['x'])"
    sections = {  # name -> what it measures, when this run asks for it
        "working-range sweep": None if args.no_sweep else sweep_rate,
        "sensitivities": (lambda: run_contender(f"{design}.sensitivity_cost()")) if "excavator-digging" in workloads else None,
        "design studies": None if args.no_studies else lambda: run_contender(f"{design}.study_cost()"),
        "kinegen explore": None if args.no_explore else lambda: run_contender("__import__('kinegen.bench.explore', fromlist=['x']).exploration_scaling()"),
        "certified steps": (lambda: run_contender(f"__import__('kinegen.bench.certified', fromlist=['x']).certificate_cost(repeats={3 if args.quick else 9})"))
        if "excavator-digging" in workloads else None,
        "forces": (lambda: run_contender("__import__('kinegen.bench.forces', fromlist=['x']).force_cost()")) if "excavator-digging" in workloads else None,
        "C target memory": lambda: {w: run_contender(f"c_target_memory({w!r})") for w in workloads if w.startswith("excavator")},
        "time-optimal cycle": (lambda: run_contender("__import__('kinegen.bench.cycle', fromlist=['x']).cycle_cost()"))
        if "excavator-digging" in workloads else None,
        "command start-up": (lambda: run_contender("__import__('kinegen.bench.startup', fromlist=['x']).startup_cost()"))
        if "excavator-digging" in workloads else None,  # kinegen info of the excavator among them
    }
    measured: dict[str, dict | None] = {}
    with Stages("bench", len(plan) + sum(f is not None for f in sections.values()), unit="runs") as bar:
        for w, name, call in plan:
            bar.stage(f"{w}, {name}")
            row = run_contender(call.format(w=w))
            rows[(w, name)] = row
            if "failed" in row:
                failures += 1
                bar.write(f"{w:<19} {name:<36} FAILED: {row['failed']}")
                continue
            base = rows.get((w, KINEGEN), {}).get("trajectory")  # (not run: --only left it out)
            ok = row["error"] < TOLERANCE
            failures += not ok
            ratio = f"{row['trajectory'] / base:>9.2f}" if base else f"{'-':>9}"
            bar.write(
                f"{w:<19} {name:<36} {row['build']:>8.3f} {row['trajectory']:>8.3f} "
                f"{ratio} {row['iterations']:>7.2f} "
                f"{row['error']:>8.1e} {row['peak_mb']:>7.0f}"
                + ("" if ok else "  ERROR > 1e-9")
                + (f"  ({row['note']})" if "note" in row else "")
            )
        for name, measure in sections.items():
            if measure is not None:
                bar.stage(name)
            measured[name] = None if measure is None else measure()
    sweep, sensitivity, studies = measured["working-range sweep"], measured["sensitivities"], measured["design studies"]
    exploration, memory = measured["kinegen explore"], measured["C target memory"]
    certified = measured["certified steps"]
    if certified is not None:
        print()
        if "failed" in certified:
            failures += 1
            print(f"certified steps: FAILED: {certified['failed']}")
        else:
            for case, row in certified.items():
                if case == "peak_mb":
                    continue
                print(f"certified steps (excavator {case}, compiled, 1000 points): {row['certified']:.4f} s vs {row['plain']:.4f} s "
                      f"uncertified = {row['ratio']:.2f}x, vs {row['sampled']:.4f} s along the samples' cubic path = {row['enclosed']:.2f}x; "
                      f"steps subdivided: {'some' if row['subdivided'] else 'none'}")
    print()
    for w, m in list(memory.items())[:1]:
        if "failed" in m:
            print(f"C target memory ({w}): FAILED: {m['failed']}")
            continue
        total = m["workspace"] + m["struct"] + m["stack"]
        print(
            f"C target, one solver instance ({w.split('-')[0]}, Euler parameters): workspace {m['workspace']:,} B + "
            f"struct {m['struct']} B + stack of a step <= {m['stack']:,} B = {total:,} B; the model's tables "
            f"{m['static']:,} B, shared by every instance"
        )
    if sensitivity is not None:
        print()
        if "failed" in sensitivity:
            print(f"sensitivities (excavator, {sensitivity.get('parameters', 11)} design parameters): FAILED: {sensitivity['failed']}")
        else:
            s = sensitivity
            print(
                f"sensitivities, excavator digging with {s['parameters']} design parameters (kinegen/bench/design.py), 1000 points: "
                f"dq/dp, dv/dp, da/dp {s['compiled_sensitivities']:.3f} s; trajectory solve compiled {s['compiled_solve']:.3f} s, "
                f"pure Python {s['python_solve']:.3f} s; build {s['build']:.1f} s"
            )
    failures += _section(exploration, "kinegen explore", _exploration_line)
    held = measured["forces"]
    failures += _section(held, "forces", lambda f: (
        f"forces (excavator digging, payload + cutting, {f['points']} points) after a compiled trajectory solve of {f['solve']:.3f} s: "
        f"compiled force solve (kinegen_forces: multipliers, element forces) {f['compiled_forces']:.4f} s, with the bodies' weight "
        f"and inertia (inverse dynamics) {f['compiled_dynamics']:.4f} s; kinegen.forces.forces "
        f"(also reactions and pressures, Python) {f['forces']:.3f} s; ISO 6015 tool forces (kinegen forces) {f['tool_forces']:.3f} s; "
        f"tangent force map of {f['poses']:,} poses {f['map']:.3f} s; ISO 10567 lift chart {f['lift']:.3f} s", 0))
    startup = measured["command start-up"]
    failures += _section(startup, "command start-up", lambda c: (
        "command start-up (wall time, median of 7 fresh processes): " + ", ".join(f"{name} {c[name]:.3f} s" for name in
        ("python -c pass", "kinegen --help", "kinegen models", "kinegen info (first)", "kinegen info (cached)")), 0))
    timed = measured["time-optimal cycle"]
    failures += _section(timed, "time-optimal cycle", lambda c: (
        f"time-optimal cycle (excavator digging, payload, {c['points']} points, compiled): the path's solve {c['solve']:.3f} s, "
        f"its fastest timing (kinegen.forces.cycle.fastest) {c['retiming']:.3f} s = {c['retiming'] / c['solve']:.1f}x the solve; "
        f"cycle time {c['cycle_time']:.2f} s; cycle_time with its gradient by {c['parameters']} parameters on the case's "
        f"{c['gradient_points']} points, solve included: {c['with_gradient']:.3f} s", 0))
    print()
    print("Targets, on this run's figures:")
    failures += _section(studies, "design studies", _study_lines)
    if held and "failed" not in held:
        print("  " + _met("compiled forces / compiled trajectory step (issue 28)", held["compiled_forces"] / held["solve"], 0.2, True))
        print("  " + _met("compiled inverse dynamics / compiled trajectory step (issue 29)", held["compiled_dynamics"] / held["solve"], 0.3, True))
        print("  " + _met("ISO 6015 tool forces (issue 28)", held["tool_forces"], 0.5, True, " s"))
        print("  " + _met(f"force map of {held['poses']:,} poses (issue 28)", held["map"], 1.0, True, " s"))
        print("  " + _met("ISO 10567 lift chart, both sides, every point's pose search (issue 29)", held["lift"], 1.0, True, " s"))
    if timed and "failed" not in timed:
        print("  " + _met(f"re-timing the {timed['points']:,}-point digging path, compiled (issue 40)", timed["retiming"], 1.0, True, " s"))
        print("  " + _met("one cycle_time evaluation with its gradient (issue 40)", timed["with_gradient"], 2.0, True, " s"))
    if startup and "failed" not in startup:
        for name in ("kinegen --help", "kinegen models", "kinegen info (cached)"):
            print("  " + _met(f"{name}, start to end (issue 39)", startup[name], 0.3, True, " s"))
    for line in targets(rows, sweep, sensitivity, exploration, certified if certified and "failed" not in certified else None):
        print("  " + line)
    return 1 if failures else 0


def _met(text: str, value: float, limit: float, below: bool, unit: str = "") -> str:
    """One target's line: the figure, the target, met or not."""
    met = value <= limit if below else value >= limit
    return f"{text}: {value:.3g}{unit} ({'<=' if below else '>='} {limit:g}{unit}) {'met' if met else 'NOT met'}"


def _section(row: dict | None, name: str, lines) -> int:
    """A measured row's lines after a blank line (nothing when not measured); 1 for a failure."""
    if row is None:
        return 0
    print()
    if "failed" in row:
        print(f"{name}: FAILED: {row['failed']}")
        return 1
    text, failed = lines(row)
    print(text)
    return failed


def _exploration_line(e: dict) -> tuple[str, int]:
    return (
        f"kinegen explore (excavator calibration study, {e['samples']} variants in partitions of {e['partition_size']}, median of "
        f"{e['rounds']} rounds): one process {e['in_process']:.1f} s ({e['samples'] / e['in_process']:.1f} variants/s), Dask 1 worker "
        f"{e['workers_1']:.1f} s ({e['samples'] / e['workers_1']:.1f}/s), 2 workers {e['workers_2']:.1f} s ({e['samples'] / e['workers_2']:.1f}/s); "
        f"a worker's one-time set-up {e['setup_1']:.1f} s",
        0,
    )


def _study_lines(studies: dict) -> tuple[str, int]:
    lines, failed = ["design studies (kinegen optimize, SLSQP; models/excavator.yaml): exact gradients vs SciPy's finite differences"], 0
    for name, s in studies.items():
        if not isinstance(s, dict):  # the row's peak memory
            continue
        e, f = s["exact"], s["fd"]
        lines.append(
            f"  {name} ({s['parameters']} parameters): exact {e['iterations']} iterations, {e['gradient_evaluations']} gradients, "
            f"{e['designs']} designs, {e['seconds']:.1f} s; finite differences {f['iterations']} iterations, {f['designs']} designs, "
            f"{f['seconds']:.1f} s ({s['seconds_ratio']:.1f}x the time); optima {s['optimum_difference']:.1e} apart"
        )
        failed += not (e["success"] and f["success"])
    return "\n".join(lines), failed


def targets(
    rows: dict[tuple[str, str], dict], sweep: dict | None, sensitivity: dict | None = None, exploration: dict | None = None,
    certified: dict | None = None,
) -> list[str]:
    """One line per target that this run measured: the figure, the target, met or not."""

    def get(w: str, name: str, key: str) -> float | None:
        row = rows.get((w, name))
        return None if row is None or "failed" in row else row[key]

    def line(text: str, value: float | None, limit: float, below: bool, unit: str = "") -> str | None:
        return None if value is None else _met(text, value, limit, below, unit)

    out = []
    for case, row in (certified or {}).items():
        if isinstance(row, dict):
            out.append(line(f"excavator {case} certified / uncertified compiled step (issue 25)", row["ratio"], 1.3, True))
            out.append(line(f"excavator {case} certified along its functions / along its samples' cubic path (issue 38)", row["enclosed"], 1.15, True))
    workloads = sorted({w for w, _ in rows})
    for w in workloads:
        casadi = get(w, CASADI, "trajectory")
        for name in (KINEGEN, KINEGEN_OWN, "kinegen quaternion (own predictor)", KINEGEN_C, KINEGEN_C_OWN):
            mine = get(w, name, "trajectory")
            if mine is not None and casadi is not None:
                out.append(line(f"{w} {name} trajectory / CasADi Python loop", mine / casadi, 1.0, True))
        whole_c = get(w, CASADI_C, "trajectory")
        for name in (KINEGEN_C, KINEGEN_C_OWN):
            mine = get(w, name, "trajectory")
            if mine is not None and whole_c is not None and (w.startswith("excavator") or w in ("chain-50", "chain-100")):
                out.append(line(f"{w} {name} trajectory / CasADi whole-trajectory C (issue 11)", mine / whole_c, 0.33, True))
            elif mine is not None and whole_c is not None:
                out.append(line(f"{w} {name} trajectory / CasADi whole-trajectory C", mine / whole_c, 1.0, True))
            # the default compiled solve (certified along the case's functions) on the workloads issue 41 names:
            # chain-14, -50 and -100 and the excavator (chain-3's ratio is the untagged line above)
            if name == KINEGEN_C_OWN and mine is not None and whole_c is not None and (w.startswith("excavator") or w in ISSUE_41_CHAINS):
                out.append(line(f"{w} {name} trajectory / CasADi whole-trajectory C (issue 41)", mine / whole_c, 0.2, True))
        scipy_time = get(w, "SciPy hybr + finite differences", "trajectory")
        for name in (KINEGEN, KINEGEN_OWN, KINEGEN_C, KINEGEN_C_OWN):
            mine = get(w, name, "trajectory")
            if scipy_time is not None and mine is not None:
                out.append(line(f"{w} SciPy finite differences / {name} trajectory", scipy_time / mine, 50, False))
    for w in workloads:  # issue 12: the dual-quaternion parametrizations against the quaternion, same workload
        pairs = (
            ("kinegen quaternion (own predictor)", "kinegen dual-quaternion (own)"),
            ("kinegen quaternion (own predictor)", "kinegen dual-euler-parameters (own)"),
            ("kinegen quaternion compiled C (own)", "kinegen dual-quaternion compiled C"),
            ("kinegen quaternion compiled C (own)", "kinegen dual-euler-params compiled C"),
        )
        for base, new in pairs:
            b_build, n_build = get(w, base, "build"), get(w, new, "build")
            b_time, n_time = get(w, base, "trajectory"), get(w, new, "trajectory")
            if "compiled" not in base and b_build and n_build:
                out.append(line(f"{w} {new} build / quaternion's (issue 12)", n_build / b_build, 1.5, True))
            if b_time and n_time:
                out.append(line(f"{w} {new} trajectory / quaternion's (issue 12)", n_time / b_time, 1.3, True))
    out.append(line("chain-14 kinegen build", get("chain-14", KINEGEN, "build"), 1.0, True, " s"))
    b14, b100 = get("chain-14", KINEGEN, "build"), get("chain-100", KINEGEN, "build")
    if b14 and b100:
        out.append(line("chain-100 / chain-14 build", b100 / b14, 8, True))
    naive50, mine50 = get("chain-50", "naive SymPy lambdify (cse)", "build"), get("chain-50", KINEGEN, "build")
    if naive50 and mine50:
        out.append(line("chain-50 naive SymPy build / kinegen build", naive50 / mine50, 10, False))
    for w in workloads:
        if w.startswith("excavator"):
            out.append(line(f"{w} kinegen build peak memory", get(w, KINEGEN, "peak_mb"), 300, True, " MB"))
            out.append(line(f"{w} kinegen build with the C compilation (issue 11)", get(w, KINEGEN_C, "build"), 3.0, True, " s"))
            break
    out.append(line("chain-100 kinegen build with the C compilation (issue 11)", get("chain-100", KINEGEN_C, "build"), 10.0, True, " s"))
    if sweep and "failed" not in sweep:
        rate = sweep["grid"] / sweep["grid_seconds"]
        out.append(
            line(f"working-range sweep, batched grid in C ({sweep['grid']} configurations, median of 5; issue 11)", rate, 100000, False, "/s")
        )
        cold = sweep["grid"] / sweep["cold_seconds"]
        total = f"{sweep['seconds']:.2f} s with the SLSQP refinement of the five figures ({sweep['solves']} solves)"
        out.append(f"  (first, cold run: {cold:,.0f}/s; whole working range: {total})")
    if sensitivity and "failed" not in sensitivity:
        ratio = sensitivity["compiled_sensitivities"] / sensitivity["compiled_solve"]
        out.append(line(f"excavator digging sensitivities ({sensitivity['parameters']} parameters) / compiled trajectory solve (issue 13)", ratio, 3.0, True))
        out.append(f"  (/ pure-Python trajectory solve: {sensitivity['compiled_sensitivities'] / sensitivity['python_solve']:.2f})")
    if exploration and "failed" not in exploration:
        out.append(line("kinegen explore, 2 Dask workers / 1 worker, variants per second (issue 14)", exploration["workers_1"] / exploration["workers_2"], 1.8, False, "x"))
        overhead = 100 * (exploration["workers_1"] / exploration["in_process"] - 1)
        out.append(line("kinegen explore, Dask overhead per variant, 1 worker vs one process without Dask (issue 14)", overhead, 10, True, " %"))
    return [x for x in out if x]


if __name__ == "__main__":
    raise SystemExit(main())
