"""One shard: built by a worker from the config alone, stored as a byte-reproducible ``.npz``.

Shard ``.npz`` members (N maps, H = n_range, W = n_azimuth; no object arrays, no pickle):

======================  ===============  =====================================================
key                     dtype, shape     meaning
======================  ===============  =====================================================
schema_version          int64 ()         :data:`SCHEMA_VERSION`
shard, split            str ()           file name, "train" | "val" | "test"
config_sha256           str ()           digest of the dataset's resolved config
radar_json              str ()           the RadarConfig (JSON)
range_axis              float64 (H,)     [m]
azimuth_axis            float64 (W,)     [rad]
ra                      complex64        RA maps (N, H, W)
map_index               int64 (N,)       global map index = scene_index·frames_per_scene + frame
scene_index, frame      int64 (N,)       scene (global index) and frame within the scene
scene_seed, noise_seed  int64 (N,)       generator seed; seed of the forward model's rng
family                  str (N,)         scene family
timestamp               float64 (N,)     t = frame·frame_interval [s]
los_points              float64 (L, 2)   ground truth of map i: rows los_offsets[i]:[i+1] [m]
los_offsets             int64 (N+1,)
los_snr_db              float32 (L,)     expected RA-map SNR of each LOS point [dB] (version ≥ 2)
mnlos_points            float64 (M, 2)   virtual points o′ [m]; rows mnlos_offsets[i]:[i+1]
hidden_points           float64 (M, 2)   true hidden points o, row-aligned with mnlos_points [m]
mnlos_object            int64 (M,)       index into map i's object names
mnlos_offsets           int64 (N+1,)
mnlos_snr_db            float32 (M,)     expected RA-map SNR of each mNLOS point [dB] (version ≥ 2)
object_names            str (O,)         rows object_offsets[i]:[i+1]
object_offsets          int64 (N+1,)
walls                   float64 (K, 2, 2) ground-truth wall segments (start, end) [m]
wall_names              str (K,)         rows wall_offsets[i]:[i+1]
wall_offsets            int64 (N+1,)
frame_meta_json         str ()           JSON list of the N frames' ``meta``
scenes_json             str ()           JSON list, per scene: scene_index, scene_seed, family,
                                         scene (the full Scene, whose ``meta`` holds the drawn
                                         generator parameters)
ra_velocity             float32 (N,H,W)  only with Doppler maps: RAMap.velocity [m/s]
ra_velocity_std         float32 (N,H,W)  only with Doppler maps: RAMap.velocity_std [m/s]
truth_* , hidden_velocity, mnlos_velocity   only when frames_per_scene > 1: per-frame object truth
                                         (:mod:`sims.dataset.truth`)
======================  ===============  =====================================================

The optional members are added only when they apply, so a still dataset without Doppler is the same
bytes as before they existed.

Zip members carry a fixed timestamp and frame ``meta`` loses its wall-clock entries
(:data:`TIMING_KEYS`, e.g. the ray tracer's ``trace_s``), so the same config and seed give the same
shard bytes on every run and machine. Timing lives in ``completed.jsonl`` (``seconds``,
``cpu_seconds``), which no shard or dataset digest covers.
"""
from __future__ import annotations

import hashlib
import io
import json
import time
import zipfile
from contextlib import nullcontext
from functools import lru_cache
from typing import Any

import numpy as np

from xnlos_core.errors import XnlosError
from xnlos_core.io import json_default
from xnlos_core.radar import RadarConfig
from xnlos_core.types import FRAME_IN_SCENE, Frame, GroundTruth, RAMap, WallSegment

from .config import DatasetConfig, scene_generators
from .outlines import outline_meta, scene_objects
from .plan import noise_seed
from .truth import meta_from_arrays, object_rows, truth_arrays

SCHEMA_VERSION = 2
READABLE_VERSIONS = (1, 2)  # version 1: no per-point SNR (read as NaN)
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)
# Frame meta entries that measure wall-clock time: left out of shards (they differ on every run).
TIMING_KEYS = frozenset({"trace_s"})


class DatasetError(XnlosError, ValueError):
    """A dataset directory or shard is missing, corrupt, of another schema or of another config."""


def encode_npz(arrays: dict[str, np.ndarray], compression: str = "deflate", level: int = 1) -> bytes:
    """``.npz`` bytes readable by ``np.load(allow_pickle=False)``, identical for identical arrays."""
    method = zipfile.ZIP_DEFLATED if compression == "deflate" else zipfile.ZIP_STORED
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", allowZip64=True) as zf:
        for key, arr in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asarray(arr), allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_TIME)
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue(), compress_type=method,
                        compresslevel=level if method == zipfile.ZIP_DEFLATED else None)
    return buf.getvalue()


def decode_npz(data: bytes, name: str) -> dict[str, np.ndarray]:
    """Every member of shard bytes ``data`` (pickle never allowed); errors name the shard."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            out = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise DatasetError(f"shard {name}: not a readable .npz ({type(exc).__name__}: {exc})") from None
    version = int(out.get("schema_version", -1))
    if version not in READABLE_VERSIONS:
        raise DatasetError(f"shard {name}: schema version {version}; this xnlos reads versions "
                           f"{', '.join(map(str, READABLE_VERSIONS))}")
    return out


@lru_cache(maxsize=4)
def _forward_model(name: str, params_json: str):
    """One forward model per process and configuration (workers reuse it across shards)."""
    from xnlos_core.registry import get_registry

    return get_registry().create("forward_model", name, json.loads(params_json), source="dataset")


def build_shard(config: DatasetConfig, name: str, split: str, scenes: list[tuple[int, int, str]],
                digest: str, generators: dict[str, type] | None = None) -> dict[str, Any]:
    """Render the maps of ``scenes`` [(scene_index, scene_seed, family)] into shard bytes.

    ``config`` must be resolved (full radar, forward model parameters). ``generators``: family →
    scene generator class, as the parent process's registry resolved the names (a worker's own
    registry holds only the entry points, not a plugin registered by hand); None looks the
    names up in this process's registry. Returns {shard, data (bytes), sha256, n_maps,
    n_scenes, seconds (wall), cpu_seconds (this process)}.
    """
    from xnlos_core.scene import Scene

    t0, c0 = time.perf_counter(), time.process_time()
    radar = RadarConfig.model_validate(config.radar)
    fm = _forward_model(config.forward_model.name, json.dumps(config.forward_model.params, sort_keys=True))
    gens = scene_generators(config, f"shard {name}", classes=generators)
    fps = config.frames_per_scene
    frames: list[Frame] = []
    rows: dict[str, list] = {k: [] for k in ("map_index", "scene_index", "frame", "scene_seed", "noise_seed",
                                             "family", "timestamp")}
    scene_docs = []
    truth: list[list[tuple]] = []
    for k, seed, fam in scenes:
        where = f"shard {name}, scene {k} (family {fam!r}, seed {seed})"
        try:
            scene = gens[fam].generate(seed)
            if not isinstance(scene, Scene):
                raise TypeError(f"the scene generator returned {type(scene).__name__}, expected a Scene")
            scene_docs.append({"scene_index": k, "scene_seed": seed, "family": fam,
                               "scene": scene.model_dump(mode="json")})
            for f in range(fps):
                ns = noise_seed(config.seed, k, f)
                t = f * config.frame_interval
                frame = fm.simulate(scene, radar, np.random.default_rng(ns), timestamp=t, index=k * fps + f)
                frames.append(frame)
                if fps > 1:
                    truth.append(object_rows(scene, frame, (fps - 1) * config.frame_interval))
                for key, v in zip(rows, (k * fps + f, k, f, seed, ns, fam, t)):
                    rows[key].append(v)
        except XnlosError as exc:
            raise DatasetError(f"{where}: {exc}") from exc
        except Exception as exc:
            raise DatasetError(f"{where}: {type(exc).__name__}: {exc}") from exc
    arrays = _arrays(frames, rows, radar)
    if fps > 1:
        arrays.update(truth_arrays(truth, frames))
    arrays = {"schema_version": np.array(SCHEMA_VERSION, dtype=np.int64), "shard": np.array(name),
              "split": np.array(split), "config_sha256": np.array(digest),
              "radar_json": np.array(radar.model_dump_json()), **arrays,
              "scenes_json": np.array(json.dumps(scene_docs, sort_keys=True))}
    data = encode_npz(arrays, config.compression, config.compression_level)
    return {"shard": name, "data": data, "sha256": hashlib.sha256(data).hexdigest(), "n_maps": len(frames),
            "n_scenes": len(scenes), "seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0}


def run_shard_job(job: dict[str, Any]) -> dict[str, Any]:
    """Executor entry point (module-level, importable by worker processes and Dask workers).

    BLAS runs single-threaded here, in every mode: parallelism comes from the workers (as Dask
    sets up its worker processes), and a 2-thread BLAS per worker on 2 cores costs ~35 % more
    CPU per map in oversubscription.
    """
    from xnlos_core.config import validate_model

    cfg = validate_model(DatasetConfig, job["config"], source=f"dataset job {job['shard']}", prefix="config")
    with _one_blas_thread():
        return build_shard(cfg, job["shard"], job["split"], [tuple(s) for s in job["scenes"]], job["digest"],
                           job.get("generators"))


def _one_blas_thread():
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional (scikit-learn brings it); without it BLAS keeps its default threads
        return nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _offsets(counts: list[int]) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]).astype(np.int64)


def _arrays(frames: list[Frame], rows: dict[str, list], radar: RadarConfig) -> dict[str, np.ndarray]:
    gts = [fr.ground_truth if fr.ground_truth is not None else GroundTruth() for fr in frames]
    h, w = radar.n_range_bins, len(radar.azimuth_axis)
    ra = np.stack([fr.ra_map.data for fr in frames]) if frames else np.zeros((0, h, w), np.complex64)
    cat = lambda xs, shape: np.concatenate(xs) if xs else np.zeros(shape)  # noqa: E731
    walls = [np.array([[s.start, s.end] for s in g.walls], dtype=np.float64).reshape(-1, 2, 2) for g in gts]
    out = {
        "range_axis": frames[0].ra_map.range_axis if frames else radar.range_axis,
        "azimuth_axis": frames[0].ra_map.azimuth_axis if frames else radar.azimuth_axis,
        "ra": ra.astype(np.complex64, copy=False),
        **{k: np.array(rows[k], dtype=np.int64) for k in ("map_index", "scene_index", "frame", "scene_seed",
                                                          "noise_seed")},
        "family": np.array(rows["family"], dtype=str),
        "timestamp": np.array(rows["timestamp"], dtype=np.float64),
        "los_points": cat([g.los_points for g in gts], (0, 2)),
        "los_offsets": _offsets([len(g.los_points) for g in gts]),
        "los_snr_db": cat([g.los_snr_db for g in gts], (0,)).astype(np.float32),
        "mnlos_snr_db": cat([g.mnlos_snr_db for g in gts], (0,)).astype(np.float32),
        "mnlos_points": cat([g.mnlos_points for g in gts], (0, 2)),
        "hidden_points": cat([g.hidden_points for g in gts], (0, 2)),
        "mnlos_object": cat([g.mnlos_object for g in gts], (0,)).astype(np.int64),
        "mnlos_offsets": _offsets([len(g.mnlos_points) for g in gts]),
        "object_names": np.array([n for g in gts for n in g.object_names], dtype=str),
        "object_offsets": _offsets([len(g.object_names) for g in gts]),
        "walls": cat(walls, (0, 2, 2)),
        "wall_names": np.array([s.name for g in gts for s in g.walls], dtype=str),
        "wall_offsets": _offsets([len(g.walls) for g in gts]),
        "frame_meta_json": np.array(json.dumps([{k: v for k, v in fr.meta.items() if k not in TIMING_KEYS}
                                                for fr in frames], sort_keys=True, default=json_default)),
    }
    if frames and all(fr.ra_map.velocity is not None for fr in frames):  # Doppler maps
        out["ra_velocity"] = np.stack([fr.ra_map.velocity for fr in frames]).astype(np.float32)
        out["ra_velocity_std"] = np.stack([fr.ra_map.velocity_std for fr in frames]).astype(np.float32)
    return out


def frames_from_arrays(z: dict[str, np.ndarray], radar: RadarConfig) -> list[Frame]:
    """The shard's maps as Frames with exact ground truth; ``meta`` adds shard, split, scene and seeds,
    and ``object_outlines`` (:mod:`sims.dataset.outlines`) when the shard's scenes are readable."""
    name, split = str(z["shard"]), str(z["split"])
    metas = json.loads(str(z["frame_meta_json"]))
    scenes = scene_objects(z)
    off = {k: z[f"{k}_offsets"] for k in ("los", "mnlos", "object", "wall")}
    out = []
    for i in range(len(z["map_index"])):
        sl = {k: slice(int(o[i]), int(o[i + 1])) for k, o in off.items()}
        walls = tuple(WallSegment(s, e, str(n)) for (s, e), n in zip(z["walls"][sl["wall"]],
                                                                     z["wall_names"][sl["wall"]]))
        gt = GroundTruth(z["los_points"][sl["los"]], z["mnlos_points"][sl["mnlos"]],
                         z["hidden_points"][sl["mnlos"]], z["mnlos_object"][sl["mnlos"]],
                         tuple(str(n) for n in z["object_names"][sl["object"]]), walls,
                         z["los_snr_db"][sl["los"]] if "los_snr_db" in z else None,  # shards before SNR was kept
                         z["mnlos_snr_db"][sl["mnlos"]] if "mnlos_snr_db" in z else None,
                         *((z["hidden_velocity"][sl["mnlos"]], z["mnlos_velocity"][sl["mnlos"]])
                           if "hidden_velocity" in z else ()),
                         los_radial_velocity=metas[i].get("doppler", {}).get("los_radial_velocity"))
        doppler = (z["ra_velocity"][i], z["ra_velocity_std"][i]) if "ra_velocity" in z else ()
        ra = RAMap(z["ra"][i], z["range_axis"], z["azimuth_axis"], radar, *doppler)
        meta = {**metas[i], "shard": name, "split": split, "scene_index": int(z["scene_index"][i]),
                FRAME_IN_SCENE: int(z["frame"][i]), "scene_seed": int(z["scene_seed"][i]),
                "noise_seed": int(z["noise_seed"][i]), "family": str(z["family"][i])}
        objects = meta_from_arrays(z, i)
        if objects is not None:
            meta["object_truth"] = objects
        if meta["scene_index"] in scenes:
            meta["object_outlines"] = outline_meta(scenes[meta["scene_index"]], float(z["timestamp"][i]))
        out.append(Frame(ra, float(z["timestamp"][i]), gt, int(z["map_index"][i]), meta))
    return out
