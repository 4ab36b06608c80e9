"""Where dense detectors go wrong: every miss and false alarm sorted by cause (not a test).

    .venv/bin/python benchmarks/detector_errors.py [--dataset out/data/default] [--split test]
        [--max-maps 60] [--detectors swin_unet,unet] [--out benchmarks/detector_errors.md]
        [--figure benchmarks/detector_errors.png]

Per class (LOS, mNLOS), each ground-truth point (thinned to resolution cells, as scored) that no
detection of its class matches within the radius is a **miss**, and each unmatched detection a
**false alarm**. Causes, tested in this order:

* miss: *wrong class* (a detection of the other class within the radius), *displaced* (a
  detection of its class within 2.5 radii, already matched elsewhere or too far), *missed*.
* false alarm: *wrong class* (ground truth of the other class within the radius), *displaced or
  duplicate* (ground truth of its class within 2.5 radii), *multipath* (within 1.5 m of an echo
  the ground truth leaves out by design: two or more mirrors, or out along one chain and back along
  another, with path SNR > 5 dB; found by re-tracing the frame's scene, ``raytrace`` datasets
  only), *other* (noise, sidelobes, echoes below the ground truth's SNR threshold).

Two ceilings are printed as well, per class: the *grid ceiling*, the F1 between the ground truth and
itself thinned on a grid shifted by half a resolution cell (thinning picks one point per cell, so
where a cell boundary falls is arbitrary; no detector that cannot know the grid beats it), and the
*decoding ceiling*, the F1 of the first dense detector's own training target (the Gaussian
heatmap of the map's ground truth, as logits) decoded as that detector decodes its network's
output: what a network that reproduced its target exactly would score, so the gap below it is the
network's, not the peak extraction's.

**Shared misses**, per pair of detectors and class: of the ground-truth points either misses, how
many both miss. Misses both share point at the data (echoes the map does not separate); misses of
one only point at that network, and the recall of the pair (a point matched by either) bounds what
a better network of the same kind could reach. Recall alone ignores false alarms, so **averaged
pairs** score the pair as one detector as well: the mean of the two networks' logits, decoded on
the first's settings (thresholds, cell suppression; pairs whose heads are alike: dense, with the same
training target, so that their logits mean the same), against each alone. A pair
that scores little above its better member leaves little to errors of one network.
"""
from __future__ import annotations

import sys
import argparse
from pathlib import Path

import numpy as np

CAUSES_MISS = ("wrong class", "displaced", "missed")
CAUSES_FA = ("wrong class", "displaced or duplicate", "multipath", "other")



def made_by() -> str:
    """The line that says which command wrote the page (this script with its arguments)."""
    return "Made by `python " + " ".join([f"benchmarks/{Path(sys.argv[0]).name}", *sys.argv[1:]]) + "`."

def _near(points: np.ndarray, p: np.ndarray, radius: float) -> bool:
    return len(points) > 0 and float(np.min(np.linalg.norm(points - p, axis=1))) < radius


def multipath_echoes(frame, fm) -> np.ndarray:
    """(K, 2) apparent positions [m] of the frame's echoes that are not ground truth (re-traced)."""
    from sims.generators import generate_scene
    from sims.propagation import ra_snr_db

    meta = frame.meta or {}
    if meta.get("forward_model") != "raytrace" or "scene_seed" not in meta:
        return np.empty((0, 2))
    scene = generate_scene(meta["family"], int(meta["scene_seed"]))
    _, paths, _, _ = fm.trace(scene, frame.ra_map.radar, frame.timestamp)
    if not len(paths):
        return np.empty((0, 2))
    keep = (paths.kind == 2) & (ra_snr_db(frame.ra_map.radar, paths.power) > 5.0)
    return paths.pos[keep]


def errors(det, frames, fm, radius: float) -> dict:
    """Counts {class: {"tp", "gt", "pred", "miss": {cause: n}, "fa": {cause: n}, "hit": (gt,) bool}}
    over ``frames``; ``hit`` marks the matched ground-truth points, frame after frame."""
    from xnlos_core.metrics import match_points, thin_to_resolution
    from xnlos_core.types import LOS, MNLOS

    out = {c: {"tp": 0, "gt": 0, "pred": 0, "miss": dict.fromkeys(CAUSES_MISS, 0), "fa": dict.fromkeys(CAUSES_FA, 0),
               "hit": []} for c in ("los", "mnlos")}
    for f in frames:
        d = det.detect(f)
        g = thin_to_resolution(f.ground_truth, f.ra_map.radar)
        clutter = None
        for c, label, mine, other in (("los", LOS, g.los_points, g.mnlos_points),
                                      ("mnlos", MNLOS, g.mnlos_points, g.los_points)):
            pred, rest = d.position[d.label == label], d.position[d.label != label]
            pi, gi = match_points(pred, mine, radius)
            s = out[c]
            s["tp"] += len(pi)
            s["gt"] += len(mine)
            s["pred"] += len(pred)
            hit = np.zeros(len(mine), dtype=bool)
            hit[gi] = True
            s["hit"].append(hit)
            for i in np.setdiff1d(np.arange(len(mine)), gi):
                cause = ("wrong class" if _near(rest, mine[i], radius) else
                         "displaced" if _near(pred, mine[i], 2.5 * radius) else "missed")
                s["miss"][cause] += 1
            for i in np.setdiff1d(np.arange(len(pred)), pi):
                if _near(other, pred[i], radius):
                    cause = "wrong class"
                elif _near(mine, pred[i], 2.5 * radius):
                    cause = "displaced or duplicate"
                else:
                    if clutter is None:
                        clutter = multipath_echoes(f, fm)
                    cause = "multipath" if _near(clutter, pred[i], 1.5) else "other"
                s["fa"][cause] += 1
    for s in out.values():
        s["hit"] = np.concatenate(s["hit"]) if s["hit"] else np.zeros(0, dtype=bool)
    return out


def shared_misses(res: dict) -> list[str]:
    """Markdown table: per pair of detectors and class, misses of each, of both, and the pair's recall."""
    from itertools import combinations

    lines = ["| pair | class | misses of the first / second | missed by both | share of the first's misses "
             "| recall: first / second / either |", "|---|---|---|---|---|---|"]
    for a, b in combinations(res, 2):
        for c in ("los", "mnlos"):
            ha, hb = res[a][c]["hit"], res[b][c]["hit"]
            n = max(len(ha), 1)
            both = int(np.sum(~ha & ~hb))
            lines.append(f"| {a} / {b} | {c} | {int(np.sum(~ha))} / {int(np.sum(~hb))} | {both} | "
                         f"{both / max(int(np.sum(~ha)), 1):.2f} | {ha.sum() / n:.3f} / {hb.sum() / n:.3f} / "
                         f"{(ha | hb).sum() / n:.3f} |")
    return lines


def dense_detectors(dets: dict) -> dict:
    """The learned detectors of ``dets`` with a dense head (logits per cell, ``output`` / ``decode``)."""
    return {n: d for n, d in dets.items() if hasattr(d, "decode") and d.metadata["head"]["kind"] == "dense"}


def averaged_pairs(dets: dict, frames, radius: float) -> list[str]:
    """Markdown table: per pair of learned detectors with alike dense heads (the same checkpoint head
    record), mean Macro / LOS / mNLOS F1 over ``frames`` of each and of the mean of their logits
    decoded as the first decodes (module doc)."""
    from itertools import combinations

    from xnlos_core.metrics import dense_metrics, thin_to_resolution

    dense = dense_detectors(dets)
    gts = [thin_to_resolution(f.ground_truth, f.ra_map.radar) for f in frames]
    outs = {n: [d.output(f)[:, :f.ra_map.shape[0], :f.ra_map.shape[1]] for f in frames] for n, d in dense.items()}

    def f1(decoder, logits) -> tuple[float, float, float]:
        m = [dense_metrics(decoder.decode(z, f.ra_map), g, radius) for z, f, g in zip(logits, frames, gts)]
        return tuple(float(np.mean([x[k]["f1"] for x in m])) for k in ("macro", "los", "mnlos"))

    alone = {n: f1(dense[n], outs[n]) for n in dense}
    lines = ["| pair | Macro F1: first / second / averaged | LOS F1: averaged | mNLOS F1: averaged "
             "| averaged − better member |", "|---|---|---|---|---|"]
    for a, b in combinations(dense, 2):
        if dense[a].metadata["head"] != dense[b].metadata["head"]:
            continue
        avg = f1(dense[a], [0.5 * (x + y) for x, y in zip(outs[a], outs[b])])
        lines.append(f"| {a} + {b} | {alone[a][0]:.3f} / {alone[b][0]:.3f} / {avg[0]:.3f} | {avg[1]:.3f} | "
                     f"{avg[2]:.3f} | {avg[0] - max(alone[a][0], alone[b][0]):+.3f} |")
    return lines


def grid_ceiling(frames, shift: tuple[float, float] = (0.5, 0.5)) -> dict[str, float]:
    """Mean F1 (LOS, mNLOS) of the thinned ground truth against itself thinned on a grid shifted by
    ``shift`` resolution cells (range, azimuth): what a detector that cannot know the cell grid loses."""
    from xnlos_core.metrics import f1_score, thin_to_resolution

    f1 = {"los": [], "mnlos": []}
    for f in frames:
        g0 = thin_to_resolution(f.ground_truth, f.ra_map.radar)
        g1 = thin_to_resolution(f.ground_truth, f.ra_map.radar, shift)
        f1["los"].append(f1_score(g1.los_points, g0.los_points, 1.0)["f1"])
        f1["mnlos"].append(f1_score(g1.mnlos_points, g0.mnlos_points, 1.0)["f1"])
    return {k: float(np.mean(v)) for k, v in f1.items()}


def decoding_ceiling(det, frames, radius: float) -> dict[str, float]:
    """Mean F1 (LOS, mNLOS) of ``det``'s training target of each frame, as logits, through ``det.decode``."""
    from plugins.detectors.heatmaps import peak_cells
    from plugins.detectors.tasks import make_head
    from xnlos_core.metrics import dense_metrics, thin_to_resolution

    head = make_head(det.metadata["head"])
    f1 = {"los": [], "mnlos": []}
    for f in frames:
        y = np.clip(head.targets(peak_cells(f.ra_map, f.ground_truth), f.ra_map.shape).astype(np.float64),
                    1e-6, 1 - 1e-6)
        m = dense_metrics(det.decode(np.log(y) - np.log1p(-y), f.ra_map),
                          thin_to_resolution(f.ground_truth, f.ra_map.radar), radius)
        for k in f1:
            f1[k].append(m[k]["f1"])
    return {k: float(np.mean(v)) for k, v in f1.items()}


def figure(res: dict, path: str) -> None:
    from xnlos_core.app.plot.figures import save_png

    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 1.4 + 0.8 * len(res)), sharey=True)
    colours = plt.get_cmap("tab10").colors
    for ax, (kind, causes, title) in zip(axes, (("miss", CAUSES_MISS, "misses (share of ground truth)"),
                                                ("fa", CAUSES_FA, "false alarms (share of detections)"))):
        labels, y = [], 0
        for name, r in res.items():
            for c in ("los", "mnlos"):
                s, left = r[c], 0.0
                total = s["gt"] if kind == "miss" else s["pred"]
                for k, cause in enumerate(causes):
                    w = s[kind][cause] / max(total, 1)
                    ax.barh(y, w, left=left, color=colours[k], label=cause if y == 0 else None)
                    left += w
                labels.append(f"{name} {c}")
                y += 1
        ax.set_yticks(range(len(labels)), labels)
        ax.set_title(title)
        ax.set_xlabel("share")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1 - 0.4 / len(labels)), ncol=len(causes), fontsize=8,
                  frameon=False)
    fig.tight_layout()
    save_png(fig, path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="out/data/default")
    ap.add_argument("--split", default="test")
    ap.add_argument("--max-maps", type=int, default=60)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--radius", type=float, default=1.0)
    ap.add_argument("--detectors", default="swin_unet,unet")
    ap.add_argument("--out", default=None, help="also write the Markdown report here")
    ap.add_argument("--figure", default=None, help="PNG of the error shares")
    args = ap.parse_args()

    import torch

    from sims.dataset import open_dataset
    from xnlos_core.registry import get_registry

    torch.set_num_threads(args.threads)
    ds = open_dataset(args.dataset, args.split)
    frames = [f for _, f in zip(range(args.max_maps or len(ds)), ds)]
    reg = get_registry()
    fm = reg.create("forward_model", "raytrace", {})
    dets = {name: reg.create("detector", name, {}) for name in args.detectors.split(",")}
    res = {name: errors(det, frames, fm, args.radius) for name, det in dets.items()}
    ceiling = grid_ceiling(frames)

    lines = [f"# Detector errors by cause ({args.dataset}, {args.split}: first {len(frames)} maps, "
             f"match radius {args.radius} m)", "", made_by(), "", "Counts pooled over the maps (the module doc of "
             "`benchmarks/detector_errors.py` defines each cause).", "",
             "| detector | class | ground truth | detections | matched | misses: " + " / ".join(CAUSES_MISS) +
             " | false alarms: " + " / ".join(CAUSES_FA) + " |", "|---|---|---|---|---|---|---|"]
    for name, r in res.items():
        for c in ("los", "mnlos"):
            s = r[c]
            lines.append(f"| {name} | {c} | {s['gt']} | {s['pred']} | {s['tp']} | "
                         f"{' / '.join(str(s['miss'][k]) for k in CAUSES_MISS)} | "
                         f"{' / '.join(str(s['fa'][k]) for k in CAUSES_FA)} |")
    lines += ["", f"Grid ceiling: the ground truth thinned on a grid shifted by half a resolution cell scores "
              f"F1 {ceiling['los']:.3f} (LOS) and {ceiling['mnlos']:.3f} (mNLOS) against itself."]
    dense = list(dense_detectors(dets))
    if dense:
        dc = decoding_ceiling(dets[dense[0]], frames, args.radius)
        lines += ["", f"Decoding ceiling: {dense[0]}'s training target, decoded as {dense[0]} decodes, scores "
                  f"F1 {dc['los']:.3f} (LOS) and {dc['mnlos']:.3f} (mNLOS) (module doc)."]
    if len(res) > 1:
        lines += ["", "## Shared misses", "", "Ground-truth points missed by two detectors (module doc).", ""]
        lines += shared_misses(res)
        pairs = averaged_pairs(dets, frames, args.radius)
        if len(pairs) > 2:
            lines += ["", "## Averaged pairs", "", "Mean F1 over the maps of each detector and of the mean of the "
                      "pair's logits, decoded as the first decodes (module doc).", ""] + pairs
    if args.figure:
        figure(res, args.figure)
        lines += ["", f"![errors by cause]({Path(args.figure).name})"]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        from xnlos_core.io import atomic_write_text

        atomic_write_text(args.out, text)


if __name__ == "__main__":
    main()
