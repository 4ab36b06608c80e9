"""Tracker checkpoints: ``state()`` → JSON → ``load_state()`` on a fresh tracker gives
bit-identical outputs afterwards (nearest, kalman, sindy with an identified turn model); a state that is
not the tracker's own is a typed error naming the key; a tracker without them says so."""
import json

import numpy as np
import pytest

from estimators.trackers.kalman import KalmanTracker
from estimators.trackers.nearest import NearestTracker
from estimators.trackers.sindy import SindyTracker
from xnlos_core import HiddenPoints, InputError
from xnlos_core.errors import PluginError
from xnlos_core.interfaces import Tracker
from xnlos_core.motion import ConstantTurn

CLASSES = {"nearest": NearestTracker, "kalman": KalmanTracker, "sindy": SindyTracker}
PARAMS = {"nearest": {}, "kalman": {"region": [[0, 0], [5, 0], [5, 5], [0, 5]]},
          "sindy": {"identification": "ensemble", "min_samples": 8, "refit_every": 4, "n_models": 3, "min_evidence": 0.0,
                    "region": [[0, 0], [5, 0], [5, 5], [0, 5]]},
          "sindy_library": {"min_samples": 8, "refit_every": 4, "region": [[0, 0], [5, 0], [5, 5], [0, 5]]}}
DT = 0.1


def _frames(n: int) -> list[tuple[HiddenPoints, float]]:
    """Two cars on noisy turning paths, one disappearing for a while, with Doppler: (points, t)."""
    rng = np.random.default_rng(3)
    turn = ConstantTurn(speed=8.0, yaw_rate=0.4).state(DT * np.arange(n), start=(15.0, -10.0), heading=np.pi / 2)
    out = []
    for k in range(n):
        t = DT * k
        p = [turn.position[k], np.array([30.0, 5.0]) + np.array([-3.0, 0.0]) * t]
        v = [turn.velocity[k], np.array([-3.0, 0.0])]
        keep = [0, 1] if not 8 <= k < 11 else [0]
        pts = np.array([p[i] + 0.15 * rng.standard_normal(2) for i in keep])
        vel = np.array([v[i] for i in keep])
        g = pts / np.linalg.norm(pts, axis=1, keepdims=True)
        n_ = len(pts)
        out.append((HiddenPoints(pts, np.tile(0.02 * np.eye(2), (n_, 1, 1)), np.arange(n_), np.zeros(n_),
                                 velocity=vel, velocity_cov=0.04 * g[:, :, None] * g[:, None, :]), t))
    return out


def _tracks_equal(a, b) -> None:
    for field in ("track_id", "position", "velocity", "predicted", "timestamp", "horizons", "forecast", "radius50",
                  "radius90", "arrival", "arrival_interval"):
        x, y = getattr(a, field, None), getattr(b, field, None)
        if x is None or y is None:
            assert x is None and y is None, field
        else:
            np.testing.assert_array_equal(x, y, err_msg=field)
    assert a.model == b.model


@pytest.fixture(scope="module")
def sindy_state() -> dict:
    """A sindy tracker's state after 14 frames, one track following an identified model."""
    tr = SindyTracker(PARAMS["sindy"])
    for p, t in _frames(14):
        tr.update(p, t)
    return tr.state()


@pytest.mark.parametrize("name", list(CLASSES))
def test_state_round_trip_through_json_gives_identical_outputs(name):
    frames, k = _frames(22), 14
    cls, params = CLASSES[name], PARAMS[name]
    ref = cls(params)
    for p, t in frames[:k]:
        ref.update(p, t)
    state = ref.state()
    text = json.dumps(state)
    assert json.dumps(json.loads(text)) == text  # plain JSON, stable
    resumed = cls(params)
    resumed.load_state(json.loads(text))
    assert resumed.state() == state
    for p, t in frames[k:]:
        _tracks_equal(resumed.update(p, t), ref.update(p, t))
    if name == "sindy":  # the case that matters: a track follows an identified (non-CV) model at the cut
        assert any(tr["identified"] is not None and tr["motion"]["label"] != "cv" for tr in state["tracks"]), \
            [tr["motion"]["label"] for tr in state["tracks"]]
    if name == "sindy_library":  # likewise with the manoeuvre library's fit in the checkpoint
        assert any(tr["library"] is not None and tr["library"]["label"] != "cv" for tr in state["tracks"]), \
            [tr["library"] and tr["library"]["label"] for tr in state["tracks"]]


@pytest.mark.parametrize("name", list(CLASSES))
def test_fresh_tracker_state_loads(name):
    a = CLASSES[name](PARAMS[name])
    b = CLASSES[name](PARAMS[name])
    b.load_state(json.loads(json.dumps(a.state())))
    p, t = _frames(1)[0]
    _tracks_equal(a.update(p, t), b.update(p, t))


def _corrupt(state: dict, path: list, value) -> dict:
    s = json.loads(json.dumps(state))
    d = s
    for key in path[:-1]:
        d = d[key]
    if value is KeyError:
        del d[path[-1]]
    else:
        d[path[-1]] = value
    return s


@pytest.mark.parametrize("path, value, match", [
    (["tracker"], "NearestTracker", r"the state is 'NearestTracker''s"),
    (["format"], 99, r"state format 99"),
    (["next_id"], KeyError, r"missing key 'next_id'"),
    (["next_id"], -1, r"next_id = -1; expected an integer ≥ 0"),
    (["t_last"], "soon", r"t_last = soon; expected a number or null"),
    (["tracks", 0, "P"], [[1.0, 2.0]], r"tracks\[0\]: P = .*expected an array of shape \(4, 4\)"),
    (["tracks", 0, "x"], ["a", "b", "c", "d"], r"tracks\[0\]: x = .*expected an array"),
    (["tracks", 0, "confirmed"], 1, r"tracks\[0\]: confirmed = 1; expected true or false"),
    (["tracks", 0, "history", 0], [0.0, [1.0, 2.0]], r"history\[0\] must be"),
    (["tracks", 0, "motion", "xi"], [[0.0]], r"motion: xi = .*shape \(2, 2\)"),
    (["tracks"], {"0": 1}, r"tracks = .*expected a list"),
])
def test_a_state_that_is_not_the_trackers_own_is_refused_naming_the_key(sindy_state, path, value, match):
    tr = SindyTracker(PARAMS["sindy"])
    tr.load_state(sindy_state)
    bad = _corrupt(sindy_state, path, value)
    with pytest.raises(InputError, match=match):
        tr.load_state(bad)
    assert tr.state()["tracks"] == [] and tr.state()["t_last"] is None  # refused: reset, nothing half-loaded


def test_identified_fit_shapes_are_checked(sindy_state):
    tr, state = SindyTracker(PARAMS["sindy"]), sindy_state
    i = next(i for i, t in enumerate(state["tracks"]) if t["identified"] is not None)
    with pytest.raises(InputError, match=r"fits\[0\]: theta = .*expected an array of shape"):
        tr.load_state(_corrupt(state, ["tracks", i, "identified", "fits", 0, "theta"], [0.0]))
    with pytest.raises(InputError, match=r"fits\[0\]: mask = .*true/false"):
        tr.load_state(_corrupt(state, ["tracks", i, "identified", "fits", 0, "mask"], [1, 0]))


def test_a_world_frame_identification_of_an_older_checkpoint_is_dropped_not_misread(sindy_state):
    # Before the rotation-invariant library a fit's support was a (2, 2) mask over Ξ's entries; such a
    # model loads as "not identified" (re-identified at the next refit), the track's forecast model kept.
    tr, state = SindyTracker(PARAMS["sindy"]), json.loads(json.dumps(sindy_state))
    i = next(i for i, t in enumerate(state["tracks"]) if t["identified"] is not None)
    for f in state["tracks"][i]["identified"]["fits"]:
        f["mask"] = [[False, True], [True, False]]
        f["theta"] = f["theta"][:4] + [0.1, -0.1]
    tr.load_state(state)
    loaded = tr.state()["tracks"][i]
    assert loaded["identified"] is None and loaded["motion"] == state["tracks"][i]["motion"]


def test_an_exponential_identification_of_an_older_checkpoint_is_dropped_not_misread(sindy_state):
    # Before the constant-acceleration library a fit's θ[4] was the exponential rate α [1/s], not β
    # [m/s²], and the identified model had no "rates": it loads as "not identified", the forecast kept.
    tr, state = SindyTracker(PARAMS["sindy"]), json.loads(json.dumps(sindy_state))
    i = next(i for i, t in enumerate(state["tracks"]) if t["identified"] is not None)
    del state["tracks"][i]["identified"]["rates"]
    tr.load_state(state)
    loaded = tr.state()["tracks"][i]
    assert loaded["identified"] is None and loaded["motion"] == state["tracks"][i]["motion"]


def test_a_tracker_without_a_checkpoint_says_so():
    class Plain(Tracker):
        def update(self, points, timestamp):
            raise AssertionError

    assert not Plain().supports_state and all(c().supports_state for c in CLASSES.values())
    with pytest.raises(PluginError, match="no checkpoint"):
        Plain().state()
    with pytest.raises(PluginError, match="no checkpoint"):
        Plain().load_state({})


def test_sindy_history_keeps_its_doppler_samples_and_reads_the_older_three_field_form(sindy_state):
    # Each history sample is [t, z, R, ĝ, y]: y null where the measurement had no Doppler (the birth
    # sample). A checkpoint written before the identification used Doppler ([t, z, R]) still loads.
    hist = next(t["history"] for t in sindy_state["tracks"] if len(t["history"]) > 3)
    assert all(len(h) == 5 for h in hist) and hist[0][4] is None and all(isinstance(h[4], float) for h in hist[1:])
    old = json.loads(json.dumps(sindy_state))
    for t in old["tracks"]:
        t["history"] = [h[:3] for h in t["history"]]
    tr = SindyTracker(PARAMS["sindy"])
    tr.load_state(old)
    assert all(all(h[4] is None for h in t["history"]) for t in tr.state()["tracks"])
