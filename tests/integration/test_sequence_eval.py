"""`xnlos eval` on sequence datasets: per-frame object truth in shards, tracking metrics in
closed form, a tracked eval end to end on a tiny sequence dataset, and resume per whole sequence."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sims.dataset import load_dataset_config, open_dataset, simulate_dataset
from xnlos_core.app.evaluation import run_eval
from xnlos_core.io import read_jsonl
from xnlos_core.app.sequence_eval import Step, pool, score_sequence, summarize
from xnlos_core.types import HiddenPoints, Tracks

ROOT = Path(__file__).resolve().parents[2]


# --- closed forms ---------------------------------------------------------------------------------

def _steps(n=40, dt=0.1, v=(1.0, 0.0), p0=(10.0, 0.0), forecast=True, drop=(), blind=(), offset=0.0):
    """A road user at p0 + t·v; tracks at the truth (+ ``offset`` in x), exact CV forecasts with radii 0.1 m,
    arrival into the region x ≥ 12 m (t = 2 s); no track in frames ``drop``; no mirror path in ``blind``."""
    v, p0 = np.asarray(v), np.asarray(p0)
    hz = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    out = []
    for k in range(n):
        t = k * dt
        p = p0 + t * v
        truth = {"id": [0], "name": ["car"], "position": [p.tolist()], "velocity": [v.tolist()],
                 "mirror": [k not in blind], "motion": ["straight"]}
        if k in drop:
            tr = Tracks(np.empty(0, np.int64), np.empty((0, 2)), np.empty((0, 2)), np.empty((0, 2)), t)
        else:
            q = p + [offset, 0.0]
            extra = {}
            if forecast:
                extra = {"horizons": hz, "forecast": (q + hz[:, None] * v)[None], "radius50": np.full((1, 6), 0.1),
                         "radius90": np.full((1, 6), 0.1), "model": ("cv",),
                         "arrival": np.array([max(t, 2.0)]), "arrival_interval": np.array([[1.9, 2.1]])}
            tr = Tracks(np.array([7]), q[None], v[None], (q + dt * v)[None], t, **extra)
        out.append(Step(t, truth, tr, HiddenPoints.empty(), None))
    return out


REGION = [[12.0, -5.0], [40.0, -5.0], [40.0, 5.0], [12.0, 5.0]]


def test_perfect_tracks_score_mota_one_and_zero_prediction_error():
    rec = score_sequence(_steps(), threshold=1.0, region=REGION)
    p = pool([{**rec, "family": "f"}])
    assert p["mota"] == 1.0 and p["idf1"] == 1.0 and p["motp"] == pytest.approx(0.0, abs=1e-12)
    assert p["velocity_rmse"] == pytest.approx(0.0, abs=1e-12)
    for src in ("model", "cv"):
        for h in ("1", "2", "3"):
            assert p[src][f"ade@{h}s"] == pytest.approx(0.0, abs=1e-9)
            assert p[src][f"fde@{h}s"] == pytest.approx(0.0, abs=1e-9)
    # Forecasts from frames 0 … 9 reach 3 s within the 3.9 s sequence; 0 … 19 reach 2 s.
    assert p["model"]["n@3s"] == 10 and p["model"]["n@2s"] == 20
    assert p["coverage50"] == 1.0 and p["coverage90"] == 1.0
    # Truth enters x ≥ 12 m at t = 2.0 s: forecasts from t ≥ 0 (within 3 s) and before 2 s are scored.
    assert p["arrival"]["scored"] == 20 and p["arrival"]["mae_s"] == pytest.approx(0.0, abs=1e-9)
    assert p["arrival"]["interval_coverage"] == 1.0


def test_misses_offsets_and_blind_frames_in_closed_form():
    # 10 of 40 frames without a track: MOTA = 1 − 10/40; an offset of 0.5 m: MOTP = 0.5 m, ADE = 0.5 m.
    p = pool([{**score_sequence(_steps(drop=range(10, 20), offset=0.5), 1.0), "family": "f"}])
    assert p["mota"] == pytest.approx(0.75) and p["motp"] == pytest.approx(0.5)
    assert p["model"]["ade@2s"] == pytest.approx(0.5) and p["cv"]["fde@3s"] == pytest.approx(0.5)
    assert p["coverage90"] == 0.0  # 0.5 m off, radius 0.1 m
    # Frames without a mirror path: the truth is not scored there and a track on it is ignored.
    q = pool([{**score_sequence(_steps(blind=range(5)), 1.0), "family": "f"}])
    assert q["counts"]["num_objects"] == 35 and q["counts"]["num_false_positives"] == 0 and q["mota"] == 1.0


def test_a_tracker_without_forecast_reports_model_errors_as_missing_not_zero():
    rec = score_sequence(_steps(forecast=False, offset=0.2), 1.0, region=REGION)
    s = summarize([{**rec, "family": "f", "sequence": 0}])
    o = s["overall"]
    assert o["model"]["ade@2s"] is None and o["coverage90"] is None and o["arrival"]["scored"] == 0
    assert o["cv"]["ade@2s"] == pytest.approx(0.2)
    assert s["motions"]["straight"]["cv"]["fde@1s"] == pytest.approx(0.2)


def test_radial_velocity_rmse_with_and_without_gross_errors_in_closed_form():
    # Two hidden points at 20 m of a car moving at (0, 5) m/s, seen along ĝ = ŷ: radial errors 0.2 m/s
    # and 3 m/s (a point mirrored through the wrong wall). RMSE √((0.04 + 9)/2); without the gross
    # one 0.2 m/s, gross share ½. A record of the older [sse, n] form pools into the RMSE alone.
    from xnlos_core.types import GroundTruth

    ref = np.array([[20.0, 0.0], [20.0, 1.0]])
    gt = GroundTruth(los_points=np.empty((0, 2)), mnlos_points=ref + [10.0, 0.0], hidden_points=ref,
                     mnlos_object=np.array([0, 0]), object_names=("car",), hidden_velocity=np.array([[0.0, 5.0]] * 2),
                     mnlos_velocity=np.array([[0.0, 5.0]] * 2))
    hp = HiddenPoints(ref, np.tile(0.01 * np.eye(2), (2, 1, 1)), [0, 1], [0, 0],
                      velocity=np.array([[0.0, 5.2], [0.0, 8.0]]), velocity_cov=np.tile(0.01 * np.eye(2), (2, 1, 1)))
    steps = _steps(n=1)
    steps[0] = Step(0.0, steps[0].truth, steps[0].tracks, hp, gt)
    rec = {**score_sequence(steps, 1.0), "family": "f"}
    cell = pool([rec])["radial_velocity"]["15–25 m"]
    assert cell["points"] == 2 and cell["rmse"] == pytest.approx(np.sqrt((0.04 + 9.0) / 2))
    assert cell["rmse_without_gross"] == pytest.approx(0.2) and cell["gross_share"] == 0.5
    old = {**rec, "radial": {k: v[:2] for k, v in rec["radial"].items()}}
    both = pool([rec, old])["radial_velocity"]["15–25 m"]
    assert both["points"] == 4 and both["rmse"] == pytest.approx(cell["rmse"]) and both["gross_share"] == 0.5


# --- a tiny sequence dataset, end to end ----------------------------------------------------------

@pytest.fixture(scope="module")
def seq_dataset(tmp_path_factory) -> Path:
    """configs/datasets/sequences_tiny.toml (30 maps: 6 sequences × 5 frames, Doppler, small radar)."""
    out = tmp_path_factory.mktemp("seq")
    simulate_dataset(load_dataset_config(ROOT / "configs/datasets/sequences_tiny.toml"), out, workers=1, progress=False)
    return out


def test_sequence_shards_carry_object_truth_doppler_maps_and_point_velocities(seq_dataset):
    ds = open_dataset(seq_dataset, "train")
    frames = list(ds)
    f = frames[1]
    truth = f.meta["object_truth"]
    assert truth["id"] == [0] and truth["motion"][0] in ("straight", "turning", "braking")
    assert f.ra_map.velocity is not None and f.ra_map.velocity.shape == f.ra_map.data.shape
    assert f.ground_truth.hidden_velocity is not None
    # LOS range rates (GroundTruth.los_radial_velocity) come back row-aligned, from the frame meta's Doppler truth.
    for g in frames:
        lrv = g.ground_truth.los_radial_velocity
        assert lrv is not None and lrv.shape == (len(g.ground_truth.los_points),)
        np.testing.assert_array_equal(lrv, g.meta["doppler"]["los_radial_velocity"])
    # Centres move with the recorded velocity (a straight or braking road user over one 0.2 s step).
    same = [g for g in frames if g.meta["scene_index"] == f.meta["scene_index"]]
    p = np.array([g.meta["object_truth"]["position"][0] for g in same])
    v = np.array([g.meta["object_truth"]["velocity"][0] for g in same])
    assert np.allclose(np.diff(p, axis=0), 0.2 * (v[:-1] + v[1:]) / 2, atol=0.05)
    # mirror = the object owns mNLOS ground-truth points.
    for g in frames:
        owns = len(g.ground_truth.mnlos_points) > 0 and "hidden0" in "".join(g.ground_truth.object_names)
        assert g.meta["object_truth"]["mirror"][0] == owns


def _config(tmp_path: Path, dataset: Path, tracker: str = "kalman") -> Path:
    p = tmp_path / "track.toml"
    # The train split of the tiny dataset holds the car that is seen (frames 1–4 of its sequence).
    p.write_text(f'name = "tiny-track"\n[backend]\nname = "dataset"\nparams = {{ path = "{dataset}", split = "train" }}\n'
                 '[detector]\nname = "nlos_cfar"\nparams = { pfa = 1e-5 }\n[wall_estimator]\nname = "lsq"\n'
                 '[reconstructor]\nname = "mirror"\n[tracker]\nname = "kalman"\n[run]\nmatch_radius = 2.0\n'
                 f'[sweep]\n"tracker.name" = ["{tracker}"]\n')
    return p


@pytest.mark.parametrize("tracker", ["nearest", "kalman"])
def test_eval_with_a_tracker_scores_sequences(seq_dataset, tmp_path, tracker):
    res = run_eval(_config(tmp_path, seq_dataset, tracker), tmp_path / "ev", figures=0, progress=False)
    run = res["runs"][0]
    t = run["tracking"]["overall"]
    assert t["sequences"] == 2 and t["frames"] == 10 and run["overall"]["maps"] == 10
    assert np.isfinite(t["mota"]) and np.isfinite(t["idf1"]) and t["counts"]["num_objects"] > 0
    for key in ("ade@1s", "fde@1s", "ade@2s", "fde@2s", "ade@3s", "fde@3s"):
        assert key in t["model"] and key in t["cv"]
    assert set(run["tracking"]["families"]) == {"hidden_car_approach", "hidden_cyclist"}
    md = (tmp_path / "ev" / "eval.md").read_text()
    assert "## Tracking (sequences)" in md and "2 s-ahead error by motion" in md
    seqs = read_jsonl(tmp_path / "ev" / "run-000" / "sequences.jsonl")
    assert [s["sequence"] for s in seqs] == sorted(s["sequence"] for s in seqs) and len(seqs) == 2


def test_a_killed_sequence_eval_resumes_per_whole_sequence(seq_dataset, tmp_path):
    cfg = _config(tmp_path, seq_dataset)
    full = run_eval(cfg, tmp_path / "a", figures=0, progress=False)["runs"][0]["tracking"]
    run_eval(cfg, tmp_path / "b", figures=0, progress=False)
    d = tmp_path / "b" / "run-000"
    # Killed in the second sequence: its sequence line is missing and only 2 of its 5 map lines made it.
    seqs = (d / "sequences.jsonl").read_text().splitlines(keepends=True)
    (d / "sequences.jsonl").write_text(seqs[0])
    maps = (d / "frames.jsonl").read_text().splitlines(keepends=True)
    (d / "frames.jsonl").write_text("".join(maps[:7]) + maps[7][:20])  # + a torn line
    (tmp_path / "b" / "eval.json").unlink()
    resumed = run_eval(cfg, tmp_path / "b", figures=0, progress=False)["runs"][0]
    assert json.dumps(resumed["tracking"], sort_keys=True) == json.dumps(full, sort_keys=True)
    recs = read_jsonl(d / "frames.jsonl")
    assert [r["position"] for r in sorted(recs, key=lambda r: r["position"])] == list(range(10))
    assert len(read_jsonl(d / "sequences.jsonl")) == 2


def test_a_larger_limit_redoes_a_sequence_the_smaller_one_cut(seq_dataset, tmp_path):
    cfg = _config(tmp_path, seq_dataset)
    full = run_eval(cfg, tmp_path / "a", figures=0, progress=False)["runs"][0]["tracking"]
    cut = run_eval(cfg, tmp_path / "b", figures=0, progress=False, limit=7)["runs"][0]
    assert cut["tracking"]["overall"]["frames"] == 7  # 5 + the first 2 maps of the second sequence
    grown = run_eval(cfg, tmp_path / "b", figures=0, progress=False)["runs"][0]
    assert json.dumps(grown["tracking"], sort_keys=True) == json.dumps(full, sort_keys=True)
    assert sorted(r["position"] for r in read_jsonl(tmp_path / "b" / "run-000" / "frames.jsonl")) == list(range(10))


def test_a_run_over_several_sequences_tracks_each_on_its_own(seq_dataset, tmp_path):
    """`xnlos run` over a split of 2 sequences (timestamps start again at 0 in the second): the
    pipeline resets its tracker and wall history at the second sequence's first frame, so the run
    finishes (the tracker refused the decreasing time before) and the second sequence's tracks are
    those of a pipeline that sees that sequence alone."""
    from xnlos_core.config import parse_pipeline
    from xnlos_core.pipeline import Pipeline
    from xnlos_core.app.runner import run_to_dir

    table = {"name": "two-sequences", "backend": {"name": "dataset", "params": {"path": str(seq_dataset),
                                                                               "split": "test"}},
             "detector": {"name": "oracle"}, "wall_estimator": {"name": "lsq", "params": {"history_frames": 3}},
             "reconstructor": {"name": "mirror"}, "tracker": {"name": "kalman"},
             "run": {"frames": 10, "figure": False}}
    cfg = parse_pipeline(table, str(tmp_path / "two.toml"))
    run_to_dir(cfg, tmp_path / "run", progress=False)
    rows = read_jsonl(tmp_path / "run" / "results.jsonl")
    assert len(rows) == 10
    pipe = Pipeline(cfg)
    frames = list(pipe.frames())
    assert [f.meta["frame_in_scene"] for f in frames] == [0, 1, 2, 3, 4] * 2
    alone = Pipeline(cfg)
    tracks = [alone.process(f).tracks for f in frames[5:]]
    for row, t in zip(rows[5:], tracks):
        assert row["tracks"]["id"] == t.track_id.tolist()
        np.testing.assert_allclose(row["tracks"]["position"], t.position.reshape(-1, 2).tolist())
    assert any(len(t.track_id) for t in tracks), "no track in the second sequence: the test cannot tell"
