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
