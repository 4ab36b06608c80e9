"""`xnlos eval`: the dataset backend, aggregation conventions, sweep cases, resume, figures, Table 2 end to end."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from sims.dataset import open_dataset
from xnlos_core import LOS, MNLOS, Detections, GroundTruth
from xnlos_core.app.cli import main
from xnlos_core.config import expand_sweep
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.app.evaluation import PAPER_TABLE2, aggregate, run_eval
from xnlos_core.io import read_jsonl
from xnlos_core.metrics import dense_metrics
from xnlos_core.registry import get_registry

ROOT = Path(__file__).resolve().parents[2]
PNG = b"\x89PNG\r\n\x1a\n"


# --- aggregation and empty-set conventions --------------------------------------------------------

def _rec(family, f1, cd, classified=True, t=1.0):
    m = {k: None for k in ("dense.los.f1", "dense.mnlos.f1", "dense.all.f1", "dense.los.cd", "dense.mnlos.cd",
                           "dense.all.cd", "reconstruction.f1", "reconstruction.cd", "reconstruction.precision",
                           "reconstruction.recall")}
    m.update({"dense.macro.f1": f1, "dense.macro.cd": cd, "reconstruction.f1": f1, "reconstruction.cd": cd})
    return {"family": family, "metrics": m, "classified": classified,
            "timings_ms": {"source": 5.0, "detector": t, "reconstructor": 2 * t}}


def test_aggregate_means_f1_over_maps_and_cd_over_finite_maps():
    recs = [_rec("a", 1.0, 0.0), _rec("a", 0.0, math.inf, t=3.0), _rec("b", 0.5, 4.0, t=5.0)]
    agg = aggregate(recs)
    assert agg["maps"] == 3 and agg["classified"]
    assert agg["metrics"]["dense.macro.f1"] == pytest.approx(0.5)            # (1 + 0 + 0.5) / 3
    assert agg["metrics"]["dense.macro.cd"] == pytest.approx(2.0)            # (0 + 4) / 2: inf left out
    assert agg["cd_maps"]["dense.macro.cd"] == 2
    assert agg["metrics"]["dense.los.cd"] is None and agg["cd_maps"]["dense.los.cd"] == 0
    assert agg["time_ms"]["detector"] == {"median": 3.0, "mean": 3.0}
    assert agg["time_ms"]["processing"]["mean"] == pytest.approx(9.0)      # 3·t without the source
    assert aggregate([_rec("a", math.nan, math.inf)])["metrics"]["dense.macro.cd"] is None


def test_dense_metrics_of_empty_maps_follow_the_documented_conventions():
    e = np.empty((0, 2))
    gt_empty = GroundTruth(e, e, e, np.empty(0, np.int64), (), ())
    gt_one = GroundTruth(np.array([[5.0, 0.0]]), e, e, np.empty(0, np.int64), (), ())
    both = dense_metrics(Detections.empty(), gt_empty, 1.0)
    assert both["los"]["f1"] == 1.0 and both["los"]["cd"] == 0.0 and both["macro"]["f1"] == 1.0
    missed = dense_metrics(Detections.empty(), gt_one, 1.0)  # LOS truth, no prediction; mNLOS both empty
    assert missed["los"]["f1"] == 0.0 and missed["los"]["cd"] == math.inf
    assert missed["macro"]["f1"] == 0.5 and missed["macro"]["cd"] == math.inf
    false_alarm = dense_metrics(Detections.from_points([[5.0, 0.0], [9.0, 1.0]], label=MNLOS), gt_one, 1.0)
    assert false_alarm["mnlos"]["f1"] == 0.0 and false_alarm["mnlos"]["cd"] == math.inf
    hit = dense_metrics(Detections.from_points([[5.0, 0.5], [20.0, 0.0]], label=LOS), gt_one, 1.0)
    # one of two predictions matched: P = 1/2, R = 1 → F1 = 2/3; CD = (0.25 + 15²)/2 + 0.25
    assert hit["los"]["f1"] == pytest.approx(2 / 3) and hit["los"]["cd"] == pytest.approx((0.25 + 225) / 2 + 0.25)


# --- [[sweep.cases]] ------------------------------------------------------------------------------

def test_sweep_cases_times_grid_and_validation():
    base = {"name": "b", "detector": {"name": "cfar", "params": {"pfa": 1e-3}}, "reconstructor": {"name": "mirror"}}
    t = dict(base, sweep={"cases": [{"name": "x", "detector.name": "nlos_cfar"}, {"name": "y"}], "seed": [1, 2]})
    points = expand_sweep(t, "s.toml")
    assert [a for a, _ in points] == [{"name": "x", "detector.name": "nlos_cfar", "seed": 1},
                                      {"name": "x", "detector.name": "nlos_cfar", "seed": 2},
                                      {"name": "y", "seed": 1}, {"name": "y", "seed": 2}]
    assert points[0][1]["detector"] == {"name": "nlos_cfar", "params": {}}   # another plugin: params reset
    assert points[2][1]["detector"] == base["detector"] and points[3][1]["seed"] == 2
    for sweep, msg in (({"cases": []}, "non-empty list of tables"), ({"cases": [{}]}, "#0: an empty case"),
                       ({"cases": [{"detectr.name": "x"}]}, "'detectr' is not a pipeline key"),
                       ({"cases": [{"seed": 1}], "seed": [2]}, "both a grid key and a key of")):
        with pytest.raises(ConfigError, match=re.escape(msg)):
            expand_sweep(dict(base, sweep=sweep), "s.toml")


# --- the dataset backend --------------------------------------------------------------------------

def test_dataset_backend_round_trips_frames_and_ground_truth(tiny_dataset):
    want = list(open_dataset(tiny_dataset, "test"))
    b = get_registry().create("backend", "dataset", {"path": str(tiny_dataset), "split": "test"})
    got = list(b.frames())
    assert b.n_frames == len(got) == len(want) == 4
    for f, g in zip(got, want):
        assert f.index == g.index and f.meta["family"] == g.meta["family"]
        assert np.array_equal(f.ra_map.data, g.ra_map.data)
        for a in ("los_points", "mnlos_points", "hidden_points", "mnlos_object"):
            assert np.array_equal(getattr(f.ground_truth, a), getattr(g.ground_truth, a)), a
    part = get_registry().create("backend", "dataset", {"path": str(tiny_dataset), "split": "test", "start": 1,
                                                        "limit": 2})
    assert [f.index for f in part.frames()] == [g.index for g in want[1:3]] and part.n_frames == 2
    assert [f.index for f in part.frames(1)] == [want[1].index]
    assert len(list(get_registry().create("backend", "dataset", {"path": str(tiny_dataset), "split": "all"})
                    .frames())) == 8


def test_dataset_backend_errors_name_the_input(tiny_dataset, tmp_path):
    with pytest.raises(ConfigError, match=r"params.split.*'train', 'val', 'test' or 'all'"):
        get_registry().create("backend", "dataset", {"path": str(tiny_dataset), "split": "tset"})
    missing = get_registry().create("backend", "dataset", {"path": str(tmp_path / "nope")})
    with pytest.raises(InputError, match="params.path .*nope.* is not a directory"):
        list(missing.frames())
    with pytest.raises(InputError, match="holds no manifest.json"):
        list(get_registry().create("backend", "dataset", {"path": str(tmp_path)}).frames())
    with pytest.raises(InputError, match="past the end of split 'test'"):
        list(get_registry().create("backend", "dataset", {"path": str(tiny_dataset), "start": 9}).frames())


# --- xnlos eval -----------------------------------------------------------------------------------

def test_eval_cli_end_to_end_resume_and_figures(tiny_dataset, tmp_path, capsys, eval_config):
    cfg, out = eval_config(tmp_path, tiny_dataset), tmp_path / "out"
    assert main(["eval", str(cfg), "--out", str(out), "--limit", "3", "--figures", "1", "-q"]) == 0
    assert capsys.readouterr().out == ""  # -q: the table is in eval.md, not on stdout
    assert "Table 2" in (out / "eval.md").read_text()
    res = json.loads((out / "eval.json").read_text())
    (run,) = res["runs"]
    assert run["overall"]["maps"] == 3 and run["dataset"]["split"] == "test"
    assert set(run["families"]) <= {"corner_a", "corner_b", "corner_c"}
    assert sum(a["maps"] for a in run["families"].values()) == 3
    assert 0.0 <= run["overall"]["metrics"]["dense.macro.f1"] <= 1.0
    assert {"detector", "wall_estimator", "processing"} <= set(run["overall"]["time_ms"])
    fig = out / "run-000" / run["figures"][0]
    assert len(run["figures"]) == 1 and fig.read_bytes()[:8] == PNG
    md = (out / "eval.md").read_text()
    assert "| 0 | tiny-eval | nlos_cfar → mirror | 3 |" in md and "## Per scene family" in md

    # A killed eval: one complete record and a torn line; the rerun scores only what is missing.
    log = out / "run-000" / "frames.jsonl"
    full = read_jsonl(log)
    log.write_text(json.dumps(full[0]) + "\n" + '{"position": 1, "met')
    assert main(["eval", str(cfg), "--out", str(out), "--limit", "3", "--figures", "1", "-q"]) == 0
    again = read_jsonl(log)
    assert [r["position"] for r in again] == [0, 1, 2]
    assert [r["metrics"] for r in again] == [r["metrics"] for r in full]
    assert json.loads((out / "eval.json").read_text())["runs"][0]["overall"]["metrics"] == run["overall"]["metrics"]
    # A larger limit extends the same records; another pipeline in the same --out is refused.
    assert main(["eval", str(cfg), "--out", str(out), "--no-figures", "-q"]) == 0
    assert [r["position"] for r in read_jsonl(log)] == [0, 1, 2, 3]
    other = eval_config(tmp_path, tiny_dataset, "[run]\nmatch_radius = 2.0\n")
    capsys.readouterr()
    assert main(["eval", str(other), "--out", str(out), "-q"]) == 2
    assert "another configuration" in capsys.readouterr().err


def test_eval_refuses_to_resume_with_other_learned_weights(tiny_dataset, tmp_path, capsys, eval_config,
                                                           tiny_checkpoint):
    ckpt = tmp_path / "unet.pt"
    tiny_checkpoint(ckpt, "unet", seed=0)
    cfg = eval_config(tmp_path, tiny_dataset).read_text().replace('name = "nlos_cfar"', f'name = "unet"\n'
                                                                f'params = {{ checkpoint = "{ckpt}", device = "cpu" }}')
    p, out = tmp_path / "learned.toml", tmp_path / "out"
    p.write_text(cfg)
    assert main(["eval", str(p), "--out", str(out), "--limit", "2", "--no-figures", "-q"]) == 0
    state = json.loads((out / "run-000" / "run.json").read_text())["state_sha256"]
    assert set(state) == {"detector"}
    tiny_checkpoint(ckpt, "unet", seed=1)  # retrained into the same file; the config is unchanged
    capsys.readouterr()
    assert main(["eval", str(p), "--out", str(out), "--limit", "2", "--no-figures", "-q"]) == 2
    assert f"other learned weights (detector {state['detector'][:12]}" in capsys.readouterr().err
    assert main(["eval", str(p), "--out", str(out), "--limit", "2", "--no-figures", "-q", "--overwrite"]) == 0
    assert json.loads((out / "run-000" / "run.json").read_text())["state_sha256"] != state


@pytest.mark.filterwarnings("ignore::xnlos_core.errors.GridMismatchWarning")  # the shipped models on a small test radar
def test_table2_sweep_end_to_end_on_a_tiny_dataset(tiny_dataset, tmp_path):
    # the tiny dataset's radar is not the one the shipped models were trained on: they are refused
    # unless each learned case runs anyway (allow_mismatch)
    text = re.sub(r'("detector.name" = "(?:rtn|further_than_cfar|unet|swin_unet)")',
                  r'\1\n"detector.params.allow_mismatch" = true', (ROOT / "configs/ablations/table2.toml").read_text())
    (tmp_path / "table2.toml").write_text(text)
    res = run_eval(tmp_path / "table2.toml", tmp_path / "out", dataset=str(tiny_dataset),
                   split="test", limit=2, figures=1, progress=False)
    assert [r["name"] for r in res["runs"]] == list(PAPER_TABLE2)  # every row, residual_mirror included
    md = (tmp_path / "out" / "eval.md").read_text()
    assert "| 0 | NLOS-CFAR | nlos_cfar → mirror | 2 | " in md and "(0.23)" in md and "(29.7)" in md
    for r in res["runs"]:
        assert r["overall"]["maps"] == 2 and len(r["figures"]) == 1
        assert (tmp_path / "out" / r["dir"] / r["figures"][0]).read_bytes()[:8] == PNG
    # the learned rows ran off their training set-up: the table says so, also when fully resumed
    learned = {"rtn", "further_than_cfar", "unet", "swin_unet"}
    assert all(bool(r["setup_differs"]) == (r["detector"] in learned) for r in res["runs"])
    assert "DIFFERS" in md
    again = run_eval(tmp_path / "table2.toml", tmp_path / "out", dataset=str(tiny_dataset),
                     split="test", limit=2, figures=1, progress=False)
    assert [bool(r["setup_differs"]) for r in again["runs"]] == [bool(r["setup_differs"]) for r in res["runs"]]


def test_table2_config_checks():
    assert main(["check", str(ROOT / "configs/ablations/table2.toml")]) == 0


def test_maps_are_scored_alone_whatever_a_stage_carries(tiny_dataset, tmp_path, eval_config):
    """A map eval resets the pipeline before each map: lsq pooling 4 frames scores every map as it
    scores it alone (the tiny dataset's maps are four different scenes)."""
    plain = eval_config(tmp_path, tiny_dataset)
    pooled = tmp_path / "pooled.toml"
    pooled.write_text(plain.read_text().replace('[wall_estimator]\nname = "lsq"\n',
                                                '[wall_estimator]\nname = "lsq"\nparams = { history_frames = 4 }\n'))
    assert "history_frames" in pooled.read_text()
    a = run_eval(plain, tmp_path / "a", figures=0, progress=False)
    b = run_eval(pooled, tmp_path / "b", figures=0, progress=False)
    assert b["runs"][0]["overall"]["maps"] == 4
    strip = lambda rows: [{k: v for k, v in r.items() if k != "timings_ms"} for r in rows]  # noqa: E731
    assert strip(read_jsonl(tmp_path / "a" / "run-000" / "frames.jsonl")) == \
        strip(read_jsonl(tmp_path / "b" / "run-000" / "frames.jsonl"))
