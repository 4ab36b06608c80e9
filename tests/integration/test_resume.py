"""Resume keyed on frame numbers: results.jsonl, provenance.json, sweep.jsonl and
eval's frames.jsonl are read line by line, repaired where the damage is a crash's, refused naming
file and line otherwise; a resumed run computes exactly the missing frames."""
from __future__ import annotations

import json
import random
import shutil
from pathlib import Path

import pytest

from xnlos_core.app.cli import main
from xnlos_core.config import parse_pipeline
from xnlos_core.errors import InputError
from xnlos_core.io import append_jsonl, read_jsonl, read_keyed_jsonl
from xnlos_core.app.runner import run_to_dir
from xnlos_core.testing import small_pipeline_table

N = 6


def _cfg(**over):
    return parse_pipeline(small_pipeline_table(run={"frames": N, "figure": False}, **over), "resume.toml")


def _strip(rec: dict) -> dict:
    return {k: v for k, v in rec.items() if k != "timings_s"}


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """An uninterrupted run of N frames."""
    out = tmp_path_factory.mktemp("ref") / "run"
    run_to_dir(_cfg(), out, progress=False)
    return out


def _damaged(reference: Path, tmp_path: Path, lines: list[bytes]) -> Path:
    out = tmp_path / "run"
    shutil.copytree(reference, out)
    (out / "results.jsonl").write_bytes(b"".join(lines))
    return out


def _lines(reference: Path) -> list[bytes]:
    return (reference / "results.jsonl").read_bytes().splitlines(keepends=True)


def test_duplicated_line_resumes_into_every_frame_once(reference, tmp_path):
    """a duplicated line made the resume skip the last frame (frame 10 twice, no frame 60)."""
    ref = _lines(reference)
    out = _damaged(reference, tmp_path, [ref[0], ref[1], ref[1], ref[2], ref[3]])  # killed after frame 3
    run_to_dir(_cfg(), out, progress=False)
    got = read_jsonl(out / "results.jsonl")
    assert [r["frame"] for r in got] == list(range(N))
    assert [_strip(r) for r in got] == [_strip(r) for r in read_jsonl(reference / "results.jsonl")]
    assert json.loads((out / "summary.json").read_text())["frames"] == N


def test_removed_line_recomputes_exactly_that_frame(reference, tmp_path):
    """a removed line made the resume recompute the last frame (frame 59 twice)."""
    ref = _lines(reference)
    out = _damaged(reference, tmp_path, [r for k, r in enumerate(ref) if k != 2])
    run_to_dir(_cfg(), out, progress=False)
    got = read_jsonl(out / "results.jsonl")
    want = read_jsonl(reference / "results.jsonl")
    assert [r["frame"] for r in got] == list(range(N))
    # The recorded frames are kept as they were (their timings too): only frame 2 was computed.
    assert [r for k, r in enumerate(got) if k != 2] == [r for k, r in enumerate(want) if k != 2]
    assert got[2] != want[2] and _strip(got[2]) == _strip(want[2])


def test_a_gap_with_a_tracker_gets_the_tracks_of_an_uninterrupted_run(tmp_path):
    cfg = parse_pipeline(small_pipeline_table(run={"frames": 4, "figure": False}, tracker={"name": "nearest"}),
                         "t.toml")
    ref = tmp_path / "ref"
    run_to_dir(cfg, ref, progress=False)
    want = read_jsonl(ref / "results.jsonl")
    assert any(r["tracks"]["id"] for r in want[1:]), "the test needs tracks to compare"
    out = tmp_path / "gap"
    shutil.copytree(ref, out)
    lines = (ref / "results.jsonl").read_bytes().splitlines(keepends=True)
    (out / "results.jsonl").write_bytes(lines[0] + lines[2])  # frames 1 and 3 lost
    run_to_dir(cfg, out, progress=False)
    assert [_strip(r) for r in read_jsonl(out / "results.jsonl")] == [_strip(r) for r in want]


@pytest.mark.parametrize("bad, match", [
    (b"null\n", r"results.jsonl: line 2 holds a JSON null"),
    (b"[1, 2]\n", r"results.jsonl: line 2 holds a JSON array"),
    (b'{"frame": 1, "notes": ["\xff\xfe"]}\n', r"results.jsonl: line 2 is not valid UTF-8"),
    (b'{"frame": 1, "no\n', r"results.jsonl: line 2 is not valid JSON"),
    (b'{"notes": []}\n', r"results.jsonl: line 2 has no 'frame' field"),
    (b'{"frame": -1}\n', r"results.jsonl: line 2: frame = -1; expected a frame index in 0 … 5"),
    (b'{"frame": 6}\n', r"results.jsonl: line 2: frame = 6; expected a frame index in 0 … 5"),
    (b'{"frame": "1"}\n', r"results.jsonl: line 2: frame = '1'; expected a frame index"),
    (b'{"frame": true}\n', r"results.jsonl: line 2: frame = True; expected a frame index"),
    (b'{"frame": 0, "other": 1}\n', r"results.jsonl: lines 1 and 2 hold different records for frame 0"),
])
def test_damaged_results_are_refused_naming_file_and_line(reference, tmp_path, bad, match):
    ref = _lines(reference)
    out = _damaged(reference, tmp_path, [ref[0], bad, ref[1]])
    before = (out / "results.jsonl").read_bytes()
    with pytest.raises(InputError, match=match):
        run_to_dir(_cfg(), out, progress=False)
    assert (out / "results.jsonl").read_bytes() == before  # nothing was overwritten


def test_damaged_results_through_the_cli_are_an_error_not_a_traceback(tmp_path, capsys, sweep_toml):
    toml, out = tmp_path / "p.toml", tmp_path / "o"
    toml.write_text(sweep_toml.split("[sweep]")[0].replace("frames = 1", "frames = 2"))
    assert main(["run", str(toml), "--out", str(out), "-q"]) == 0
    first = (out / "results.jsonl").read_bytes().splitlines(keepends=True)[0]
    (out / "results.jsonl").write_bytes(first + b"null\n")
    capsys.readouterr()
    assert main(["run", str(toml), "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "results.jsonl: line 2 holds a JSON null" in err and "Traceback" not in err


def test_torn_last_line_with_bad_bytes_is_dropped_and_recomputed(reference, tmp_path):
    ref = _lines(reference)
    out = _damaged(reference, tmp_path, ref[:5] + [b'{"frame": 5, "notes": ["\xe2\x82'])  # cut mid-character
    run_to_dir(_cfg(), out, progress=False)
    got = read_jsonl(out / "results.jsonl")
    assert [r["frame"] for r in got] == list(range(N)) and got[:5] == read_jsonl(reference / "results.jsonl")[:5]


@pytest.mark.parametrize("content, match", [
    (b"\xff\xfe{}", "provenance.json: provenance is not valid UTF-8"),
    (b'{"config_sha256": ', "provenance.json: provenance is not valid JSON"),
    (b"[1, 2]", "provenance.json: provenance holds a JSON array, expected an object"),
    (b"null", "provenance.json: provenance holds a JSON null"),
])
def test_damaged_provenance_is_a_typed_error_naming_the_file(reference, tmp_path, content, match):
    out = tmp_path / "run"
    shutil.copytree(reference, out)
    (out / "provenance.json").write_bytes(content)
    with pytest.raises(InputError, match=match):
        run_to_dir(_cfg(), out, progress=False)


@pytest.mark.fuzz
def test_keyed_log_reader_repairs_or_refuses_every_mutation(tmp_path, fuzz_cases):
    """Random byte edits of a valid log: the reader returns records keyed by their index or raises
    InputError; never another exception, never a record under a key it does not carry."""
    path = tmp_path / "log.jsonl"
    for k in range(5):
        append_jsonl(path, {"frame": k, "value": [k, "é", 0.5]})
    clean = path.read_bytes()
    rng = random.Random(26)
    outcomes = {"read": 0, "refused": 0}
    for _ in range(fuzz_cases):
        data = bytearray(clean)
        for _ in range(rng.randint(1, 3)):
            if not data:  # truncated to nothing by an earlier edit
                break
            op, i = rng.randrange(4), rng.randrange(len(data))
            if op == 0:
                data[i] ^= 1 << rng.randrange(8)
            elif op == 1:
                del data[i:i + rng.randint(1, 20)]
            elif op == 2:
                j = data.rfind(b"\n", 0, i) + 1
                data[j:j] = data[j:data.find(b"\n", i) + 1] if b"\n" in data[i:] else b""
            else:
                data = data[:i]
        path.write_bytes(bytes(data))
        try:
            recs = read_keyed_jsonl(path, "frame")
        except InputError as exc:
            assert "log.jsonl: line" in str(exc)
            outcomes["refused"] += 1
            continue
        assert all(r["frame"] == k for k, r in recs.items()) and list(recs) == sorted(recs)
        outcomes["read"] += 1
    assert outcomes["read"] and outcomes["refused"]


def test_keyed_log_reader_repairs_a_repeated_identical_line(tmp_path):
    path = tmp_path / "log.jsonl"
    path.write_text('{"frame": 1}\n{"frame": 0}\n\n{"frame": 1}\n')
    assert read_keyed_jsonl(path, "frame") == {0: {"frame": 0}, 1: {"frame": 1}}
    path.write_text('{"point": 1, "v": 1}\n{"point": 1, "v": 2}\n')
    assert read_keyed_jsonl(path, "point", supersede=True) == {1: {"point": 1, "v": 2}}


# --- sweep.jsonl ------------------------------------------------------------------------------------

def test_sweep_point_whose_results_are_gone_is_not_done(tmp_path, capsys, sweep_toml):
    p, out = tmp_path / "s.toml", tmp_path / "o"
    p.write_text(sweep_toml)
    assert main(["sweep", str(p), "--out", str(out), "--workers", "1", "-q"]) == 0
    first = read_keyed_jsonl(out / "sweep.jsonl", "point")
    (out / "point-001" / "results.jsonl").unlink()
    assert main(["sweep", str(p), "--out", str(out), "--workers", "1", "-q"]) == 0
    assert (out / "point-001" / "results.jsonl").is_file()
    again = read_keyed_jsonl(out / "sweep.jsonl", "point")
    assert list(again) == [0, 1] and again[0] == first[0]  # point 0 was not rerun
    assert len(read_jsonl(out / "sweep.jsonl")) == 2
    # A damaged line is refused naming file and line (through the CLI: exit 2, no traceback).
    with (out / "sweep.jsonl").open("ab") as fh:
        fh.write(b"null\n")
    capsys.readouterr()
    assert main(["sweep", str(p), "--out", str(out), "--workers", "1", "-q"]) == 2
    err = capsys.readouterr().err
    assert "sweep.jsonl: line 3 holds a JSON null" in err and "Traceback" not in err


# --- eval frames.jsonl -------------------------------------------------------------------------------

def test_eval_resume_keys_on_the_map_position(tiny_dataset, tmp_path, eval_config):
    cfg, out = eval_config(tmp_path, tiny_dataset), tmp_path / "out"
    assert main(["eval", str(cfg), "--out", str(out), "--limit", "3", "--no-figures", "-q"]) == 0
    log = out / "run-000" / "frames.jsonl"
    full = read_jsonl(log)
    lines = log.read_bytes().splitlines(keepends=True)
    log.write_bytes(lines[0] + lines[0] + lines[2])  # position 0 twice, position 1 lost
    assert main(["eval", str(cfg), "--out", str(out), "--limit", "3", "--no-figures", "-q"]) == 0
    again = read_jsonl(log)
    assert sorted(r["position"] for r in again) == [0, 1, 2]
    assert sorted((r["position"], json.dumps(r["metrics"])) for r in again) == \
        sorted((r["position"], json.dumps(r["metrics"])) for r in full)
