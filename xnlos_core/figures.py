"""Figures: the RA map with detections beside the bird's-eye view of walls and hidden points."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .io import atomic_write_bytes
from .types import LOS, MNLOS, UNCLASSIFIED

CLASS_STYLE = {LOS: ("LOS", "tab:cyan", "o"), MNLOS: ("mNLOS", "tab:red", "x"),
               UNCLASSIFIED: ("unclassified", "gold", "s")}


def _ellipse_xy(mean, cov, nsigma=2.0, n=48):
    """Points of the nσ ellipse of a 2-D Gaussian, shape (n, 2)."""
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    vals = np.clip(vals, 0, None)
    t = np.linspace(0, 2 * np.pi, n)
    circle = np.stack([np.cos(t), np.sin(t)], -1)
    return mean + nsigma * (circle * np.sqrt(vals)) @ vecs.T


def plot_frame(result, path: str | Path, title: str = "") -> Path:
    """Write a two-panel PNG for one FrameResult: RA map (dB) and bird's-eye reconstruction."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frame, det = result.frame, result.detections
    ra = frame.ra_map
    fig, (ax_ra, ax_bev) = plt.subplots(1, 2, figsize=(14, 6.2), gridspec_kw={"width_ratios": [1, 1.25]})

    p_db = ra.power_db()
    floor = np.median(p_db)
    az_deg = np.degrees(ra.azimuth_axis)
    im = ax_ra.imshow(p_db - floor, origin="lower", aspect="auto", cmap="viridis", vmin=0, vmax=max(30.0, np.percentile(p_db - floor, 99.9)),
                      extent=[az_deg[0], az_deg[-1], ra.range_axis[0], ra.range_axis[-1]])
    fig.colorbar(im, ax=ax_ra, label="power above median [dB]")
    for lab, (name, color, marker) in CLASS_STYLE.items():
        m = det.label == lab
        if m.any():
            style = {"facecolors": "none", "edgecolors": color} if marker == "o" else {"c": color}
            ax_ra.scatter(np.degrees(det.azimuth[m]), det.range[m], s=28, marker=marker,
                          label=f"{name} ({m.sum()})", linewidths=1.2, **style)
    ax_ra.set_xlabel("azimuth θ [deg] (positive = left)")
    ax_ra.set_ylabel("range [m]")
    ax_ra.set_title("RA map and detections")
    if len(det):
        ax_ra.legend(loc="upper right", fontsize=8)

    # Bird's-eye view: x forward (up), y left (to the left), as seen from above.
    def bev(points):
        p = np.asarray(points, float).reshape(-1, 2)
        return -p[:, 1], p[:, 0]

    gt = frame.ground_truth
    fov = ra.azimuth_axis[[0, -1]]
    rmax = ra.range_axis[-1]
    for a in fov:
        ax_bev.plot(*bev([[0, 0], [rmax * np.cos(a), rmax * np.sin(a)]]), color="0.8", lw=0.8, ls=":")
    if gt is not None:
        for i, w in enumerate(gt.walls):
            ax_bev.plot(*bev([w.start, w.end]), color="0.75", lw=5, solid_capstyle="butt",
                        label="true walls" if i == 0 else None)
    for i, w in enumerate(result.walls):
        if w.model == "line" and w.extent is not None:
            ax_bev.plot(*bev(w.extent), color="tab:orange", lw=2, ls="--", zorder=4,
                        label="estimated walls" if i == 0 else None)
    for lab, (name, color, marker) in CLASS_STYLE.items():
        m = det.label == lab
        if m.any():
            label = "mNLOS detections (virtual o')" if lab == MNLOS else f"{name} detections"
            ax_bev.scatter(*bev(det.position[m]), s=16, c=color, marker=marker, label=label, alpha=0.8)
    if gt is not None and len(gt.hidden_points):
        ax_bev.scatter(*bev(gt.hidden_points), s=14, c="tab:green", marker="o", label="true hidden points")
    h = result.hidden
    if len(h):
        ax_bev.scatter(*bev(h.mean), s=60, c="tab:purple", marker="+", linewidths=2, label="reconstructed (2σ)")
        for mu, c in zip(h.mean, h.cov):
            ax_bev.plot(*bev(_ellipse_xy(mu, c)), color="tab:purple", lw=0.8, alpha=0.7)
    ax_bev.scatter([0], [0], marker="^", s=90, c="k", label="radar", zorder=5)
    # Frame the scene (ground truth when known); far false alarms fall outside rather than
    # shrinking the scene to a corner of the plot.
    pts = [np.zeros((1, 2))]
    if gt is not None and (len(gt.walls) or len(gt.hidden_points)):
        pts += [gt.hidden_points, gt.mnlos_points] + [np.stack([w.start, w.end]) for w in gt.walls]
    else:
        pts += [det.position, h.mean]
    allp = np.concatenate([p.reshape(-1, 2) for p in pts])
    lo, hi = allp.min(0) - 5, allp.max(0) + 5
    ax_bev.set_xlim(-hi[1], -lo[1])
    ax_bev.set_ylim(min(lo[0], -2), hi[0])
    ax_bev.set_aspect("equal")
    ax_bev.set_xlabel("−y [m] (right →)")
    ax_bev.set_ylabel("x [m] (forward)")
    ax_bev.set_title("bird's-eye view: walls and hidden points")
    ax_bev.legend(loc="upper right", fontsize=7, framealpha=0.85)
    ax_bev.grid(alpha=0.3)
    if title:
        fig.suptitle(f"{title} — frame {frame.index}, t = {frame.timestamp:.2f} s")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)
