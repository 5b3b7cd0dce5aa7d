"""Pictures checked from their figures' objects (issue 27): what each promises, not only that a
file was written."""

from __future__ import annotations

import numpy as np

from kinegen.analysis.animation import animation_figure
from kinegen.analysis.plots import _in_frame, pyplot
from kinegen.analysis.view import _BARREL, _OUT, _ROD, cylinder
from kinegen.runtime import solve
from tests.conftest import generated_system


def _bbox(artist, renderer):
    return artist.get_window_extent(renderer)


def test_the_animation_draws_each_cylinder_as_barrel_and_rod_red_out_of_range_with_a_legend_off_the_drawing():
    """bucket_near_toggle (the bucket cylinder leaves its range at some time points), in the upper
    structure's x-z plane: at every drawn time point each actuator's barrel starts at its base and
    its rod ends at its eye (the points' solved positions, projected), with the lengths `cylinder`
    gives; red exactly where the actuator is out of its range; the legend names bodies, barrel,
    rod, out of range and the path, lies below the axes (no overlap) and the axes fill the width."""
    results = solve(generated_system("excavator_quaternion", "bucket_near_toggle", compiled=True))
    system = results.system
    fig, draw, keep = animation_figure(results, "upper", ("bucket", "T"))
    names = list(system.actuators)
    bodies = len([b for b, p in system.points.items() if b != "ground" and p])
    basis = np.array([[1.0, 0, 0], [0, 0, 1.0]])
    lengths = {n: results.actuator_length(n) for n in names}
    seen_out = seen_in = False
    for k in keep:
        artists = draw(int(k))
        barrels, rods = artists[bodies : bodies + len(names)], artists[bodies + len(names) : bodies + 2 * len(names)]
        for name, barrel, rod in zip(names, barrels, rods):
            (b1, p1), (b2, p2), limits = system.actuators[name]
            base = _in_frame(results, "upper", results.point_position(b1, p1))[k] @ basis.T
            eye = _in_frame(results, "upper", results.point_position(b2, p2))[k] @ basis.T
            expected_barrel, expected_rod = cylinder(base, eye, limits)
            assert np.allclose(np.column_stack(barrel.get_data()), expected_barrel, atol=1e-12), (name, k)
            assert np.allclose(np.column_stack(rod.get_data()), expected_rod, atol=1e-12), (name, k)
            out = limits is not None and not limits[0] - 1e-9 <= lengths[name][k] <= limits[1] + 1e-9
            assert (barrel.get_color(), rod.get_color()) == ((_OUT, _OUT) if out else (_BARREL, _ROD)), (name, k)
            seen_out |= out
            seen_in |= not out
    assert seen_out and seen_in  # both states drawn
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    (legend,) = fig.legends
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels == ["bodies", "cylinder barrel", "cylinder rod", "out of its range", "path of bucket.T"]
    ax = fig.axes[0]
    assert not _bbox(legend, renderer).overlaps(ax.get_tightbbox(renderer))  # off the drawing and its labels
    assert _bbox(ax, renderer).width >= 0.8 * fig.bbox.width  # no wide margins
    pyplot().close(fig)
