"""Bird's-eye view of a traced scene (walls, objects, rays by bounce order, ground truth) beside its RA map,
oriented like every xnlos figure: x forward up, y left to the left (:mod:`xnlos_core.bev`), and the RA
map's positive azimuth on the left.

    python -m sims.raytrace.picture [--scene FILE.toml | --family NAME --seed N] [--out raytrace.png]

Without a scene the built-in corner is drawn. The RA map is shown in dB over range × azimuth.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from xnlos_core.bev import bev, legend_outside, orient_azimuth, save_png
from xnlos_core.radar import RadarConfig

ORDER_COLOURS = ("tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:gray")


def plot_trace(scene, radar: RadarConfig, path: str | Path, *, seed: int = 0, params: dict | None = None,
               max_rays: int = 400) -> Path:
    """Trace ``scene`` with the raytrace model and write the two-panel PNG (:func:`trace_figure`)
    to ``path``."""
    return save_png(trace_figure(scene, radar, seed=seed, params=params, max_rays=max_rays), path, dpi=120)


def trace_figure(scene, radar: RadarConfig, *, seed: int = 0, params: dict | None = None, max_rays: int = 400):
    """Trace ``scene`` with the raytrace model; the two-panel Figure (not closed): bird's-eye rays,
    walls and objects, and the RA map.

    max_rays: at most this many fan rays are drawn (evenly subsampled), every bounce of each.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .model import RaytraceForwardModel

    model = RaytraceForwardModel(params or {})
    _, _, trace, _ = model.trace(scene, radar, keep_segments=True)
    frame = model.simulate(scene, radar, np.random.default_rng(seed))
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 5.8))
    segs, order = trace.segments, trace.segment_order
    n_fan = int((order == 0).sum())
    step = max(1, n_fan // max_rays)
    for k in range(int(order.max()) + 1 if len(order) else 0):
        sel = np.flatnonzero(order == k)[::step]
        colour = ORDER_COLOURS[k % len(ORDER_COLOURS)]
        for s in segs[sel]:
            ax.plot(*bev(s[:, :2]), color=colour, lw=0.3, alpha=0.5)
        ax.plot([], [], color=colour, label=f"ray legs after {k} bounce(s)")
    for w in scene.wall_segments():
        ax.plot(*bev([w.start, w.end]), "k-", lw=2.5)
    for o in scene.objects:
        pts, _, _ = o.scatterers(frame.timestamp)
        ax.plot(*bev(pts), "b.", ms=3)
        ax.annotate(o.kind if o.kind != "generic" else o.name, np.column_stack(bev(o.center_at(frame.timestamp)))[0],
                    fontsize=8)
    gt = frame.ground_truth
    if len(gt.mnlos_points):
        ax.plot(*bev(gt.mnlos_points), "rx", ms=4, label="mNLOS (virtual o')")
    ax.plot(0, 0, "k^", ms=9, label="radar")
    ax.set(xlabel="−y [m] (right →)", ylabel="x [m] (forward)", aspect="equal",
           title=f"{scene.name}: rays, walls, objects")
    lim = radar.max_range
    ax.set_xlim(-lim * 0.75, lim * 0.75)
    ax.set_ylim(-5, lim)
    legend_outside(ax, where="below")
    p_db = 10 * np.log10(np.maximum(frame.ra_map.power, 1e-30))
    top = p_db.max()
    im = ax2.imshow(p_db, origin="lower", aspect="auto", vmin=top - 60, vmax=top, cmap="viridis",
                    extent=[np.degrees(radar.azimuth_axis[0]), np.degrees(radar.azimuth_axis[-1]), 0, radar.max_range])
    fig.colorbar(im, ax=ax2, label="|κ|² [dB W]")
    ax2.set(ylabel="range [m]",
            title=f"RA map: {frame.meta['n_paths']} paths, rays bounced up to {frame.meta['max_bounce']} times")
    orient_azimuth(ax2, np.degrees(radar.azimuth_axis[[0, -1]]))  # positive azimuth (left) on the left, like the BEV
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, help="scene TOML file")
    ap.add_argument("--family", help="scene generator family (see sims.generators)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("raytrace.png"))
    args = ap.parse_args(argv)
    from xnlos_core.scene import load_scene

    if args.family:
        from sims.generators import generate_scene

        scene = generate_scene(args.family, args.seed)
    elif args.scene:
        # the file named on the command line is trusted: its folder is the config root
        scene = load_scene({"file": Path(args.scene).name}, str(args.scene), Path(args.scene).resolve().parent)
    else:
        scene = load_scene({"builtin": "corner"}, "corner")
    out = plot_trace(scene, RadarConfig(), args.out, seed=args.seed)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
