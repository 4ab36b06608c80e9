"""Training (Sec. 4.2): every learned detector overfits a tiny dataset; `xnlos train` runs,
validates, checkpoints, resumes to the same weights, and refuses bad configs with located errors."""
from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from plugins.training.checkpoint import load_checkpoint, save_checkpoint
from plugins.detectors.data import MapSet
from plugins.detectors.features import ra_features
from plugins.detectors.heatmaps import peak_cells
from plugins.detectors.nets import architectures
from plugins.detectors.tasks import default_head
from plugins.detectors.train import Batcher
from plugins.detectors.train_config import load_train_config, parse_train_config
from xnlos_core.app.cli import main
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.io import read_jsonl
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
TINY_TOML = ROOT / "configs" / "training" / "tiny.toml"
TINY = {"swin_unet": dict(embed_dim=16, depths=(2, 2), heads=(2, 4), window=(4, 4), patch=(2, 2)),
        "unet": dict(base_channels=8, levels=2), "further_than_cfar": dict(base_channels=8, levels=2),
        "rtn": dict(base_channels=8)}


@pytest.fixture
def one_thread():
    """One torch thread: on a shared 2-core machine OpenMP spinning makes 2 threads slower."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


@pytest.fixture(scope="module")
def corner_maps():
    radar = RadarConfig(n_samples=256, max_range=60.0, n_azimuth_bins=31)  # 241 × 31: LOS and mNLOS
    fm = get_registry().create("forward_model", "image", {})
    scene = load_scene({"builtin": "corner"}, "test")
    frames = [fm.simulate(scene, radar, np.random.default_rng(i)) for i in range(2)]
    return MapSet(np.stack([ra_features(f.ra_map.data).astype(np.float16) for f in frames]),
                  [peak_cells(f.ra_map, f.ground_truth) for f in frames])


@pytest.mark.parametrize("name", ["swin_unet", "unet", "further_than_cfar", "rtn"])
def test_each_learned_detector_overfits_a_tiny_dataset(corner_maps, one_thread, name):
    arch = architectures()[name]
    hp = arch.HParams(**TINY[name])
    torch.manual_seed(0)
    net = arch.module(hp)
    head = default_head(name, hp, (0.7, 1.0))
    x, y = next(Batcher(corner_maps, head, net.multiple, None, 2).epoch(0, 0))
    assert {0.0, 1.0} <= set(np.unique(corner_maps.peaks[0][:, 2]))  # both classes present
    x, y = torch.from_numpy(x), torch.from_numpy(y)
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    losses = []
    for _ in range(400):  # a step budget, not a time budget: the outcome must not depend on the load
        loss = head.loss(net(x), y)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
        if losses[-1] <= losses[0] / 10:
            break
    assert losses[-1] <= losses[0] / 10, f"{name}: loss {losses[0]:.3f} → {losses[-1]:.3f} in {len(losses)} steps"


def test_train_cli_writes_a_documented_model_and_resumes_identically(tmp_path, one_thread, monkeypatch, capsys):
    import plugins.detectors.train as tr

    assert main(["train", str(TINY_TOML), "--out", str(tmp_path / "a"), "--epochs", "2", "-q"]) == 0
    assert "validation Macro-F1" in capsys.readouterr().out
    records = [json.loads(line) for line in (tmp_path / "a" / "metrics.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in records] == [1, 2] and all("macro_f1" in r["val"] for r in records)
    sd_a, meta, _ = load_checkpoint(tmp_path / "a" / "model.pt", "swin_unet")
    assert meta["training"]["dataset"]["source"] == "generate" and meta["decode"]["calibration"]
    assert meta["training"]["config"]["model"]["name"] == "swin_unet"
    assert json.loads((tmp_path / "a" / "model.json").read_text())["weights_sha256"] == meta["weights_sha256"]
    # self-describing: the radar and RA grid of the training maps (tiny.toml's radar)
    rec = meta["trained_on"]
    assert rec["radar"]["n_samples"] == 256 and rec["radar"]["carrier_frequency"] == 10e9
    assert rec["azimuth_axis"]["n"] == 31 and rec["range_axis"]["first"] == 0.0 and rec["source"].startswith("generated")
    assert load_checkpoint(tmp_path / "a" / "best.pt", "swin_unet")[1]["trained_on"] == rec

    real_epoch = tr.Batcher.epoch

    def dies_in_epoch_2(self, seed, epoch):
        if epoch == 2:
            raise KeyboardInterrupt
        return real_epoch(self, seed, epoch)

    monkeypatch.setattr(tr.Batcher, "epoch", dies_in_epoch_2)
    capsys.readouterr()
    assert main(["train", str(TINY_TOML), "--out", str(tmp_path / "b"), "--epochs", "2", "-q"]) == 130
    assert "interrupted; finished epochs are saved (last.pt)" in capsys.readouterr().err  # not "frames"
    assert not (tmp_path / "b" / "model.pt").exists() and (tmp_path / "b" / "last.pt").exists()
    monkeypatch.setattr(tr.Batcher, "epoch", real_epoch)
    assert main(["train", str(TINY_TOML), "--out", str(tmp_path / "b"), "--epochs", "2", "-q"]) == 0
    assert "resumed after epoch 1" in capsys.readouterr().out
    sd_b, _, _ = load_checkpoint(tmp_path / "b" / "model.pt", "swin_unet")
    for key in sd_a:
        torch.testing.assert_close(sd_b[key], sd_a[key], rtol=0, atol=0)
    other = tmp_path / "other.toml"  # another config (learning rate) is another run
    other.write_text(TINY_TOML.read_text().replace("lr = 3e-3", "lr = 2e-3"))
    assert main(["train", str(other), "--out", str(tmp_path / "b"), "--epochs", "2", "-q"]) == 2
    assert "another configuration" in capsys.readouterr().err


def test_a_larger_epochs_extends_a_finished_run_and_a_smaller_one_is_refused(tmp_path, one_thread, capsys):
    """`xnlos train CONFIG --epochs N` extends a finished run (the README's promise;
    it was refused because the epochs were part of the config digest). The extension resumes from
    last.pt: the first epochs are the finished run's, unchanged, and the extra ones follow."""
    run = tmp_path / "run"
    assert main(_tiny_run(run, epochs=2)) == 0
    two = _lines_without_seconds(run / "metrics.jsonl")
    weights_two = load_checkpoint(run / "last.pt", sealed=True)[0]
    assert main(_tiny_run(run, epochs=4)) == 0
    four = _lines_without_seconds(run / "metrics.jsonl")
    assert [r["epoch"] for r in four] == [1, 2, 3, 4] and four[:2] == two
    summary = json.loads((run / "summary.json").read_text())
    assert summary["epochs_run"] == 4 and not summary["stopped_early"]
    assert load_checkpoint(run / "model.pt", "swin_unet")[1]["training"]["config"]["optim"]["epochs"] == 4
    assert not all(torch.equal(weights_two[k], v) for k, v in load_checkpoint(run / "last.pt", sealed=True)[0].items())
    # the cosine schedule spans optim.epochs (plugins.training.optim): the 2-epoch run ended at its
    # floor, the extension continues on the 4-epoch cosine, so it is not a run started with 4 epochs
    assert two[1]["lr"] == pytest.approx(3e-3 * 0.02) and four[2]["lr"] > two[1]["lr"]
    capsys.readouterr()
    assert main(_tiny_run(run, epochs=3)) == 2
    err = capsys.readouterr().err
    assert "holds a run of 4 epochs, longer than optim.epochs = 3" in err and "Traceback" not in err
    assert [r["epoch"] for r in read_jsonl(run / "metrics.jsonl")] == [1, 2, 3, 4]  # left as it was


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_train_writes_into_the_installed_package_only_when_the_command_names_the_export(tmp_path, one_thread,
                                                                                      monkeypatch, capsys):
    """`xnlos train configs/training/residual_mirror.toml --out elsewhere` overwrote the
    shipped model its `export` key names. The same with the tiny config whose `export` names a model
    of the package — a copy of plugins/detectors/models standing in for the installed package, so
    that the real shipped files are never at risk (their hashes are checked too)."""
    import shutil

    import xnlos_core.rundir as rundir

    shipped = {p: _sha(p) for p in sorted((ROOT / "plugins").glob("*/models/*"))}
    assert shipped
    pkg = tmp_path / "site-packages" / "plugins"
    shutil.copytree(ROOT / "plugins" / "detectors" / "models", pkg / "detectors" / "models")
    monkeypatch.setattr(rundir, "package_dirs", lambda distribution="xnlos": [pkg.resolve()])
    target = pkg / "detectors" / "models" / "swin_unet.pt"
    before = {p: _sha(p) for p in (pkg / "detectors" / "models").iterdir()}
    cfg = tmp_path / "tiny_export.toml"
    cfg.write_text(TINY_TOML.read_text().replace('out = "../../out/train/tiny"',
                                                 f'out = "out/train/tiny"\nexport = "{target}"'))

    assert main(["train", str(cfg), "--out", str(tmp_path / "elsewhere"), "--epochs", "1", "-q"]) == 0
    out, err = capsys.readouterr()
    assert {p: _sha(p) for p in (pkg / "detectors" / "models").iterdir()} == before
    assert f"not exported to {target}" in err and f"--export {target}" in err and " and " not in out
    assert json.loads((tmp_path / "elsewhere" / "summary.json").read_text())["export"] is None

    # named on the command line: written (the finished run is reused, not retrained)
    assert main(["train", str(cfg), "--out", str(tmp_path / "elsewhere"), "--epochs", "1", "--export", str(target),
                 "-q"]) == 0
    assert f"and {target}" in capsys.readouterr().out
    assert _sha(target) == _sha(tmp_path / "elsewhere" / "model.pt") != before[target]
    # an export outside the package is the user's own file: written as the config says
    mine = tmp_path / "mine" / "model.pt"
    cfg.write_text(cfg.read_text().replace(str(target), str(mine)))
    assert main(["train", str(cfg), "--out", str(tmp_path / "elsewhere"), "--epochs", "1", "-q"]) == 0
    assert _sha(mine) == _sha(tmp_path / "elsewhere" / "model.pt")
    assert {p: _sha(p) for p in shipped} == shipped


def test_the_shipped_residual_mirror_config_exports_into_the_package_only_when_named(monkeypatch):
    """The reproduction's own config: its `export` is the shipped residual_mirror.pt, which only an
    explicit --export may replace."""
    from plugins.training.run import export_target
    from xnlos_core.config import load_toml

    monkeypatch.chdir(ROOT / "tests")  # the config's folder decides, not the working directory
    folder = ROOT / "configs" / "training"
    export = load_toml(folder / "residual_mirror.toml")["export"]
    dest, why = export_target(export, named=False, base_dir=folder)
    shipped = Path(os.path.normpath(folder / export))  # printed without ../..
    assert dest is None and "inside the installed xnlos package" in why and f"--export {shipped}" in why
    assert export_target(export, named=True, base_dir=folder) == (shipped, None)
    assert (folder / export).resolve() == ROOT / "plugins" / "mirror" / "residual" / "models" / "residual_mirror.pt"


def test_training_config_errors_name_the_key(tmp_path):
    base = load_train_config(TINY_TOML).model_dump(mode="json")
    with pytest.raises(ConfigError, match=r"\[optim.lrate\] unknown key"):
        parse_train_config({**base, "optim": {**base["optim"], "lrate": 1}}, "t.toml")
    with pytest.raises(ConfigError, match="unknown model 'swin'"):
        parse_train_config({**base, "model": {**base["model"], "name": "swin"}}, "t.toml")
    with pytest.raises(ConfigError, match=r"model.params.embed_dims"):
        parse_train_config({**base, "model": {**base["model"], "params": {"embed_dims": 8}}}, "t.toml")
    with pytest.raises(ConfigError, match="exactly one of data.dataset"):
        parse_train_config({**base, "data": {"crop": [8, 8]}}, "t.toml")
    with pytest.raises(ConfigError, match="device"):
        parse_train_config({**base, "device": "tpu"}, "t.toml")


def test_every_shipped_training_config_is_valid():
    from plugins.training.trainers import trainer_for
    from xnlos_core.config import load_toml

    for path in sorted((ROOT / "configs" / "training").glob("*.toml")):
        table = load_toml(path)
        cfg = trainer_for(table, str(path)).parse(table, str(path))  # the residual mirror's too
        assert cfg.model.name in {*architectures(), "residual_mirror"}


def test_fine_tuning_starts_from_the_init_checkpoint_and_refuses_another_network(tmp_path, one_thread):
    from plugins.detectors.train import train
    from xnlos_core.errors import InputError

    base = load_train_config(TINY_TOML).model_dump(mode="json")
    first = parse_train_config({**base, "out": str(tmp_path / "a"), "optim": {**base["optim"], "epochs": 1}})
    train(first, progress=False)
    sd_a, meta_a, _ = load_checkpoint(tmp_path / "a" / "model.pt", "swin_unet")
    # whole maps (no crop), a learning rate too small to move anything: the weights stay those of init
    tune = {**base, "out": str(tmp_path / "b"), "init": str(tmp_path / "a" / "model.pt"),
            "data": {**base["data"], "crop": None}, "optim": {**base["optim"], "epochs": 1, "lr": 1e-12}}
    train(parse_train_config(tune), progress=False)
    sd_b, meta_b, _ = load_checkpoint(tmp_path / "b" / "model.pt", "swin_unet")
    for key in sd_a:  # batch-norm running statistics follow the data whatever the learning rate
        if "running_" not in key and "num_batches" not in key:
            torch.testing.assert_close(sd_b[key], sd_a[key], rtol=0, atol=1e-6, msg=key)
    init = meta_b["training"]["dataset"]["init"]
    assert init["weights_sha256"] == meta_a["weights_sha256"] and init["command"] == meta_a["training"]["command"]
    assert init["epochs_run"] == meta_a["training"]["epochs_run"] and "init" not in init  # a started from scratch
    # a third stage from b records the whole chain: b, and under it b's own parent a
    train(parse_train_config({**tune, "out": str(tmp_path / "f"), "init": str(tmp_path / "b" / "model.pt")}),
          progress=False)
    chain = load_checkpoint(tmp_path / "f" / "model.pt", "swin_unet")[1]["training"]["dataset"]["init"]
    assert chain["weights_sha256"] == meta_b["weights_sha256"] and chain["init"] == init

    other = {**tune, "out": str(tmp_path / "c"),
             "model": {**base["model"], "params": {**base["model"]["params"], "embed_dim": 8}}}
    with pytest.raises(InputError, match=r"init .*hyper-parameters"):
        train(parse_train_config(other), progress=False)
    with pytest.raises(InputError, match="missing.pt"):
        train(parse_train_config({**tune, "out": str(tmp_path / "d"), "init": str(tmp_path / "missing.pt")}),
              progress=False)
    # a parent written before a hyper-parameter existed (here decoder_convs) counts with the default
    meta_old = {k: v for k, v in meta_a.items() if k != "weights_sha256"}
    meta_old["hparams"] = {k: v for k, v in meta_a["hparams"].items() if k != "decoder_convs"}
    save_checkpoint(tmp_path / "old.pt", sd_a, meta_old)
    train(parse_train_config({**tune, "out": str(tmp_path / "e"), "init": str(tmp_path / "old.pt")}), progress=False)


def test_azimuth_flip_mirrors_features_and_targets_and_leaves_other_runs_alone(corner_maps):
    head = default_head("unet", architectures()["unet"].HParams(**TINY["unet"]), (0.7, 1.0))
    plain, flip = Batcher(corner_maps, head, (4, 4), None, 1), Batcher(corner_maps, head, (4, 4), None, 1, flip=True)
    x0, y0 = plain.padded(0)
    x1, y1 = plain.padded(0, flip=True)
    w = corner_maps.features.shape[-1]  # 31 bins, padded to 32 at the high-azimuth end
    assert np.array_equal(x1[:, :, :w], x0[:, :, :w][:, :, ::-1]) and not x1[:, :, w:].any()
    # the Gaussian targets peak at 1 on the mirrored cells
    p = corner_maps.peaks[0]
    r, a, c = np.rint(p[:, 0]).astype(int), np.rint(p[:, 1]).astype(int), p[:, 2].astype(int)
    assert np.allclose(y1[c, r, w - 1 - a], 1.0) and np.allclose(y0[c, r, a], 1.0)
    # over a few epochs both orientations occur, each sample being one of the two
    seen = set()
    for epoch in range(4):
        for x, _ in flip.epoch(0, epoch):
            i = [k for k in range(2) if np.array_equal(x[0], plain.padded(k)[0]) or
                 np.array_equal(x[0], plain.padded(k, True)[0])]
            assert len(i) == 1
            seen.add(np.array_equal(x[0], plain.padded(i[0], True)[0]))
    assert seen == {False, True}


def as_written_from(cfg, folder: Path, root: Path):
    """``cfg`` (a config of ``folder``) with its relative ``data.dataset`` and ``init`` rewritten
    relative to ``root`` (the paths the digest covers; ``out`` and ``export`` it leaves out)."""
    import os

    def rebase(p):
        return p if p is None or Path(p).is_absolute() else os.path.relpath(os.path.normpath(folder / p), root)

    data = cfg.data.model_copy(update={"dataset": rebase(cfg.data.dataset)})
    return cfg.model_copy(update={"data": data, "init": rebase(cfg.init)})


def test_shipped_models_keep_the_digest_of_their_training_config():
    """Each shipped model's training config still hashes to the digest in its metadata, and the
    options added later (data.flip_azimuth, data.doppler, data.previous_frames: they count only when set) change it when toggled."""
    from plugins.detectors.learned import MODELS_DIR

    for name in ("swin_unet", "unet", "further_than_cfar", "rtn"):
        meta = json.loads((MODELS_DIR / f"{name}.json").read_text())
        path = ROOT / meta["training"]["config_file"]
        cfg = load_train_config(path)
        # the models were trained when a training config's paths were taken from the working
        # directory (the project root); the config's paths, re-expressed from the root, hash as then
        assert as_written_from(cfg, path.parent, ROOT).digest() == meta["training"]["config_sha256"], name
        toggled = cfg.model_copy(update={"data": cfg.data.model_copy(update={"flip_azimuth": not cfg.data.flip_azimuth})})
        assert toggled.digest() != cfg.digest()
        plain = toggled if cfg.data.flip_azimuth else cfg  # without the option: hashed as before it existed
        dump = plain.model_dump(exclude={"out", "export", "threads"})
        for key in ("flip_azimuth", "doppler", "previous_frames"):  # the late options, unset
            del dump["data"][key]
        assert plain.digest() == hashlib.sha256(json.dumps(dump, sort_keys=True, default=str).encode()).hexdigest()


# --- resume integrity -------------------------------------------------------

def _tiny_run(out: Path, epochs: int = 3) -> list[str]:
    return ["train", str(TINY_TOML), "--out", str(out), "--epochs", str(epochs), "-q"]


def _lines_without_seconds(path: Path) -> list[dict]:
    """metrics.jsonl records without their timings (the only fields two identical runs differ in)."""
    recs = [json.loads(line) for line in path.read_text().splitlines()]
    return [{k: v for k, v in r.items() if not k.endswith("_seconds")} for r in recs]


@pytest.fixture(scope="module")
def straight_run(tmp_path_factory):
    """An uninterrupted 3-epoch tiny run (one torch thread)."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("straight") / "run"
    assert main(_tiny_run(out)) == 0
    torch.set_num_threads(n)
    return out


class Crash(Exception):
    """A stand-in for the process dying at a chosen point."""


def _flip(data: bytes, bit: int) -> bytes:
    b = bytearray(data)
    b[bit // 8] ^= 1 << (bit % 8)
    return bytes(b)


def test_a_flipped_bit_anywhere_in_last_pt_is_refused(straight_run, tmp_path):
    """5 of 12 bit flips in a mid-run last.pt (optimizer state) were accepted. Here
    24 flips spread over the file and 8 inside the optimizer's tensors and the pickled progress /
    history are each refused, naming the file; the optimizer flips pass the weights hash alone."""
    from plugins.training.checkpoint import SEAL, weights_digest

    data = (straight_run / "last.pt").read_bytes()
    assert data.startswith(SEAL)
    _, _, payload = load_checkpoint(straight_run / "last.pt", "swin_unet", sealed=True)
    opt_state = payload["optimizer"]["state"]
    big = max(opt_state.values(), key=lambda s: s["exp_avg_sq"].numel())
    regions = []
    for t in (big["exp_avg"], big["exp_avg_sq"]):
        raw = t.numpy().tobytes()
        start = data.find(raw)
        assert start > 0 and data.find(raw, start + 1) < 0
        regions.append((start, len(raw)))
    for marker in (b"bad_epochs", b"train_loss"):  # progress and history in the pickled record
        regions.append((data.find(marker), len(marker)))
    assert all(start > 0 for start, _ in regions)
    spread = [int(x) for x in np.linspace(0, 8 * len(data) - 1, 24)]
    inside = [8 * (s + k * n // 2) + 3 for s, n in regions for k in (0, 1)]
    target = tmp_path / "last.pt"
    body_len = len(data) - (len(SEAL) + 65)
    for bit in spread + inside:
        target.write_bytes(_flip(data, bit))
        with pytest.raises(InputError, match=r"last\.pt.*corrupted"):
            load_checkpoint(target, "swin_unet", sealed=True)
        if bit in inside[:4]:  # in the optimizer's tensors: the weights themselves are intact
            body = _flip(data, bit)[-body_len:]
            flipped = torch.load(io.BytesIO(body), weights_only=True)
            assert weights_digest(flipped["state_dict"]) == json.loads(flipped["metadata_json"])["weights_sha256"]
    # a resume checkpoint without the seal (an older xnlos) is refused too, not trusted
    sd, meta, payload = load_checkpoint(straight_run / "last.pt", sealed=True)
    save_checkpoint(target, sd, {k: v for k, v in meta.items() if k != "weights_sha256"}, sidecar=False,
                    extra={k: payload[k] for k in ("optimizer", "scheduler", "progress")})
    with pytest.raises(InputError, match="no whole-file hash"):
        load_checkpoint(target, sealed=True)


def test_resuming_from_a_corrupted_last_pt_stops_with_an_error_naming_it(straight_run, tmp_path, capsys):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(straight_run, run)
    data = (run / "last.pt").read_bytes()
    (run / "last.pt").write_bytes(_flip(data, 8 * (len(data) // 2)))
    assert main(_tiny_run(run)) == 2
    err = capsys.readouterr().err
    assert "last.pt" in err and "corrupted" in err and "Traceback" not in err


@pytest.mark.parametrize("point", ["after_best", "after_last", "torn_line"])
def test_a_crash_at_any_point_of_an_epoch_commit_resumes_to_the_uninterrupted_run(straight_run, tmp_path, one_thread,
                                                                               monkeypatch, point):
    """a crash between writing last.pt and appending metrics.jsonl lost the epoch's
    line for good (epochs_run 39, stopped_early true instead of 40, false). Crashing in epoch 2
    after best.pt, after last.pt, or halfway through the line, then resuming, gives the same
    summary, metrics lines and weights as the uninterrupted run."""
    import plugins.training.resume as rs

    real_save, real_append = rs.save_epoch, rs.append_jsonl

    def save_epoch(out, net, metadata, *args):
        if metadata["training"]["epoch"] == 2 and point == "after_best":
            raise Crash
        return real_save(out, net, metadata, *args)

    def append_jsonl(path, record):
        if record["epoch"] == 2 and point != "after_best":
            if point == "torn_line":
                with open(path, "a") as fh:
                    fh.write(json.dumps(record)[:40])
            raise Crash
        return real_append(path, record)

    monkeypatch.setattr(rs, "save_epoch", save_epoch)
    monkeypatch.setattr(rs, "append_jsonl", append_jsonl)
    run = tmp_path / "run"
    with pytest.raises(Crash):
        main(_tiny_run(run))
    assert not (run / "summary.json").exists()
    assert [r["epoch"] for r in read_jsonl(run / "metrics.jsonl")] == [1]  # epoch 2's line is not there
    monkeypatch.setattr(rs, "save_epoch", real_save)
    monkeypatch.setattr(rs, "append_jsonl", real_append)
    assert main(_tiny_run(run)) == 0
    got, want = (json.loads((d / "summary.json").read_text()) for d in (run, straight_run))
    assert (got["epochs_run"], got["stopped_early"], got["best_epoch"]) == (3, False, want["best_epoch"])
    assert want["epochs_run"] == 3 and not want["stopped_early"]
    assert _lines_without_seconds(run / "metrics.jsonl") == _lines_without_seconds(straight_run / "metrics.jsonl")
    sd_a, _, _ = load_checkpoint(straight_run / "model.pt", "swin_unet")
    sd_b, _, _ = load_checkpoint(run / "model.pt", "swin_unet")
    for key in sd_a:
        torch.testing.assert_close(sd_b[key], sd_a[key], rtol=0, atol=0)


def test_train_and_check_name_the_models_they_can_train(tmp_path, capsys):
    cfg = tmp_path / "t.toml"
    cfg.write_text(TINY_TOML.read_text().replace('name = "swin_unet"', 'name = "swin"'))
    for command in (["train", str(cfg), "-q"], ["check", str(cfg)]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert f"{cfg}: [model] name 'swin': no trainer" in err and "residual_mirror" in err and "swin_unet" in err


def test_a_run_directory_of_an_earlier_xnlos_is_recognised_by_its_config_digest(straight_run, tmp_path, one_thread,
                                                                                capsys):
    """run.json written before run_sha256 existed holds only config_sha256 (epochs included): the same
    config resumes from it, a changed one is refused as before."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(straight_run, run)
    record = json.loads((run / "run.json").read_text())
    del record["run_sha256"]
    (run / "run.json").write_text(json.dumps(record))
    assert main(_tiny_run(run, epochs=4)) == 2
    assert "holds a training run of another configuration" in capsys.readouterr().err
    assert main(_tiny_run(run)) == 0
    assert json.loads((run / "summary.json").read_text())["epochs_run"] == 3
    assert "run_sha256" in json.loads((run / "run.json").read_text())


def test_a_copied_training_config_takes_its_paths_from_its_own_folder(tmp_path, one_thread, monkeypatch, capsys):
    """every path of a training config (out, init, export, data.generate's scene file)
    is taken from the config file's folder, so a copied config runs the same from any working
    directory; paths on the command line stay relative to the working directory."""
    proj = tmp_path / "proj"
    (proj / "cfg").mkdir(parents=True)
    (proj / "cfg" / "scenes").mkdir()  # files the core reads stay inside the config roots
    shutil.copy(ROOT / "configs" / "scenes" / "corner.toml", proj / "cfg" / "scenes" / "corner.toml")
    text = (TINY_TOML.read_text().replace('out = "../../out/train/tiny"', 'out = "../runs/a"')
            .replace('scene = { builtin = "corner" }', 'scene = { file = "scenes/corner.toml" }'))
    (proj / "cfg" / "a.toml").write_text(text)
    (proj / "cfg" / "b.toml").write_text(text.replace('out = "../runs/a"', 'out = "../runs/b"\ninit = "../runs/a/model.pt"'
                                                        '\nexport = "../exported/b.pt"'))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["check", str(proj / "cfg" / "a.toml")]) == 0
    assert main(["train", str(proj / "cfg" / "a.toml"), "--epochs", "1", "-q"]) == 0
    assert (proj / "runs" / "a" / "model.pt").is_file() and not any(elsewhere.iterdir())
    assert main(["train", "../proj/cfg/b.toml", "--epochs", "1", "-q"]) == 0
    meta = load_checkpoint(proj / "runs" / "b" / "model.pt", "swin_unet")[1]
    assert meta["training"]["dataset"]["init"]["path"] == "../runs/a/model.pt"  # as written: the digest's form
    assert _sha(proj / "exported" / "b.pt") == _sha(proj / "runs" / "b" / "model.pt")
    # --out on the command line: from the working directory
    assert main(["train", str(proj / "cfg" / "a.toml"), "--epochs", "1", "--out", "mine", "-q"]) == 0
    assert (elsewhere / "mine" / "model.pt").is_file()
    capsys.readouterr()
