"""The cross-modality study prints a range ratio only from two measured ranges: a range at the sweep's
farthest distance or below its nearest is a bound of the sweep, and the report says which instead."""
from pathlib import Path

from xnlos_core.app.crossmodal.config import StudyConfig
from xnlos_core.app.crossmodal.study import render_markdown, summarise
from xnlos_core.files import load_toml

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "ablations" / "crossmodal.toml"


def _cfg(distances):
    table = load_toml(CONFIG)
    table["distances"] = distances
    return StudyConfig.model_validate(table)


def _trials(hits: list[float]) -> list[dict]:
    """Trials whose detection and reconstruction hit (F1 1) or miss (F1 0) the hidden car."""
    outcome = lambda hit: {"tp": hit, "fp": False, "fn": not hit}  # noqa: E731
    return [{"detection": outcome(bool(h)), "reconstruction": outcome(bool(h))} for h in hits]


def _study(xband: list[float], spad: list[float], distances=(1.0, 2.0, 4.0)):
    cfg = _cfg(list(distances))
    results = {"xband": {d: _trials([f]) for d, f in zip(distances, xband)},
               "spad/lct": {d: _trials([f]) for d, f in zip(distances, spad)}}
    res = summarise(cfg, results)
    return res, render_markdown(cfg, res, "c.toml")


def test_measured_ranges_give_a_ratio():
    res, md = _study([1.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    assert res["range_ratio"] == {"value": 2.0, "bound": "="} and "ratio xband / spad/lct: 2.0" in md


def test_no_ratio_from_a_bound():
    res, md = _study([1.0, 1.0, 1.0], [1.0, 0.0, 0.0])
    assert res["range_ratio"] is None and "above 4 m" in res["range_ratio_note"]
    assert "No range ratio" in md and "ratio xband / spad/lct:" not in md
    res, md = _study([1.0, 1.0, 0.0], [0.0, 0.0, 0.0])
    assert res["range_ratio"] is None and "below 1 m" in res["range_ratio_note"]
