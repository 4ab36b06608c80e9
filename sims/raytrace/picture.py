"""Bird's-eye view of a traced scene (walls, objects, rays by bounce order, ground truth) beside its RA map.

    python -m sims.raytrace.picture [--scene FILE.toml | --family NAME --seed N] [--out raytrace.png]

Without a scene the built-in corner is drawn. The RA map is shown in dB over range × azimuth.
"""
from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import numpy as np

from xnlos_core.io import atomic_write_bytes
from xnlos_core.radar import RadarConfig

ORDER_COLOURS = ("tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:gray")


def plot_trace(scene, radar: RadarConfig, path: str | Path, *, seed: int = 0, params: dict | None = None,
               max_rays: int = 400) -> Path:
    """Trace ``scene`` with the raytrace model and write the two-panel PNG to ``path``.

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
            ax.plot(s[:, 0], s[:, 1], color=colour, lw=0.3, alpha=0.5)
        ax.plot([], [], color=colour, label=f"ray legs after {k} bounce(s)")
    for w in scene.wall_segments():
        ax.plot([w.start[0], w.end[0]], [w.start[1], w.end[1]], "k-", lw=2.5)
    for o in scene.objects:
        pts, _, _ = o.scatterers(frame.timestamp)
        ax.plot(pts[:, 0], pts[:, 1], "b.", ms=3)
        ax.annotate(o.kind if o.kind != "generic" else o.name, o.center_at(frame.timestamp), fontsize=8)
    gt = frame.ground_truth
    if len(gt.mnlos_points):
        ax.plot(gt.mnlos_points[:, 0], gt.mnlos_points[:, 1], "rx", ms=4, label="mNLOS (virtual o')")
    ax.plot(0, 0, "k^", ms=9, label="radar")
    ax.set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title=f"{scene.name}: rays, walls, objects")
    lim = radar.max_range
    ax.set_xlim(-5, lim)
    ax.set_ylim(-lim * 0.75, lim * 0.75)
    ax.legend(fontsize=7, loc="upper left")
    p_db = 10 * np.log10(np.maximum(frame.ra_map.power, 1e-30))
    top = p_db.max()
    im = ax2.imshow(p_db, origin="lower", aspect="auto", vmin=top - 60, vmax=top, cmap="viridis",
                    extent=[np.degrees(radar.azimuth_axis[0]), np.degrees(radar.azimuth_axis[-1]), 0, radar.max_range])
    fig.colorbar(im, ax=ax2, label="|κ|² [dB W]")
    ax2.set(xlabel="azimuth [deg]", ylabel="range [m]",
            title=f"RA map: {frame.meta['n_paths']} paths, rays bounced up to {frame.meta['max_bounce']} times")
    ax2.invert_xaxis()  # positive azimuth (left) on the left, like the BEV
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=120)
    plt.close(fig)
    out = Path(path)
    atomic_write_bytes(out, buf.getvalue())
    return out


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
