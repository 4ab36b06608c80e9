"""Models that know their array: a learned detector compares the radar its checkpoint was trained on
(carrier, bandwidth, virtual array, grid) with the radar of the maps it will see before the first
frame, so ``xnlos check`` and warm-up refuse a mismatch; ``allow_mismatch`` runs anyway, warns, and
the run's provenance records it."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from plugins.training.trained_on import (grid_record, map_mismatches, radar_mismatches, recorded_array,
                                         read_sidecar)
from xnlos_core.app.cli import main
from xnlos_core.config import parse_pipeline
from xnlos_core.errors import ConfigError, GridMismatchWarning, InputError
from xnlos_core.pipeline import Pipeline
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.signal.antenna import virtual_layout
from xnlos_core.testing import small_pipeline_table
from xnlos_core.types import Frame, RAMap

SMALL = RadarConfig(n_samples=128, max_range=30.0, n_azimuth_bins=31)
BOARD = SMALL.model_copy(update={"n_tx": 3, "n_rx": 4})  # a 3 TX × 4 RX board, same waveform and grid


def _map(radar: RadarConfig) -> RAMap:
    shape = (radar.n_range_bins, radar.n_azimuth_bins)
    return RAMap.from_radar(np.ones(shape, np.complex64), radar)


def test_radar_mismatches_name_each_item_with_both_values():
    rec = grid_record(_map(SMALL), "test")
    assert np.array_equal(rec["virtual_array"], virtual_layout(SMALL).tolist())
    assert radar_mismatches(rec, SMALL) == [] and map_mismatches(rec, _map(SMALL)) == []
    (arr,) = radar_mismatches(rec, BOARD)
    assert arr == "virtual array 32 channels, y 0…15.5 λ, z 0 λ trained, 12 channels, y 0…5.5 λ, z 0 λ here"
    assert map_mismatches(rec, _map(BOARD)) == [arr]  # per frame as well
    # a raised transmitter is another array even with the same channel count and y extent
    raised = SMALL.model_copy(update={"tx_elevation_offset": 0.5})
    assert radar_mismatches(rec, raised) == ["virtual array 32 channels, y 0…15.5 λ, z 0 λ trained, "
                                             "32 channels, y 0…15.5 λ, z 0.5 λ here"]
    other = SMALL.model_copy(update={"carrier_frequency": 77e9, "bandwidth": 300e6})
    got = radar_mismatches(rec, other)
    assert got[0] == "carrier 10 GHz trained, 77 GHz here" and got[1] == "bandwidth 600 MHz trained, 300 MHz here"
    assert any(p.startswith("range spacing") for p in got) and not any("virtual array" in p for p in got)


def test_array_compared_as_a_set_of_positions():
    """Another channel order or a shift of the whole array makes the same maps: not a mismatch."""
    rec = grid_record(_map(BOARD), "test")
    shifted = BOARD.model_copy(update={"tx_positions": ((3.0, 0.0), (5.0, 0.0), (7.0, 0.0)),
                                       "rx_positions": ((1.5, 0.0), (0.5, 0.0), (1.0, 0.0), (0.0, 0.0))})
    assert radar_mismatches(rec, shifted) == []
    wider = BOARD.model_copy(update={"rx_spacing": 0.6})
    assert radar_mismatches(rec, wider)[0].startswith("virtual array 12 channels, y 0…5.5 λ")


def test_shipped_record_gives_its_array_from_its_radar():
    """The shipped sidecars predate ``virtual_array``: the array comes from the recorded radar (4 × 8 at λ/2)."""
    from plugins.detectors.learned import MODELS_DIR

    meta = json.loads((MODELS_DIR / "swin_unet.json").read_text())
    rec = read_sidecar(MODELS_DIR / "swin_unet.pt", meta["weights_sha256"])
    assert "virtual_array" not in rec
    arr = recorded_array(rec)
    assert arr.shape == (32, 2) and np.allclose(np.sort(arr[:, 0]), 0.5 * np.arange(32)) and not arr[:, 1].any()


@pytest.fixture
def recorded_model(tmp_path, tiny_checkpoint):
    path = tmp_path / "m.pt"
    tiny_checkpoint(path, "further_than_cfar", extra_meta={"trained_on": grid_record(_map(SMALL), "a test radar")})

    def make(**params):
        return get_registry().create("detector", "further_than_cfar", {"checkpoint": str(path), "device": "cpu",
                                                                       **params})
    return make


def test_check_model_refuses_unless_allowed_then_warns_once(recorded_model):
    assert recorded_model().check_model(SMALL) == []
    with pytest.raises(ConfigError, match=r"virtual array 32 channels.*trained, 12 channels.*here.*allow_mismatch"):
        recorded_model().check_model(BOARD)
    det = recorded_model(allow_mismatch=True)
    with pytest.warns(GridMismatchWarning, match=r"\(allow_mismatch = true\): virtual array") as rec:
        assert det.check_model(BOARD) == [radar_mismatches(grid_record(_map(SMALL), "x"), BOARD)[0]]
        det.check_model(BOARD)
    assert len([w for w in rec if w.category is GridMismatchWarning]) == 1
    with warnings.catch_warnings():  # frames of the radar accepted before the run are not compared again
        warnings.simplefilter("error", GridMismatchWarning)
        det.detect(Frame(_map(BOARD)))


def test_frames_of_an_unchecked_radar_compare_the_array(recorded_model):
    with pytest.warns(GridMismatchWarning, match="virtual array 32 channels"):
        recorded_model().detect(Frame(_map(BOARD)))
    with pytest.raises(InputError, match="virtual array.*strict = true"):
        recorded_model(strict=True).detect(Frame(_map(BOARD)))
    with pytest.warns(GridMismatchWarning):  # allowed: strict does not refuse it
        recorded_model(strict=True, allow_mismatch=True).detect(Frame(_map(BOARD)))


def test_pipeline_checks_the_recordings_radar_not_its_own(tmp_path, recorded_model):
    """With ``[backend] adc`` the maps are the recording's: a 3 × 4 recording is refused by check_inputs
    (what ``xnlos check`` runs) and warm-up, although the pipeline's [radar] is the model's."""
    from hardware.testing import make_adc_recording

    rec = make_adc_recording(tmp_path / "adc", BOARD.model_copy(update={"n_chirps": 2}), frames=1)
    ckpt = recorded_model().params.checkpoint
    table = small_pipeline_table(radar=SMALL.model_dump(mode="json"), backend={"name": "adc",
                                 "params": {"recording": str(rec)}},
                                 detector={"name": "further_than_cfar", "params": {"checkpoint": ckpt,
                                                                                   "device": "cpu"}})
    for key in ("forward_model", "scene", "wall_estimator", "reconstructor"):
        table.pop(key)
    pipe = Pipeline(parse_pipeline(table, "t"))
    assert pipe.frame_radar.n_channels == 12 and pipe.radar.n_channels == 32
    with pytest.raises(ConfigError, match="virtual array 32 channels.*12 channels"):
        pipe.check_inputs()
    with pytest.raises(ConfigError, match="virtual array"):
        pipe.warm_up()
    table["detector"]["params"]["allow_mismatch"] = True
    with pytest.warns(GridMismatchWarning):
        prov = Pipeline(parse_pipeline(table, "t")).provenance()
    assert prov["accepted_mismatch"]["detector"][0].startswith("virtual array 32 channels")


def test_shipped_swin_unet_on_a_3x4_board(tmp_path, capsys):
    """Acceptance: ``xnlos check`` exits non-zero naming the array; with the override the run goes and
    its provenance lists the differences."""
    cfg = tmp_path / "board.toml"
    base = ('name = "board"\nseed = 0\n[radar]\nn_tx = 3\nn_rx = 4\n{grid}[scene]\nbuiltin = "corner"\n'
            '[forward_model]\nname = "image"\n[detector]\nname = "swin_unet"\nparams = {{ device = "cpu"{extra} }}\n'
            '[run]\nframes = 1\nfigure = false\n')
    cfg.write_text(base.format(grid="", extra=""))
    capsys.readouterr()
    assert main(["check", str(cfg)]) != 0
    err = capsys.readouterr().err
    assert "virtual array 32 channels, y 0…15.5 λ, z 0 λ trained, 12 channels, y 0…5.5 λ, z 0 λ here" in err
    assert "allow_mismatch" in err and "range" not in err.split("trained on another radar")[1].split(".")[0]
    # the override, on a smaller grid to keep the run short (the grid is then listed too)
    cfg.write_text(base.format(grid="n_samples = 128\nmax_range = 30.0\nn_azimuth_bins = 31\n",
                               extra=", allow_mismatch = true"))
    assert main(["run", str(cfg), "--out", str(tmp_path / "out"), "-q"]) == 0
    assert "warning: SwinUNetDetector (checkpoint 'default') runs on another radar" in capsys.readouterr().err
    prov = json.loads((tmp_path / "out" / "provenance.json").read_text())
    got = prov["accepted_mismatch"]["detector"]
    assert got[0].startswith("virtual array 32 channels") and any("range bins" in p for p in got)
    assert prov["plugins"]["detector"]["params"]["allow_mismatch"] is True


@pytest.mark.parametrize("radar, named", [
    ({"carrier_frequency": 77e9}, "carrier 10 GHz trained, 77 GHz here"),   # refused by check, not only by run
    ({"n_tx": 2, "n_rx": 4}, "virtual array 32 channels, y 0…15.5 λ, z 0 λ trained, 8 channels"),
])
def test_check_refuses_what_a_strict_run_refused(tmp_path, capsys, radar, named):
    cfg = tmp_path / "c.toml"
    lines = "".join(f"{k} = {v!r}\n" for k, v in radar.items())
    cfg.write_text(f'name = "c"\n[radar]\n{lines}[scene]\nbuiltin = "corner"\n[forward_model]\nname = "image"\n'
                   '[detector]\nname = "swin_unet"\nparams = { device = "cpu", strict = true }\n')
    capsys.readouterr()
    assert main(["check", str(cfg)]) == 2
    assert named in capsys.readouterr().err
