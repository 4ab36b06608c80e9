"""benchmarks/interval_calibration.py: conformal disc factors from records written by hand, with the
factors a run was scored with divided out again."""
import json

import numpy as np
import pytest


def _run(tmp_path, name, params, rows):
    run = tmp_path / name
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"name": "sindy + Doppler", "config": {"tracker": {"name": "sindy",
                                                                                              "params": params}}}))
    (run / "sequences.jsonl").write_text(json.dumps({"forecasts": rows}))
    return run


def test_factors_of_the_config_are_divided_out(tmp_path, benchmark_module):
    ic = benchmark_module("interval_calibration")
    # errors 1 … 10 m against Gaussian radii of 2 m (r50) and 4 m (r90), on cv tracks and on model tracks
    rows = [{"err": [float(e)], "r50": [2.0], "r90": [4.0], "model": m} for e in range(1, 11) for m in ("cv", "vx'=vy")]
    raw = ic.pairs(_run(tmp_path, "raw", {}, rows))
    # the same forecasts scored with factors: radii stored scaled, ratios against the Gaussian's own radii
    scaled_rows = [{**r, "r50": [2.0 * (0.5 if r["model"] == "cv" else 3.0)],
                    "r90": [4.0 * (1.5 if r["model"] == "cv" else 0.7)]} for r in rows]
    scaled = ic.pairs(_run(tmp_path, "scaled", {"interval_scale": [0.5, 1.5], "model_interval_scale": [3.0, 0.7]},
                           scaled_rows))
    for cls in ("cv", "model"):
        for q in ic.LEVELS:
            np.testing.assert_allclose(scaled[cls][q], raw[cls][q])
    np.testing.assert_allclose(raw["cv"][0.5], np.arange(1, 11) / 2.0)
    # ⌈11 · 0.5⌉ = 6th smallest of e / 2: 3.0; level 0.9 needs ⌈9.9⌉ = 10 ≤ n pairs: the largest, 10 / 4
    assert ic.conformal_factor(raw["cv"][0.5], 0.5) == pytest.approx(3.0)
    assert ic.conformal_factor(raw["cv"][0.9], 0.9) == pytest.approx(2.5)
    assert ic.conformal_factor(raw["cv"][0.9][:5], 0.99) == float("inf")


def test_pac_factor_over_whole_sequences(benchmark_module):
    ic = benchmark_module("interval_calibration")
    same = [np.linspace(0.1, 2.0, 20) for _ in range(10)]
    # every draw of identical sequences holds the same ratios: the PAC factor is the pooled one
    assert ic.sequence_factor(same, 0.9) == pytest.approx(ic.conformal_factor(np.concatenate(same), 0.9))
    # half the sequences easy, half hard: a draw with more hard ones needs a larger factor, and the
    # 0.9-confidence factor lies above the pooled one (below the hard sequences' own)
    mixed = [np.linspace(0.1, 1.0, 20)] * 5 + [np.linspace(1.0, 3.0, 20)] * 5
    pooled = ic.conformal_factor(np.concatenate(mixed), 0.9)
    pac = ic.sequence_factor(mixed, 0.9, confidence=0.9, resamples=400, seed=1)
    assert pooled < pac < ic.conformal_factor(mixed[-1], 0.9)
    assert pac == ic.sequence_factor(mixed, 0.9, confidence=0.9, resamples=400, seed=1)  # seeded
    assert ic.sequence_factor([], 0.9) == float("inf")
