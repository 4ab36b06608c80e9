"""Honest results: a pipeline that can never reconstruct is flagged by `check`;
detection-only pipelines run; an object without a mirror path is "not observable" (not a vacuous
F1 of 1) in the summary and drawn in the figure, unless it is in plain view ("in line of sight");
one object-error figure; `-q` is quiet; output files are readable by others."""
import json
import os
import re
import stat
import tomllib

import pytest

from xnlos_core.app.plot import figures
from xnlos_core.app.cli import main
from xnlos_core.config import parse_pipeline
from xnlos_core.errors import ConfigError, PipelineWarning
from xnlos_core.io import read_jsonl
from xnlos_core.pipeline import Pipeline
from xnlos_core.scene import BUILTIN_DIR
from xnlos_core.testing import small_pipeline_table

# A second vehicle far down the cross street: its mirror path is longer than the radar's 60 m range.
VAN = {"name": "van", "shape": "box", "center": [22.0, -75.0], "size": [5.0, 2.0], "heading": 1.5707963267948966}
# A kiosk in plain view left of the radar: seen directly, but no relay wall mirrors it back.
KIOSK = {"name": "kiosk", "shape": "box", "center": [8.0, 6.0], "size": [1.5, 1.5], "heading": 0.0}


def _corner(*extra) -> dict:
    scene = tomllib.loads((BUILTIN_DIR / "corner.toml").read_text())
    scene["objects"] += list(extra)
    return scene


def _toml(table: dict) -> str:
    """A pipeline table as TOML (the few shapes small_pipeline_table uses)."""
    def value(v):
        return json.dumps(v) if not isinstance(v, bool) else str(v).lower()

    def body(d, prefix):
        lines = [f"{k} = {value(v)}" for k, v in d.items() if not isinstance(v, dict) and not
                 (isinstance(v, list) and v and isinstance(v[0], dict))]
        for k, v in d.items():
            if isinstance(v, dict):
                lines += ["", f"[{prefix}{k}]"] + body(v, f"{prefix}{k}.")
            elif isinstance(v, list) and v and isinstance(v[0], dict):
                for item in v:
                    lines += ["", f"[[{prefix}{k}]]"] + body(item, f"{prefix}{k}.")
        return lines

    return "\n".join(body(table, "")) + "\n"


def _write(tmp_path, name="p.toml", **over) -> str:
    p = tmp_path / name
    p.write_text(_toml(small_pipeline_table(**over)))
    return str(p)


@pytest.fixture
def umask022():
    old = os.umask(0o022)
    yield
    os.umask(old)


# --- (b) check flags a pipeline that can never reconstruct; detection-only pipelines are valid ---

def test_check_flags_classless_detector_feeding_a_wall_estimator(tmp_path, capfd):
    p = _write(tmp_path, detector={"name": "cfar"})
    assert main(["check", p]) == 0  # flagged, not refused: a CFAR ablation still scores its detections
    out, err = capfd.readouterr()
    assert "1 flagged" in out
    assert "xnlos: warning:" in err and "'cfar' cannot classify" in err and "never reconstruct" in err
    assert "Traceback" not in err


def test_check_does_not_flag_a_classifying_detector(tmp_path, capfd):
    assert main(["check", _write(tmp_path)]) == 0
    out, err = capfd.readouterr()
    assert "valid (1 pipeline(s))" in out and "warning" not in err


def test_pipeline_construction_warns_too():
    with pytest.warns(PipelineWarning, match="can never reconstruct"):
        Pipeline(parse_pipeline(small_pipeline_table(detector={"name": "cfar"}), "t"))


def test_detection_only_pipeline_is_valid_and_runs(tmp_path, capfd):
    table = small_pipeline_table(detector={"name": "cfar"})
    del table["wall_estimator"], table["reconstructor"]
    p = tmp_path / "det.toml"
    p.write_text(_toml(table))
    assert main(["check", str(p)]) == 0
    out, err = capfd.readouterr()
    assert "valid (1 pipeline(s))" in out and "warning" not in err
    assert main(["run", str(p), "--out", str(tmp_path / "o"), "-q"]) == 0
    (rec,) = read_jsonl(tmp_path / "o" / "results.jsonl")
    assert set(rec["timings_s"]) == {"source", "detector"}
    assert rec["detections"]["unclassified"] > 0 and rec["hidden_points"] == []
    assert set(rec["metrics"]) == {"dense", "mirror_paths", "los_points"}  # no reconstruction to score
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["objects"]["car"]["status"] == "not scored"
    assert "| car | not scored (no reconstructor) |" in (tmp_path / "o" / "summary.md").read_text()


def test_a_stage_without_its_input_stage_is_refused():
    table = small_pipeline_table(tracker={"name": "nearest"})
    del table["wall_estimator"]  # the reconstructor mirrors across walls nobody estimates
    with pytest.raises(ConfigError, match=r"needs \[wall_estimator\]"):
        parse_pipeline(table, "t")
    table = small_pipeline_table(tracker={"name": "nearest"})
    del table["reconstructor"]  # a tracker alone tracks the line-of-sight detections
    assert parse_pipeline(table, "t").reconstructor is None


# --- (c) one object-error figure; an object without a mirror path is "not observable" ------------
# (or "in line of sight" when the radar sees it directly: in plain view, nothing hidden, no failure)

def test_object_without_mirror_path_is_not_observable_and_drawn(tmp_path, capsys, monkeypatch, umask022):
    drawn = {}
    real = figures.plot_frame

    def spy(result, path, **kw):
        drawn.update(kw.get("unobservable") or {})
        return real(result, path, **kw)

    monkeypatch.setattr(figures, "plot_frame", spy)
    p = _write(tmp_path, scene=_corner(VAN, KIOSK), run={"frames": 1, "figure": True})
    assert main(["run", p, "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    o = tmp_path / "o"
    summary = json.loads((o / "summary.json").read_text())
    car, van, kiosk = (summary["objects"][k] for k in ("car", "van", "kiosk"))
    assert van == {"frames": 1, "observable_frames": 0, "los_frames": 0, "error_m": None, "status": "not observable"}
    assert kiosk == {"frames": 1, "observable_frames": 0, "los_frames": 1, "error_m": None,
                     "status": "in line of sight"}
    assert car["status"] == "reconstructed" and car["observable_frames"] == 1 and car["error_m"] < 1.0
    assert car["los_frames"] == 0  # hidden behind the block: no direct view
    md = (o / "summary.md").read_text()
    assert "| van | not observable (no mirror path in any of 1 frame(s)) | 0 of 1 | 0 of 1 |" in md
    assert ("| kiosk | in line of sight (seen directly in 1 of 1 frame(s), no mirror path: nothing hidden to "
            "reconstruct) | 0 of 1 | 1 of 1 |") in md
    assert "hidden van: reconstruction error not observable" in out
    assert "kiosk: in line of sight" in out and "hidden kiosk" not in out
    (rec,) = read_jsonl(o / "results.jsonl")
    assert rec["metrics"]["los_points"]["kiosk"] > 0 and rec["metrics"]["mirror_paths"]["kiosk"] == 0
    # One object-error figure: the headline and the summary table print the same number, rounded
    # alike, and no other object error is tabulated.
    (headline,) = re.findall(r"hidden car: reconstruction error ([0-9.]+ m)", out)
    assert f"| car | {headline} | 1 of 1 | 0 of 1 |" in md and headline == f"{car['error_m']:.2f} m"
    assert "object_error" not in md and not any("object_error" in k for k in summary["metrics"])
    # Drawn in the figure with its outline; the kiosk in plain view is not "not observable".
    assert set(drawn) == {"van"} and drawn["van"].shape == (4, 2)
    # (a) readable by others: what a plain open() gives under umask 022.
    for name in ("summary.md", "summary.json", "provenance.json", summary["figure"], "results.jsonl"):
        assert stat.S_IMODE(os.stat(o / name).st_mode) == 0o644, name


def test_only_unobservable_hidden_object_scores_no_vacuous_f1():
    # The van is the scene's only object: nothing can be reconstructed, and F1 = 1 (0/0) would hide that.
    (res,) = Pipeline(parse_pipeline(small_pipeline_table(scene={**_corner(), "objects": [VAN]}), "t")).run()
    assert res.metrics["mirror_paths"] == {"van": 0} and res.metrics["los_points"] == {"van": 0}
    h = res.metrics["hidden"]
    assert len(res.hidden) == 0 and h["f1"] is None and h["recall"] is None and h["precision"] is None
    assert "object_error_m" not in h  # the one object error is reconstruction.object_error_m


def test_unobservable_outline_is_labelled_in_the_axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    figures.draw_unobservable(ax, {"van": [[0, 0], [1, 0], [1, 1], [0, 1]], "bike": [[5.0, 5.0]]})
    texts = {t.get_text() for t in ax.texts}
    assert texts == {"van: not observable", "bike: not observable"}
    assert "hidden, no mirror path (not observable)" in ax.get_legend_handles_labels()[1]
    plt.close(fig)


# --- (d) -q silences everything but errors -------------------------------------------------------

def test_quiet_run_and_check_print_nothing(tmp_path, capfd):
    p = _write(tmp_path, run={"frames": 1, "figure": True})
    assert main(["run", p, "--out", str(tmp_path / "o"), "-q"]) == 0
    assert main(["check", p, "-q"]) == 0
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert (tmp_path / "o" / "summary.md").exists()
    # Not quiet: the report (stdout) and the progress bar (stderr).
    assert main(["run", p, "--out", str(tmp_path / "o2")]) == 0
    out, err = capfd.readouterr()
    assert "hidden car: reconstruction error" in out and "run small" in err


def test_quiet_still_reports_errors(tmp_path, capfd):
    table = small_pipeline_table()
    del table["wall_estimator"]
    p = tmp_path / "bad.toml"
    p.write_text(_toml(table))
    assert main(["run", str(p), "--out", str(tmp_path / "o"), "-q"]) == 2
    out, err = capfd.readouterr()
    assert out == "" and err.startswith("xnlos: error:") and "needs [wall_estimator]" in err


def test_footprint_is_the_box_corners_and_a_point_itself():
    from xnlos_core.scene import ObjectSpec

    box = ObjectSpec(name="b", center=(10.0, 0.0), size=(4.0, 2.0), heading=0.0, velocity=(1.0, 0.0))
    assert box.footprint(2.0).tolist() == [[14.0, 1.0], [10.0, 1.0], [10.0, -1.0], [14.0, -1.0]]
    assert ObjectSpec(name="p", shape="point", center=(3.0, 4.0)).footprint().tolist() == [[3.0, 4.0]]


def test_quiet_keeps_xnlos_warnings(tmp_path, capfd):
    p = _write(tmp_path, detector={"name": "cfar"})
    assert main(["run", p, "--out", str(tmp_path / "o"), "-q"]) == 0
    out, err = capfd.readouterr()
    assert out == "" and err.startswith("xnlos: warning:") and err.count("\n") == 1
