"""Bird's-eye view of tracks: each track's recent history, current position and
velocity arrow, and its prediction cone — the forecast mean path with the 50 % and 90 % discs
(Tracks.radius50 / radius90 around Tracks.forecast) swept along the horizons — labelled by track id
and motion model, with the tracker's arrival region when it has one.

The cone of one level is the union over consecutive horizons k, k+1 of the convex hull of the two
discs (the region a disc sweeps when centre and radius move linearly between them), starting from
the current position with radius 0. It is drawn as one patch whose sub-paths all run
counter-clockwise, so matplotlib's non-zero fill rule paints the union once, at uniform opacity.
Axes as in :mod:`xnlos_core.app.plot.figures`: x forward (up), y left (to the left).
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from xnlos_core.bev import bev, save_png, set_bev_limits
from xnlos_core.types import Tracks

#: Smallest disc radius drawn [m]: keeps the hull of a zero-radius start non-degenerate.
MIN_RADIUS = 0.05
CONE_ALPHA = {50: 0.35, 90: 0.15}
#: Track colours, by id: none of the colours the frame figures give walls (orange, grey), detections
#: (cyan, red), hidden points (purple, green) or the arrival region (olive).
TRACK_COLORS = ("tab:blue", "m", "tab:brown", "navy", "teal", "darkgoldenrod", "deeppink", "slateblue")


def track_color(track_id: int) -> str:
    """Matplotlib colour of a track, by id (stable over frames)."""
    return TRACK_COLORS[int(track_id) % len(TRACK_COLORS)]


def cone_path(centres, radii, n: int = 40):
    """matplotlib Path (bird's-eye coordinates) of the union of discs (centres (K, 2) [m], radii
    (K,) [m]) swept between consecutive horizons; NaN radii are left out; None when none is finite."""
    from matplotlib.path import Path as MplPath
    from scipy.spatial import ConvexHull

    centres = np.asarray(centres, float).reshape(-1, 2)
    radii = np.asarray(radii, float).reshape(-1)
    ok = np.isfinite(radii) & np.isfinite(centres).all(1)
    centres, radii = centres[ok], np.maximum(radii[ok], MIN_RADIUS)
    if not len(radii):
        return None
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    circle = np.stack([np.cos(t), np.sin(t)], -1)
    discs = [np.column_stack(bev(c + r * circle)) for c, r in zip(centres, radii)]
    pieces = [discs[0]] if len(discs) == 1 else [np.concatenate(p) for p in zip(discs[:-1], discs[1:])]
    verts, codes = [], []
    for pts in pieces:
        hull = pts[ConvexHull(pts).vertices]  # 2-D: counter-clockwise; bev() is a rotation, so it stays so
        verts += [*hull, hull[0]]
        codes += [MplPath.MOVETO] + [MplPath.LINETO] * (len(hull) - 1) + [MplPath.CLOSEPOLY]
    return MplPath(np.asarray(verts), codes)


def _label(tracks: Tracks, i: int) -> str:
    text = f"#{tracks.track_id[i]}"
    if tracks.model is not None:
        text += f" {tracks.model[i]}"
    if tracks.arrival is not None and np.isfinite(tracks.arrival[i]):
        lo, hi = tracks.arrival_interval[i] - tracks.timestamp
        hi_s = "∞" if not np.isfinite(hi) else f"{hi:.1f}"
        text += f"\narrives in {tracks.arrival[i] - tracks.timestamp:.1f} s [{lo:.1f}, {hi_s}]"
    return text


def draw_tracks(ax, tracks: Tracks | None, history: Mapping[int, np.ndarray] | None = None, region=None, *,
                arrow_s: float = 1.0, fontsize: float = 7) -> dict[str, list]:
    """Draw ``tracks`` (None: only the region) on a bird's-eye ``ax``; returns the artists by role.

    history: track id → (n, 2) [m] its positions over past frames, oldest first (e.g.
    :func:`xnlos_core.track_record.track_history`), drawn as a thin line with dots; region: (P, 2)
    [m] polygon of the tracker's arrival region, or None; arrow_s [s]: the velocity arrow is the
    displacement over this time. Returns {"history", "positions", "arrows", "paths", "cone50",
    "cone90", "labels", "region"}: lists of artists ("cone50"/"cone90": one patch per track with
    a finite radius of that level).
    """
    from matplotlib.patches import PathPatch, Polygon

    art: dict[str, list] = {k: [] for k in ("history", "positions", "arrows", "paths", "cone50", "cone90",
                                            "labels", "region")}
    if region is not None and len(region) >= 3:
        art["region"].append(ax.add_patch(Polygon(np.column_stack(bev(region)), closed=True, fc="tab:olive",
                                                  alpha=0.12, ec="tab:olive", lw=1.2, ls="--",
                                                  label="arrival region")))
    for i, tid in enumerate(() if tracks is None else tracks.track_id):
        color = track_color(tid)
        p, v = tracks.position[i], tracks.velocity[i]
        past = None if history is None else history.get(int(tid))
        if past is not None and len(past):
            art["history"] += ax.plot(*bev(past), color=color, lw=1.0, alpha=0.6, marker=".", ms=3)
        if tracks.forecast is not None:
            h0 = len(tracks.horizons) and tracks.horizons[0] == 0
            centres = tracks.forecast[i] if h0 else np.vstack([p, tracks.forecast[i]])
            art["paths"] += ax.plot(*bev(centres), color=color, lw=1.0, ls="--", marker="o", ms=2)
            for level in (90, 50):
                radii = getattr(tracks, f"radius{level}")[i]
                path = cone_path(centres, radii if h0 else np.concatenate([[0.0], radii]))
                if path is not None and np.isfinite(radii).any():
                    art[f"cone{level}"].append(ax.add_patch(PathPatch(path, fc=color, ec="none",
                                                                      alpha=CONE_ALPHA[level], zorder=2)))
        art["positions"].append(ax.scatter(*bev(p), s=40, c=color, marker="D", edgecolors="k", linewidths=0.6,
                                           zorder=6, gid=f"track {int(tid)}"))
        if np.isfinite(v).all() and np.hypot(*v) > 0:
            tip = np.column_stack(bev(p + arrow_s * v))[0]
            art["arrows"].append(ax.annotate("", xy=tip, xytext=np.column_stack(bev(p))[0], zorder=6,
                                             arrowprops={"arrowstyle": "->", "color": color, "lw": 1.6}))
        art["labels"].append(ax.annotate(_label(tracks, i), np.column_stack(bev(p))[0], xytext=(6, 6),
                                         textcoords="offset points", fontsize=fontsize, color=color, zorder=7,
                                         bbox={"boxstyle": "round,pad=0.2", "fc": "w", "ec": "none", "alpha": 0.7}))
    return art


def mark_outside_view(ax, tracks: Tracks | None, *, fontsize: float = 7) -> list:
    """Mark on ``ax`` (limits already set) each track whose position lies outside the view: a
    hollow diamond on the view's edge where the line from the view's centre to the track leaves
    it, labelled "#id at (x, y) m", so that every counted track is seen. Call after the limits
    are final. Returns the artists (gid "track <id> outside")."""
    if tracks is None or not len(tracks):
        return []
    x0, x1 = sorted(ax.get_xlim())
    y0, y1 = sorted(ax.get_ylim())
    c = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
    half = 0.97 * 0.5 * np.array([x1 - x0, y1 - y0])  # just inside the frame, so the marker shows whole
    arts = []
    for tid, p in zip(tracks.track_id, tracks.position):
        q = np.column_stack(bev(p))[0]
        d = q - c
        if not np.isfinite(d).all() or (abs(d) <= 0.5 * np.array([x1 - x0, y1 - y0])).all():
            continue
        edge = c + d / np.max(np.abs(d) / half)
        color = track_color(tid)
        arts.append(ax.scatter(*edge, s=40, marker="D", facecolors="none", edgecolors=color, linewidths=1.2,
                               zorder=7, clip_on=False, gid=f"track {int(tid)} outside"))
        inward = -np.sign(d) * (np.abs(d / half) >= np.abs(d / half).max() - 1e-9)
        arts.append(ax.annotate(f"#{int(tid)} at ({p[0]:.0f}, {p[1]:.0f}) m", edge, xytext=tuple(10 * inward),
                                textcoords="offset points", fontsize=fontsize, color=color, zorder=7,
                                ha="left" if inward[0] > 0 else "right" if inward[0] < 0 else "center",
                                va="bottom" if inward[1] > 0 else "top" if inward[1] < 0 else "center",
                                gid=f"track {int(tid)} outside"))
    return arts


def count_outside(arts) -> int:
    """Number of tracks :func:`mark_outside_view` marked (its returned artists)."""
    return len({a.get_gid() for a in arts})


def track_legend_handles(tracks: Tracks | None):
    """Proxy artists explaining the track glyphs (for a legend): position, history, cones."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = [Line2D([], [], color="0.3", marker="D", ls="", ms=5, label="track (velocity arrow: 1 s)"),
               Line2D([], [], color="0.3", marker=".", lw=1.0, alpha=0.6, label="track history")]
    if tracks is not None and tracks.forecast is not None:
        h = tracks.horizons
        span = f"{h[0]:g}–{h[-1]:g} s" if len(h) else ""
        handles += [Line2D([], [], color="0.3", ls="--", marker="o", ms=2, label=f"forecast mean {span}"),
                    Patch(fc="0.3", alpha=CONE_ALPHA[50], label="50 % forecast disc"),
                    Patch(fc="0.3", alpha=CONE_ALPHA[90], label="90 % forecast disc")]
    return handles


def plot_tracks(tracks: Tracks, path: str | Path, history: Mapping[int, np.ndarray] | None = None, region=None,
                walls=None, title: str = "") -> Path:
    """Write a bird's-eye PNG of ``tracks`` alone, over ``walls`` (a list of (n, 2) [m] polylines,
    e.g. GroundTruth wall ends, drawn grey) when given; returns the path. Limits: the radar, the
    tracks, their history and 90 % forecast discs, the region, 3 m margin."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 7))
    for i, w in enumerate(walls or []):
        ax.plot(*bev(w), color="0.75", lw=5, solid_capstyle="butt", label="walls" if i == 0 else None)
    draw_tracks(ax, tracks, history, region)
    ax.scatter([0], [0], marker="^", s=80, c="k", label="radar", zorder=5)
    pts = [np.zeros((1, 2)), tracks.position.reshape(-1, 2)]
    pts += [np.asarray(p, float).reshape(-1, 2) for p in (history or {}).values()]
    if tracks.forecast is not None:
        pts.append(tracks.forecast.reshape(-1, 2) + np.nan_to_num(tracks.radius90.reshape(-1, 1)))
        pts.append(tracks.forecast.reshape(-1, 2) - np.nan_to_num(tracks.radius90.reshape(-1, 1)))
    if region is not None:
        pts.append(np.asarray(region, float).reshape(-1, 2))
    set_bev_limits(ax, np.concatenate(pts), margin=3.0)
    handles, _ = ax.get_legend_handles_labels()
    ax.legend(handles=handles + track_legend_handles(tracks), loc="upper right", fontsize=7, framealpha=0.85)
    ax.grid(alpha=0.3)
    ax.set_title(title or f"tracks at t = {tracks.timestamp:.2f} s")
    return save_png(fig, path, dpi=100)
