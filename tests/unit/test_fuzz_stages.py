"""Seeded fuzz of the stages: every registered detector's ``detect`` on generated RA maps
and every registered wall estimator's ``estimate`` on generated LOS point sets.

The inputs are what a careless or hostile caller can build: map shapes from 2 × 2 up, zeros,
constants, single spikes, amplitudes over 1e-30 … 1e30, odd CFAR windows; points at 1e-300 … 2e6 m,
duplicates, collinear sets, two points, standard deviations 1e-12 … 1e160 m. Every case must end in
finite outputs or a *typed* project error from a short list of expected causes (an InputError that
only says a core type refused a NaN would be a stage bug, so the messages are checked too). Non-finite
maps are refused when the RAMap is built and cannot be written afterwards (arrays are read-only).

Case counts come from the ``fuzz_cases`` fixture (50 in ``make test``, 10,000 in ``make fuzz``);
the learned detectors run a tenth of them on maps of at most 48 × 48 cells (a forward pass each),
emcee runs 40-step chains. Each test prints its tally (``pytest -s``), e.g. ``ok: 120, InputError: 80``.
"""
from __future__ import annotations

import collections
import math
import warnings

import numpy as np
import pytest

from plugins.detectors.learned import LEARNED
from plugins.detectors.peaks import window_error
from xnlos_core.errors import InputError, InsufficientDataError, XnlosError
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.types import LOS, MNLOS, Detections, Frame, GroundTruth, RAMap, WallSegment

pytestmark = pytest.mark.fuzz

RADAR = RadarConfig()
CFAR_FAMILY = ("cfar", "nlos_cfar")
DETECTORS = get_registry().names("detector")
ESTIMATORS = get_registry().names("wall_estimator")
# The InputErrors a wall estimator may raise on finite Detections (estimators.lsq.los_clusters).
ESTIMATOR_INPUT_ERRORS = ("exceed |x|, |y|", "largest position standard deviation")


def random_map(rng: np.random.Generator, max_side: int) -> np.ndarray:
    """A finite complex (H, W) map, 2 ≤ H, W ≤ max_side, of one of several adversarial kinds."""
    h, w = (int(math.exp(rng.uniform(math.log(2), math.log(max_side + 1)))) for _ in range(2))
    kind = rng.integers(8)
    phase = np.exp(1j * rng.uniform(-np.pi, np.pi, (h, w)))
    if kind == 0:  # zeros
        return np.zeros((h, w), complex)
    if kind == 1:  # a constant, 1e-30 … 1e30
        return np.full((h, w), 10.0 ** rng.uniform(-30, 30) * phase[0, 0])
    if kind == 2:  # one spike on zeros or on faint noise
        m = np.zeros((h, w), complex) if rng.random() < 0.5 else 1e-20 * phase
        m[rng.integers(h), rng.integers(w)] = 10.0 ** rng.uniform(-30, 30)
        return m
    if kind == 3:  # log-uniform amplitudes over 60 decades
        return 10.0 ** rng.uniform(-30, 30, (h, w)) * phase
    if kind == 4:  # Rayleigh noise plus a few strong targets
        m = rng.standard_normal((h, w)) + 1j * rng.standard_normal((h, w))
        k = rng.integers(0, 6)
        m[rng.integers(0, h, k), rng.integers(0, w, k)] *= 10.0 ** rng.uniform(0, 15, k)
        return m
    if kind == 5:  # a ridge (a wall) along range or azimuth
        m = 1e-3 * phase
        if rng.random() < 0.5:
            m[rng.integers(h), :] = 1e3
        else:
            m[:, rng.integers(w)] = 1e3
        return m
    if kind == 6:  # checkerboard of extremes
        return np.where((np.add.outer(np.arange(h), np.arange(w)) % 2) == 0, 1e30, 1e-30) * phase
    return np.sign(rng.standard_normal((h, w))) * 10.0 ** rng.integers(-30, 31, (h, w))  # decades, signed


def random_frame(rng: np.random.Generator, data: np.ndarray, with_walls: bool) -> Frame:
    """A Frame around ``data`` with random ascending axes (ranges ≥ 0 m, azimuths within ±π)."""
    h, w = data.shape
    r0 = 10.0 ** rng.uniform(-3, 2) if rng.random() < 0.7 else 0.0
    rng_axis = r0 + np.arange(h) * 10.0 ** rng.uniform(-3, 1)
    half = rng.uniform(0.05, np.pi)
    az = np.linspace(-half, half, w)
    gt = None
    if with_walls:
        gt = GroundTruth(walls=(WallSegment([3.0, -5.0], [3.0, 5.0]), WallSegment([1.0, 2.0], [9.0, 2.5])))
    return Frame(RAMap(data, rng_axis, az, RADAR), ground_truth=gt)


def cfar_params(rng: np.random.Generator, shape: tuple[int, int]) -> dict:
    """CFAR parameters: mostly windows that fit the map, some that do not, some up to the bound 256."""
    def cells(n: int) -> tuple[int, int]:
        mode = rng.random()
        if mode < 0.6:  # fits: 2(g + t) + 1 ≤ n
            g = int(rng.integers(0, max((n - 1) // 2, 0) + 1))
            t = int(rng.integers(0, max((n - 1) // 2 - g, 0) + 1))
        elif mode < 0.85:
            g, t = int(rng.integers(0, 8)), int(rng.integers(0, 16))
        else:
            g, t = int(rng.integers(0, 257)), int(rng.integers(0, 257))
        return g, t

    (gr, tr), (ga, ta) = cells(shape[0]), cells(shape[1])
    if tr + ta == 0:
        ta = 1
    return {"pfa": float(10.0 ** rng.uniform(-12, -0.3)), "guard_cells": (gr, ga), "train_cells": (tr, ta),
            "min_range": float(rng.choice([0.0, 1.0, 10.0 ** rng.uniform(-2, 3)]))}


def check_detections(det: Detections, frame: Frame) -> None:
    """Finite detections inside the map's axes (Detections itself already checked its ranges)."""
    assert isinstance(det, Detections)
    ra = frame.ra_map
    for name in ("range", "azimuth", "confidence", "range_std", "azimuth_std", "position"):
        assert np.all(np.isfinite(getattr(det, name))), name
    if len(det):
        span = ra.range_axis[-1] - ra.range_axis[0]
        tol = 1e-9 * max(1.0, span)
        assert det.range.min() >= ra.range_axis[0] - tol and det.range.max() <= ra.range_axis[-1] + tol
        assert det.azimuth.min() >= ra.azimuth_axis[0] - 1e-9 and det.azimuth.max() <= ra.azimuth_axis[-1] + 1e-9


def report(name: str, tally: collections.Counter) -> None:
    print(f"\n[fuzz] {name}: {sum(tally.values())} cases, " + ", ".join(f"{k}: {v}" for k, v in sorted(tally.items())))


def test_non_finite_maps_are_refused_and_maps_cannot_be_corrupted(fuzz_cases):
    rng = np.random.default_rng(260)
    tally = collections.Counter()
    for _ in range(fuzz_cases):
        data = random_map(rng, 64)
        bad = rng.choice([np.nan, np.inf, -np.inf, 1e39, complex(np.nan, 0), complex(0, np.inf)])
        data = data.astype(complex)
        data[rng.integers(data.shape[0]), rng.integers(data.shape[1])] = bad  # 1e39 overflows complex64
        with pytest.raises(InputError, match="NaN or infinite"):
            random_frame(rng, data, False)
        frame = random_frame(rng, random_map(rng, 64), False)
        with pytest.raises(ValueError, match="read-only"):
            frame.ra_map.data[0, 0] = np.inf
        tally["refused"] += 1
    report("non-finite RA maps", tally)


@pytest.mark.parametrize("name", [n for n in DETECTORS if n not in LEARNED])
def test_detectors_on_random_maps(name, fuzz_cases):
    """cfar / nlos_cfar: an InputError exactly when the window does not fit the map, else finite
    detections; other (third-party) detectors: finite detections or a typed error."""
    rng = np.random.default_rng(261)
    reg = get_registry()
    tally = collections.Counter()
    for _ in range(fuzz_cases):
        data = random_map(rng, 160)
        frame = random_frame(rng, data, with_walls=rng.random() < 0.8)
        if name not in CFAR_FAMILY:  # a third-party detector: finite detections or a typed error
            try:
                out = reg.create("detector", name, {}).detect(frame)
            except XnlosError as exc:
                tally[type(exc).__name__] += 1
                continue
        else:
            params = cfar_params(rng, data.shape)
            if name == "nlos_cfar" and frame.ground_truth is None:
                params |= {"wall_source": "config", "walls": [[2.0, -3.0, 2.0, 3.0]]}
            det = reg.create("detector", name, params)
            if window_error(params["guard_cells"], params["train_cells"], data.shape, "the RA map"):
                with pytest.raises(InputError, match=r"2·\(train \+ guard\) \+ 1 must be ≤"):
                    det.detect(frame)
                tally["InputError (window > map)"] += 1
                continue
            out = det.detect(frame)
        check_detections(out, frame)
        tally["ok, detections" if len(out) else "ok, empty"] += 1
    report(name, tally)


# The checkpoint's decoding, and an extreme one: every peak above 0.001, the widest window, one per cell.
LEARNED_VARIANTS = ({}, {"threshold": 0.001, "window": (31, 31), "cells": True, "max_detections": 5})


@pytest.fixture(scope="module")
def learned():
    reg = get_registry()
    return {n: [reg.create("detector", n, {"device": "cpu", "threads": 1, **v}) for v in LEARNED_VARIANTS]
            for n in DETECTORS if n in LEARNED}


@pytest.mark.filterwarnings("ignore::xnlos_core.errors.GridMismatchWarning")  # random maps of any size: not the models' grid
@pytest.mark.parametrize("name", [n for n in DETECTORS if n in LEARNED])
def test_learned_detectors_on_random_maps(name, learned, fuzz_cases):
    """Shipped checkpoints on small odd-sized maps, decoded as the checkpoint says and at extremes:
    always finite detections and heatmaps in [0, 1]."""
    rng = np.random.default_rng(262)
    tally = collections.Counter()
    for case in range(max(fuzz_cases // 10, 10)):
        det = learned[name][case % len(LEARNED_VARIANTS)]
        frame = random_frame(rng, random_map(rng, 48), with_walls=False)
        out = det.detect(frame)
        check_detections(out, frame)
        heat = det.heatmap(frame)
        assert np.all(np.isfinite(heat)) and heat.min() >= 0 and heat.max() <= 1
        tally["ok, detections" if len(out) else "ok, empty"] += 1
    report(name, tally)


def random_points(rng: np.random.Generator) -> Detections:
    """LOS (and some mNLOS) detections of one of several degenerate or extreme geometries."""
    kind = rng.integers(9)
    n = int(rng.integers(3, 24)) if rng.random() < 0.8 else int(rng.integers(0, 3))
    scale = 10.0 ** rng.uniform(-6, 6.3)
    if kind == 0:  # a cloud
        pts = rng.standard_normal((n, 2)) * scale
    elif kind == 1:  # exactly collinear, anywhere
        pts = rng.standard_normal(2) * scale + rng.standard_normal(n)[:, None] * scale * rng.standard_normal(2)
    elif kind == 2:  # duplicates
        pts = np.repeat(rng.standard_normal((max(1, n // 3), 2)) * scale, 3, axis=0)
    elif kind == 3:  # at or next to the origin
        pts = rng.standard_normal((n, 2)) * rng.choice([0.0, 1e-300, 1e-12])
    elif kind == 4:  # a wall 8 m ahead with noise from 1 nm to 10 m
        pts = np.c_[np.full(n, 8.0), np.linspace(-3, 3, n)] + rng.standard_normal((n, 2)) * 10.0 ** rng.uniform(-9, 1)
    elif kind == 5:  # a far wall, up to past the estimators' bound
        pts = np.c_[np.full(n, rng.choice([1e3, 1e5, 1e6, 2e6, 1e300])), np.linspace(-3, 3, n) * scale]
    elif kind == 6:  # two points
        pts = rng.standard_normal((2, 2)) * scale
    elif kind == 7:  # an arc of radius 1 mm … 1000 km
        a = np.linspace(-0.5, 0.5, n)
        radius = 10.0 ** rng.uniform(-3, 6)
        pts = np.c_[radius * np.cos(a), radius * np.sin(a)] + 5.0
    else:  # a wall with outliers
        pts = np.c_[np.full(n, 6.0), np.linspace(-4, 4, n)]
        k = int(rng.integers(0, n + 1))
        pts[:k] += rng.standard_normal((k, 2)) * 10.0 ** rng.uniform(-1, 2)
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    k = len(pts)
    rs = np.full(k, 0.05)
    if rng.random() < 0.3:  # stated errors over many decades, mostly below the 1e6-m bound
        rs = 10.0 ** rng.uniform(-12, rng.choice([3.0, 6.0, 160.0]), k)
    az = 10.0 ** rng.uniform(-12, 1, k) if rng.random() < 0.3 else np.full(k, 0.005)
    label = np.where(rng.random(k) < 0.85, LOS, MNLOS)
    return Detections.from_points(pts, label=label, range_std=rs, azimuth_std=az)


ESTIMATOR_PARAMS = {"emcee": {"n_walkers": 8, "n_steps": 40, "burn": 10, "min_ess": 0.0}}


@pytest.mark.parametrize("name", ESTIMATORS)
def test_wall_estimators_on_random_point_sets(name, fuzz_cases):
    """Finite walls (mean, cov, extent, samples, anchor), or InsufficientDataError, or the estimators'
    own InputErrors (points or position errors beyond MAX_COORDINATE) — nothing else."""
    rng = np.random.default_rng(263)
    est = get_registry().create("wall_estimator", name, ESTIMATOR_PARAMS.get(name, {}))
    tally = collections.Counter()
    for _ in range(fuzz_cases):
        det = random_points(rng)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                walls = est.estimate(det)
        except InsufficientDataError:
            tally["InsufficientDataError"] += 1
            continue
        except InputError as exc:
            assert any(s in str(exc) for s in ESTIMATOR_INPUT_ERRORS), exc
            tally["InputError"] += 1
            continue
        assert walls
        for w in walls:
            for field in ("mean", "cov", "extent", "samples", "anchor"):
                v = getattr(w, field)
                assert v is None or np.all(np.isfinite(v)), (field, v)
            assert w.n_points >= 2
        tally["ok"] += 1
    report(name, tally)
