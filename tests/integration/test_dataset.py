"""Dataset generation: deterministic shards, resume after a kill, verification, splits, reader, CLI, Dask."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sims.dataset.shard import _one_blas_thread
from sims.dataset import (SCHEMA_VERSION, DatasetError, make_plan, open_dataset, parse_dataset_config,
                          read_manifest, resolve, verify_dataset)
from sims.dataset.plan import apportion, noise_seed, scene_seed, spread_labels
from sims.dataset.shard import decode_npz
from xnlos_core.app.cli import main
from xnlos_core.errors import ConfigError
from xnlos_core.io import read_jsonl
from xnlos_core.registry import get_registry

ROOT = Path(__file__).resolve().parents[2]


def test_seeds_are_spawned_children_of_the_root(dataset_cfg):
    root = np.random.SeedSequence(7)
    first, second = root.spawn(2)
    scenes = first.spawn(3)
    assert scene_seed(7, 2) == int(scenes[2].generate_state(1, np.uint64)[0] >> np.uint64(1))
    frame = second.spawn(2)[1].spawn(2)[1]
    assert noise_seed(7, 1, 1) == int(frame.generate_state(1, np.uint64)[0] >> np.uint64(1))
    assert apportion([0.8, 0.1, 0.1], 2160) == [1728, 216, 216]
    assert apportion([1, 1, 1], 4) == [2, 1, 1]
    labels = spread_labels([3, 1, 1])
    assert sorted(labels) == [0, 0, 0, 1, 2]
    weighted = make_plan(dataset_cfg(families={"corner_a": 2.0, "corner_b": 1.0}))
    assert sorted(weighted.family).count("corner_a") == 8 and weighted.family.count("corner_b") == 4


def test_default_plan_splits_by_scene_seed_80_10_10():
    from sims.dataset import load_dataset_config

    c = load_dataset_config(ROOT / "configs/datasets/default.toml")
    assert c.n_maps == 2160 and c.forward_model.name == "raytrace" and len(c.weights()) == 6
    plan = make_plan(c)
    seeds = plan.split_seeds()
    assert {k: len(v) for k, v in seeds.items()} == {"train": 1728, "val": 216, "test": 216}
    assert not (set(seeds["train"]) & set(seeds["val"])) and not (set(seeds["train"]) & set(seeds["test"]))
    assert not (set(seeds["val"]) & set(seeds["test"]))
    assert len(set(plan.scene_seed.tolist())) == 2160
    for fam in c.weights():  # every split gets its share of each family
        per = [sum(1 for f, s in zip(plan.family, plan.split) if f == fam and s == sp) for sp in seeds]
        assert per == [288, 36, 36]
    # Whole scenes only: all frames of one scene share its seed, hence its split.
    multi = make_plan(c.model_copy(update={"frames_per_scene": 3, "n_maps": 30, "shard_size": 6}))
    for s in multi.shards:
        assert s.n_maps == 3 * len(s.scenes) and all(multi.split[k] == s.split for k in s.scenes)


def test_max_maps_keeps_the_full_datasets_scenes_and_splits(dataset_table):
    """--max-maps: a reduced dataset takes the first scenes of each split of the full
    plan, as many per split as the fractions apportion, with their indices, seeds, families and
    splits, so no training or validation scene of the full dataset (that of the shipped models)
    lands in its test split; the canonical form of a full config (its digest) is unchanged."""
    from sims.dataset import load_dataset_config

    c = load_dataset_config(ROOT / "configs/datasets/default.toml")
    assert "full_n_maps" not in c.model_dump() and c.plan_scenes == 2160
    full = make_plan(c)
    assert full.contiguous and full.scene_index == tuple(range(2160))
    first = {sp: [k for k in full.scene_index if full.split[k] == sp] for sp in ("train", "val", "test")}
    sizes = {6: [5, 1, 0], 7: [5, 1, 1], 24: [19, 3, 2], 120: [96, 12, 12]}  # apportion(0.8/0.1/0.1, m)
    for m, want in sizes.items():
        r = load_dataset_config(ROOT / "configs/datasets/default.toml", n_maps=m)
        assert (r.n_maps, r.full_n_maps) == (m, 2160)
        plan = make_plan(r)
        assert [plan.split.count(sp) for sp in first] == want == apportion([0.8, 0.1, 0.1], m)
        for sp, n in zip(first, want):  # the first n scenes of the full plan's split, in index order
            assert [k for s in plan.shards if s.split == sp for k in s.scenes] == first[sp][:n]
        assert list(plan.scene_index) == sorted(plan.scene_index) and len(plan.scene_index) == m
        for pos, k in enumerate(plan.scene_index):  # no scene changes split, seed or family
            assert plan.scene(k) == full.scene(k) == (int(plan.scene_seed[pos]), plan.family[pos], plan.split[pos])
        assert all(plan.scene(k)[2] == s.split for s in plan.shards for k in s.scenes)
        assert sum(s.n_maps for s in plan.shards) == m
    assert not make_plan(load_dataset_config(ROOT / "configs/datasets/default.toml", n_maps=7)).contiguous
    with pytest.raises(KeyError, match="scene index 4 is not in this plan"):
        make_plan(load_dataset_config(ROOT / "configs/datasets/default.toml", n_maps=7)).scene(4)
    # on the tiny config (50/25/25 of 12 scenes), also through a second --max-maps; more maps: own plan
    table = dataset_table()
    whole = make_plan(parse_dataset_config(table, "t"))
    small = make_plan(parse_dataset_config(table, "t", n_maps=6))
    assert [small.split.count(sp) for sp in first] == [3, 2, 1]
    assert all(small.scene(k) == whole.scene(k) for k in small.scene_index)
    again = parse_dataset_config({**table, "n_maps": 6, "full_n_maps": 12}, "t", n_maps=4)
    assert again.full_n_maps == 12 and set(make_plan(again).scene_index) <= set(small.scene_index)
    assert parse_dataset_config(table, "t", n_maps=24).full_n_maps is None
    with pytest.raises(ConfigError, match="full_n_maps"):
        parse_dataset_config({**table, "full_n_maps": 6}, "t")


def test_reduced_counts_stay_within_the_full_plans_splits():
    from sims.dataset.plan import reduced_counts

    assert reduced_counts([0.8, 0.1, 0.1], 24, [1728, 216, 216]) == [19, 3, 2]
    # a split the full plan cannot fill gives its scene to the split furthest below its quota
    assert reduced_counts([0.5, 0.25, 0.25], 6, [3, 1, 8]) == [3, 1, 2]
    assert reduced_counts([0.5, 0.5, 0.0], 3, [1, 1, 5]) == [1, 1, 1]
    with pytest.raises(ValueError, match="holds only 3"):
        reduced_counts([0.5, 0.25, 0.25], 4, [1, 1, 1])


def test_reduced_dataset_maps_are_the_full_datasets(reference_dataset, tmp_path, dataset_cfg, simulate_tiny):
    """A --max-maps dataset's maps are byte for byte the full dataset's maps of the same scenes."""
    out = tmp_path / "six"
    summary = simulate_tiny(dataset_cfg(n_maps=6, full_n_maps=12), out, workers=1, progress=False)
    assert summary["splits"] == {"train": 3, "val": 2, "test": 1}
    assert verify_dataset(out).healthy
    man, whole = read_manifest(out), read_manifest(reference_dataset)
    idx = man["scenes"]["scene_index"]
    assert "scene_index" not in whole["scenes"] and idx != list(range(6)) and man["n_scenes"] == 6
    for key in ("scene_seed", "family", "split"):
        assert man["scenes"][key] == [whole["scenes"][key][k] for k in idx]
    full = {f.index: f for f in open_dataset(reference_dataset, None)}
    got = list(open_dataset(out, None))
    assert sorted(f.meta["scene_index"] for f in got) == idx
    for f in got:
        g = full[f.index]
        assert f.index == f.meta["scene_index"] and f.meta == g.meta
        assert np.array_equal(f.ra_map.data, g.ra_map.data)
        for a in ("los_points", "mnlos_points", "hidden_points", "mnlos_object", "los_snr_db", "mnlos_snr_db"):
            assert np.array_equal(getattr(f.ground_truth, a), getattr(g.ground_truth, a)), a


def test_workers_and_order_do_not_change_the_shards(reference_dataset, tmp_path, dataset_cfg, shard_hashes,
                                                    simulate_tiny):
    out = tmp_path / "pool"
    summary = simulate_tiny(dataset_cfg(), out, workers=2, progress=False)
    assert summary["generated"] == 7 and summary["splits"] == {"train": 6, "val": 3, "test": 3}
    assert shard_hashes(out) == shard_hashes(reference_dataset)
    assert all(shard_hashes(out).values())
    m = read_manifest(out)
    assert m["complete"] and m["schema_version"] == SCHEMA_VERSION and m["config_sha256"]
    assert m["versions"]["xnlos"] and m["radar"]["n_samples"] == 128


def test_two_ray_traced_builds_are_byte_identical(tmp_path, dataset_cfg, simulate_tiny):
    """Same config and seed → the same shard bytes, with the ray tracer (whose frames time their trace:
    that wall-clock entry stays out of the shards, in completed.jsonl's seconds instead)."""
    cfg = dataset_cfg(n_maps=4, forward_model={"name": "raytrace"})
    for run in ("a", "b"):
        simulate_tiny(cfg, tmp_path / run, workers=1, progress=False)
    names = sorted(p.name for p in (tmp_path / "a" / "shards").glob("*.npz"))
    assert len(names) >= 2
    for name in names:
        a, b = ((tmp_path / run / "shards" / name).read_bytes() for run in ("a", "b"))
        assert a == b, name
        meta = json.loads(str(decode_npz(a, name)["frame_meta_json"]))
        assert meta and all(m["forward_model"] == "raytrace" and "trace_s" not in m for m in meta)
    assert all(r["seconds"] > 0 for r in read_jsonl(tmp_path / "a" / "completed.jsonl"))


def test_dask_local_cluster_gives_the_same_shards(reference_dataset, tmp_path, dataset_cfg, shard_hashes,
                                                  simulate_tiny):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp",
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        simulate_tiny(dataset_cfg(), tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False)
    assert shard_hashes(tmp_path / "dask") == shard_hashes(reference_dataset)


def test_resume_after_interruption_loses_and_duplicates_nothing(reference_dataset, tmp_path, dataset_cfg,
                                                                shard_hashes, simulate_tiny):
    out = tmp_path / "killed"

    def stop_after_two(rec, seen=[]):  # noqa: B006 (counts calls)
        seen.append(rec["shard"])
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        simulate_tiny(dataset_cfg(), out, workers=1, progress=False, on_shard=stop_after_two)
    assert len(read_jsonl(out / "completed.jsonl")) == 2 and not read_manifest(out)["complete"]
    # What a kill can also leave: a temporary file of a shard being written and a torn log line.
    stale = out / "shards" / ".train-00002.npz.abc123.tmp"
    stale.write_bytes(b"partial")
    with (out / "completed.jsonl").open("a") as fh:
        fh.write('{"shard": "train-00002.npz", "sha2')
    summary = simulate_tiny(dataset_cfg(), out, workers=1, progress=False)
    assert summary["skipped"] == 2 and summary["generated"] == 5
    assert not stale.exists()
    names = [r["shard"] for r in read_jsonl(out / "completed.jsonl")]
    assert sorted(names) == sorted(shard_hashes(reference_dataset)) and len(names) == len(set(names))
    assert shard_hashes(out) == shard_hashes(reference_dataset)
    assert sorted(p.name for p in (out / "shards").iterdir()) == sorted(shard_hashes(reference_dataset))


def test_killed_cli_process_resumes_bit_identical(tmp_path, dataset_table, shard_hashes, simulate_tiny, tiny_plugin,
                                                  tiny_plugin_env):
    """SIGKILL a real `xnlos simulate` mid-run, rerun the same command, compare with an uninterrupted run."""
    t = dataset_table(n_maps=24, family_overrides={f: {"delay": 0.05} for f in tiny_plugin.FAMILIES})
    path = tmp_path / "slow.toml"
    path.write_text(_toml(t))
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "xnlos_core", "-p", "tiny_scenes", "simulate", str(path), "--out", str(out),
           "--workers", "1", "-q"]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=tiny_plugin_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    log = out / "completed.jsonl"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        if log.exists() and len(read_jsonl(log)) >= 2:
            break
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()
    n_before = len(read_jsonl(log))
    assert 2 <= n_before < 12, "the run should have been killed part-way"
    assert subprocess.run(cmd, cwd=ROOT, env=tiny_plugin_env, capture_output=True).returncode == 0
    recs = read_jsonl(log)
    assert len(recs) == 12 and len({r["shard"] for r in recs}) == 12
    ref = tmp_path / "ref"
    simulate_tiny(parse_dataset_config(t, str(path)), ref, workers=1, progress=False)
    assert shard_hashes(out) == shard_hashes(ref)


def test_corrupt_and_missing_shards_are_reported_by_name_and_repaired(reference_dataset, tmp_path, dataset_cfg,
                                                                      shard_hashes, simulate_tiny):
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(reference_dataset, out)
    shard = out / "shards" / "val-00000.npz"
    data = bytearray(shard.read_bytes())
    data[len(data) // 2] ^= 0xFF
    shard.write_bytes(bytes(data))
    (out / "shards" / "test-00000.npz").unlink()
    rep = verify_dataset(out)
    assert not rep.healthy and list(rep.corrupt) == ["val-00000.npz"] and rep.missing == ["test-00000.npz"]
    assert "val-00000.npz" in rep.render() and "--repair" in rep.render()
    with pytest.raises(DatasetError, match="val-00000.npz is corrupt"):
        simulate_tiny(dataset_cfg(), out, workers=1, progress=False)
    with pytest.raises(DatasetError, match="val-00000.npz is corrupt"):
        list(open_dataset(out, "val"))
    summary = simulate_tiny(dataset_cfg(), out, workers=1, progress=False, repair=True)
    assert summary["repaired"] == ["test-00000.npz", "val-00000.npz"]
    assert verify_dataset(out).healthy and shard_hashes(out) == shard_hashes(reference_dataset)


def test_reader_round_trips_maps_and_ground_truth_exactly(reference_dataset, dataset_cfg, tiny_plugin):
    c = resolve(dataset_cfg(), registry=tiny_plugin.tiny_registry())
    plan = make_plan(c)
    fm = get_registry().create("forward_model", "image", c.forward_model.params)
    from xnlos_core.radar import RadarConfig

    radar = RadarConfig.model_validate(c.radar)
    total = 0
    seen_seeds = {}
    for split, n in (("train", 6), ("val", 3), ("test", 3)):
        ds = open_dataset(reference_dataset, split)
        assert len(ds) == n
        frames = list(ds)
        assert len(frames) == n and ds[n - 1].index == frames[-1].index
        for f in frames:
            k = f.meta["scene_index"]
            assert plan.scene(k)[2] == split and f.meta["scene_seed"] == plan.scene(k)[0]
            seen_seeds.setdefault(f.meta["scene_seed"], set()).add(split)
            with _one_blas_thread():  # as the shard workers: BLAS sums in one fixed order
                want = fm.simulate(tiny_plugin.tiny_scene(plan.family[k], int(plan.scene_seed[k])), radar,
                                   np.random.default_rng(noise_seed(c.seed, k, 0)), timestamp=0.0, index=k)
            assert np.array_equal(f.ra_map.data, want.ra_map.data) and f.ra_map.data.dtype == np.complex64
            g, h = f.ground_truth, want.ground_truth
            for a in ("los_points", "mnlos_points", "hidden_points", "mnlos_object"):
                assert np.array_equal(getattr(g, a), getattr(h, a)), a
            for a in ("los_snr_db", "mnlos_snr_db"):  # stored as float32 [dB]
                assert np.array_equal(getattr(g, a), getattr(h, a).astype(np.float32)) and np.isfinite(getattr(g, a)).all()
            assert g.object_names == h.object_names
            assert [(w.name, w.start.tolist(), w.end.tolist()) for w in g.walls] == \
                   [(w.name, w.start.tolist(), w.end.tolist()) for w in h.walls]
        total += n
    assert all(len(v) == 1 for v in seen_seeds.values())  # a scene seed lives in one split only
    assert len(open_dataset(reference_dataset, None)) == total == 12
    assert any(len(f.ground_truth.mnlos_points) for f in open_dataset(reference_dataset, "train"))
    z = open_dataset(reference_dataset, "train").load_shard("train-00000.npz")
    scenes = json.loads(str(z["scenes_json"]))
    assert scenes[0]["scene"]["meta"]["family"] == scenes[0]["family"]


def test_moving_scenes_render_frames_at_k_times_the_interval(tmp_path, dataset_cfg, simulate_tiny):
    out = tmp_path / "multi"
    simulate_tiny(dataset_cfg(n_maps=12, frames_per_scene=3, shard_size=6, frame_interval=0.5), out, workers=1,
                     progress=False)
    frames = list(open_dataset(out, None))
    by_scene = {}
    for f in frames:
        by_scene.setdefault(f.meta["scene_index"], []).append(f)
    assert len(by_scene) == 4
    for fs in by_scene.values():
        assert [f.timestamp for f in fs] == [0.0, 0.5, 1.0] and len({f.meta["split"] for f in fs}) == 1
        assert len({f.meta["noise_seed"] for f in fs}) == 3


def test_schema_version_is_checked(reference_dataset, tmp_path, dataset_cfg, simulate_tiny):
    import shutil

    out = tmp_path / "old"
    shutil.copytree(reference_dataset, out)
    m = json.loads((out / "manifest.json").read_text())
    m["schema_version"] = SCHEMA_VERSION + 1
    (out / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(DatasetError, match="schema version"):
        open_dataset(out)
    with pytest.raises(ConfigError, match="schema version"):
        simulate_tiny(dataset_cfg(), out, workers=1, progress=False)
    from sims.dataset.shard import encode_npz

    with pytest.raises(DatasetError, match="shard x.npz: schema version 99"):
        decode_npz(encode_npz({"schema_version": np.array(99)}), "x.npz")


def test_another_config_in_out_needs_overwrite(reference_dataset, tmp_path, dataset_cfg, simulate_tiny):
    import shutil

    out = tmp_path / "o"
    shutil.copytree(reference_dataset, out)
    with pytest.raises(ConfigError, match="another configuration.*--overwrite"):
        simulate_tiny(dataset_cfg(seed=8), out, workers=1, progress=False)
    simulate_tiny(dataset_cfg(seed=8), out, workers=1, progress=False, overwrite=True)
    assert read_manifest(out)["config"]["seed"] == 8 and verify_dataset(out).healthy


@pytest.mark.parametrize("over, key", [
    ({"n_mapz": 3}, "did you mean 'n_maps'"),
    ({"split": {"train": 0.8, "val": 0.1, "test": 0.2}}, "[split.test] Value error, train + val + test must be 1"),
    ({"shard_size": 3, "frames_per_scene": 2, "n_maps": 12}, "[shard_size] Value error, must be a multiple"),
    ({"families": []}, "[families]"),
    ({"family_overrides": {"nowhere": {}}}, "[family_overrides]"),
    ({"forward_model": {"name": "imagee"}}, "unknown forward_model 'imagee'"),
    ({"forward_model": {"name": "image", "params": {"noise": "maybe"}}}, "forward_model.params.noise"),
    ({"generator": "tests.nowhere:gen"}, "[generator] Value error, a config cannot name code to import or call"),
    ({"families": ["corner_a", "corner_z"]},
     "[families] unknown scene generator 'corner_z'; registered scene generators: corner_a, corner_b, corner_c"),
    ({"family_overrides": {"corner_a": {"colour": "red"}}}, "[family_overrides.corner_a.colour] unknown key"),
    ({"generator_params": {"colour": "red"}}, "[generator_params.colour] unknown key"),
    ({"generator_params": {"rcs": -1.0}}, "[generator_params.rcs] Input should be greater than 0"),
    ({"radar": {"n_samples": -4}}, "radar.n_samples"),
])
def test_bad_configs_are_located_errors(over, key, dataset_cfg, tiny_plugin):
    with pytest.raises(ConfigError) as err:
        resolve(dataset_cfg(**over), "tiny.toml", registry=tiny_plugin.tiny_registry())
    assert "tiny.toml" in str(err.value) and key in str(err.value)


def _smoke_copy(tmp_path: Path, families: tuple[str, ...] | None = None) -> Path:
    """configs/datasets/smoke.toml in tmp_path; with ``families`` (the tiny generators) in place of its own."""
    src = (ROOT / "configs/datasets/smoke.toml").read_text()
    if families:  # fast and independent of sims.generators' speed
        src = _replace_families(src, families)
    src = src.replace('preset = "../radar/', f'preset = "{ROOT}/configs/radar/')
    path = tmp_path / "smoke.toml"
    path.write_text(src)
    return path


@pytest.mark.slow
def test_smoke_config_with_the_real_generators(tmp_path):
    if not _have_generators():
        pytest.skip("sims.generators is not available")
    out = tmp_path / "smoke"
    assert main(["simulate", str(_smoke_copy(tmp_path)), "--out", str(out), "--workers", "2", "-q"]) == 0
    frames = list(open_dataset(out, None))
    assert len(frames) == 24 and {f.meta["family"] for f in frames} == set(resolve_default().weights())


def resolve_default():
    from sims.dataset import load_dataset_config

    return resolve(load_dataset_config(ROOT / "configs/datasets/default.toml"))


def test_default_config_resolves_against_the_installed_plugins():
    if not _have_generators() or "raytrace" not in get_registry().names("forward_model"):
        pytest.skip("the default config needs sims.generators and the raytrace forward model")
    c = resolve_default()
    assert c.radar["carrier_frequency"] == 10e9 and c.forward_model.params and len(c.weights()) == 6


def test_cli_simulate_smoke_config_end_to_end(tmp_path, capsys, tiny_cli, tiny_plugin):
    path = _smoke_copy(tmp_path, tiny_plugin.FAMILIES)
    out = tmp_path / "smoke"
    assert main(["simulate", str(path), "--out", str(out), "--workers", "1", "-q"]) == 0
    text = capsys.readouterr().out
    assert "24 map(s)" in text and str(out) in text
    m = read_manifest(out)
    assert m["complete"] and sum(s["n_maps"] for s in m["shards"]) == 24
    assert main(["simulate", "--verify", str(out)]) == 0
    assert "0 corrupt" in capsys.readouterr().out
    assert main(["simulate", str(path), "--out", str(out), "-q"]) == 0  # resumes: nothing left to do
    assert "0 generated" in capsys.readouterr().out
    shard = sorted((out / "shards").glob("*.npz"))[0]
    shard.write_bytes(shard.read_bytes()[:-10])
    assert main(["simulate", "--verify", str(out)]) == 1
    assert f"corrupt: shards/{shard.name}" in capsys.readouterr().out
    assert main(["simulate", "--repair", str(out), "-q"]) == 0
    assert main(["simulate", "--verify", str(out)]) == 0
    capsys.readouterr()
    assert main(["simulate", str(path), "--out", str(tmp_path / "six"), "--max-maps", "6", "--workers", "1",
                 "-q"]) == 0
    text = capsys.readouterr().out
    assert "6 map(s)" in text and len(open_dataset(tmp_path / "six", None)) == 6
    assert "6 of the full dataset's 24 maps: the first scenes of each of its splits, split as there" in text
    six, whole = read_manifest(tmp_path / "six")["scenes"], read_manifest(out)["scenes"]
    assert all(six[k] == [whole[k][i] for i in six["scene_index"]]  # the full one's scenes
               for k in ("scene_seed", "family", "split"))
    assert main(["simulate", "--verify", str(tmp_path / "six")]) == 0


def test_cli_errors_are_clear_not_tracebacks(tmp_path, dataset_table):
    path = tmp_path / "bad.toml"
    path.write_text(_toml(dataset_table(shard_sise=4)))
    out = subprocess.run([sys.executable, "-m", "xnlos_core", "simulate", str(path), "--out", str(tmp_path / "o")],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "bad.toml" in out.stderr and "shard_sise" in out.stderr and "did you mean 'shard_size'" in out.stderr
    assert main(["simulate", str(path)]) == 2  # no --out


def _have_generators() -> bool:
    try:
        from sims.generators import FAMILIES, generate_scene  # noqa: F401
    except ImportError:
        return False
    return True


def _replace_families(src: str, families: tuple[str, ...]) -> str:
    lines = src.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("families = ["))
    end = next(i for i in range(start, len(lines)) if lines[i].rstrip().endswith("]"))
    lines[start:end + 1] = [f"families = {json.dumps(list(families))}"]
    return "\n".join(lines) + "\n"


def _toml(t: dict) -> str:
    """A flat TOML rendering of a test table (values as JSON, which TOML accepts for these)."""
    top = [f"{k} = {json.dumps(v)}" for k, v in t.items() if not isinstance(v, dict)]
    tables = []
    for k, v in t.items():
        if isinstance(v, dict):
            body = [f"{kk} = {_inline(vv)}" for kk, vv in v.items()]
            tables.append(f"[{k}]\n" + "\n".join(body))
    return "\n".join(top) + "\n" + "\n".join(tables) + "\n"


def _inline(v) -> str:
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_inline(x)}" for k, x in v.items()) + " }"
    return json.dumps(v)
