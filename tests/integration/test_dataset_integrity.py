"""Dataset manifest integrity and completed.jsonl: every bit flip in
manifest.json is seen, `--verify` fails on any inconsistency with the shards on disk, a wrong
`len()` is impossible, and a damaged log is refused naming the line."""
from __future__ import annotations

import json
import random
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from sims.dataset import DatasetError, open_dataset, read_manifest, simulate_dataset, verify_dataset
from sims.dataset.manifest import CHECKSUM, manifest_checksum, render_manifest
from sims.dataset.shard import decode_npz, encode_npz
from xnlos_core.app.cli import main
from xnlos_core.errors import InputError, XnlosError


# Every registry lookup (simulate, repair, ``main([...])``) sees the tiny scene generators.
pytestmark = pytest.mark.usefixtures("tiny_cli")


@pytest.fixture
def copy(reference_dataset, tmp_path) -> Path:
    out = tmp_path / "copy"
    shutil.copytree(reference_dataset, out)
    return out


def _edit(out: Path, fn, *, checksum: bool = True) -> None:
    """Change the manifest with ``fn(man)``; ``checksum``: re-seal it (a consistent forgery)."""
    man = json.loads((out / "manifest.json").read_text())
    fn(man)
    if checksum:
        man[CHECKSUM] = manifest_checksum(man)
    (out / "manifest.json").write_text(render_manifest(man))


def test_manifest_carries_a_checksum_of_its_own_content(reference_dataset):
    man = read_manifest(reference_dataset)
    assert man[CHECKSUM] == manifest_checksum(man)
    assert (reference_dataset / "manifest.json").read_text() == render_manifest(man)
    assert verify_dataset(reference_dataset).healthy and not verify_dataset(reference_dataset).problems


@pytest.mark.fuzz
def test_every_single_bit_flip_of_the_manifest_is_detected(reference_dataset, tmp_path, fuzz_cases):
    """10 of 30 single-bit flips went unnoticed. Each flip: opening fails with a typed
    error naming manifest.json, and --verify reports it unhealthy."""
    data = (reference_dataset / "manifest.json").read_bytes()
    rng = np.random.default_rng(26)
    n = max(30, fuzz_cases // 20)
    offsets = rng.choice(len(data), size=min(n, len(data)), replace=False)
    undetected = []
    for off in offsets:
        out = tmp_path / f"flip{off}"
        shutil.copytree(reference_dataset, out)
        flipped = bytearray(data)
        flipped[off] ^= 1 << int(rng.integers(8))
        (out / "manifest.json").write_bytes(bytes(flipped))
        try:
            open_dataset(out, None)
        except XnlosError as exc:
            assert "manifest.json" in str(exc), exc
        else:
            undetected.append(int(off))
            continue
        try:
            healthy = verify_dataset(out).healthy
        except XnlosError:
            healthy = False
        if healthy:
            undetected.append(int(off))
        shutil.rmtree(out)
    assert not undetected, f"flips at byte offsets {undetected} went unnoticed"


def test_empty_shard_list_fails_verify(copy, capsys):
    """`"shards": []` verified as healthy with exit 0."""
    _edit(copy, lambda m: m.update(shards=[]))
    rep = verify_dataset(copy)
    assert not rep.healthy and any("no shards listed but n_maps = 12" in p for p in rep.problems)
    assert main(["simulate", "--verify", str(copy)]) == 1
    assert "no shards listed" in capsys.readouterr().out
    with pytest.raises(DatasetError, match="manifest.json: .*no shards listed"):
        open_dataset(copy, None)


def test_edited_shard_n_maps_cannot_give_a_wrong_len(copy, reference_dataset):
    """a shard's n_maps edited 2 → 3 gave len(ds) one more than iteration yields."""
    text = (copy / "manifest.json").read_text()
    i = text.index('"n_maps": 2', text.index('"train-00000.npz"'))
    (copy / "manifest.json").write_text(text[:i] + '"n_maps": 3' + text[i + len('"n_maps": 2'):])
    with pytest.raises(DatasetError, match="manifest.json: checksum mismatch"):
        open_dataset(copy, "train")
    assert not verify_dataset(copy).healthy
    # The same edit re-sealed with a fresh checksum (and the totals made to agree) is still caught.
    def forge(m):
        m["shards"][0]["n_maps"] = 3
        m["n_maps"] += 1
        m["config"]["n_maps"] += 1
        m["splits"]["train"]["n_maps"] += 1
    shutil.copy(reference_dataset / "manifest.json", copy / "manifest.json")
    _edit(copy, forge)
    with pytest.raises(DatasetError, match="shard train-00000.npz: n_maps 2 but manifest.json records 3"):
        ds = open_dataset(copy, "train")
        assert len(ds) == len(list(ds))
    rep = verify_dataset(copy)
    assert not rep.healthy and any("holds 2 maps" in p or "differ from the plan" in p for p in rep.problems)


def test_verify_counts_maps_in_each_shard_file(copy):
    """A shard file holding other maps than its entry says (hash re-recorded to match) is reported."""
    name = "train-00000.npz"
    z = decode_npz((copy / "shards" / name).read_bytes(), name)
    short = {k: (v[:1] if k in ("map_index", "scene_index", "frame") else v) for k, v in z.items()}
    data = encode_npz(short)
    (copy / "shards" / name).write_bytes(data)
    import hashlib

    digest = hashlib.sha256(data).hexdigest()
    _edit(copy, lambda m: next(s for s in m["shards"] if s["name"] == name).update(sha256=digest))
    log = [json.loads(x) for x in (copy / "completed.jsonl").read_text().splitlines()]
    for r in log:
        if r["shard"] == name:
            r["sha256"] = digest
    (copy / "completed.jsonl").write_text("".join(json.dumps(r) + "\n" for r in log))
    rep = verify_dataset(copy)
    assert any(f"shards/{name}: holds 1 maps but manifest.json records n_maps = 2" in p for p in rep.problems)
    assert not rep.healthy


def test_verify_checks_the_log_against_the_manifest(copy):
    log = [json.loads(x) for x in (copy / "completed.jsonl").read_text().splitlines()]
    (copy / "completed.jsonl").write_text("".join(json.dumps(r) + "\n" for r in log[1:]))
    rep = verify_dataset(copy)
    assert any(f"no line for shard {log[0]['shard']}" in p for p in rep.problems) and not rep.healthy
    log[1]["sha256"] = "0" * 64
    (copy / "completed.jsonl").write_text("".join(json.dumps(r) + "\n" for r in log))
    with pytest.raises(DatasetError, match=f"completed.jsonl: shard {log[1]['shard']}: sha256"):
        open_dataset(copy, None)
    assert not verify_dataset(copy).healthy


@pytest.mark.parametrize("bad, match", [
    (b"null\n", "completed.jsonl: line 2 holds a JSON null"),
    (b'{"shard": "x", "n": "\xff"}\n', "completed.jsonl: line 2 is not valid UTF-8"),
    (b'{"shard": 3}\n', "completed.jsonl: line 2: shard = 3; expected a shard file name"),
])
def test_damaged_completed_log_is_refused_naming_the_line(copy, bad, match, dataset_cfg):
    lines = (copy / "completed.jsonl").read_bytes().splitlines(keepends=True)
    (copy / "completed.jsonl").write_bytes(lines[0] + bad + b"".join(lines[1:]))
    for call in (lambda: open_dataset(copy, None),
                 lambda: simulate_dataset(dataset_cfg(), copy, workers=1, progress=False)):
        with pytest.raises(InputError, match=match):
            call()


def test_duplicated_log_line_is_repaired_on_resume(copy, reference_dataset, dataset_cfg):
    lines = (copy / "completed.jsonl").read_bytes().splitlines(keepends=True)
    (copy / "completed.jsonl").write_bytes(b"".join(lines) + lines[3])
    assert len(open_dataset(copy, None)) == 12
    s = simulate_dataset(dataset_cfg(), copy, workers=1, progress=False)
    assert s["generated"] == 0 and (copy / "completed.jsonl").read_bytes().count(b"\n") == len(lines)


def test_a_logged_shard_whose_file_is_gone_is_not_done(copy, reference_dataset, dataset_cfg, shard_hashes):
    (copy / "shards" / "val-00000.npz").unlink()
    with pytest.raises(DatasetError, match="val-00000.npz is missing"):
        simulate_dataset(dataset_cfg(), copy, workers=1, progress=False)
    s = simulate_dataset(dataset_cfg(), copy, workers=1, progress=False, repair=True)
    assert s["repaired"] == ["val-00000.npz"] and shard_hashes(copy) == shard_hashes(reference_dataset)


def test_damaged_manifest_is_rebuilt_by_repair(copy, reference_dataset, capsys, dataset_cfg, shard_hashes):
    data = bytearray((copy / "manifest.json").read_bytes())
    i = data.index(b'"complete"')
    data[i + 3] ^= 0x04  # a key name: the content changes but still parses
    (copy / "manifest.json").write_bytes(bytes(data))
    with pytest.raises(DatasetError, match="manifest.json: "):
        simulate_dataset(dataset_cfg(), copy, workers=1, progress=False)
    assert main(["simulate", "--repair", str(copy), "-q"]) == 0
    assert verify_dataset(copy).healthy and shard_hashes(copy) == shard_hashes(reference_dataset)
    assert read_manifest(copy)["created"] == read_manifest(reference_dataset)["created"]


def test_manifest_without_checksum_is_read_with_a_warning_and_repair_adds_it(copy, dataset_cfg):
    _edit(copy, lambda m: m.pop(CHECKSUM), checksum=False)
    with pytest.warns(UserWarning, match="before manifests carried a checksum"):
        assert len(open_dataset(copy, None)) == 12
    rep = verify_dataset(copy)
    assert not rep.healthy and any("no checksum" in p for p in rep.problems)
    simulate_dataset(dataset_cfg(), copy, workers=1, progress=False, repair=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert CHECKSUM in read_manifest(copy) and verify_dataset(copy).healthy


@pytest.mark.fuzz
def test_random_manifest_edits_are_typed_errors(reference_dataset, tmp_path, fuzz_cases):
    """Random multi-byte edits: opening is a typed error or (never) a silently wrong length."""
    data = (reference_dataset / "manifest.json").read_bytes()
    rng = random.Random(4)
    out = tmp_path / "edit"
    shutil.copytree(reference_dataset, out)
    for _ in range(max(20, fuzz_cases // 10)):
        b = bytearray(data)
        i = rng.randrange(len(b))
        b[i:i + rng.randint(1, 4)] = bytes(rng.randrange(256) for _ in range(rng.randint(0, 4)))
        (out / "manifest.json").write_bytes(bytes(b))
        try:
            ds = open_dataset(out, None)
        except XnlosError:
            continue
        assert bytes(b) == data and len(ds) == 12
