"""The main job (``make run``): build every model in ``models/``, solve every case.

Prints one summary row per (model, case, parametrization) and writes a CSV and a PNG
per row into the output folder. ``--regenerate-only`` just rebuilds ``generated/``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from kinegen.codegen import build
from kinegen.errors import KinegenError, SingularJacobianError
from kinegen.runtime import from_module, load_module, solve

#: What the main job builds: model file -> parametrizations (committed in generated/).
MAIN_JOB: dict[str, tuple[str, ...]] = {
    "boom.yaml": ("quaternion", "euler-parameters", "euler:zxz"),
    "slider_crank.yaml": ("quaternion", "euler-parameters"),
    "four_bar.yaml": ("quaternion", "euler-parameters"),
    "rssr.yaml": ("quaternion", "euler-parameters"),
    "excavator.yaml": ("quaternion", "euler-parameters", "euler:zxz", "euler:zxy"),
}


def regenerate(models: Path, generated: Path) -> list[Path]:
    """Rebuild every module of :data:`MAIN_JOB` (byte-identical when nothing changed)."""
    return [build(models / name, param, generated) for name, params in MAIN_JOB.items() for param in params]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m kinegen.demo", description=__doc__)
    parser.add_argument("--models", default="models", type=Path)
    parser.add_argument("--generated", default="generated", type=Path)
    parser.add_argument("--out", default="out", type=Path)
    parser.add_argument("--regenerate-only", action="store_true")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    paths = regenerate(args.models, args.generated)
    print(f"built {len(paths)} modules into {args.generated}/ in {time.perf_counter() - start:.1f} s")
    if args.regenerate_only:
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    header = f"{'model':<13} {'case':<11} {'parametrization':<17} {'steps':>5} {'Newton it.':>10} {'max|Phi|':>9} {'solve s':>8}  result"
    print(header)
    print("-" * len(header))
    failures = 0
    for path in paths:
        module = load_module(path)
        for case in module.CASES:
            system = from_module(module, case)
            stem = f"{system.model}_{case}_{system.parametrization.file_tag}"
            row = f"{system.model:<13} {case:<11} {system.parametrization.name:<17} {system.steps:>5}"
            try:
                t = time.perf_counter()
                results = solve(system)
                elapsed = time.perf_counter() - t
            except SingularJacobianError as exc:
                expected = system.parametrization.name.startswith("euler:")
                failures += not expected
                first = str(exc).splitlines()[0]
                print(
                    f"{row} {'-':>10} {'-':>9} {'-':>8}  {'singular, as the paper predicts' if expected else 'FAILED'}: {first}"
                )
                continue
            except KinegenError as exc:
                failures += 1
                print(f"{row}  FAILED: {exc}")
                continue
            results.to_csv(args.out / f"{stem}.csv")
            from kinegen.analysis.plots import plot_results

            plot_results(results, args.out / f"{stem}.png")
            print(
                f"{row} {results.iterations.mean():>10.2f} {results.residuals.max():>9.1e} {elapsed:>8.3f}  "
                f"ok -> {args.out}/{stem}.csv, .png"
            )
    print(f"outputs in {args.out.resolve()}")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
