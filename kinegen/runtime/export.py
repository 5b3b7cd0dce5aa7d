"""A solve's time histories as a table and as CSV (one row per time point).

Columns: the solve's own figures (time [s], convergence, Newton iterations, max |Phi|, the
2-norm condition number of Phi_q), the driver inputs, then per body its origin [m], quaternion
(w, x, y, z), velocity, acceleration, angular velocity and acceleration (global), per named
point its position, velocity and acceleration, and per actuator its length, rate and
acceleration.
"""

from __future__ import annotations

import csv
import io
import sys
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from kinegen.files import STDOUT, atomic_writer
from kinegen.runtime import kinematics as kin

if TYPE_CHECKING:
    from kinegen.runtime.results import Results


def table(results: Results) -> tuple[list[str], np.ndarray]:
    """Column names and values (K, n) of the CSV export."""
    columns = [
        results.times[:, None], results.converged[:, None].astype(float), results.iterations[:, None], results.residuals[:, None],
        kin.condition_numbers(results)[:, None], results.inputs,
    ]  # fmt: skip
    names = [
        "t", "converged", "newton_iterations", "max_abs_phi", "jacobian_condition",
        *(f"input.{d}" for d in results.system.driver_names),
    ]  # fmt: skip
    for body in results.system.bodies:
        for label, values in (
            ("", kin.position(results, body)),
            ("q", kin.quaternion(results, body)),
            ("v", kin.velocity(results, body)),
            ("a", kin.acceleration(results, body)),
            ("omega", kin.omega(results, body)),
            ("omega_dot", kin.omega_dot(results, body)),
        ):
            axes = "wxyz" if label == "q" else "xyz"
            names += [f"{body}.{label}{'_' if label else ''}{c}" for c in axes]
            columns.append(values)
        for point in results.system.points.get(body, {}):
            for label, values in (
                ("", kin.point_position(results, body, point)),
                ("v", kin.point_velocity(results, body, point)),
                ("a", kin.point_acceleration(results, body, point)),
            ):
                names += [f"{body}.{point}.{label}{'_' if label else ''}{c}" for c in "xyz"]
                columns.append(values)
    for name in results.system.actuators:
        names += [f"{name}.length", f"{name}.rate", f"{name}.acceleration"]
        columns.append(np.c_[kin.actuator_length(results, name), kin.actuator_rate(results, name), kin.actuator_acceleration(results, name)])
    return names, np.hstack(columns)


def to_csv(results: Results, path: str | Path, extra: tuple[list[str], np.ndarray] | None = None) -> Path:
    """Write every time history to a CSV file (one row per time point); ``extra``: more
    columns (names, values (K, n)) after them, e.g. the forces of :mod:`kinegen.forces`."""
    names, values = table(results)
    if extra is not None:
        names, values = names + list(extra[0]), np.hstack([values, extra[1]])
    return write_csv(path, names, values)


def write_csv(path: str | Path, names: list[str], values: np.ndarray) -> Path:
    """A table (column ``names``, ``values`` (K, n)) as CSV into ``path`` (``-``: standard output),
    all or nothing: a full disk or an interrupted write keeps the previous file."""
    if str(path) == STDOUT:
        _csv_rows(sys.stdout, names, values)
        sys.stdout.flush()
        return Path(path)
    path = Path(path)
    with atomic_writer(path) as binary:
        handle = io.TextIOWrapper(binary, encoding="utf-8", newline="")
        _csv_rows(handle, names, values)
        handle.flush()
        handle.detach()
    return path


#: columns that hold counts and flags: written as integers (as the C target's example writes them)
INTEGER_COLUMNS = ("converged", "newton_iterations")


def _csv_rows(handle: TextIO, names: list[str], values: np.ndarray) -> None:
    """Values as round-trip decimals; the counts and flags of :data:`INTEGER_COLUMNS` as integers."""
    writer = csv.writer(handle)
    writer.writerow(names)
    whole = [name in INTEGER_COLUMNS for name in names]
    writer.writerows([[str(int(x)) if w and np.isfinite(x) else repr(float(x)) for x, w in zip(row, whole)] for row in values])


__all__ = ["INTEGER_COLUMNS", "table", "to_csv", "write_csv"]
