"""Conditioning of Phi_q along a case, per parametrization, with early warnings.

The physical motion is solved once with the quaternion parametrization (regular for
every orientation); each requested parametrization's Phi_q is evaluated at the same
physical configurations. Besides sigma_min/sigma_max and the condition number of the
whole Phi_q, every diagonal block of its block-triangular form is watched: a singularity
lives in one block (which names the bodies) and is not masked there by the scaling of
the rest of the mechanism.

Block ratios are taken with rows and columns scaled to unit norm, so that units and the
scaling of a parametrization do not matter. Two warnings, both before Newton-Raphson
has any trouble: per parametrization, the first time a block's ratio is below
``warn_ratio`` (that parametrization is singular there: a representation singularity
shows as ~1e-10); and, from the physical (quaternion) trace, a mechanism singularity
ahead: near a fold (toggle, dead centre) sigma_min grows like the square root of the
distance to it, so sigma^2 falls linearly to zero, and a block already below ``watch``
whose linear sigma^2 trend reaches zero within ``horizon`` steps is reported with the
predicted time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinegen.analysis.inspect import convert
from kinegen.errors import ConvergenceError, SingularJacobianError
from kinegen.progress import progress
from kinegen.runtime import NumericSystem, Solver
from kinegen.symbolic.blocks import block_triangular


@dataclass
class ScanTrace:
    """sigma_min/sigma_max and condition of one parametrization over time (whole Phi_q and
    its worst diagonal block)."""

    parametrization: str
    ratio: np.ndarray
    condition: np.ndarray
    block_ratio: np.ndarray
    block_bodies: list[str]  # bodies of the worst block at each time
    warning: str | None = None
    warning_time: float | None = None


@dataclass
class ScanResult:
    times: np.ndarray
    traces: list[ScanTrace] = field(default_factory=list)
    stopped: str | None = None  # why the physical solve stopped early, if it did
    ahead: str | None = None  # a mechanism singularity predicted before it is reached
    ahead_time: float | None = None

    def text(self) -> str:
        lines = [f"{len(self.times)} time points, t = {self.times[0]:g} .. {self.times[-1]:g} s"]
        for trace in self.traces:
            finite = trace.ratio[np.isfinite(trace.ratio)]
            worst = float(finite.min()) if finite.size else float("nan")
            k = int(np.nanargmin(trace.ratio)) if finite.size else 0
            b = int(np.nanargmin(trace.block_ratio))
            lines.append(
                f"{trace.parametrization:<17} Phi_q: min sigma_min/sigma_max {worst:.2e} at t = {self.times[k]:.4g}, "
                f"max condition {np.nanmax(trace.condition):.2e}; worst block ({trace.block_bodies[b]}): "
                f"{trace.block_ratio[b]:.2e} at t = {self.times[b]:.4g}"
            )
            if trace.warning:
                lines.append(f"  WARNING: {trace.warning}")
        if self.ahead:
            lines.append(f"WARNING (mechanism): {self.ahead}")
        if self.stopped:
            lines.append(f"stopped: {self.stopped}")
        return "\n".join(lines)


def _threshold_warning(
    times: np.ndarray, ratio: np.ndarray, bodies: list[str], warn_ratio: float
) -> tuple[str | None, float | None]:
    """First time a block's ratio is below ``warn_ratio``: this parametrization is (near) singular."""
    for k in np.flatnonzero(ratio < warn_ratio):
        return (
            f"t = {times[k]:.4g}: sigma_min/sigma_max = {ratio[k]:.2e} < {warn_ratio:g} in the block of {bodies[k]}: singular Jacobian here",
            float(times[k]),
        )
    return None, None


def _prediction(
    times: np.ndarray, ratio: np.ndarray, bodies: list[str], watch: float, horizon: int
) -> tuple[str | None, float | None]:
    """First time a block below ``watch`` is heading for zero within ``horizon`` steps (sigma^2 linear)."""
    for k in range(4, len(times)):
        if not ratio[k] < watch:
            continue
        squares = ratio[k - 4 : k + 1] ** 2
        slope = np.polyfit(times[k - 4 : k + 1] - times[k], squares, 1)[0]
        step = times[k] - times[k - 1]
        if slope < 0 and squares[-1] + slope * step * horizon <= 0:
            reach = times[k] - squares[-1] / slope
            return (
                f"t = {times[k]:.4g}: sigma_min/sigma_max = {ratio[k]:.2e} in the block of {bodies[k]} and falling; "
                f"at the current rate of the inputs the mechanism reaches a singular pose near t = {reach:.4g}",
                float(times[k]),
            )
    return None, None


def scan(
    physical: NumericSystem,
    systems: dict[str, NumericSystem],
    times: np.ndarray | None = None,
    warn_ratio: float = 1e-3,
    watch: float = 0.06,
    horizon: int = 20,
) -> ScanResult:
    """Scan ``systems`` (parametrization name -> numeric system of the same case) along the
    motion solved with ``physical`` (the quaternion system of that case).

    Per parametrization, a warning marks the first time a diagonal block's ratio is below
    ``warn_ratio`` (singular in that parametrization). A mechanism singularity ahead is
    predicted from the physical (quaternion) trace: a block below ``watch`` whose sigma^2
    trend reaches zero within ``horizon`` steps.
    """
    if physical.parametrization.name not in {s.parametrization.name for s in systems.values()}:
        systems = {physical.parametrization.name: physical, **systems}
    if times is None:
        times = np.linspace(physical.t0, physical.t1, physical.steps)
    solver = Solver(physical)
    q, v, a = physical.initial_q.copy(), None, None
    configurations, stopped = [], None
    for i, t in enumerate(times):
        u, ud, udd = physical.driver_inputs(t)
        try:
            if i > 0:
                h = t - times[i - 1]
                q = solver.retract(q, v * h + 0.5 * a * h * h)
            q, _, _ = solver.position(q, u, t)
            v, a = solver.rates(q, u, ud, udd, solver.factorize(q, u, t))
        except (ConvergenceError, SingularJacobianError) as exc:
            stopped = str(exc).splitlines()[0]
            break
        configurations.append(q.copy())
    times = times[: len(configurations)]
    result = ScanResult(times, stopped=stopped)
    bodies = len(physical.bodies)
    for name, system in systems.items():
        shape = (len(system.constraint_names), system.n_velocity)
        blocks = [b for b in block_triangular(shape, system.jac_rows, system.jac_cols) or [] if b.size > 1]
        ratio, condition, block_ratio = (np.full(len(times), np.nan) for _ in range(3))
        block_bodies: list[str] = []
        for k, (t, q) in enumerate(progress(zip(times, configurations), f"scan: {name}", total=len(times), unit="point")):
            q_p = convert(q, physical.parametrization, system.parametrization, bodies)
            jacobian = system.jacobian(q_p, system.driver_inputs(t)[0])
            ratio[k] = _ratio(jacobian)
            condition[k] = np.inf if ratio[k] == 0 else 1.0 / ratio[k]
            worst, worst_bodies = (np.inf, "") if blocks else (ratio[k], "whole Phi_q")
            scale = float(np.linalg.norm(jacobian, axis=1).max())
            for block in blocks:
                value = _ratio(_equilibrated(jacobian[np.ix_(block.rows, block.cols)], scale))
                if value < worst:
                    worst = value
                    worst_bodies = ", ".join(sorted({system.velocity_names[c].split(".")[0] for c in block.cols}))
            block_ratio[k] = worst
            block_bodies.append(worst_bodies)
        warning, when = _threshold_warning(times, block_ratio, block_bodies, warn_ratio)
        trace = ScanTrace(name, ratio, condition, block_ratio, block_bodies, warning, when)
        result.traces.append(trace)
        if system.parametrization.name == physical.parametrization.name:
            result.ahead, result.ahead_time = _prediction(times, block_ratio, block_bodies, watch, horizon)
    return result


def _equilibrated(matrix: np.ndarray, scale: float) -> np.ndarray:
    """Rows, then columns scaled to unit 2-norm, so the ratio does not depend on units.

    Rows and columns below 1e-9 of ``scale`` (the whole Phi_q's largest row norm) are
    rounding noise of zero and are not scaled up.
    """
    floor = 1e-9 * scale
    scaled = matrix / np.maximum(np.linalg.norm(matrix, axis=1, keepdims=True), floor)
    return scaled / np.maximum(np.linalg.norm(scaled, axis=0, keepdims=True), 1e-9)


def _ratio(matrix: np.ndarray) -> float:
    sigma = np.linalg.svd(matrix, compute_uv=False)
    return float(sigma[min(matrix.shape) - 1] / sigma[0]) if sigma[0] > 0 else 0.0


def warning_lines(result: ScanResult) -> list[tuple[float, str]]:
    """The times the scan plot marks with a dashed line: each parametrization's first warning
    (labelled with its name) and the predicted mechanism singularity ("mechanism singularity ahead")."""
    lines = [(t.warning_time, t.parametrization) for t in result.traces if t.warning_time is not None]
    if result.ahead_time is not None:
        lines.append((result.ahead_time, "mechanism singularity ahead"))
    return lines


def plot_scan(result: ScanResult, path: str | Path, title: str = "") -> Path:
    """sigma_min/sigma_max and condition number against time, one line per parametrization."""
    from kinegen.figures import pyplot, save

    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    for trace in result.traces:
        line = top.semilogy(result.times, np.maximum(trace.ratio, 1e-18), label=f"{trace.parametrization}: Phi_q")[0]
        top.semilogy(
            result.times,
            np.maximum(trace.block_ratio, 1e-18),
            ls=":",
            color=line.get_color(),
            label=f"{trace.parametrization}: worst block",
        )
        bottom.semilogy(result.times, np.minimum(trace.condition, 1e18), color=line.get_color())
    warned = warning_lines(result)
    for when, label in warned:
        colour = next((t_line.get_color() for t_line, tr in zip(top.get_lines()[::2], result.traces) if label == tr.parametrization), "black")
        for ax in (top, bottom):
            ax.axvline(when, color=colour, ls="--", lw=1.0, label=f"first warning: {label}" if ax is top else None)
    top.set(
        ylabel="sigma_min / sigma_max",
        title=(title + ": " if title else "") + "conditioning along the motion" + (" (dashed: first warning)" if warned else ""),
    )
    bottom.set(ylabel="condition number", xlabel="t [s]")
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    top.legend(fontsize=8)
    return save(fig, path)
