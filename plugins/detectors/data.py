"""Training data: RA maps → (features, ground-truth peak cells), held in memory.

Maps come from a dataset directory (the registry's ``dataset`` backend, :mod:`plugins.training.frames`) or are simulated on the fly
from a :class:`GenerateConfig` (frame k of a split from a generator seeded by
``SeedSequence([seed, split_index]).spawn`` child k). Features are stored as float16 (their
range is [−3, 10] in 10 dB units, so 0.004 resolution costs nothing); targets are rendered per
batch from the peak cells by the output head.
"""
from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.errors import ConfigError
from xnlos_core.metrics import thin_to_resolution
from xnlos_core.types import FRAME_IN_SCENE, Frame, GroundTruth, RAMap

from .features import MAX_PREVIOUS, RA_CHANNELS, channel_layout, map_features
from .heatmaps import peak_cells
from .train_config import DataConfig, GenerateConfig, scene_generators


@dataclass
class MapSet:
    """N maps of one split: features (N, C, H, W) float16 (C input channels, :mod:`.features`), peak cells per map (P, 3), and for
    evaluation the maps' axes (RAMap without data is not possible, so the RAMap itself is kept
    only when ``keep_maps``) and thinned ground truth."""

    features: np.ndarray
    peaks: list[np.ndarray]
    maps: list[RAMap] = field(default_factory=list)
    truths: list[GroundTruth] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.peaks)


def _add(frames, keep_maps: bool, limit: int | None, desc: str, progress: bool,
         channels: tuple[str, ...] = RA_CHANNELS) -> MapSet:
    from tqdm import tqdm

    from collections import deque

    feats, peaks, maps, truths = [], [], [], []
    history: deque = deque(maxlen=MAX_PREVIOUS)  # earlier frames' log power of this sequence, the last first
    for f in tqdm(itertools.islice(frames, limit), desc=desc, unit="map", disable=not progress, total=limit):
        if not isinstance(f, Frame) or f.ground_truth is None:
            raise ConfigError(f"{desc}: map {getattr(f, 'index', '?')} has no ground truth; training needs "
                              "simulated maps")
        if f.meta.get(FRAME_IN_SCENE, 0) == 0:
            history.clear()  # a new sequence (or maps that stand alone)
        x = map_features(f.ra_map, channels, name=f"{desc}: map {f.index}", previous=history)
        history.appendleft(x[0])
        feats.append(x.astype(np.float16))
        peaks.append(peak_cells(f.ra_map, f.ground_truth))
        if keep_maps:
            maps.append(f.ra_map)
            truths.append(thin_to_resolution(f.ground_truth, f.ra_map.radar))
    if not feats:
        raise ConfigError(f"{desc}: no maps")
    shapes = {x.shape for x in feats}
    if len(shapes) > 1:
        raise ConfigError(f"{desc}: maps of different sizes {sorted(shapes)}; one training run needs one size")
    return MapSet(np.stack(feats), peaks, maps, truths)


def _generated(gen: GenerateConfig, seed: int, split: str, base_dir: Path):
    from xnlos_core.radar import load_radar
    from xnlos_core.registry import get_registry
    from xnlos_core.scene import load_scene

    index = {"train": 0, "val": 1, "test": 2}[split]
    n = {"train": gen.n_train, "val": gen.n_val, "test": gen.n_test}[split]
    radar = load_radar(gen.radar, "data.generate", base_dir)
    fm = get_registry().create("forward_model", gen.forward_model.name, gen.forward_model.params,
                               source="data.generate.forward_model")
    fixed = load_scene(gen.scene, "data.generate.scene", base_dir) if gen.scene is not None else None
    families = scene_generators(gen)
    seeds = np.random.SeedSequence([seed, index]).spawn(n)
    for k in range(n):
        if fixed is not None:
            scene = fixed
        else:
            scene = families[k % len(families)].generate(int(seeds[k].generate_state(1, np.uint32)[0]))
        yield fm.simulate(scene, radar, np.random.default_rng(seeds[k]), index=k)


def load_split(cfg: DataConfig, seed: int, split: str, keep_maps: bool, limit: int | None,
               progress: bool = False, base_dir: str | Path = ".") -> MapSet:
    """The maps of ``split`` ("train", "val", "test") for training or evaluation, as features of the
    input channels that ``cfg.doppler`` and ``cfg.previous_frames`` select (:meth:`TrainConfig.channels`;
    a sequence dataset's maps come in frame order, and ``frame_in_scene`` 0 starts a sequence)."""
    channels = channel_layout(cfg.doppler, cfg.previous_frames)
    if cfg.generate is not None:
        frames = _generated(cfg.generate, seed, split, Path(base_dir))
    else:
        from plugins.training.frames import dataset_backend

        name = {"train": cfg.train_split, "val": cfg.val_split}.get(split, split)
        frames = dataset_backend(cfg.dataset, name, base_dir).frames()
    return _add(frames, keep_maps, limit, f"load {split}", progress, channels)


def dataset_record(cfg: DataConfig, base_dir: str | Path = ".") -> dict[str, Any]:
    """Provenance of the training data: the dataset's manifest hashes, or the generator spec.
    base_dir: the config file's folder, which a relative ``dataset`` is taken from."""
    if cfg.generate is not None:
        spec = cfg.generate.model_dump(mode="json")
        return {"source": "generate", "spec": spec,
                "sha256": hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()}
    from plugins.training.frames import dataset_backend

    rec = dataset_backend(cfg.dataset, "all", base_dir, verify=False).record()
    return {"source": "dataset", "path": str(cfg.dataset), "name": rec["name"], "config_sha256": rec["config_sha256"],
            "sha256": rec["sha256"], "n_maps": rec["n_maps"], "splits": rec["splits"]}
