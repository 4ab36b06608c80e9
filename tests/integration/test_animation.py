"""``xnlos run`` writes sequence.gif: one GIF frame per recorded frame, from the
per-frame snapshots and results.jsonl, again after a resume, and for a finished run whose
animation is turned on afterwards (the option is not part of the config hash)."""
import json
import shutil

import numpy as np
import pytest
from PIL import Image

from xnlos_core.app.plot.animation import shown_frames, snapshot_path, write_sequence_gif
from xnlos_core.config import parse_pipeline
from xnlos_core.errors import InputError
from xnlos_core.files import load_toml
from xnlos_core.app.plot.frame_snapshot import FrameSnapshot
from xnlos_core.io import read_jsonl
from xnlos_core.app.runner import run_to_dir
from xnlos_core.scene import BUILTIN_DIR
from xnlos_core.testing import small_pipeline_table

N = 3
TINY_RADAR = {"n_samples": 256, "max_range": 60.0, "n_azimuth_bins": 61}


def _cfg(doppler=False, **run):
    scene = load_toml(BUILTIN_DIR / "corner.toml")
    car = scene["objects"][0]
    car.pop("velocity", None)
    car["trajectory"] = {"model": "constant_velocity", "velocity": [0.0, 5.0]}
    radar = {**TINY_RADAR, "n_chirps": 8} if doppler else TINY_RADAR
    table = small_pipeline_table(scene=scene, radar=radar, tracker={"name": "kalman"},
                                 forward_model={"name": "image", "params": {"doppler": doppler}},
                                 run={"frames": N, "frame_interval": 0.2, "figure": False, **run})
    return parse_pipeline(table, "anim.toml")


def _gif_frames(path) -> int:
    with Image.open(path) as im:
        assert im.format == "GIF"
        return im.n_frames


@pytest.fixture(scope="module")
def doppler_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("anim") / "run"
    summary = run_to_dir(_cfg(doppler=True), out, progress=False)
    return out, summary


def test_a_tracked_run_writes_one_gif_frame_per_frame(doppler_run):
    out, summary = doppler_run
    assert _gif_frames(out / "sequence.gif") == N
    assert summary["animation"] == "sequence.gif" and "![sequence](sequence.gif)" in (out / "summary.md").read_text()
    for k in range(N):
        s = FrameSnapshot.load(snapshot_path(out, k))
        assert s.index == k and s.timestamp == pytest.approx(0.2 * k) and s.ra_db.dtype == np.float16
        assert np.isfinite(s.det_velocity).all()  # Doppler rendering: every detection has a velocity
    with Image.open(out / "sequence.gif") as im:
        assert im.info["duration"] == 200  # real time: 0.2 s a frame


def test_a_snapshot_round_trips(doppler_run, tmp_path):
    out, _ = doppler_run
    s = FrameSnapshot.load(snapshot_path(out, 1))
    back = FrameSnapshot.load(s.save(tmp_path / "s.npz"))
    for name in ("ra_db", "det_range", "det_velocity", "hidden_mean", "hidden_cov", "true_walls", "true_hidden"):
        np.testing.assert_array_equal(getattr(back, name), getattr(s, name))
    assert len(back.walls) == len(s.walls) >= 1
    for a, b in zip(back.walls, s.walls):
        np.testing.assert_array_equal(a, b)
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="bad.npz: not an animation frame snapshot"):
        FrameSnapshot.load(tmp_path / "bad.npz")


def test_the_gif_is_drawn_from_the_files_alone_and_needs_every_snapshot(doppler_run, tmp_path):
    out, _ = doppler_run
    records = read_jsonl(out / "results.jsonl")
    gif = write_sequence_gif(tmp_path / "again.gif", records, out / "animation", max_frames=2,
                             region=[[15, 2], [30, 2], [30, -2]])
    assert _gif_frames(gif) == 2  # first and last of the three
    shutil.copytree(out / "animation", tmp_path / "snaps")
    (tmp_path / "snaps" / "frame_0001.npz").unlink()
    with pytest.raises(InputError, match="frame_0001.npz: missing the snapshot of frame 1"):
        write_sequence_gif(tmp_path / "x.gif", records, tmp_path / "snaps")


def test_shown_frames_are_evenly_spaced_and_keep_both_ends():
    assert shown_frames([4, 0, 2]) == [0, 2, 4]
    assert shown_frames(list(range(10)), 4) == [0, 3, 6, 9]


def test_no_animation_without_a_tracker_by_default_or_with_one_frame(tmp_path):
    table = small_pipeline_table(radar=TINY_RADAR, run={"frames": 2, "figure": False})
    summary = run_to_dir(parse_pipeline(table, "plain.toml"), tmp_path / "a", progress=False)
    assert "animation" not in summary and not (tmp_path / "a" / "sequence.gif").exists()
    assert not (tmp_path / "a" / "animation").exists()
    one = _cfg(frames=1, animation=True)
    run_to_dir(one, tmp_path / "b", progress=False)
    assert not (tmp_path / "b" / "sequence.gif").exists()


def test_a_resumed_run_writes_the_whole_animation(tmp_path):
    ref = tmp_path / "ref"
    run_to_dir(_cfg(), ref, progress=False)
    lines = (ref / "results.jsonl").read_bytes().splitlines(keepends=True)
    out = tmp_path / "run"
    shutil.copytree(ref, out)
    # killed after frame 0's line: the later frames' lines, snapshots and the GIF never written
    (out / "results.jsonl").write_bytes(lines[0])
    (out / "sequence.gif").unlink()
    for k in (1, 2):
        snapshot_path(out, k).unlink()
    run_to_dir(_cfg(), out, progress=False)
    assert _gif_frames(out / "sequence.gif") == N
    strip = [{k: v for k, v in r.items() if k != "timings_s"} for r in read_jsonl(out / "results.jsonl")]
    assert strip == [{k: v for k, v in r.items() if k != "timings_s"} for r in read_jsonl(ref / "results.jsonl")]


def test_turning_the_animation_on_resumes_a_finished_run(tmp_path):
    out = tmp_path / "run"
    run_to_dir(_cfg(animation=False), out, progress=False)
    assert not (out / "sequence.gif").exists() and not (out / "animation").exists()
    before = (out / "results.jsonl").read_bytes()
    summary = run_to_dir(_cfg(animation=True), out, progress=False)  # same config hash: a resume
    assert summary["animation"] == "sequence.gif" and _gif_frames(out / "sequence.gif") == N
    assert (out / "results.jsonl").read_bytes() == before  # nothing recorded again
    assert json.loads((out / "provenance.json").read_text())["resumed"] == 1


def test_the_animation_option_is_not_part_of_the_config_hash():
    import hashlib

    plain = _cfg()
    dump = plain.model_dump(exclude={"base_dir"})
    for key in ("animation", "figures", "blas_threads", "share_cores"):  # hashed as before they existed
        del dump["run"][key]
    want = hashlib.sha256(json.dumps(dump, sort_keys=True, default=str).encode()).hexdigest()
    assert plain.digest() == want == _cfg(animation=True).digest() == _cfg(animation=False).digest()
    assert _cfg(figures="all").digest() == want == _cfg(figures=4).digest()
    assert _cfg(figure=True).digest() != want
