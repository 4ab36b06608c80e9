"""The cross-modality study, one command (paper Sec. 5.1.2 and Fig. 5):
``xnlos crossmodal configs/ablations/crossmodal.toml --out DIR``.

It moves ONE hidden object down the hidden street of ONE corner scene (same relay wall, same
object, same occluders for every modality) and scores whether each modality detects and
reconstructs it (:mod:`xnlos_core.app.crossmodal.score` defines both). All modalities transmit the
same total average power (1.6 mW in the shipped config: the radar's ``transmit_power`` is per
transmitter in TDM-MIMO, one TX at a time, so the radiated average is 1.6 mW; the SPAD's ``power``
is the laser's average power).

Distance behind the corner, d [m]: the distance from the occluder's front line (the line through
``corner`` perpendicular to ``direction``) to the NEAREST point of the hidden object's footprint,
measured along the hidden street (``direction``). The object keeps its heading; its centre is
``corner + (d + h)·direction`` with h the footprint's half extent along ``direction``.

Trials: seed k (k < ``seeds``) of modality m draws its noise from SeedSequence(seed, m, k) at EVERY
distance (common random numbers: a trial's success then changes with d through the physics, not
through a new noise draw). Two measurements per row:

* the F1 grid: per ``distances`` entry, detection and reconstruction F1 over the seeds' trials;
* the range to failure: per seed, :func:`~xnlos_core.app.crossmodal.bisect.bisect_range` of
  "the trial's reconstruction F1 ≥ ``threshold``" (the existing score; for one trial: a hit)
  between ``bisection.lower`` and ``bisection.upper``; the row's range is the (lower) median over
  seeds with a seeded percentile-bootstrap interval, and each ``ratios`` pair gets the ratio of the
  medians with its bootstrap interval. A seed that still succeeds at the upper bound (or fails at
  the lower) has reached a bound of the sweep and is censored there; when the median falls on such
  a seed the row's range is reported as that bound and no ratio is computed from it
  (``range_ratio_note`` says which bound was reached).

Modalities (``[[modality]]``, each ``type = "radar"`` or ``"spad"``):

* radar: a pipeline (``radar``, ``forward_model``, ``detector``, ``wall_estimator``,
  ``reconstructor`` tables as in a pipeline file) built by :class:`~xnlos_core.pipeline.Pipeline`,
  one frame per trial. Its range axis follows from the configuration, never a fixed crop
  (:func:`radar_range_table`): ``max_range`` is the whole unambiguous range N·c/2B, with
  ``n_samples`` N doubled (same bandwidth and chirp duration: a faster ADC, the same chirp energy
  and SNR) until that covers the hidden object's mirror image at ``bisection.upper`` plus ``gate``.
* spad: a registered ``transient_model`` (e.g. "spad", sims) scans the relay wall; every
  ``solvers`` entry (registered ``nlos_solver``: "lct", "fk") reconstructs the same scans and is
  its own row ("<label>/<solver>"). With ``placement = "facing"`` the scan patch is placed per
  distance where the wall faces the object among the positions the sensor sees
  (:func:`sims.spad.placement.facing_offset`).

Outputs in ``--out``: ``cells/*.json`` (every trial of a modality, keyed by seed and distance,
written atomically after each new trial: a killed run resumes there; a config change recomputes),
``crossmodal.json`` and ``crossmodal.md`` (ranges with intervals, ratios, the F1 grid),
``range_curve.png`` (F1 vs distance and each row's failure point with its interval) and
``panel.png`` (Fig. 5-style: per modality the scene, the raw measurement, the intensity and the
reconstruction at ``panel_distance``). Progress on stderr. Deterministic: the same config gives the
same tables on every run.
"""
from __future__ import annotations

import copy
import json
import math
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


def radar_range_table(cfg: StudyConfig, mod: RadarModality, base_dir: Path) -> dict[str, Any]:
    """The modality's ``[radar]`` table with its range axis derived from the configuration (module
    docstring): ``n_samples`` N (the preset's, doubled while N·c/2B is short of the hidden object's
    farthest mirror-image range at ``bisection.upper`` plus ``gate``) and ``max_range`` = N·c/2B,
    the whole unambiguous range (no crop)."""
    from xnlos_core.radar import load_radar

    src = f"{cfg.name} [[modality]] {mod.label}"
    radar = load_radar(mod.radar, src, base_dir)
    need = image_range(cfg, max(cfg.bisection.upper, max(cfg.distances), cfg.panel_distance), base_dir) + cfg.gate
    n = radar.n_samples
    while n * radar.range_resolution < need:
        n *= 2
    table = {**mod.radar, "n_samples": n}
    table.pop("max_range", None)
    table["max_range"] = load_radar({**table, "max_range": 2 * radar.range_resolution}, src,
                                    base_dir).max_unambiguous_range
    return table


def image_range(cfg: StudyConfig, distance: float, base_dir: Path) -> float:
    """Largest range [m] from the radar (origin) of the hidden object's outline mirrored across the
    relay wall (its virtual image, Eq. 7) at ``distance`` behind the corner."""
    scene = _scene(cfg, distance, base_dir)
    obj = next(o for o in scene.objects if o.name == cfg.hidden_object)
    wall = next(w for w in scene.walls if w.name == cfg.relay_wall)
    img = cs.mirror_points(obj.footprint(0.0), wall.start, wall.end)
    return float(np.linalg.norm(img, axis=1).max())


def _radar_pipeline(cfg: StudyConfig, mod: RadarModality, table: dict, seed: int, base_dir: Path,
                    radar: dict | None = None, frames: int = 1):
    from xnlos_core.config import parse_pipeline
    from xnlos_core.pipeline import Pipeline

    t = {"name": f"{cfg.name}-{mod.label}", "seed": seed, "radar": radar or mod.radar, "scene": table,
         "forward_model": mod.forward_model.model_dump(), "detector": mod.detector.model_dump(),
         "wall_estimator": mod.wall_estimator.model_dump(), "reconstructor": mod.reconstructor.model_dump(),
         "run": {"frames": frames}}
    return Pipeline(parse_pipeline(t, f"{cfg.name} [[modality]] {mod.label}", base_dir),
                    source=f"{cfg.name} [[modality]] {mod.label}")


def _radar_trial(cfg: StudyConfig, mod: RadarModality, d: float, seed: int, base_dir: Path, radar: dict,
                 keep: bool = False):
    """One radar trial (one frame of pipeline seed ``seed``) at distance ``d``: ({row: trial}, shown)."""
    from xnlos_core.types import MNLOS

    pipe = _radar_pipeline(cfg, mod, scene_table(cfg, d), seed, base_dir, radar)
    obj = next(o for o in pipe.scene.objects if o.name == cfg.hidden_object)
    wall = next(w for w in pipe.scene.walls if w.name == cfg.relay_wall)
    fp = obj.footprint(0.0)
    image = cs.mirror_points(cs.outline_points(fp), wall.start, wall.end)
    res = next(iter(pipe.run()))
    det = res.detections
    m = det.label == MNLOS
    xy = np.c_[det.range[m] * np.cos(det.azimuth[m]), det.range[m] * np.sin(det.azimuth[m])]
    hidden = res.hidden.mean.reshape(-1, 2)
    trial = {"detection": cs.radar_detection(xy, image, cfg.gate).as_dict(),
             "reconstruction": cs.radar_reconstruction(hidden, fp, cfg.tolerance).as_dict(),
             "walls": len(res.walls)}
    shown = {"result": res, "pipeline": pipe, "footprint": fp, "image": image} if keep else None
    return {mod.label: trial}, shown


def _spad_params(cfg: StudyConfig, mod: SpadModality, scene) -> tuple[dict, dict]:
    """The transient model's params at this scene (the patch placed when ``placement = "facing"``, by
    the registered model's :meth:`~xnlos_core.interfaces.TransientModel.facing_params`) and the
    placement record."""
    params = dict(mod.transient_model.params)
    fixed = {"placement": "fixed", "grid_offset": params.get("grid_offset", 0.0)}
    if mod.placement == "fixed":
        return params, fixed
    from xnlos_core.registry import get_registry

    model = get_registry().create("transient_model", mod.transient_model.name, params,
                                  source=f"{cfg.name} [[modality]] {mod.label}")
    obj = next(o for o in scene.objects if o.name == cfg.hidden_object)
    placed = model.facing_params(scene, [*obj.center_at(0.0), obj.height / 2], exclude=cfg.hidden_object)
    if placed is None:
        return params, fixed
    facing, record = placed
    return {**params, "grid_offset": facing["grid_offset"]} if record["grid_offset"] is not None else params, record


def _spad_trial(cfg: StudyConfig, mod: SpadModality, d: float, seed: int, base_dir: Path, solvers: dict,
                keep: bool = False):
    """One SPAD scan (photon noise of ``seed``) at distance ``d``, reconstructed by every solver:
    ({'<label>/<solver>': trial}, shown)."""
    from xnlos_core.registry import get_registry
    from xnlos_core.transient import TransientVolume

    scene = _scene(cfg, d, base_dir)
    params, where = _spad_params(cfg, mod, scene)
    if where["placement"] == "facing" and where["grid_offset"] is None:  # no patch both seen and seeing
        miss = {"detection": cs.Outcome(False, False, True).as_dict(),
                "reconstruction": cs.Outcome(False, False, True).as_dict(), "patch": where}
        return {f"{mod.label}/{s}": dict(miss) for s in solvers}, None
    src = f"{cfg.name} [[modality]] {mod.label}"
    model = get_registry().create("transient_model", mod.transient_model.name, params, source=src)
    truth = model.truth(scene)
    vol = model.simulate(scene, seed)
    sx, sy = vol.grid()
    peak = cs.transient_peak(vol.data, vol.bin_width, vol.t0, mod.window, mod.n_sigma)
    det = cs.spad_detection(peak, cs.range_interval(truth, sx, sy), cfg.gate)
    rvol = vol
    if mod.background_subtract:
        clean = np.maximum(vol.data - np.median(vol.data, axis=0, keepdims=True), 0.0)
        if np.any(clean > 0):
            rvol = TransientVolume(clean, vol.bin_width, vol.wall_width, vol.wall_height, vol.t0)
    out, shown = {}, None
    for s, solver in solvers.items():
        nv = solver.reconstruct(rvol)
        top = max(peak.range + cfg.gate, mod.first_bounce_gate)
        vp = cs.volume_peak(nv.albedo, nv.z, nv.grid(), top, mod.first_bounce_gate)
        rec = cs.spad_reconstruction(vp, truth, cfg.tolerance, peak.detected)
        out[f"{mod.label}/{s}"] = {"detection": det.as_dict(), "reconstruction": rec.as_dict(),
                                   "peak_range": peak.range, "excess": peak.excess, "threshold": peak.threshold,
                                   "peak_xyz": list(vp.xyz), "peak_interior": vp.interior, "patch": where}
        if keep and shown is None:
            shown = {"volume": vol, "nlos": nv, "truth": truth, "scene": scene, "solver": s,
                     "peak": vp, "search": (mod.first_bounce_gate, top), "hit": rec.tp,
                     "detected": peak.detected, "range": peak.range}
    return out, shown


class Trials:
    """Every trial of one modality, computed once and kept (``cells/<m>_<label>.json``, keyed by seed
    index and distance in mm; written atomically at most every SAVE_EVERY seconds while new trials
    come in and by :meth:`save` at the end of the modality; reused while the config's digest is
    unchanged)."""

    SAVE_EVERY = 5.0  # [s]

    def __init__(self, cfg: StudyConfig, index: int, mod, base_dir: Path, cells_dir: Path | None, digest: str):
        from xnlos_core.registry import get_registry

        self.cfg, self.index, self.mod, self.base_dir = cfg, index, mod, base_dir
        self.rows = rows(cfg.model_copy(update={"modality": [mod]}))
        self.path = None if cells_dir is None else cells_dir / f"{index:02d}_{mod.label}.json"
        self.digest = digest
        self.cache: dict[str, dict] = {}
        self.computed = 0
        self._saved = time.monotonic()
        if self.path is not None and self.path.is_file():
            saved = json.loads(self.path.read_text())
            if saved.get("digest") == digest:
                self.cache = saved["trials"]
        src = f"{cfg.name} [[modality]] {mod.label}"
        if isinstance(mod, RadarModality):
            self.radar = radar_range_table(cfg, mod, base_dir)
        else:
            reg = get_registry()
            self.solvers = {s: reg.create("nlos_solver", s, {}, source=src) for s in mod.solvers}

    def seed(self, k: int) -> int:
        """Trial seed k of this modality (the same at every distance)."""
        return int(np.random.SeedSequence([self.cfg.seed, self.index, k]).generate_state(1, np.uint64)[0] >> 1)

    def run(self, d: float, seed: int, keep: bool = False):
        if isinstance(self.mod, RadarModality):
            return _radar_trial(self.cfg, self.mod, d, seed, self.base_dir, self.radar, keep)
        return _spad_trial(self.cfg, self.mod, d, seed, self.base_dir, self.solvers, keep)

    def trial(self, k: int, d: float) -> dict:
        """{row: trial dict} of seed k at distance d [m] (rounded to 1 mm)."""
        key = f"{k}:{round(d * 1000)}"
        if key not in self.cache:
            self.cache[key] = self.run(round(d * 1000) / 1000, self.seed(k))[0]
            self.computed += 1
            if time.monotonic() - self._saved > self.SAVE_EVERY:
                self.save()
        return self.cache[key]

    def save(self) -> None:
        """Write the trials so far (atomically)."""
        self._saved = time.monotonic()
        if self.path is not None and self.computed:
            atomic_write_text(self.path, json.dumps({"digest": self.digest, "trials": self.cache}, default=float))


def success(trial: dict, threshold: float) -> bool:
    """The study's success criterion for one trial: its reconstruction F1 ≥ ``threshold``."""
    f = cs.f1_rate([trial["reconstruction"]])
    return f is not None and f >= threshold


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
            _radar_pipeline(cfg, mod, scene_table(cfg, cfg.distances[0]), 0, base_dir,
                            radar_range_table(cfg, mod, base_dir))
        else:
            src = f"{path} [[modality]] {mod.label}"
            scene = _scene(cfg, cfg.distances[0], base_dir)
            params, _ = _spad_params(cfg, mod, scene)
            model = reg.create("transient_model", mod.transient_model.name, params, source=src)
            model.truth(scene)
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
    from xnlos_core.app.crossmodal.bisect import bisect_range

    cfg, base_dir = load_study(config)
    out = Path(out)
    digest = cfg.digest()
    results: dict[str, dict[float, list]] = {r: {} for r in rows(cfg)}
    bisections: dict[str, list[dict]] = {}
    t_start = time.perf_counter()
    b = cfg.bisection
    for mi, mod in enumerate(cfg.modality):
        trials = Trials(cfg, mi, mod, base_dir, out / "cells", digest)
        t0 = time.perf_counter()
        for d in cfg.distances:
            cell = [trials.trial(k, d) for k in range(cfg.seeds)]
            for r in trials.rows:
                results[r][d] = [c[r] for c in cell]
            summary = ", ".join(f"{r}: det {_fmt(cs.f1_rate(c[r]['detection'] for c in cell))} rec "
                                f"{_fmt(cs.f1_rate(c[r]['reconstruction'] for c in cell))}" for r in trials.rows)
            _log(f"{mod.label} grid d = {d:g} m: {summary}", progress)
        for r in trials.rows:
            runs = []
            for k in range(cfg.seeds):
                res = bisect_range(lambda d, k=k, r=r: success(trials.trial(k, d)[r], cfg.threshold),
                                   b.lower, b.upper, rel_tol=b.rel_tol)
                runs.append(res.as_dict())
            bisections[r] = runs
            _log(f"{r} ranges to failure: " + ", ".join(_range_text(x) for x in runs), progress)
        trials.save()
        _log(f"{mod.label}: {trials.computed} new trial(s) [{time.perf_counter() - t0:.1f} s]", progress)
    res = summarise(cfg, results, bisections)
    atomic_write_text(out / "crossmodal.json", strict_json_text(res, indent=2))
    atomic_write_text(out / "crossmodal.md", render_markdown(cfg, res, str(config), str(out)))
    _log(f"tables written [{time.perf_counter() - t_start:.1f} s]", progress)
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
            trials = Trials(cfg, mi, mod, base_dir, None, digest)
            _, shown = trials.run(cfg.panel_distance, _trial_seed(cfg, mi, 10_000), keep=True)
            if shown is None:
                continue
            label = mod.label if isinstance(mod, RadarModality) else f"{mod.label}/{shown['solver']}"
            panel[label] = {**shown, "colour": colours[label]}
        panel_figure(cfg, panel, out / "panel.png")
        res["figures"] = ["range_curve.png", "panel.png"]
        atomic_write_text(out / "crossmodal.json", strict_json_text(res, indent=2))
    return res


def _fmt(v) -> str:
    return "—" if v is None else f"{v:.2f}"


def _interval_text(iv: dict, lower: float | None = None, upper: float | None = None) -> str:
    """"[low, high]"; an end at 0 / inf (a censored seed, bisect module) as the bound it stands for."""
    def end(v: float) -> str:
        if v == 0:
            return f"< {lower:g}" if lower is not None else "0 (bound)"
        if math.isinf(v):
            return f"≥ {upper:g}" if upper is not None else "∞ (bound)"
        return f"{v:.2f}"
    return f"[{end(iv['low'])}, {end(iv['high'])}]"


def _range_text(run: dict) -> str:
    if run["status"] == "below":
        return f"< {run['hi']:g}"
    if run["status"] == "above":
        return f"≥ {run['lo']:g}"
    return f"{run['lo']:g}"


def _row_range(cfg: StudyConfig, runs: list[dict], seed: int) -> dict:
    """A row's range to failure from its seeds' bisections (:mod:`~xnlos_core.app.crossmodal.bisect`):
    the lower median over seeds with its bootstrap interval; status "measured" (the median falls on
    a bracketed seed), "above" / "below" (it falls on a seed still in range at the upper bound /
    failing at the lower one: a bound of the sweep); the count of seeds at each bound."""
    from xnlos_core.app.crossmodal.bisect import censored_values, median_interval

    v = censored_values(runs)
    iv = median_interval(v, seed=seed, level=cfg.bootstrap.level, resamples=cfg.bootstrap.resamples)
    st = [r["status"] for r in runs]
    status = "below" if iv.value == 0 else "above" if math.isinf(iv.value) else "measured"
    return {"status": status, "interval": iv.as_dict(), "n_above": st.count("above"), "n_below": st.count("below"),
            "n": len(runs), "ranges": [r["range"] for r in runs]}


def _bound_text(cfg: StudyConfig, label: str, r: dict) -> str:
    b = cfg.bisection
    if r["status"] == "above":
        return (f"{label} still reconstructs at the upper bound {b.upper:g} m in {r['n_above']}/{r['n']} seed(s) "
                f"(its median range is above {b.upper:g} m)")
    return (f"{label} already fails at the lower bound {b.lower:g} m in {r['n_below']}/{r['n']} seed(s) "
            f"(its median range is below {b.lower:g} m)")


def summarise(cfg: StudyConfig, results: dict[str, dict[float, list]], bisections: dict[str, list[dict]]) -> dict:
    """F1 per row and grid distance, each row's range to failure (median over seeds, bootstrap
    interval), and the ``ratios`` with bootstrap intervals — only from measured ranges."""
    from xnlos_core.app.crossmodal.bisect import censored_values, ratio_interval

    table = {}
    for i, (r, by_d) in enumerate(results.items()):
        ds = sorted(by_d)
        det = [cs.f1_rate(t["detection"] for t in by_d[d]) for d in ds]
        rec = [cs.f1_rate(t["reconstruction"] for t in by_d[d]) for d in ds]
        table[r] = {"distances": ds, "detection_f1": det, "reconstruction_f1": rec,
                    "max_grid_range_detection": cs.max_range(ds, det, cfg.threshold),
                    "max_grid_range_reconstruction": cs.max_range(ds, rec, cfg.threshold)}
        if r in bisections:
            boot = int(np.random.SeedSequence([cfg.seed, 1, i]).generate_state(1, np.uint32)[0])
            table[r]["range_to_failure"] = _row_range(cfg, bisections[r], boot)
            table[r]["bisections"] = bisections[r]
    # A ratio only from two measured ranges: a range at the bisection's upper bound (still in range)
    # or below its lower bound (never in range) is a bound of the sweep, not a measurement, and a
    # ratio of bounds is no number (the note says which bound was reached instead).
    ratios = []
    for j, (ref, base) in enumerate(cfg.ratios):
        a, b = table[ref].get("range_to_failure"), table[base].get("range_to_failure")
        entry = {"reference": ref, "baseline": base, "value": None, "interval": None, "note": None}
        if a is None or b is None:
            entry["note"] = "no range ratio: no bisection for these rows"
        else:
            bounds = [_bound_text(cfg, lab, x) for lab, x in ((ref, a), (base, b)) if x["status"] != "measured"]
            if bounds:
                entry["note"] = "no range ratio: the sweep's bound was reached: " + "; ".join(bounds)
            else:
                seed = int(np.random.SeedSequence([cfg.seed, 2, j]).generate_state(1, np.uint32)[0])
                iv = ratio_interval(censored_values(bisections[ref]), censored_values(bisections[base]), seed=seed,
                                    level=cfg.bootstrap.level, resamples=cfg.bootstrap.resamples)
                entry["value"], entry["interval"] = iv.value, iv.as_dict()
        ratios.append(entry)
    first = ratios[0] if ratios else None
    return {"name": cfg.name, "digest": cfg.digest(), "seeds": cfg.seeds, "gate_m": cfg.gate,
            "tolerance_m": cfg.tolerance, "threshold": cfg.threshold, "bisection": cfg.bisection.model_dump(),
            "bootstrap": cfg.bootstrap.model_dump(), "rows": table, "ratios": ratios,
            "range_ratio": None if first is None or first["value"] is None else
            {"value": first["value"], "interval": first["interval"], "bound": "="},
            "range_ratio_note": None if first is None else first["note"]}


def marked(name: str, lines: list[str]) -> list[str]:
    """``lines`` between ``<!-- table:NAME -->`` and ``<!-- /table -->``: the markers with which a
    benchmark page names a deterministic table (``benchmarks/pages.py`` compares the lines between
    them with a rerun of the page's seeded command; HTML comments, invisible on the rendered page).
    Written here, not imported: the core imports nothing from ``benchmarks/``."""
    return [f"<!-- table:{name} -->", *lines, "<!-- /table -->"]


def command_line(config: str, out: str) -> str:
    """The command that regenerates a study's tables (printed at the top of ``crossmodal.md``)."""
    return f"xnlos crossmodal {config} --out {out}"


def render_markdown(cfg: StudyConfig, res: dict, source: str, out: str = "out/crossmodal") -> str:
    """The study's tables: range to failure per row (median over seeds, bootstrap interval, per-seed
    ranges), the range ratios, and the F1 grid (detection / reconstruction per distance). Each is
    :func:`marked` (``ranges``, ``ratios`` with ``ratio_notes``, ``f1_grid``): all are deterministic
    (the same config gives the same text on every run)."""
    b, lvl = cfg.bisection, f"{100 * cfg.bootstrap.level:g} %"
    lines = [f"# Cross-modality study `{cfg.name}`", "",
             f"Command: `{command_line(source, out)}` (seed {cfg.seed}; deterministic)", "",
             f"{cfg.seeds} seed(s) per row; success of a trial: reconstruction F1 ≥ {cfg.threshold:g} (gate "
             f"{cfg.gate:g} m, tolerance {cfg.tolerance:g} m). Range to failure: per seed, bisection of the "
             f"distance between {b.lower:g} and {b.upper:g} m to a bracket hi/lo ≤ {1 + b.rel_tol:g} (the "
             f"range is the last success); row: the (lower) median over seeds, {lvl} percentile-bootstrap "
             f"interval over resampled seeds ({cfg.bootstrap.resamples} resamples, seeded); a seed that still "
             f"succeeds at {b.upper:g} m or already fails at {b.lower:g} m is censored at that bound (shown ≥ / <), "
             "and a median or interval end on a censored seed is that bound, never a number.", "",
             "## Range to failure", ""]
    ranges = [f"| row | range [m] | {lvl} interval [m] | per-seed ranges [m] |", "|---|---|---|---|"]
    for r, t in res["rows"].items():
        x = t.get("range_to_failure")
        if x is None:
            continue
        per = ", ".join(_range_text(run) for run in t["bisections"])
        iv = x["interval"]
        value = (f"{iv['value']:.2f}" if x["status"] == "measured" else
                 f"≥ {b.upper:g} (upper bound reached)" if x["status"] == "above" else
                 f"< {b.lower:g} (fails at the lower bound)")
        ranges.append(f"| {r} | {value} | {_interval_text(iv, b.lower, b.upper)} | {per} |")
    lines += marked("ranges", ranges)
    if res["ratios"]:
        table = [f"| ratio | value | {lvl} interval |", "|---|---|---|"]
        for q in res["ratios"]:
            if q["value"] is not None:
                table.append(f"| {q['reference']} / {q['baseline']} | {q['value']:.2f} | "
                             f"{_interval_text(q['interval'])} |")
            else:
                table.append(f"| {q['reference']} / {q['baseline']} | — | — |")
        lines += ["", "## Range ratios", "", *marked("ratios", table)]
        notes = []
        if any(q["interval"] and (q["interval"]["low"] == 0 or math.isinf(q["interval"]["high"]))
               for q in res["ratios"]):
            notes += ["", "A ratio interval that ends at ∞ (or 0) is open on that side: in some resamples of the "
                      "seeds the baseline's (or reference's) median fell on a seed censored at the lower bound."]
        for q in res["ratios"]:
            if q["note"]:
                notes.append("")
                notes.append(f"{q['reference']} / {q['baseline']}: " + q["note"][0].upper() + q["note"][1:] + ".")
        if notes:
            lines += [*notes[:1], *marked("ratio_notes", notes[1:])]
    ds = sorted(cfg.distances)
    grid = ["| row | " + " | ".join(f"{d:g} m" for d in ds) + " |", "|---|" + "---|" * len(ds)]
    for r, t in res["rows"].items():
        cells = [f"{_fmt(a)} / {_fmt(c)}" for a, c in zip(t["detection_f1"], t["reconstruction_f1"])]
        grid.append(f"| {r} | " + " | ".join(cells) + " |")
    lines += ["", "## F1 on the distance grid", "",
              "Cells: detection F1 / reconstruction F1 over the seeds' trials (the same trial seeds as the "
              "bisection).", "", *marked("f1_grid", grid)]
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
