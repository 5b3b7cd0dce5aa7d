"""What a designer looks at after an exploration: the Pareto front of two quantities and the
ranking of the parameters by their influence on each quantity.

The ranking is by standardized regression coefficients (SRC): a least-squares plane
y = a + sum_j b_j p_j through the ``ok`` variants, and SRC_j = b_j std(p_j) / std(y) -- the change
of y, in its standard deviations over the sample, when p_j moves by one of its own. Over a box
small enough for y to be nearly linear (R^2 near 1, printed beside it) b_j is the derivative
dy/dp_j, and the SRCs add up in squares to R^2; where R^2 is low the ranking is only indicative.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


def pareto_front(x: np.ndarray, y: np.ndarray, maximize: tuple[bool, bool] = (True, True)) -> np.ndarray:
    """Indices of the non-dominated points of (x, y) (each maximized or minimized), ordered by x:
    no other point is at least as good in both and better in one."""
    sx = np.where(maximize[0], 1.0, -1.0) * np.asarray(x, dtype=float)
    sy = np.where(maximize[1], 1.0, -1.0) * np.asarray(y, dtype=float)
    order = np.lexsort((-sy, -sx))  # best x first, ties by best y
    front, best = [], -np.inf
    for i in order:
        if sy[i] > best:
            front.append(i)
            best = sy[i]
    return np.array(sorted(front, key=lambda i: x[i]), dtype=np.intp)


#: a quantity whose spread over the sample is below this (relative) is constant: not ranked
CONSTANT = 1e-9


@dataclass
class Ranking:
    """Standardized regression coefficients of each quantity on each parameter."""

    parameters: list[str]
    quantities: list[str]
    src: np.ndarray  #: (n_quantities, n_parameters)
    slope: np.ndarray  #: (n_quantities, n_parameters) b_j, in the quantity's unit per the parameter's
    r2: np.ndarray  #: (n_quantities,) NaN for a quantity constant over the sample
    variants: int  #: ok variants used

    def table(self) -> str:
        width = max(len(q) for q in self.quantities)
        lines = [f"  {'quantity':<{width}}  R^2     parameters by |SRC| (standardized regression coefficient)"]
        for i, quantity in enumerate(self.quantities):
            if not np.isfinite(self.r2[i]):
                lines.append(f"  {quantity:<{width}}  -      constant over the sample (to rounding)")
                continue
            order = np.argsort(-np.abs(self.src[i]))
            ranked = ", ".join(f"{self.parameters[j]} {self.src[i, j]:+.2f}" for j in order)
            lines.append(f"  {quantity:<{width}}  {self.r2[i]:.3f}  {ranked}")
        return "\n".join(lines)


def ranking(parameters: dict[str, np.ndarray], quantities: dict[str, np.ndarray]) -> Ranking:
    """The SRC ranking from the ``ok`` variants' parameter and quantity columns (equal lengths)."""
    names, labels = list(parameters), list(quantities)
    p = np.column_stack([parameters[n] for n in names])
    p_std = p.std(axis=0)
    design = np.column_stack([np.ones(len(p)), p - p.mean(axis=0)])
    src = np.zeros((len(labels), len(names)))
    slope = np.zeros_like(src)
    r2 = np.zeros(len(labels))
    for i, label in enumerate(labels):
        y = np.asarray(quantities[label], dtype=float)
        coefficients = np.linalg.lstsq(design, y, rcond=None)[0]
        fitted = design @ coefficients
        spread = y.std()
        slope[i] = coefficients[1:]
        r2[i] = np.nan
        if spread > CONSTANT * max(1.0, abs(float(y.mean()))):  # else constant to rounding: nothing to rank
            src[i] = coefficients[1:] * p_std / spread
            r2[i] = 1 - np.sum((y - fitted) ** 2) / np.sum((y - y.mean()) ** 2)
    return Ranking(names, labels, src, slope, r2, len(p))


def ranking_of(table, provenance: dict) -> Ranking | None:
    """The SRC ranking of an exploration's table (its ``ok`` variants); None with too few of them
    to fit a plane."""
    ok = table.column("status").to_numpy(zero_copy_only=False) == "ok"
    parameters, quantities = list(provenance["parameters"]), list(provenance["quantities"])
    if ok.sum() <= len(parameters) + 1:
        return None
    column = {n: table.column(n).to_numpy()[ok] for n in [*parameters, *quantities]}
    return ranking({n: column[n] for n in parameters}, {q: column[q] for q in quantities})


def plot_exploration(
    table,
    provenance: dict,
    pareto: tuple[str, str],
    maximize: tuple[bool, bool],
    path: str | Path,
) -> Path:
    """The Pareto front of the two ``pareto`` quantities (every ok variant, the feasible ones, the
    front, the nominal design) beside the parameters' SRC ranking for every quantity; a PNG."""
    from kinegen.analysis.plots import pyplot, save

    plt = pyplot()
    data = {name: table.column(name).to_numpy(zero_copy_only=False) for name in table.column_names}
    ok = data["status"] == "ok"
    feasible = data["feasible"] & ok
    x_label, y_label = pareto
    x, y = data[x_label], data[y_label]
    result = ranking_of(table, provenance)

    figure, (left, right) = plt.subplots(1, 2, figsize=(14, 6), gridspec_kw={"width_ratios": [1.1, 1]})
    left.scatter(x[ok & ~feasible], y[ok & ~feasible], s=6, color="0.75", label=f"ok, a constraint not met ({int((ok & ~feasible).sum())})")
    left.scatter(x[feasible], y[feasible], s=6, color="tab:blue", alpha=0.6, label=f"feasible ({int(feasible.sum())})")
    front = np.flatnonzero(feasible)[pareto_front(x[feasible], y[feasible], maximize)] if feasible.any() else np.array([], dtype=int)
    if len(front):
        left.plot(x[front], y[front], "-o", color="tab:red", markersize=3, label=f"Pareto front ({len(front)})")
    nominal = provenance.get("nominal", {}).get("quantities", {})
    if x_label in nominal and y_label in nominal:
        left.plot(nominal[x_label], nominal[y_label], "*", color="black", markersize=14, label="nominal design")
    senses = ["max" if m else "min" for m in maximize]
    left.set_xlabel(f"{x_label} ({senses[0]})")
    left.set_ylabel(f"{y_label} ({senses[1]})")
    failed = int((~ok).sum())
    left.set_title(f"{provenance['model']} / {provenance['study']}: {len(ok)} variants" + (f", {failed} not ok" if failed else ""))
    left.legend(loc="best", fontsize=8)
    left.grid(alpha=0.3)

    if result is None:
        right.text(0.5, 0.5, "too few ok variants to rank the parameters", ha="center", va="center")
        right.set_axis_off()
    else:
        _ranking_map(right, result)
    return save(figure, path, dpi=110)


def _ranking_map(axes, result: Ranking) -> None:
    """The SRCs as a map: parameters (most influential first) down, quantities across."""
    order = np.argsort(-np.abs(result.src).max(axis=0))
    shown = result.src[:, order].T
    limit = max(1e-12, float(np.abs(shown).max()))
    axes.imshow(shown, cmap="RdBu_r", vmin=-limit, vmax=limit, aspect="auto")
    for r in range(shown.shape[0]):
        for c in range(shown.shape[1]):
            axes.text(c, r, f"{shown[r, c]:+.2f}", ha="center", va="center", fontsize=8)
    axes.set_yticks(range(len(order)), [result.parameters[j] for j in order], fontsize=8)
    ticks = [_short(q) + (f"\nR²={r2:.2f}" if np.isfinite(r2) else "\nconstant") for q, r2 in zip(result.quantities, result.r2)]
    axes.set_xticks(range(len(result.quantities)), ticks, fontsize=7, rotation=30, ha="right")
    axes.set_title(f"sensitivity ranking: standardized regression coefficients ({result.variants} ok variants)", fontsize=9)


def _short(label: str) -> str:
    """A quantity's label cut for a tick: its kind and first argument."""
    return label if len(label) <= 28 else label[:26] + "…"
