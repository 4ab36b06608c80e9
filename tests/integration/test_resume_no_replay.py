"""Resume without replay: ``xnlos run`` checkpoints the tracker (and a wall
estimator with a history) with each frame (stage_state.json), so a killed run resumes without recomputing the frames it holds, a finished run
reruns no stage, and an unusable checkpoint falls back to the replay with a CheckpointWarning."""
from __future__ import annotations

import json
import os
import shutil
import warnings
from pathlib import Path

import pytest

from xnlos_core.config import parse_pipeline
from xnlos_core.errors import CheckpointWarning
from xnlos_core.io import read_jsonl
from xnlos_core.pipeline import Pipeline
from xnlos_core.app.runner import run_to_dir
from xnlos_core.testing import small_pipeline_table
from xnlos_core.checkpoint import STATE_FILE

N, K = 10, 8  # frames, frames done when the run is killed (sindy identifies a track at frame 7)
TRACKERS = {"kalman": {}, "sindy": {"min_samples": 8, "refit_every": 2, "min_evidence": 0.0, "n_models": 3}}


class Killed(Exception):
    """Stands for the process being killed."""


def _cfg(tracker: str | None, history: int = 1, **run):
    t = small_pipeline_table(run={"frames": N, "frame_interval": 0.2, "figure": False, "animation": False, **run})
    t["scene"] = {"builtin": "corner", "objects": [{"name": "car", "center": [22.0, -16.0], "heading": 1.5708,
                                                    "velocity": [0.0, 4.0]}]}
    if tracker is not None:
        t["tracker"] = {"name": tracker, "params": TRACKERS[tracker]}
    if history > 1:
        t["wall_estimator"] = {"name": "lsq", "params": {"history_frames": history}}
    return parse_pipeline(t, "noreplay.toml")


def _spy(monkeypatch, cfg, kill_after: int | None = None) -> dict[str, list]:
    """Frame indices each stage (forward model, detector, tracker) is called with; the detector
    raises Killed on its call number ``kill_after`` + 1."""
    stages = Pipeline(cfg).stages
    calls: dict[str, list] = {"forward_model": [], "detector": [], "tracker": []}

    def wrap(kind, method, index):
        cls = type(stages[kind])
        orig = getattr(cls, method)

        def spy(self, *args, **kw):
            if kind == "detector" and kill_after is not None and len(calls["detector"]) >= kill_after:
                raise Killed
            calls[kind].append(index(args, kw))
            return orig(self, *args, **kw)

        monkeypatch.setattr(cls, method, spy)

    wrap("forward_model", "simulate", lambda a, kw: kw.get("index", a[4] if len(a) > 4 else None))
    wrap("detector", "detect", lambda a, kw: a[0].index)
    if "tracker" in stages:
        wrap("tracker", "update", lambda a, kw: a[1])
    return calls


def _strip(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "timings_s"} for r in rows]


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict[str, list[dict]]:
    """results.jsonl of an uninterrupted run, per tracker (stripped of timings)."""
    out = {}
    for name in TRACKERS:
        d = tmp_path_factory.mktemp(name) / "run"
        run_to_dir(_cfg(name), d, progress=False)
        out[name] = _strip(read_jsonl(d / "results.jsonl"))
    return out


def _killed(monkeypatch, cfg, out: Path) -> None:
    with monkeypatch.context() as m:
        _spy(m, cfg, kill_after=K)
        with pytest.raises(Killed):
            run_to_dir(cfg, out, progress=False)
    assert [r["frame"] for r in read_jsonl(out / "results.jsonl")] == list(range(K))


@pytest.mark.parametrize("tracker", list(TRACKERS))
def test_a_killed_run_resumes_without_recomputing_its_frames(reference, tmp_path, monkeypatch, tracker):
    cfg, out = _cfg(tracker), tmp_path / "run"
    _killed(monkeypatch, cfg, out)
    state = json.loads((out / STATE_FILE).read_text())
    assert (state["frame"], state["frames_done"]) == (K - 1, K)
    if tracker == "sindy":  # the checkpoint holds an identified model, which must come back exactly
        assert any(t["identified"] is not None or t.get("library") is not None
                   for t in state["stages"]["tracker"]["state"]["tracks"])
    calls = _spy(monkeypatch, cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("error", CheckpointWarning)
        run_to_dir(cfg, out, progress=False)
    assert calls == {"forward_model": list(range(K, N)), "detector": list(range(K, N)),
                     "tracker": [0.2 * k for k in range(K, N)]}
    assert _strip(read_jsonl(out / "results.jsonl")) == reference[tracker]
    assert json.loads((out / STATE_FILE).read_text())["frame"] == N - 1


def test_a_finished_run_reruns_no_stage_and_a_fresh_one_computes_each_frame_once(tmp_path, monkeypatch):
    cfg = _cfg("kalman", frames=4, figure=True, animation=True)
    calls = _spy(monkeypatch, cfg)
    run_to_dir(cfg, tmp_path, progress=False)
    # The last frame's figure is drawn as the frame comes, not by replaying the run at its end.
    assert calls["detector"] == [0, 1, 2, 3] and (tmp_path / "frame_0003.png").exists()
    before = (tmp_path / "results.jsonl").read_bytes()
    for v in calls.values():
        v.clear()
    run_to_dir(cfg, tmp_path, progress=False)
    assert calls == {"forward_model": [], "detector": [], "tracker": []}
    assert (tmp_path / "results.jsonl").read_bytes() == before


@pytest.fixture(scope="module")
def killed_kalman(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("killed") / "run"
    with pytest.MonkeyPatch.context() as m:
        _killed(m, _cfg("kalman"), out)
    return out


def _edit(state: dict, how: str) -> bytes:
    if how == "not json":
        return b"{\"frame\": 7, \"sta"
    if how == "other config":
        state["config_sha256"] = "0" * 64
    elif how == "other tracker":
        state["stages"]["tracker"]["name"] = "nearest"
    elif how == "bad track":
        state["stages"]["tracker"]["state"]["tracks"][0]["P"] = [[1.0]]
    elif how == "stale frame":  # killed between a frame's results line and its state: no warning
        state["frame"], state["frames_done"] = K - 2, K - 1
    return json.dumps(state).encode()


@pytest.mark.parametrize("how, match", [
    ("not json", "not valid JSON"), ("other config", "another configuration"),
    ("other tracker", "tracker 'nearest'"), ("bad track", r"tracker: .*tracks\[0\]: P = "), ("stale frame", None)])
def test_an_unusable_checkpoint_falls_back_to_the_replay(reference, killed_kalman, tmp_path, monkeypatch, how, match):
    out = tmp_path / "run"
    shutil.copytree(killed_kalman, out)
    state = json.loads((out / STATE_FILE).read_text())
    assert state["stages"]["tracker"]["state"]["tracks"], "the test needs a track to damage"
    (out / STATE_FILE).write_bytes(_edit(state, how))
    cfg = _cfg("kalman")
    calls = _spy(monkeypatch, cfg)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        run_to_dir(cfg, out, progress=False)
    msgs = [str(w.message) for w in seen if issubclass(w.category, CheckpointWarning)]
    if match is None:
        assert msgs == []
    else:
        assert len(msgs) == 1 and STATE_FILE in msgs[0] and "replayed" in msgs[0], msgs
        assert __import__("re").search(match, msgs[0]), msgs[0]
    # Replayed: every frame through the tracker again, and the results are the uninterrupted run's.
    assert calls["detector"] == list(range(N)) and calls["forward_model"] == list(range(N))
    assert _strip(read_jsonl(out / "results.jsonl")) == reference["kalman"]


def test_a_finished_run_rerun_rewrites_no_output_unless_it_is_stale(tmp_path, monkeypatch):
    """outputs.json (xnlos_core.app.run_outputs): a rerun of a finished run leaves summary, figure and GIF
    alone (their mtimes, set to a known past value, stay), reruns no stage; a deleted GIF, an edited
    summary or another figure setting makes it write them again."""
    cfg = _cfg("kalman", frames=3, figure=True, animation=True)
    run_to_dir(cfg, tmp_path, progress=False)
    outputs = ["summary.md", "summary.json", "frame_0002.png", "sequence.gif"]
    past = 1_000_000_000_000_000_000  # ns: 2001-09-09
    for name in outputs:
        os.utime(tmp_path / name, ns=(past, past))
    calls = _spy(monkeypatch, cfg)
    first = json.loads((tmp_path / "summary.json").read_text())
    assert run_to_dir(cfg, tmp_path, progress=False) == first
    assert calls == {"forward_model": [], "detector": [], "tracker": []}
    assert {n: (tmp_path / n).stat().st_mtime_ns for n in outputs} == dict.fromkeys(outputs, past)

    (tmp_path / "sequence.gif").unlink()
    (tmp_path / "summary.md").write_text("edited")
    run_to_dir(cfg, tmp_path, progress=False)
    assert (tmp_path / "sequence.gif").exists() and (tmp_path / "summary.md").read_text().startswith("#")
    assert (tmp_path / "frame_0002.png").stat().st_mtime_ns == past  # present and current: not redrawn

    run_to_dir(_cfg("kalman", frames=3, figure=True, animation=True, figures="all"), tmp_path, progress=False)
    assert all((tmp_path / f"frame_{k:04d}.png").exists() for k in range(3))


@pytest.mark.parametrize("tracker", ["kalman", None])
def test_a_wall_history_is_checkpointed_beside_the_tracker(tmp_path, monkeypatch, tracker):
    """lsq with history_frames 4 carries the LOS detections of 3 frames: a killed run restores them
    from stage_state.json (with the tracker's state, or alone) and gives the uninterrupted run's walls."""
    cfg = _cfg(tracker, history=4)
    run_to_dir(cfg, tmp_path / "ref", progress=False)
    ref = _strip(read_jsonl(tmp_path / "ref" / "results.jsonl"))
    single = tmp_path / "single"
    run_to_dir(_cfg(tracker), single, progress=False)
    walls = [[w["params"] for w in r["walls"]] for r in ref]
    assert walls != [[w["params"] for w in r["walls"]] for r in read_jsonl(single / "results.jsonl")], \
        "the history changed no wall: the test cannot tell a restored history from an empty one"
    out = tmp_path / "run"
    _killed(monkeypatch, cfg, out)
    held = json.loads((out / STATE_FILE).read_text())["stages"]
    assert sorted(held) == sorted(["wall_estimator"] + (["tracker"] if tracker else []))
    assert len(held["wall_estimator"]["state"]["frames"]) == 3
    calls = _spy(monkeypatch, cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("error", CheckpointWarning)
        run_to_dir(cfg, out, progress=False)
    assert calls["detector"] == list(range(K, N))
    assert _strip(read_jsonl(out / "results.jsonl")) == ref
