"""Figures: the RA map with detections beside the bird's-eye view of walls and hidden points, and
the corner plot of a wall posterior.

Credible ellipses: for a 2-D Gaussian N(μ, Σ) the p-credible region is the ellipse
(x − μ)ᵀΣ⁻¹(x − μ) ≤ χ²₂(p) = −2 ln(1 − p), i.e. radius √(−2 ln(1 − p)) in σ units
(1.18σ for 50 %, 2.15σ for 90 %).
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from xnlos_core.app.plot import palette
from xnlos_core.bev import bev, legend_outside, orient_azimuth, save_png  # noqa: F401  (re-exported to figure modules)
from xnlos_core.io import atomic_write_bytes
from xnlos_core.app.plot.palette import CLASS_STYLE  # noqa: F401  (re-exported: figure modules import it from here)
from xnlos_core.types import MNLOS


def credible_radius(p: float) -> float:
    """√χ²₂(p): radius in σ units of the p-credible ellipse of a 2-D Gaussian."""
    return float(np.sqrt(-2.0 * np.log1p(-p)))


def draw_walls(ax, walls, true_walls=None, label: str = "estimated walls", samples: int = 0) -> None:
    """Bird's-eye walls on ``ax``: the true walls (GroundTruth.walls) when given — a wide light band
    under everything and a thin centre line above the estimates (ground truth on top) — each
    estimated WallPosterior over its extent (dashed), and for a sampled wall ``samples`` posterior
    draws as thin lines."""
    if true_walls is not None:
        for i, w in enumerate(true_walls):
            ax.plot(*bev([w.start, w.end]), color=palette.TRUE_WALL_BAND, lw=5, solid_capstyle="butt",
                    zorder=palette.Z_BAND)
            ax.plot(*bev([w.start, w.end]), color=palette.TRUE_WALL, lw=1.0, zorder=palette.Z_TRUTH,
                    label="true walls" if i == 0 else None)
    drawn = sampled = False
    for w in walls:
        curve = wall_curve(w)
        if curve is None:
            continue
        ax.plot(*bev(curve), color=palette.WALL_ESTIMATE, lw=2, ls="--", zorder=palette.Z_ESTIMATE,
                label=None if drawn else label)
        drawn = True
        if w.samples is not None and samples > 0 and w.extent is not None:
            _plot_wall_draws(ax, w, samples, first=not sampled)
            sampled = True


def draw_objects(ax, outlines: dict, annotate: bool = True) -> None:
    """True outlines of the hidden objects that have a mirror path: name → (K, 2) [m] bird's-eye
    outline (``ObjectSpec.footprint``: a box's corners, or one point), drawn solid in the truth
    colour above the reconstructions, labelled by name."""
    for i, (name, pts) in enumerate(outlines.items()):
        pts = np.asarray(pts, float).reshape(-1, 2)
        label = "hidden objects (true outline)" if i == 0 else None
        if len(pts) > 1:
            ax.fill(*bev(pts), facecolor="none", edgecolor=palette.TRUTH, lw=1.6, label=label, zorder=palette.Z_TRUTH)
        else:
            ax.scatter(*bev(pts), s=80, facecolors="none", edgecolors=palette.TRUTH, lw=1.6, label=label,
                       zorder=palette.Z_TRUTH)
        if annotate:
            x, y = bev(pts.mean(0, keepdims=True))
            ax.annotate(name, (x[0], y[0]), textcoords="offset points", xytext=(0, 10), ha="center", fontsize=8,
                        color=palette.TRUTH, zorder=palette.Z_TRUTH, gid=OBJECT_LABEL)


def draw_unobservable(ax, outlines: dict, annotate: bool = True) -> None:
    """Outlines of hidden objects without a mirror path (no relay wall shows them to the radar):
    name → (K, 2) [m] bird's-eye outline (a box's corners, or one point), drawn dashed grey with a
    "<name>: not observable" label, so that an object nothing could reconstruct stays visible."""
    for i, (name, pts) in enumerate(outlines.items()):
        pts = np.asarray(pts, float).reshape(-1, 2)
        label = "hidden, no mirror path (not observable)" if i == 0 else None
        if len(pts) > 1:
            ax.fill(*bev(pts), facecolor="none", edgecolor=palette.UNOBSERVABLE, ls="--", lw=1.4, label=label,
                    zorder=palette.Z_TRUTH)
        else:
            ax.scatter(*bev(pts), s=60, facecolors="none", edgecolors=palette.UNOBSERVABLE, linestyle="--",
                       label=label, zorder=palette.Z_TRUTH)
        if annotate:
            x, y = bev(pts.mean(0, keepdims=True))
            ax.annotate(f"{name}: not observable", (x[0], y[0]), textcoords="offset points", xytext=(0, 10),
                        ha="center", fontsize=8, color="0.25", gid=OBJECT_LABEL)


#: gid of the object name labels that :func:`separate_labels` moves apart.
OBJECT_LABEL = "object label"


def separate_labels(ax, gid: str = OBJECT_LABEL, pad_pt: float = 2.0) -> int:
    """Move the annotations of ``ax`` with ``gid`` (object names, placed in offset points) upward,
    lowest anchor first, until no two boxes overlap at the current layout (``pad_pt`` points
    apart); call once limits are set. Returns how many were moved."""
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    texts = sorted((t for t in ax.texts if t.get_gid() == gid), key=lambda t: (t.xy[1], t.xy[0]))
    placed, moved = [], 0
    for t in texts:
        for _ in range(len(texts) + 1):
            box = t.get_window_extent(renderer)
            hits = [b for b in placed if box.x0 < b.x1 and b.x0 < box.x1 and box.y0 < b.y1 and b.y0 < box.y1]
            if not hits:
                break
            dx, dy = t.xyann
            t.xyann = (dx, dy + (max(b.y1 for b in hits) - box.y0) * 72.0 / fig.dpi + pad_pt)
            moved += 1
        placed.append(t.get_window_extent(renderer))
    return moved


OUTLINES_META = "object_outlines"


def outlines_from_meta(meta: dict) -> dict[str, np.ndarray]:
    """Object name → bird's-eye outline (K, 2) [m] from ``meta["object_outlines"]`` (what the dataset
    reader puts into a map's ``frame.meta``: name → list of [x, y] at the map's time); {} when the
    key is absent. InputError naming the object when an outline is not a list of finite [x, y]."""
    raw = meta.get(OUTLINES_META)
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        from xnlos_core.errors import InputError

        raise InputError(f"frame.meta[{OUTLINES_META!r}]: expected a mapping object name → [[x, y], …] [m], "
                         f"got {type(raw).__name__}")
    out = {}
    for name, pts in raw.items():
        a = np.asarray(pts, dtype=float)
        if a.ndim != 2 or a.shape[1] != 2 or not len(a) or not np.isfinite(a).all():
            from xnlos_core.errors import InputError

            raise InputError(f"frame.meta[{OUTLINES_META!r}][{name!r}]: expected a non-empty list of finite "
                             f"[x, y] [m], got an array of shape {a.shape}")
        out[str(name)] = a
    return out


def split_outlines(outlines: dict, metrics: dict) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(objects, unobservable) of the outlines name → (K, 2) [m] of a frame's scene objects, by the
    frame's metrics (:meth:`xnlos_core.pipeline.Pipeline` ground-truth counts): ``objects`` holds those
    with a mirror path (``mirror_paths`` ≥ 1, or not counted), drawn by :func:`draw_objects`;
    ``unobservable`` those with none that are not in line of sight either (``los_points`` 0 or not
    recorded), drawn by :func:`draw_unobservable`; an object seen only directly is in neither."""
    paths = metrics.get("mirror_paths") or {}
    los = metrics.get("los_points") or {}
    objects = {n: p for n, p in outlines.items() if paths.get(n, 1) != 0}
    unobservable = {n: p for n, p in outlines.items() if paths.get(n, 1) == 0 and los.get(n, 0) == 0}
    return objects, unobservable


def zoom_inset(ax, draw, focus, *, margin: float = 2.0, bounds=(1.04, 0.0, 0.55, 0.45)):
    """A zoomed copy of the bird's-eye panel ``ax`` around the points ``focus`` (N, 2) [m] (the
    hidden object): an inset axes at ``bounds`` (axes fraction x0, y0, width, height; the default
    sits outside the data area, right of the panel under its legend) on which ``draw(inset)`` draws
    the panel's content again, limited to the focus box plus ``margin`` [m] (at least 1.5 m around
    its centre), with the zoomed region marked on ``ax``. Returns the inset axes, or None when
    ``focus`` holds no finite point."""
    pts = np.asarray(focus, float).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(1)]
    if not len(pts):
        return None
    inset = ax.inset_axes(bounds)
    draw(inset)
    x, y = bev(pts)
    cx, cy = 0.5 * (x.min() + x.max()), 0.5 * (y.min() + y.max())
    half = max(1.5, 0.5 * max(np.ptp(x), np.ptp(y)) + margin)
    inset.set_xlim(cx - half, cx + half)
    inset.set_ylim(cy - half, cy + half)
    inset.set_aspect("equal")
    inset.tick_params(labelsize=6)
    if bounds[0] >= 1.0:  # right of the panel: tick labels on the far side, off the panel's data area
        inset.yaxis.tick_right()
    inset.set_title("zoom: hidden object", fontsize=7)
    inset.grid(alpha=0.3)
    ax.indicate_inset_zoom(inset, edgecolor="0.3")
    return inset


def frame_bev(ax, gt, fallback, extra=()) -> None:
    """Bird's-eye limits (5 m margin) around the radar and the ground truth ``gt`` (walls, hidden
    and virtual points) or, without ground truth, around the arrays (N, 2) [m] in ``fallback``; far
    false alarms then fall outside rather than shrinking the scene to a corner of the plot.
    ``extra``: more arrays (N, 2) [m] always inside (e.g. unobservable objects' outlines)."""
    pts = [np.zeros((1, 2))] + list(extra)
    if gt is not None and (len(gt.walls) or len(gt.hidden_points)):
        pts += [gt.hidden_points, gt.mnlos_points] + [np.stack([w.start, w.end]) for w in gt.walls]
    else:
        pts += list(fallback)
    allp = np.concatenate([p.reshape(-1, 2) for p in pts])
    lo, hi = allp.min(0) - 5, allp.max(0) + 5
    ax.set_xlim(-hi[1], -lo[1])
    ax.set_ylim(min(lo[0], -2), hi[0])
    ax.set_aspect("equal")
    ax.set_xlabel("−y [m] (right →)")
    ax.set_ylabel("x [m] (forward)")


def wall_curve(w, n: int = 64) -> np.ndarray | None:
    """(n, 2) points along a 'line'/'arc' WallPosterior between its extent ends, or None.

    An arc is drawn by arc length s from its tangent point p₀ (WallPosterior doc):
    p(s) = p₀ + u·sin(κs)/κ − n·(1 − cos κs)/κ, written with sinc so that κ = 0 is the line.
    """
    if w.model not in ("line", "arc") or w.extent is None:
        return None
    if w.model == "line":
        return np.asarray(w.extent)
    nrm, kappa, p0 = w.normal, w.curvature, w.tangent_point
    u = np.array([-nrm[1], nrm[0]])
    t_ends = (w.extent - p0) @ u
    s_ends = t_ends if kappa == 0 else np.arcsin(np.clip(kappa * t_ends, -1.0, 1.0)) / kappa
    s = np.linspace(s_ends[0], s_ends[1], n)
    along = s * np.sinc(kappa * s / np.pi)
    across = 0.5 * kappa * s * s * np.sinc(kappa * s / (2 * np.pi)) ** 2
    return p0 + along[:, None] * u - across[:, None] * nrm


def ellipse_xy(mean, cov, nsigma=2.0, n=48):
    """Points of the nσ ellipse of a 2-D Gaussian, shape (n, 2)."""
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    vals = np.clip(vals, 0, None)
    t = np.linspace(0, 2 * np.pi, n)
    circle = np.stack([np.cos(t), np.sin(t)], -1)
    return mean + nsigma * (circle * np.sqrt(vals)) @ vecs.T


def plot_frame(result, path: str | Path, title: str = "", **kw) -> Path:
    """Write :func:`frame_figure` of one FrameResult to ``path`` as PNG; returns the path. Keywords
    as :func:`frame_figure`."""
    return save_png(frame_figure(result, title, **kw), path, dpi=110)


def has_velocity(result) -> bool:
    """Whether a FrameResult carries radial velocities (a Doppler run): its detections' velocities
    (some finite) or its RA map's per-cell ``velocity``."""
    v = result.detections.velocity
    return (v is not None and bool(np.isfinite(v).any())) or result.frame.ra_map.velocity is not None


def velocity_norm(velocities, floor: float = 1.0):
    """Symmetric colour scale ±v [m/s] for radial velocities: v = the 99th percentile of |v| (finite
    ones), at least ``floor``; a matplotlib Normalize."""
    from matplotlib.colors import Normalize

    v = np.abs(np.asarray(velocities, float).ravel())
    v = v[np.isfinite(v)]
    top = max(floor, float(np.percentile(v, 99))) if len(v) else floor
    return Normalize(-top, top)


#: Diverging colormap of radial velocity (blue approaching, red receding).
VELOCITY_CMAP = "RdBu_r"


def scatter_ra_detections(ax, det, norm=None, *, s: float = 28, zorder: float = palette.Z_ESTIMATE):
    """Detections on an RA-map panel (azimuth [deg] × range [m]), marker by class (CLASS_STYLE).
    Without ``norm``: class colours. With ``norm`` (a Doppler run, :func:`velocity_norm`): filled
    by radial velocity (:data:`VELOCITY_CMAP`, black edge), grey where a detection has none.
    Returns the velocity-coloured PathCollection to hang a colour bar on, or None."""
    mappable = None
    vel = None if det.velocity is None else np.asarray(det.velocity, float)
    for lab, (name, color, marker) in CLASS_STYLE.items():
        m = det.label == lab
        if not m.any():
            continue
        az, r = np.degrees(det.azimuth[m]), det.range[m]
        if norm is None or vel is None:
            style = {"facecolors": "none", "edgecolors": color} if marker == "o" else {"c": color}
            ax.scatter(az, r, s=s, marker=marker, label=f"{name} ({m.sum()})", linewidths=1.2, zorder=zorder, **style)
            continue
        v = vel[m]
        known = np.isfinite(v)
        mk = "X" if marker == "x" else marker
        if (~known).any():
            ax.scatter(az[~known], r[~known], s=s, marker=mk, c="0.6", edgecolors="k", linewidths=0.5,
                       label=f"{name}, no velocity ({(~known).sum()})", zorder=zorder)
        if known.any():
            mappable = ax.scatter(az[known], r[known], s=s, marker=mk, c=v[known], cmap=VELOCITY_CMAP, norm=norm,
                                  edgecolors="k", linewidths=0.5, label=f"{name} ({known.sum()})", zorder=zorder)
    return mappable


def velocity_colorbar(fig, ax, norm, **kw):
    """The radial-velocity colour bar of ``ax`` (drawn only for a Doppler run); returns it."""
    import matplotlib as mpl

    from xnlos_core.app.plot.radar_views import VELOCITY_LABEL

    return fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=VELOCITY_CMAP), ax=ax, label=VELOCITY_LABEL, **kw)


def frame_figure(result, title: str = "", *, credible: tuple[float, ...] = (0.5, 0.9), wall_samples: int = 30,
                 history=None, region=None, unobservable=None, objects=None, zoom: bool = True,
                 ra_view: str = "polar", range_doppler: bool | None = None):
    """The figure of one FrameResult: the RA map with the detections, for a Doppler run its
    range–Doppler view, and the bird's-eye reconstruction with the tracks (history, velocity,
    prediction cones: :func:`xnlos_core.app.plot.track_figure.draw_tracks`) when the result has them.
    Legends sit outside the data areas (the bird's-eye one below its panel, the zoom inset right
    of it), ground truth above the estimates, detections under the walls fitted through them.
    Returns the matplotlib Figure (not closed).

    Velocity: when the result carries radial velocities (:func:`has_velocity`), the RA map is grey
    and the detections are filled by radial velocity with a colour bar in m/s; without, no
    velocity colour bar. ra_view: "polar" (azimuth × range image) or "cartesian" (the fan in the
    bird's-eye plane, :func:`xnlos_core.app.plot.radar_views.draw_ra_cartesian`); range_doppler:
    add the range–Doppler panel from the map's per-cell velocity
    (:func:`~xnlos_core.app.plot.radar_views.range_velocity_from_ra`); default: when the RA map
    has one. Tracks outside the bird's-eye view are marked at its edge
    (:func:`~xnlos_core.app.plot.track_figure.mark_outside_view`), so the title's count is what
    is drawn.

    credible: levels of the credible ellipses drawn around each reconstructed hidden point (from
    HiddenPoints.cov; the largest solid, the others dotted); wall_samples: how many posterior
    draws of each sampled wall (WallPosterior.samples) are drawn as thin lines; history: track id
    → (n, 2) [m] past positions; region: (P, 2) [m] the tracker's arrival region polygon or None;
    unobservable: name → (K, 2) [m] outline of each hidden object without a mirror path
    (:func:`draw_unobservable`) or None; objects: name → (K, 2) [m] true outline of each hidden
    object with one (:func:`draw_objects`) or None; zoom: add :func:`zoom_inset` around the hidden
    objects (their outlines, else the true hidden points, else the reconstructed ones).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from xnlos_core.app.plot import radar_views

    if ra_view not in ("polar", "cartesian"):
        from xnlos_core.errors import InputError

        raise InputError(f"frame_figure ra_view={ra_view!r}: expected 'polar' or 'cartesian'")
    frame, det = result.frame, result.detections
    ra = frame.ra_map
    doppler = has_velocity(result)
    rd = ra.velocity is not None if range_doppler is None else bool(range_doppler)
    ratios = [1.0] + ([0.75] if rd else []) + [1.25]
    fig, axes = plt.subplots(1, len(ratios), figsize=(9 + 8 * sum(ratios) / 2.25, 7.2),
                             gridspec_kw={"width_ratios": ratios})
    ax_ra, ax_bev = axes[0], axes[-1]

    p_db = ra.power_db()
    floor = np.median(p_db)
    vmax = max(30.0, float(np.percentile(p_db - floor, 99.9)))
    az_deg = np.degrees(ra.azimuth_axis)
    norm = velocity_norm(det.velocity if det.velocity is not None else []) if doppler else None
    cmap = "gray" if doppler else "viridis"
    if ra_view == "polar":
        im = ax_ra.imshow(p_db - floor, origin="lower", aspect="auto", cmap=cmap, vmin=0, vmax=vmax,
                          extent=[az_deg[0], az_deg[-1], ra.range_axis[0], ra.range_axis[-1]])
        scatter_ra_detections(ax_ra, det, norm)
        orient_azimuth(ax_ra, az_deg)
        ax_ra.set_ylabel("range [m]")
    else:
        im = radar_views.draw_ra_cartesian(ax_ra, ra, vmax=vmax, cmap=cmap)
        _scatter_bev_detections(ax_ra, det, norm, s=20)
    fig.colorbar(im, ax=ax_ra, label="power above median [dB]")
    if norm is not None:
        velocity_colorbar(fig, ax_ra, norm)
    if ra_view == "polar":
        ax_ra.set_title(f"RA map and detections ({len(det)})")
        if len(det):
            legend_outside(ax_ra, where="below", fontsize=8)
    else:  # an equal-aspect fan leaves no fixed room below: the legend goes between it and its title
        ax_ra.set_title(f"RA map and detections ({len(det)}), fan view", pad=22 if len(det) else 6)
        if len(det):
            legend_outside(ax_ra, where="above", fontsize=8, ncol=4, frameon=False)
    if rd:
        ax_rd = axes[1]
        db, v_axis = radar_views.range_velocity_from_ra(ra)
        mesh = radar_views.draw_range_doppler(ax_rd, db, ra.range_axis, v_axis)
        fig.colorbar(mesh, ax=ax_rd, label="power at that velocity, above median [dB]")
        ax_rd.set_title("range–Doppler (per-cell velocity)")

    gt = frame.ground_truth
    h = result.hidden
    tracks = result.tracks
    objects = objects or {}
    unobservable = unobservable or {}

    def draw(ax, main: bool = True) -> None:
        fov = ra.azimuth_axis[[0, -1]]
        rmax = ra.range_axis[-1]
        for a in fov:
            ax.plot(*bev([[0, 0], [rmax * np.cos(a), rmax * np.sin(a)]]), color="0.8", lw=0.8, ls=":",
                    zorder=palette.Z_BAND)
        draw_walls(ax, result.walls, None if gt is None else gt.walls, samples=wall_samples)
        for lab, (name, color, marker) in CLASS_STYLE.items():
            m = det.label == lab
            if m.any():
                label = f"mNLOS detections (virtual o') ({m.sum()})" if lab == MNLOS else f"{name} detections ({m.sum()})"
                ax.scatter(*bev(det.position[m]), s=12, c=color, marker=marker, label=label, alpha=0.8,
                           zorder=palette.Z_DETECTION)
        if len(h):
            levels = sorted(credible)
            pct = "/".join(f"{100 * p:g}" for p in levels)
            ax.scatter(*bev(h.mean), s=60, c=palette.ESTIMATE, marker="+", linewidths=2, zorder=palette.Z_ESTIMATE,
                       label=f"reconstructed hidden points ({len(h)}; {pct} % credible)" if levels
                       else f"reconstructed hidden points ({len(h)})")
            for mu, c in zip(h.mean, h.cov):
                for p in levels:
                    ax.plot(*bev(ellipse_xy(mu, c, credible_radius(p))), color=palette.ESTIMATE,
                            lw=0.9 if p == levels[-1] else 0.7, ls="-" if p == levels[-1] else ":", alpha=0.75,
                            zorder=palette.Z_ESTIMATE)
        if gt is not None and len(gt.hidden_points):
            ax.scatter(*bev(gt.hidden_points), s=14, c=palette.TRUTH, marker="o", label="true hidden points",
                       zorder=palette.Z_TRUTH)
        if (tracks is not None and len(tracks)) or region is not None:
            from xnlos_core.app.plot.track_figure import draw_tracks

            draw_tracks(ax, tracks, history, region)
        draw_objects(ax, objects, annotate=main)
        draw_unobservable(ax, unobservable, annotate=main)
        ax.scatter([0], [0], marker="^", s=90, c="k", label="radar", zorder=palette.Z_RADAR)

    draw(ax_bev)
    frame_bev(ax_bev, gt, [det.position, h.mean], extra=list(objects.values()) + list(unobservable.values()))
    n_tracks = 0 if tracks is None else len(tracks)
    outside = 0
    if n_tracks:
        from xnlos_core.app.plot.track_figure import count_outside, mark_outside_view

        outside = count_outside(mark_outside_view(ax_bev, tracks))
    ax_bev.set_title(f"bird's-eye view: {len(h)} reconstructed hidden point{'s' * (len(h) != 1)}"
                     + (f", {n_tracks} track{'s' * (n_tracks != 1)}" if n_tracks else "")
                     + (f" ({outside} outside the view, marked at its edge)" if outside else ""))
    handles, _ = ax_bev.get_legend_handles_labels()
    if n_tracks:
        from xnlos_core.app.plot.track_figure import track_legend_handles

        handles += track_legend_handles(tracks)
    legend_outside(ax_bev, handles=handles, where="below", framealpha=0.85, ncol=2)
    ax_bev.grid(alpha=0.3)
    separate_labels(ax_bev)
    if zoom:
        focus = (np.concatenate([np.reshape(v, (-1, 2)) for v in objects.values()]) if objects
                 else gt.hidden_points if gt is not None and len(gt.hidden_points) else h.mean)
        zoom_inset(ax_bev, lambda ax: draw(ax, main=False), focus)
    if title:
        fig.suptitle(f"{title} — frame {frame.index}, t = {frame.timestamp:.2f} s")
    return fig


def _scatter_bev_detections(ax, det, norm=None, *, s: float = 16) -> None:
    """Detections at their bird's-eye positions (mNLOS: the virtual point o'), marker by class,
    filled by radial velocity when ``norm`` is given (as :func:`scatter_ra_detections`)."""
    vel = None if det.velocity is None else np.asarray(det.velocity, float)
    for lab, (name, color, marker) in CLASS_STYLE.items():
        m = det.label == lab
        if not m.any():
            continue
        if norm is None or vel is None:
            ax.scatter(*bev(det.position[m]), s=s, c=color, marker=marker, label=f"{name} ({m.sum()})",
                       zorder=palette.Z_DETECTION)
        else:
            ax.scatter(*bev(det.position[m]), s=s, c=vel[m], cmap=VELOCITY_CMAP, norm=norm, plotnonfinite=True,
                       marker="X" if marker == "x" else marker, edgecolors="k", linewidths=0.5,
                       label=f"{name} ({m.sum()})", zorder=palette.Z_DETECTION)


def _plot_wall_draws(ax, wall, k: int, first: bool) -> None:
    """``k`` evenly spaced posterior draws of a sampled wall over its extent, drawn over its mean
    in :data:`palette.WALL_DRAWS`; the legend entry states how far they spread: the 90th
    percentile over the draws of their largest distance from the mean curve [cm], which may be
    less than a line width at the figure's scale."""
    from dataclasses import replace

    idx = np.linspace(0, len(wall.samples) - 1, min(k, len(wall.samples))).astype(int)
    mean_curve = wall_curve(wall)
    curves = []
    for s in wall.samples[idx]:
        draw = replace(wall, mean=s, cov=np.zeros_like(wall.cov), samples=None, info={})
        if wall.model == "line":  # the extent is the mean's: its ends projected onto the drawn line
            n = np.array([np.cos(s[0]), np.sin(s[0])])
            ends = np.asarray(wall.extent, float)
            curve = ends - (ends @ n + s[1])[:, None] * n
        else:
            curve = wall_curve(draw)
        if curve is not None and np.isfinite(curve).all():
            curves.append(curve)
    if not curves:
        return
    spread = [float(np.max(np.linalg.norm(c - mean_curve, axis=1))) for c in curves
              if mean_curve is not None and c.shape == mean_curve.shape]
    label = f"wall posterior draws ({len(curves)}"
    label += f"; 90 % within {100 * np.percentile(spread, 90):.0f} cm)" if spread else ")"
    for j, curve in enumerate(curves):
        ax.plot(*bev(curve), color=palette.WALL_DRAWS, lw=0.8, alpha=0.45, zorder=palette.Z_ESTIMATE + 0.5,
                label=label if first and j == 0 else None)


def plot_wall_corner(posterior, path: str | Path, truth=None, n_draws: int = 4000, seed: int = 0) -> Path:
    """Corner plot (PNG) of a WallPosterior's parameters: its samples, or — for a Laplace/Gaussian
    posterior without samples — ``n_draws`` draws of N(mean, cov) from ``seed``. φ is shown in
    degrees; ``truth`` (P,) in the posterior's parameters marks the true values. The title
    carries the model and the model-selection reason when the posterior has one."""
    import matplotlib

    matplotlib.use("Agg")
    import corner
    import matplotlib.pyplot as plt

    mean = np.asarray(posterior.mean, float)
    if posterior.samples is not None and len(posterior.samples) > len(mean):
        draws, source = np.asarray(posterior.samples, float), "posterior samples"
    else:
        rng = np.random.default_rng(seed)
        draws = rng.multivariate_normal(mean, posterior.cov, size=n_draws, method="eigh")
        source = "Laplace Gaussian"
    draws = draws.copy()
    draws[:, 0] = np.degrees(mean[0] + np.angle(np.exp(1j * (draws[:, 0] - mean[0]))))
    units = {"phi": "φ [deg]", "b": "b [m]", "kappa": "κ [1/m]"}
    labels = [units.get(n, n) for n in posterior.param_names]
    truths = None
    if truth is not None:
        truths = np.asarray(truth, float).copy()
        truths[0] = np.degrees(mean[0] + np.angle(np.exp(1j * (truths[0] - mean[0]))))
    span = np.ptp(draws, axis=0)
    if np.any(span <= 0):  # corner needs a non-empty range per parameter
        draws = draws + 1e-12 * np.maximum(np.abs(draws).max(axis=0), 1.0) * \
            np.random.default_rng(seed).standard_normal(draws.shape)
    fig = corner.corner(draws, labels=labels, truths=truths, quantiles=[0.05, 0.5, 0.95],
                        show_titles=True, title_fmt=".3g", levels=(0.5, 0.9))
    sel = posterior.info.get("model_selection", {}) if isinstance(posterior.info, dict) else {}
    text = f"wall model '{posterior.model}' ({source}, {posterior.n_points} LOS points)"
    if sel.get("reason"):
        text += "\n" + sel["reason"]
    fig.suptitle(text, fontsize=9, y=1.02)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)
