"""Figures of the cross-modality study (:mod:`xnlos_core.app.crossmodal.study`): the range curve (F1 vs
distance behind the corner per modality, and below it each row's range to failure: the seeds'
bisection results, their median and bootstrap interval, or the sweep bound reached) and a Fig. 5-style panel (paper Sec. 5.1.2): one row per
modality, columns scene (top view), raw measurement (radar: |RA map| [dB] over range × azimuth;
SPAD: counts summed over the scan rows, scan x × round-trip range c·t/2), intensity or dense
prediction (radar: RA map with the detections, LOS and mNLOS; SPAD: the solver's albedo, max over
the scan rows, x × depth z) and reconstruction (radar: hidden points and the true outline, top
view, the scene panel's axes; SPAD: the albedo's peak, the visible hidden surface, the scan
aperture and the peak search region, x × z in wall coordinates). Colours and drawing order from
:mod:`xnlos_core.app.plot.palette`; RA maps with positive azimuth on the left (:func:`bev.orient_azimuth`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from xnlos_core.app.plot import palette as pal
from xnlos_core.bev import bev, legend_outside, orient_azimuth, save_png, set_bev_limits
from xnlos_core.transient import SPEED_OF_LIGHT
from xnlos_core.types import LOS, MNLOS


def row_colours(rows: dict[str, str | None]) -> dict[str, str]:
    """One colour per study row (row → its radar detector's registry name, None for a SPAD row),
    every two at least :data:`palette.MIN_DELTA_E` apart in CIELAB: the detector's palette colour
    (:func:`palette.detector_colour`) for the first row that uses the detector, the palette's
    stable pick for the row label otherwise, moved to the next free palette colour when too
    close to one taken (:func:`palette.distinct_colours`)."""
    return pal.distinct_colours({row: pal.detector_colour(detector or row) for row, detector in rows.items()})


def log_distance_ticks(ax, distances, min_gap: float = 0.07) -> list[float]:
    """Label a log x-axis at the study's ``distances`` [m] only, as plain numbers, dropping a
    distance whose label would sit closer than ``min_gap`` (fraction of the axis' log span) to
    the previous one, so that no two tick labels overlap; minor ticks keep no labels. Returns
    the labelled distances."""
    from matplotlib.ticker import FixedLocator, NullFormatter, NullLocator

    d = np.unique(np.asarray([x for x in distances if x and x > 0], float))
    lo, hi = np.log10(ax.get_xlim())
    kept: list[float] = []
    for x in d:
        if not kept or (np.log10(x) - np.log10(kept[-1])) >= min_gap * max(hi - lo, 1e-9):
            kept.append(float(x))
    ax.xaxis.set_major_locator(FixedLocator(kept))
    ax.xaxis.set_major_formatter(lambda x, _: f"{x:g}")
    ax.xaxis.set_minor_locator(NullLocator())
    ax.xaxis.set_minor_formatter(NullFormatter())
    return kept


def draw_range_curve(ax, res: dict, colours: dict[str, str] | None = None) -> dict[str, list]:
    """F1 vs distance [m] (log axis, labelled at the study's distances only:
    :func:`log_distance_ticks`) on ``ax``: reconstruction solid, detection dashed, one colour per
    row (``colours``: row → colour, :func:`row_colours`; default: by row label), legend outside
    right. Returns row → its two Line2D."""
    colours = colours or row_colours({r: None for r in res["rows"]})
    lines: dict[str, list] = {}
    for row, t in res["rows"].items():
        c = colours[row]
        ds = t["distances"]
        nan = lambda v: [np.nan if x is None else x for x in v]  # noqa: E731
        lines[row] = ax.plot(ds, nan(t["reconstruction_f1"]), "-o", color=c, ms=4, label=f"{row} reconstruction")
        lines[row] += ax.plot(ds, nan(t["detection_f1"]), "--", color=c, alpha=0.7, label=f"{row} detection")
    ax.axhline(res["threshold"], color="0.5", lw=0.8, ls=":")
    ax.set_xscale("log")
    log_distance_ticks(ax, [d for t in res["rows"].values() for d in t["distances"]])
    ax.set_xlabel("distance behind the corner [m]")
    ax.set_ylabel("F1 over seeds")
    ax.set_ylim(-0.03, 1.03)
    ax.set_title(f"{res['name']}: NLOS range at equal transmit power")
    legend_outside(ax, where="right")
    return lines


def draw_failure_points(ax, res: dict, colours: dict[str, str] | None = None) -> dict[str, list]:
    """Each row's range to failure on ``ax`` (log distance axis, one line per row): the seeds'
    ranges (dots), the median (diamond) and its bootstrap interval (bar, drawn to the sweep's bound
    where it ends on a censored seed); seeds that reached a bound of the bisection get an arrow at
    that bound (▶ at the upper bound: still in range there; ◀ at the lower bound: failed already
    there), and a median on such a seed is that arrow, not a diamond. Returns row → its artists."""
    colours = colours or row_colours({r: None for r in res["rows"]})
    b = res.get("bisection") or {}
    names = [r for r, t in res["rows"].items() if t.get("range_to_failure")]
    out: dict[str, list] = {}
    for i, row in enumerate(names):
        x, c, y = res["rows"][row]["range_to_failure"], colours[row], len(names) - 1 - i
        runs = res["rows"][row]["bisections"]
        got = [r["range"] for r in runs if r["status"] == "bracketed"]
        arts = [ax.plot(got, [y] * len(got), "o", color=c, ms=3, alpha=0.6)[0]] if got else []
        if x["status"] == "measured":
            iv = x["interval"]
            lo = iv["low"] if iv["low"] > 0 else b.get("lower", iv["value"])
            hi = iv["high"] if np.isfinite(iv["high"]) else b.get("upper", iv["value"])
            arts.append(ax.errorbar([iv["value"]], [y], xerr=[[iv["value"] - lo], [hi - iv["value"]]],
                                    fmt="D", color=c, ms=7, capsize=4, lw=2))
        if x["n_above"]:
            arts.append(ax.plot([b.get("upper")], [y], ">", color=c, ms=9)[0])
        if x["n_below"]:
            arts.append(ax.plot([b.get("lower")], [y], "<", color=c, ms=9)[0])
        out[row] = arts
    ax.set_yticks(range(len(names)), list(reversed(names)), fontsize=8)
    ax.set_ylim(-0.7, len(names) - 0.3)
    for v, what in ((b.get("lower"), "lower"), (b.get("upper"), "upper")):
        if v:
            ax.axvline(v, color="0.6", lw=0.8, ls=":")
            ax.annotate(f"{what} bound {v:g} m", (v, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 2),
                        textcoords="offset points", ha="center", va="bottom", fontsize=7, color="0.4")
    level = (res.get("bootstrap") or {}).get("level", 0.95)
    ax.set_title(f"range to failure (bisection per seed): seeds •, median ◆ with its {100 * level:g} % bootstrap "
                 "interval; ▶ / ◀ bound of the sweep reached", fontsize=8, pad=12)
    return out


def range_curve(res: dict, path: str | Path, colours: dict[str, str] | None = None) -> Path:
    """Write the study result ``res`` to ``path`` (PNG): :func:`draw_range_curve` above and, when the
    result holds ranges to failure, :func:`draw_failure_points` below on the same distance axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    failures = any(t.get("range_to_failure") for t in res["rows"].values())
    if not failures:
        fig, ax = plt.subplots(figsize=(8, 4))
        draw_range_curve(ax, res, colours)
        return save_png(fig, path)
    n = sum(1 for t in res["rows"].values() if t.get("range_to_failure"))
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(9, 4.5 + 0.35 * n), sharex=True,
                                 gridspec_kw={"height_ratios": [3, 0.6 + 0.3 * n]})
    draw_range_curve(ax, res, colours)
    draw_failure_points(bx, res, colours)
    b = res.get("bisection") or {}
    ds = [d for t in res["rows"].values() for d in t["distances"]] + [b.get("lower"), b.get("upper")]
    ds = [d for d in ds if d]
    ax.set_xlim(min(ds) / 1.3, max(ds) * 1.3)
    log_distance_ticks(bx, ds)
    ax.set_xlabel("")
    bx.set_xlabel("distance behind the corner [m]")
    return save_png(fig, path)


def _scene_points(scene) -> np.ndarray:
    return np.vstack([o.footprint(0.0) for o in scene.objects] + [[w.start, w.end] for w in scene.walls if w.relay]
                     + [[[0.0, 0.0]]])


def _draw_scene(ax, scene, hidden: str) -> None:
    """Walls (relay darker), objects (the hidden one in the truth colour, above), radar at the origin."""
    for w in scene.walls:
        ax.plot(*bev([w.start, w.end]), color="k" if w.relay else pal.TRUE_WALL, lw=2 if w.relay else 1.5,
                zorder=pal.Z_BAND)
    for o in scene.objects:
        fp = o.footprint(0.0)
        fp = np.vstack([fp, fp[:1]])
        if o.name == hidden:
            ax.fill(*bev(fp), color=pal.TRUTH, alpha=0.8, zorder=pal.Z_TRUTH, label="hidden object (truth)")
        else:
            ax.fill(*bev(fp), color="0.7", alpha=0.8, zorder=pal.Z_BAND)
    ax.plot(0, 0, "^", color="r", ms=6, zorder=pal.Z_RADAR)


def _scene_ax(ax, scene, hidden: str, title: str) -> None:
    _draw_scene(ax, scene, hidden)
    set_bev_limits(ax, _scene_points(scene))
    ax.set_title(title, fontsize=8)


def _radar_row(axes, row: str, shown: dict, cfg) -> None:
    res, pipe = shown["result"], shown["pipeline"]
    ra = res.frame.ra_map
    db = 20 * np.log10(np.abs(ra.data) + 1e-12)
    az = np.degrees(ra.azimuth_axis)
    ext = [az[0], az[-1], ra.range_axis[0], ra.range_axis[-1]]
    _scene_ax(axes[0], pipe.scene, cfg.hidden_object, f"{row}: scene")
    axes[1].imshow(db, origin="lower", aspect="auto", extent=ext, cmap="viridis", vmin=db.max() - 60)
    axes[1].set_title("raw: |RA map| [dB]", fontsize=8)
    axes[2].imshow(db, origin="lower", aspect="auto", extent=ext, cmap="gray", vmin=db.max() - 60)
    det = res.detections
    for lab in (LOS, MNLOS):
        name, c, mk = pal.CLASS_STYLE[lab]
        m = det.label == lab
        axes[2].plot(np.degrees(det.azimuth[m]), det.range[m], mk, mfc="none", color=c, ms=4, label=name,
                     zorder=pal.Z_ESTIMATE)
    legend_outside(axes[2], where="right")
    detector = pipe.config.detector.name
    axes[2].set_title(f"detections ({detector})", fontsize=8, color=pal.detector_colour(detector))
    for ax in axes[1:3]:
        orient_azimuth(ax, az)  # positive azimuth (left) on the left, as in the bird's-eye view
        ax.xaxis.label.set_fontsize(7)
        ax.set_ylabel("range [m]", fontsize=7)
    # reconstruction: the scene panel's axes and orientation, truth above the estimates
    ax = axes[3]
    _draw_scene(ax, pipe.scene, cfg.hidden_object)
    ax.plot(*bev(shown["image"]), ".", color=pal.UNOBSERVABLE, ms=1, label="virtual image (Eq. 7)",
            zorder=pal.Z_ESTIMATE - 1)
    h = res.hidden.mean.reshape(-1, 2)
    ax.plot(*bev(h), "x", color=shown.get("colour", pal.detector_colour(detector)), ms=6, mew=1.5, label=f"reconstructed ({detector})",
            zorder=pal.Z_ESTIMATE)
    set_bev_limits(ax, _scene_points(pipe.scene))
    lim = _scene_points(pipe.scene)
    lo, hi = lim.min(0) - 5, lim.max(0) + 5
    out = int(np.sum(np.any((h < lo) | (h > hi), axis=1)))
    legend_outside(ax, where="right")
    ax.set_title("reconstruction (top view)" + (f"; {out} point(s) outside the view" if out else ""), fontsize=8)


def _spad_row(axes, row: str, shown: dict, cfg) -> None:
    vol, nv, truth, pk = shown["volume"], shown["nlos"], shown["truth"], shown["peak"]
    lo_z, hi_z = shown["search"]
    x, _ = vol.grid()
    rho = SPEED_OF_LIGHT * vol.times() / 2
    _scene_ax(axes[0], shown["scene"], cfg.hidden_object, f"{row}: scene (scan on the black relay wall)")
    top = min(rho[-1], max(float(np.linalg.norm(truth, axis=1).max()) if len(truth) else 0.0, hi_z) + 3.0)
    raw = vol.data.sum(axis=1)[rho <= top]  # (T', W)
    axes[1].imshow(raw, origin="lower", aspect="auto", extent=[x[0], x[-1], rho[0], top], cmap="magma")
    axes[1].set_title("raw: counts (Σ rows)", fontsize=8)
    axes[1].set_xlabel("scan x along the wall [m]", fontsize=7)
    axes[1].set_ylabel("c·t/2 [m]", fontsize=7)
    inten = nv.albedo.max(axis=1)[nv.z <= top]  # (Z', W)
    axes[2].imshow(inten, origin="lower", aspect="auto", extent=[x[0], x[-1], nv.z[0], top], cmap="magma")
    for zz in (lo_z, hi_z):
        axes[2].axhline(zz, color="w", lw=0.8, ls="--")
    axes[2].set_title(f"intensity: {shown['solver']} albedo (max over rows); -- peak search", fontsize=8)
    axes[2].set_xlabel("x along the wall [m]", fontsize=7)
    axes[2].set_ylabel("depth z [m]", fontsize=7)
    # reconstruction: truth (visible surface) and the peak in the same wall frame, top view
    ax = axes[3]
    dx = (x[1] - x[0]) / 2 if len(x) > 1 else 0.05
    ax.axhspan(lo_z, hi_z, color="0.93", zorder=0, label="peak search region")
    ax.plot([x[0] - dx, x[-1] + dx], [0, 0], "-", color="k", lw=4, solid_capstyle="butt", zorder=pal.Z_BAND,
            label="scan aperture (relay wall)")
    if len(truth):
        ax.plot(truth[:, 0], truth[:, 2], ".", color=pal.TRUTH, ms=2, zorder=pal.Z_TRUTH, label="visible surface (truth)")
    c = shown.get("colour", pal.ESTIMATE)
    if shown["detected"]:
        verdict = "hit" if shown["hit"] else ("edge of the search region: no hit" if not pk.interior else "miss")
        ax.plot([pk.x], [pk.z], "x", color=c, ms=9, mew=2, zorder=pal.Z_ESTIMATE, label=f"albedo peak ({verdict})")
    else:
        ax.text(0.5, 0.5, "no detection: nothing reported", transform=ax.transAxes, ha="center", fontsize=7)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x along the wall [m]", fontsize=7)
    ax.set_ylabel("depth z from the wall [m]", fontsize=7)
    legend_outside(ax, where="right")
    ax.set_title("reconstruction (wall frame, top view)", fontsize=8)


def panel_figure(cfg, panel: dict[str, dict], path: str | Path) -> Path:
    """Fig. 5-style panel: one row per modality of ``panel`` (row label → what its cell kept)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panel), 4, figsize=(18, 3.6 * len(panel)), squeeze=False,
                             gridspec_kw={"width_ratios": [1, 1.2, 1.2, 1.3]})
    for axrow, (row, shown) in zip(axes, panel.items()):
        (_radar_row if "result" in shown else _spad_row)(axrow, row, shown, cfg)
    fig.suptitle(f"{cfg.name}: hidden object {cfg.panel_distance:g} m behind the corner", fontsize=10)
    return save_png(fig, path, dpi=90)
