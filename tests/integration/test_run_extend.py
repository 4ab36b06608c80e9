"""A finished run is extended by asking for more frames (frame k is the same draw whatever the count),
refused with a clear message when fewer frames are asked for than it holds, and its summary.json is
strict JSON (no NaN or Infinity, which RFC 8259 and strict parsers refuse)."""
import json

import pytest

from xnlos_core.app.runner import run_to_dir
from xnlos_core.config import parse_pipeline
from xnlos_core.errors import InputError
from xnlos_core.io import finite_json, read_jsonl, strict_json_text
from xnlos_core.testing import small_pipeline_table


def _cfg(frames: int, **extra):
    return parse_pipeline(small_pipeline_table(run={"frames": frames, "figure": False}, **extra), "t")


def _strict(text: str):
    def refuse(name):
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


def test_more_frames_extend_a_finished_run(tmp_path):
    run_to_dir(_cfg(2), tmp_path / "a", progress=False)
    run_to_dir(_cfg(3), tmp_path / "a", progress=False)  # extends: frames 0, 1 kept, frame 2 added
    run_to_dir(_cfg(3), tmp_path / "b", progress=False)  # the same three frames in one go
    a, b = read_jsonl(tmp_path / "a" / "results.jsonl"), read_jsonl(tmp_path / "b" / "results.jsonl")
    assert [r["frame"] for r in a] == [0, 1, 2]
    for x, y in zip(a, b):
        assert x["hidden_points"] == y["hidden_points"] and x["detection_table"] == y["detection_table"]
    with pytest.raises(InputError, match=r"frame = 2; expected a frame index in 0 … 1 .* asking for at least"):
        run_to_dir(_cfg(2), tmp_path / "a", progress=False)


def test_summary_json_is_strict(tmp_path):
    run_to_dir(_cfg(1), tmp_path, progress=False)
    _strict((tmp_path / "summary.json").read_text())


def test_non_finite_numbers_become_null():
    value = {"cd": float("inf"), "f1": [1.0, float("nan")], "n": 3, "t": (float("-inf"),)}
    assert finite_json(value) == {"cd": None, "f1": [1.0, None], "n": 3, "t": [None]}
    assert _strict(strict_json_text(value)) == {"cd": None, "f1": [1.0, None], "n": 3, "t": [None]}
