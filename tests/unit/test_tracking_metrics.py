"""MOTA/MOTP/IDF1 (motmetrics), ADE/FDE and interval coverage on hand-made sequences."""
import numpy as np
import pytest

from xnlos_core import InputError
from xnlos_core.app.tracking_metrics import interval_coverage, mot_metrics, prediction_errors


def frames(ids_per_frame, x_per_frame):
    return [(ids, np.c_[xs, np.zeros(len(xs))]) for ids, xs in zip(ids_per_frame, x_per_frame)]


def test_perfect_tracking():
    truth = frames([[1, 2]] * 4, [[0.0, 10.0]] * 4)
    hyp = frames([[7, 8]] * 4, [[0.1, 10.3]] * 4)
    m = mot_metrics(truth, hyp, threshold=1.0)
    assert m["mota"] == 1.0 and m["idf1"] == 1.0 and m["num_switches"] == 0
    assert m["motp"] == pytest.approx(0.2)  # mean of 0.1 and 0.3 m


def test_one_id_switch_hand_computed():
    # One object over 4 frames; the hypothesis id changes 5 → 6 after frame 2.
    # MOTA = 1 − 1 switch / 4 = 0.75; IDF1 = 2·2 / (4 + 4) = 0.5 (best mapping keeps 2 of 4 frames).
    truth = frames([[1]] * 4, [[0.0]] * 4)
    hyp = frames([[5], [5], [6], [6]], [[0.0]] * 4)
    m = mot_metrics(truth, hyp, threshold=1.0)
    assert m["num_switches"] == 1
    assert m["mota"] == pytest.approx(0.75) and m["idf1"] == pytest.approx(0.5)


def test_miss_and_false_positive_beyond_threshold():
    # Frame 2's hypothesis is 2 m off (threshold 1 m): one miss and one false positive.
    truth = frames([[1]] * 2, [[0.0], [0.0]])
    hyp = frames([[5]] * 2, [[0.0], [2.0]])
    m = mot_metrics(truth, hyp, threshold=1.0)
    assert (m["num_misses"], m["num_false_positives"], m["num_matches"]) == (1, 1, 1)
    assert m["mota"] == pytest.approx(0.0)  # 1 − 2/2
    assert m["idf1"] == pytest.approx(0.5)  # 2·1 / (2 + 2)


def test_ade_fde():
    h = [1.0, 2.0, 3.0]
    truth = np.zeros((2, 3, 2))
    pred = np.zeros((2, 3, 2))
    pred[0, :, 0] = [1.0, 2.0, 3.0]   # error grows 1 m/s
    pred[1, :, 1] = [0.0, 0.0, 6.0]
    e = prediction_errors(pred, truth, h)
    assert e["fde@1s"] == pytest.approx(0.5) and e["fde@3s"] == pytest.approx(4.5)
    assert e["ade@2s"] == pytest.approx((1 + 2 + 0 + 0) / 4)
    assert e["ade@3s"] == pytest.approx((1 + 2 + 3 + 6) / 6)


def test_coverage():
    c = np.zeros((4, 2))
    truth = np.array([[0.5, 0.0], [0.0, 1.5], [2.0, 0.0], [0.0, 0.9]])
    assert interval_coverage(c, np.ones(4), truth) == 0.5


def test_errors_name_the_input():
    with pytest.raises(InputError, match="threshold"):
        mot_metrics([], [], 0.0)
    with pytest.raises(InputError, match="frames"):
        mot_metrics(frames([[1]], [[0.0]]), [], 1.0)
    with pytest.raises(InputError, match="twice"):
        mot_metrics(frames([[1, 1]], [[0.0, 1.0]]), frames([[1]], [[0.0]]), 1.0)
    with pytest.raises(InputError, match="horizon 2.0 s is not among"):
        prediction_errors(np.zeros((1, 2, 2)), np.zeros((1, 2, 2)), [0.5, 1.0])
    with pytest.raises(InputError, match="truth"):
        interval_coverage(np.zeros((2, 2)), np.ones(2), np.zeros((3, 2)))


def test_pooled_motp_is_motmetrics_overall_motp_with_an_id_switch():
    # Sequence A: one object, 4 frames, distances 0.2, 0.4, 0.6, 0.8 m, the hypothesis id changing 5 → 6 at
    # frame 2 (a SWITCH event, whose distance counts); sequence B: one match at 0.1 m. motmetrics:
    # MOTP = Σd / (matches + switches): A (0.2 + 0.4 + 0.6 + 0.8) / (3 + 1) = 0.5, pooled 2.1 / 5 = 0.42 m.
    # Weighting by matches only (3 + 1) would give (0.5·3 + 0.1) / 4 = 0.4 m.
    import motmetrics as mm

    from xnlos_core.app.sequence_eval import RANGE_BINS, pool
    from xnlos_core.app.tracking_metrics import mot_matches

    seqs = [(frames([[1]] * 4, [[0.0]] * 4), frames([[5], [5], [6], [6]], [[0.2], [0.4], [0.6], [0.8]])),
            (frames([[1]], [[0.0]]), frames([[9]], [[0.1]]))]
    accs, recs = [], []
    for truth, hyp in seqs:
        acc = mm.MOTAccumulator(auto_id=True)
        for (oid, opos), (hid, hpos) in zip(truth, hyp):
            acc.update(list(oid), list(hid), np.linalg.norm(opos[:, None] - hpos[None], axis=-1))
        accs.append(acc)
        m, _ = mot_matches(truth, hyp, threshold=1.0)
        recs.append({"frames": len(truth), "mot": m, "velocity": [0.0, 0], "forecasts": [], "arrivals": [],
                     "radial": {b[2]: [0.0, 0] for b in RANGE_BINS}})
    want = mm.metrics.create().compute_many(accs, metrics=["motp"], generate_overall=True).loc["OVERALL", "motp"]
    assert recs[0]["mot"]["num_switches"] == 1 and recs[0]["mot"]["num_matches"] == 3
    assert recs[0]["mot"]["motp"] == pytest.approx(0.5) and recs[0]["mot"]["motp_sum"] == pytest.approx(2.0)
    assert want == pytest.approx(0.42)
    assert pool(recs)["motp"] == pytest.approx(want, rel=1e-12)


def test_ghosts_are_hidden_points_within_2_m_of_no_object_and_pool_as_a_rate():
    from xnlos_core.app.sequence_eval import Step, _ghost_summary, ghosts
    from xnlos_core.types import HiddenPoints

    mean = np.array([[10.0, 5.0],     # 1.5 m from the car's centre: not a ghost
                     [20.0, -3.0],    # 0.5 m from a static hidden surface point: not a ghost
                     [30.0, 8.0],     # 2.5 m from the nearest object: a ghost
                     [40.0, 40.0]])   # far from everything: a ghost
    hp = HiddenPoints(mean, np.tile(np.eye(2), (4, 1, 1)), np.arange(4), np.zeros(4, int), gated=np.array([7, 9]))
    step = Step(0.0, {"position": [[10.0, 6.5], [30.0, 5.5]]}, None, hp, None)
    assert ghosts(step) == (3, 4, 2)  # without ground truth the static surface is unknown
    from xnlos_core.types import GroundTruth

    gt = GroundTruth(los_points=np.empty((0, 2)), mnlos_points=np.array([[20.0, -3.5]]),
                     hidden_points=np.array([[20.0, -3.5]]))
    step = Step(0.0, {"position": [[10.0, 6.5], [30.0, 5.5]]}, None, hp, gt)
    assert ghosts(step) == (2, 4, 2)
    assert ghosts(Step(0.0, {"position": []}, None, HiddenPoints.empty(), None)) == (0, 0, 0)
    assert _ghost_summary([[2, 4, 2], [1, 6, 0]]) == {"ghosts": {"rate": 0.3, "ghosts": 3, "points": 10, "gated": 2}}
    assert _ghost_summary([]) == {}
