"""residual_mirror (Eq. 7 + learned residual, Eq. 9): the network overfits a tiny set, the loss is
Eq. 9, checkpoints load / round-trip / fail clearly, conformance, and covariance in → out."""
from pathlib import Path

import numpy as np
import pytest
import torch

from plugins.training.checkpoint import load_checkpoint, save_checkpoint
from plugins.mirror.residual.data import NoiseConfig, scene_inputs
from plugins.mirror.residual.net import HParams, geo_loss
from plugins.mirror.residual.reconstructor import DEFAULT_MODEL, ResidualMirrorReconstructor, load_model
from plugins.mirror.residual.train import RMOptim, fit, new_network, tensors
from xnlos_core import LOS, MNLOS, Detections, InputError, WallPosterior
from xnlos_core.geometry import mirror_reflect
from xnlos_core.testing import check_reconstructor
from xnlos_core.types import GroundTruth


@pytest.fixture(autouse=True)
def one_thread():
    """One torch thread: on a shared 2-core machine OpenMP spinning makes 2 threads much slower."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def corner_scene():
    """A facade that bends by 10° (x = 20 for y ∈ [0, 15], then on to (22.6, 29.8)): below lsq's
    corner_angle, so lsq fits one line through both legs and the analytic mirror is off; hidden points
    mirrored across the x = 20 leg."""
    bend = np.radians(10.0)
    los = np.concatenate([np.stack([np.full(16, 20.0), np.linspace(0, 15, 16)], 1),
                          np.c_[20.0 + np.sin(bend) * np.linspace(1, 15, 15), 15.0 + np.cos(bend) * np.linspace(1, 15, 15)]])
    hidden = np.stack([np.linspace(8, 16, 12), np.linspace(-12, -2, 12)], 1)
    virt = mirror_reflect(hidden, np.array([-1.0, 0.0]), 20.0)
    keep = (virt[:, 1] / virt[:, 0] * 20 > 0) & (virt[:, 1] / virt[:, 0] * 20 < 15)
    virt, hidden = virt[keep] if keep.any() else virt, hidden[keep] if keep.any() else hidden
    return GroundTruth(los, virt, hidden, np.zeros(len(virt), int), ("car",))


def tiny_pairs():
    rec = ResidualMirrorReconstructor()
    parts = [scene_inputs(corner_scene(), rec, NoiseConfig(range_std=0.05, azimuth_std=0.002),
                          np.random.default_rng([0, d]), 8, 3.0) for d in range(3)]
    keys = ("query", "neigh", "mask", "normal")
    out = {k: np.concatenate([p[3][k] for p in parts]) for k in keys}
    out["target"] = np.concatenate([p[4] - p[2].mean for p in parts])
    return tensors(out)


def test_overfits_a_tiny_set():
    data = tiny_pairs()
    net = new_network(HParams(), seed=0)
    before = float(geo_loss(torch.zeros_like(data["target"]), data["target"]))  # the untrained net is the mirror
    assert before > 1.0
    with torch.random.fork_rng(devices=[]):
        fit(net, data, None, RMOptim(epochs=300, batch_size=len(data["target"]), lr=1e-2, nll_weight=0.0), seed=0)
    from plugins.mirror.residual.train import evaluate

    after = evaluate(net, data)["l_geo"]
    assert after <= before / 10, (before, after)


def test_eq9_loss_by_hand():
    delta = torch.tensor([[1.0, 2.0], [0.5, -1.0]])
    target = torch.tensor([[0.0, 0.0], [1.0, -1.0]])
    # (|1| + |2| + |−0.5| + |0|) / 2
    assert float(geo_loss(delta, target)) == pytest.approx(1.75)


def test_shipped_checkpoint_loads_and_round_trips(tmp_path):
    assert DEFAULT_MODEL.is_file() and DEFAULT_MODEL.stat().st_size < 1_000_000
    net, meta = load_model()
    assert meta["architecture"] == "residual_mirror" and meta["neighbours"] >= 1
    copy = tmp_path / "copy.pt"
    save_checkpoint(copy, net, meta)
    net2, meta2 = load_model(copy)
    x = (torch.randn(5, 12), torch.randn(5, 4, 5), torch.ones(5, 4, dtype=torch.bool))
    with torch.inference_mode():
        assert all(torch.equal(a, b) for a, b in zip(net(*x), net2(*x)))
    assert meta2["hparams"] == meta["hparams"]


def test_bad_checkpoints_name_the_file(tmp_path):
    net, meta = load_model()
    wrong = tmp_path / "unet.pt"
    save_checkpoint(wrong, net, {**meta, "architecture": "unet"})
    with pytest.raises(InputError, match=r"unet\.pt.*'unet' model"):
        load_model(wrong)
    shape = tmp_path / "shape.pt"
    save_checkpoint(shape, net, {**meta, "hparams": {**meta["hparams"], "dim": 8}})
    with pytest.raises(InputError, match=r"shape\.pt.*do not fit"):
        load_model(shape)
    bad = tmp_path / "corrupt.pt"
    bad.write_bytes(DEFAULT_MODEL.read_bytes()[:5000])
    with pytest.raises(InputError, match=r"corrupt\.pt"):
        load_model(bad)
    with pytest.raises(InputError, match=r"missing\.pt.*no such file"):
        ResidualMirrorReconstructor({"model": str(tmp_path / "missing.pt")}).reconstruct(
            Detections.from_points([[30.0, 5.0]], MNLOS), [WallPosterior.line([-1.0, 0.0], 20.0)])


def test_conformance_kit():
    check_reconstructor(ResidualMirrorReconstructor())


def _scene(cov):
    los = np.stack([np.full(8, 20.0), np.linspace(-4, 10, 8)], 1)
    virt = np.array([[26.0, 3.0], [30.0, 8.0]])
    det = Detections.concat(Detections.from_points(los, LOS, 1.0, 0.1, 0.01),
                            Detections.from_points(virt, MNLOS, 1.0, 0.1, 0.01))
    return det, [WallPosterior.line(np.array([-1.0, 0.0]), 20.0, cov=cov, extent=np.array([[20.0, -4], [20.0, 10]]))]


def test_covariance_is_psd_and_grows_with_the_wall_covariance():
    rec = ResidualMirrorReconstructor()
    traces = []
    for scale in (0.0, 1e-4, 1e-2):  # 0: a point-estimate wall
        det, walls = _scene(np.diag([scale, 10 * scale]))
        hp = rec.reconstruct(det, walls)
        assert hp.source_index.tolist() == [8, 9]
        assert np.all(np.isfinite(hp.cov)) and np.allclose(hp.cov, np.swapaxes(hp.cov, 1, 2))
        assert np.all(np.linalg.eigvalsh(hp.cov) > 0)
        traces.append(np.trace(hp.cov, axis1=1, axis2=2))
    assert np.all(np.diff(np.stack(traces), axis=0) > 0)
    geom = ResidualMirrorReconstructor({"residual_cov": False}).reconstruct(*_scene(np.zeros((2, 2))))
    assert np.all(np.trace(traces[0][:, None, None] * np.eye(2), axis1=1, axis2=2) > np.trace(geom.cov, axis1=1, axis2=2))


def test_wall_samples_and_arcs_are_accepted():
    det, (line,) = _scene(np.diag([1e-4, 1e-3]))
    rng = np.random.default_rng(0)
    sampled = WallPosterior("line", line.mean, line.cov, extent=line.extent,
                            samples=line.mean + rng.multivariate_normal(np.zeros(2), line.cov, 200))
    arc = WallPosterior.arc(line.normal, line.offset, 0.01, anchor=np.array([20.0, 3.0]), cov=np.diag([1e-4, 1e-3, 1e-6]),
                            extent=line.extent)
    for wall in (sampled, arc):
        hp = ResidualMirrorReconstructor().reconstruct(det, [wall])
        assert len(hp) == 2 and np.all(np.isfinite(hp.mean)) and np.all(np.linalg.eigvalsh(hp.cov) > 0)
        assert np.linalg.norm(hp.mean - [[14.0, 3.0], [10.0, 8.0]], axis=1).max() < 2.0


def test_params_validated():
    from xnlos_core.errors import ConfigError

    with pytest.raises(ConfigError, match="neighbours"):
        ResidualMirrorReconstructor({"neighbours": 0})


def test_resumed_training_matches_an_uninterrupted_run(tmp_path):
    data = {k: v[:40] for k, v in tiny_pairs().items()}
    opt = RMOptim(epochs=4, batch_size=16, lr=3e-3)
    straight = new_network(HParams(dim=8), seed=1)
    fit(straight, data, None, opt, seed=1)
    first = new_network(HParams(dim=8), seed=1)
    saved = {}

    def stop_after_two(epoch, rec, states):
        saved.update(states, epoch=epoch)
        return epoch == 2

    fit(first, data, None, opt, seed=1, on_epoch=stop_after_two)
    save_checkpoint(tmp_path / "last.pt", first, {"architecture": "residual_mirror"}, sidecar=False,
                    extra={"optimizer": saved["optimizer"], "scheduler": saved["scheduler"]})
    sd, _, payload = load_checkpoint(tmp_path / "last.pt")  # weights_only=True must accept the states
    resumed = new_network(HParams(dim=8), seed=99)
    resumed.load_state_dict(sd)
    fit(resumed, data, None, opt, seed=1, state={**payload, "epoch": 2})
    for (name, a), b in zip(straight.state_dict().items(), resumed.state_dict().values()):
        assert torch.allclose(a, b, atol=1e-6), name


def test_resume_state_is_sealed_and_rebuilds_metrics_after_a_crash(tmp_path, monkeypatch):
    """for the residual mirror's training (the shared plugins.training.resume): a crash
    after last.pt but before its metrics line loses no line, best.pt is rebuilt from last.pt, the
    resumed fit ends on the uninterrupted weights, and a flipped bit in the optimizer state is refused."""
    import json

    import plugins.training.resume as rs

    data = {k: v[:40] for k, v in tiny_pairs().items()}
    opt = RMOptim(epochs=4, batch_size=16, lr=3e-3)
    straight = new_network(HParams(dim=8), seed=1)
    fit(straight, data, None, opt, seed=1)
    first = new_network(HParams(dim=8), seed=1)
    meta = {"architecture": "residual_mirror", "hparams": HParams(dim=8).model_dump(mode="json")}
    history, real_append = [], rs.append_jsonl

    class Crash(Exception):
        pass

    def append_dies_in_epoch_2(path, record):
        if record["epoch"] == 2:
            raise Crash
        real_append(path, record)

    def on_epoch(epoch, rec, states):
        history.append(rec)
        rs.save_epoch(tmp_path, first, {**meta, "training": {"epoch": epoch}}, states["optimizer"],
                      states["scheduler"], {"epoch": epoch}, history, rs.best_copy(first, meta))

    monkeypatch.setattr(rs, "append_jsonl", append_dies_in_epoch_2)
    rs.start_fresh(tmp_path)
    with pytest.raises(Crash):
        fit(first, data, None, opt, seed=1, on_epoch=on_epoch)
    assert len((tmp_path / "metrics.jsonl").read_text().splitlines()) == 1
    saved = rs.load_resume(tmp_path, "residual_mirror")
    assert [r["epoch"] for r in saved.history] == [1, 2] and saved.progress == {"epoch": 2}
    lines = [json.loads(x) for x in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in lines] == [1, 2]
    assert load_checkpoint(tmp_path / "best.pt")[1]["architecture"] == "residual_mirror"
    # the optimizer's moments (state dicts that training then updates in place)
    moment = next(iter(saved.optimizer["state"].values()))["exp_avg_sq"].numpy().tobytes()
    raw = (tmp_path / "last.pt").read_bytes()
    resumed = new_network(HParams(dim=8), seed=99)
    resumed.load_state_dict(saved.state_dict)
    fit(resumed, data, None, opt, seed=1, state={"optimizer": saved.optimizer, "scheduler": saved.scheduler,
                                                  "epoch": 2})
    for (name, a), b in zip(straight.state_dict().items(), resumed.state_dict().values()):
        assert torch.allclose(a, b, atol=1e-6), name

    at = raw.find(moment)
    assert at > 0
    flipped = bytearray(raw)
    flipped[at + len(moment) // 2] ^= 0x10
    (tmp_path / "last.pt").write_bytes(bytes(flipped))
    with pytest.raises(InputError, match=r"last\.pt.*corrupted"):
        rs.load_resume(tmp_path, "residual_mirror")
