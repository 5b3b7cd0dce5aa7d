"""Pictures checked from their figures' objects (issue 27): what each promises, not only that a
file was written."""

from __future__ import annotations

import re

import numpy as np
from matplotlib.patches import Patch
from scipy.spatial.transform import Rotation

from kinegen.analysis.animation import animate, animation_figure, gif_frame
from kinegen.analysis.chart import outlines, transport_q, working_range_figure
from kinegen.analysis.plots import _in_frame
from kinegen.analysis.view import _BARREL, _OUT, _ROD, cylinder
from kinegen.figures import pyplot
from kinegen.runtime import export, kinematics, solve
from tests.conftest import WORKING_RANGE_GROUP, excavator_working_range, generated_system, model


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
    lengths = {n: kinematics.actuator_length(results, n) for n in names}
    seen_out = seen_in = False
    for k in keep:
        artists = draw(int(k))
        barrels, rods = artists[bodies : bodies + len(names)], artists[bodies + len(names) : bodies + 2 * len(names)]
        for name, barrel, rod in zip(names, barrels, rods):
            (b1, p1), (b2, p2), limits = system.actuators[name]
            base = _in_frame(results, "upper", kinematics.point_position(results, b1, p1))[k] @ basis.T
            eye = _in_frame(results, "upper", kinematics.point_position(results, b2, p2))[k] @ basis.T
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


@WORKING_RANGE_GROUP
def test_the_working_range_chart_draws_the_machine_quotes_its_figures_and_keeps_its_labels_off_the_drawing():
    """The excavator's chart: every dimension line runs from the swing axis (horizontal figures) or
    the ground (vertical ones) to exactly the figure it quotes; the letters overlap neither each
    other, nor any dimension line but their own, nor the boundary, nor the machine; the
    undercarriage and the upper structure are the model's outlines (the upper one moved with the
    transport pose), projected; no horizontal dimension lies on the ground band; the legend is
    beside the drawing, and the drawing is sized to its content (equal scales, no blank band)."""
    excavator = model("excavator")
    _, system, envelope, boundary = excavator_working_range()
    drawn = outlines(excavator)
    assert set(drawn) == {"ground", "upper"}
    fig = working_range_figure(envelope, boundary, system, boundary.direction, drawn)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    ax, side = fig.axes
    by_gid = {a.get_gid(): a for a in ax.get_children() if a.get_gid()}
    figures = {**envelope.figures, "min_front_swing_radius": envelope.front.radius}
    letters = {"A": "max_reach", "B": "max_reach_at_ground", "C": "max_depth", "D": "max_cutting_height",
               "E": "max_dumping_height", "F": "max_vertical_wall_depth", "G": "min_front_swing_radius"}  # fmt: skip
    for letter, name in letters.items():
        ends = np.column_stack(by_gid[f"dimension:{letter}"].get_data())
        if letter in "ABG":  # horizontal, from the swing axis, not on the ground band
            assert ends[0, 0] == 0.0 and abs(ends[1, 0] - figures[name]) < 1e-12 and ends[0, 1] == ends[1, 1]
            assert not -0.2 <= ends[0, 1] <= 0.05, letter
        else:  # vertical, from the ground
            assert ends[0, 1] == 0.0 and abs(abs(ends[1, 1]) - figures[name]) < 1e-12 and ends[0, 0] == ends[1, 0]
    vertical = sorted(np.column_stack(by_gid[f"dimension:{letter}"].get_data())[0, 0] for letter in "CDEF")
    assert min(np.diff(vertical)) >= 0.45 - 1e-12  # no two vertical dimension lines on each other (C and F sit near one reach)
    from kinegen.analysis.chart import DIFFERS

    for letter, name in letters.items():  # each published figure that differs is on its own dimension line
        published = excavator.working_range.published.get(name)
        if published is not None and abs(published - figures[name]) > DIFFERS:
            at = by_gid[f"published:{letter}"].get_xydata()[0]
            ends = np.column_stack(by_gid[f"dimension:{letter}"].get_data())
            assert abs((at[0] if letter in "ABG" else abs(at[1])) - published) < 1e-12 and (at[1] if letter in "ABG" else at[0]) == ends[0, 1 if letter in "ABG" else 0]
        else:
            assert f"published:{letter}" not in by_gid
    words = " ".join(t.get_text() for t in [*side.texts, *ax.texts, ax.title])
    assert "solves" not in words and not re.search(r"\d s\b", words)  # no run statistics in the drawing
    labels = {letter: by_gid[f"label:{letter}"].get_window_extent(renderer) for letter in letters}
    for a in letters:
        for b in letters:
            assert a >= b or not labels[a].overlaps(labels[b]), (a, b)
    obstacles = [a for gid, a in by_gid.items() if gid.startswith(("machine:", "dimension:")) or gid == "boundary"]
    for letter, box in labels.items():
        for artist in obstacles:
            if artist.get_gid() == f"dimension:{letter}":
                continue
            path = artist.get_transform().transform_path(artist.get_path())
            assert not path.intersects_bbox(box, filled=isinstance(artist, Patch)), (letter, artist.get_gid())
    ground = by_gid["machine:ground"].get_xy()[:-1]  # a closed polygon repeats its first vertex
    assert np.allclose(ground, np.array(excavator.ground_outline)[:, [0, 2]], atol=1e-12)
    q, _ = transport_q(system, envelope)
    stored = system.body_coordinates(q, "upper")  # x, y, z, then the unit quaternion w, x, y, z
    upper = stored[:3] + Rotation.from_quat(stored[[4, 5, 6, 3]]).apply(drawn["upper"])  # SciPy: scalar last
    expected = np.column_stack([upper[:, :2] @ boundary.direction, upper[:, 2]])
    assert np.allclose(by_gid["machine:upper"].get_xy()[:-1], expected, atol=1e-12)
    assert ax.get_legend() is None and side.get_legend() is not None
    assert not side.get_legend().get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
    box = ax.get_window_extent(renderer)
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert abs(box.width / box.height - (x1 - x0) / (y1 - y0)) < 0.02 * box.width / box.height  # the drawing fills its axes
    assert box.width > 0.5 * fig.bbox.width and box.height > 0.8 * fig.bbox.height
    pyplot().close(fig)


def _panels(fig) -> dict:
    return {ax.get_gid(): ax for ax in fig.axes}


def test_the_case_plot_of_a_four_bar_traces_the_chosen_point_and_plots_signed_angular_rates():
    """four_bar: the traced point is the one asked for (coupler.C, its projected path exactly);
    each body's rate is signed about its fixed axis (z): the crank's and the rocker's equal the
    time derivative of their angles from their points' positions (central differences, 1e-3 of
    the largest); the condition curve is sigma_max / sigma_min of Phi_q (SciPy's svdvals); the
    legends lie beside the panels, covering no curve."""
    from scipy.linalg import svdvals

    from kinegen.analysis.plots import case_figure

    results = solve(generated_system("four_bar_quaternion"))
    system = results.system
    fig = case_figure(results, None, ("coupler", "C"))
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    panels = _panels(fig)
    (path,) = [line for line in panels["drawing"].lines if line.get_gid() == "path"]
    expected = kinematics.point_position(results, "coupler", "C")[:, :2]  # the x-y plane: the four-bar's
    assert np.allclose(np.column_stack(path.get_data()), expected, atol=1e-12)
    assert panels["drawing"].get_xlabel() == "x, global [m]" and panels["drawing"].get_ylabel() == "y, global [m]"
    curves = {line.get_label().split(",")[0]: line for line in panels["omega"].lines}
    t = results.times
    for body, (a, b) in {"crank": ("A", "B"), "rocker": ("D", "C")}.items():
        d = kinematics.point_position(results, body, b) - kinematics.point_position(results, body, a)
        angle = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
        rate = np.gradient(angle, t, edge_order=2)
        plotted = curves[body].get_ydata()
        assert "about (0, 0, 1)" in curves[body].get_label()
        assert np.abs(plotted[2:-2] - rate[2:-2]).max() < 1e-3 * np.abs(rate).max(), body
    assert (curves["rocker"].get_ydata() < 0).any() and (curves["rocker"].get_ydata() > 0).any()  # signed: no |omega| cusps
    condition = panels["condition"].lines[0].get_ydata()
    for k in (0, len(t) // 3, len(t) - 1):
        s = svdvals(system.jacobian(results.q[k], results.inputs[k]))
        assert abs(condition[k] - s[0] / s[-1]) < 1e-9 * condition[k]
    for name in ("omega",):
        legend = panels[name].get_legend()
        assert not legend.get_window_extent(renderer).overlaps(panels[name].get_window_extent(renderer))
    pyplot().close(fig)


def test_a_tilted_plane_is_named_and_its_axes_given_in_words():
    """plane_axes: the x-y/x-z/y-z planes by name; a plane tilted 30 deg from the vertical with its
    horizontal line at heading 40 deg is drawn along that line and up the plane, labelled with
    those angles (no direction vectors), its axes orthonormal and in the plane."""
    from kinegen.analysis.plots import plane_axes

    assert plane_axes(np.array([0, 1.0, 0]))[1] == ("x, global [m]", "z, global [m]")
    assert plane_axes(np.array([0, 0, -1.0]))[2] == "the x-y plane"
    heading, tilt = np.radians(40.0), np.radians(30.0)
    level = np.array([np.cos(heading), np.sin(heading), 0.0])
    up = np.cos(tilt) * np.array([0, 0, 1.0]) + np.sin(tilt) * np.cross([0, 0, 1.0], level)
    basis, labels, name = plane_axes(np.cross(level, up))
    assert np.allclose(basis, [level, up], atol=1e-12)
    assert labels == ("horizontal, heading 40 deg from x toward y [m]", "up the plane, 30 deg from the vertical [m]")
    assert name == "a plane tilted 30 deg from the vertical, heading 40 deg" and "(" not in "".join(labels).replace("[m]", "")


def test_the_excavators_case_plot_keeps_its_legends_off_the_curves():
    """digging: the actuator-length legend beside its panel; the drawing has none (its title names
    the traced path)."""
    from kinegen.analysis.plots import case_figure

    results = solve(generated_system("excavator_quaternion", "digging", compiled=True))
    fig = case_figure(results, "upper", ("bucket", "T"))
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    panels = _panels(fig)
    legend = panels["lengths"].get_legend()
    assert not legend.get_window_extent(renderer).overlaps(panels["lengths"].get_window_extent(renderer))
    assert panels["drawing"].get_legend() is None and "red: the path of bucket.T" in panels["drawing"].get_title()
    labels = [tick.get_text() for tick in panels["condition"].get_yticklabels() if tick.get_text()]
    assert labels and all("$" not in text for text in labels)  # plain numbers, not 10^x mathtext
    pyplot().close(fig)


def test_the_case_plot_shows_both_twin_cylinders_labels_its_ranges_and_draws_the_ground_only_where_the_model_does(tmp_path):
    """The excavator's digging plot (with its model): the right boom cylinder, whose length is the
    left one's, is drawn dashed over it (in the drawing and both panels), each distinct range once
    with its min and max labelled by the cylinders that share it, the ground line (the model draws
    the ground); the condition curve is the CSV's jacobian_condition, sigma_max / sigma_min (SciPy's
    svdvals). The boom (no ground outline) gets no ground line; every axis is named in words."""
    from scipy.linalg import svdvals

    from kinegen.analysis.plots import case_figure

    excavator = model("excavator")
    results = solve(generated_system("excavator_quaternion", "digging", compiled=True))
    fig = case_figure(results, "upper", ("bucket", "T"), model=excavator)
    panels = _panels(fig)
    twins = [line for line in panels["drawing"].lines if line.get_gid() == "twin:boom_cylinder_right"]
    assert len(twins) == 6 and all(line.get_linestyle() == "--" for line in twins)
    for name in ("lengths", "rates"):
        (dashed,) = [line for line in panels[name].lines if line.get_label() == "boom_cylinder_right (= boom_cylinder_left)"]
        (left,) = [line for line in panels[name].lines if line.get_label() == "boom_cylinder_left"]
        assert np.allclose(dashed.get_ydata(), left.get_ydata(), atol=1e-9) and dashed.get_linestyle() != left.get_linestyle()
    texts = [t.get_text() for t in panels["lengths"].texts]
    assert "min boom_cylinder_left (+1)" in texts and "max boom_cylinder_left (+1)" in texts  # the twins' one range
    assert {"min arm_cylinder", "max arm_cylinder", "min bucket_cylinder", "max bucket_cylinder"} <= set(texts)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in panels["lengths"].texts]
    assert not any(boxes[i].overlaps(boxes[j]) for i in range(len(boxes)) for j in range(i))  # the range labels never collide
    assert any(line.get_gid() == "ground" for line in panels["drawing"].lines)
    names, table = export.table(results)
    condition = panels["condition"].lines[0].get_ydata()
    np.testing.assert_array_equal(condition, table[:, names.index("jacobian_condition")])
    for k in (0, len(condition) // 2, len(condition) - 1):
        s = svdvals(results.system.jacobian(results.q[k], results.inputs[k]))
        assert abs(condition[k] - s[0] / s[-1]) < 1e-9 * condition[k]
    for ax in panels.values():
        assert ax.get_ylabel() and not ax.get_ylabel().startswith("[")
    assert panels["drawing"].get_xlabel() == "x along the upper frame [m]"
    pyplot().close(fig)
    boom = solve(generated_system("boom_quaternion"))
    fig = case_figure(boom, None, ("boom", "tip"), model=model("boom"))
    assert not any(line.get_gid() == "ground" for line in _panels(fig)["drawing"].lines)
    pyplot().close(fig)


def test_the_animations_gif_holds_every_frame_each_within_a_few_levels_of_its_rendering(tmp_path):
    """The GIF of the four-bar's crank turn holds one picture per drawn time point, and a frame reduced to
    the GIF's 256 colours (Pillow's fast octree) is within 16/255 of matplotlib's rendering at every
    pixel, 2/255 on average (the digging cycle's 86 frames measured 14/255 and 1.05/255)."""
    from PIL import Image

    results = solve(generated_system("four_bar_quaternion", "crank_turn", compiled=True))
    gif = animate(results, tmp_path / "crank_turn.gif")
    fig, draw, keep = animation_figure(results)
    with Image.open(gif) as opened:
        assert opened.n_frames == len(keep)
    for k in (keep[0], keep[len(keep) // 2]):
        draw(int(k))
        fig.canvas.draw()
        rendered = np.asarray(fig.canvas.buffer_rgba())
        reduced = np.asarray(gif_frame(rendered).convert("RGB"), dtype=float)
        difference = np.abs(reduced - rendered[..., :3]).max(axis=2)
        assert difference.max() <= 16 and difference.mean() <= 2, (difference.max(), difference.mean())
    pyplot().close(fig)


def test_a_distance_joints_coupler_is_drawn_in_the_plot_the_animation_and_the_page(tmp_path):
    """The RSSR's coupler is a distance joint, carried by no body: the case plot, the animation's
    frames and the 3-D page each draw it as a line between exactly its two points."""
    from kinegen.analysis.plots import case_figure
    from kinegen.analysis.view import _Scene

    rssr = model("rssr")
    results = solve(generated_system("rssr_quaternion"))
    ends = [kinematics.point_position(results, "crank", "B"), kinematics.point_position(results, "rocker", "C")]
    fig = case_figure(results, None, None, model=rssr)
    drawn = [line for line in _panels(fig)["drawing"].lines if (line.get_gid() or "").startswith("coupler:")]
    assert len(drawn) == 6
    pyplot().close(fig)
    fig, draw, keep = animation_figure(results, None, None, rssr)
    (line,) = [a for a in fig.axes[0].lines if (a.get_gid() or "").startswith("coupler:")]
    assert fig.axes[0].get_xlabel().startswith("horizontal, heading") and fig.axes[0].get_ylabel().startswith("up the plane")  # in words
    assert "coupler (distance joint)" in [t.get_text() for t in fig.legends[0].get_texts()]
    k = int(keep[len(keep) // 2])
    draw(k)
    xy = np.column_stack(line.get_data())
    assert abs(np.linalg.norm(ends[1][k] - ends[0][k]) - 0.52) < 1e-9  # the coupler's length, in space
    assert 0 < np.linalg.norm(xy[1] - xy[0]) <= 0.52 + 1e-9  # drawn: its projection on the animation's plane
    pyplot().close(fig)
    scene = _Scene(results, rssr, None, 1e6)
    (trace,) = [t for t in scene.traces(k) if t["name"] == "couplers (distance joints)"]
    np.testing.assert_allclose(np.column_stack([trace["x"], trace["y"], trace["z"]])[:2], np.array([ends[0][k], ends[1][k]]), atol=1e-12)


def test_the_exploration_plot_has_units_a_colour_bar_readable_cells_full_labels_and_shows_the_variants_not_measured():
    """An exploration of 60 variants (y1 = 2 a + b, y2 = b - a plus a little of c; 5 not ok): the
    Pareto axes carry the quantities' units and say "larger is better" only for what the study maximizes,
    the parameters' axes their units, no legend entry counts zero variants, the not-ok
    variants are drawn (grey crosses, all 5) in the parameters that tell them apart, the map has a
    colour bar, each cell's number is white on a dark colour and black on a light one, and the
    quantities' full names label the columns without overlapping."""
    import pyarrow as pa

    from kinegen.explore.plots import exploration_figure

    rng = np.random.default_rng(1)
    a, b, c = rng.uniform(size=(3, 60))
    ok = np.ones(60, dtype=bool)
    ok[a > np.sort(a)[-6]] = False  # the 5 largest a: not measured
    y1 = np.where(ok, 2 * a + b, np.nan)
    y2 = np.where(ok, b - a + 0.01 * c, np.nan)
    names = ["max_reach", "actuator_margin(boom_cylinder_left, digging)"]
    table = pa.table({"a": a, "b": b, "c": c, "status": np.where(ok, "ok", "unreachable"), names[0]: y1, names[1]: y2,
                      "feasible": ok})  # fmt: skip
    provenance = {"model": "m", "study": "s", "parameters": ["a", "b", "c"], "quantities": names, "senses": {names[0]: "maximize"},
                  "units": {"a": "m", "b": "m", "c": "kg"}}  # fmt: skip
    fig = exploration_figure(table, provenance, (names[0], names[1]), (True, True))
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    panels = _panels(fig)
    pareto, failed, ranking = panels["pareto"], panels["failed"], panels["ranking"]
    assert pareto.get_xlabel().startswith("max_reach [m]") and pareto.get_ylabel().startswith(f"{names[1]} [m]")
    # "larger is better" only where the study's objective says so: max_reach is its term, the margin only a constraint
    assert "larger is better: the study maximizes it" in pareto.get_xlabel()
    assert "better" not in pareto.get_ylabel() and "not ranked by the study" in pareto.get_ylabel()
    for ax in (pareto, failed):
        assert all("(0)" not in text.get_text() for text in ax.get_legend().get_texts())
    crosses = [c for c in failed.collections if c.get_label().startswith("not ok")]
    assert len(crosses) == 1 and len(crosses[0].get_offsets()) == 5 and failed.get_xlabel() == "a [m]" and failed.get_ylabel().endswith("]")
    (image,) = ranking.images
    assert image.colorbar is not None
    for text in ranking.texts:
        x, y = (round(v) for v in text.get_position())
        rgba = image.cmap(image.norm(image.get_array()[y, x]))
        luminance = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2]
        assert abs((1.0 if text.get_color() == "white" else 0.0) - luminance) >= 0.5, (text.get_text(), luminance)
    labels = [t for t in ranking.get_xticklabels() if t.get_text()]
    assert [t.get_text().split("\nR²")[0].replace(",\n", ", ") for t in labels] == names
    boxes = [t.get_window_extent(renderer) for t in labels]
    assert not any(boxes[i].overlaps(boxes[j]) for i in range(len(boxes)) for j in range(i))
    pyplot().close(fig)


@WORKING_RANGE_GROUP
def test_the_force_map_draws_its_cells_inside_the_exact_boundary_and_states_its_assumptions():
    """The tangent force map (a coarse raster): on both panels the filled contours (and the lines)
    are clipped to the working range's exact boundary, which the axes show whole; every raster point
    inside the boundary is coloured (no white holes); the legend of the limiting cylinders lies below
    the panels; the figure says what is assumed (static, massless, no friction), how it is made and
    how it differs from the ISO 6015 figure."""
    from kinegen.forces.maps import _filled, force_map_figure, reach_map

    _, system, _, boundary = excavator_working_range()
    found = reach_map(system, model("excavator"), "tangent", attitudes=9, per_input=11, spacing=0.1)
    fig = force_map_figure(found, boundary)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes[:2]:  # the two panels (then the colour bar)
        filled = [a for a in ax.collections if a.get_clip_path() is not None]
        assert filled
        for artist in filled:
            vertices = artist.get_clip_path().get_fully_transformed_path().vertices  # display coordinates
            drawn = ax.transData.transform(boundary.points[:, :2])
            assert np.abs(vertices[: len(drawn)] - drawn).max() < 1e-6
        (x0, x1), (z0, z1) = ax.get_xlim(), ax.get_ylim()
        assert x0 < boundary.points[:, 0].min() and boundary.points[:, 0].max() < x1
        assert z0 < boundary.points[:, 1].min() and boundary.points[:, 1].max() < z1
    force, limiting, _ = _filled(found, boundary)
    from matplotlib.path import Path as Outline

    rr, hh = np.meshgrid(found.radius, found.height)
    inside = Outline(boundary.points[:, :2]).contains_points(np.column_stack([rr.ravel(), hh.ravel()])).reshape(rr.shape)
    assert np.isfinite(force[inside]).all() and (limiting[inside] >= 0).all()
    legend = fig.axes[1].get_legend().get_window_extent(renderer)
    assert legend.y1 < fig.axes[1].get_window_extent(renderer).y0
    title = fig._suptitle.get_text()
    assert "static, massless links, no friction" in title and "Not the ISO 6015 figure" in title and "exact poses" in title


@WORKING_RANGE_GROUP
def test_the_lift_chart_picture_writes_each_rating_at_its_point_coloured_by_its_limit():
    """Every grid point of the lift chart carries two labels, the ratings over the front and the side
    as the table prints them ('*' where hydraulic), blue where the hydraulic limit rules and red where
    tipping does, next to the point; beside the drawing, the table in the manufacturers' layout (a
    row per height, front and side per radius, the largest reach's ratings and radius), coloured the
    same; the outline drawn is the lift point's own range: every rated grid point inside it, every
    point the lift point cannot reach outside; the rule is stated, and the legend covers no label."""
    from matplotlib.colors import to_hex
    from matplotlib.path import Path as Outline

    from kinegen.forces.lift import lift_chart, lift_chart_figure

    _, _, _, boundary = excavator_working_range()
    chart = lift_chart(generated_system("excavator_quaternion", "digging"), model("excavator"))
    fig = lift_chart_figure(chart, boundary)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    ax, side = fig.axes
    labels = {(round(t.xy[0], 9), round(t.xy[1], 9), t.get_text()): to_hex(t.get_color()) for t in ax.texts}
    points = [p for row in chart.grid for p in row if p is not None]
    assert len(ax.texts) == 2 * len(points)
    for p in points:
        for on_side in (False, True):
            value, limit = p.rated(on_side)
            text = f"{'*' if limit == 'hydraulic' else ''}{value:,.0f}"
            assert labels[(round(p.radius, 9), round(p.height, 9), text)] == to_hex("tab:blue" if limit == "hydraulic" else "tab:red")
    cells = {gid: c for c in side.tables[0].get_celld().values() if (gid := c.get_gid())}
    radii = len(chart.radii)
    for r, (height, far) in enumerate(zip(chart.heights, chart.max_reach), start=1):
        assert cells[f"cell:{r}:0"].get_text().get_text() == f"{height:g} m"
        for on_side in (False, True):
            value, limit = far.rated(on_side)
            cell = cells[f"cell:{r}:{1 + 2 * radii + on_side}"].get_text()
            assert cell.get_text() == f"{'*' if limit == 'hydraulic' else ''}{value:,.0f}"
            assert to_hex(cell.get_color()) == to_hex("tab:blue" if limit == "hydraulic" else "tab:red")
        assert cells[f"cell:{r}:{3 + 2 * radii}"].get_text().get_text() == f"{far.radius:.2f} m"
    (outline,) = [line for line in ax.lines if line.get_gid() == "outline"]
    assert "range of the lift point arm.Q" in outline.get_label()
    inside = Outline(np.column_stack(outline.get_data()))
    for row, height in zip(chart.grid, chart.heights):
        for p, radius in zip(row, chart.radii):
            assert inside.contains_point((radius, height)) == (p is not None), (radius, height)
    legend = ax.get_legend().get_window_extent(renderer)
    assert not any(legend.overlaps(t.get_window_extent(renderer)) for t in ax.texts)
    assert "75 % of the tipping load" in fig._suptitle.get_text()
