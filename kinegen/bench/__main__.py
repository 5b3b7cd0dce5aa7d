"""``make bench``: chain-N contenders, one fresh process each, ratios measured in one run.

Usage: python -m kinegen.bench [--sizes 3 14] [--quick]

Every row: build time, 1000-step trajectory time, Newton iterations per step, largest tip
error against the analytic solution (the run fails if any exceeds 1e-9 m), and the
ratios to kinegen's own run in the same invocation (the machines are shared and noisy:
absolute times alone mean little). ``--quick`` leaves out the slow SciPy baseline.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

CONTENDERS = {
    "kinegen (own predictor)": "kinegen_run({n}, True)",
    "kinegen (previous q, as specified)": "kinegen_run({n}, False)",
    "naive SymPy lambdify (cse)": "naive_sympy_run({n}, True)",
    "naive SymPy lambdify": "naive_sympy_run({n}, False)",
    "SciPy hybr + finite differences": "scipy_hybr_run({n})",
}
TOLERANCE = 1e-9


def run_contender(call: str, n: int) -> dict:
    code = f"import json; from kinegen.bench.contenders import *; print(json.dumps({call.format(n=n)}))"
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=3600)
    if done.returncode != 0:
        return {"failed": done.stderr.strip().splitlines()[-1] if done.stderr.strip() else f"exit {done.returncode}"}
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m kinegen.bench", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[3, 14])
    parser.add_argument("--quick", action="store_true", help="leave out the SciPy finite-difference baseline")
    args = parser.parse_args(argv)
    failures = 0
    header = f"{'N':>3} {'contender':<36} {'build s':>8} {'x kinegen':>9} {'traj. s':>8} {'x kinegen':>9} {'it/step':>7} {'tip error':>9}"
    print("chain-N, Euler parameters, 1000 steps on [0, 10] s, Newton to max|Phi| < 1e-10 (one process per row)")
    print(header)
    print("-" * len(header))
    for n in args.sizes:
        reference = None
        for name, call in CONTENDERS.items():
            if args.quick and name.startswith("SciPy"):
                continue
            row = run_contender(call, n)
            if "failed" in row:
                failures += 1
                print(f"{n:>3} {name:<36} FAILED: {row['failed']}")
                continue
            reference = reference or row
            ok = row["error"] < TOLERANCE
            failures += not ok
            print(
                f"{n:>3} {name:<36} {row['build']:>8.3f} {row['build'] / reference['build']:>9.2f} {row['trajectory']:>8.3f} "
                f"{row['trajectory'] / reference['trajectory']:>9.2f} {row['iterations']:>7.2f} {row['error']:>9.1e}"
                + ("" if ok else "  ERROR > 1e-9")
                + (f"  ({row['note']})" if "note" in row else "")
            )
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
