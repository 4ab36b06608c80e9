"""Inputs of the conformance checks: a small radar, a synthetic RA-map frame with known LOS and mNLOS
targets, a small pipeline config table and a synthetic SPAD transient volume."""
from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np

from ..geometry import cartesian_to_polar, mirror_reflect
from ..radar import RadarConfig
from ..types import Frame, GroundTruth, RAMap, WallSegment

KIT_WALL = WallSegment(np.array([15.0, 10.0]), np.array([35.0, -10.0]), "kit_wall")
KIT_HIDDEN = np.array([[22.0, -14.0]])


def small_radar(**overrides) -> RadarConfig:
    """A small, fast radar (60 m, 61 azimuth bins) for conformance checks."""
    kw = dict(n_samples=256, max_range=60.0, n_azimuth_bins=61)
    kw.update(overrides)
    return RadarConfig(**kw)


def small_pipeline_table(**overrides) -> dict[str, Any]:
    """A fast pipeline config table (the parsed-TOML dict ``parse_pipeline`` takes) on the built-in
    corner scene: 256 samples to 60 m, 121 azimuth bins (1°), one frame, no figure, seed 5, stages
    image → nlos_cfar → lsq → mirror. Each keyword replaces one top-level key (deep-copied), e.g.
    ``small_pipeline_table(detector={"name": "my_detector"})`` runs a new detector end to end."""
    table: dict[str, Any] = {
        "name": "small", "seed": 5, "radar": {"n_samples": 256, "max_range": 60.0, "n_azimuth_bins": 121},
        "scene": {"builtin": "corner"}, "forward_model": {"name": "image"}, "detector": {"name": "nlos_cfar"},
        "wall_estimator": {"name": "lsq"}, "reconstructor": {"name": "mirror"},
        "run": {"frames": 1, "figure": False},
    }
    table.update(copy.deepcopy(overrides))
    return table


def synthetic_frame(radar: RadarConfig | None = None, seed: int = 0, snr_db: float = 35.0) -> Frame:
    """A frame with unit-power complex noise, LOS peaks along ``KIT_WALL`` and one mNLOS peak.

    Peaks are separable Gaussians one resolution cell wide (range ΔR, azimuth 2/N_virtual rad);
    the mNLOS peak is the mirror image of ``KIT_HIDDEN`` across the wall. Ground truth included.
    """
    radar = radar or small_radar()
    rng = np.random.default_rng(seed)
    r_ax, a_ax = radar.range_axis, radar.azimuth_axis
    los = KIT_WALL.start + np.linspace(0.15, 0.7, 6)[:, None] * (KIT_WALL.end - KIT_WALL.start)
    virt = mirror_reflect(KIT_HIDDEN, KIT_WALL.normal, KIT_WALL.offset)
    pts = np.concatenate([los, virt])
    rr, aa = cartesian_to_polar(pts)
    amp = 10 ** (snr_db / 20)
    sig_r, sig_a = radar.range_resolution, 2.0 / (radar.n_channels)
    data = (rng.standard_normal((len(r_ax), len(a_ax))) + 1j * rng.standard_normal((len(r_ax), len(a_ax)))) / math.sqrt(2)
    for r, a in zip(rr, aa):
        if r <= r_ax[-1] and abs(a) <= a_ax[-1]:
            blob = np.exp(-0.5 * ((r_ax[:, None] - r) / sig_r) ** 2 - 0.5 * ((a_ax[None, :] - a) / sig_a) ** 2)
            data += amp * blob * np.exp(2j * np.pi * rng.random())
    gt = GroundTruth(los, virt, KIT_HIDDEN, np.zeros(1, int), ("kit_object",), (KIT_WALL,))
    return Frame(RAMap.from_radar(data.astype(np.complex64), radar), 0.0, gt, 0)



def kit_transient(points, n: int = 16, n_bins: int = 128, wall: float = 1.0, max_depth: float = 1.0):
    """A confocal TransientVolume (n_bins, n, n) of hidden points (x, y, z) [m] (z > 0 the depth):
    scan point (x_j, y_i) counts 1/r⁴ at round-trip bin rint(2r/(c·Δt)), r = √((x − x_j)² + (y − y_i)² + z²);
    Δt chosen so the bins reach depth ``max_depth`` [m]."""
    from ..transient import SPEED_OF_LIGHT, TransientVolume

    bw = 2 * max_depth / SPEED_OF_LIGHT / n_bins
    x = (np.arange(n) - (n - 1) / 2) * (wall / n)
    data = np.zeros((n_bins, n, n))
    for px, py, pz in points:
        r = np.sqrt((x[None, :] - px) ** 2 + (x[:, None] - py) ** 2 + pz ** 2)
        k = np.rint(2 * r / SPEED_OF_LIGHT / bw).astype(int)
        i, j = np.nonzero(k < n_bins)
        np.add.at(data, (k[i, j], i, j), r[i, j] ** -4.0)
    return TransientVolume(data, bw, wall, wall)


