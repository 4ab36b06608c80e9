"""Figures a reader trusts, checked on the matplotlib artists, not on pixels: RA
maps put positive azimuth on the left like the bird's-eye view, the hidden object has its outline
and a zoom inset, ground truth is drawn above the reconstructions, legends sit outside the data
area, titles count what the legends count, and a detector has one colour everywhere."""
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import zlib

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from xnlos_core.app.plot import palette  # noqa: E402
from xnlos_core.bev import AZIMUTH_LABEL, bev  # noqa: E402
from xnlos_core.app.plot.figures import frame_figure  # noqa: E402
from xnlos_core.app.plot.frame_figure import frame_panels_figure  # noqa: E402
from xnlos_core.pipeline import FrameResult  # noqa: E402
from xnlos_core.testing import KIT_HIDDEN, synthetic_frame  # noqa: E402
from xnlos_core.types import LOS, MNLOS, Detections, HiddenPoints  # noqa: E402

OUTLINE = {"kit_object": KIT_HIDDEN[0] + np.array([[1.0, 0.5], [-1.0, 0.5], [-1.0, -0.5], [1.0, -0.5]])}


def _result():
    frame = synthetic_frame()
    rng = np.array([18.0, 20.0, 30.0])
    az = np.radians([20.0, 5.0, -25.0])
    det = Detections(rng, az, np.array([LOS, LOS, MNLOS]), np.ones(3))
    hidden = HiddenPoints(KIT_HIDDEN + 0.4, 0.2 * np.eye(2)[None], np.array([2]), np.array([0]))
    return FrameResult(frame, det, [], hidden, None)


@pytest.fixture
def fig():
    f = frame_figure(_result(), "t", objects=OUTLINE)
    f.canvas.draw()
    yield f
    plt.close(f)


def _ra_axes(f):
    return [ax for ax in f.axes if ax.get_xlabel() == AZIMUTH_LABEL]


def _bev_axes(f):
    return [ax for ax in f.axes if ax.get_ylabel() == "x [m] (forward)"]


def test_positive_azimuth_is_on_the_left_of_every_ra_panel_like_the_bev(fig):
    (ax,) = _ra_axes(fig)
    lo, hi = ax.get_xlim()
    assert lo > 0 > hi and ax.xaxis_inverted()
    # a detection at +20° (left of boresight) is left of one at −25° in both panels
    left_ra = ax.transData.transform((20.0, 18.0))[0] < ax.transData.transform((-25.0, 30.0))[0]
    (bev_ax,) = _bev_axes(fig)
    p_left = np.column_stack(bev(18 * np.array([[np.cos(0.349), np.sin(0.349)]])))[0]
    p_right = np.column_stack(bev(30 * np.array([[np.cos(-0.436), np.sin(-0.436)]])))[0]
    assert left_ra and bev_ax.transData.transform(p_left)[0] < bev_ax.transData.transform(p_right)[0]


def test_the_six_panel_figure_orients_all_its_ra_panels():
    for heatmaps, n in ((None, 2), (np.zeros((2, 4, 4)), 4)):
        f = frame_panels_figure(_result(), heatmaps)
        try:
            axes = _ra_axes(f)
            assert len(axes) == n  # (a) map, (d) detections, and (b), (c) heatmaps when the detector has them
            assert all(ax.get_xlim()[0] > ax.get_xlim()[1] for ax in axes)
        finally:
            plt.close(f)


def test_the_hidden_object_outline_and_a_zoom_inset_are_drawn(fig):
    (ax,) = _bev_axes(fig)
    outline = [p for p in ax.patches if p.get_label() == "hidden objects (true outline)"]
    assert len(outline) == 1
    verts = outline[0].get_path().vertices[:4]
    assert np.allclose(np.sort(verts, 0), np.sort(np.column_stack(bev(OUTLINE["kit_object"])), 0))
    (inset,) = ax.child_axes
    x0, x1 = inset.get_xlim()
    cx, cy = np.column_stack(bev(KIT_HIDDEN))[0]
    assert x0 < cx < x1 and inset.get_ylim()[0] < cy < inset.get_ylim()[1]
    assert x1 - x0 < 0.5 * np.ptp(ax.get_xlim())  # a zoom, not a copy
    assert any(p.get_label() == "hidden objects (true outline)" for p in inset.patches)


def test_ground_truth_is_drawn_above_the_reconstructions(fig):
    (ax,) = _bev_axes(fig)
    for a in (ax, ax.child_axes[0]):
        arts = a.collections + a.lines + a.patches
        truth = [x.get_zorder() for x in arts if x.get_label() in ("true hidden points", "true walls",
                                                                   "hidden objects (true outline)")]
        est = [x.get_zorder() for x in arts if x.get_label().startswith(("reconstructed", "LOS det", "mNLOS det"))]
        ellipses = [x.get_zorder() for x in a.lines if x.get_color() == palette.ESTIMATE]
        assert len(truth) >= 2 and est and ellipses
        assert min(truth) > max(est + ellipses)


def _overlaps(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_legends_sit_outside_every_data_area(fig):
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    assert len(legends) == 2
    data_areas = [ax.get_window_extent() for ax in fig.axes if ax.get_label() != "<colorbar>"]
    for leg in legends:
        box = leg.get_window_extent()
        assert not any(_overlaps(box, area) for area in data_areas)


def test_titles_count_what_the_legends_count(fig):
    (ra,) = _ra_axes(fig)
    title_n = int(re.search(r"\((\d+)\)", ra.get_title()).group(1))
    legend_n = sum(int(re.search(r"\((\d+)\)", t.get_text()).group(1)) for t in ra.get_legend().get_texts())
    assert title_n == legend_n == 3
    (ax,) = _bev_axes(fig)
    n_title = int(re.search(r"(\d+) reconstructed hidden point", ax.get_title()).group(1))
    (entry,) = [t.get_text() for t in ax.get_legend().get_texts() if t.get_text().startswith("reconstructed")]
    assert n_title == int(re.search(r"\((\d+)", entry).group(1)) == 1


def test_one_colour_per_detector(monkeypatch):
    import xnlos_core.app.plot.figures as figures
    from benchmarks.detectors import _class_panels

    made = []
    monkeypatch.setattr(figures, "save_png", lambda f, *a, **k: made.append(f))
    curves = {(n, c): np.array([0.5, 0.7]) for n in ("cfar", "swin_unet", "mine") for c in ("los", "mnlos")}
    _class_panels(["cfar", "swin_unet", "mine"], curves, np.array([1, 2]), "x", "recall", "unused.png")
    for ax in made[0].axes:
        assert {ln.get_label(): matplotlib.colors.to_hex(ln.get_color()) for ln in ax.lines} == {
            n: matplotlib.colors.to_hex(palette.detector_colour(n)) for n in ("cfar", "swin_unet", "mine")}
    plt.close(made[0])
    names = list(palette.DETECTOR_COLOURS)
    assert len(set(palette.DETECTOR_COLOURS.values())) == len(names)
    roles = {palette.TRUTH, palette.ESTIMATE, palette.WALL_ESTIMATE} | {c for _, c, _ in palette.CLASS_STYLE.values()}
    assert not roles & set(palette.DETECTOR_COLOURS.values())
    # a third party's detector gets the same colour in every process and on every machine (CRC-32 of its name)
    assert palette.detector_colour("my_detector") == "lightcoral"
    assert palette.detector_colour("mine") == palette.EXTRA_COLOURS[zlib.crc32(b"mine") % len(palette.EXTRA_COLOURS)]


def test_the_animation_frame_agrees_on_orientation_legends_and_zorder():
    from xnlos_core.app.plot.animation import animation_figure
    from xnlos_core.app.plot.frame_snapshot import FrameSnapshot

    f = animation_figure(FrameSnapshot.from_result(_result()), {})
    try:
        f.canvas.draw()
        (ra,) = _ra_axes(f)
        assert ra.get_xlim()[0] > 0 > ra.get_xlim()[1]
        areas = [ax.get_window_extent() for ax in (ra, *_bev_axes(f))]
        for ax in f.axes:
            if ax.get_legend() is not None:
                assert not any(_overlaps(ax.get_legend().get_window_extent(), a) for a in areas)
        (bev_ax,) = _bev_axes(f)
        z = {x.get_label(): x.get_zorder() for x in bev_ax.collections}
        assert z["true hidden points"] > z["reconstructed hidden points (1; 90 % credible)"]
    finally:
        plt.close(f)


# --- the six-panel `xnlos eval` figure draws outlines carried by frame.meta (dataset maps) ---------

def _panels(meta=None, metrics=None):
    res = _result()
    if meta is not None:
        res.frame.meta.update(meta)
    res.metrics = metrics or {}
    f = frame_panels_figure(res)
    f.canvas.draw()
    return f


def _panel_f(f):
    (ax,) = [a for a in _bev_axes(f) if a.get_title().startswith("(f)")]
    return ax


def test_the_six_panel_figure_draws_the_meta_outline_and_a_zoom_inset():
    meta = {"object_outlines": {k: v.tolist() for k, v in OUTLINE.items()}}
    f = _panels(meta, {"mirror_paths": {"kit_object": 3}})
    try:
        ax = _panel_f(f)
        (outline,) = [p for p in ax.patches if p.get_label() == "hidden objects (true outline)"]
        want = np.column_stack(bev(OUTLINE["kit_object"]))
        assert np.allclose(np.sort(outline.get_path().vertices[:4], 0), np.sort(want, 0))
        (inset,) = ax.child_axes
        cx, cy = want.mean(0)
        assert inset.get_xlim()[0] < cx < inset.get_xlim()[1] and inset.get_ylim()[0] < cy < inset.get_ylim()[1]
        assert np.ptp(inset.get_xlim()) < 0.5 * np.ptp(ax.get_xlim())
        assert any(p.get_label() == "hidden objects (true outline)" for p in inset.patches)
        assert not any(a.child_axes for a in f.axes if a is not ax)  # panel (e) stays as it was
    finally:
        plt.close(f)


def test_without_outline_meta_the_six_panel_figure_has_no_outline_and_no_inset():
    f = _panels()
    try:
        ax = _panel_f(f)
        assert not ax.child_axes
        assert not [p for p in ax.patches if "outline" in p.get_label() or "no mirror path" in p.get_label()]
    finally:
        plt.close(f)


def test_an_object_without_mirror_path_is_dashed_and_not_zoomed():
    meta = {"object_outlines": {k: v.tolist() for k, v in OUTLINE.items()}}
    f = _panels(meta, {"mirror_paths": {"kit_object": 0}, "los_points": {"kit_object": 0}})
    try:
        ax = _panel_f(f)
        assert not ax.child_axes
        (p,) = [p for p in ax.patches if p.get_label() == "hidden, no mirror path (not observable)"]
        assert p.get_linestyle() == "--"
    finally:
        plt.close(f)


@pytest.mark.parametrize("bad, match", [([[0.0, 1.0]], "expected a mapping"),
                                        ({"car": [[0.0, 1.0, 2.0]]}, r"\['car'\].*shape \(1, 3\)"),
                                        ({"car": [[0.0, float("nan")]]}, "finite")])
def test_malformed_outline_meta_is_an_input_error_naming_the_object(bad, match):
    from xnlos_core.errors import InputError
    from xnlos_core.app.plot.figures import outlines_from_meta

    with pytest.raises(InputError, match=match):
        outlines_from_meta({"object_outlines": bad})
