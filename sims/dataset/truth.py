"""Per-frame object truth of sequence datasets: where each moving road user is.

Written only when ``frames_per_scene > 1`` (still datasets keep their bytes). Shard members, T rows in
all, rows ``truth_offsets[i]:[i+1]`` for map i:

======================  ===============  =====================================================
truth_id                int64 (T,)       the object's index in its scene's ``objects``
truth_name              str (T,)         the object's name
truth_position          float64 (T, 2)   centre at the map's timestamp [m]
truth_velocity          float64 (T, 2)   centre velocity at the map's timestamp [m/s]
truth_mirror            bool (T,)        it has a mirror path: ≥ 1 mNLOS ground-truth point of its own
truth_motion            str (T,)         its motion over the whole sequence
                                         (:func:`sims.scene_truth.motion_kind`)
truth_offsets           int64 (N+1,)
hidden_velocity         float64 (M, 2)   GroundTruth.hidden_velocity [m/s], rows as mnlos_points
mnlos_velocity          float64 (M, 2)   GroundTruth.mnlos_velocity [m/s]
======================  ===============  =====================================================

Only moving objects (:func:`sims.scene_truth.is_moving`) are road users; static clutter is not.
The reader turns map i's rows into ``frame.meta["object_truth"]`` (:func:`meta_from_arrays`).
"""
from __future__ import annotations

import numpy as np

from sims.scene_truth import is_moving, motion_kind
from xnlos_core.types import Frame

KEYS = ("truth_id", "truth_name", "truth_position", "truth_velocity", "truth_mirror", "truth_motion")


def object_rows(scene, frame: Frame, duration: float) -> list[tuple]:
    """(id, name, position (2,), velocity (2,), mirror, motion) of each moving object of ``scene`` at
    ``frame.timestamp``; ``duration`` [s] is the sequence's length (for the motion kind)."""
    gt = frame.ground_truth
    seen = set()
    if gt is not None and len(gt.mnlos_object):
        seen = {gt.object_names[i] for i in np.unique(gt.mnlos_object)}
    rows = []
    for k, o in enumerate(scene.objects):
        if is_moving(o):
            s = o.motion(np.array([frame.timestamp]))
            rows.append((k, o.name, s.position[0], s.velocity[0], o.name in seen, motion_kind(o, duration)))
    return rows


def truth_arrays(rows: list[list[tuple]], frames: list[Frame]) -> dict[str, np.ndarray]:
    """The shard members of the module table from per-map ``rows`` (:func:`object_rows`) and the frames'
    ground-truth point velocities (zeros where a frame has none)."""
    flat = [r for rs in rows for r in rs]
    gts = [f.ground_truth for f in frames]

    def vel(name):
        parts = [np.zeros((len(g.mnlos_points), 2)) if getattr(g, name) is None else getattr(g, name)
                 for g in gts if g is not None]
        return np.concatenate(parts) if parts else np.zeros((0, 2))

    return {
        "truth_id": np.array([r[0] for r in flat], dtype=np.int64),
        "truth_name": np.array([r[1] for r in flat], dtype=str),
        "truth_position": np.array([r[2] for r in flat], dtype=np.float64).reshape(-1, 2),
        "truth_velocity": np.array([r[3] for r in flat], dtype=np.float64).reshape(-1, 2),
        "truth_mirror": np.array([r[4] for r in flat], dtype=bool),
        "truth_motion": np.array([r[5] for r in flat], dtype=str),
        "truth_offsets": np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(np.int64),
        "hidden_velocity": vel("hidden_velocity"),
        "mnlos_velocity": vel("mnlos_velocity"),
    }


def meta_from_arrays(z: dict[str, np.ndarray], i: int) -> dict | None:
    """``frame.meta["object_truth"]`` of map i, JSON-ready: {id, name, position, velocity, mirror,
    motion}, one list entry per road user; None for a shard without object truth."""
    if "truth_offsets" not in z:
        return None
    sl = slice(int(z["truth_offsets"][i]), int(z["truth_offsets"][i + 1]))
    return {"id": z["truth_id"][sl].tolist(), "name": [str(n) for n in z["truth_name"][sl]],
            "position": z["truth_position"][sl].tolist(), "velocity": z["truth_velocity"][sl].tolist(),
            "mirror": z["truth_mirror"][sl].tolist(), "motion": [str(m) for m in z["truth_motion"][sl]]}
