"""The results.jsonl schema: records of real (tiny) pipeline runs validate, with and
without Doppler and tracker; a broken record fails naming the key; the schema stays in the keyword
subset the hand-written checker implements; wall / detection / hidden records round-trip."""
import copy
import json

import numpy as np
import pytest

from xnlos_core.config import parse_pipeline
from xnlos_core.errors import InputError, SchemaKeywordError, SchemaViolation
from xnlos_core.frame_record import (SCHEMA_VERSION, detections_from_record, detections_record, hidden_from_record,
                                     hidden_record, wall_from_record, wall_record)
from xnlos_core.io import json_default
from xnlos_core.app.json_schema import check, check_schema
from xnlos_core.pipeline import Pipeline
from xnlos_core.app.results_schema import RESULTS_SCHEMA, validate_record
from xnlos_core.testing import small_pipeline_table
from xnlos_core.types import Detections, HiddenPoints, WallPosterior

DOPPLER = dict(forward_model={"name": "image", "params": {"doppler": True}},
               radar={"n_samples": 256, "max_range": 60.0, "n_azimuth_bins": 121, "n_chirps": 4},
               tracker={"name": "kalman"}, run={"frames": 2, "figure": False, "frame_interval": 0.2})


def _records(**overrides):
    results = list(Pipeline(parse_pipeline(small_pipeline_table(**overrides), "small.toml")).run())
    return [json.loads(json.dumps(r.record(), default=json_default)) for r in results]  # as written


@pytest.fixture(scope="module")
def plain():
    (rec,) = _records()
    return rec


@pytest.fixture(scope="module")
def doppler():
    return _records(**DOPPLER)


def test_a_plain_run_validates_and_has_the_schema_2_keys(plain):
    validate_record(plain)
    assert plain["schema_version"] == SCHEMA_VERSION
    assert "velocity" not in plain["detection_table"] and "velocity" not in plain["hidden"]
    assert plain["tracks"] is None and len(plain["walls"]) >= 1 and len(plain["hidden"]["mean"]) >= 1
    w = plain["walls"][0]
    assert w["model"] == "line" and w["param_names"] == ["phi", "b"] and set(w["params"]) == {"phi", "b"}
    assert np.shape(w["extent"]) == (2, 2) and np.shape(plain["hidden"]["cov"])[1:] == (2, 2)
    assert set(plain["detection_table"]["class"]) <= {"LOS", "mNLOS", "unclassified"}


def test_a_doppler_run_with_a_tracker_validates(doppler):
    for rec in doppler:
        validate_record(rec)
        assert len(rec["detection_table"]["velocity"]) == len(rec["detection_table"]["range"])
        assert len(rec["hidden"]["velocity_cov"]) == len(rec["hidden"]["mean"])
        assert rec["tracks"] is not None and "forecast" in rec["tracks"]
        assert rec["detection_doppler"]["velocity"] == rec["detection_table"]["velocity"]  # schema-1 key kept


def _set(path, value):
    def mutate(rec):
        *head, last = path
        for k in head:
            rec = rec[k]
        rec[last] = value(rec[last]) if callable(value) else value
    return mutate


def _delete(*path):
    def mutate(rec):
        *head, last = path
        for k in head:
            rec = rec[k]
        del rec[last]
    return mutate


BROKEN = [
    (_delete("walls", 0, "cov"), "walls[0].cov"),
    (_delete("hidden"), "hidden"),
    (_set(("detection_table", "azimuth", 0), 4.0), "detection_table.azimuth[0]"),
    (_set(("detection_table", "confidence"), lambda v: v[:-1]), "detection_table.confidence"),
    (_set(("detection_table", "class", 0), "bogus"), "detection_table.class[0]"),
    (_set(("detection_table", "label", 0), lambda v: (v + 1) % 3), "detection_table.class[0]"),
    (_set(("detections", "LOS"), lambda v: v + 1), "detections.LOS"),
    (_set(("walls", 0, "cov"), [[1.0, 0.0, 0.0]] * 3), "walls[0].cov"),
    (_set(("walls", 0, "cov", 1), [1.0]), "walls[0].cov"),
    (_set(("walls", 0, "params", "phi"), lambda v: v + 1.0), "walls[0].params"),
    (_set(("walls", 0, "extent"), [[0.0, 0.0]]), "walls[0].extent"),
    (_set(("hidden", "cov", 0), [[1.0, 0.0]]), "hidden.cov[0]"),
    (_set(("hidden", "wall_index", 0), 99), "hidden.wall_index[0]"),
    (_set(("hidden_points",), lambda v: v[:-1]), "hidden_points"),
    (_set(("schema_version",), 3), "schema_version"),
    (_set(("frame",), -1), "frame"),
    (_set(("timestamp",), True), "timestamp"),
    (_set(("surprise",), 1), "surprise"),
    (_set(("tracks",), {"id": [1], "position": [], "velocity": []}), "tracks"),
]


@pytest.mark.parametrize("mutate, path", BROKEN, ids=[p for _, p in BROKEN])
def test_a_broken_record_fails_naming_the_key(plain, mutate, path):
    rec = copy.deepcopy(plain)
    mutate(rec)
    with pytest.raises(SchemaViolation) as info:
        validate_record(rec)
    assert info.value.path == path and str(info.value).startswith(path)


def test_the_schema_is_json_and_in_the_checkers_keyword_subset():
    check_schema(RESULTS_SCHEMA)
    assert json.loads(json.dumps(RESULTS_SCHEMA)) == RESULTS_SCHEMA
    with pytest.raises(SchemaKeywordError, match="oneOf"):
        check_schema({"type": "object", "properties": {"a": {"oneOf": []}}})
    with pytest.raises(SchemaKeywordError, match="pattern"):
        check("x", {"type": "string", "pattern": "x"})


def test_checker_types_follow_json_not_python():
    with pytest.raises(SchemaViolation, match="expected number, got boolean"):
        check(True, {"type": "number"})
    with pytest.raises(SchemaViolation, match="expected integer"):
        check(1.5, {"type": "integer"})
    check(2.0, {"type": "integer"})
    check(float("inf"), {"type": "number"})  # Python's json writes and reads ±Infinity
    check(None, {"type": ["number", "null"]})


def _json(x):
    return json.loads(json.dumps(x))


def test_an_arc_wall_round_trips_with_its_names_extent_and_anchor():
    cov = np.diag([1e-4, 4e-2, 1e-6])
    w = WallPosterior.arc([0.6, 0.8], 12.0, -0.01, anchor=[5.0, 9.0], cov=cov, n_points=7,
                          extent=[[1.0, 10.0], [9.0, 4.0]])
    rec = _json(wall_record(w))
    assert rec["params"] == dict(zip(("phi", "b", "kappa"), w.mean.tolist()))
    back = wall_from_record(rec)
    assert (back.model, back.param_names, back.n_points) == ("arc", ("phi", "b", "kappa"), 7)
    for name in ("mean", "cov", "extent", "anchor"):
        np.testing.assert_array_equal(getattr(back, name), getattr(w, name))


def test_detections_and_hidden_round_trip_empty_and_with_doppler():
    d = Detections([3.0, 8.0], [0.1, -0.2], [0, 1], [0.9, 0.4], [0.1, 0.2], [0.01, 0.02], [1.5, -2.0], [0.1, 0.3])
    back = detections_from_record(_json(detections_record(d)))
    for name in ("range", "azimuth", "label", "confidence", "range_std", "azimuth_std", "velocity", "velocity_var"):
        np.testing.assert_array_equal(getattr(back, name), getattr(d, name))
    assert len(detections_from_record(_json(detections_record(Detections.empty())))) == 0
    h = HiddenPoints([[1.0, 2.0]], [[[1.0, 0.1], [0.1, 2.0]]], [1], [0], [[0.5, 0.0]], [np.eye(2)])
    back = hidden_from_record(_json(hidden_record(h)))
    for name in ("mean", "cov", "source_index", "wall_index", "velocity", "velocity_cov"):
        np.testing.assert_array_equal(getattr(back, name), getattr(h, name))
    empty = hidden_from_record(_json(hidden_record(HiddenPoints.empty())))
    assert empty.mean.shape == (0, 2) and empty.cov.shape == (0, 2, 2)
    seen = HiddenPoints([[1.0, 2.0]], [np.eye(2)], [0], [0], view=[[0.6, -0.8]])  # no velocity, a view
    back = hidden_from_record(_json(hidden_record(seen)))
    assert back.velocity is None and back.view.tolist() == [[0.6, -0.8]]
    with pytest.raises(InputError, match="view"):
        HiddenPoints([[1.0, 2.0]], [np.eye(2)], [0], [0], view=[[1.0, 1.0]])  # not a unit vector
