"""The cross-modality study, one command (paper Sec. 5.1.2 and Fig. 5):
``xnlos crossmodal configs/ablations/crossmodal.toml --out DIR``.

It moves ONE hidden object down the hidden street of ONE corner scene (same relay wall, same
object, same occluders for every modality) and, per distance and seed, scores whether each
modality detects and reconstructs it (:mod:`xnlos_core.app.crossmodal.score` defines both). All
modalities transmit the same total average power (1.6 mW in the shipped config: the radar's
``transmit_power`` is per transmitter in TDM-MIMO, one TX at a time, so the radiated average is
1.6 mW; the SPAD's ``power`` is the laser's average power).

Distance behind the corner, d [m]: the distance from the occluder's front line (the line through
``corner`` perpendicular to ``direction``) to the NEAREST point of the hidden object's footprint,
measured along the hidden street (``direction``). The object keeps its heading; its centre is
``corner + (d + h)·direction`` with h the footprint's half extent along ``direction``.

Modalities (``[[modality]]``, each ``type = "radar"`` or ``"spad"``):

* radar: a pipeline (``radar``, ``forward_model``, ``detector``, ``wall_estimator``,
  ``reconstructor`` tables as in a pipeline file) built by :class:`~xnlos_core.pipeline.Pipeline`;
  trial k of a distance is frame k (its own child seed) of a static scene.
* spad: a registered ``transient_model`` (e.g. "spad", sims) scans the relay wall; every
  ``solvers`` entry (registered ``nlos_solver``: "lct", "fk") reconstructs the same scans and is
  its own row ("<label>/<solver>").

Outputs in ``--out``: ``cells/*.json`` (one per modality and distance, written atomically: a
killed run resumes there; a config change recomputes), ``crossmodal.json`` and ``crossmodal.md``
(F1 per distance, maximum NLOS range = largest distance with F1 ≥ 0.5, the X-band / SPAD ratio),
``range_curve.png`` (F1 vs distance) and ``panel.png`` (Fig. 5-style: per modality the scene, the
raw measurement, the intensity and the reconstruction at ``panel_distance``). Progress on stderr.
"""
from __future__ import annotations

import copy
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.app.crossmodal import score as cs
from xnlos_core.app.crossmodal.config import RadarModality, SpadModality, StudyConfig, load_study
from xnlos_core.errors import ConfigError
from xnlos_core.io import atomic_write_text, strict_json_text


# ---------------------------------------------------------------------------------------------- scene


def scene_table(cfg: StudyConfig, distance: float) -> dict[str, Any]:
    """The study's scene table with the hidden object placed ``distance`` [m] behind the corner."""
    from xnlos_core.scene import ObjectSpec

    table = copy.deepcopy(cfg.scene)
    objs = table.get("objects") or []
    hit = [o for o in objs if o.get("name") == cfg.hidden_object]
    if len(hit) != 1:
        raise ConfigError(f"[scene] expected exactly one object named {cfg.hidden_object!r} (hidden_object), "
                          f"found {len(hit)}")
    walls = [w.get("name") for w in table.get("walls") or []]
    if cfg.relay_wall not in walls:
        raise ConfigError(f"relay_wall: no wall named {cfg.relay_wall!r} in [scene]; walls: {walls}")
    obj = hit[0]
    u = np.asarray(cfg.direction, float)
    u /= np.linalg.norm(u)
    probe = ObjectSpec.model_validate({**obj, "center": (0.0, 0.0), "velocity": (0.0, 0.0)})
    half = float(np.max(-(probe.footprint(0.0) @ u)))  # extent of the footprint behind its centre
    c = np.asarray(cfg.corner, float) + (distance + half) * u
    obj["center"] = [float(c[0]), float(c[1])]
    return table


def _scene(cfg: StudyConfig, distance: float, base_dir: Path):
    from xnlos_core.scene import load_scene

    return load_scene(scene_table(cfg, distance), f"crossmodal scene at {distance:g} m", base_dir)


def _trial_seed(cfg: StudyConfig, m: int, d: int) -> int:
    return int(np.random.SeedSequence([cfg.seed, m, d]).generate_state(1, np.uint64)[0] >> 1)


# ------------------------------------------------------------------------------------------ modalities


def rows(cfg: StudyConfig) -> list[str]:
    """Row labels: a radar's label, a SPAD's '<label>/<solver>' per solver."""
    out = []
    for m in cfg.modality:
        out += [m.label] if isinstance(m, RadarModality) else [f"{m.label}/{s}" for s in m.solvers]
    return out


def _radar_pipeline(cfg: StudyConfig, mod: RadarModality, table: dict, seed: int, base_dir: Path):
    from xnlos_core.config import parse_pipeline
    from xnlos_core.pipeline import Pipeline

    t = {"name": f"{cfg.name}-{mod.label}", "seed": seed, "radar": mod.radar, "scene": table,
         "forward_model": mod.forward_model.model_dump(), "detector": mod.detector.model_dump(),
         "wall_estimator": mod.wall_estimator.model_dump(), "reconstructor": mod.reconstructor.model_dump(),
         "run": {"frames": cfg.seeds}}
    return Pipeline(parse_pipeline(t, f"{cfg.name} [[modality]] {mod.label}", base_dir),
                    source=f"{cfg.name} [[modality]] {mod.label}")


def _radar_cell(cfg: StudyConfig, mod: RadarModality, d: float, seed: int, base_dir: Path, keep: bool):
    from xnlos_core.types import MNLOS

    pipe = _radar_pipeline(cfg, mod, scene_table(cfg, d), seed, base_dir)
    obj = next(o for o in pipe.scene.objects if o.name == cfg.hidden_object)
    wall = next(w for w in pipe.scene.walls if w.name == cfg.relay_wall)
    fp = obj.footprint(0.0)
    image = cs.mirror_points(cs.outline_points(fp), wall.start, wall.end)
    trials, shown = [], None
    for res in pipe.run():
        det = res.detections
        m = det.label == MNLOS
        xy = np.c_[det.range[m] * np.cos(det.azimuth[m]), det.range[m] * np.sin(det.azimuth[m])]
        hidden = res.hidden.mean.reshape(-1, 2)
        trials.append({"detection": cs.radar_detection(xy, image, cfg.gate).as_dict(),
                       "reconstruction": cs.radar_reconstruction(hidden, fp, cfg.tolerance).as_dict(),
                       "walls": len(res.walls)})
        if keep and shown is None:
            shown = {"result": res, "pipeline": pipe, "footprint": fp, "image": image}
    return {mod.label: trials}, shown


def _spad_cell(cfg: StudyConfig, mod: SpadModality, d: float, seed: int, base_dir: Path, keep: bool):
    from xnlos_core.registry import get_registry
    from xnlos_core.transient import TransientVolume

    reg = get_registry()
    src = f"{cfg.name} [[modality]] {mod.label}"
    model = reg.create("transient_model", mod.transient_model.name, mod.transient_model.params, source=src)
    solvers = {s: reg.create("nlos_solver", s, {}, source=src) for s in mod.solvers}
    scene = _scene(cfg, d, base_dir)
    truth = model.truth(scene)
    seeds = np.random.SeedSequence(seed).generate_state(cfg.seeds, np.uint64) >> np.uint64(1)
    out = {f"{mod.label}/{s}": [] for s in mod.solvers}
    shown = None
    for k in range(cfg.seeds):
        vol = model.simulate(scene, int(seeds[k]))
        sx, sy = vol.grid()
        peak = cs.transient_peak(vol.data, vol.bin_width, vol.t0, mod.window, mod.n_sigma)
        det = cs.spad_detection(peak, cs.range_interval(truth, sx, sy), cfg.gate)
        rvol = vol
        if mod.background_subtract:
            clean = np.maximum(vol.data - np.median(vol.data, axis=0, keepdims=True), 0.0)
            if np.any(clean > 0):
                rvol = TransientVolume(clean, vol.bin_width, vol.wall_width, vol.wall_height, vol.t0)
        for s, solver in solvers.items():
            nv = solver.reconstruct(rvol)
            top = max(peak.range + cfg.gate, mod.first_bounce_gate)
            vp = cs.volume_peak(nv.albedo, nv.z, nv.grid(), top, mod.first_bounce_gate)
            rec = cs.spad_reconstruction(vp, truth, cfg.tolerance, peak.detected)
            out[f"{mod.label}/{s}"].append({"detection": det.as_dict(), "reconstruction": rec.as_dict(),
                                            "peak_range": peak.range, "excess": peak.excess,
                                            "threshold": peak.threshold, "peak_xyz": list(vp.xyz),
                                            "peak_interior": vp.interior})
            if keep and shown is None:
                shown = {"volume": vol, "nlos": nv, "truth": truth, "scene": scene, "solver": s,
                         "peak": vp, "search": (mod.first_bounce_gate, top), "hit": rec.tp,
                         "detected": peak.detected, "range": peak.range}
    return out, shown


def check_study(path: str | Path) -> str:
    """``xnlos check`` of a study: the config, the scene at every distance, every modality's
    components (radar pipelines at the first distance); returns the one-line verdict."""
    from xnlos_core.registry import get_registry

    cfg, base_dir = load_study(path)
    for d in cfg.distances:
        _scene(cfg, d, base_dir)
    reg = get_registry()
    for mod in cfg.modality:
        if isinstance(mod, RadarModality):
            _radar_pipeline(cfg, mod, scene_table(cfg, cfg.distances[0]), 0, base_dir)
        else:
            src = f"{path} [[modality]] {mod.label}"
            model = reg.create("transient_model", mod.transient_model.name, mod.transient_model.params, source=src)
            model.truth(_scene(cfg, cfg.distances[0], base_dir))
            for s in mod.solvers:
                reg.create("nlos_solver", s, {}, source=src)
    return f"{path}: valid (cross-modality study: {len(rows(cfg))} row(s) × {len(cfg.distances)} distance(s))"


# ---------------------------------------------------------------------------------------------- study


def _log(msg: str, progress: bool) -> None:
    if progress:
        print(f"[crossmodal] {msg}", file=sys.stderr, flush=True)


def run_study(config: str | Path, out: str | Path, *, progress: bool = True, figures: bool = True) -> dict:
    """Run (or resume) the study of ``config`` into ``out``; returns the summary dict written to
    ``crossmodal.json``."""
    cfg, base_dir = load_study(config)
    out = Path(out)
    digest = cfg.digest()
    cells_dir = out / "cells"
    results: dict[str, dict[float, list]] = {r: {} for r in rows(cfg)}
    n_cells = len(cfg.modality) * len(cfg.distances)
    done = 0
    t_start = time.perf_counter()
    for mi, mod in enumerate(cfg.modality):
        for di, d in enumerate(cfg.distances):
            path = cells_dir / f"{mi:02d}_{mod.label}_{di:02d}.json"
            cell = None
            if path.is_file():
                saved = json.loads(path.read_text())
                if saved.get("digest") == digest:
                    cell = saved["rows"]
            if cell is None:
                t0 = time.perf_counter()
                seed = _trial_seed(cfg, mi, di)
                run = _radar_cell if isinstance(mod, RadarModality) else _spad_cell
                cell, _ = run(cfg, mod, d, seed, base_dir, keep=False)
                atomic_write_text(path, json.dumps({"digest": digest, "distance": d, "rows": cell}, default=float))
                took = f"{time.perf_counter() - t0:.1f} s"
            else:
                took = "resumed"
            done += 1
            for r, trials in cell.items():
                results[r][d] = trials
            summary = ", ".join(f"{r}: det {_fmt(cs.f1_rate(t['detection'] for t in trials))} rec "
                                f"{_fmt(cs.f1_rate(t['reconstruction'] for t in trials))}" for r, trials in cell.items())
            _log(f"({done}/{n_cells}) {mod.label} d = {d:g} m [{took}]: {summary}", progress)
    res = summarise(cfg, results)
    res["wall_s"] = time.perf_counter() - t_start
    atomic_write_text(out / "crossmodal.json", strict_json_text(res, indent=2))
    atomic_write_text(out / "crossmodal.md", render_markdown(cfg, res, str(config)))
    if figures:
        from xnlos_core.app.crossmodal.figures import panel_figure, range_curve, row_colours

        detectors = {}
        for mod in cfg.modality:
            for r in rows(cfg.model_copy(update={"modality": [mod]})):
                detectors[r] = mod.detector.name if isinstance(mod, RadarModality) else None
        colours = row_colours(detectors)
        range_curve(res, out / "range_curve.png", colours)
        _log(f"panel at {cfg.panel_distance:g} m", progress)
        panel = {}
        for mi, mod in enumerate(cfg.modality):
            run = _radar_cell if isinstance(mod, RadarModality) else _spad_cell
            _, shown = run(cfg, mod, cfg.panel_distance, _trial_seed(cfg, mi, 10_000), base_dir, keep=True)
            label = mod.label if isinstance(mod, RadarModality) else f"{mod.label}/{shown['solver']}"
            panel[label] = {**shown, "colour": colours[label]}
        panel_figure(cfg, panel, out / "panel.png")
        res["figures"] = ["range_curve.png", "panel.png"]
        atomic_write_text(out / "crossmodal.json", strict_json_text(res, indent=2))
    return res


def _fmt(v) -> str:
    return "—" if v is None else f"{v:.2f}"


def summarise(cfg: StudyConfig, results: dict[str, dict[float, list]]) -> dict:
    """F1 per row and distance, maximum NLOS range per row and stage, X-band / SPAD ratio."""
    table = {}
    for r, by_d in results.items():
        ds = sorted(by_d)
        det = [cs.f1_rate(t["detection"] for t in by_d[d]) for d in ds]
        rec = [cs.f1_rate(t["reconstruction"] for t in by_d[d]) for d in ds]
        table[r] = {"distances": ds, "detection_f1": det, "reconstruction_f1": rec,
                    "max_range_detection": cs.max_range(ds, det, cfg.threshold),
                    "max_range_reconstruction": cs.max_range(ds, rec, cfg.threshold)}
    # A ratio only from two measured ranges: a range at the sweep's farthest distance (still in range) or
    # below its nearest (never in range) is a bound of the sweep, not a measurement, and a ratio of
    # bounds is no number (range_ratio_note says which bound was reached instead).
    ratio, note = None, None
    ref, base = cfg.reference, cfg.baseline
    if ref in table and base in table:
        lo, top = min(cfg.distances), max(cfg.distances)
        bounds = []
        for label in (ref, base):
            r = table[label]["max_range_reconstruction"]
            if r is None:
                bounds.append(f"{label} never reaches F1 ≥ {cfg.threshold:g} (its range is below {lo:g} m)")
            elif r == top:
                bounds.append(f"{label} still reconstructs at the farthest distance (its range is above {top:g} m)")
        if bounds:
            note = "no range ratio: the sweep's bound was reached: " + "; ".join(bounds)
        else:
            ratio = {"value": table[ref]["max_range_reconstruction"] / table[base]["max_range_reconstruction"],
                     "bound": "="}
    return {"name": cfg.name, "digest": cfg.digest(), "seeds": cfg.seeds, "gate_m": cfg.gate,
            "tolerance_m": cfg.tolerance, "threshold": cfg.threshold, "rows": table,
            "reference": ref, "baseline": base, "range_ratio": ratio, "range_ratio_note": note}


def render_markdown(cfg: StudyConfig, res: dict, source: str) -> str:
    """The study's table: F1 (detection / reconstruction) per row and distance, ranges, ratio."""
    ds = sorted(cfg.distances)
    lines = [f"# Cross-modality study `{cfg.name}`", "",
             f"Config `{source}`, {cfg.seeds} seed(s) per cell, gate {cfg.gate:g} m, tolerance {cfg.tolerance:g} m; "
             "cells: detection F1 / reconstruction F1.", "",
             "| row | " + " | ".join(f"{d:g} m" for d in ds) + " | max range det. | max range rec. |",
             "|---|" + "---|" * (len(ds) + 2)]
    below = f"< {min(ds):g} m"
    for r, t in res["rows"].items():
        cells = [f"{_fmt(a)} / {_fmt(b)}" for a, b in zip(t["detection_f1"], t["reconstruction_f1"])]
        rd, rr = t["max_range_detection"], t["max_range_reconstruction"]
        lines.append(f"| {r} | " + " | ".join(cells) + f" | {below if rd is None else f'{rd:g} m'} | "
                     f"{below if rr is None else f'{rr:g} m'} |")
    ratio = res["range_ratio"]
    lines += ["", f"Maximum NLOS range: largest distance with F1 ≥ {cfg.threshold:g}."]
    top = max(ds)
    for r, t in res["rows"].items():
        if t["max_range_reconstruction"] == top:
            lines.append(f"{r} still reconstructs at the farthest distance ({top:g} m): its range is a lower bound.")
    if ratio is not None:
        lines.append(f"Reconstruction range ratio {res['reference']} / {res['baseline']}: {ratio['value']:.1f}")
    elif res.get("range_ratio_note"):
        lines.append(res["range_ratio_note"][0].upper() + res["range_ratio_note"][1:] + ".")
    return "\n".join(lines) + "\n"


def add_command(sub) -> None:
    """``xnlos crossmodal CONFIG --out DIR`` (called by :func:`xnlos_core.app.cli.build_parser`)."""
    c = sub.add_parser("crossmodal", help="cross-modality study (SPAD vs 77 GHz vs X-band): F1 vs distance behind "
                       "the corner, maximum NLOS range, Fig. 5-style panel (resumable)")
    c.add_argument("config", type=Path, help="study TOML, e.g. configs/ablations/crossmodal.toml")
    c.add_argument("--out", type=Path, help="output directory (default out/crossmodal/<config stem>; rerun to resume)")
    c.add_argument("--no-figures", action="store_true", help="write no PNGs")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr, no table on stdout")
    c.set_defaults(func=_cmd)


def _cmd(args) -> int:
    out = args.out or Path("out/crossmodal") / args.config.stem
    run_study(args.config, out, progress=not args.quiet, figures=not args.no_figures)
    if not args.quiet:
        print((out / "crossmodal.md").read_text())
    return 0
