"""Self-describing models: a checkpoint records the radar and RA grid it was
trained on, and a learned detector warns (or, strict, refuses) on maps of another carrier or grid."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from plugins.detectors.learned import LEARNED, MODELS_DIR
from plugins.training.checkpoint import load_checkpoint
from plugins.training.trained_on import (grid_mismatches, grid_record, read_sidecar, sidecar_path,
                                         write_sidecar)
from xnlos_core.errors import GridMismatchWarning, InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.testing import synthetic_frame
from xnlos_core.types import Frame, RAMap

SMALL = RadarConfig(n_samples=128, max_range=30.0, n_azimuth_bins=31)


def _map(radar: RadarConfig) -> RAMap:
    rng = np.random.default_rng(0)
    shape = (radar.n_range_bins, radar.n_azimuth_bins)
    return RAMap.from_radar((rng.standard_normal(shape) + 1j * rng.standard_normal(shape)).astype(np.complex64), radar)


def test_mismatches_name_carrier_bins_spacing_and_field_of_view():
    rec = grid_record(_map(SMALL), "test")
    assert grid_mismatches(rec, _map(SMALL)) == []
    assert grid_mismatches(json.loads(json.dumps(rec)), _map(SMALL)) == []  # survives JSON
    (carrier,) = grid_mismatches(rec, _map(SMALL.model_copy(update={"carrier_frequency": 77e9})))
    assert "10 GHz trained" in carrier and "77 GHz here" in carrier
    bins = grid_mismatches(rec, _map(SMALL.model_copy(update={"n_azimuth_bins": 121})))
    assert "31 azimuth bins trained, 121 here" in bins and any("azimuth spacing" in p for p in bins)
    fov = grid_mismatches(rec, _map(SMALL.model_copy(update={"field_of_view": np.radians(45)})))
    assert any("azimuth extent -60…60 ° trained, -45…45 ° here" in p for p in fov)
    rng = grid_mismatches(rec, _map(SMALL.model_copy(update={"bandwidth": 300e6})))
    assert any("range spacing" in p for p in rng)
    # a map cropped in range keeps its spacing but not its extent
    m = _map(SMALL)
    cropped = RAMap(m.data[:50], m.range_axis[:50], m.azimuth_axis, SMALL)
    assert grid_mismatches(rec, cropped) and not any("spacing" in p for p in grid_mismatches(rec, cropped))


def test_a_checkpoint_on_a_mismatched_grid_warns(tmp_path, tiny_checkpoint):
    """Acceptance: warns once per detector instance, naming both grids; strict refuses."""
    tiny_checkpoint(tmp_path / "m.pt", "further_than_cfar",
                    extra_meta={"trained_on": grid_record(_map(SMALL), "a 31-bin test radar")})
    make = lambda **p: get_registry().create("detector", "further_than_cfar",  # noqa: E731
                                             {"checkpoint": str(tmp_path / "m.pt"), "device": "cpu", **p})
    det = make()
    assert det.metadata["trained_on"]["azimuth_axis"]["n"] == 31
    with warnings.catch_warnings():
        warnings.simplefilter("error", GridMismatchWarning)
        det.detect(Frame(_map(SMALL)))  # the grid it was trained on: silent
    other = SMALL.model_copy(update={"n_azimuth_bins": 21, "carrier_frequency": 77e9})
    with pytest.warns(GridMismatchWarning) as rec:
        det.detect(Frame(_map(other)))
        det.detect(Frame(_map(other)))
    assert len([w for w in rec if w.category is GridMismatchWarning]) == 1  # once per instance
    msg = str(rec[0].message)
    assert "10 GHz, 121 × 31 cells" in msg and "77 GHz, 121 × 21 cells" in msg and "31 azimuth bins" in msg
    with pytest.warns(GridMismatchWarning):
        make().detect(Frame(_map(other)))  # a new instance warns again
    with pytest.raises(InputError, match="77 GHz here.*strict = true"):
        make(strict=True).detect(Frame(_map(other)))
    make(strict=True).detect(Frame(_map(SMALL)))


def test_checkpoint_without_a_record_is_not_checked(tmp_path, tiny_checkpoint):
    tiny_checkpoint(tmp_path / "m.pt", "further_than_cfar")
    det = get_registry().create("detector", "further_than_cfar",
                                {"checkpoint": str(tmp_path / "m.pt"), "device": "cpu", "strict": True})
    assert "trained_on" not in det.metadata
    det.detect(synthetic_frame(SMALL))


def test_sidecar_record_is_bound_to_the_weights(tmp_path, tiny_checkpoint):
    tiny_checkpoint(tmp_path / "m.pt", "further_than_cfar")
    _, meta, _ = load_checkpoint(tmp_path / "m.pt")
    write_sidecar(tmp_path / "m.pt", meta["weights_sha256"], grid_record(_map(SMALL), "sidecar"))
    assert sidecar_path(tmp_path / "m.pt").name == "m.trained_on.json"
    det = get_registry().create("detector", "further_than_cfar", {"checkpoint": str(tmp_path / "m.pt"),
                                                                  "device": "cpu", "strict": True})
    assert det.metadata["trained_on"]["source"] == "sidecar"
    with pytest.raises(InputError, match="carrier"):
        det.detect(Frame(_map(SMALL.model_copy(update={"carrier_frequency": 24e9}))))
    write_sidecar(tmp_path / "m.pt", "0" * 64, grid_record(_map(SMALL), "other weights"))
    with pytest.raises(InputError, match="m.trained_on.json: describes weights 000000000000"):
        read_sidecar(tmp_path / "m.pt", meta["weights_sha256"])


@pytest.mark.parametrize("name", sorted(LEARNED))
def test_shipped_models_record_the_default_dataset_radar(name):
    """The shipped models' records (sidecars, their .pt unchanged) hold the radar of
    configs/datasets/default.toml, the dataset whose config digest their metadata names."""
    from sims.dataset import load_dataset_config
    from sims.dataset.config import resolve

    cfg = resolve(load_dataset_config("configs/datasets/default.toml"), "default.toml")
    _, meta, _ = load_checkpoint(MODELS_DIR / f"{name}.pt", name)
    assert "trained_on" not in meta and meta["training"]["dataset"]["config_sha256"] == cfg.digest()
    rec = read_sidecar(MODELS_DIR / f"{name}.pt", meta["weights_sha256"])
    radar = RadarConfig.model_validate(cfg.radar)
    assert rec["radar"] == radar.model_dump(mode="json")
    assert rec["range_axis"]["n"] == 401 and rec["azimuth_axis"]["n"] == 121
    assert grid_mismatches(rec, _map(radar)) == []
    smoke = radar.model_copy(update={"n_azimuth_bins": 31})  # the smoke dataset's grid
    assert any("121 azimuth bins trained, 31 here" in p for p in grid_mismatches(rec, _map(smoke)))


@pytest.mark.parametrize("dataset", ["sequences_64chirps", "sequences_large_64chirps"])
def test_sequence_model_records_the_sequence_datasets_radar(dataset):
    """swin_unet_sequences64.pt, the detector of the tracking ablation's swin_unet cases, was fine-tuned on
    the train split of sequences_large_64chirps.toml (its metadata names that config's digest) and records
    that radar's grid, which the default sequence dataset shares: no grid warning on either's maps, one on
    the Table 2 dataset's 401 range bins."""
    from sims.dataset import load_dataset_config
    from sims.dataset.config import resolve

    def radar_of(name):
        cfg = resolve(load_dataset_config(f"configs/datasets/{name}.toml"), f"{name}.toml")
        return cfg, RadarConfig.model_validate(cfg.radar)

    _, meta, _ = load_checkpoint(MODELS_DIR / "swin_unet_sequences64.pt", "swin_unet")
    rec = meta["trained_on"]
    _, radar = radar_of(dataset)
    assert rec["radar"] == radar.model_dump(mode="json") and radar.n_chirps == 64
    assert grid_mismatches(rec, _map(radar)) == []
    assert meta["training"]["dataset"]["config_sha256"] == radar_of("sequences_large_64chirps")[0].digest()
    assert meta["training"]["dataset"]["init"]["weights_sha256"] == load_checkpoint(MODELS_DIR / "swin_unet.pt",
                                                                                    "swin_unet")[1]["weights_sha256"]
    assert any("241 range bins trained, 401 here" in m for m in grid_mismatches(rec, _map(radar_of("default")[1])))
    from plugins.detectors.train_config import load_train_config  # and its training config is the one in the repo

    assert load_train_config(meta["training"]["config_file"]).digest() == meta["training"]["config_sha256"]


def test_shipped_model_warns_on_a_77_ghz_map():
    det = get_registry().create("detector", "further_than_cfar", {"device": "cpu"})
    radar = SMALL.model_copy(update={"carrier_frequency": 77e9})
    with pytest.warns(GridMismatchWarning, match="trained on 10 GHz, 401 × 121 cells.*77 GHz here"):
        det.detect(Frame(_map(radar)))
