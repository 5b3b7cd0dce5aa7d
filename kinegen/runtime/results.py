"""Results of a trajectory solve: per body and time, poses, velocities, accelerations.

Arrays are indexed by time first. Rotation matrices map body to global coordinates;
quaternions are (w, x, y, z); omega and omega_dot are global; point quantities are
global positions, velocities and accelerations of named body points.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from kinegen.files import STDOUT, atomic_writer
from kinegen.model.schema import GROUND
from kinegen.runtime.system import NumericSystem


@dataclass
class Results:
    """Time histories of one solve (the *data*; the system is the model)."""

    system: NumericSystem
    times: np.ndarray
    q: np.ndarray  #: stored coordinates, (K, n)
    v: np.ndarray  #: velocity coordinates, (K, nv)
    a: np.ndarray  #: their time derivatives, (K, nv)
    iterations: np.ndarray  #: Newton iterations per time point
    residuals: np.ndarray  #: max |Phi| at convergence per time point
    conditions: np.ndarray  #: the solver's condition number of Phi_q per time point (``condition_kind``)
    inputs: np.ndarray  #: driver inputs u per time point, (K, n_inputs)
    condition_kind: str = "none"  #: "none" (NaN, the solver's default), "estimate" (1-norm) or "exact" (2-norm)
    #: per time point: True where Newton reached the tolerance (False only for the last
    #: point of a run stopped with ``on_failure="stop"``; its q, v, a are NaN)
    converged: np.ndarray | None = None
    failure: Exception | None = None  #: the error that stopped the run, if it stopped

    def __post_init__(self) -> None:
        if self.converged is None:
            self.converged = np.ones(len(self.times), dtype=bool)

    @property
    def complete(self) -> bool:
        """True when every time point converged."""
        return self.failure is None and bool(np.all(self.converged))

    def _body(self, body: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The body's stored, velocity and acceleration coordinates over time (K, nq), (K, nv), (K, nv)."""
        if body not in self.system.bodies:
            raise KeyError(f"no body {body!r} (bodies: {', '.join(self.system.bodies)})")
        coordinates = self.system.body_coordinates
        return coordinates(self.q, body), coordinates(self.v, body, velocity=True), coordinates(self.a, body, velocity=True)

    def position(self, body: str) -> np.ndarray:
        """Body-frame origin, global, (K, 3)."""
        return self.system.parametrization.pose(self._body(body)[0])[0]

    def velocity(self, body: str) -> np.ndarray:
        """Velocity of the body-frame origin, (K, 3)."""
        return self.system.parametrization.frame_velocity(*self._body(body)[:2])[0]

    def acceleration(self, body: str) -> np.ndarray:
        """Acceleration of the body-frame origin, (K, 3)."""
        return self.system.parametrization.frame_acceleration(*self._body(body))[0]

    def rotation_matrix(self, body: str) -> np.ndarray:
        """Rotation matrices body -> global, (K, 3, 3)."""
        return self.system.parametrization.pose(self._body(body)[0])[1]

    def quaternion(self, body: str) -> np.ndarray:
        """Unit quaternions (w, x, y, z), (K, 4), sign chosen with w >= 0."""
        from kinegen.rotations import quaternion_algebra as qa

        return qa.from_matrix(self.rotation_matrix(body))

    def euler_angles(self, body: str, sequence: str = "zxz") -> np.ndarray:
        """Intrinsic Euler angles for display (SciPy ``as_euler(sequence.upper())``), (K, 3)."""
        from kinegen.rotations import get

        return get(f"euler:{sequence}").from_matrix(self.rotation_matrix(body))

    def omega(self, body: str) -> np.ndarray:
        """Global angular velocity, (K, 3)."""
        return self.system.parametrization.frame_velocity(*self._body(body)[:2])[1]

    def omega_dot(self, body: str) -> np.ndarray:
        """Global angular acceleration, (K, 3)."""
        return self.system.parametrization.frame_acceleration(*self._body(body))[1]

    def arm(self, body: str, point: str) -> np.ndarray:
        """The global vector [m] (K, 3) from a body's frame origin to its named point, at every time point."""
        points = self.system.points.get(body, {})
        if point not in points:
            raise KeyError(f"no point {point!r} on body {body!r} (points: {', '.join(points) or 'none'})")
        return np.einsum("kij,j->ki", self.rotation_matrix(body), np.array(points[point]))

    def _ground_point(self, point: str) -> np.ndarray:
        points = self.system.ground_points
        if point not in points:
            raise KeyError(f"no point {point!r} on body 'ground' (points: {', '.join(points) or 'none'})")
        return np.tile(np.array(points[point], dtype=float), (len(self.times), 1))

    def point_position(self, body: str, point: str) -> np.ndarray:
        """Global position of a named body point (``ground`` allowed), (K, 3)."""
        if body == GROUND:
            return self._ground_point(point)
        return self.position(body) + self.arm(body, point)

    def point_velocity(self, body: str, point: str) -> np.ndarray:
        """Global velocity of a named body point: r' + omega x (A s'), (K, 3)."""
        if body == GROUND:
            return 0.0 * self._ground_point(point)
        return self.velocity(body) + np.cross(self.omega(body), self.arm(body, point))

    def point_acceleration(self, body: str, point: str) -> np.ndarray:
        """Global acceleration: r'' + omega' x (A s') + omega x (omega x A s'), (K, 3)."""
        if body == GROUND:
            return 0.0 * self._ground_point(point)
        arm = self.arm(body, point)
        w = self.omega(body)
        return self.acceleration(body) + np.cross(self.omega_dot(body), arm) + np.cross(w, np.cross(w, arm))

    def time_points(self, which: slice | np.ndarray) -> Results:
        """These results at some of their time points (a slice or indices): what a quantity measured
        at one time point (its maximum over a motion) differentiates there. Sensitivities are
        recomputed for them, not sliced."""
        fields = ("times", "q", "v", "a", "iterations", "residuals", "conditions", "inputs", "converged")
        return dataclasses.replace(self, **{name: getattr(self, name)[which] for name in fields})

    def condition_numbers(self) -> np.ndarray:
        """kinegen's condition number of Phi_q at each time point -- one definition everywhere (the
        CSV's ``jacobian_condition``, the case plot, ``kinegen compare``): the 2-norm condition number
        sigma_max / sigma_min, exact (the solve's own where it computed them so, else from the solved
        configurations, one SVD per point); NaN where a point is not solved, inf where Phi_q is singular."""

        def compute(results: Results) -> np.ndarray:
            if results.condition_kind == "exact":
                return results.conditions
            out = np.full(len(results.times), np.nan)
            solved = np.flatnonzero(results.converged)
            if len(solved):
                matrices = np.stack([results.system.jacobian(results.q[k], results.inputs[k]) for k in solved])
                s = np.linalg.svd(matrices, compute_uv=False)
                with np.errstate(divide="ignore"):
                    out[solved] = np.where(s[:, -1] > 0, s[:, 0] / s[:, -1], np.inf)
            return out

        return self.once("condition_numbers", compute)

    def once(self, name: str, compute: Callable[[Results], Any]) -> Any:
        """``compute(self)``, computed once for these results and kept with them under ``name``
        (what is derived from one solve: its condition numbers, its state's sensitivities)."""
        cache = self.__dict__.setdefault("_once", {})
        if name not in cache:
            cache[name] = compute(self)
        return cache[name]

    def _actuator(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        if name not in self.system.actuators:
            raise KeyError(f"no actuator {name!r} (actuators: {', '.join(self.system.actuators) or 'none'})")
        (b1, p1), (b2, p2), _ = self.system.actuators[name]
        d = self.point_position(b2, p2) - self.point_position(b1, p1)
        dv = self.point_velocity(b2, p2) - self.point_velocity(b1, p1)
        da = self.point_acceleration(b2, p2) - self.point_acceleration(b1, p1)
        length = np.linalg.norm(d, axis=1)
        return d, dv, da, length, np.einsum("ki,ki->k", d, dv) / length, np.einsum("ki,ki->k", dv, dv)

    def actuator_length(self, name: str) -> np.ndarray:
        """Distance between the actuator's two points, (K,)."""
        return self._actuator(name)[3]

    def actuator_rate(self, name: str) -> np.ndarray:
        """Extension rate dL/dt, (K,)."""
        return self._actuator(name)[4]

    def actuator_acceleration(self, name: str) -> np.ndarray:
        """Extension acceleration d2L/dt2 = (|d'|^2 + d.d'' - L'^2) / L, (K,)."""
        d, _, da, length, rate, speed2 = self._actuator(name)
        return (speed2 + np.einsum("ki,ki->k", d, da) - rate**2) / length

    def range_violations(self) -> list[tuple[float, str, float, tuple[float, float]]]:
        """(time, actuator, length, range) for every time point where an actuator is outside its range."""
        found = []
        for name, (_, _, limits) in self.system.actuators.items():
            if limits is None:
                continue
            length = self.actuator_length(name)
            for k in np.flatnonzero((length < limits[0]) | (length > limits[1])):
                found.append((float(self.times[k]), name, float(length[k]), tuple(limits)))
        return sorted(found)

    def table(self) -> tuple[list[str], np.ndarray]:
        """Column names and values of the CSV export."""
        columns = [
            self.times[:, None], self.converged[:, None].astype(float), self.iterations[:, None], self.residuals[:, None],
            self.condition_numbers()[:, None], self.inputs,
        ]  # fmt: skip
        names = [
            "t", "converged", "newton_iterations", "max_abs_phi", "jacobian_condition",
            *(f"input.{d}" for d in self.system.driver_names),
        ]  # fmt: skip
        for body in self.system.bodies:
            for label, values in (
                ("", self.position(body)),
                ("q", self.quaternion(body)),
                ("v", self.velocity(body)),
                ("a", self.acceleration(body)),
                ("omega", self.omega(body)),
                ("omega_dot", self.omega_dot(body)),
            ):
                axes = "wxyz" if label == "q" else "xyz"
                names += [f"{body}.{label}{'_' if label else ''}{c}" for c in axes]
                columns.append(values)
            for point in self.system.points.get(body, {}):
                for label, values in (
                    ("", self.point_position(body, point)),
                    ("v", self.point_velocity(body, point)),
                    ("a", self.point_acceleration(body, point)),
                ):
                    names += [f"{body}.{point}.{label}{'_' if label else ''}{c}" for c in "xyz"]
                    columns.append(values)
        for name in self.system.actuators:
            names += [f"{name}.length", f"{name}.rate", f"{name}.acceleration"]
            columns.append(np.c_[self.actuator_length(name), self.actuator_rate(name), self.actuator_acceleration(name)])
        return names, np.hstack(columns)

    def to_csv(self, path: str | Path, extra: tuple[list[str], np.ndarray] | None = None) -> Path:
        """Write every time history to a CSV file (one row per time point); ``extra``: more
        columns (names, values (K, n)) after them, e.g. the forces of :mod:`kinegen.forces`."""
        names, values = self.table()
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
