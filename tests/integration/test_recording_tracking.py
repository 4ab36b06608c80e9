"""A raw recording through a whole pipeline: ``[backend] adc`` → CFAR → tracker, with no reconstructor.

A synthetic DCA1000 capture (written by the test) of a road user in plain view receding at a known
radial velocity and a static reflector: the detections in results.jsonl carry the radial velocity of
the Doppler chain, within the Doppler bin and its σ, and a tracker fed the line-of-sight detections
writes a track that follows the mover."""
from __future__ import annotations

import json
import math

import numpy as np

from hardware.testing import write_dca1000_recording
from xnlos_core.app.runner import run_to_dir
from xnlos_core.config import parse_pipeline
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.doppler import add_chirp_noise, chirp_sequence_cube

# X band, ΔR = 0.39 m, 16 chirp loops of 2 TX every 0.4 ms: Δv = 2.3 m/s per Doppler bin, v_max = 18 m/s
RADAR = RadarConfig(n_samples=64, bandwidth=384e6, chirp_duration=6.4e-6, chirp_period=200e-6, n_chirps=16,
                    n_tx=2, n_rx=4, max_range=20.0, n_azimuth_bins=31, frame_period=0.1)
R0, AZ, V = 6.0, 0.2, 1.3          # mover: range at frame 0 [m], azimuth [rad], radial velocity [m/s]
STATIC = (12.0, -0.3)              # a reflector at rest [m], [rad]
FRAMES = 6
AMP = 4e-7                         # echo amplitude [√W]: −4 dB per sample, ≈ 35 dB in the map
SCALE = 1e-7                       # √W per ADC count


def _capture(tmp_path):
    cubes = []
    for k in range(FRAMES):
        t = k * RADAR.frame_period
        clean = chirp_sequence_cube(RADAR, [R0 + V * t, STATIC[0]], [AZ, STATIC[1]], [AMP, AMP], [V, 0.0])
        cubes.append(add_chirp_noise(clean, RADAR, np.random.default_rng(k)))
    return write_dca1000_recording(tmp_path / "rec", cubes, RADAR, scale=SCALE)


def _pipeline(toml, tracker: bool):
    table = {"seed": 0, "radar": {"preset": "xband_default"},
             "backend": {"name": "adc", "params": {"recording": str(toml)}},
             "detector": {"name": "cfar", "params": {"guard_cells": [2, 2], "train_cells": [4, 4], "pfa": 1e-4}},
             "run": {"frames": FRAMES, "figure": False, "animation": False}}
    if tracker:
        table["tracker"] = {"name": "kalman", "params": {"confirm_hits": 2, "confirm_window": 3}}
    return parse_pipeline(table, str(toml), toml.parent)


def _records(out):
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


def test_detections_from_a_recording_carry_radial_velocity(tmp_path):
    toml = _capture(tmp_path)
    run_to_dir(_pipeline(toml, tracker=False), tmp_path / "out", source=str(toml), progress=False)
    records = _records(tmp_path / "out")
    assert len(records) == FRAMES
    for rec in records:
        det = rec["detection_doppler"]  # present only when the detections carry velocity
        r, a = np.array(det["range"]), np.array(det["azimuth"])
        v, var = np.array(det["velocity"]), np.array(det["velocity_var"])
        mover = np.flatnonzero((np.abs(r - (R0 + V * rec["timestamp"])) < 0.6) & (np.abs(a - AZ) < 0.1))
        still = np.flatnonzero((np.abs(r - STATIC[0]) < 0.6) & (np.abs(a - STATIC[1]) < 0.1))
        assert len(mover) == 1 and len(still) == 1, (r, a)
        sd = math.sqrt(var[mover[0]])
        assert 0 < sd < RADAR.velocity_resolution / 4
        assert abs(v[mover[0]] - V) < min(RADAR.velocity_resolution / 2, 4 * sd)
        assert abs(v[still[0]]) < min(RADAR.velocity_resolution / 2, 4 * math.sqrt(var[still[0]]))


def test_a_tracker_without_a_reconstructor_tracks_the_line_of_sight_detections(tmp_path):
    toml = _capture(tmp_path)
    config = _pipeline(toml, tracker=True)
    assert config.reconstructor is None and config.wall_estimator is None
    run_to_dir(config, tmp_path / "out", source=str(toml), progress=False)
    records = _records(tmp_path / "out")
    last = records[-1]
    assert last["hidden_points"] == []  # no reconstructor: nothing is mirrored
    tracks = last["tracks"]
    assert tracks is not None and len(tracks["id"]) >= 1
    truth = (R0 + V * last["timestamp"]) * np.array([math.cos(AZ), math.sin(AZ)])
    pos, vel = np.array(tracks["position"]), np.array(tracks["velocity"])
    k = int(np.argmin(np.linalg.norm(pos - truth, axis=1)))
    assert np.linalg.norm(pos[k] - truth) < 0.5
    u = np.array([math.cos(AZ), math.sin(AZ)])
    assert abs(vel[k] @ u - V) < 0.3  # its radial velocity: the Doppler rows of the LOS points
    assert last["timestamp"] == (FRAMES - 1) * RADAR.frame_period
