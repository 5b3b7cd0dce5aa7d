"""The picture of a time-optimal cycle (:class:`kinegen.forces.cycle.Cycle`): the path speed along
the path coloured by the limit that holds it, the fastest speed each point allows on its own, and
what the pumps and the engine give along the re-timed motion."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinegen.figures import pyplot, save


def plot_cycle(cycle, path: str | Path, flows=None) -> Path:
    """PNG of ``cycle``: top, the path speed ṡ (1: the case's own pace) over the case's own time s,
    each stretch coloured by its limiting constraint, under the speed the flows and speed limits
    alone allow (dashed); bottom, with ``flows`` (:class:`kinegen.forces.supply.Flows` of the re-timed
    motion with its forces), each pump's flow and the engine's power as fractions of their limits
    over the re-timed time."""
    plt = pyplot()
    rows = 2 if flows is not None else 1
    fig, axes = plt.subplots(rows, 1, figsize=(11, 4.2 * rows), squeeze=False)
    top = axes[0, 0]
    names = list(dict.fromkeys(str(n) for n in cycle.limiting))
    colours = {name: plt.get_cmap("tab10")(k % 10) for k, name in enumerate(names)}
    s, speed = cycle.s, cycle.speed
    for k in range(len(s) - 1):
        top.plot(s[k : k + 2], speed[k : k + 2], color=colours[str(cycle.limiting[k])], linewidth=2.2, solid_capstyle="butt")
    bound = cycle.constraints.speed_bound
    if bound.shape[1]:
        alone = np.min(bound, axis=1)
        top.plot(s, alone, color="0.45", linestyle="--", linewidth=1,
                 label="fastest the flows and speed limits allow")  # fmt: skip
    top.axhline(1.0, color="0.6", linewidth=0.8, linestyle=":")
    top.text(s[-1], 1.0, "the case's own pace ", va="bottom", ha="right", fontsize=8, color="0.4")
    for name in names:
        top.plot([], [], color=colours[name], linewidth=3, label=f"limited by {name}")
    top.set_xlim(s[0], s[-1])
    moving = speed[1:-1][speed[1:-1] > 0]
    top.set_yscale("log")
    top.set_ylim(0.7 * float(min(moving.min(), 1.0)), 1.5 * float(max(speed.max(), 1.0)))
    top.set_xlabel("position along the path: the case's own time s [s]")
    top.set_ylabel("path speed ds/dt, log scale (1 = the case's pace)")
    loads = f", holding {', '.join(cycle.loads)}" if cycle.loads else ""
    top.set_title(f"{cycle.model} / {cycle.case}: fastest timing {cycle.duration:.2f} s against the case's own "
                  f"{cycle.own_duration:.2f} s{loads}", fontsize=11)  # fmt: skip
    top.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3, fontsize=8, frameon=False)
    top.grid(alpha=0.3)
    if flows is not None:
        low = axes[1, 0]
        for p, name in enumerate(flows.pumps):
            low.plot(
                flows.times,
                100 * flows.flow[p] / flows.max_flow[p],
                label=f"pump {name}: flow, % of its {flows.max_flow[p] * 6e4:.0f} L/min",
            )
        if flows.power is not None:
            low.plot(flows.times, 100 * flows.power.sum(axis=0) / flows.engine_power, color="k", linewidth=1.2,
                     label=f"engine: power the pumps take, % of its {flows.engine_power / 1e3:.0f} kW")  # fmt: skip
        low.axhline(100, color="0.5", linewidth=0.8, linestyle=":")
        low.set_xlim(flows.times[0], flows.times[-1])
        low.set_ylim(0, 110)
        low.set_xlabel("time of the re-timed cycle t [s]")
        low.set_ylabel("share of the limit [%]")
        low.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize=8, frameon=False)
        low.grid(alpha=0.3)
    fig.tight_layout()
    written = save(fig, path)
    plt.close(fig)
    return written
