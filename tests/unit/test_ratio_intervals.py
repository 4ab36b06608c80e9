"""benchmarks/ratio_intervals.py: the 2 s ratio to CV and its sequence bootstrap, on records written by hand."""
import json

import numpy as np
import pytest


def _row(err2, cv2):
    return {"h": [1.0, 2.0], "err": [err2 / 2, err2], "err_cv": [cv2 / 2, cv2], "motion": "braking",
            "in50": None, "in90": None}


def test_ratio_and_bootstrap_over_whole_sequences(tmp_path, benchmark_module):
    ri = benchmark_module("ratio_intervals")
    run = tmp_path / "run-000"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"name": "sindy + Doppler"}))
    # sequence 0: two forecasts at half of CV's error, sequence 1: one at CV's, sequence 2: a cyclist
    seqs = [{"family": "hidden_car_approach", "forecasts": [_row(1.0, 2.0), _row(2.0, 4.0)]},
            {"family": "hidden_car_approach", "forecasts": [_row(3.0, 3.0)]},
            {"family": "hidden_cyclist", "forecasts": [_row(5.0, 1.0)]}]
    (run / "sequences.jsonl").write_text("\n".join(json.dumps(s) for s in seqs))
    by = ri.by_sequence(run, "hidden_car_approach/braking")
    assert [len(s) for s in by] == [2, 1]
    # the mean 2 s errors' ratio over the pooled forecasts: (1 + 2 + 3) / (2 + 4 + 3)
    r, lo, hi, n = ri.interval(by, 2000, np.random.default_rng(0))
    assert r == pytest.approx(6 / 9) and n == 2
    # resamples hold sequence 0 alone (0.5), sequence 1 alone (1.0) or both: the interval spans them
    assert lo == pytest.approx(0.5) and hi == pytest.approx(1.0)
    assert ri.interval([by[0]], 50, np.random.default_rng(0))[1:3] == pytest.approx((0.5, 0.5))
    assert ri.interval([], 50, np.random.default_rng(0))[3] == 0


def test_figure_draws_each_run_and_skips_motions_it_lacks(tmp_path, benchmark_module):
    ri = benchmark_module("ratio_intervals")
    found = {("large", "sindy + Doppler"): {"hidden_car_approach/braking": (0.6, 0.5, 0.8, 10)},
             ("large", "oracle"): {"hidden_car_approach/braking": (0.9, 0.8, 1.0, 12),
                                   "hidden_car_approach/straight": (1.1, 1.0, 1.2, 4)}}
    ri.figure(found, str(tmp_path / "r.png"))
    assert (tmp_path / "r.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
