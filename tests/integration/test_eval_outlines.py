"""`xnlos eval`'s six-panel figure of a dataset map: the hidden object's true outline (recomputed by the
reader from the scene each shard stores, at the map's time) and a zoom inset; shards keep their bytes."""
from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sims.dataset import open_dataset  # noqa: E402
from xnlos_core.bev import bev  # noqa: E402
from xnlos_core.config import load_pipeline  # noqa: E402
from xnlos_core.app.plot.frame_figure import frame_panels_figure  # noqa: E402
from xnlos_core.pipeline import Pipeline  # noqa: E402

OUTLINE = "hidden objects (true outline)"


def test_dataset_maps_carry_their_objects_true_outlines_at_the_maps_time(tiny_dataset, tiny_plugin):
    for f in open_dataset(tiny_dataset, None):
        scene = tiny_plugin.tiny_scene(f.meta["family"], f.meta["scene_seed"])
        want = {o.name: o.footprint(f.timestamp) for o in scene.objects}
        got = f.meta["object_outlines"]
        assert set(got) == set(want) == {"car"}
        assert np.allclose(got["car"], want["car"]) and json.loads(json.dumps(got)) == got  # JSON-ready
    # Computed when reading: nothing new is stored, so shards written before keep their bytes.
    z = open_dataset(tiny_dataset, "test").load_shard("test-00000.npz")
    assert "object_outlines" not in str(z["frame_meta_json"])


def test_the_eval_figure_of_a_dataset_map_draws_the_outline_and_a_zoom_inset(tiny_dataset, tmp_path, eval_config):
    pipe = Pipeline(load_pipeline(eval_config(tmp_path, tiny_dataset)))
    frame = next(f for f in open_dataset(tiny_dataset, "test") if len(f.ground_truth.mnlos_points))
    res = pipe.process(frame)
    assert res.metrics["mirror_paths"]["car"] > 0
    fig = frame_panels_figure(res, title="tiny")
    try:
        fig.canvas.draw()
        (ax,) = [a for a in fig.axes if a.get_title().startswith("(f)")]
        (patch,) = [p for p in ax.patches if p.get_label() == OUTLINE]
        want = np.column_stack(bev(np.asarray(frame.meta["object_outlines"]["car"])))
        assert np.allclose(np.sort(patch.get_path().vertices[:4], 0), np.sort(want, 0))
        (inset,) = ax.child_axes
        assert any(p.get_label() == OUTLINE for p in inset.patches)
        cx, cy = want.mean(0)
        assert inset.get_xlim()[0] < cx < inset.get_xlim()[1] and inset.get_ylim()[0] < cy < inset.get_ylim()[1]
        fig.tight_layout()  # as save_png lays it out: the inset right of (f) stays on the figure
        fig.canvas.draw()
        assert inset.get_window_extent().x1 <= fig.bbox.x1
    finally:
        plt.close(fig)
    frame.meta.pop("object_outlines")  # e.g. a recording's map, or a dataset backend of another package
    fig = frame_panels_figure(pipe.process(frame))
    try:
        (ax,) = [a for a in fig.axes if a.get_title().startswith("(f)")]
        assert not ax.child_axes and not [p for p in ax.patches if p.get_label() == OUTLINE]
    finally:
        plt.close(fig)
