"""Cross-modality study: F1 scoring on hand-made inputs, the tiny study end to
end, typed errors for bad config keys."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from xnlos_core.app.crossmodal import score as cs
from xnlos_core.app.crossmodal.study import load_study, run_study, scene_table
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.transient import SPEED_OF_LIGHT

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "ablations" / "crossmodal.toml"

BOX = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])


def test_f1_rate_closed_forms():
    hit = cs.Outcome(True, False, False)
    miss = cs.Outcome(False, False, True)
    wrong = cs.Outcome(False, True, True)
    assert cs.f1_rate([hit, hit]) == 1.0
    assert cs.f1_rate([hit, miss]) == pytest.approx(2 / 3)  # 2·1 / (2·1 + 0 + 1)
    assert cs.f1_rate([hit, wrong]) == pytest.approx(0.5)  # 2 / (2 + 1 + 1)
    assert cs.f1_rate([miss, wrong]) == 0.0
    assert cs.f1_rate([]) is None
    assert cs.f1_rate([{"tp": True, "fp": True, "fn": False}]) == pytest.approx(2 / 3)


def test_outcome_and_max_range():
    o = cs.outcome(np.array([0.5, 3.0]), 1.0)
    assert (o.tp, o.fp, o.fn, o.n_reports) == (True, True, False, 2)
    assert cs.outcome(np.zeros(0), 1.0) == cs.Outcome(False, False, True, 0)
    assert cs.max_range([1, 2, 5, 10], [1.0, 0.6, 0.4, 0.5]) == 10
    assert cs.max_range([1, 2], [0.2, None]) is None
    with pytest.raises(InputError, match="NaN"):
        cs.outcome(np.array([np.nan]), 1.0)


def test_distance_to_footprint_and_mirror():
    d = cs.distance_to_footprint([[1.0, 0.5], [3.0, 0.5], [1.0, -2.0], [3.0, 4.0]], BOX)
    np.testing.assert_allclose(d, [0.0, 1.0, 2.0, math.hypot(1.0, 3.0)])
    # mirror across the line x + y = 25 (wall (15, 10) → (35, −10)): (22, −14) ↦ (39, 3)
    np.testing.assert_allclose(cs.mirror_points([[22.0, -14.0]], (15, 10), (35, -10)), [[39.0, 3.0]])
    img = cs.outline_points(BOX, 0.5)
    assert len(img) == 2 * (4 + 2) and np.all(cs.distance_to_footprint(img, BOX) < 1e-12)


def test_radar_trials():
    fp = BOX + [10.0, -5.0]
    assert cs.radar_reconstruction([[11.0, -4.5]], fp, 1.0).as_dict() == {"tp": True, "fp": False, "fn": False,
                                                                         "n_reports": 1}
    o = cs.radar_reconstruction([[11.0, -4.5], [30.0, 0.0]], fp, 1.0)
    assert o.tp and o.fp and not o.fn
    o = cs.radar_detection(np.zeros((0, 2)), cs.outline_points(fp), 2.0)
    assert (o.tp, o.fp, o.fn) == (False, False, True)


def test_spad_detection_on_a_handmade_histogram():
    t, bw = 200, 1e-9
    data = np.full((t, 2, 2), 4.0)  # background 16 counts per bin over the 4 scan points
    data[100:103] += 30.0  # 360 excess counts around bin 101
    p = cs.transient_peak(data, bw, window=5, n_sigma=5.0)
    assert p.detected and p.background == 16.0
    assert p.excess == pytest.approx(360.0) and p.threshold == pytest.approx(5 * math.sqrt(5 * 16))
    rho = SPEED_OF_LIGHT * 101.5 * bw / 2
    assert abs(p.range - rho) <= SPEED_OF_LIGHT * bw  # within a bin either side of the pulse centre
    assert cs.spad_detection(p, (rho - 0.1, rho + 0.1), 1.0).tp
    assert cs.spad_detection(p, (rho + 5.0, rho + 6.0), 1.0).fp
    flat = cs.transient_peak(np.full((t, 2, 2), 4.0), bw)
    assert not flat.detected and cs.spad_detection(flat, (0, 1), 1.0).fn
    lo, hi = cs.range_interval([[0.0, 0.0, 3.0]], [-4.0, 4.0], [0.0])
    assert (lo, hi) == pytest.approx((5.0, 5.0))


def test_spad_reconstruction_and_volume_peak():
    a = np.zeros((5, 3, 3))
    a[4, 0, 0] = 10.0  # far-depth noise
    a[2, 1, 1] = 1.0  # the return
    z = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    grid = (np.array([-0.5, 0.0, 0.5]), np.array([-0.5, 0.0, 0.5]))
    assert cs.volume_peak(a, z, grid, 3.5) == cs.VolumePeak(0.0, 0.0, 2.0, True)
    assert cs.volume_peak(a, z, grid, 10.0) == cs.VolumePeak(-0.5, -0.5, 4.0, False)
    truth = [[0.0, 0.0, 2.2]]
    hit = cs.volume_peak(a, z, grid, 3.5)
    assert cs.spad_reconstruction(hit, truth, 0.5, True).tp
    assert cs.spad_reconstruction(hit, truth, 0.5, False).fn
    assert cs.spad_reconstruction(hit, np.zeros((0, 3)), 0.5, True).fp
    with pytest.raises(InputError, match="no depth slice"):
        cs.volume_peak(a, z, grid, 0.5, min_depth=0.6)
    with pytest.raises(InputError, match="shape"):
        cs.volume_peak(a[:, :2], z, grid, 3.0)


def test_boundary_artefacts_that_the_old_score_counted_are_not_hits():
    """The artefacts seen in the 1 m SPAD panel (crossmodal.md): the albedo's maximum at the scan
    aperture's corner on the wall (z = 0) or on the depth cut z = ρ + gate, 1 m from a point of the
    car that the scan never sees. The old score (argmax over z ≤ ρ + gate, distance to every truth
    point) called both hits; the new one reports neither, and finds the weaker interior return."""
    z = np.arange(0.0, 6.0, 0.25)  # (24,) depths [m]
    x = y = np.linspace(-0.9375, 0.9375, 16)
    vis = np.array([[0.0625, -0.1875, 2.0], [0.3125, -0.1875, 2.0]])  # the face toward the wall, seen
    hidden = np.array([[-0.9375, -0.9375, 1.0], [0.9375, 0.9375, 3.0]])  # far-side points, never seen
    every = np.vstack([vis, hidden])

    def old(albedo, max_depth):
        sub = np.where((z <= max_depth)[:, None, None], albedo, -np.inf)
        k, i, j = np.unravel_index(int(np.argmax(sub)), albedo.shape)
        d = np.linalg.norm(every - [x[j], y[i], z[k]], axis=1).min(keepdims=True)
        return cs.outcome(d, 1.5)

    base = np.zeros((len(z), 16, 16))
    base[8, 6, 8] = 1.0  # the real return at (x[8], y[6], z[8]) = (0.0625, −0.1875, 2.0)
    wall = base.copy()
    wall[0, 0, 0] = 5.0  # first-bounce / t = 0 artefact at the aperture's corner
    ceiling = base.copy()
    ceiling[12, 15, 15] = 5.0  # r⁴-lifted noise on the depth cut z = 3.0 (ρ + gate), corner
    for vol in (wall, ceiling):
        assert old(vol, 3.0).tp  # what the old score reported
    pk = cs.volume_peak(wall, z, (x, y), 3.0, min_depth=0.5)
    assert pk == cs.VolumePeak(0.0625, -0.1875, 2.0, True)
    assert cs.spad_reconstruction(pk, vis, 1.5, True).tp
    pk = cs.volume_peak(ceiling, z, (x, y), 3.0, min_depth=0.5)
    assert not pk.interior and pk.z == 3.0
    o = cs.spad_reconstruction(pk, every, 1.5, True)
    assert (o.tp, o.fp, o.fn) == (False, True, True)


TINY = CONFIG.with_name("crossmodal_tiny.toml")


def test_tiny_study_end_to_end(tmp_path):
    out = tmp_path / "out"
    res = run_study(TINY, out, progress=False)
    for name in ("crossmodal.json", "crossmodal.md", "range_curve.png", "panel.png"):
        assert (out / name).stat().st_size > 0, name
    assert set(res["rows"]) == {"spad_night/lct", "spad_night/fk", "spad_day/lct", "spad_day/fk", "radar77", "xband"}
    for row in res["rows"].values():
        assert row["distances"] == [1.0, 20.0]
        assert all(f is None or 0 <= f <= 1 for f in row["detection_f1"] + row["reconstruction_f1"])
        rtf = row["range_to_failure"]
        assert rtf["status"] in {"measured", "above", "below"} and rtf["n"] == 2
        v = rtf["interval"]["value"]
        assert rtf["status"] == ("below" if v == 0 else "above" if math.isinf(v) else "measured")
    assert json.loads((out / "crossmodal.json").read_text())["rows"] == json.loads(json.dumps(res["rows"]))
    md = (out / "crossmodal.md").read_text()
    assert md.splitlines()[2].startswith(f"Command: `xnlos crossmodal {TINY} --out {out}`")
    # a ratio is printed only from two measured ranges
    for q in res["ratios"]:
        measured = all(res["rows"][r]["range_to_failure"]["status"] == "measured" for r in (q["reference"], q["baseline"]))
        assert (q["value"] is not None) == measured and (q["note"] is None) == measured
    cells = sorted((out / "cells").glob("*.json"))
    assert len(cells) == 4
    # resumed: the same summary from the saved cells, nothing recomputed (cells untouched)
    stamps = [c.stat().st_mtime_ns for c in cells]
    again = run_study(TINY, out, progress=False, figures=False)
    assert again["rows"] == res["rows"] and [c.stat().st_mtime_ns for c in cells] == stamps
    # deterministic: a fresh run gives the same tables
    fresh = run_study(TINY, tmp_path / "fresh", progress=False, figures=False)
    assert fresh["rows"] == res["rows"] and fresh["ratios"] == res["ratios"]


def test_radar_range_axis_follows_from_the_configuration():
    """No fixed crop: max_range is the unambiguous range N·c/2B, with N doubled from the preset's 512
    until the car's mirror image at the bisection's upper bound (150 m behind the corner) fits."""
    from xnlos_core.app.crossmodal.study import image_range, radar_range_table
    from xnlos_core.radar import load_radar

    cfg, base = load_study(CONFIG)
    need = image_range(cfg, 150.0, base) + cfg.gate
    # the car (x 23.1 … 24.9, y −155.5 … −151 at 150 m) mirrored across x + y = 25: (x, y) → (25 − y, 25 − x);
    # its farthest corner (23.1, −155.5) → (180.5, 1.9)
    assert need - cfg.gate == pytest.approx(np.hypot(180.5, 1.9), rel=1e-9)
    for mod in cfg.modality:
        if mod.type != "radar":
            continue
        table = radar_range_table(cfg, mod, base)
        radar = load_radar(table, "t", base)
        assert radar.max_range == pytest.approx(radar.max_unambiguous_range)
        assert radar.max_unambiguous_range >= need > radar.max_unambiguous_range / 2
        assert radar.n_samples == 1024 and radar.range_resolution == pytest.approx(SPEED_OF_LIGHT / 2 / 600e6)
        assert radar.range_axis[-1] >= need - radar.range_resolution


def test_object_placed_behind_the_corner():
    cfg, _ = load_study(CONFIG)
    for d in (1.0, 7.5):
        car = next(o for o in scene_table(cfg, d)["objects"] if o["name"] == "car")
        # heading π/2: the 4.5 m length lies along the street (−y); nearest point d below y = −1
        assert car["center"] == pytest.approx([24.0, -1.0 - d - 2.25])


@pytest.mark.parametrize("edit, match", [
    (("seeds = 20", "seeds = 20\nseedz = 3"), "seedz"),
    (("upper = 150.0", "upper = 0.1"), "lower < upper"),
    (('["xband", "radar77"]', '["xband", "radar7"]'), "radar77"),
    (("gate = 2.0", "gate = -1.0"), "gate"),
    (('label = "xband"', 'label = "xband"\nsolvers = ["lct"]'), "solvers"),
    (('type = "spad"', 'type = "lidar"'), "type"),
])
def test_bad_config_keys_are_typed_errors(tmp_path, edit, match):
    path = tmp_path / "bad.toml"
    path.write_text(CONFIG.read_text().replace(*edit, 1))
    with pytest.raises(ConfigError, match=match):
        load_study(path)


def test_unknown_hidden_object_is_a_config_error(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(CONFIG.read_text().replace('hidden_object = "car"', 'hidden_object = "bus"'))
    cfg, _ = load_study(path)
    with pytest.raises(ConfigError, match="bus"):
        scene_table(cfg, 1.0)


def test_check_and_conformance():
    from xnlos_core.app.cli import check_file
    from xnlos_core.testing import check_component

    assert "valid (cross-modality study: 6 row(s) × 9 distance(s))" in check_file(CONFIG)
    check_component("transient_model", "spad", {"grid_points": (8, 8), "n_bins": 256, "bin_width": 1e-10})


def test_unknown_solver_is_an_error_naming_it(tmp_path):
    from xnlos_core.errors import XnlosError

    path = tmp_path / "bad.toml"
    path.write_text(CONFIG.read_text().replace('solvers = ["lct", "fk"]', 'solvers = ["lct", "phasor"]'))
    from xnlos_core.app.cli import check_file

    with pytest.raises(XnlosError, match="phasor"):
        check_file(path)
