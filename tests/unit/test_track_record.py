"""Tracks in results.jsonl: forecast and arrival fields round-trip through the record,
records of trackers without them keep their old form, and the history the figures draw."""
import json

import numpy as np
import pytest

from xnlos_core.errors import InputError
from xnlos_core.pipeline import FrameResult
from xnlos_core.testing import synthetic_frame
from xnlos_core.track_record import track_history, tracks_from_record, tracks_record
from xnlos_core.types import Detections, HiddenPoints, Tracks

H = np.array([0.5, 1.0, 2.0])


def _tracks(forecast=True, arrival=True) -> Tracks:
    pos = np.array([[20.0, -10.0], [25.0, -5.0]])
    vel = np.array([[0.0, 5.0], [1.0, -2.0]])
    kw = {}
    if forecast:
        r50 = np.array([[0.4, 0.7, 1.3], [np.nan, np.nan, np.nan]])  # the second has no interval yet
        kw.update(horizons=H, forecast=pos[:, None] + vel[:, None] * H[None, :, None], radius50=r50,
                  radius90=2 * r50, model=("vx'=-0.3 vy", "cv"))
    if arrival:
        kw.update(arrival=np.array([2.5, np.nan]), arrival_interval=np.array([[2.1, np.inf], [np.nan, np.nan]]))
    return Tracks([3, 8], pos, vel, pos + 0.1 * vel, 1.2, **kw)


def _record_of(tracks: Tracks) -> dict:
    frame = synthetic_frame()
    res = FrameResult(frame, Detections.empty(), [], HiddenPoints.empty(), tracks)
    # as the runner writes and reads it: json with NaN → null (record) and Infinity kept
    return json.loads(json.dumps(res.record()))


def _same(a, b):
    np.testing.assert_array_equal(np.asarray(a, float), np.asarray(b, float))  # NaN == NaN here


def test_forecast_and_arrival_round_trip_through_the_record():
    t = _tracks()
    rec = _record_of(t)["tracks"]
    assert rec["radius50"][1] == [None, None, None] and rec["arrival"][1] is None
    assert rec["arrival_interval"][0][1] == float("inf") and rec["model"] == ["vx'=-0.3 vy", "cv"]
    back = tracks_from_record(rec, timestamp=1.2)
    assert back.track_id.tolist() == [3, 8] and back.model == t.model and back.timestamp == 1.2
    for name in ("position", "velocity", "horizons", "forecast", "radius50", "radius90", "arrival",
                 "arrival_interval"):
        _same(getattr(back, name), getattr(t, name))


def test_without_forecast_the_tracks_record_is_as_before():
    t = _tracks(forecast=False, arrival=False)
    rec = _record_of(t)["tracks"]
    # the form results.jsonl had before the optional fields existed, byte for byte
    old = {"id": t.track_id.tolist(), "position": t.position.tolist(), "velocity": t.velocity.tolist()}
    assert json.dumps(rec, sort_keys=True) == json.dumps(old, sort_keys=True)
    assert tracks_from_record(rec).forecast is None and tracks_from_record(rec).arrival is None
    assert tracks_from_record(None) is None


def test_forecast_without_arrival_and_no_tracks_round_trip():
    rec = _record_of(_tracks(arrival=False))["tracks"]
    assert "arrival" not in rec and tracks_from_record(rec).forecast.shape == (2, 3, 2)
    empty = Tracks(np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)), horizons=H,
                   forecast=np.zeros((0, 3, 2)), radius50=np.zeros((0, 3)), radius90=np.zeros((0, 3)), model=())
    back = tracks_from_record(json.loads(json.dumps(tracks_record(empty))))
    assert len(back) == 0 and back.forecast.shape == (0, 3, 2)


def test_a_damaged_tracks_record_is_a_typed_error_naming_the_key():
    rec = tracks_record(_tracks())
    with pytest.raises(InputError, match="frame 4: tracks: missing velocity"):
        tracks_from_record({k: v for k, v in rec.items() if k != "velocity"}, where="frame 4: tracks")
    with pytest.raises(InputError, match=r"tracks\.radius90: expected"):
        tracks_from_record({**rec, "radius90": "wide"})


def test_track_history_keeps_the_last_frames_up_to_the_current_one():
    recs = [{"frame": k, "tracks": {"id": [1] + ([2] if k >= 3 else []),
                                    "position": [[k, 0.0]] + ([[0.0, k]] if k >= 3 else [])}} for k in range(6)]
    recs.insert(2, {"frame": 9, "tracks": None})  # a later frame, in any order: ignored
    h = track_history(recs, upto=4, max_frames=3)
    np.testing.assert_array_equal(h[1], [[2, 0], [3, 0], [4, 0]])
    np.testing.assert_array_equal(h[2], [[0, 3], [0, 4]])
