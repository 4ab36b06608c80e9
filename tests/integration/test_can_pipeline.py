"""The `can` and `replay` backends in pipelines, the conformance kit, configs and `xnlos emulate`."""
from pathlib import Path

import numpy as np

from hardware.replay import ReplayBackend
from hardware.testing import private_channel
from xnlos_core.app.cli import main
from xnlos_core.config import load_pipeline, parse_pipeline
from xnlos_core.pipeline import Pipeline
from xnlos_core.radar import RadarConfig
from xnlos_core.testing import check_component, small_pipeline_table

ROOT = Path(__file__).resolve().parents[2]
RADAR = {"n_samples": 128, "max_range": 30.0, "n_azimuth_bins": 41}
WALLS = [[15.0, 10.0, 35.0, -10.0], [5.0, -4.0, 18.0, -4.0], [18.0, -4.0, 18.0, -30.0]]  # built-in corner


def table(source: dict) -> dict:
    t = small_pipeline_table(radar=RADAR, run={"frames": 3, "figure": False, "frame_interval": 0.1},
                    detector={"name": "nlos_cfar", "params": {"wall_source": "config", "walls": WALLS}})
    if "backend" in source:
        del t["forward_model"]
    t.update(source)
    return t


def run(t):
    pipe = Pipeline(parse_pipeline(t, "test"))
    return list(pipe.run())


def test_can_and_replay_swap_with_the_simulator(tmp_path):
    log = tmp_path / "hil.blf"
    sim = run(table({}))
    hil = run(table({"backend": {"name": "can", "params": {
        "channel": private_channel(), "frame_interval": 0.1, "record": str(log),
        "emulator": {"seed": 5, "pace": False, "scene": {"builtin": "corner"}}}}}))
    rep = run(table({"backend": {"name": "replay", "params": {"file": str(log)}}}))
    assert len(sim) == len(hil) == len(rep) == 3
    for a, b, c in zip(sim, hil, rep):
        assert np.array_equal(a.frame.ra_map.data, b.frame.ra_map.data)
        assert np.array_equal(b.frame.ra_map.data, c.frame.ra_map.data)
        assert a.frame.timestamp == b.frame.timestamp == c.frame.timestamp
        for x in (b, c):
            assert np.array_equal(a.detections.range, x.detections.range)
            assert np.array_equal(a.detections.label, x.detections.label)
            assert np.array_equal(a.hidden.mean, x.hidden.mean)
        assert "source" in b.timings


def test_can_backend_with_adc_payload_passes_the_conformance_kit():
    # The defaults (RA payload) and a replayed recording run the kit in test_conformance.py.
    check_component("backend", "can", {"channel": private_channel(), "payload": "adc_int16",
                                       "emulator": {"pace": False}})


def test_shipped_configs_are_valid():
    for name in ("can_hil.toml", "replay.toml"):
        cfg = load_pipeline(ROOT / "configs" / "pipelines" / name)
        Pipeline(cfg, source=name)  # plugins and parameters validate; nothing is opened
    assert cfg.backend.name == "replay"


def test_cli_emulate_streams_and_records(tmp_path, capsys):
    cfg = tmp_path / "hil.toml"
    cfg.write_text(
        'seed = 3\n[radar]\nn_samples = 128\nmax_range = 20.0\nn_azimuth_bins = 31\n'
        '[scene]\nbuiltin = "corner"\n[forward_model]\nname = "image"\n'
        '[detector]\nname = "cfar"\n[wall_estimator]\nname = "lsq"\n[reconstructor]\nname = "mirror"\n'
        '[run]\nframes = 2\nframe_interval = 0.05\n')
    log = tmp_path / "emu.asc"
    rc = main(["emulate", "--channel", private_channel(), "--config", str(cfg), "--frames", "2", "--fast",
               "--record", str(log)])
    out = capsys.readouterr().out
    assert rc == 0 and "frame     1" in out and "ok=2" in out and "2 frame(s) sent" in out
    radar = RadarConfig(n_samples=128, max_range=20.0, n_azimuth_bins=31)
    b = ReplayBackend({"file": str(log)})
    b.open(radar)
    assert [f.index for f in b.frames()] == [0, 1]
    rc = main(["emulate", "--interface", "nosuchcan", "--config", str(cfg), "--frames", "1"])
    assert rc == 2 and "nosuchcan" in capsys.readouterr().err


def test_in_process_emulator_frames_carry_ground_truth_and_metrics():
    t = small_pipeline_table(run={"frames": 2, "figure": False})  # nlos_cfar with ground-truth walls, as in simulation
    del t["forward_model"]
    t["backend"] = {"name": "can", "params": {"channel": private_channel(), "emulator": {"seed": 5, "pace": False}}}
    hil = run(t)
    sim = run(small_pipeline_table(run={"frames": 2, "figure": False}))
    for a, b in zip(sim, hil):
        assert b.frame.meta["ground_truth"] == "emulator"
        assert np.array_equal(a.frame.ground_truth.hidden_points, b.frame.ground_truth.hidden_points)
        assert a.record()["metrics"] == b.record()["metrics"] and b.record()["metrics"]
