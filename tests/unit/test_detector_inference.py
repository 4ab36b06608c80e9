"""Fast inference of the learned detectors (plugins/detectors/inference.py):
channels-last float32 equal to the plain network within 1e-5, bf16 detections close to float32's,
the compile fallback, the thread count, parameter validation, and the pipeline's warm-up before
the first frame (counted in network forwards, not timed)."""
from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from plugins.detectors.features import ra_features
from plugins.detectors.inference import CompileFallbackWarning, InferenceRunner
from plugins.detectors.learned import LEARNED, run_network
from xnlos_core.errors import ConfigError
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.testing import synthetic_frame

pytestmark = pytest.mark.filterwarnings("ignore::xnlos_core.errors.GridMismatchWarning")  # toy maps

SMALL = RadarConfig(n_samples=128, max_range=30.0, n_azimuth_bins=31)


def _det(name="swin_unet", **params):
    return get_registry().create("detector", name, {"device": "cpu", **params})


def _plain(det) -> torch.nn.Module:
    """The detector's network as the code before the fast path ran it: contiguous (NCHW) weights."""
    det._load()
    return copy.deepcopy(det._net).to(memory_format=torch.contiguous_format)


@pytest.mark.parametrize("name", sorted(LEARNED))
def test_fp32_channels_last_equals_plain_network(name):
    det = _det(name)
    frame = synthetic_frame(SMALL)
    out = det.output(frame)
    ref = run_network(_plain(det), ra_features(frame.ra_map.data), torch.device("cpu"))
    assert out.shape == ref.shape and out.dtype == np.float32 and out.flags.c_contiguous
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-5)


def test_fp32_flip_tta_equals_plain_network():
    det = _det(tta="flip")
    frame = synthetic_frame(SMALL)
    feats = ra_features(frame.ra_map.data)
    net, w = _plain(det), feats.shape[-1]
    ref = run_network(net, feats, torch.device("cpu"))
    back = run_network(net, feats[..., ::-1], torch.device("cpu"))[..., :w][..., ::-1]
    ref[..., :w] = 0.5 * (ref[..., :w] + back)
    np.testing.assert_allclose(det.output(frame), ref, rtol=0, atol=1e-5)


def _f1(a, b, radar) -> float:
    """F1 of detections ``a`` against ``b``: same class, within one range bin and one azimuth bin
    (greedy, one-to-one)."""
    da, dr = np.diff(radar.azimuth_axis[:2])[0], radar.range_resolution
    used, tp = set(), 0
    for r, az, k in zip(a.range, a.azimuth, a.label):
        near = np.flatnonzero((np.abs(b.range - r) <= dr) & (np.abs(b.azimuth - az) <= da) & (b.label == k))
        near = [j for j in near if j not in used]
        if near:
            used.add(near[0])
            tp += 1
    return 2 * tp / max(len(a) + len(b), 1)


def test_bf16_detections_agree_with_fp32():
    """Tolerance: on the conformance kit's map (default radar, 7 peaks) bf16 finds the same
    detections as fp32 (F1 ≥ 0.9 within one bin, same class) and its logits differ by < 0.5
    (measured 0.08–0.15 on the shipped models); the dataset-wide figures are in
    benchmarks/detector_speed.md."""
    radar = RadarConfig()
    frame = synthetic_frame(radar, seed=3)
    fp32, bf16 = _det(), _det(precision="bf16")
    a, b = fp32.detect(frame), bf16.detect(frame)
    assert len(a) > 0 and _f1(a, b, radar) >= 0.9
    assert np.max(np.abs(fp32.output(frame) - bf16.output(frame))) < 0.5


@pytest.mark.parametrize("params, match", [
    ({"precision": "fp16"}, "precision"),
    ({"threads": 0}, "threads"),
    ({"compile": "yes"}, "compile"),
])
def test_params_are_validated(params, match):
    with pytest.raises(ConfigError, match=match):
        get_registry().create("detector", "swin_unet", {"device": "cpu", **params})


def test_bf16_on_a_device_without_autocast_is_a_config_error():
    net = _det(checkpoint="none")
    net._load()
    with pytest.raises(ConfigError, match="precision 'bf16' needs device cpu or cuda"):
        InferenceRunner(net._net, torch.device("meta"), "bf16")


@pytest.mark.parametrize("where", ["compile", "first call"])
def test_compile_falls_back_to_eager_with_a_warning(monkeypatch, where):
    def broken_compile(module, *a, **k):
        if where == "compile":
            raise RuntimeError("torch.compile is not supported on this platform")

        def fails(*x):
            raise RuntimeError("inductor: no C++ compiler")
        return fails

    monkeypatch.setattr(torch, "compile", broken_compile)
    frame = synthetic_frame(SMALL)
    with pytest.warns(CompileFallbackWarning, match="compile = true"):
        det = _det(checkpoint="none", compile=True)
        det.warm_up(SMALL)
    assert not det._runner.compiled
    np.testing.assert_array_equal(det.output(frame), _det(checkpoint="none").output(frame))


@pytest.mark.slow
def test_compiled_network_equals_eager():
    """torch.compile (inductor) on the tiny untrained network: ~20–90 s to compile on 2 cores."""
    frame = synthetic_frame(SMALL)
    det = _det("unet", checkpoint="none", compile=True)
    det.warm_up(SMALL)
    out = det.output(frame)
    assert det._runner.compiled
    np.testing.assert_allclose(out, _det("unet", checkpoint="none").output(frame), rtol=0, atol=1e-5)


def test_threads_are_set_during_the_forward_and_restored():
    before = torch.get_num_threads()
    want = 1 if before != 1 else 2
    det = _det(checkpoint="none", threads=want)
    det._load()
    seen = []
    det._net.register_forward_hook(lambda *a: seen.append(torch.get_num_threads()))
    det.detect(synthetic_frame(SMALL))
    assert seen == [want] and torch.get_num_threads() == before


def test_warm_up_runs_once_per_grid_shape():
    det = _det(checkpoint="none")
    assert det.forwards == 0
    assert det.warm_up(SMALL) == 1 and det.forwards == 1
    assert det.warm_up(SMALL) == 0 and det.forwards == 1
    assert det.warm_up(None) == 0


def test_pipeline_warms_the_detector_up_before_the_first_frame(monkeypatch):
    """The network is loaded and run once on an empty map before the first frame reaches detect:
    at the first detect one forward (the warm-up) has been made, and the detector's first-frame
    timing is a steady-state forward."""
    from xnlos_core.config import parse_pipeline
    from xnlos_core.pipeline import Pipeline

    table = {"name": "warm", "seed": 0, "scene": {"builtin": "corner"}, "forward_model": {"name": "image"},
             "detector": {"name": "swin_unet", "params": {"checkpoint": "none", "device": "cpu"}},
             "wall_estimator": {"name": "lsq"}, "reconstructor": {"name": "mirror"},
             "run": {"frames": 2, "figure": False}}
    pipe = Pipeline(parse_pipeline(table, "test"), source="test")
    det = pipe.stages["detector"]
    assert det.forwards == 0  # construction (and `xnlos check`) loads nothing
    at_detect = []
    detect = det.detect
    monkeypatch.setattr(det, "detect", lambda frame: (at_detect.append(det.forwards), detect(frame))[1])
    results = list(pipe.run())
    assert at_detect == [1, 2] and det.forwards == 3 and len(results) == 2
    assert pipe.warm_up() == 0  # once per pipeline


def test_pipeline_warm_up_builds_the_wall_estimators_problems_too():
    """The wall estimator's casadi problems are built in the warm-up, not in the first frame."""
    from xnlos_core.config import parse_pipeline
    from xnlos_core.pipeline import Pipeline

    table = {"name": "warm", "seed": 0, "scene": {"builtin": "corner"}, "forward_model": {"name": "image"},
             "detector": {"name": "nlos_cfar"}, "wall_estimator": {"name": "casadi_map"},
             "reconstructor": {"name": "mirror"}, "run": {"frames": 1, "figure": False}}
    pipe = Pipeline(parse_pipeline(table, "test"), source="test")
    built = pipe.stages["wall_estimator"].warm_up()  # what the estimator builds for itself
    assert built > 0
    fresh = Pipeline(parse_pipeline(table, "test"), source="test")
    assert fresh.warm_up() == built and fresh.warm_up() == 0
