"""benchmarks/forecast_bound.py: the detection and tracking shares and the true manoeuvre's forecast, on
frames written by hand."""
import numpy as np
import pytest


def _frame(t, car, points, track):
    """One map: a braking car (truth id 0) at ``car`` moving at 5 m/s along x, the hidden points, and one
    track at ``track`` (None: no track) with the car's velocity and a CV forecast."""
    ids = np.array([7]) if track is not None else np.empty(0, int)
    pos = np.array([track], float) if track is not None else np.empty((0, 2))
    vel = np.array([[5.0, 0.0]]) if track is not None else np.empty((0, 2))
    fc = (pos + 2.0 * vel)[:, None, :] if track is not None else np.empty((0, 1, 2))
    return {"t": t, "ids": ids, "pos": pos, "vel": vel, "hz": np.array([2.0]), "fc": fc,
            "points": np.array(points, float).reshape(-1, 2), "model": ("cv",) * len(ids), "ident": {},
            "truth": {0: (np.asarray(car, float), np.array([5.0, 0.0]), True, "braking")}}


def test_detected_and_tracked_shares_per_car(benchmark_module):
    fb = benchmark_module("forecast_bound")
    # 30 frames at 10 Hz; points near the car in the first 10 frames only, a track on it in frames 0–4
    seq = []
    for k in range(30):
        car = [0.5 * k, 0.0]
        points = [[car[0] + 0.5, 0.2]] if k < 10 else [[car[0] + 20.0, 0.0]]
        seq.append(_frame(0.1 * k, car, points, car if k < 5 else None))
    out = fb.score([seq], radius=2.0)
    lines = fb._detection_table(out, ["braking"])
    row = [c.strip() for c in lines[-1].strip("|").split("|")]
    assert row == ["braking", "1", "30", f"{10 / 30:.2f}", f"{5 / 30:.2f}", f"{10 / 30:.2f}", "0"]
    # a constant-velocity car: CV forecasts it exactly and so does its true (null) manoeuvre; frames 1–4 of
    # the tracked ones score (frame 0 has no earlier frame for the true acceleration's central difference)
    assert np.allclose(out["braking"]["cv"], 0.0) and np.allclose(out["braking"]["true_xi"], 0.0)
    assert len(out["braking"]["cv"]) == 4 and out["braking"]["tracker"] == pytest.approx([0.0] * 4)
