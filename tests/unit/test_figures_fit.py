"""Figures fit to print, checked on the laid-out artists (Agg renderer window extents), not on
pixels: legends and zoom insets stay off every data area, axis label and tick label and inside
the figure; tick labels and object labels do not overlap; detector colours differ by ΔE*ab ≥ 20;
a Doppler run shows velocity (and only a Doppler run has a velocity colour bar); the title's
track count is what is drawn; walls sit above the detections; posterior draws are visible; the
range–Doppler and fan views put a target where it is."""
import itertools
import re
from dataclasses import replace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from xnlos_core.app.plot import palette  # noqa: E402
from xnlos_core.app.plot.figures import OBJECT_LABEL, frame_figure  # noqa: E402
from xnlos_core.app.plot.frame_figure import frame_panels_figure  # noqa: E402
from xnlos_core.app.plot.radar_views import VELOCITY_LABEL  # noqa: E402
from xnlos_core.pipeline import FrameResult  # noqa: E402
from xnlos_core.testing import KIT_HIDDEN, KIT_WALL, small_radar, synthetic_frame  # noqa: E402
from xnlos_core.types import LOS, MNLOS, Detections, HiddenPoints, Tracks, WallPosterior  # noqa: E402

#: Two hidden objects side by side: their name labels would sit on each other.
OUTLINES = {"kit_object": KIT_HIDDEN[0] + np.array([[1.0, 0.5], [-1.0, 0.5], [-1.0, -0.5], [1.0, -0.5]]),
            "kit_object_two": KIT_HIDDEN[0] + np.array([[1.5, 0.6], [-0.5, 0.6], [-0.5, -0.4], [1.5, -0.4]])}


def _tracks() -> Tracks:
    """Three tracks: one at the hidden object, one behind-left of the radar, one 200 m out."""
    h = np.array([0.5, 1.0])
    pos = np.array([KIT_HIDDEN[0], [-16.0, 4.0], [200.0, -5.0]])
    vel = np.array([[0.0, 1.0], [1.0, -2.0], [0.0, 0.0]])
    r50 = np.tile(0.3 + 0.5 * h, (3, 1))
    return Tracks([1, 4, 9], pos, vel, pos, 2.0, horizons=h, forecast=pos[:, None] + vel[:, None] * h[None, :, None],
                  radius50=r50, radius90=2 * r50, model=("cv", "cv", "cv"))


def _result(doppler: bool = False, tracks: bool = True) -> FrameResult:
    frame = synthetic_frame()
    det_v = None
    if doppler:
        v = np.random.default_rng(1).normal(0.0, 2.0, frame.ra_map.data.shape)
        frame = replace(frame, ra_map=replace(frame.ra_map, velocity=v, velocity_std=np.full(v.shape, 0.3)))
        det_v = np.array([1.0, -2.0, 3.0, 0.0])
    det = Detections(np.array([18.0, 20.0, 30.0, 22.0]), np.radians([20.0, 5.0, -25.0, 10.0]),
                     np.array([LOS, LOS, MNLOS, LOS]), np.ones(4), velocity=det_v)
    hidden = HiddenPoints(KIT_HIDDEN + 0.4, 0.2 * np.eye(2)[None], np.array([2]), np.array([0]))
    phi, b = np.arctan2(KIT_WALL.normal[1], KIT_WALL.normal[0]), KIT_WALL.offset
    rng = np.random.default_rng(0)
    samples = np.column_stack([phi + rng.normal(0, 0.01, 100), b + rng.normal(0, 0.1, 100)])
    wall = WallPosterior("line", np.array([phi, b]), np.diag([1e-4, 1e-2]), n_points=6,
                         extent=np.array([KIT_WALL.start, KIT_WALL.end]), samples=samples)
    return FrameResult(frame, det, [wall], hidden, _tracks() if tracks else None)


def _laid_out(fig):
    fig.set_dpi(60)  # small: the checks compare extents, not pixels
    fig.tight_layout()  # as save_png lays a figure out
    fig.canvas.draw()
    return fig


def _panels(doppler: bool):
    res = _result(doppler, tracks=False)
    res.frame.meta["object_outlines"] = {k: v.tolist() for k, v in OUTLINES.items()}
    return frame_panels_figure(res, detector="cfar")


def _animation(doppler: bool):
    from xnlos_core.app.plot.animation import animation_figure
    from xnlos_core.app.plot.frame_snapshot import FrameSnapshot

    res = _result(doppler)
    rec = {"tracks": res.record()["tracks"]}
    return animation_figure(FrameSnapshot.from_result(res), rec)


FIGURES = {
    "frame": lambda: frame_figure(_result(), "t", objects=OUTLINES),
    "frame_doppler": lambda: frame_figure(_result(True), "t", objects=OUTLINES),
    "frame_fan": lambda: frame_figure(_result(True), "t", ra_view="cartesian"),
    "panels": lambda: _panels(False),
    "panels_doppler": lambda: _panels(True),
    "animation": lambda: _animation(False),
    "animation_doppler": lambda: _animation(True),
}


@pytest.fixture(scope="module")
def figs():
    made = {name: _laid_out(make()) for name, make in FIGURES.items()}
    yield made
    for f in made.values():
        plt.close(f)


def _overlap(a, b, tol: float = 0.5) -> bool:
    return a.x0 + tol < b.x1 and b.x0 + tol < a.x1 and a.y0 + tol < b.y1 and b.y0 + tol < a.y1


def _tick_labels(ax, renderer):
    out = []
    for axis in (ax.xaxis, ax.yaxis):
        out.append([t.get_window_extent(renderer) for t in axis.get_ticklabels()
                    if t.get_visible() and t.get_text() and axis.get_visible()])
    return out


def _main_axes(fig):
    insets = {c for ax in fig.axes for c in ax.child_axes}
    return [ax for ax in fig.axes if ax not in insets and ax.get_visible()]


@pytest.mark.parametrize("name", list(FIGURES))
def test_legends_and_insets_stay_off_data_labels_and_ticks_and_on_the_figure(figs, name):
    fig = figs[name]
    r = fig.canvas.get_renderer()
    floating = [("legend", ax.get_legend().get_window_extent(r)) for ax in fig.axes if ax.get_legend()]
    floating += [("inset", c.get_tightbbox(r)) for ax in fig.axes for c in ax.child_axes]
    assert floating
    keep_off = []
    for ax in _main_axes(fig):
        if ax.axison:
            keep_off.append((f"data area of {ax.get_title() or ax.get_label()!r}", ax.get_window_extent(r)))
            for lab in (ax.xaxis.label, ax.yaxis.label):
                if lab.get_text():
                    keep_off.append((f"label {lab.get_text()!r}", lab.get_window_extent(r)))
            keep_off += [("tick label", b) for boxes in _tick_labels(ax, r) for b in boxes]
    for what, box in floating:
        assert fig.bbox.x0 - 1 <= box.x0 and box.x1 <= fig.bbox.x1 + 1 and fig.bbox.y0 - 1 <= box.y0, \
            f"{name}: {what} cut at the figure's edge"
        hits = [k for k, b in keep_off if _overlap(box, b)]
        assert not hits, f"{name}: {what} overlaps {hits[:3]}"


@pytest.mark.parametrize("name", list(FIGURES))
def test_tick_labels_and_object_labels_do_not_overlap(figs, name):
    fig = figs[name]
    r = fig.canvas.get_renderer()
    for ax in fig.axes:
        for boxes in _tick_labels(ax, r):
            assert not any(_overlap(a, b) for a, b in itertools.combinations(boxes, 2)), \
                f"{name}: tick labels overlap on {ax.get_title()!r}"
        labels = [t.get_window_extent(r) for t in ax.texts if t.get_gid() == OBJECT_LABEL]
        assert not any(_overlap(a, b) for a, b in itertools.combinations(labels, 2))
    if name in ("frame", "frame_doppler", "panels"):
        assert sum(t.get_gid() == OBJECT_LABEL for ax in fig.axes for t in ax.texts) == 2


def _colorbar_labels(fig):
    return [ax.get_ylabel() or ax.get_xlabel() for ax in fig.axes if ax.get_label() == "<colorbar>"]


@pytest.mark.parametrize("name", list(FIGURES))
def test_only_a_doppler_run_has_a_velocity_colour_bar_and_its_detections_show_velocity(figs, name):
    fig = figs[name]
    bars = [b for b in _colorbar_labels(fig) if b == VELOCITY_LABEL]
    coloured = [c for ax in fig.axes if ax.get_label() != "<colorbar>" for c in ax.collections
                if isinstance(c, matplotlib.collections.PathCollection) and c.get_array() is not None
                and c.get_cmap().name == "RdBu_r"]
    if name.endswith(("doppler", "fan")):
        assert len(bars) == 1 and coloured
        v = np.concatenate([np.asarray(c.get_array(), float) for c in coloured])
        assert {1.0, -2.0, 3.0} <= set(np.round(v, 6))  # the detections' radial velocities
    else:
        assert not bars and not coloured


def test_a_doppler_frame_has_a_range_doppler_panel_and_the_fan_view_is_a_polar_mesh(figs):
    (rd,) = [ax for ax in figs["frame_doppler"].axes if ax.get_xlabel() == VELOCITY_LABEL]
    assert rd.collections and rd.get_title().startswith("range–Doppler")
    assert not [ax for ax in figs["frame"].axes if ax.get_xlabel() == VELOCITY_LABEL]
    fan = figs["frame_fan"].axes[0]
    (mesh,) = [c for c in fan.collections if isinstance(c, matplotlib.collections.QuadMesh)]
    ra = synthetic_frame().ra_map
    assert mesh.get_array().shape == ra.data.shape


def _track_title_count(ax) -> int:
    return int(re.search(r"(\d+) tracks?", ax.get_title()).group(1))


@pytest.mark.parametrize("name", ["frame", "frame_doppler", "animation"])
def test_the_title_counts_the_tracks_that_are_drawn(figs, name):
    (ax,) = [a for a in figs[name].axes if "bird's-eye" in a.get_title()]
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    inside = {c.get_gid() for c in ax.collections if (c.get_gid() or "").startswith("track ")
              and not c.get_gid().endswith("outside")
              and all(x0 <= x <= x1 and y0 <= y <= y1 for x, y in c.get_offsets())}
    edge = {c.get_gid() for c in ax.collections if (c.get_gid() or "").endswith("outside")}
    assert len(inside) == 1 and len(edge) == 2  # the two far tracks are marked on the edge
    assert _track_title_count(ax) == len(inside) + len(edge) == 3
    assert "2 outside" in ax.get_title()


def test_fitted_walls_are_drawn_above_the_detections_and_posterior_draws_show(figs):
    (ax,) = [a for a in figs["frame"].axes if "bird's-eye" in a.get_title()]
    walls = [ln for ln in ax.lines if ln.get_label() == "estimated walls"]
    dets = [c for c in ax.collections if c.get_label().startswith(("LOS det", "mNLOS det"))]
    assert walls and dets and min(w.get_zorder() for w in walls) > max(d.get_zorder() for d in dets)
    draws = [ln for ln in ax.lines if matplotlib.colors.same_color(ln.get_color(), palette.WALL_DRAWS)]
    assert len(draws) == 30 and all(ln.get_alpha() >= 0.4 and ln.get_linewidth() >= 0.8 for ln in draws)
    mean = walls[0].get_xydata()
    spread = max(np.abs(ln.get_xydata() - mean).max() for ln in draws)
    assert spread > 0.1  # σ_b = 0.1 m: the draws are not the mean drawn again
    (lab,) = [t for t in ax.get_legend().get_texts() if t.get_text().startswith("wall posterior draws")]
    assert re.search(r"90 % within \d+ cm", lab.get_text())


def test_a_detector_without_heatmaps_gets_one_text_panel_not_two_empty_images(figs):
    fig = figs["panels"]
    images = [im for ax in fig.axes for im in ax.images]
    assert len(images) == 2  # (a) and (d): no blank heatmap image
    assert any("no heatmaps" in t.get_text() for ax in fig.axes for t in ax.texts)


# --- colours ------------------------------------------------------------------------------------

def test_cielab_matches_published_values():
    assert np.allclose(palette.cielab("white"), [100.0, 0.0, 0.0], atol=0.01)
    assert np.allclose(palette.cielab("black"), [0.0, 0.0, 0.0], atol=0.01)
    assert np.allclose(palette.cielab("#ff0000"), [53.24, 80.09, 67.20], atol=0.02)  # sRGB red, D65
    assert np.allclose(palette.cielab("#808080"), [53.59, 0.0, 0.0], atol=0.02)


def test_every_two_detector_colours_differ_by_delta_e_20():
    colours = list(palette.DETECTOR_COLOURS.values()) + list(palette.EXTRA_COLOURS)
    roles = [palette.TRUTH, palette.ESTIMATE, palette.WALL_ESTIMATE] + [c for _, c, _ in palette.CLASS_STYLE.values()]
    assert min(palette.delta_e(a, b) for a, b in itertools.combinations(colours, 2)) >= palette.MIN_DELTA_E
    assert min(palette.delta_e(a, b) for a in colours for b in roles) >= palette.MIN_DELTA_E
    # names that hash to one colour still get distinct ones when drawn together
    same = {f"d{k}": palette.EXTRA_COLOURS[0] for k in range(6)}
    got = palette.distinct_colours(same)
    assert min(palette.delta_e(a, b) for a, b in itertools.combinations(got.values(), 2)) >= palette.MIN_DELTA_E


def test_the_range_curve_has_one_distinct_colour_per_row_and_readable_log_ticks():
    from xnlos_core.app.crossmodal.figures import draw_range_curve, row_colours

    rows = {"radar cfar": "cfar", "radar nlos": "nlos_cfar", "spad fk": None, "spad lct": None, "77 GHz": "cfar"}
    ds = [5.0, 5.5, 7.0, 10.0, 14.0, 20.0, 28.0]
    res = {"name": "x", "threshold": 0.5,
           "rows": {r: {"distances": ds, "reconstruction_f1": [0.5] * 7, "detection_f1": [0.4] * 7} for r in rows}}
    fig, ax = plt.subplots(figsize=(8, 4))
    try:
        lines = draw_range_curve(ax, res, row_colours(rows))
        _laid_out(fig)
        cols = [matplotlib.colors.to_hex(ls[0].get_color()) for ls in lines.values()]
        assert min(palette.delta_e(a, b) for a, b in itertools.combinations(cols, 2)) >= palette.MIN_DELTA_E
        r = fig.canvas.get_renderer()
        (xt, _) = _tick_labels(ax, r)
        assert 4 <= len(xt) < len(ds)  # 5.5 beside 5 is dropped rather than drawn over it
        assert not any(_overlap(a, b) for a, b in itertools.combinations(xt, 2))
        assert not any(_overlap(ax.get_legend().get_window_extent(r), b) for b in [ax.get_window_extent(r), *xt])
    finally:
        plt.close(fig)


# --- radar views: a target lands where it is -----------------------------------------------------

def test_range_doppler_from_a_chirp_cube_peaks_at_the_targets_range_and_velocity():
    from xnlos_core.app.plot.radar_views import draw_range_doppler, range_doppler_db
    from xnlos_core.signal.doppler import chirp_sequence_cube

    radar = small_radar(n_chirps=16)
    v_true, r_true = 0.5 * radar.max_unambiguous_velocity, 20.0
    cube = chirp_sequence_cube(radar, [r_true], [0.0], [1e-3], [v_true])
    db = range_doppler_db(cube, radar)
    i, k = np.unravel_index(np.argmax(db), db.shape)
    assert abs(radar.range_axis[i] - r_true) <= radar.range_resolution
    assert abs(radar.velocity_axis[k] - v_true) <= radar.velocity_resolution
    fig, ax = plt.subplots(figsize=(3, 3))
    try:
        mesh = draw_range_doppler(ax, db, radar.range_axis, radar.velocity_axis)
        assert mesh.get_array().shape == db.shape and ax.get_xlabel() == VELOCITY_LABEL
    finally:
        plt.close(fig)


def test_the_fan_view_draws_the_strongest_cell_at_its_bird_eye_position():
    from xnlos_core.app.plot.radar_views import draw_ra_cartesian
    from xnlos_core.bev import bev

    ra = synthetic_frame().ra_map
    fig, ax = plt.subplots(figsize=(3, 3))
    try:
        mesh = draw_ra_cartesian(ax, ra)
        i, j = np.unravel_index(np.argmax(np.abs(ra.data)), ra.data.shape)
        coords = mesh.get_coordinates()  # (R + 1, A + 1, 2) cell corners in bird's-eye (−y, x)
        centre = coords[i:i + 2, j:j + 2].reshape(-1, 2).mean(0)
        r, a = ra.range_axis[i], ra.azimuth_axis[j]
        want = np.column_stack(bev([[r * np.cos(a), r * np.sin(a)]]))[0]
        assert np.hypot(*(centre - want)) < 2 * ra.range_axis[1] + r * abs(ra.azimuth_axis[1] - ra.azimuth_axis[0])
    finally:
        plt.close(fig)
