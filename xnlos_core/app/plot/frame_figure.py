"""Fig. 6-style panels of one frame: RA map, the detector's LOS / mNLOS heatmaps, detections, fitted walls
and the bird's-eye reconstruction (written by ``xnlos eval`` for its first maps).

Panels (2 × 3): (a) RA map, power above the map's median [dB] over azimuth [deg] × range [m];
(b), (c) LOS and mNLOS confidence heatmaps in [0, 1] (a learned detector's ``heatmap(frame)``;
classical detectors have none: then one text panel across (b) and (c) says so); (d) detections
on the RA map (LOS ○, mNLOS ×; for a Doppler run filled by radial velocity, with its colour bar)
with the thinned ground truth as small dots; (e) bird's-eye view of the LOS detections,
the fitted relay walls and the true walls; (f) bird's-eye reconstruction: LOS detections, fitted
walls, reconstructed hidden points with their 90 % credible ellipses (HiddenPoints.cov), the
true hidden points, when the result has tracks, the tracks and their prediction cones, and, when
the frame's meta carries them (dataset maps), the hidden objects' true outlines with a zoom inset.
Bird's-eye axes as in :mod:`xnlos_core.app.plot.figures`: x forward (up), y left.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.app.plot import palette
from xnlos_core.app.plot.figures import (CLASS_STYLE, ellipse_xy, bev, credible_radius, draw_objects, draw_unobservable, draw_walls,
                      frame_bev, has_velocity, legend_outside, orient_azimuth, outlines_from_meta, save_png,
                      scatter_ra_detections, separate_labels, split_outlines, velocity_colorbar, velocity_norm,
                      zoom_inset)
from xnlos_core.geometry import cartesian_to_polar
from xnlos_core.types import LOS, MNLOS


def _ra_extent(ra):
    az = np.degrees(ra.azimuth_axis)
    return [az[0], az[-1], ra.range_axis[0], ra.range_axis[-1]]


def _polar_deg(points):
    r, a = cartesian_to_polar(np.asarray(points, float).reshape(-1, 2))
    return np.degrees(a), r


def _detections_bev(ax, det, classes=(LOS, MNLOS)):
    for lab in classes:
        name, color, marker = CLASS_STYLE[lab]
        m = det.label == lab
        if m.any():
            label = "mNLOS detections (virtual o')" if lab == MNLOS else f"{name} detections"
            ax.scatter(*bev(det.position[m]), s=12, c=color, marker=marker, label=f"{label} ({m.sum()})", alpha=0.8,
                       zorder=palette.Z_DETECTION)


def _walls_bev(ax, result, gt):
    draw_walls(ax, result.walls, None if gt is None else gt.walls, label="fitted walls")


def _frame_bev(ax, result, gt, extra=()):
    frame_bev(ax, gt, [result.detections.position, result.hidden.mean], extra=extra)
    ax.scatter([0], [0], marker="^", s=60, c="k", label="radar", zorder=palette.Z_RADAR)
    ax.grid(alpha=0.3)
    legend_outside(ax, where="below", fontsize=6, ncol=2)


def plot_frame_panels(result, path: str | Path, heatmaps: np.ndarray | None = None, title: str = "",
                      detector: str = "", credible: float = 0.9) -> Path:
    """Write the six-panel PNG (module doc, :func:`frame_panels_figure`) of one FrameResult to
    ``path``; returns the path."""
    return save_png(frame_panels_figure(result, heatmaps, title, detector, credible), path, dpi=90)


def frame_panels_figure(result, heatmaps: np.ndarray | None = None, title: str = "", detector: str = "",
                        credible: float = 0.9, zoom: bool = True):
    """The six-panel Figure (module doc) of one FrameResult (not closed). Every RA-map panel puts
    positive azimuth on the left, like the bird's-eye panels; legends sit below their panels.

    heatmaps: (2, H', W') LOS / mNLOS confidences in [0, 1] over the RA map's extent (any grid),
    or None; detector: its name, for the panel titles; credible: level of the hidden points'
    ellipses (radius √χ²₂(p) σ).

    Panel (f) draws the hidden objects' true outlines when the frame carries them
    (``frame.meta["object_outlines"]``, which the dataset reader fills from the scenes a shard
    stores: :func:`xnlos_core.app.plot.figures.outlines_from_meta`), split by the frame's metrics into objects
    with a mirror path (solid, :func:`~xnlos_core.app.plot.figures.draw_objects`) and unobservable ones
    (dashed); zoom: then add a :func:`~xnlos_core.app.plot.figures.zoom_inset` around the former, right of
    the panel. Without that meta key the panel has neither."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frame, det = result.frame, result.detections
    ra, gt = frame.ra_map, frame.ground_truth
    if heatmaps is not None:
        heatmaps = np.asarray(heatmaps)
        if heatmaps.ndim != 3 or heatmaps.shape[0] < 2:
            raise InputError(f"heatmaps: expected shape (2, H, W) (LOS, mNLOS confidences), got {heatmaps.shape}")
    objects, unobservable = split_outlines(outlines_from_meta(frame.meta), result.metrics)
    inset = zoom and bool(objects)
    fig, axes = plt.subplots(2, 3, figsize=(20 if inset else 17, 12.5))  # room for the inset right of (f)
    p_db = ra.power_db()
    rel = p_db - np.median(p_db)
    vmax = max(30.0, float(np.percentile(rel, 99.9)))
    ext = _ra_extent(ra)

    ax = axes[0, 0]
    im = ax.imshow(rel, origin="lower", aspect="auto", cmap="viridis", vmin=0, vmax=vmax, extent=ext)
    fig.colorbar(im, ax=ax, label="power above median [dB]")
    ax.set_title("(a) RA map")
    if heatmaps is None:  # one plain text panel in place of (b) and (c): no empty images
        gs = axes[0, 1].get_subplotspec().get_gridspec()
        for ax in axes[0, 1:]:
            ax.remove()
        ax = fig.add_subplot(gs[0, 1:])
        ax.set_axis_off()
        ax.set_title(f"(b), (c) LOS / mNLOS heatmaps" + (f" ({detector})" if detector else ""))
        ax.text(0.5, 0.5, f"no heatmaps: {detector or 'this detector'} is not a learned detector;\n"
                "its detections are in (d)", ha="center", va="center", transform=ax.transAxes, fontsize=11,
                color="0.25", bbox={"boxstyle": "round,pad=0.8", "fc": "0.96", "ec": "0.7"})
        ra_top = [axes[0, 0]]
    else:
        for k, (ax, cls) in enumerate(zip(axes[0, 1:], ("LOS", "mNLOS"))):
            ax.set_title(f"({'bc'[k]}) {cls} heatmap" + (f" ({detector})" if detector else ""))
            im = ax.imshow(heatmaps[k], origin="lower", aspect="auto", cmap="magma", vmin=0, vmax=1, extent=ext)
            fig.colorbar(im, ax=ax, label="confidence")
        ra_top = list(axes[0])
    for ax in ra_top:
        orient_azimuth(ax, ext[:2])
        ax.set_ylabel("range [m]")

    ax = axes[1, 0]
    ax.imshow(rel, origin="lower", aspect="auto", cmap="gray", vmin=0, vmax=vmax, extent=ext)
    if gt is not None:
        for pts, color, label in ((gt.los_points, "tab:cyan", "true LOS"), (gt.mnlos_points, "tab:red", "true mNLOS")):
            if len(pts):
                ax.scatter(*_polar_deg(pts), s=4, c=color, alpha=0.5, label=label, zorder=palette.Z_TRUTH)
    norm = velocity_norm(det.velocity if det.velocity is not None else []) if has_velocity(result) else None
    scatter_ra_detections(ax, det, norm)
    if norm is not None:
        velocity_colorbar(fig, ax, norm)
    orient_azimuth(ax, ext[:2])
    ax.set_ylim(ext[2], ext[3])
    ax.set_title(f"(d) detections ({len(det)})")
    ax.set_ylabel("range [m]")
    legend_outside(ax, where="below", fontsize=7)

    ax = axes[1, 1]
    _walls_bev(ax, result, gt)
    _detections_bev(ax, det, (LOS,))
    ax.set_title(f"(e) fitted walls ({len(result.walls)})")
    _frame_bev(ax, result, gt)

    ax = axes[1, 2]
    h = result.hidden

    def draw(ax, main: bool = True) -> None:
        _walls_bev(ax, result, gt)
        _detections_bev(ax, det, (LOS,))
        if gt is not None and len(gt.hidden_points):
            ax.scatter(*bev(gt.hidden_points), s=10, c=palette.TRUTH, marker="o", label="true hidden points",
                       zorder=palette.Z_TRUTH)
        if len(h):
            ax.scatter(*bev(h.mean), s=50, c=palette.ESTIMATE, marker="+", linewidths=1.5, zorder=palette.Z_ESTIMATE,
                       label=f"reconstructed hidden points ({len(h)}; {100 * credible:g} % credible)")
            for mu, c in zip(h.mean, h.cov):
                ax.plot(*bev(ellipse_xy(mu, c, credible_radius(credible))), color=palette.ESTIMATE, lw=0.8,
                        alpha=0.7, zorder=palette.Z_ESTIMATE)
        if result.tracks is not None and len(result.tracks):
            from xnlos_core.app.plot.track_figure import draw_tracks

            draw_tracks(ax, result.tracks)
        draw_objects(ax, objects, annotate=main)
        draw_unobservable(ax, unobservable, annotate=main)

    draw(ax)
    ax.set_title(f"(f) reconstruction ({len(h)} reconstructed hidden point{'s' * (len(h) != 1)})")
    _frame_bev(ax, result, gt, extra=list(objects.values()) + list(unobservable.values()))
    separate_labels(ax)
    if inset:  # beside the panel, under nothing: (f) is the right column and its legend sits below it
        zoom_inset(ax, lambda a: draw(a, main=False), np.concatenate(list(objects.values())),
                   bounds=(1.04, 0.0, 0.45, 0.45))

    fam = frame.meta.get("family")
    head = (f"{title} — map {frame.index}" + (f" ({fam})" if fam else "")).lstrip(" —")
    fig.suptitle(head)
    return fig
