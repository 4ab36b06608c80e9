"""Learned detectors (swin_unet, unet, further_than_cfar, rtn): conformance, odd sizes, bad input,
features, checkpoints (round trip, wrong architecture, corruption) and the device parameter."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from plugins.training.checkpoint import load_checkpoint, save_checkpoint
from plugins.detectors.features import ra_features
from plugins.detectors.learned import LEARNED, MODELS_DIR
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.testing import check_component, synthetic_frame
from xnlos_core.types import LOS, Detections, Frame, RAMap

pytestmark = pytest.mark.filterwarnings("ignore::xnlos_core.errors.GridMismatchWarning")  # toy maps, not the models' grid

NAMES = sorted(LEARNED)
SMALL = RadarConfig(n_samples=128, max_range=30.0, n_azimuth_bins=31)


@pytest.fixture(scope="module")
def detectors():
    return {n: get_registry().create("detector", n, {"device": "cpu"}) for n in NAMES}


def _frame(data, radar=None) -> Frame:
    data = np.asarray(data, np.complex64)
    h, w = data.shape
    r = np.linspace(0.0, 0.25 * (h - 1), h)
    a = np.linspace(-1.0, 1.0, w)
    return Frame(RAMap(data, r, a, radar or SMALL))


@pytest.mark.parametrize("name", NAMES)
def test_shipped_models_exist_are_small_and_documented(name):
    path = MODELS_DIR / f"{name}.pt"
    assert path.is_file() and path.stat().st_size < 10 * 2**20
    sd, meta, _ = load_checkpoint(path, name)
    assert meta["architecture"] == name and meta["training"]["command"].startswith("xnlos train ")
    assert meta["training"]["dataset"]["sha256"] and "val" in meta["training"]["metrics"]
    assert (MODELS_DIR / f"{name}.json").is_file()


@pytest.mark.parametrize("name", NAMES)
def test_conformance_kit_with_cpu_device(name):
    check_component("detector", name, {"device": "cpu"})


@pytest.mark.parametrize("shape", [(2, 2), (7, 5), (121, 31), (33, 130)])
@pytest.mark.parametrize("name", NAMES)
def test_odd_sizes(detectors, name, shape):
    rng = np.random.default_rng(0)
    data = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)
    data[shape[0] // 2, shape[1] // 2] = 3e3
    frame = _frame(data)
    det = detectors[name].detect(frame)
    assert isinstance(det, Detections)
    if len(det):
        assert det.range.min() >= 0 and det.range.max() <= frame.ra_map.range_axis[-1] + 1e-9
        assert np.abs(det.azimuth).max() <= 1.0 + 1e-9
    heat = detectors[name].heatmap(frame)
    assert np.all(np.isfinite(heat)) and heat.min() >= 0 and heat.max() <= 1
    if name != "rtn":
        assert heat.shape == (2,) + shape


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_maps_are_refused_with_a_clear_error(detectors, bad):
    frame = _frame(np.ones((121, 31)))
    with pytest.raises(ValueError, match="read-only"):
        frame.ra_map.data[3, 4] = bad  # RAMap refuses NaN and cannot be corrupted after construction
    data = np.ones((121, 31), np.complex64)
    data[3, 4] = bad
    with pytest.raises(InputError, match="NaN or infinite"):
        ra_features(data)  # the detectors' own check, for maps that bypass RAMap
    for name in NAMES:
        assert np.all(np.isfinite(detectors[name].output(frame)))


def test_zero_and_huge_dynamic_range_maps_give_finite_heatmaps(detectors):
    zero = _frame(np.zeros((121, 31)))
    rng = np.random.default_rng(1)
    huge = rng.standard_normal((121, 31)) * 1e-6 + 0j
    huge[60, 15] = 1e6  # 1e12 in amplitude, 240 dB in power
    for name in NAMES:
        for frame in (zero, _frame(huge)):
            heat = detectors[name].heatmap(frame)
            assert np.all(np.isfinite(heat))
            det = detectors[name].detect(frame)
            assert np.all(np.isfinite(det.range)) and np.all(np.isfinite(det.confidence))


def test_features_documented_properties():
    rng = np.random.default_rng(2)
    k = (rng.standard_normal((40, 9)) + 1j * rng.standard_normal((40, 9))).astype(np.complex64)
    f = ra_features(k)
    assert f.shape == (4, 40, 9) and f.dtype == np.float32
    np.testing.assert_array_equal(f[3, 1:], np.maximum.accumulate(f[0, :-1], axis=0))  # occlusion channel
    np.testing.assert_allclose(ra_features(k * np.complex64(1e6)), f, atol=1e-5)  # scale invariant
    np.testing.assert_allclose(f[1] ** 2 + f[2] ** 2, 1.0, atol=1e-5)
    assert np.all(ra_features(np.zeros((5, 5))) == 0)
    big = np.ones((5, 5), np.complex64)
    big[2, 2] = 1e30
    fb = ra_features(big)
    assert np.all(np.isfinite(fb)) and fb[0].max() == 10.0 and fb[0].min() >= -3.0
    with pytest.raises(InputError, match="NaN or infinite"):
        ra_features(np.array([[1.0, np.nan]]))


@pytest.mark.parametrize("name", NAMES)
def test_checkpoint_round_trip(tmp_path, name, tiny_checkpoint):
    net = tiny_checkpoint(tmp_path / "m.pt", name, extra_meta={"training": {"note": "round trip"}})
    sd, meta, _ = load_checkpoint(tmp_path / "m.pt", name)
    assert meta["training"] == {"note": "round trip"} and meta["hparams"] == net.hp.model_dump(mode="json")
    for key, value in net.state_dict().items():
        assert torch.equal(sd[key], value)
    det = get_registry().create("detector", name, {"checkpoint": str(tmp_path / "m.pt"), "device": "cpu"})
    frame = synthetic_frame(SMALL)
    out = det.output(frame)
    from plugins.detectors.learned import run_network
    net.eval()
    # the detector runs channels-last (plugins/detectors/inference.py): equal within 1e-5, not bitwise
    np.testing.assert_allclose(out, run_network(net, ra_features(frame.ra_map.data), torch.device("cpu")),
                               rtol=0, atol=1e-5)
    assert isinstance(det.detect(frame), Detections)


def test_checkpoint_of_another_architecture_is_refused(tmp_path, tiny_checkpoint):
    tiny_checkpoint(tmp_path / "unet.pt", "unet")
    det = get_registry().create("detector", "swin_unet", {"checkpoint": str(tmp_path / "unet.pt")})
    with pytest.raises(InputError, match="holds a 'unet' model, but detector 'swin_unet' needs"):
        det.detect(synthetic_frame(SMALL))


def test_corrupted_and_foreign_checkpoints_are_refused(tmp_path, tiny_checkpoint):
    tiny_checkpoint(tmp_path / "good.pt", "rtn")
    raw = (tmp_path / "good.pt").read_bytes()
    (tmp_path / "truncated.pt").write_bytes(raw[: len(raw) // 2])
    (tmp_path / "garbage.pt").write_bytes(np.random.default_rng(0).bytes(4096))
    torch.save({"weights": torch.zeros(3)}, tmp_path / "foreign.pt")
    sd, meta, payload = load_checkpoint(tmp_path / "good.pt")
    sd = {k: v.clone() for k, v in sd.items()}
    first = next(k for k, v in sd.items() if v.is_floating_point())
    sd[first].view(-1)[0] += 1.0  # one weight changed behind the metadata's back
    payload = {**payload, "state_dict": sd}
    torch.save(payload, tmp_path / "tampered.pt")
    cases = {"truncated.pt": "not a readable torch checkpoint", "garbage.pt": "not a readable torch checkpoint",
             "foreign.pt": "not an xnlos detector checkpoint", "tampered.pt": "corrupted",
             "missing.pt": "no such file"}
    for fname, msg in cases.items():
        with pytest.raises(InputError, match=msg):
            get_registry().create("detector", "rtn", {"checkpoint": str(tmp_path / fname)}).detect(synthetic_frame(SMALL))


def test_weights_that_do_not_fit_the_hparams_are_refused(tmp_path, tiny_checkpoint):
    tiny_checkpoint(tmp_path / "a.pt", "unet")
    sd, meta, _ = load_checkpoint(tmp_path / "a.pt")
    meta["hparams"]["base_channels"] = 6
    save_checkpoint(tmp_path / "b.pt", sd, {k: v for k, v in meta.items() if k != "weights_sha256"})
    with pytest.raises(InputError, match="weights do not fit a 'unet' network"):
        get_registry().create("detector", "unet", {"checkpoint": str(tmp_path / "b.pt")}).detect(synthetic_frame(SMALL))


def test_untrained_network_is_deterministic_by_seed():
    frame = synthetic_frame(SMALL)
    a = get_registry().create("detector", "unet", {"checkpoint": "none", "seed": 3}).output(frame)
    b = get_registry().create("detector", "unet", {"checkpoint": "none", "seed": 3}).output(frame)
    c = get_registry().create("detector", "unet", {"checkpoint": "none", "seed": 4}).output(frame)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_decode_of_an_output_is_detect_and_takes_combined_outputs(detectors):
    """decode(output(frame)) is detect(frame), cropped dense logits decode alike, and the mean of two
    networks' logits (an ensemble) decodes on the first's settings into detections inside the map."""
    frame = synthetic_frame(RadarConfig())
    h, w = frame.ra_map.shape
    swin, unet = detectors["swin_unet"], detectors["unet"]
    z = swin.output(frame)
    ref = swin.detect(frame)
    for out in (z, z[:, :h, :w]):
        got = swin.decode(out, frame.ra_map)
        np.testing.assert_array_equal(got.position, ref.position)
        np.testing.assert_array_equal(got.label, ref.label)
    mean = 0.5 * (z[:, :h, :w] + unet.output(frame)[:, :h, :w])
    det = swin.decode(mean, frame.ra_map)
    assert len(det) > 0 and np.all(np.isin(det.label, (0, 1)))
    assert np.all((det.range >= frame.ra_map.range_axis[0]) & (det.range <= frame.ra_map.range_axis[-1]))


@pytest.mark.parametrize("name", ["swin_unet", "unet"])
def test_flip_tta_is_mirror_equivariant_and_refused_for_grid_heads(name):
    """tta = 'flip': the heatmap of the mirrored map is the mirrored heatmap (a plain network's is
    not), and it changes the result; a grid head (rtn) is refused by name."""
    rng = np.random.default_rng(5)
    data = (rng.standard_normal((37, 13)) + 1j * rng.standard_normal((37, 13))) * np.exp(rng.uniform(0, 6, (37, 13)))
    heat = {}
    for tta in ("none", "flip"):
        det = get_registry().create("detector", name, {"device": "cpu", "tta": tta})
        heat[tta] = det.heatmap(_frame(data)), det.heatmap(_frame(data[:, ::-1]))
    np.testing.assert_allclose(heat["flip"][1], heat["flip"][0][:, :, ::-1], atol=1e-6)
    assert np.abs(heat["none"][1] - heat["none"][0][:, :, ::-1]).max() > 1e-3
    assert np.abs(heat["flip"][0] - heat["none"][0]).max() > 1e-3
    with pytest.raises(ConfigError, match="tta = 'flip' needs a dense head"):
        get_registry().create("detector", "rtn", {"tta": "flip"}).detect(_frame(data))
    with pytest.raises(ConfigError, match="tta"):
        get_registry().create("detector", name, {"tta": "rotate"})


def test_rtn_default_grid_holds_one_point_per_resolution_cell():
    """RTN's default grid is no coarser than a radar resolution cell (one range bin; a beam of about
    four azimuth bins): a cloud at that density loses no point to cell sharing; a 2 × 2 grid keeps half."""
    from plugins.detectors.heatmaps import grid_targets
    from plugins.detectors.nets.rtn import RTNParams

    rr, aa = np.meshgrid(np.arange(64), np.arange(0, 64, 4), indexing="ij")
    peaks = np.stack([rr.ravel(), aa.ravel() + 1.3, np.ones(rr.size)], 1)  # mNLOS points, sub-bin azimuth

    def kept(stride):
        return int(grid_targets(peaks, (64, 64), stride)[1].sum())

    assert kept(RTNParams().stride) == rr.size
    assert kept((2, 2)) == rr.size // 2


def test_params_are_validated():
    with pytest.raises(ConfigError, match="device"):
        get_registry().create("detector", "swin_unet", {"device": "gpu0"})
    with pytest.raises(ConfigError, match="window"):
        get_registry().create("detector", "swin_unet", {"window": [2, 3]})
    with pytest.raises(ConfigError, match="threshold"):
        get_registry().create("detector", "swin_unet", {"threshold": 1.5})


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the error on a machine without CUDA")
def test_cuda_device_without_cuda_is_a_clear_error():
    det = get_registry().create("detector", "swin_unet", {"device": "cuda"})
    with pytest.raises(InputError, match="CUDA is not available"):
        det.detect(synthetic_frame(SMALL))


def test_shipped_swin_unet_runs_on_the_corner_scene_deterministically(detectors):
    # Its quality (F1 per class over the test split) is a benchmark figure: benchmarks/detectors.md.
    # Here: the shipped checkpoint fits the default grid (no mismatch warning), two calls agree bit for
    # bit, and its most confident LOS detection is a ground-truth LOS echo (within one range cell).
    import warnings

    from xnlos_core.metrics import thin_to_resolution
    from xnlos_core.scene import load_scene

    radar = RadarConfig()
    frame = get_registry().create("forward_model", "image", {}).simulate(
        load_scene({"builtin": "corner"}, "test"), radar, np.random.default_rng(0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = detectors["swin_unet"].detect(frame)
    b = detectors["swin_unet"].detect(frame)
    np.testing.assert_array_equal(a.range, b.range)
    np.testing.assert_array_equal(a.confidence, b.confidence)
    los = a.label == LOS
    assert los.any()
    top = np.argmax(np.where(los, a.confidence, -1.0))
    gt = thin_to_resolution(frame.ground_truth, radar)
    truth = gt.los_points
    p = a.range[top] * np.array([np.cos(a.azimuth[top]), np.sin(a.azimuth[top])])
    assert np.min(np.linalg.norm(truth - p, axis=1)) < 1.0


def test_swin_unet_decoder_convs_and_checkpoints_made_before_the_field(tmp_path, tiny_checkpoint, tiny_hparams):
    from plugins.detectors.nets.swin_unet import SwinUNet, SwinUNetParams, count_parameters

    base = tiny_hparams["swin_unet"]
    one, two = SwinUNet(SwinUNetParams(**base)), SwinUNet(SwinUNetParams(**base, decoder_convs=2))
    s0, s1 = base["stem_channels"], base["head_channels"]
    # one extra 3×3 conv (no bias) + BatchNorm (weight, bias) at full and at half resolution
    assert count_parameters(two) - count_parameters(one) == 9 * s0 * s0 + 2 * s0 + 9 * s1 * s1 + 2 * s1
    x = torch.randn(1, 4, 8, 8)
    assert two.eval()(x).shape == (1, 2, 8, 8)
    # a checkpoint written before the field existed (no "decoder_convs" in its hparams) loads as 1
    tiny_checkpoint(tmp_path / "a.pt", "swin_unet")
    sd, meta, _ = load_checkpoint(tmp_path / "a.pt")
    del meta["hparams"]["decoder_convs"]
    save_checkpoint(tmp_path / "old.pt", sd, {k: v for k, v in meta.items() if k != "weights_sha256"})
    det = get_registry().create("detector", "swin_unet", {"checkpoint": str(tmp_path / "old.pt"), "device": "cpu"})
    new = get_registry().create("detector", "swin_unet", {"checkpoint": str(tmp_path / "a.pt"), "device": "cpu"})
    frame = synthetic_frame(SMALL)
    assert det.metadata["hparams"].get("decoder_convs", 1) == 1
    np.testing.assert_array_equal(det.output(frame), new.output(frame))  # the same network, read as before
    a, b = det.detect(frame), new.detect(frame)
    np.testing.assert_array_equal(a.range, b.range)
    np.testing.assert_array_equal(a.label, b.label)


def test_swin_unet_mlp_conv_adds_one_local_depthwise_conv_per_block(tiny_hparams):
    from plugins.detectors.nets.swin_unet import MixMLP, SwinUNet, SwinUNetParams, count_parameters

    base = tiny_hparams["swin_unet"]
    plain, mixed = SwinUNet(SwinUNetParams(**base)), SwinUNet(SwinUNetParams(**base, mlp_conv=True))
    hp = plain.hp
    # encoder stages and the decoder stages below the bottleneck; a 3×3 depthwise conv with bias
    hidden = [int(hp.embed_dim * 2**i * hp.mlp_ratio) for i in range(len(hp.depths))]
    blocks = [(d, h) for d, h in zip(hp.depths, hidden)] + [(d, h) for d, h in zip(hp.depths[:-1], hidden)]
    assert count_parameters(mixed) - count_parameters(plain) == sum(d * 10 * h for d, h in blocks)
    assert mixed.eval()(torch.randn(1, 4, 8, 12)).shape == (1, 2, 8, 12)
    # an impulse at one token changes the MLP's output on exactly its 3 × 3 neighbourhood
    mlp = MixMLP(4, 8).eval()
    x = torch.randn(1, 7, 9, 4)
    x2 = x.clone()
    x2[0, 3, 4] += 1.0
    with torch.no_grad():
        changed = (mlp(x2) - mlp(x)).abs().amax(-1)[0] > 1e-7
    assert changed.nonzero().tolist() == [[i, j] for i in (2, 3, 4) for j in (3, 4, 5)]


def test_swin_unet_stem_levels_put_conv_levels_below_the_patch_embedding(tmp_path, tiny_checkpoint, tiny_hparams):
    from plugins.detectors.nets.swin_unet import SwinUNet, SwinUNetParams

    base = tiny_hparams["swin_unet"]
    with pytest.raises(ValueError, match="multiple of 4"):
        SwinUNetParams(**base, stem_levels=3)  # patch (2, 2) cannot sit on a 1/4-resolution stem
    two = SwinUNet(SwinUNetParams(**base))
    three = tiny_checkpoint(tmp_path / "three.pt", "swin_unet", patch=(4, 4), stem_levels=3)
    top = {net: {k.split(".")[0] for k in net.state_dict()} for net in (two, three)}
    # two levels keep the module names of the checkpoints made before the field; three add one level
    assert {"stem0", "stem1", "up0", "fuse0", "fuse1"} <= top[two] and not top[two] & {"stem2", "up1", "fuse2"}
    assert top[three] - top[two] == {"stem2", "up1", "fuse2"}
    seen = {}
    for name in ("stem2", "embed"):
        getattr(three, name).register_forward_hook(lambda m, i, o, name=name: seen.update({name: tuple(o.shape)}))
    assert three.multiple == (8, 8)
    assert three.eval()(torch.randn(1, 4, 16, 24)).shape == (1, 2, 16, 24)
    hc, c = base["head_channels"], base["embed_dim"]
    assert seen == {"stem2": (1, 2 * hc, 4, 6), "embed": (1, c, 4, 6)}  # 1/4 resolution, 2 · head_channels
    # the detector pads any map to the multiple (8, 8) and crops back
    det = get_registry().create("detector", "swin_unet", {"checkpoint": str(tmp_path / "three.pt"), "device": "cpu"})
    frame = _frame(np.random.default_rng(0).normal(size=(37, 13)) + 1j)
    assert det.output(frame).shape == (2, 40, 16)
    assert det.heatmap(frame).shape == (2, 37, 13)
    out = det.detect(frame)
    ra = frame.ra_map
    assert np.all((out.range >= ra.range_axis[0]) & (out.range <= ra.range_axis[-1]))
    assert np.all((out.azimuth >= ra.azimuth_axis[0]) & (out.azimuth <= ra.azimuth_axis[-1]))
