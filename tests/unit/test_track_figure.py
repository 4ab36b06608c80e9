"""The bird's-eye view of tracks: prediction cones against closed-form areas, one cone
patch per track with radii, and the standalone PNG."""
import numpy as np
import pytest
from PIL import Image

from xnlos_core.app.plot.track_figure import MIN_RADIUS, cone_path, draw_tracks, plot_tracks
from xnlos_core.types import Tracks

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")


def _area(verts: np.ndarray) -> float:
    """Signed shoelace area of a closed polygon (> 0 counter-clockwise)."""
    x, y = verts[:-1].T
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _pieces(path):
    """The closed sub-paths of a cone path, each (n + 1, 2) with the closing vertex."""
    return [np.asarray(p) for p in path.to_polygons(closed_only=True)]


def test_a_cone_piece_is_the_hull_of_two_discs_with_the_closed_form_area():
    n = 400  # polygon of n vertices inscribed in each circle: area → πr² + 2rd as n grows
    r, d = 1.5, 4.0
    (piece,) = _pieces(cone_path([[10.0, 0.0], [10.0 + d, 0.0]], [r, r], n=n))
    assert _area(piece) > 0  # counter-clockwise, so the non-zero rule fills the union once
    assert _area(piece) == pytest.approx(np.pi * r * r + 2 * r * d, rel=1e-3)
    (disc,) = _pieces(cone_path([[3.0, 4.0]], [2.0], n=n))
    assert _area(disc) == pytest.approx(np.pi * 4.0, rel=1e-3)


def test_a_cone_has_one_piece_per_pair_of_horizons_and_skips_nan_radii():
    c = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]
    path = cone_path(c, [0.0, np.nan, 0.5, 1.0])
    pieces = _pieces(path)
    assert len(pieces) == 2 and all(_area(p) > 0 for p in pieces)
    # the zero radius at the start is drawn as MIN_RADIUS: the cone reaches MIN_RADIUS behind it
    assert min(p[:, 1].min() for p in pieces) == pytest.approx(-MIN_RADIUS, rel=1e-9)  # bev y = x
    assert cone_path(c, [np.nan] * 4) is None


def _tracks() -> Tracks:
    h = np.array([0.5, 1.0, 1.5, 2.0])
    pos = np.array([[20.0, -10.0], [25.0, -5.0], [15.0, 3.0]])
    vel = np.array([[0.0, 5.0], [1.0, -2.0], [0.0, 0.0]])
    fc = pos[:, None] + vel[:, None] * h[None, :, None]
    r50 = np.vstack([0.3 + 0.5 * h, 0.2 + 0.3 * h, np.full(4, np.nan)])  # the third: no interval yet
    r50[1, :2] = np.nan
    return Tracks([1, 4, 9], pos, vel, pos, 2.0, horizons=h, forecast=fc, radius50=r50, radius90=2 * r50,
                  model=("cv", "vx'=-0.3 vy", "cv"), arrival=np.array([3.1, np.nan, np.nan]),
                  arrival_interval=np.array([[2.6, np.inf], [np.nan, np.nan], [np.nan, np.nan]]))


def test_draw_tracks_gives_one_cone_per_track_with_radii_and_labels_every_track():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    t = _tracks()
    hist = {1: np.array([[20.0, -12.0], [20.0, -11.0]]), 99: np.zeros((2, 2))}  # 99: no such track now
    art = draw_tracks(ax, t, hist, region=[[10, 2], [30, 2], [30, -2], [10, -2]])
    plt.close(fig)
    with_radii = int(np.isfinite(t.radius50).any(axis=1).sum())
    assert with_radii == 2
    assert len(art["cone50"]) == len(art["cone90"]) == with_radii
    assert len(art["positions"]) == len(art["labels"]) == len(art["paths"]) == 3
    assert len(art["arrows"]) == 2  # the standing track has no arrow
    assert len(art["history"]) == 1 and len(art["region"]) == 1
    texts = [a.get_text() for a in art["labels"]]
    assert texts[0].startswith("#1 cv") and "arrives in 1.1 s [0.6, ∞]" in texts[0]
    assert texts[1] == "#4 vx'=-0.3 vy"


def test_tracks_without_forecast_draw_no_cones():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    t = _tracks()
    art = draw_tracks(ax, Tracks(t.track_id, t.position, t.velocity, t.predicted))
    plt.close(fig)
    assert art["cone50"] == art["cone90"] == art["paths"] == [] and len(art["positions"]) == 3


def test_plot_tracks_draws_walls_radar_tracks_and_a_legend_and_writes_a_png(tmp_path, monkeypatch):
    import xnlos_core.app.plot.track_figure as tf
    from xnlos_core.bev import save_png

    figs = []
    monkeypatch.setattr(tf, "save_png", lambda fig, path, **kw: (figs.append(fig), save_png(fig, path, **kw))[1])
    out = plot_tracks(_tracks(), tmp_path / "tracks.png", history={1: np.array([[20.0, -12.0]])},
                      region=[[10, 2], [30, 2], [30, -2]], walls=[[[5, -4], [18, -4]]], title="hand-made tracks")
    with Image.open(out) as im:
        assert im.format == "PNG" and im.size == (700, 700)  # figsize 7 × 7 in at 100 dpi
    (fig,) = figs
    ax = fig.axes[0]
    assert ax.get_title() == "hand-made tracks"
    (wall,) = [ln for ln in ax.lines if ln.get_label() == "walls"]
    assert np.allclose(np.c_[wall.get_xdata(), wall.get_ydata()], np.c_[tf.bev(np.array([[5, -4], [18, -4]]))])
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "walls" in labels and "radar" in labels
    # every track, the radar, the region and the history lie inside the axes (3 m margin)
    x0, x1 = sorted(ax.get_xlim())
    y0, y1 = sorted(ax.get_ylim())
    shown = np.c_[tf.bev(np.array([[20.0, -10.0], [25.0, -5.0], [15.0, 3.0], [0.0, 0.0], [20.0, -12.0]]))]
    assert np.all((shown[:, 0] > x0) & (shown[:, 0] < x1) & (shown[:, 1] > y0) & (shown[:, 1] < y1))
    assert sorted(t.get_text().split()[0] for t in ax.texts if t.get_text().startswith("#")) == ["#1", "#4", "#9"]


def test_the_frame_figures_draw_the_tracks_of_a_result(tmp_path, monkeypatch):
    import xnlos_core.app.plot.track_figure as tf
    from xnlos_core.app.plot.figures import plot_frame
    from xnlos_core.app.plot.frame_figure import plot_frame_panels
    from xnlos_core.pipeline import FrameResult
    from xnlos_core.testing import synthetic_frame
    from xnlos_core.types import Detections, HiddenPoints

    drawn = []
    real = tf.draw_tracks
    monkeypatch.setattr(tf, "draw_tracks", lambda ax, *a, **k: drawn.append(real(ax, *a, **k)) or drawn[-1])
    res = FrameResult(synthetic_frame(), Detections.empty(), [], HiddenPoints.empty(), _tracks())
    assert plot_frame(res, tmp_path / "f.png", "t", history={1: np.array([[20.0, -12.0]])}).exists()
    assert plot_frame_panels(res, tmp_path / "p.png").exists()
    assert [len(a["cone50"]) for a in drawn] == [2, 2, 2]  # plot_frame: its panel and the zoom inset
