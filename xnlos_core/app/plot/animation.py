"""The animated sequence of a run: ``sequence.gif``, written by ``xnlos run``.

Each GIF frame shows, left, the RA map (power above its median [dB], grey) with the detections
coloured by radial velocity (diverging colormap, limits ±v symmetric about 0 and fixed over the
sequence, colourbar in m/s, positive receding; grey where a detection has no velocity; no velocity
colourbar when no frame of the sequence has one; marker by class: LOS ○, mNLOS ×, unclassified □) and, right, the bird's-eye view: true and fitted walls, the
mNLOS detections (virtual points o'), the reconstructed hidden points, the true hidden points and
the tracks with their history and prediction cones (:mod:`xnlos_core.app.plot.track_figure`). Axis limits
and colour scales are fixed over the sequence so that motion reads as motion; the bird's-eye box
holds the radar, the true hidden points of every frame and the tracks (the true walls instead
when no hidden point is known, the estimates without ground truth), 5 m margin; a track outside
that box is marked on its edge and counted in the title as such.

The frames are drawn one at a time from the run's results.jsonl records (tracks, forecasts) and
its per-frame snapshots (:class:`xnlos_core.app.plot.frame_snapshot.FrameSnapshot`), so the animation can
be written again from the files of a finished or resumed run. Pillow (a matplotlib dependency)
encodes the GIF (each frame reduced to 256 colours by maximum coverage, which keeps the few
pixels of the markers' colours better than median cut on these mostly grey frames); it keeps the
encoded frames until the file is written (≈ 1.5 MB each, measured, for 1350 × 540 pixels), so at
most ``MAX_FRAMES`` frames (evenly spaced over the run) are drawn; frames are drawn lazily as they
are encoded, so no other copy is held.
"""
from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.app.plot import palette
from xnlos_core.bev import bev, legend_outside, orient_azimuth, set_bev_limits
from xnlos_core.app.plot.figures import CLASS_STYLE, ellipse_xy, credible_radius
from xnlos_core.app.plot.frame_snapshot import FrameSnapshot
from xnlos_core.io import atomic_write_bytes
from xnlos_core.app.plot.track_figure import count_outside, draw_tracks, mark_outside_view, track_legend_handles
from xnlos_core.track_record import track_history, tracks_from_record
from xnlos_core.types import LOS, MNLOS

#: Most GIF frames drawn (evenly spaced when the run has more): bounds memory.
MAX_FRAMES = 120
SNAPSHOT_DIR = "animation"
MARKERS = {LOS: "o", MNLOS: "X"}


def snapshot_path(out: str | Path, index: int) -> Path:
    """Where ``xnlos run`` keeps frame ``index``'s snapshot under its output directory ``out``."""
    return Path(out) / SNAPSHOT_DIR / f"frame_{index:04d}.npz"


def shown_frames(indices: Sequence[int], max_frames: int = MAX_FRAMES) -> list[int]:
    """At most ``max_frames`` of the sorted frame ``indices``, evenly spaced, first and last kept."""
    idx = sorted(indices)
    if len(idx) <= max_frames:
        return idx
    pick = np.unique(np.round(np.linspace(0, len(idx) - 1, max_frames)).astype(int))
    return [idx[k] for k in pick]


class _Scales:
    """Limits fixed over the sequence: bird's-eye box, |v| [m/s] and dB ceiling of the maps."""

    def __init__(self, snaps_points: list[np.ndarray], speeds: list[np.ndarray], db_tops: list[float]):
        self.points = np.concatenate(snaps_points) if snaps_points else np.zeros((1, 2))
        v = np.abs(np.concatenate(speeds)) if speeds else np.zeros(0)
        v = v[np.isfinite(v)]
        self.v_max = max(1.0, float(np.percentile(v, 99))) if len(v) else 1.0
        self.has_velocity = bool(len(v))  # a Doppler run: else no velocity colourbar at all
        self.db_max = max([30.0, *db_tops])


def _scales(snap_paths: list[Path], records: dict[int, dict]) -> _Scales:
    pts, speeds, tops = [np.zeros((1, 2))], [], []
    for path in snap_paths:
        s = FrameSnapshot.load(path)
        rmax = float(s.range_axis[-1])
        if len(s.true_hidden):  # where the hidden objects go: the walls' far ends may fall outside
            pts.append(s.true_hidden)
        elif len(s.true_walls):
            pts.append(s.true_walls.reshape(-1, 2))
        else:  # no ground truth: what was estimated, within the map's range
            est = np.concatenate([s.hidden_mean, s.det_position[s.det_label == LOS]])
            pts.append(est[np.hypot(*est.T) <= rmax])
        speeds.append(s.det_velocity)
        tops.append(float(np.percentile(s.ra_db.astype(float), 99.9)))
        t = records[s.index].get("tracks")
        if t and t["position"]:
            p = np.asarray(t["position"], float).reshape(-1, 2)
            pts.append(p[np.hypot(*p.T) <= rmax])
    return _Scales(pts, speeds, tops)


def _ra_panel(fig, ax, s: FrameSnapshot, scales: _Scales) -> None:
    az = np.degrees(s.azimuth_axis)
    ext = [az[0], az[-1], s.range_axis[0], s.range_axis[-1]]
    im = ax.imshow(s.ra_db.astype(np.float32), origin="lower", aspect="auto", cmap="gray", vmin=0,
                   vmax=scales.db_max, extent=ext)
    fig.colorbar(im, ax=ax, location="bottom", fraction=0.05, pad=0.12, label="power above median [dB]")
    sc = None
    for lab, (name, colour, marker) in CLASS_STYLE.items():
        m = s.det_label == lab
        if not m.any():
            continue
        v = s.det_velocity[m]
        known = np.isfinite(v)
        mk = MARKERS.get(lab, marker)
        if (~known).any():  # grey in a Doppler run; the class colour in a run without velocities
            ax.scatter(_az(s, m)[~known], s.det_range[m][~known], s=30, marker=mk,
                       c="0.6" if scales.has_velocity else colour, edgecolors="k", linewidths=0.5,
                       label=f"{name}{', no velocity' * scales.has_velocity} ({(~known).sum()})")
        if known.any():
            sc = ax.scatter(_az(s, m)[known], s.det_range[m][known], s=30, marker=mk, c=v[known], cmap="RdBu_r",
                            vmin=-scales.v_max, vmax=scales.v_max, edgecolors="k", linewidths=0.5,
                            label=f"{name} ({known.sum()})")
    if scales.has_velocity:  # on every frame of a Doppler run, with or without moving detections: same layout
        import matplotlib as mpl

        from xnlos_core.app.plot.radar_views import VELOCITY_LABEL

        sc = sc or mpl.cm.ScalarMappable(norm=mpl.colors.Normalize(-scales.v_max, scales.v_max), cmap="RdBu_r")
        fig.colorbar(sc, ax=ax, label=VELOCITY_LABEL)
    orient_azimuth(ax, ext[:2])
    ax.set_ylim(ext[2], ext[3])
    ax.set_ylabel("range [m]")
    ax.set_title(f"RA map and detections ({len(s.det_range)})", fontsize=10, pad=20)
    if len(s.det_range):  # above the map, under the title: the dB colourbar is below it
        legend_outside(ax, where="above", ncol=4, frameon=False)


def _az(s: FrameSnapshot, mask) -> np.ndarray:
    """Azimuths [deg] of the masked detections."""
    return np.degrees(s.det_azimuth[mask])


def _bev_panel(ax, s: FrameSnapshot, tracks, history, region, scales: _Scales) -> None:
    rmax = s.range_axis[-1]
    for a in s.azimuth_axis[[0, -1]]:
        ax.plot(*bev([[0, 0], [rmax * np.cos(a), rmax * np.sin(a)]]), color="0.8", lw=0.8, ls=":", zorder=palette.Z_BAND)
    for i, (a, b) in enumerate(s.true_walls):
        ax.plot(*bev([a, b]), color=palette.TRUE_WALL_BAND, lw=5, solid_capstyle="butt", zorder=palette.Z_BAND)
        ax.plot(*bev([a, b]), color=palette.TRUE_WALL, lw=1.0, zorder=palette.Z_TRUTH,
                label="true walls" if i == 0 else None)
    for i, c in enumerate(s.walls):
        ax.plot(*bev(c), color=palette.WALL_ESTIMATE, lw=2, ls="--", zorder=palette.Z_ESTIMATE,
                label="fitted walls" if i == 0 else None)
    m = s.det_label == MNLOS
    if m.any():
        ax.scatter(*bev(s.det_position[m]), s=10, c=CLASS_STYLE[MNLOS][1], marker="x", alpha=0.5,
                   label=f"mNLOS (virtual o') ({m.sum()})", zorder=palette.Z_DETECTION)
    if len(s.hidden_mean):
        ax.scatter(*bev(s.hidden_mean), s=40, c=palette.ESTIMATE, marker="+", linewidths=1.4, zorder=palette.Z_ESTIMATE,
                   label=f"reconstructed hidden points ({len(s.hidden_mean)}; 90 % credible)")
        for mu, c in zip(s.hidden_mean, s.hidden_cov):
            ax.plot(*bev(ellipse_xy(mu, c, credible_radius(0.9))), color=palette.ESTIMATE, lw=0.6, alpha=0.6,
                    zorder=palette.Z_ESTIMATE)
    if len(s.true_hidden):
        ax.scatter(*bev(s.true_hidden), s=8, c=palette.TRUTH, alpha=0.6, label="true hidden points",
                   zorder=palette.Z_TRUTH)
    draw_tracks(ax, tracks, history, region)
    ax.scatter([0], [0], marker="^", s=70, c="k", label="radar", zorder=palette.Z_RADAR)
    set_bev_limits(ax, scales.points, margin=5.0)
    outside = count_outside(mark_outside_view(ax, tracks))
    handles, _ = ax.get_legend_handles_labels()
    if tracks is not None and len(tracks):
        handles += track_legend_handles(tracks)
    legend_outside(ax, handles=handles, where="right", frameon=False)
    ax.grid(alpha=0.3)
    n, m = 0 if tracks is None else len(tracks), len(s.hidden_mean)
    ax.set_title(f"bird's-eye view: {m} reconstructed hidden point{'s' * (m != 1)}, {n} track{'s' * (n != 1)}"
                 + (f" ({outside} outside, at the edge)" if outside else ""), fontsize=10)


def render_frame(s: FrameSnapshot, record: dict, history=None, region=None, scales: _Scales | None = None,
                 title: str = "", dpi: int = 90):
    """One animation frame as a palette (``P``) PIL image; ``record``: the frame's results.jsonl
    record (its ``tracks``), history: track id → past positions (:func:`track_history`)."""
    import matplotlib.pyplot as plt
    from PIL import Image

    fig = animation_figure(s, record, history, region, scales, title)
    try:
        fig.tight_layout()
        fig.set_dpi(dpi)
        fig.canvas.draw()
        rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3]
    finally:
        plt.close(fig)
    return Image.fromarray(np.ascontiguousarray(rgb)).quantize(colors=256, method=Image.Quantize.MAXCOVERAGE)


def animation_figure(s: FrameSnapshot, record: dict, history=None, region=None, scales: _Scales | None = None,
                     title: str = ""):
    """The matplotlib Figure of one animation frame (not laid out, not closed); arguments as
    :func:`render_frame`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scales = scales or _scales_from([s])
    tracks = tracks_from_record(record.get("tracks"), s.timestamp, where=f"frame {s.index}: tracks")
    fig, (ax_ra, ax_bev) = plt.subplots(1, 2, figsize=(15, 6), gridspec_kw={"width_ratios": [1, 1.05]})
    try:
        _ra_panel(fig, ax_ra, s, scales)
        _bev_panel(ax_bev, s, tracks, history, region, scales)
    except BaseException:
        plt.close(fig)
        raise
    fig.suptitle(f"{title} — frame {s.index}, t = {s.timestamp:.2f} s".lstrip(" —"))
    return fig


def _scales_from(snaps) -> _Scales:
    """Scales of the given snapshots alone (a frame drawn on its own)."""
    pts, speeds, tops = [np.zeros((1, 2))], [], []
    for s in snaps:
        pts += [s.true_walls.reshape(-1, 2), s.true_hidden, s.hidden_mean]
        speeds.append(s.det_velocity)
        tops.append(float(np.percentile(s.ra_db.astype(float), 99.9)) if s.ra_db.size else 0.0)
    return _Scales(pts, speeds, tops)


def write_sequence_gif(path: str | Path, records: Sequence[dict], snapshot_dir: str | Path, *, region=None,
                       title: str = "", progress: bool = False, max_frames: int = MAX_FRAMES,
                       history_frames: int = 15) -> Path:
    """Write the animated GIF of a run to ``path`` (atomically) from its results.jsonl ``records``
    and the snapshots ``snapshot_dir/frame_NNNN.npz`` of the same frames; returns the path.

    region: (P, 2) [m] the tracker's arrival region polygon or None; history_frames: how many past
    frames of each track's positions are drawn. Frame delay: the recorded time between the shown
    frames (real time), clamped to 50 ms … 2 s. Raises InputError naming the frame whose snapshot
    is missing, and when there are no records.
    """
    from tqdm import tqdm

    by_frame = {int(r["frame"]): r for r in records}
    if not by_frame:
        raise InputError(f"{path}: no frames to animate (the run has no records)")
    shown = shown_frames(list(by_frame), max_frames)
    paths = []
    for k in shown:
        p = Path(snapshot_dir) / f"frame_{k:04d}.npz"
        if not p.exists():
            raise InputError(f"{p}: missing the snapshot of frame {k} that the animation needs")
        paths.append(p)
    scales = _scales(paths, by_frame)

    def frames():  # drawn lazily as Pillow encodes: only Pillow's copies of the frames are held
        for k, p in tqdm(list(zip(shown, paths)), disable=not progress, desc="animation", unit="frame"):
            hist = track_history(by_frame.values(), k, history_frames)
            yield render_frame(FrameSnapshot.load(p), by_frame[k], hist, region, scales, title)

    times = [by_frame[k].get("timestamp") or 0.0 for k in shown]
    dt = float(np.median(np.diff(times))) if len(times) > 1 else 0.5
    duration = int(np.clip(1000 * dt, 50, 2000))
    images = frames()
    buf = io.BytesIO()
    next(images).save(buf, format="GIF", save_all=True, append_images=images, duration=duration, loop=0)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)

