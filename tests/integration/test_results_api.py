"""The reader API: load_results gives back, as core types, what the pipeline produced in
the same run; schema-1 records still load; a damaged record is refused naming the key; the docs'
"Python API" block (docs/api.md) runs as written."""
import json
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from xnlos_core.config import parse_pipeline
from xnlos_core.errors import InputError, LegacyRecordWarning
from xnlos_core.pipeline import Pipeline
from xnlos_core.app.results import load_results
from xnlos_core.app import runner
from xnlos_core.testing import small_pipeline_table

ROOT = Path(__file__).resolve().parents[2]
DOPPLER = dict(forward_model={"name": "image", "params": {"doppler": True}},
               radar={"n_samples": 256, "max_range": 60.0, "n_azimuth_bins": 121, "n_chirps": 4},
               tracker={"name": "kalman"},
               run={"frames": 2, "figure": False, "frame_interval": 0.2, "animation": False})
SCHEMA_2 = ("schema_version", "detection_table", "hidden")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """(run directory, the FrameResults that run_to_dir wrote there) of a 2-frame Doppler + Kalman run."""
    out = tmp_path_factory.mktemp("run")
    seen = []

    class Recording(Pipeline):
        def run(self, *args, **kw):
            for res in super().run(*args, **kw):
                seen.append(res)
                yield res

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(runner, "Pipeline", Recording)
        runner.run_to_dir(parse_pipeline(small_pipeline_table(**DOPPLER), "small.toml"), out, progress=False)
    return out, seen


def _same(a, b, names):
    for name in names:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_load_results_round_trips_the_frame_results(run):
    out, results = run
    frames = load_results(out)
    assert [f.frame for f in frames] == [r.frame.index for r in results] == [0, 1]
    for f, r in zip(frames, results):
        assert f.schema_version == 2 and f.timestamp == r.frame.timestamp
        _same(f.detections, r.detections, ("range", "azimuth", "label", "confidence", "range_std",
                                           "azimuth_std", "velocity", "velocity_var"))
        assert len(f.walls) == len(r.walls) >= 1
        for w, v in zip(f.walls, r.walls):
            assert (w.model, w.param_names, w.n_points) == (v.model, v.param_names, v.n_points)
            _same(w, v, ("mean", "cov", "extent"))
        _same(f.hidden, r.hidden, ("mean", "cov", "source_index", "wall_index", "velocity", "velocity_cov"))
        _same(f.tracks, r.tracks, ("track_id", "position", "velocity", "horizons", "forecast"))
        assert f.metrics == json.loads(json.dumps(r.metrics)) and f.notes == r.notes
        assert f.detection_counts == {"LOS": int((r.detections.label == 0).sum()),
                                      "mNLOS": int((r.detections.label == 1).sum()),
                                      "unclassified": int((r.detections.label == 2).sum())}


def test_schema_1_records_still_load_with_a_warning(run, tmp_path):
    out, results = run
    lines = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    for rec in lines:
        for key in SCHEMA_2:
            del rec[key]
        rec["walls"] = [{k: w[k] for k in ("model", "mean", "cov", "n_points")} for w in rec["walls"]]
    (tmp_path / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    with pytest.warns(LegacyRecordWarning, match="schema 1"):
        frames = load_results(tmp_path / "results.jsonl")
    assert all(f.detections is None and f.hidden is None and f.schema_version == 1 for f in frames)
    _same(frames[0].walls[0], results[0].walls[0], ("mean", "cov"))
    assert frames[0].walls[0].extent is None


def test_a_damaged_record_is_refused_naming_file_frame_and_key(run, tmp_path):
    out, _ = run
    lines = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    lines[1]["hidden"]["cov"] = [[[1.0]]] * len(lines[1]["hidden"]["mean"])
    (tmp_path / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    with pytest.raises(InputError, match=r"results\.jsonl: frame 1: hidden\.cov\[0\]: expected at least 2"):
        load_results(tmp_path)
    with pytest.raises(InputError, match=r"frame 1: hidden\.cov: expected shape \(n, 2, 2\)"):
        load_results(tmp_path, validate=False)  # the types still check what they are given
    with pytest.raises(InputError, match="no such results file"):
        load_results(tmp_path / "nowhere")


def test_the_docs_python_api_block_runs_as_written(tmp_path, monkeypatch, capsys):
    page = (ROOT / "docs" / "api.md").read_text()
    match = re.search(r"<!-- python-api -->\n```python\n(.*?)```", page, re.S)
    assert match, "docs/api.md: no ```python block after <!-- python-api -->"
    shutil.copytree(ROOT / "configs", tmp_path / "configs")  # the block's paths are the project's
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", LegacyRecordWarning)
        exec(compile(match.group(1), "docs/api.md#python-api", "exec"), {"__name__": "docs"})
    assert (tmp_path / "out" / "api-demo" / "results.jsonl").is_file()
    assert "line" in capsys.readouterr().out
