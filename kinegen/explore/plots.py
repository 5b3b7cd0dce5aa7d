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
    """:func:`exploration_figure` written to ``path`` (PNG)."""
    from kinegen.figures import save

    return save(exploration_figure(table, provenance, pareto, maximize), path, dpi=110)


def exploration_figure(table, provenance: dict, pareto: tuple[str, str], maximize: tuple[bool, bool]):
    """The Pareto front of the two ``pareto`` quantities (every ok variant, the feasible ones, the
    front, the nominal design; axes in the quantities' units) and, when some variants could not be
    measured, where they lie among the ok ones in the two parameters that tell them apart best
    (greyed); beside them the parameters' SRC ranking for every quantity, with its colour bar.
    Legend entries only for what is drawn. Axes carry gids: ``pareto``, ``failed``, ``ranking``."""
    from kinegen.figures import legend_beside, pyplot

    plt = pyplot()
    data = {name: table.column(name).to_numpy(zero_copy_only=False) for name in table.column_names}
    ok = data["status"] == "ok"
    feasible = data["feasible"] & ok
    x_label, y_label = pareto
    x, y = data[x_label], data[y_label]
    result = ranking_of(table, provenance)
    failed = int((~ok).sum())
    parameters = list(provenance["parameters"])

    figure = plt.figure(figsize=(15, 6.5))
    grid = figure.add_gridspec(2 if failed else 1, 2, width_ratios=[1.0, 1.15], height_ratios=[2.2, 1] if failed else [1])
    left = figure.add_subplot(grid[0, 0], gid="pareto")
    right = figure.add_subplot(grid[:, 1], gid="ranking")
    infeasible = ok & ~feasible
    if infeasible.any():
        left.scatter(x[infeasible], y[infeasible], s=6, color="0.7", label=f"ok, a constraint not met ({int(infeasible.sum())})")
    if feasible.any():
        left.scatter(x[feasible], y[feasible], s=6, color="tab:blue", alpha=0.6, label=f"feasible ({int(feasible.sum())})")
    front = np.flatnonzero(feasible)[pareto_front(x[feasible], y[feasible], maximize)] if feasible.any() else np.array([], dtype=int)
    if len(front):
        left.plot(x[front], y[front], "-o", color="tab:red", markersize=3, label=f"Pareto front ({len(front)})")
    nominal = provenance.get("nominal", {}).get("quantities", {})
    if x_label in nominal and y_label in nominal:
        left.plot(nominal[x_label], nominal[y_label], "*", color="black", markersize=14, label="nominal design")
    said = provenance.get("senses", {})
    senses = [_sense(label, said.get(label), m) for label, m in zip(pareto, maximize)]
    left.set_xlabel(f"{x_label} [{quantity_unit(x_label)}]\n({senses[0]})")
    left.set_ylabel(f"{y_label} [{quantity_unit(y_label)}]\n({senses[1]})")
    left.set_title(f"{provenance['model']} / {provenance['study']}: {len(ok)} variants" + (f", {failed} not ok" if failed else ""))
    legend_beside(left, fontsize=8)
    left.grid(alpha=0.3)
    if failed:
        _failed_variants(figure.add_subplot(grid[1, 0], gid="failed"), data, parameters, ok, provenance.get("units", {}))
    if result is None:
        right.text(0.5, 0.5, "too few ok variants to rank the parameters", ha="center", va="center")
        right.set_axis_off()
    else:
        _ranking_map(figure, right, result)
    figure.tight_layout()
    return figure


def _sense(label: str, study: str | None, maximize: bool) -> str:
    """What an axis says of its quantity: "larger is better" only where the study's objective says
    so (``study``: ``maximize``, ``minimize`` or ``target``; None: the study does not rank it), else
    only how the front was drawn."""
    taken = "larger" if maximize else "smaller"
    if study == "maximize":
        return "larger is better: the study maximizes it" + ("" if maximize else "; front: smaller")
    if study == "minimize":
        return "smaller is better: the study minimizes it" + ("" if not maximize else "; front: larger")
    if study == "target":
        return f"the study aims at a target; front: {taken}"
    return f"not ranked by the study; front: {taken}"


def quantity_unit(label: str) -> str:
    """The unit of a study quantity's column (a working-range figure's name, or ``kind(...)``)."""
    from kinegen.model.schema import QUANTITY_UNITS, WORKING_RANGE_FIGURES

    return "m" if label in WORKING_RANGE_FIGURES else QUANTITY_UNITS.get(label.split("(")[0], "?")


def _failed_variants(axes, data: dict, parameters: list[str], ok: np.ndarray, parameter_units: dict[str, str]) -> None:
    """The variants that could not be measured (grey crosses) among the ok ones (blue dots), in
    the two parameters whose values tell the two groups apart best (difference of means over
    the spread)."""
    from kinegen.figures import legend_beside

    values = np.column_stack([np.asarray(data[p], dtype=float) for p in parameters])
    spread = values.std(axis=0)
    spread[spread == 0] = 1.0
    separation = np.abs(values[~ok].mean(axis=0) - values[ok].mean(axis=0)) / spread
    order = np.argsort(-separation)
    a, b = order[0], order[min(1, len(order) - 1)]  # one parameter: against itself
    axes.scatter(values[ok, a], values[ok, b], s=5, color="tab:blue", alpha=0.35, label=f"ok ({int(ok.sum())})")
    axes.scatter(values[~ok, a], values[~ok, b], s=22, marker="x", color="0.35", label=f"not ok ({int((~ok).sum())}): no measure")
    axes.set_xlabel(f"{parameters[a]} [{parameter_units.get(parameters[a], '?')}]")
    axes.set_ylabel(f"{parameters[b]} [{parameter_units.get(parameters[b], '?')}]")
    axes.set_title("where the variants that could not be measured lie", fontsize=9)
    legend_beside(axes, fontsize=8)
    axes.grid(alpha=0.3)


def _ranking_map(figure, axes, result: Ranking) -> None:
    """The SRCs as a map: parameters (most influential first) down, quantities across, each cell's
    value written in black or white (whichever contrasts more with its colour's luminance), a
    colour bar beside it."""
    order = np.argsort(-np.abs(result.src).max(axis=0))
    shown = result.src[:, order].T
    limit = max(1e-12, float(np.abs(shown).max()))
    image = axes.imshow(shown, cmap="RdBu_r", vmin=-limit, vmax=limit, aspect="auto")
    for r in range(shown.shape[0]):
        for c in range(shown.shape[1]):
            red, green, blue, _ = image.cmap(image.norm(shown[r, c]))
            dark = 0.299 * red + 0.587 * green + 0.114 * blue < 0.5  # the cell's luminance: white text on it
            value = f"{shown[r, c]:+.2f}" if abs(shown[r, c]) >= 0.005 else "0.00"  # no -0.00
            axes.text(c, r, value, ha="center", va="center", fontsize=8, color="white" if dark else "black")
    axes.set_yticks(range(len(order)), [result.parameters[j] for j in order], fontsize=8)
    ticks = [q.replace(", ", ",\n") + (f"\nR²={r2:.2f}" if np.isfinite(r2) else "\nconstant") for q, r2 in zip(result.quantities, result.r2)]
    axes.set_xticks(range(len(result.quantities)), ticks, fontsize=7, rotation=35, ha="right", rotation_mode="anchor")
    axes.set_title(f"sensitivity ranking: standardized regression coefficients ({result.variants} ok variants)", fontsize=9)
    bar = figure.colorbar(image, ax=axes, fraction=0.05, pad=0.02)
    bar.set_label("SRC: the quantity's change per parameter change (each in its standard deviations)", fontsize=8)
