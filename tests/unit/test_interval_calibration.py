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
