"""Figures of the cross-modality study (:mod:`xnlos_core.crossmodal`): the range curve (F1 vs
distance behind the corner per modality) and a Fig. 5-style panel (paper Sec. 5.1.2): one row per
modality, columns scene (top view), raw measurement (radar: |RA map| [dB] over range × azimuth;
SPAD: counts summed over the scan rows, scan x × round-trip range c·t/2), intensity or dense
prediction (radar: RA map with the detections, LOS and mNLOS; SPAD: the solver's albedo, max over
the scan rows, x × depth z) and reconstruction (radar: hidden points and the true outline, top
view; SPAD: the albedo's peak and the true hidden surface, x × z in wall coordinates)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .bev import bev, save_png
from .transient import SPEED_OF_LIGHT
from .types import LOS, MNLOS


def range_curve(res: dict, path: str | Path) -> Path:
    """F1 vs distance [m] (log axis): reconstruction solid, detection dashed, one colour per row."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for i, (row, t) in enumerate(res["rows"].items()):
        c = f"C{i}"
        ds = t["distances"]
        nan = lambda v: [np.nan if x is None else x for x in v]  # noqa: E731
        ax.plot(ds, nan(t["reconstruction_f1"]), "-o", color=c, ms=4, label=f"{row} reconstruction")
        ax.plot(ds, nan(t["detection_f1"]), "--", color=c, alpha=0.7, label=f"{row} detection")
    ax.axhline(res["threshold"], color="0.5", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_xlabel("distance behind the corner [m]")
    ax.set_ylabel("F1 over seeds")
    ax.set_ylim(-0.03, 1.03)
    ax.set_title(f"{res['name']}: NLOS range at equal transmit power")
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    return save_png(fig, path)


def _scene_ax(ax, scene, hidden: str, title: str) -> None:
    for w in scene.walls:
        ax.plot(*bev([w.start, w.end]), color="k" if w.relay else "0.4", lw=2 if w.relay else 1.5)
    for o in scene.objects:
        fp = o.footprint(0.0)
        fp = np.vstack([fp, fp[:1]])
        ax.fill(*bev(fp), color="gold" if o.name == hidden else "0.7", alpha=0.8)
    ax.plot(0, 0, "r^", ms=6)
    pts = np.vstack([o.footprint(0.0) for o in scene.objects] + [[w.start, w.end] for w in scene.walls if w.relay]
                    + [[[0.0, 0.0]]])
    (x0, y0), (x1, y1) = pts.min(axis=0) - 5, pts.max(axis=0) + 5
    ax.set_xlim(-y1, -y0)
    ax.set_ylim(x0, x1)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=8)


def _radar_row(axes, row: str, shown: dict, cfg) -> None:
    res, pipe = shown["result"], shown["pipeline"]
    ra = res.frame.ra_map
    db = 20 * np.log10(np.abs(ra.data) + 1e-12)
    ext = [np.degrees(ra.azimuth_axis[0]), np.degrees(ra.azimuth_axis[-1]), ra.range_axis[0], ra.range_axis[-1]]
    _scene_ax(axes[0], pipe.scene, cfg.hidden_object, f"{row}: scene")
    axes[1].imshow(db, origin="lower", aspect="auto", extent=ext, cmap="viridis", vmin=db.max() - 60)
    axes[1].set_title("raw: |RA map| [dB]", fontsize=8)
    axes[2].imshow(db, origin="lower", aspect="auto", extent=ext, cmap="gray", vmin=db.max() - 60)
    det = res.detections
    for lab, c, name in ((LOS, "c", "LOS"), (MNLOS, "m", "mNLOS")):
        m = det.label == lab
        axes[2].plot(np.degrees(det.azimuth[m]), det.range[m], "o", mfc="none", color=c, ms=4, label=name)
    axes[2].legend(fontsize=6)
    axes[2].set_title(f"detections ({pipe.config.detector.name})", fontsize=8)
    for ax in axes[1:3]:
        ax.set_xlabel("azimuth [°]", fontsize=7)
        ax.set_ylabel("range [m]", fontsize=7)
    fp = np.vstack([shown["footprint"], shown["footprint"][:1]])
    ax = axes[3]
    for w in pipe.scene.walls:
        ax.plot(*bev([w.start, w.end]), color="0.6", lw=1)
    ax.fill(*bev(fp), color="gold", alpha=0.6, label="truth")
    ax.plot(*bev(shown["image"]), ".", color="0.5", ms=1, label="virtual image")
    h = res.hidden.mean.reshape(-1, 2)
    ax.plot(*bev(h), "mx", ms=6, label="reconstructed")
    ax.set_aspect("equal")
    ax.legend(fontsize=6)
    ax.set_title("reconstruction (top view)", fontsize=8)


def _spad_row(axes, row: str, shown: dict, cfg) -> None:
    vol, nv, truth = shown["volume"], shown["nlos"], shown["truth"]
    x, _ = vol.grid()
    rho = SPEED_OF_LIGHT * vol.times() / 2
    _scene_ax(axes[0], shown["scene"], cfg.hidden_object, f"{row}: scene")
    top = min(rho[-1], float(np.linalg.norm(truth, axis=1).max()) + 5.0)  # the depths that matter
    raw = vol.data.sum(axis=1)[rho <= top]  # (T', W)
    axes[1].imshow(raw, origin="lower", aspect="auto", extent=[x[0], x[-1], rho[0], top], cmap="magma")
    axes[1].set_title("raw: counts (Σ rows)", fontsize=8)
    axes[1].set_xlabel("scan x [m]", fontsize=7)
    axes[1].set_ylabel("c·t/2 [m]", fontsize=7)
    inten = nv.albedo.max(axis=1)[nv.z <= top]  # (Z', W)
    axes[2].imshow(inten, origin="lower", aspect="auto", extent=[x[0], x[-1], nv.z[0], top], cmap="magma")
    axes[2].set_title(f"intensity: {shown['solver']} albedo (max over rows)", fontsize=8)
    axes[2].set_xlabel("x [m]", fontsize=7)
    axes[2].set_ylabel("depth z [m]", fontsize=7)
    xp, _, z = shown["peak_xyz"]
    ax = axes[3]
    ax.plot(truth[:, 0], truth[:, 2], ".", color="gold", ms=2, label="truth")
    if shown["detected"]:
        ax.plot([xp], [z], "mx", ms=8, label=f"peak (z ≤ {shown['range'] + cfg.gate:.1f} m)")
    else:
        ax.text(0.5, 0.9, "no detection: nothing reported", transform=ax.transAxes, ha="center", fontsize=7)
    ax.axvspan(x[0], x[-1], color="0.9", label="scan aperture")
    ax.set_xlabel("x along wall [m]", fontsize=7)
    ax.set_ylabel("z from wall [m]", fontsize=7)
    ax.legend(fontsize=6)
    ax.set_title("reconstruction (wall frame)", fontsize=8)


def panel_figure(cfg, panel: dict[str, dict], path: str | Path) -> Path:
    """Fig. 5-style panel: one row per modality of ``panel`` (row label → what its cell kept)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panel), 4, figsize=(14, 3.2 * len(panel)), squeeze=False)
    for axrow, (row, shown) in zip(axes, panel.items()):
        (_radar_row if "result" in shown else _spad_row)(axrow, row, shown, cfg)
    fig.suptitle(f"{cfg.name}: hidden object {cfg.panel_distance:g} m behind the corner", fontsize=10)
    return save_png(fig, path, dpi=90)
