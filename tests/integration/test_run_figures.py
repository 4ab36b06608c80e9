"""``[run] figures``: a figure per frame on request in ``xnlos run`` ("last" by default, "all", or
every N-th frame), drawn again for a finished run whose ``figures`` is changed afterwards (the
option is not part of the config hash), with the hidden objects' outlines passed to the figure."""
import pytest

from xnlos_core.config import RunConfig, parse_pipeline
from xnlos_core.errors import ConfigError
from xnlos_core.files import load_toml
from xnlos_core.app.runner import run_to_dir
from xnlos_core.scene import BUILTIN_DIR
from xnlos_core.testing import small_pipeline_table

N = 3
TINY_RADAR = {"n_samples": 256, "max_range": 60.0, "n_azimuth_bins": 61}


def _cfg(**run):
    scene = load_toml(BUILTIN_DIR / "corner.toml")
    table = small_pipeline_table(scene=scene, radar=TINY_RADAR, forward_model={"name": "image"},
                                 run={"frames": N, "frame_interval": 0.2, **run})
    return parse_pipeline(table, "figs.toml")


def _pngs(out):
    return sorted(p.name for p in out.glob("frame_*.png"))


@pytest.fixture
def drawn(monkeypatch):
    """Record plot_frame's calls instead of drawing (the figure itself is tested in test_figures_trust)."""
    import xnlos_core.app.plot.figures as figures

    calls = []

    def fake(result, path, title="", **kw):
        calls.append((result.frame.index, kw))
        path.write_bytes(b"png")
        return path

    monkeypatch.setattr(figures, "plot_frame", fake)
    return calls


def test_figure_frames_picks_last_all_or_every_nth():
    assert RunConfig(frames=5).figure_frames(range(5)) == [4]
    assert RunConfig(frames=5, figures="all").figure_frames(range(5)) == [0, 1, 2, 3, 4]
    assert RunConfig(frames=5, figures=2).figure_frames(range(5)) == [0, 2, 4]
    assert RunConfig(frames=5, figures=3).figure_frames([7, 8, 9, 10, 11]) == [7, 10, 11]
    assert RunConfig(frames=5, figure=False, figures="all").figure_frames(range(5)) == []


@pytest.mark.parametrize("bad", ["some", 0, -2])
def test_a_bad_figures_value_is_refused(bad):
    with pytest.raises(ConfigError, match="figures"):
        _cfg(figures=bad)


def test_default_run_draws_the_last_frame_only(tmp_path, drawn):
    summary = run_to_dir(_cfg(), tmp_path, progress=False)
    assert _pngs(tmp_path) == ["frame_0002.png"] and summary["figure"] == "frame_0002.png"
    assert "figures" not in summary
    ((k, kw),) = drawn
    assert k == 2 and set(kw["objects"]) | set(kw["unobservable"]) == {"car"}


def test_all_and_every_nth_and_a_later_change_resumes_with_the_missing_figures(tmp_path, drawn):
    summary = run_to_dir(_cfg(figures=2), tmp_path, progress=False)
    assert _pngs(tmp_path) == ["frame_0000.png", "frame_0002.png"] and summary["figures"] == _pngs(tmp_path)
    assert [k for k, _ in drawn] == [0, 2]
    drawn.clear()
    summary = run_to_dir(_cfg(figures="all"), tmp_path, progress=False)  # same hash: a resume
    assert [k for k, _ in drawn] == [1]  # only the missing one is recomputed
    assert _pngs(tmp_path) == [f"frame_{k:04d}.png" for k in range(N)] == summary["figures"]
