"""The cross-modality study prints a range ratio only from two measured ranges: a row whose seeds
reached the bisection's upper bound (still in range) or failed at its lower bound is a bound of the
sweep, and the report says which instead of a number; measured ranges give a ratio with a seeded
bootstrap interval."""
from pathlib import Path

from xnlos_core.app.crossmodal.config import StudyConfig
from xnlos_core.app.crossmodal.study import render_markdown, summarise
from xnlos_core.files import load_toml

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "ablations" / "crossmodal.toml"


def _cfg():
    table = load_toml(CONFIG)
    table["distances"] = [1.0, 2.0, 4.0]
    table["ratios"] = [["xband", "spad_night/fk"]]
    return StudyConfig.model_validate(table)


def _trial(hit: bool) -> dict:
    outcome = {"tp": hit, "fp": False, "fn": not hit}
    return {"detection": outcome, "reconstruction": outcome}


def _runs(ranges) -> list[dict]:
    """Per-seed bisection records: a number is a bracketed range, '>' the upper bound, '<' the lower."""
    out = []
    for r in ranges:
        if r == ">":
            out.append({"range": 150.0, "lo": 150.0, "hi": None, "status": "above", "evaluations": []})
        elif r == "<":
            out.append({"range": None, "lo": None, "hi": 0.5, "status": "below", "evaluations": []})
        else:
            out.append({"range": r, "lo": r, "hi": r * 1.02, "status": "bracketed", "evaluations": []})
    return out


def _study(xband, spad):
    cfg = _cfg()
    grid = {d: [_trial(True)] for d in cfg.distances}
    res = summarise(cfg, {"xband": grid, "spad_night/fk": grid}, {"xband": _runs(xband), "spad_night/fk": _runs(spad)})
    return res, render_markdown(cfg, res, "c.toml")


def test_measured_ranges_give_a_ratio_with_an_interval():
    res, md = _study([40.0, 44.0, 36.0, 40.0, 42.0], [2.0, 2.0, 2.1, 1.9, 2.0])
    q = res["ratios"][0]
    assert q["value"] == 20.0 and q["note"] is None
    assert q["interval"]["low"] < 20.0 < q["interval"]["high"]
    assert res["range_ratio"]["value"] == 20.0 and res["range_ratio_note"] is None
    assert "| xband / spad_night/fk | 20.00 | [" in md
    again, _ = _study([40.0, 44.0, 36.0, 40.0, 42.0], [2.0, 2.0, 2.1, 1.9, 2.0])
    assert again["ratios"] == res["ratios"]  # seeded bootstrap


def test_no_ratio_from_a_bound():
    res, md = _study([">", ">", ">", ">"], [2.0, 2.0, 2.0, 2.0])
    assert res["range_ratio"] is None and "above 150 m" in res["range_ratio_note"]
    assert res["rows"]["xband"]["range_to_failure"]["status"] == "above"
    assert "≥ 150 (upper bound reached)" in md and "| xband / spad_night/fk | — | — |" in md
    assert "No range ratio: the sweep's bound was reached" in md
    res, md = _study([40.0, 44.0, 36.0, 40.0], ["<", "<", "<", "<"])
    assert res["range_ratio"] is None and "below 0.5 m" in res["range_ratio_note"]
    # the median is a bound as soon as it falls on a censored seed (here 3 of 4 above) ...
    res, md = _study([40.0, ">", ">", ">"], [2.0, 2.0, 2.0, 2.0])
    assert res["rows"]["xband"]["range_to_failure"]["status"] == "above"
    assert res["ratios"][0]["value"] is None and "3/4 seed(s)" in res["range_ratio_note"]
    assert "| xband / spad_night/fk | — | — |" in md
    # ... and a measurement while it falls on a bracketed one; an interval end on a censored seed is a bound
    res, md = _study([40.0, ">", 36.0, 40.0], [2.0, 2.0, 2.0, 2.0])
    x = res["rows"]["xband"]["range_to_failure"]
    assert x["status"] == "measured" and x["interval"]["value"] == 40.0 and x["n_above"] == 1
    assert res["ratios"][0]["value"] == 20.0
    assert "| xband | 40.00 | [36.00, ≥ 150] |" in md


def test_the_report_marks_its_tables_for_the_benchmark_page():
    """crossmodal.md marks every seeded table as benchmarks/pages.py reads them (the study writes the
    markers itself: the core imports nothing from benchmarks/), so benchmarks/crossmodal.md's tables
    are compared with a rerun; a changed cell is a difference."""
    from benchmarks.pages import compare, marked, tables
    from xnlos_core.app.crossmodal.study import marked as study_marked

    assert study_marked("t", ["| a |"]) == marked("t", ["| a |"])
    _, md = _study([40.0, ">", ">", ">"], [2.0, 2.0, 2.0, 2.0])
    got = tables(md)
    assert set(got) == {"ranges", "ratios", "ratio_notes", "f1_grid"}
    assert got["ratios"] == ["| ratio | value | 95 % interval |", "|---|---|---|",
                             "| xband / spad_night/fk | — | — |"]
    assert "3/4 seed(s)" in got["ratio_notes"][0]
    assert [ln.split(" |")[0] for ln in got["f1_grid"][2:]] == ["| xband", "| spad_night/fk"]
    _, measured = _study([40.0, 44.0, 36.0, 40.0, 42.0], [2.0, 2.0, 2.1, 1.9, 2.0])
    assert "ratio_notes" not in tables(measured) and compare(measured, measured) == []
    assert compare(measured, measured.replace("| xband | 40.00 |", "| xband | 40.02 |"))
