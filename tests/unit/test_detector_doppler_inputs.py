"""Doppler input channels of the learned detectors: the features against hand-computed values, a
model that wants them refuses a map without Doppler, and widening a trained network's inputs keeps
its outputs (fine-tuning starts from the parent)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from plugins.detectors.features import (DOPPLER_CHANNELS, RA_CHANNELS, doppler_features, map_features,
                                        ra_features)
from plugins.detectors.train import features_record, widened_inputs
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.testing import synthetic_frame
from xnlos_core.types import Frame, RAMap

pytestmark = pytest.mark.filterwarnings("ignore::xnlos_core.errors.GridMismatchWarning")

SMALL = RadarConfig(n_samples=128, max_range=30.0, n_azimuth_bins=31, n_chirps=16)


def _doppler_map(velocity: np.ndarray, power: np.ndarray, std: float = 0.05) -> RAMap:
    h, w = power.shape
    data = np.sqrt(power).astype(np.complex64)
    return RAMap(data, np.linspace(0.0, 0.25 * (h - 1), h), np.linspace(-1.0, 1.0, w), SMALL,
                 velocity, np.full((h, w), std))


def test_doppler_channels_match_their_closed_forms():
    vmax, dv = SMALL.max_unambiguous_velocity, SMALL.velocity_resolution
    power = np.ones((12, 10))
    power[2:7, 2:7] = 1e4                      # one strong reflector, 5 × 5 cells
    v = np.random.default_rng(0).uniform(-vmax, vmax, power.shape)  # noise cells: random bins
    v[2:7, 2:7] = 0.4 * vmax
    f = doppler_features(_doppler_map(v, power, std=dv), ra_features(power.astype(np.complex64))[0])
    assert f.shape == (3, 12, 10) and f.dtype == np.float32
    np.testing.assert_allclose(f[0, 2:7, 2:7], 0.4, atol=1e-6)          # v / v_max on the echo
    assert np.all(f[:, :2] == 0) and np.all(f[:, 8:] == 0)              # noise (ℓ ≤ 0): nothing
    np.testing.assert_allclose(f[1, 2:7, 2:7], 0.75, atol=1e-6)         # σ_v = Δv → (0 + 3) / 4
    np.testing.assert_allclose(f[2, 3:6, 3:6], 0.0, atol=1e-6)          # one velocity: no spread
    # half the neighbourhood static, half at v_max/2: |(1 + j)/2|·… → 1 − |Σw e^{jθ}|/Σw, closed form
    v2 = v.copy()
    v2[2:7, 2:4] = 0.0
    v2[2:7, 4:7] = 0.5 * vmax
    g = doppler_features(_doppler_map(v2, power), ra_features(power.astype(np.complex64))[0])
    w0, w1 = 3.0, 6.0                            # cell (4, 4): columns 3 (static) and 4, 5 (moving), 3 rows
    assert g[2, 4, 4] == pytest.approx(1.0 - abs(w0 + w1 * 1j) / (w0 + w1), abs=1e-6)


def test_the_spread_does_not_see_a_fold():
    vmax = SMALL.max_unambiguous_velocity
    power = np.ones((9, 9))
    power[2:7, 2:7] = 1e4
    v = np.zeros(power.shape)
    v[2:7, 2:7] = 0.3 * vmax
    folded = v.copy()
    folded[2:7, 4:7] = 0.3 * vmax - 2 * vmax   # the same velocity, one fold apart
    level = ra_features(power.astype(np.complex64))[0]
    a = doppler_features(_doppler_map(v, power), level)
    b = doppler_features(_doppler_map(folded, power), level)
    np.testing.assert_allclose(a[2], b[2], atol=1e-6)


def test_a_doppler_model_refuses_a_map_without_doppler_with_a_clear_error():
    frame = synthetic_frame(SMALL)
    assert frame.ra_map.velocity is None
    with pytest.raises(InputError, match=r"Doppler channels.*RAMap.velocity is None.*doppler = true"):
        map_features(frame.ra_map, RA_CHANNELS + DOPPLER_CHANNELS)
    with pytest.raises(ConfigError, match="other inputs"):
        map_features(frame.ra_map, ("log_power_10db_over_median", "elevation"))
    np.testing.assert_array_equal(map_features(frame.ra_map), ra_features(frame.ra_map.data))


def _doppler_checkpoint(path, tiny_checkpoint):
    from plugins.training.checkpoint import load_checkpoint, save_checkpoint

    tiny_checkpoint(path, "swin_unet", in_channels=7)
    sd, meta, _ = load_checkpoint(path)
    meta = {k: v for k, v in meta.items() if k != "weights_sha256"}
    save_checkpoint(path, sd, {**meta, "features": features_record(RA_CHANNELS + DOPPLER_CHANNELS)})


def test_a_detector_with_doppler_inputs_runs_on_doppler_maps_only(tmp_path, tiny_checkpoint):
    _doppler_checkpoint(tmp_path / "d.pt", tiny_checkpoint)
    det = get_registry().create("detector", "swin_unet", {"checkpoint": str(tmp_path / "d.pt"), "device": "cpu"})
    assert det.needs_doppler and det.input_channels == RA_CHANNELS + DOPPLER_CHANNELS
    frame = synthetic_frame(SMALL)
    with pytest.raises(InputError, match=r"SwinUNetDetector \(checkpoint .*d\.pt'\) on frame 0.*Doppler channels"):
        det.detect(frame)
    m = frame.ra_map
    moving = dataclasses.replace(m, velocity=np.full(m.shape, 3.0), velocity_std=np.full(m.shape, 0.1))
    det.warm_up(SMALL)
    out = det.detect(Frame(moving, index=0))
    assert out.velocity is not None                        # read off the Doppler map as for any detector


def test_a_shipped_model_is_chosen_by_name_and_a_wrong_name_gets_the_choices():
    det = get_registry().create("detector", "swin_unet", {"model": "swin_unet_sequences64", "device": "cpu"})
    import json

    from plugins.detectors.learned import MODELS_DIR

    side = json.loads((MODELS_DIR / "swin_unet_sequences64.json").read_text())
    assert det.state_sha256() == side["weights_sha256"] and not det.needs_doppler
    with pytest.raises(ConfigError, match="did you mean 'swin_unet_sequences64'"):
        get_registry().create("detector", "swin_unet", {"model": "swin_unet_sequence64"}).metadata
    with pytest.raises(ConfigError, match="not both"):
        get_registry().create("detector", "swin_unet", {"model": "swin_unet", "checkpoint": "none"})


def test_widened_inputs_start_as_the_parent_network(tiny_hparams):
    from plugins.detectors.nets.swin_unet import SwinUNet, SwinUNetParams

    torch.manual_seed(0)
    parent = SwinUNet(SwinUNetParams(**tiny_hparams["swin_unet"])).eval()
    child = SwinUNet(SwinUNetParams(**{**tiny_hparams["swin_unet"], "in_channels": 7})).eval()
    child.load_state_dict(widened_inputs(parent.state_dict(), child.state_dict(), 4))
    x = torch.randn(1, 7, *parent.multiple)
    with torch.inference_mode():
        np.testing.assert_allclose(child(x).numpy(), parent(x[:, :4]).numpy(), atol=1e-5)
    bad = {k: (v[:, :2] if v.ndim == 4 and v.shape[1] == 4 else v) for k, v in parent.state_dict().items()}
    with pytest.raises(InputError, match="do not fit"):
        widened_inputs(bad, child.state_dict(), 4)


def test_previous_frames_repeat_the_oldest_there_is_and_a_detector_resets_them(tmp_path, tiny_checkpoint):
    from plugins.detectors.features import channel_layout, previous_channels
    from plugins.training.checkpoint import load_checkpoint, save_checkpoint

    frames = [synthetic_frame(SMALL, seed=s) for s in range(3)]
    levels = [ra_features(f.ra_map.data)[0] for f in frames]
    layout = channel_layout(False, 2)
    assert layout[4:] == previous_channels(2) == ("log_power_prev1", "log_power_prev2")
    alone = map_features(frames[0].ra_map, layout)                  # no history: the frame's own, twice
    np.testing.assert_array_equal(alone[4], levels[0])
    np.testing.assert_array_equal(alone[5], levels[0])
    one = map_features(frames[1].ra_map, layout, previous=[levels[0]])
    np.testing.assert_array_equal(one[4], levels[0])
    np.testing.assert_array_equal(one[5], levels[0])
    two = map_features(frames[2].ra_map, layout, previous=[levels[1], levels[0]])
    np.testing.assert_array_equal(two[4], levels[1])
    np.testing.assert_array_equal(two[5], levels[0])
    with pytest.raises(ConfigError, match="previous frames"):
        channel_layout(False, 5)

    tiny_checkpoint(tmp_path / "p.pt", "swin_unet", in_channels=6)
    sd, meta, _ = load_checkpoint(tmp_path / "p.pt")
    meta = {k: v for k, v in meta.items() if k != "weights_sha256"}
    save_checkpoint(tmp_path / "p.pt", sd, {**meta, "features": features_record(layout)})
    det = get_registry().create("detector", "swin_unet", {"checkpoint": str(tmp_path / "p.pt"), "device": "cpu"})
    assert det.previous_frames == 2 and det.carries_state
    first = det.output(frames[0])
    det.output(frames[1])
    det.reset()
    np.testing.assert_array_equal(det.output(frames[0]), first)   # after a reset: as the first frame
    plain = get_registry().create("detector", "swin_unet", {"checkpoint": "none", "device": "cpu"})
    assert not plain.carries_state


def test_the_shipped_doppler_model_records_its_inputs_and_refuses_a_map_without_doppler():
    from plugins.detectors.learned import MODELS_DIR
    from plugins.training.checkpoint import load_checkpoint

    _, meta, _ = load_checkpoint(MODELS_DIR / "swin_unet_doppler.pt", "swin_unet")
    assert tuple(meta["features"]["channels"]) == RA_CHANNELS + DOPPLER_CHANNELS
    assert meta["hparams"]["in_channels"] == 7
    assert meta["training"]["command"].startswith("xnlos train configs/training/swin_unet_doppler.toml")
    radar = RadarConfig(**{k: v for k, v in meta["trained_on"]["radar"].items() if v is not None})
    det = get_registry().create("detector", "swin_unet", {"model": "swin_unet_doppler", "device": "cpu"})
    assert det.needs_doppler and not det.carries_state
    with pytest.raises(InputError, match=r"model 'swin_unet_doppler'.*Doppler channels.*RAMap.velocity is None"):
        det.detect(synthetic_frame(radar))
